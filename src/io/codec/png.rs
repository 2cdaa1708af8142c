//! PNG writer (png crate): packed grey for bilevel and power-of-two level counts, indexed
//! colour for palettes, 8-bit grey or RGB otherwise.
//!
//! Grey samples are bit 1 = white, the same sense as the levels, so packed rows map
//! directly. With 2^b levels (4 or 16) the default is an indexed PNG at b bits whose
//! palette holds each level's sRGB grey: the same size, and the right tone in every viewer.
//! With `device_levels` the b-bit grey sample is the level and, because levels are evenly
//! spaced in light, the file says so with gAMA 1.0 (PNG spec §11.3.3.2); sBIT records the
//! depth. Other level counts (3, 5–15, 17+) do not divide the b-bit range
//! evenly, so they are written as 8-bit codes of their reflectance (sRGB-encoded, or evenly
//! spaced for a linear display).

use std::io::Write;
use std::sync::{Arc, Mutex};

use png::{BitDepth, ColorType, PixelDimensions, ScaledFloat, SrgbRenderingIntent, Unit};

use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::WriteOptions;
use crate::io::{dots_per_metre, level_codes8, row8_of, EncodeError, EncodeResult};
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
/// whose compressed rows fit in one chunk gets exactly the bytes of the png crate's
/// whole-image `write_image_data` with the same filter (one `IDAT`); a larger one gets the
/// same compressed stream cut into chunks of this size.
const IDAT_BYTES: usize = 1 << 20;

/// The zlib level of the png crate's default (`Compression::Balanced`). On a 24 MP 4-bit
/// palette halftone (filter None, zlib-rs) levels 5, 6 and 7 gave 4.52, 4.49 and 4.43 MB
/// in 0.16, 0.21 and 0.35 s of CPU; 6 is the knee.
const ZLIB_LEVEL: u32 = 6;

/// How rows are filtered before deflate (PNG spec §9, §12.8).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Filtering {
    /// Filter type None on every row: indexed colour and samples below 8 bits, as the PNG
    /// spec recommends (§12.8). The neighbours the filters subtract are other pixels' bits
    /// or unrelated palette indices, so filtering only breaks up the repeats deflate finds.
    /// On 24 MP halftones of a photo (zlib level 6) None gave 4.49 MB against adaptive's
    /// 5.47 MB (8-colour palette, 4 bits), 1.66 against 2.03 MB (bilevel), 2.30 against
    /// 2.61 MB (4 levels, 2 bits) and 6.93 against 11.06 MB (64 colours, 8 bits).
    None,
    /// Adaptive filtering, as the png crate's default: 8-bit grey and RGB, and 256 grey
    /// levels written as 8-bit indices of a grey palette (indices in tone order, so the
    /// filters predict them as they would grey samples: 14.09 MB adaptive, 17.82 MB None).
    Adaptive,
}

impl Filtering {
    /// The filtering of a PNG of `depth` bits a sample, `indexed` or not; `grey_ramp` when
    /// the indices are levels of grey in tone order.
    fn of(depth: BitDepth, indexed: bool, grey_ramp: bool) -> Filtering {
        if depth == BitDepth::Eight && (!indexed || grey_ramp) {
            Filtering::Adaptive
        } else {
            Filtering::None
        }
    }
}

/// Bytes on their way to the page's output: the png crate's writer (header, ancillary
/// chunks, `IEND`) owns its output for the whole page while rows arrive with an output of
/// their own, so each call passes on what is pending.
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

/// Writes one chunk: length, type, data, CRC of type and data (PNG spec §5.3).
fn write_chunk(out: &mut dyn Write, kind: &[u8], data: &[u8]) -> std::io::Result<()> {
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    out.write_all(&(data.len() as u32).to_be_bytes())?;
    out.write_all(kind)?;
    out.write_all(data)?;
    out.write_all(&crc.finalize().to_be_bytes())
}

