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
use crate::tone::{Encoding, ToneOptions, ToneTable};

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
    /// Luminance in place of RGB, when the job is grey: `linearize`, then its tables.
    luma: Option<bool>,
    luma_tables: Option<Luma>,
    /// The bands' encoding.
    encoding: Encoding,
    /// Bands from the decoding thread, and their buffers sent back to be filled again.
    bands: Option<(Receiver<Result<BandPlanes>>, SyncSender<BandPlanes>)>,
    rows_read: usize,
}

/// The planes of one band.
type BandPlanes = Vec<Samples>;

/// Bands decoded ahead of the one being halftoned.
const AHEAD: usize = 1;

/// Linear-light luminance of 8-bit sRGB codes, exactly as [`Image::to_luminance`] makes
/// it: the weighted channels are read from tables of the same `f32` products, added in the
/// same order, clamped, scaled and rounded half up the same way.
pub struct Luma {
    weighted: [[f32; 256]; 3],
}

impl Luma {
    /// The tables for `linearize` (`--no-linearize` weights the codes themselves).
    pub fn new(linearize: bool) -> Luma {
        let plain = ToneOptions {
            linearize,
            ..ToneOptions::default()
        };
        let table = ToneTable::new(8, Encoding::Srgb, &plain);
        let t = table.as_slice();
        let mut weighted = [[0.0; 256]; 3];
        for (w, k) in weighted.iter_mut().zip([0.2126f32, 0.7152, 0.0722]) {
            for (o, &v) in w.iter_mut().zip(t) {
                *o = k * v;
            }
        }
        Luma { weighted }
    }

    /// Interleaved RGB codes to 16-bit luminance codes.
    pub fn convert(&self, rgb: &[u8], out: &mut [u16]) {
        let [wr, wg, wb] = &self.weighted;
        for (o, px) in out.iter_mut().zip(rgb.chunks_exact(3)) {
            let l = wr[px[0] as usize] + wg[px[1] as usize] + wb[px[2] as usize];
            let x = l.clamp(0.0, 1.0) * 65535.0;
            let t = x as u16;
            *o = t + (x - t as f32 >= 0.5) as u16;
        }
    }
}

/// The decoding thread: bands of `rows` rows (the last one shorter), split into planes, or
/// left interleaved (`luma`) for the caller to make luminance of.
fn decode_bands(
    mut jpeg: Jpeg,
    rows: usize,
    denom: usize,
    luma: bool,
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
            let mut planes = spare.try_recv().unwrap_or_default();
            if ch == 1 {
                let mut p = match planes.pop() {
                    Some(Samples::U8(v)) => v,
                    _ => Vec::new(),
                };
                jpeg.read_rows(n, &mut p)?;
                planes = vec![Samples::U8(p)];
            } else if luma {
                // Interleaved, as libjpeg gives them: the caller makes the luminance
                // (the decoder's thread has the larger share of the work already).
                let mut p = match planes.pop() {
                    Some(Samples::U8(v)) => v,
                    _ => Vec::new(),
                };
                jpeg.read_rows(n, &mut p)?;
                planes = vec![Samples::U8(p)];
            } else {
                jpeg.read_rows(n, &mut buf)?;
                let mut p: Vec<Vec<u8>> = planes
                    .into_iter()
                    .map(|s| match s {
                        Samples::U8(v) => v,
                        Samples::U16(_) => Vec::new(),
                    })
                    .collect();
                p.resize(3, Vec::new());
                split(&buf, w * n, &mut p);
                planes = p.into_iter().map(Samples::U8).collect();
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
        p.resize(n, 0);
    }
    for (i, px) in rgb[..n * 3].chunks_exact(3).enumerate() {
        r[i] = px[0];
        g[i] = px[1];
        b[i] = px[2];
    }
}

// One rule for every format: the threshold and the margin are the box shrink's (see there
// for why small images are decoded whole).
pub use super::shrink::{SHRINK_MARGIN, SHRINK_MIN_PIXELS};

