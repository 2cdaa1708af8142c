//! JPEG as a streaming source, through libjpeg-turbo ([`crate::io::jpeg`]): rows as the
//! decoder makes them (by MCU rows inside libjpeg), and shrink-on-load by DCT scaling when
//! the output is much smaller than the image.

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

/// The largest DCT-scaling denominator (8, 4, 2, else 1) whose output, `⌈w/d⌉ × ⌈h/d⌉`, is
/// still at least `min_w × min_h`: the Lanczos step after it then only shrinks.
pub fn shrink_denominator(w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    [8, 4, 2]
        .into_iter()
        .find(|&d| w.div_ceil(d) >= min_w && h.div_ceil(d) >= min_h)
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