/// PNG row filters, chosen per row as the png crate's default (`Filter::Adaptive`) does:
/// each of Up, Sub, Average and Paeth in that order, keeping the last with the smallest sum
/// of the filtered bytes read as signed (`<=`), stopping at a sum of zero (PNG spec §9;
/// png 0.18 `filter::adaptive_filter`). Written here because that function is private and
/// the whole-image call needs every row at once.
fn filter_row(bpp: usize, prev: &[u8], cur: &[u8], out: &mut [u8]) -> u8 {
    let cost = |b: &[u8]| -> u64 { b.iter().map(|&v| (v as i8).unsigned_abs() as u64).sum() };
    let (mut best, mut best_cost) = (0u8, u64::MAX);
    for kind in [2u8, 1, 3, 4] {
        apply_filter(kind, bpp, prev, cur, out);
        let c = cost(out);
        if c <= best_cost {
            best = kind;
            best_cost = c;
            if c == 0 {
                return best;
            }
        }
    }
    if best != 4 {
        apply_filter(best, bpp, prev, cur, out);
    }
    best
}

/// One PNG filter (1 Sub, 2 Up, 3 Average, 4 Paeth) of row `cur` over `prev`.
fn apply_filter(kind: u8, bpp: usize, prev: &[u8], cur: &[u8], out: &mut [u8]) {
    let n = cur.len();
    let left = |i: usize, row: &[u8]| if i >= bpp { row[i - bpp] } else { 0 };
    match kind {
        1 => {
            for i in 0..n {
                out[i] = cur[i].wrapping_sub(left(i, cur));
            }
        }
        2 => {
            for i in 0..n {
                out[i] = cur[i].wrapping_sub(prev[i]);
            }
        }
        3 => {
            for i in 0..n {
                let avg = ((left(i, cur) as u16 + prev[i] as u16) / 2) as u8;
                out[i] = cur[i].wrapping_sub(avg);
            }
        }
        _ => {
            for i in 0..n {
                let (a, b, c) = (left(i, cur) as i16, prev[i] as i16, left(i, prev) as i16);
                let p = a + b - c;
                let (pa, pb, pc) = ((p - a).abs(), (p - b).abs(), (p - c).abs());
                let pred = if pa <= pb && pa <= pc {
                    a
                } else if pb <= pc {
                    b
                } else {
                    c
                };
                out[i] = cur[i].wrapping_sub(pred as u8);
            }
        }
    }
}

/// How a page's rows become PNG rows.
enum RowKind {
    /// Packed rows as they are: palette indices, or grey levels at 2^bits levels.
    Packed,
    /// 8-bit codes through a table: one sample (grey) or three (RGB, palette colours).
    Codes8 { table: Box<[u8; 256]>, spp: usize },
}

/// The PNG encoder: header and ancillary chunks at the start of the page, rows compressed
/// as they arrive.
pub(in crate::io) struct PngEncoder {
    opts: WriteOptions,
    pending: Pending,
    page: Option<PngPage>,
    pages: usize,
}

struct PngPage {
    header: PageHeader,
    /// The png crate's writer: it has written the header and writes `IEND` at the end.
    writer: png::Writer<Pending>,
    /// The same output as `writer`'s.
    pending: Pending,
    kind: RowKind,
    filtering: Filtering,
    /// Bytes a pixel for the filters (1 below 8 bits a sample).
    bpp: usize,
    zlib: flate2::write::ZlibEncoder<Vec<u8>>,
    /// Compressed bytes not yet in a chunk.
    idat: Vec<u8>,
    /// The previous row and a filtered row (adaptive filtering only).
    prev: Vec<u8>,
    filtered: Vec<u8>,
    levels: Vec<u8>,
    row: Vec<u8>,
    done: usize,
}

impl PngPage {
    /// Writes full `IDAT` chunks of what is compressed (all of it when `last`).
    fn chunks(&mut self, last: bool) -> std::io::Result<()> {
        self.idat.append(self.zlib.get_mut());
        let mut pending = self.pending.clone();
        while self.idat.len() >= IDAT_BYTES {
            write_chunk(&mut pending, b"IDAT", &self.idat[..IDAT_BYTES])?;
            self.idat.drain(..IDAT_BYTES);
        }
        if last && !self.idat.is_empty() {
            write_chunk(&mut pending, b"IDAT", &self.idat)?;
            self.idat.clear();
        }
        Ok(())
    }
}

