//! Netpbm: a fast reader for binary greymaps and bitmaps (P5, P4), and the PBM/PGM/PPM
//! writers.
//!
//! The reader exists for speed: a P5 file is a short text header followed by the codes
//! themselves, so decoding is one read into a plane of exact size. Everything else (P1–P3,
//! P6, P7) goes through the `image` crate. Format reference: the Netpbm manual pages
//! pgm(5), pbm(5), ppm(5).

use std::io::{Read, Write};

use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{level_code, EncodeError, EncodeResult, Format, WriteOptions};
use crate::raster::{unpack_row, Samples};

/// The kinds of file the fast path reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PnmKind {
    /// P4: packed bits, 1 = black.
    Bitmap,
    /// P5: 8- or 16-bit (big-endian) grey codes.
    Greymap,
}

/// A parsed P4/P5 header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PnmHeader {
    /// P4 or P5.
    pub kind: PnmKind,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Largest code (1 for P4).
    pub maxval: u32,
    /// Offset of the first byte of pixel data.
    pub data_offset: usize,
}

/// The outcome of [`parse_header`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HeaderParse {
    /// Not a P4 or P5 file: another decoder's business.
    NotFastPath,
    /// The header runs past the bytes given: try again with more.
    Incomplete,
    /// A P4/P5 header that is wrong, and why.
    Bad(String),
    /// A complete header.
    Ok(PnmHeader),
}

/// True for the whitespace the Netpbm manual allows between header fields.
fn is_space(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
}

/// Parses a P4 or P5 header at the start of `bytes` (comments from `#` to the end of the
/// line are allowed between fields).
pub fn parse_header(bytes: &[u8]) -> HeaderParse {
    let kind = match bytes {
        [b'P', b'4', ..] => PnmKind::Bitmap,
        [b'P', b'5', ..] => PnmKind::Greymap,
        _ => return HeaderParse::NotFastPath,
    };
    let mut pos = 2;
    let fields = if kind == PnmKind::Bitmap { 2 } else { 3 };
    let mut values = [0u32; 3];
    for (i, value) in values.iter_mut().take(fields).enumerate() {
        // Whitespace and comments before the field; at least one separator.
        let start = pos;
        loop {
            match bytes.get(pos) {
                None => return HeaderParse::Incomplete,
                Some(&b) if is_space(b) => pos += 1,
                Some(b'#') => match bytes[pos..].iter().position(|&b| b == b'\n' || b == b'\r') {
                    Some(end) => pos += end,
                    None => return HeaderParse::Incomplete,
                },
                Some(_) => break,
            }
        }
        if pos == start {
            return HeaderParse::Bad("bad header: no space before a number".into());
        }
        let digits = bytes[pos..]
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .count();
        if digits == 0 {
            return HeaderParse::Bad(format!(
                "bad header: expected the {} as a number",
                ["width", "height", "maxval"][i]
            ));
        }
        if pos + digits >= bytes.len() {
            return HeaderParse::Incomplete;
        }
        let mut v: u64 = 0;
        for &d in &bytes[pos..pos + digits] {
            v = v * 10 + (d - b'0') as u64;
            if v > u32::MAX as u64 {
                return HeaderParse::Bad("bad header: number too large".into());
            }
        }
        *value = v as u32;
        pos += digits;
    }
    // Exactly one whitespace byte separates the header from the data.
    match bytes.get(pos) {
        None => return HeaderParse::Incomplete,
        Some(&b) if is_space(b) => pos += 1,
        Some(_) => return HeaderParse::Bad("bad header: no space after the last field".into()),
    }
    let (width, height) = (values[0], values[1]);
    let maxval = if kind == PnmKind::Bitmap {
        1
    } else {
        values[2]
    };
    if width == 0 || height == 0 {
        return HeaderParse::Bad(format!("image is {width}x{height}: no pixels"));
    }
    if maxval == 0 || maxval > 65535 {
        return HeaderParse::Bad(format!("maxval {maxval}: must be 1 to 65535"));
    }
    HeaderParse::Ok(PnmHeader {
        kind,
        width,
        height,
        maxval,
        data_offset: pos,
    })
}

