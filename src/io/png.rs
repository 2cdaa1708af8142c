//! PNG writer (png crate): packed grey for bilevel and power-of-two level counts, indexed
//! colour for palettes, 8-bit grey or RGB otherwise.
//!
//! Grey samples are bit 1 = white, the same sense as the levels, so packed rows map
//! directly. With 2^b levels (4 or 16) the b-bit sample is the level and, because levels
//! are evenly spaced in light, the file says so with gAMA 1.0 (PNG spec §11.3.3.2); sBIT
//! records the depth. Other level counts (3, 5–15, 17+) do not divide the b-bit range
//! evenly, so they are written as 8-bit codes of their reflectance (sRGB-encoded, or evenly
//! spaced for a linear display).

use std::io::Write;
use std::sync::{Arc, Mutex};

use png::{BitDepth, ColorType, PixelDimensions, ScaledFloat, SrgbRenderingIntent, Unit};

use super::sink::{Band, PageEncoder, PageHeader};
use super::WriteOptions;
use super::{dots_per_metre, level_codes8, row8_of, EncodeError, EncodeResult};
use crate::tone::Encoding;

/// PNG bit depth of a packed sample width.
fn depth(bits: u8) -> BitDepth {
    match bits {
        1 => BitDepth::One,
        2 => BitDepth::Two,
        4 => BitDepth::Four,
        _ => BitDepth::Eight,
    }
}

/// Bytes of compressed data a PNG `IDAT` chunk holds before the next one starts. A halftone
/// whose compressed rows fit in one chunk gets exactly the bytes of a whole-image
/// `write_image_data`; a larger one gets the same compressed stream in chunks of this size.
const IDAT_BYTES: usize = 1 << 20;

/// Compressed bytes on their way from the png crate's stream writer to the page's output:
/// the stream writer owns its writer for the whole page, while rows arrive with an output of
/// their own, so each call empties this buffer into that output.
#[derive(Clone, Default)]
struct Pending(Arc<Mutex<Vec<u8>>>);

impl Write for Pending {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("not poisoned").extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Pending {
    /// Moves what is pending to `out`.
    fn drain(&self, out: &mut dyn Write) -> EncodeResult {
        let mut v = self.0.lock().expect("not poisoned");
        out.write_all(&v)?;
        v.clear();
        Ok(())
    }
}

/// How a page's rows become PNG rows.
enum RowKind {
    /// Packed rows as they are: palette indices, or grey levels at 2^bits levels.
    Packed,
    /// 8-bit codes through a table: one sample (grey) or three (RGB, palette colours).
    Codes8 { table: [u8; 256], spp: usize },
}

/// The PNG encoder: header and ancillary chunks at the start of the page, rows compressed
/// as they arrive.
pub(super) struct PngEncoder {
    opts: WriteOptions,
    pending: Pending,
    page: Option<PngPage>,
    pages: usize,
}

struct PngPage {
    header: PageHeader,
    writer: png::StreamWriter<'static, Pending>,
    kind: RowKind,
    levels: Vec<u8>,
    row: Vec<u8>,
    done: usize,
}

fn png_err(e: png::EncodingError) -> EncodeError {
    match e {
        png::EncodingError::IoError(e) => EncodeError::Io(e),
        e => EncodeError::Other(e.to_string()),
    }
}

impl PngEncoder {
    pub(super) fn new(opts: &WriteOptions) -> PngEncoder {
        PngEncoder {
            opts: opts.clone(),
            pending: Pending::default(),
            page: None,
            pages: 0,
        }
    }
}

impl PageEncoder for PngEncoder {
    fn begin_page(&mut self, h: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if self.pages > 0 {
            return Err(EncodeError::Other(
                "this format holds one image; write each page to its own file".into(),
            ));
        }
        self.pages += 1;
        let opts = &self.opts;
        let mut enc = png::Encoder::new(self.pending.clone(), h.width as u32, h.height as u32);
        if let Some(dpi) = opts.dpi {
            let ppm = dots_per_metre(dpi);
            enc.set_pixel_dims(Some(PixelDimensions {
                xppu: ppm,
                yppu: ppm,
                unit: Unit::Meter,
            }));
        }
        let grey = h.channels == 1 && h.palette.is_none();
        let packed_grey = grey && h.levels == 1u16 << h.bits;
        let (writer, kind) = if let Some(pal) = &h.palette {
            // Indices at the halftone's own packing: rows map directly.
            enc.set_color(ColorType::Indexed);
            enc.set_depth(depth(h.bits));
            enc.set_palette(pal.iter().flatten().copied().collect::<Vec<u8>>());
            (enc.write_header().map_err(png_err)?, RowKind::Packed)
        } else if packed_grey {
            enc.set_color(ColorType::Grayscale);
            enc.set_depth(depth(h.bits));
            if h.bits > 1 && opts.display == Encoding::Srgb {
                enc.set_source_gamma(ScaledFloat::new(1.0));
            }
            let mut w = enc.write_header().map_err(png_err)?;
            if h.bits > 1 {
                w.write_chunk(png::chunk::sBIT, &[h.bits])
                    .map_err(png_err)?;
            }
            (w, RowKind::Packed)
        } else {
            let spp = if grey { 1 } else { 3 };
            enc.set_color(if spp == 1 {
                ColorType::Grayscale
            } else {
                ColorType::Rgb
            });
            enc.set_depth(BitDepth::Eight);
            if opts.display == Encoding::Srgb {
                enc.set_source_srgb(SrgbRenderingIntent::Perceptual);
            }
            let table = level_codes8(h.levels, opts.display);
            (
                enc.write_header().map_err(png_err)?,
                RowKind::Codes8 { table, spp },
            )
        };
        let writer = writer
            .into_stream_writer_with_size(IDAT_BYTES)
            .map_err(png_err)?;
        let row_len = match kind {
            RowKind::Packed => h.stride,
            RowKind::Codes8 { spp, .. } => h.width * spp,
        };
        self.page = Some(PngPage {
            header: h.clone(),
            writer,
            kind,
            levels: vec![0u8; h.width],
            row: vec![0u8; row_len],
            done: 0,
        });
        self.pending.drain(out)
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let p = self
            .page
            .as_mut()
            .ok_or_else(|| EncodeError::Other("rows before a page".into()))?;
        let stride = p.header.stride;
        for r in 0..band.rows {
            let mut rows: [&[u8]; 3] = [&[]; 3];
            for (row, pl) in rows.iter_mut().zip(band.planes) {
                *row = &pl[r * stride..(r + 1) * stride];
            }
            let data = encode_row(
                &p.header,
                &p.kind,
                &rows[..band.planes.len()],
                &mut p.levels,
                &mut p.row,
            );
            p.writer.write_all(data)?;
        }
        p.done += band.rows;
        self.pending.drain(out)
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let p = self
            .page
            .take()
            .ok_or_else(|| EncodeError::Other("end of a page never begun".into()))?;
        if p.done != p.header.height {
            return Err(EncodeError::Other(format!(
                "page of {} rows ended after {}",
                p.header.height, p.done
            )));
        }
        p.writer.finish().map_err(png_err)?;
        self.pending.drain(out)
    }
}

/// One PNG row (before filtering) from the packed rows of the planes; `levels` and `row`
/// are scratch.
fn encode_row<'a>(
    header: &PageHeader,
    kind: &RowKind,
    rows: &[&'a [u8]],
    levels: &mut [u8],
    row: &'a mut [u8],
) -> &'a [u8] {
    match kind {
        RowKind::Packed => rows[0],
        RowKind::Codes8 { table, .. } => {
            row8_of(header, rows, table, levels, row);
            row
        }
    }
}
