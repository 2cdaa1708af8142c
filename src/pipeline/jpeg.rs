//! JPEG as a streaming source, through libjpeg-turbo ([`crate::io::jpeg`]): rows as the
//! decoder makes them (by MCU rows inside libjpeg), and shrink-on-load by DCT scaling when
//! the output is much smaller than the image ([`shrink_denominator`]).

use std::io::Read;
use std::path::Path;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

use super::source::{RowSource, SourceInfo};
use crate::error::{Error, Result};
use crate::io::jpeg::Jpeg;
use crate::io::ReadOptions;
use crate::raster::{ColorKind, Image, Samples};

/// A JPEG file decoded row by row, on a thread of its own: while the caller halftones one
/// band, the next is being decoded.
pub struct JpegSource {
    name: std::path::PathBuf,
    /// The decoder until the first band is asked for; then it moves to its thread.
    jpeg: Option<Jpeg>,
    info: SourceInfo,
    /// Decode at 1/`denom` (1, 2 or 4).
    denom: usize,
    /// Bytes of the file and of what libjpeg keeps (a progressive file's coefficients).
    progressive_bytes: usize,
    channels: usize,
    /// Bands from the decoding thread, and their buffers sent back to be filled again.
    bands: Option<(Receiver<Result<BandPlanes>>, SyncSender<BandPlanes>)>,
    rows_read: usize,
}

/// The planes of one band.
type BandPlanes = Vec<Vec<u8>>;

/// Bands decoded ahead of the one being halftoned.
const AHEAD: usize = 1;

/// The decoding thread: bands of `rows` rows (the last one shorter), split into planes.
fn decode_bands(
    mut jpeg: Jpeg,
    rows: usize,
    denom: usize,
    tx: SyncSender<Result<BandPlanes>>,
    spare: Receiver<BandPlanes>,
) {
    let mut run = || -> Result<()> {
        let (w, h) = jpeg.start(denom)?;
        let ch = jpeg.channels();
        let mut buf = Vec::new();
        let mut y = 0;
        while y < h {
            let n = rows.min(h - y);
            let mut planes = spare.try_recv().unwrap_or_else(|_| vec![Vec::new(); ch]);
            if ch == 1 {
                jpeg.read_rows(n, &mut planes[0])?;
            } else {
                jpeg.read_rows(n, &mut buf)?;
                split(&buf, w * n, &mut planes);
            }
            y += n;
            if tx.send(Ok(planes)).is_err() {
                // The reader has gone (an error downstream): stop decoding.
                return Ok(());
            }
        }
        Ok(())
    };
    if let Err(e) = run() {
        let _ = tx.send(Err(e));
    }
}

/// Interleaved RGB into three planes of `n` samples.
fn split(rgb: &[u8], n: usize, planes: &mut [Vec<u8>]) {
    let [r, g, b] = planes else {
        unreachable!("three planes")
    };
    for p in [&mut *r, &mut *g, &mut *b] {
        p.clear();
        p.reserve(n);
    }
    for px in rgb[..n * 3].chunks_exact(3) {
        r.push(px[0]);
        g.push(px[1]);
        b.push(px[2]);
    }
}

/// Images smaller than this are decoded at full size whatever the output's size.
///
/// DCT scaling averages sRGB-encoded codes, not light, so a block with strong contrast
/// inside it comes out too dark (a 2×2 block of codes 50 and 200 averages to 125, 21% light,
/// where its light is 42%). In a camera-sized photo a block of 2–4 pixels rarely holds such
/// contrast; in a small one nearly every block does: on scikit-image's 512-pixel photos,
/// halftones made through 1/8 scaling lost up to 5.9 dB HVS-PSNR against the full decode,
/// and 0.3–1.2 dB even through 1/2 scaling with twice the output's size left (docs/photos.md).
pub const SHRINK_MIN_PIXELS: usize = 4_000_000;

/// The part of the shrinking left to the resize after the decoder's, at least: the Lanczos
/// filter, in linear light, then averages every output pixel over several decoded ones.
pub const SHRINK_MARGIN: usize = 2;