/// Reads the pixel data of a parsed header from `data` (positioned at its first byte) into
/// one plane: 8-bit codes for maxval ≤ 255, 16-bit otherwise, rescaled to full range when
/// maxval is not 255 or 65535 (as `image` does: `round(v × 255/maxval)`, in `f32`, so both
/// decoders give the same codes). P4 becomes 8-bit codes 0 (black) and 255 (white).
pub fn read_data(h: &PnmHeader, data: &mut dyn Read) -> Result<Samples, String> {
    let n = h.width as usize * h.height as usize;
    let truncated = |e: std::io::Error, bytes: usize| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            truncated_message(h, bytes)
        } else {
            e.to_string()
        }
    };
    match h.kind {
        PnmKind::Bitmap => {
            let row_bytes = (h.width as usize).div_ceil(8);
            let mut packed = vec![0u8; row_bytes * h.height as usize];
            data.read_exact(&mut packed)
                .map_err(|e| truncated(e, packed.len()))?;
            // Each packed byte becomes 8 codes: bit 1 (ink) → 0, bit 0 (paper) → 255.
            let mut expand = [[0u8; 8]; 256];
            for (b, e) in expand.iter_mut().enumerate() {
                for (i, c) in e.iter_mut().enumerate() {
                    *c = if b & (0x80 >> i) != 0 { 0 } else { 255 };
                }
            }
            let w = h.width as usize;
            let mut out = vec![0u8; n];
            for (row, src) in out.chunks_exact_mut(w).zip(packed.chunks_exact(row_bytes)) {
                let mut chunks = row.chunks_exact_mut(8);
                for (o, &b) in (&mut chunks).zip(src) {
                    o.copy_from_slice(&expand[b as usize]);
                }
                let rest = chunks.into_remainder();
                if !rest.is_empty() {
                    let b = src[row_bytes - 1];
                    rest.copy_from_slice(&expand[b as usize][..rest.len()]);
                }
            }
            Ok(Samples::U8(out))
        }
        PnmKind::Greymap if h.maxval <= 255 => {
            let mut out = vec![0u8; n];
            data.read_exact(&mut out).map_err(|e| truncated(e, n))?;
            rescale8(&mut out, h.maxval);
            Ok(Samples::U8(out))
        }
        PnmKind::Greymap => {
            let mut out = vec![0u16; n];
            let table: Option<Vec<u16>> = (h.maxval != 65535).then(|| {
                let factor = 65535.0f32 / h.maxval as f32;
                (0..=65535u32)
                    .map(|v| (v as f32 * factor).round() as u16)
                    .collect()
            });
            // Big-endian bytes through a small buffer: no second full-size copy.
            let mut buf = vec![0u8; 1 << 16];
            for chunk in out.chunks_mut(buf.len() / 2) {
                let bytes = &mut buf[..chunk.len() * 2];
                data.read_exact(bytes).map_err(|e| truncated(e, n * 2))?;
                for (o, b) in chunk.iter_mut().zip(bytes.chunks_exact(2)) {
                    *o = u16::from_be_bytes([b[0], b[1]]);
                }
                if let Some(t) = &table {
                    for o in chunk.iter_mut() {
                        *o = t[*o as usize];
                    }
                }
            }
            Ok(Samples::U16(out))
        }
    }
}

/// Rescales 8-bit codes of a greymap with `maxval` < 255 to full range, as [`read_data`] does.
pub fn rescale8(codes: &mut [u8], maxval: u32) {
    if maxval == 255 {
        return;
    }
    let factor = 255.0f32 / maxval as f32;
    let mut table = [0u8; 256];
    for (v, t) in table.iter_mut().enumerate() {
        *t = (v as f32 * factor).round() as u8;
    }
    for v in codes.iter_mut() {
        *v = table[*v as usize];
    }
}

/// The message for pixel data that ends early.
pub fn truncated_message(h: &PnmHeader, bytes: usize) -> String {
    format!(
        "truncated: {}x{} needs {bytes} bytes of pixel data",
        h.width, h.height
    )
}

/// The fields of a PAM (P7) header that fix its size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PamHeader {
    /// WIDTH.
    pub width: u32,
    /// HEIGHT.
    pub height: u32,
    /// DEPTH: samples a pixel.
    pub depth: u32,
    /// MAXVAL.
    pub maxval: u32,
    /// Offset of the first byte of pixel data (after `ENDHDR` and its newline).
    pub data_offset: usize,
}

