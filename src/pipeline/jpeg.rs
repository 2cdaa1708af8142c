//! JPEG as a streaming source, through libjpeg-turbo ([`crate::io::jpeg`]): rows as the
//! decoder makes them (by MCU rows inside libjpeg), and shrink-on-load by DCT scaling when
//! the output is much smaller than the image ([`shrink_denominator`]).

use std::io::Read;
use std::path::Path;

use super::source::{RowSource, SourceInfo};
use crate::error::{Error, Result};
use crate::io::jpeg::Jpeg;
use crate::io::ReadOptions;
use crate::raster::{ColorKind, Image, Samples};

/// A JPEG file decoded row by row.
pub struct JpegSource {
    jpeg: Jpeg,
    info: SourceInfo,
    /// Decode at 1/`denom` (1, 2, 4 or 8).
    denom: usize,
    started: bool,
    /// Interleaved rows of a band.
    buf: Vec<u8>,
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
            jpeg,
            info,
            denom: 1,
            started: false,
            buf: Vec::new(),
        }))
    }
}

impl RowSource for JpegSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn buffer_bytes(&self) -> usize {
        // A progressive file keeps every DCT coefficient (2 bytes each; chroma is usually
        // subsampled, so this is an upper bound) until its last scan.
        if self.jpeg.progressive {
            self.jpeg.width * self.jpeg.height * self.jpeg.channels() * 2
        } else {
            0
        }
    }

    fn bytes_per_row(&self) -> usize {
        self.info.width * self.jpeg.channels()
    }

    fn shrink_to(&mut self, min_w: usize, min_h: usize) -> bool {
        if self.started {
            return false;
        }
        let d = shrink_denominator(self.jpeg.width, self.jpeg.height, min_w, min_h);
        self.denom = d;
        (self.info.width, self.info.height) = self.jpeg.scaled_size(d);
        d > 1
    }

    fn decodes_whole_well(&self) -> bool {
        true
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        if !self.started {
            let size = self.jpeg.start(self.denom)?;
            debug_assert_eq!(size, (self.info.width, self.info.height));
            self.started = true;
        }
        let rows = self.jpeg.read_rows(rows, &mut self.buf)?;
        let w = self.info.width;
        band.width = w;
        band.height = rows;
        let n = w * rows;
        let ch = self.jpeg.channels();
        for (c, p) in band.planes.iter_mut().enumerate() {
            let Samples::U8(plane) = p else {
                unreachable!("8-bit planes for JPEG")
            };
            plane.resize(n, 0);
            if ch == 1 {
                plane.copy_from_slice(&self.buf[..n]);
            } else {
                for (o, px) in plane.iter_mut().zip(self.buf.chunks_exact(ch)) {
                    *o = px[c];
                }
            }
        }
        Ok(())
    }
}