/// The DCT-scaling denominator (4, 2, else 1) for an image of `w × h` to be resized to
/// `min_w × min_h`: the largest whose output, `⌈w/d⌉ × ⌈h/d⌉`, is still at least
/// [`SHRINK_MARGIN`] times that size; 1 for images under [`SHRINK_MIN_PIXELS`].
///
/// 1/8 is not used: on photos enlarged 4× (blocks of 8 pixels holding 2×2 of the photo's
/// own) it lost 0.5–1.0 dB, where 1/4 stayed within 0.25 dB (tests/photos.rs).
pub fn shrink_denominator(w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    if w.saturating_mul(h) < SHRINK_MIN_PIXELS {
        return 1;
    }
    let (mw, mh) = (
        min_w.saturating_mul(SHRINK_MARGIN),
        min_h.saturating_mul(SHRINK_MARGIN),
    );
    [4, 2]
        .into_iter()
        .find(|&d| w.div_ceil(d) >= mw && h.div_ceil(d) >= mh)
        .unwrap_or(1)
}

impl JpegSource {
    /// Opens the JPEG file at `path`, or `None` when libjpeg is not the decoder for it
    /// (CMYK, an EXIF orientation): the whole-image reader takes it then.
    pub fn open(name: &Path, path: &Path, opts: &ReadOptions) -> Result<Option<JpegSource>> {
        let mut file = std::fs::File::open(path).map_err(|e| Error::io(name, e))?;
        let len = file.metadata().map_err(|e| Error::io(name, e))?.len();
        let cap = crate::io::max_input_bytes(opts);
        if len > cap {
            // The whole-image reader gives the message for files over the cap.
            return Ok(None);
        }
        let mut data = Vec::with_capacity(len as usize + 1);
        (&mut file)
            .take(cap.saturating_add(1))
            .read_to_end(&mut data)
            .map_err(|e| Error::io(name, e))?;
        if data.len() as u64 > cap {
            return Ok(None);
        }
        let Some(jpeg) = Jpeg::open(name, data, opts)? else {
            return Ok(None);
        };
        let info = SourceInfo {
            width: jpeg.width,
            height: jpeg.height,
            color: if jpeg.gray {
                ColorKind::Gray
            } else {
                ColorKind::Rgb
            },
            bits: 8,
            dpi: jpeg.dpi,
        };
        Ok(Some(JpegSource {
            name: name.to_path_buf(),
            progressive_bytes: if jpeg.progressive {
                // Every DCT coefficient (2 bytes each; chroma is usually subsampled, so
                // this is an upper bound) until the last scan.
                jpeg.width * jpeg.height * jpeg.channels() * 2
            } else {
                0
            },
            channels: jpeg.channels(),
            jpeg: Some(jpeg),
            info,
            denom: 1,
            bands: None,
            rows_read: 0,
        }))
    }
}

impl RowSource for JpegSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn buffer_bytes(&self) -> usize {
        self.progressive_bytes
    }

    fn bytes_per_row(&self) -> usize {
        // The decoder's interleaved row and the bands decoded ahead.
        self.info.width * self.channels * (1 + AHEAD)
    }

    fn shrink_to(&mut self, min_w: usize, min_h: usize) -> bool {
        let Some(jpeg) = &self.jpeg else {
            return false;
        };
        let d = shrink_denominator(jpeg.width, jpeg.height, min_w, min_h);
        self.denom = d;
        (self.info.width, self.info.height) = jpeg.scaled_size(d);
        d > 1
    }

    fn decodes_whole_well(&self) -> bool {
        true
    }

    fn prefers_streaming(&self) -> bool {
        // Bands overlap decoding with halftoning, and keep memory small.
        true
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        let rows = rows.min(self.info.height - self.rows_read);
        if let Some(jpeg) = self.jpeg.take() {
            // Every band after this one has as many rows, but the last.
            let (tx, rx) = sync_channel(AHEAD);
            let (spare_tx, spare_rx) = sync_channel(AHEAD + 2);
            let denom = self.denom;
            std::thread::spawn(move || decode_bands(jpeg, rows.max(1), denom, tx, spare_rx));
            self.bands = Some((rx, spare_tx));
        }
        let (rx, spare) = self.bands.as_ref().expect("started above");
        if rows == 0 {
            band.height = 0;
            return Ok(());
        }
        let planes = rx
            .recv()
            .map_err(|_| crate::io::decode_err(&self.name, "the JPEG decoder stopped".into()))??;
        let w = self.info.width;
        debug_assert!(planes.iter().all(|p| p.len() == w * rows));
        band.width = w;
        band.height = rows;
        let old: BandPlanes = band
            .planes
            .iter_mut()
            .zip(planes)
            .map(|(p, new)| match std::mem::replace(p, Samples::U8(new)) {
                Samples::U8(v) => v,
                Samples::U16(_) => Vec::new(),
            })
            .collect();
        if old.iter().all(|v| v.capacity() > 0) {
            let _ = spare.try_send(old);
        }
        self.rows_read += rows;
        Ok(())
    }
}