/// The error for a PAM header with DEPTH 0 (its pixels have no samples).
pub const PAM_DEPTH_0: &str = "bad PAM header: DEPTH 0, no samples a pixel (1 for grey, 2 for \
                               grey with alpha, 3 for RGB, 4 for RGB with alpha)";

/// Parses a PAM header (Netpbm manual, pam: `P7`, then lines of `KEYWORD value` and
/// comments up to `ENDHDR`). `Ok(None)` when the header runs past the bytes given; an
/// error names the field that is missing or wrong.
pub fn parse_pam(bytes: &[u8]) -> Result<Option<PamHeader>, String> {
    let mut fields = [None::<u64>; 4];
    const NAMES: [&str; 4] = ["WIDTH", "HEIGHT", "DEPTH", "MAXVAL"];
    let mut pos = 0;
    let mut first = true;
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Ok(None);
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + len]);
        pos += len + 1;
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or("");
        if first {
            if key != "P7" {
                return Err("bad PAM header: it must start with a line P7".into());
            }
            first = false;
            continue;
        }
        if key == "ENDHDR" {
            break;
        }
        if let Some(i) = NAMES.iter().position(|&n| n == key) {
            let v = words
                .next()
                .and_then(|w| w.parse::<u64>().ok())
                .filter(|&v| v <= u32::MAX as u64)
                .ok_or_else(|| format!("bad PAM header: {key} needs a number"))?;
            fields[i] = Some(v);
        }
    }
    let mut v = [0u32; 4];
    for (i, f) in fields.iter().enumerate() {
        v[i] = f.ok_or_else(|| format!("bad PAM header: no {} line", NAMES[i]))? as u32;
    }
    let [width, height, depth, maxval] = v;
    if width == 0 || height == 0 {
        return Err(format!("image is {width}x{height}: no pixels"));
    }
    if maxval == 0 || maxval > 65535 {
        return Err(format!(
            "bad PAM header: MAXVAL {maxval}, must be 1 to 65535"
        ));
    }
    Ok(Some(PamHeader {
        width,
        height,
        depth,
        maxval,
        data_offset: pos,
    }))
}

/// The PBM (P4), PGM (P5) and PPM (P6) encoder, per `opts.format`: the header at the start
/// of the page, then each row as it arrives.
pub(in crate::io) struct PnmEncoder {
    opts: WriteOptions,
    page: Option<PnmPage>,
    pages: usize,
}

/// A page being written.
struct PnmPage {
    header: PageHeader,
    /// The value of every level (per component, for palettes).
    table: Vec<[u16; 3]>,
    /// Samples a pixel in the file: 1 (PBM, PGM) or 3 (PPM).
    channels_out: usize,
    /// Bytes a sample: 1, or 2 for maxval above 255.
    bytes_per: usize,
    /// Scratch: one level a pixel.
    levels: Vec<u8>,
    /// One file row.
    row: Vec<u8>,
    /// Rows written so far.
    done: usize,
    /// Bilevel 8-bit output: the samples of each packed byte, per component.
    bilevel_codes: Option<Box<[[[u8; 8]; 256]; 3]>>,
    /// Bilevel 8-bit PPM: the samples of four pixels for each three nibbles (4096 entries).
    bilevel_quads: Option<Box<[[u8; 12]]>>,
}

impl PnmEncoder {
    pub(in crate::io) fn new(opts: &WriteOptions) -> PnmEncoder {
        PnmEncoder {
            opts: opts.clone(),
            page: None,
            pages: 0,
        }
    }
}

