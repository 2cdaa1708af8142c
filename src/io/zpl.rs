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

use std::io::Write;

use flate2::write::ZlibEncoder;

use super::print::{self, Language, PrintOptions, ZplEncoding};
use super::sink::{Band, PageEncoder, PageHeader};
use super::{EncodeError, EncodeResult};

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
        if let Some(msg) = print::check(Language::Zpl, page, &self.opts) {
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
        let mut p = super::sink::take_page_for_rows(&mut self.page)?;
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
            print::ink_row(
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
        let mut p = super::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
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
}
