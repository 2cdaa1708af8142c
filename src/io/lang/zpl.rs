//! ZPL II for label printers (Zebra "ZPL II Programming Guide"): a label is `^XA`, its
//! width `^PW` and length `^LL` in dots, then the image as `^FO0,y ^GFA` graphic fields of
//! at most 99,999 data bytes each (the largest byte count `^GF` takes; a 4×6 in label at
//! 300 dpi is 270,000 bytes, so it is banded into fields), and `^XZ`.
//!
//! Field data is hexadecimal with Zebra's ASCII compression by default (the "Alternative
//! Data Compression Scheme" of the guide: repeat counts `G`–`Y` = 1–19 and `g`–`z` =
//! 20–400, `,` = zeros to the end of the row, `!` = ones to the end of the row, `:` = the
//! row before again), or `:Z64:` (zlib, base64, and a CRC-16/XMODEM of the base64 text).
//! The encoder holds one field's rows.

use std::io::{Read, Write};

use flate2::write::ZlibEncoder;

use super::{fail, Bitmap, DecodeResult};
use super::{Language, PrintOptions, ZplEncoding};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{EncodeError, EncodeResult};

/// Largest data byte count of one `^GF` field.
pub const MAX_FIELD_BYTES: usize = 99_999;

/// Streaming ZPL writer.
pub struct ZplEncoder {
    opts: PrintOptions,
    pages: usize,
    page: Option<ZplPage>,
}

struct ZplPage {
    header: PageHeader,
    /// Rows of the field being gathered (1 = dot).
    field: Vec<u8>,
    field_y: usize,
    field_rows: usize,
    max_rows: usize,
    rows: usize,
}

impl ZplEncoder {
    /// A ZPL writer.
    pub fn new(opts: PrintOptions) -> ZplEncoder {
        ZplEncoder {
            opts,
            pages: 0,
            page: None,
        }
    }

    fn flush_field(&self, p: &mut ZplPage, out: &mut dyn Write) -> EncodeResult {
        if p.field_rows == 0 {
            return Ok(());
        }
        let stride = p.header.stride;
        let total = stride * p.field_rows;
        let mut s = format!("^FO0,{}^GFA,{total},{total},{stride},", p.field_y);
        match self.opts.zpl_encoding {
            ZplEncoding::Hex => compress_hex(&p.field, stride, &mut s),
            ZplEncoding::Z64 => {
                let mut z = ZlibEncoder::new(Vec::new(), flate2::Compression::best());
                z.write_all(&p.field)?;
                let b64 = base64(&z.finish()?);
                s += &format!(":Z64:{b64}:{:04X}", crc16_xmodem(b64.as_bytes()));
            }
        }
        s += "^FS\n";
        out.write_all(s.as_bytes())?;
        p.field_y += p.field_rows;
        p.field_rows = 0;
        p.field.clear();
        Ok(())
    }
}