impl PageEncoder for PnmEncoder {
    fn begin_page(&mut self, h: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        crate::io::sink::one_page_only(&mut self.pages)?;
        let (w, ht) = (h.width, h.height);
        let opts = &self.opts;
        if opts.format == Format::Pbm {
            write!(out, "P4\n{w} {ht}\n")?;
            self.page = Some(PnmPage {
                header: h.clone(),
                table: Vec::new(),
                channels_out: 1,
                bytes_per: 1,
                levels: Vec::new(),
                row: vec![0u8; h.stride],
                done: 0,
                bilevel_codes: None,
                bilevel_quads: None,
            });
            return Ok(());
        }
        let channels_out = if opts.format == Format::Pgm { 1 } else { 3 };
        let grey = h.channels == 1 && h.palette.is_none();
        if channels_out == 1 && !grey {
            return Err(EncodeError::Other("PGM holds grey only".into()));
        }
        // Value of every level: its reflectance encoded to maxval (255 unless asked: display
        // codes any viewer shows at the right tone), or the level itself with
        // `device_levels` and no maxval (the device's own levels).
        let (maxval, table): (u32, Vec<[u16; 3]>) = match &h.palette {
            Some(pal) => (
                255,
                pal.iter()
                    .map(|c| [c[0] as u16, c[1] as u16, c[2] as u16])
                    .collect(),
            ),
            None => match opts.maxval.or((!opts.device_levels).then_some(255)) {
                None => (h.levels as u32 - 1, (0..h.levels).map(|k| [k; 3]).collect()),
                Some(m) => (
                    m as u32,
                    (0..h.levels)
                        .map(|k| [level_code(k as u8, h.levels, m as u32, opts.display) as u16; 3])
                        .collect(),
                ),
            },
        };
        let magic = if channels_out == 1 { "P5" } else { "P6" };
        write!(out, "{magic}\n{w} {ht}\n{maxval}\n")?;
        let bytes_per = if maxval > 255 { 2 } else { 1 };
        self.page = Some(PnmPage {
            header: h.clone(),
            table,
            channels_out,
            bytes_per,
            levels: vec![0u8; w],
            row: vec![0u8; w * channels_out * bytes_per],
            done: 0,
            bilevel_codes: None,
            bilevel_quads: None,
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        for r in 0..band.rows {
            let rows = band.row(r, stride);
            if self.opts.format == Format::Pbm {
                crate::io::invert_bilevel_row(rows[0], p.header.width, &mut p.row);
            } else {
                p.encode_row(&rows);
            }
            out.write_all(&p.row)?;
        }
        p.done += band.rows;
        Ok(())
    }

    fn end_page(&mut self, _out: &mut dyn Write) -> EncodeResult {
        crate::io::sink::take_complete_page(&mut self.page, |p| (p.done, p.header.height))?;
        Ok(())
    }
}

impl PnmPage {
    /// [`PnmPage::encode_row`] for 1-bit planes and 8-bit samples (a bilevel RGB or grey
    /// halftone in a PPM or PGM): a packed byte's eight pixels at once through a table of
    /// their eight codes, per output component, instead of a level a pixel.
    fn encode_bilevel_row(&mut self, rows: &[&[u8]]) {
        let (channels_out, width) = (self.channels_out, self.header.width);
        let planes = self.header.channels;
        // codes[c][b]: the eight samples of component c for the packed byte b (made once a
        // page).
        let codes = self.bilevel_codes.get_or_insert_with(|| {
            let mut codes = Box::new([[[0u8; 8]; 256]; 3]);
            for (c, table) in codes.iter_mut().enumerate().take(channels_out) {
                let comp = if self.header.palette.is_some() { c } else { 0 };
                let (off, on) = (self.table[0][comp] as u8, self.table[1][comp] as u8);
                for (b, out) in table.iter_mut().enumerate() {
                    for (i, o) in out.iter_mut().enumerate() {
                        *o = if b & (0x80 >> i) != 0 { on } else { off };
                    }
                }
            }
            codes
        });
        let plane_of = |c: usize| if planes == 3 { c } else { 0 };
        let whole = width / 8;
        if channels_out == 3 {
            // quads[n]: the twelve samples of four pixels whose red, green and blue bits are
            // the nibbles of `n` (red highest), so a packed byte of each plane makes its 24
            // bytes in two copies.
            let quads = self.bilevel_quads.get_or_insert_with(|| {
                let mut quads = vec![[0u8; 12]; 4096].into_boxed_slice();
                for (n, q) in quads.iter_mut().enumerate() {
                    let nib = |c: usize| &codes[c][((n >> (8 - 4 * c)) & 15) << 4][..4];
                    let (cr, cg, cb) = (nib(0), nib(1), nib(2));
                    for i in 0..4 {
                        q[3 * i..3 * i + 3].copy_from_slice(&[cr[i], cg[i], cb[i]]);
                    }
                }
                quads
            });
            let (r, g, b) = (rows[plane_of(0)], rows[plane_of(1)], rows[plane_of(2)]);
            let (r, g, b) = (&r[..whole], &g[..whole], &b[..whole]);
            for (k, out) in self.row[..whole * 24].chunks_exact_mut(24).enumerate() {
                let (r, g, b) = (r[k] as usize, g[k] as usize, b[k] as usize);
                let hi = (r >> 4) << 8 | (g >> 4) << 4 | b >> 4;
                let lo = (r & 15) << 8 | (g & 15) << 4 | (b & 15);
                out[..12].copy_from_slice(&quads[hi]);
                out[12..].copy_from_slice(&quads[lo]);
            }
        } else {
            let g = rows[plane_of(0)];
            for (k, out) in self.row[..whole * 8].chunks_exact_mut(8).enumerate() {
                out.copy_from_slice(&codes[0][g[k] as usize]);
            }
        }
        // The last, partial byte.
        for x in whole * 8..width {
            for c in 0..channels_out {
                let byte = rows[plane_of(c)][x / 8];
                self.row[x * channels_out + c] = codes[c][byte as usize][x % 8];
            }
        }
    }

    /// One PGM/PPM row from the packed rows of the planes.
    fn encode_row(&mut self, rows: &[&[u8]]) {
        let (channels_out, bits) = (self.channels_out, self.header.bits);
        let planes = self.header.channels;
        if bits == 1 && self.bytes_per == 1 {
            return self.encode_bilevel_row(rows);
        }
        for c in 0..channels_out {
            // A grey halftone in a PPM repeats its one plane; a palette reads plane 0 and
            // takes colour component c.
            let plane = if planes == 3 { c } else { 0 };
            let comp = if self.header.palette.is_some() { c } else { 0 };
            unpack_row(rows[plane], bits, &mut self.levels);
            if self.bytes_per == 1 {
                for (o, &l) in self
                    .row
                    .iter_mut()
                    .skip(c)
                    .step_by(channels_out)
                    .zip(self.levels.iter())
                {
                    *o = self.table[l as usize][comp] as u8;
                }
            } else {
                for (o, &l) in self
                    .row
                    .chunks_exact_mut(2)
                    .skip(c)
                    .step_by(channels_out)
                    .zip(self.levels.iter())
                {
                    o.copy_from_slice(&self.table[l as usize][comp].to_be_bytes());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_with_comments() {
        let h = parse_header(b"P5\n# made by hand\n3 # width\n2\n255\nabcdef");
        let HeaderParse::Ok(h) = h else {
            panic!("{h:?}")
        };
        assert_eq!((h.width, h.height, h.maxval), (3, 2, 255));
        assert_eq!(h.data_offset, 34);
    }

    #[test]
    fn header_failures() {
        assert_eq!(parse_header(b"P6\n1 1\n255\n"), HeaderParse::NotFastPath);
        assert_eq!(parse_header(b"P5\n1 1\n25"), HeaderParse::Incomplete);
        assert!(matches!(
            parse_header(b"P5\n1 x\n255\n"),
            HeaderParse::Bad(_)
        ));
        assert!(matches!(parse_header(b"P5\n1 1\n0\n"), HeaderParse::Bad(_)));
        assert!(matches!(
            parse_header(b"P5\n1 1\n65536\n"),
            HeaderParse::Bad(_)
        ));
        assert!(matches!(
            parse_header(b"P5\n0 1\n255\n"),
            HeaderParse::Bad(_)
        ));
        assert!(matches!(
            parse_header(b"P5\n99999999999 1\n255\n"),
            HeaderParse::Bad(_)
        ));
    }

    #[test]
    fn bitmap_expands_with_odd_width() {
        let data = b"P4\n9 2\n\x80\x80\x7f\x00";
        let HeaderParse::Ok(h) = parse_header(data) else {
            panic!()
        };
        let s = read_data(&h, &mut &data[h.data_offset..]).unwrap();
        let Samples::U8(v) = s else { panic!() };
        assert_eq!(
            v,
            [0, 255, 255, 255, 255, 255, 255, 255, 0, 255, 0, 0, 0, 0, 0, 0, 0, 255]
        );
    }

    #[test]
    fn truncated_data_is_an_error() {
        let data = b"P5\n4 4\n255\nabc";
        let HeaderParse::Ok(h) = parse_header(data) else {
            panic!()
        };
        let e = read_data(&h, &mut &data[h.data_offset..]).unwrap_err();
        assert!(e.contains("truncated"), "{e}");
    }
}