/// The DCT-scaling denominator (4, 2, else 1) for an image of `w × h` to be resized to
/// `min_w × min_h`: the largest whose output, `⌈w/d⌉ × ⌈h/d⌉`, is still at least
/// [`SHRINK_MARGIN`] times that size; 1 for images under [`SHRINK_MIN_PIXELS`].
///
/// 1/8 is not used: on photos enlarged 4× (blocks of 8 pixels holding 2×2 of the photo's
/// own) it lost 0.5–1.0 dB, where 1/4 stayed within 0.25 dB (tests/photos.rs).
pub fn shrink_denominator(w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    super::shrink::largest_shrink(&[4, 2], w, h, min_w, min_h)
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
            luma: None,
            luma_tables: None,
            encoding: Encoding::Srgb,
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

    fn shrink_to(&mut self, min_w: usize, min_h: usize) -> usize {
        let Some(jpeg) = &self.jpeg else {
            return 1;
        };
        let d = shrink_denominator(jpeg.width, jpeg.height, min_w, min_h);
        self.denom = d;
        (self.info.width, self.info.height) = jpeg.scaled_size(d);
        d
    }

    fn decodes_whole_well(&self) -> bool {
        true
    }

    fn to_luminance(&mut self, tone: &ToneOptions) -> bool {
        if self.jpeg.is_none() || self.info.color != ColorKind::Rgb {
            return false;
        }
        self.luma = Some(tone.linearize);
        self.info.color = ColorKind::Gray;
        self.info.bits = 16;
        if tone.linearize {
            self.encoding = Encoding::Linear;
        }
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
            self.luma_tables = self.luma.map(Luma::new);
            let luma = self.luma.is_some();
            std::thread::spawn(move || decode_bands(jpeg, rows.max(1), denom, luma, tx, spare_rx));
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
        band.width = w;
        band.height = rows;
        band.color = self.info.color;
        band.encoding = self.encoding;
        if let Some(luma) = &self.luma_tables {
            let Some(Samples::U8(rgb)) = planes.first() else {
                unreachable!("interleaved RGB for luminance")
            };
            debug_assert_eq!(rgb.len(), w * rows * 3);
            band.planes.resize(1, Samples::U16(Vec::new()));
            if !matches!(band.planes[0], Samples::U16(_)) {
                band.planes[0] = Samples::U16(Vec::new());
            }
            let Samples::U16(y) = &mut band.planes[0] else {
                unreachable!("set above")
            };
            y.resize(w * rows, 0);
            luma.convert(rgb, y);
            let _ = spare.try_send(planes);
            self.rows_read += rows;
            return Ok(());
        }
        debug_assert!(planes.iter().all(|p| p.len() == w * rows));
        let old = std::mem::replace(&mut band.planes, planes);
        if old.iter().all(|p| !p.is_empty()) {
            let _ = spare.try_send(old);
        }
        self.rows_read += rows;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn luminance_is_that_of_the_image() {
        // Every code in every channel, and pseudo-random colours.
        let mut rgb: Vec<u8> = (0..=255u8)
            .flat_map(|c| [c, c, c, c, 0, 0, 0, c, 0, 0, 0, c])
            .collect();
        let mut s = 12345u32;
        for _ in 0..30000 {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            rgb.push((s >> 16) as u8);
        }
        let n = rgb.len() / 3;
        let img = Image::rgb8(n, 1, &rgb[..n * 3]);
        for linearize in [true, false] {
            let tone = ToneOptions {
                linearize,
                ..ToneOptions::default()
            };
            let reference = img.to_luminance(&tone);
            let mut ours = vec![0u16; n];
            Luma::new(linearize).convert(&rgb[..n * 3], &mut ours);
            assert_eq!(
                reference.planes[0],
                Samples::U16(ours),
                "linearize {linearize}"
            );
            let encoding = if linearize {
                Encoding::Linear
            } else {
                Encoding::Srgb
            };
            assert_eq!(reference.encoding, encoding);
        }
    }
}