fn png_err(e: png::EncodingError) -> EncodeError {
    match e {
        png::EncodingError::IoError(e) => EncodeError::Io(e),
        e => EncodeError::Other(e.to_string()),
    }
}

impl PngEncoder {
    pub(in crate::io) fn new(opts: &WriteOptions) -> PngEncoder {
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
        crate::io::sink::one_page_only(&mut self.pages)?;
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
        let (writer, kind, filtering) = if let Some(pal) = &h.palette {
            // Indices at the halftone's own packing: rows map directly.
            enc.set_color(ColorType::Indexed);
            enc.set_depth(depth(h.bits));
            enc.set_palette(pal.iter().flatten().copied().collect::<Vec<u8>>());
            (
                enc.write_header().map_err(png_err)?,
                RowKind::Packed,
                Filtering::of(depth(h.bits), true, false),
            )
        } else if packed_grey && h.bits > 1 && !opts.device_levels && opts.display == Encoding::Srgb
        {
            // Display codes at the packed size: an indexed PNG whose palette holds each
            // level's sRGB grey, so viewers that ignore gAMA still show the right tone (a
            // 2-bit grey sample would be read as evenly spaced sRGB codes, far too dark).
            let table = level_codes8(h.levels, opts.display);
            enc.set_color(ColorType::Indexed);
            enc.set_depth(depth(h.bits));
            enc.set_palette(
                table[..h.levels as usize]
                    .iter()
                    .flat_map(|&c| [c, c, c])
                    .collect::<Vec<u8>>(),
            );
            enc.set_source_srgb(SrgbRenderingIntent::Perceptual);
            (
                enc.write_header().map_err(png_err)?,
                RowKind::Packed,
                Filtering::of(depth(h.bits), true, true),
            )
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
            (
                w,
                RowKind::Packed,
                Filtering::of(depth(h.bits), false, false),
            )
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
                RowKind::Codes8 {
                    table: Box::new(table),
                    spp,
                },
                Filtering::of(BitDepth::Eight, false, false),
            )
        };
        let (row_len, bpp) = match kind {
            RowKind::Packed => (h.stride, 1),
            RowKind::Codes8 { spp, .. } => (h.width * spp, spp),
        };
        let scratch = match filtering {
            Filtering::None => 0,
            Filtering::Adaptive => row_len,
        };
        self.page = Some(PngPage {
            header: h.clone(),
            writer,
            pending: self.pending.clone(),
            kind,
            filtering,
            bpp,
            zlib: flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(ZLIB_LEVEL)),
            idat: Vec::new(),
            prev: vec![0u8; scratch],
            filtered: vec![0u8; scratch],
            levels: vec![0u8; h.width],
            row: vec![0u8; row_len],
            done: 0,
        });
        self.pending.drain(out)
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        for r in 0..band.rows {
            let rows = band.row(r, stride);
            let data = encode_row(
                &p.header,
                &p.kind,
                &rows[..band.planes.len()],
                &mut p.levels,
                &mut p.row,
            );
            // Two writes a row, as the png crate makes them.
            match p.filtering {
                Filtering::None => {
                    p.zlib.write_all(&[0])?;
                    p.zlib.write_all(data)?;
                }
                Filtering::Adaptive => {
                    let kind = filter_row(p.bpp, &p.prev, data, &mut p.filtered);
                    p.zlib.write_all(&[kind])?;
                    p.zlib.write_all(&p.filtered)?;
                    p.prev.copy_from_slice(data);
                }
            }
        }
        p.done += band.rows;
        p.chunks(false)?;
        self.pending.drain(out)
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::take_complete_page(&mut self.page, |p| (p.done, p.header.height))?;
        let mut p = p;
        let rest = std::mem::take(p.zlib.get_mut());
        p.idat.extend_from_slice(&rest);
        let end = std::mem::replace(
            &mut p.zlib,
            flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::none()),
        )
        .finish()?;
        p.idat.extend_from_slice(&end);
        p.chunks(true)?;
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