impl PageEncoder for ZplEncoder {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = super::check(Language::Zpl, page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        self.pages += 1;
        // ^PW: print width, ^LL: label length, ^LH0,0: home at the corner.
        write!(out, "^XA\n^PW{}\n^LL{}\n^LH0,0\n", page.width, page.height)?;
        let max_rows = (MAX_FIELD_BYTES / page.stride.max(1)).max(1);
        self.page = Some(ZplPage {
            header: page.clone(),
            field: Vec::with_capacity(max_rows.min(page.height) * page.stride),
            field_y: 0,
            field_rows: 0,
            max_rows,
            rows: 0,
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let mut p = crate::io::sink::take_page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        let mut row = vec![0u8; stride];
        let mut result = Ok(());
        for r in 0..band.rows {
            if p.field_rows == p.max_rows {
                result = self.flush_field(&mut p, out);
                if result.is_err() {
                    break;
                }
            }
            super::ink_row(
                &band.planes[0][r * stride..(r + 1) * stride],
                p.header.width,
                &mut row,
            );
            p.field.extend_from_slice(&row);
            p.field_rows += 1;
        }
        p.rows += band.rows;
        self.page = Some(p);
        result
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let mut p =
            crate::io::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
        self.flush_field(&mut p, out)?;
        out.write_all(b"^XZ\n")?;
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        if self.pages == 0 {
            return Err(EncodeError::Other("no pages to write".into()));
        }
        out.flush()?;
        Ok(())
    }
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Appends a run of `n` hex digits `c` in Zebra's repeat-count notation.
fn put_run(n: usize, c: u8, out: &mut String) {
    let mut n = n;
    while n > 0 {
        // One count goes up to 400 + 19.
        let k = n.min(419);
        if k >= 20 {
            out.push((b'f' + (k / 20) as u8) as char);
        }
        if !k.is_multiple_of(20) && k > 1 {
            out.push((b'F' + (k % 20) as u8) as char);
        }
        out.push(c as char);
        n -= k;
    }
}

/// ZPL ASCII-compressed hex of `rows` (1 = dot), `stride` bytes a row.
pub fn compress_hex(rows: &[u8], stride: usize, out: &mut String) {
    let mut digits = Vec::with_capacity(stride * 2);
    let mut prev: Option<&[u8]> = None;
    for row in rows.chunks_exact(stride) {
        if prev == Some(row) {
            out.push(':');
            continue;
        }
        prev = Some(row);
        digits.clear();
        for &b in row {
            digits.push(HEX[(b >> 4) as usize]);
            digits.push(HEX[(b & 15) as usize]);
        }
        // The row's tail of zeros (`,`) or of ones (`!`).
        let tail_of = |d: u8| digits.iter().rev().take_while(|&&x| x == d).count();
        let (zeros, ones) = (tail_of(b'0'), tail_of(b'F'));
        let (body, end) = if zeros >= 2 {
            // An odd run of zeros starts mid-byte: send its first zero explicitly, so the
            // fill starts on a byte (some decoders fill whole bytes only).
            let z = zeros - zeros % 2;
            (digits.len() - z, Some(','))
        } else if ones >= 2 {
            let o = ones - ones % 2;
            (digits.len() - o, Some('!'))
        } else {
            (digits.len(), None)
        };
        let mut i = 0;
        while i < body {
            let c = digits[i];
            let mut j = i + 1;
            while j < body && digits[j] == c {
                j += 1;
            }
            put_run(j - i, c, out);
            i = j;
        }
        if let Some(e) = end {
            out.push(e);
        }
    }
}

/// CRC-16/XMODEM (polynomial 0x1021, initial 0, no reflection), as ZPL checks `:Z64:` data.
pub fn crc16_xmodem(data: &[u8]) -> u16 {
    let mut crc: u16 = 0;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Standard base64 with padding (RFC 4648).
pub fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let v = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(v >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

// ---------------------------------------------------------------------------------------
// Decoding

/// Largest label a ZPL stream may claim, in dots either way (`^PW` and `^LL` take at most
/// 32,000).
const ZPL_MAX_DOTS: usize = 32_000;

/// Largest data byte count of one `^GF` field.
const ZPL_MAX_FIELD_BYTES: usize = 99_999;

/// Decodes the labels of a ZPL II stream: `^XA`, `^PW`, `^LL`, `^FO x,y`, `^GFA` fields in
/// ASCII hex (with Zebra's compression: `G`–`Y` and `g`–`z` repeat counts, `,` zeros and
/// `!` ones to the end of the row, `:` the row before again) or `:Z64:` (base64 of zlib
/// data, checked against its CRC-16), and `^XZ`. Each label is a bitmap of `^PW` × `^LL`
/// dots (1 = dot) with every graphic drawn at its field origin.
pub fn decode(data: &[u8]) -> DecodeResult<Vec<Bitmap>> {
    let text = match std::str::from_utf8(data) {
        Ok(t) => t,
        Err(e) => return fail(format!("ZPL is not text: {e}")),
    };
    let mut labels = Vec::new();
    let (mut width, mut length) = (0usize, 0usize);
    let (mut fx, mut fy) = (0usize, 0usize);
    let mut graphics: Vec<(usize, usize, usize, Vec<u8>)> = Vec::new();
    let mut open = false;
    for cmd in text.split('^').skip(1) {
        let (name, args) = cmd.split_at(cmd.len().min(2));
        let args = args.trim_end();
        let bounded = |s: &str, max: usize| -> DecodeResult<usize> {
            s.trim()
                .parse::<usize>()
                .ok()
                .filter(|&v| v <= max)
                .map_or_else(|| fail(format!("bad ZPL number '{s}' in ^{name}")), Ok)
        };
        let number = |s: &str| bounded(s, ZPL_MAX_DOTS);
        match name {
            "XA" => {
                open = true;
                (width, length, fx, fy) = (0, 0, 0, 0);
                graphics.clear();
            }
            "PW" => width = number(args)?,
            "LL" => length = number(args)?,
            "FO" => {
                let mut it = args.splitn(3, ',');
                fx = number(it.next().unwrap_or(""))?;
                fy = number(it.next().unwrap_or("0"))?;
            }
            "GF" => {
                let mut it = args.splitn(5, ',');
                if it.next() != Some("A") {
                    return fail("only ^GFA graphic fields are decoded here");
                }
                let total = bounded(it.next().unwrap_or(""), ZPL_MAX_FIELD_BYTES)?;
                let _field = it.next();
                let stride = number(it.next().unwrap_or(""))?;
                let body = it.next().unwrap_or("");
                if stride == 0 || total % stride != 0 {
                    return fail(format!("^GF of {total} bytes in rows of {stride}"));
                }
                let bytes = if let Some(z) = body.strip_prefix(":Z64:") {
                    zpl_z64(z, total)?
                } else {
                    zpl_hex(body, total, stride)?
                };
                graphics.push((fx, fy, stride, bytes));
            }
            "XZ" => {
                if !open {
                    return fail("^XZ without ^XA");
                }
                open = false;
                let mut label = Bitmap::blank(width, length);
                for (gx, gy, stride, bytes) in &graphics {
                    for (r, row) in bytes.chunks_exact(*stride).enumerate() {
                        let y = gy + r;
                        if y >= length {
                            break;
                        }
                        for x in 0..stride * 8 {
                            if row[x / 8] & (0x80 >> (x % 8)) != 0 && gx + x < width {
                                let (lx, s) = (gx + x, label.stride());
                                label.data[y * s + lx / 8] |= 0x80 >> (lx % 8);
                            }
                        }
                    }
                }
                labels.push(label);
            }
            _ => {}
        }
    }
    if open {
        return fail("a label without ^XZ");
    }
    Ok(labels)
}

/// A `^GF` field's ASCII hex data with Zebra's compression, `total` bytes in rows of
/// `stride`.
fn zpl_hex(body: &str, total: usize, stride: usize) -> DecodeResult<Vec<u8>> {
    let row_digits = stride * 2;
    let mut digits: Vec<u8> = Vec::with_capacity(total * 2);
    let mut row_start = 0;
    let mut count = 0usize;
    let finish_row = |digits: &mut Vec<u8>, row_start: &mut usize, fill: u8| -> DecodeResult<()> {
        let have = digits.len() - *row_start;
        if have > row_digits || *row_start + row_digits > total * 2 {
            return fail(format!("^GF data past its {total} bytes"));
        }
        digits.extend(std::iter::repeat_n(fill, row_digits - have));
        *row_start = digits.len();
        Ok(())
    };
    for c in body.bytes() {
        match c {
            b'G'..=b'Y' => count += (c - b'F') as usize,
            b'g'..=b'z' => count += (c - b'f') as usize * 20,
            b'0'..=b'9' | b'A'..=b'F' | b'a'..=b'f' => {
                let n = count.max(1);
                count = 0;
                if n > total * 2 - digits.len() {
                    return fail(format!("^GF data past its {total} bytes"));
                }
                for _ in 0..n {
                    digits.push(c.to_ascii_uppercase());
                    if digits.len() - row_start == row_digits {
                        row_start = digits.len();
                    }
                }
            }
            b',' => finish_row(&mut digits, &mut row_start, b'0')?,
            b'!' => finish_row(&mut digits, &mut row_start, b'F')?,
            b':' => {
                if digits.len() != row_start || row_start < row_digits {
                    return fail("':' (the row before again) not at a row's start");
                }
                if digits.len() + row_digits > total * 2 {
                    return fail(format!("^GF data past its {total} bytes"));
                }
                digits.extend_from_within(row_start - row_digits..row_start);
                row_start = digits.len();
            }
            b'\r' | b'\n' | b' ' => {}
            _ => return fail(format!("unexpected {:?} in ^GF data", c as char)),
        }
    }
    if digits.len() != total * 2 {
        return fail(format!(
            "^GF data has {} bytes, not {total}",
            digits.len() / 2
        ));
    }
    let hex = |d: u8| match d {
        b'0'..=b'9' => d - b'0',
        _ => d - b'A' + 10,
    };
    Ok(digits
        .chunks_exact(2)
        .map(|p| hex(p[0]) << 4 | hex(p[1]))
        .collect())
}

/// A `:Z64:` field: base64 of zlib data, `:`, and the CRC-16/XMODEM of the base64 text.
fn zpl_z64(z: &str, total: usize) -> DecodeResult<Vec<u8>> {
    let Some((b64, crc)) = z.rsplit_once(':') else {
        return fail("a :Z64: field without its CRC");
    };
    let want = u16::from_str_radix(crc.trim(), 16).or_else(|_| fail("a bad :Z64: CRC"))?;
    if crc16_xmodem(b64.as_bytes()) != want {
        return fail("the :Z64: CRC does not match");
    }
    let packed = base64_decode(b64)?;
    let mut out = Vec::with_capacity(total);
    flate2::read::ZlibDecoder::new(&packed[..])
        .take(total as u64 + 1)
        .read_to_end(&mut out)
        .or_else(|e| fail(format!(":Z64: data: {e}")))?;
    if out.len() != total {
        return fail(format!(":Z64: data has {} bytes, not {total}", out.len()));
    }
    Ok(out)
}

/// Standard base64 with padding (RFC 4648).
fn base64_decode(s: &str) -> DecodeResult<Vec<u8>> {
    let s = s.as_bytes();
    if !s.len().is_multiple_of(4) {
        return fail("base64 text is not whole quads");
    }
    let val = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    for (q, quad) in s.chunks_exact(4).enumerate() {
        let last = q + 1 == s.len() / 4;
        let pad = quad.iter().rev().take_while(|&&c| c == b'=').count();
        if pad > 2 || (pad > 0 && !last) {
            return fail("misplaced base64 padding");
        }
        let mut v = 0u32;
        for &c in &quad[..4 - pad] {
            v = v << 6 | val(c).map_or_else(|| fail("a character outside base64"), Ok)?;
        }
        v <<= 6 * pad as u32;
        out.extend_from_slice(&v.to_be_bytes()[1..4 - pad]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // CRC-16/XMODEM check value of "123456789" (the CRC catalogue's check string).
        assert_eq!(crc16_xmodem(b"123456789"), 0x31C3);
        assert_eq!(base64(b"Man"), "TWFu");
        assert_eq!(base64(b"Ma"), "TWE=");
        assert_eq!(base64(b"M"), "TQ==");
    }

    #[test]
    fn hex_compression() {
        let mut s = String::new();
        // 0xFF 0xFF 0x00 0x0F | same | all zero
        compress_hex(
            &[0xFF, 0xFF, 0x00, 0x0F, 0xFF, 0xFF, 0x00, 0x0F, 0, 0, 0, 0],
            4,
            &mut s,
        );
        assert_eq!(s, "JFI0F:,");
        let mut s = String::new();
        // 45 digits of 'A' then a tail of ones: 45 = 40 + 5 = "hK".
        let mut row = vec![0xAA; 22];
        row.push(0xAF);
        row.extend([0xFF; 10]);
        compress_hex(&row, row.len(), &mut s);
        assert_eq!(s, "hKAF!");
        // A zero run of odd length: one explicit zero, then the fill.
        let mut s = String::new();
        compress_hex(&[0x12, 0x30, 0x00], 3, &mut s);
        assert_eq!(s, "1230,");
    }

    #[test]
    fn base64_round_trips() {
        for n in 0..20u8 {
            let data: Vec<u8> = (0..n).map(|i| i.wrapping_mul(37)).collect();
            let text = base64(&data);
            assert_eq!(base64_decode(&text).unwrap(), data);
        }
    }

    #[test]
    fn zpl_hex_compression_from_the_guide() {
        // Repeat counts (J = 4, g = 20), ',' and '!' fills, ':' repeats.
        assert_eq!(zpl_hex("JF00", 3, 3).unwrap(), [0xFF, 0xFF, 0]);
        assert_eq!(zpl_hex("F,", 4, 4).unwrap(), [0xF0, 0, 0, 0]);
        assert_eq!(zpl_hex("0!", 4, 4).unwrap(), [0x0F, 0xFF, 0xFF, 0xFF]);
        assert_eq!(zpl_hex("A1:", 2, 1).unwrap(), [0xA1, 0xA1]);
        assert_eq!(zpl_hex("gA", 10, 10).unwrap(), [0xAA; 10]);
        assert!(zpl_hex(":", 2, 1).is_err());
        assert!(zpl_hex("FFF", 1, 1).is_err());
    }
}
