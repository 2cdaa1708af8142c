//! Reference decoders for the printer languages halftone writes that no packaged tool
//! decodes exactly: PCL 5 raster graphics, ESC/POS `GS v 0` receipts and ZPL II `^GF`
//! graphic fields. They are written from the manuals (PCL 5 Technical Reference Manual,
//! ch. 15; Epson ESC/POS Command Reference; Zebra ZPL II Programming Guide), checked
//! against independent encoders in the tests (netpbm's `pbmtolj`, Ghostscript's `ljet4`,
//! python-escpos, zebrafy), and used by the tests and fuzz targets to read back what the
//! encoders wrote.
//!
//! They decode what a printer would accept, not only halftone's own output (combined PCL
//! parameters, all four PCL compression modes, ZPL's repeat counts and Z64 fields), and
//! they never panic: anything else is an error.

use std::io::Read;

/// What a reference decoder could not decode.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DecodeError(String);

impl DecodeError {
    /// An error with this message.
    pub(crate) fn new(msg: impl Into<String>) -> DecodeError {
        DecodeError(msg.into())
    }
}

/// A decoder's result.
pub type Result<T> = std::result::Result<T, DecodeError>;

fn fail<T>(msg: impl Into<String>) -> Result<T> {
    Err(DecodeError(msg.into()))
}

/// The byte at `i`, or an error naming what was cut short.
fn byte(data: &[u8], i: usize, what: &str) -> Result<u8> {
    match data.get(i) {
        Some(&b) => Ok(b),
        None => fail(format!("cut short in {what} at byte {i}")),
    }
}

/// `n` bytes at `i`, or an error naming what was cut short.
fn bytes<'a>(data: &'a [u8], i: usize, n: usize, what: &str) -> Result<&'a [u8]> {
    match i.checked_add(n).and_then(|end| data.get(i..end)) {
        Some(s) => Ok(s),
        None => fail(format!("cut short in {what}: {n} bytes at byte {i}")),
    }
}

/// A bilevel bitmap: rows of `(width + 7) / 8` bytes, most significant bit first, 1 = ink.
/// Bits past `width` in a row's last byte are zero.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bitmap {
    /// Width in dots.
    pub width: usize,
    /// Height in dots.
    pub height: usize,
    /// The rows.
    pub data: Vec<u8>,
}

impl Bitmap {
    /// A blank (no ink) bitmap.
    pub fn blank(width: usize, height: usize) -> Bitmap {
        Bitmap {
            width,
            height,
            data: vec![0; width.div_ceil(8) * height],
        }
    }

    /// Bytes a row.
    pub fn stride(&self) -> usize {
        self.width.div_ceil(8)
    }

    /// True where there is ink.
    pub fn get(&self, x: usize, y: usize) -> bool {
        self.data[y * self.stride() + x / 8] & (0x80 >> (x % 8)) != 0
    }

    /// Builds a bitmap of `width` columns from rows of any byte length: longer rows are cut,
    /// shorter ones padded with no ink.
    pub fn from_rows<R: AsRef<[u8]>>(width: usize, rows: &[R]) -> Bitmap {
        let mut out = Bitmap::blank(width, rows.len());
        let stride = out.stride();
        for (dst, src) in out.data.chunks_exact_mut(stride.max(1)).zip(rows) {
            let src = src.as_ref();
            let n = src.len().min(stride);
            dst[..n].copy_from_slice(&src[..n]);
        }
        out.clear_padding();
        out
    }

    /// Clears the bits past `width` in each row's last byte.
    fn clear_padding(&mut self) {
        let stride = self.stride();
        if !self.width.is_multiple_of(8) && stride > 0 {
            for row in self.data.chunks_exact_mut(stride) {
                row[stride - 1] &= 0xFFu8 << (8 - self.width % 8);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// PCL 5

/// One raster graphic of a PCL stream: where it started (in dots) and its rows (1 = ink),
/// each as long as the data sent for it (at least the `ESC * r # S` width).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PclRaster {
    /// Left edge in dots (the cursor's x with `ESC * r 1 A`, else 0).
    pub x: i64,
    /// Top edge in dots.
    pub y: i64,
    /// Raster resolution (`ESC * t # R`), dots per inch.
    pub dpi: u32,
    /// Rows, top to bottom.
    pub rows: Vec<Vec<u8>>,
}

impl PclRaster {
    /// The raster as a bitmap `width` dots wide.
    pub fn bitmap(&self, width: usize) -> Bitmap {
        Bitmap::from_rows(width, &self.rows)
    }
}

/// Longest row a PCL raster may claim (a 600 dpi page is 5,100 dots wide; this is 64 in).
const PCL_MAX_ROW_BYTES: usize = 4800;

/// Decodes every raster graphic of a PCL 5 stream: escape sequences with combined
/// parameters (`ESC * b 3 m 32 W`), compression modes 0 (none), 1 (run length), 2 (PackBits)
/// and 3 (delta row), `ESC * b # Y` blank rows, cursor moves in `ESC & u` units.
pub fn pcl(data: &[u8]) -> Result<Vec<PclRaster>> {
    let mut out = Vec::new();
    let (mut units, mut dpi, mut mode) = (300i64, 75u32, 0u8);
    let (mut cx, mut cy) = (0i64, 0i64);
    let mut width_bytes = 0usize;
    let mut current: Option<PclRaster> = None;
    let mut seed: Vec<u8> = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i] != 0x1b {
            i += 1;
            continue;
        }
        let p = byte(data, i + 1, "an escape sequence")?;
        if !(0x21..=0x2f).contains(&p) {
            // A two-character escape (ESC E, reset).
            i += 2;
            continue;
        }
        let g = byte(data, i + 2, "an escape sequence")?;
        i += 3;
        // Parameter groups: a value, then a letter; lower case goes on, upper case ends.
        loop {
            let start = i;
            while matches!(
                byte(data, i, "a parameter")?,
                b'+' | b'-' | b'.' | b'0'..=b'9'
            ) {
                i += 1;
            }
            let text = std::str::from_utf8(&data[start..i]).unwrap_or("");
            let relative = text.starts_with('+') || text.starts_with('-');
            let value: f64 = if text.is_empty() {
                0.0
            } else {
                match text.parse() {
                    Ok(v) => v,
                    Err(_) => return fail(format!("bad PCL value '{text}' at byte {start}")),
                }
            };
            let letter = byte(data, i, "a parameter")?;
            if !letter.is_ascii_alphabetic() && letter != b'@' {
                return fail(format!(
                    "bad PCL parameter letter {letter:#04x} at byte {i}"
                ));
            }
            i += 1;
            let move_to = |c: &mut i64, v: f64| {
                let dots = (v * dpi as f64 / units.max(1) as f64).round() as i64;
                if relative {
                    *c = c.saturating_add(dots);
                } else {
                    *c = dots;
                }
            };
            match (p, g, letter.to_ascii_uppercase()) {
                (b'&', b'u', b'D') => units = value as i64,
                (b'*', b't', b'R') => dpi = value as u32,
                (b'*', b'p', b'X') => move_to(&mut cx, value),
                (b'*', b'p', b'Y') => move_to(&mut cy, value),
                (b'*', b'r', b'S') => {
                    width_bytes = (value.max(0.0) as usize).div_ceil(8);
                    if width_bytes > PCL_MAX_ROW_BYTES {
                        return fail(format!("raster width {value} dots is too wide"));
                    }
                }
                (b'*', b'r', b'A') => {
                    seed = vec![0; width_bytes];
                    current = Some(PclRaster {
                        x: if value as u32 == 1 { cx } else { 0 },
                        y: cy,
                        dpi,
                        rows: Vec::new(),
                    });
                }
                (b'*', b'r', b'B') | (b'*', b'r', b'C') => {
                    if let Some(r) = current.take() {
                        cy = r.y.saturating_add(r.rows.len() as i64);
                        out.push(r);
                    }
                }
                (b'*', b'b', b'M') => mode = value as u8,
                (b'*', b'b', b'Y') => {
                    let Some(r) = current.as_mut() else {
                        return fail("rows outside a raster graphic");
                    };
                    seed.iter_mut().for_each(|b| *b = 0);
                    let n = value.max(0.0) as usize;
                    if n > 1 << 20 {
                        return fail(format!("{n} blank rows"));
                    }
                    r.rows.extend(std::iter::repeat_n(seed.clone(), n));
                }
                (b'*', b'b', b'W') => {
                    let n = value.max(0.0) as usize;
                    let sent = bytes(data, i, n, "raster data")?;
                    i += n;
                    let wb = width_bytes.max(seed.len());
                    seed.resize(wb, 0);
                    let row = pcl_row(mode, sent, &seed, wb)?;
                    seed.clone_from(&row);
                    let Some(r) = current.as_mut() else {
                        return fail("rows outside a raster graphic");
                    };
                    r.rows.push(row);
                }
                _ => {}
            }
            if letter.is_ascii_uppercase() {
                break;
            }
        }
    }
    Ok(out)
}

/// One PCL raster row from the bytes sent for it, in compression `mode`, against the seed
/// row (the row before) for delta rows.
fn pcl_row(mode: u8, sent: &[u8], seed: &[u8], wb: usize) -> Result<Vec<u8>> {
    let mut r = match mode {
        0 => sent.to_vec(),
        1 => {
            let mut r = Vec::new();
            for pair in sent.chunks_exact(2) {
                r.extend(std::iter::repeat_n(pair[1], pair[0] as usize + 1));
                if r.len() > PCL_MAX_ROW_BYTES {
                    return fail("a run-length row is too long");
                }
            }
            r
        }
        2 => {
            let mut r = Vec::new();
            let mut k = 0;
            while k < sent.len() {
                let c = sent[k] as i8;
                if c >= 0 {
                    let lit = bytes(sent, k + 1, c as usize + 1, "a PackBits literal")?;
                    r.extend_from_slice(lit);
                    k += 2 + c as usize;
                } else if c != -128 {
                    let b = byte(sent, k + 1, "a PackBits run")?;
                    r.extend(std::iter::repeat_n(b, (1 - c as isize) as usize));
                    k += 2;
                } else {
                    k += 1;
                }
                if r.len() > PCL_MAX_ROW_BYTES {
                    return fail("a PackBits row is too long");
                }
            }
            r
        }
        3 => {
            let mut r = seed.to_vec();
            let (mut k, mut pos) = (0, 0usize);
            while k < sent.len() {
                let count = (sent[k] >> 5) as usize + 1;
                let mut offset = (sent[k] & 31) as usize;
                k += 1;
                if offset == 31 {
                    loop {
                        let b = byte(sent, k, "a delta-row offset")?;
                        offset += b as usize;
                        k += 1;
                        if b != 255 {
                            break;
                        }
                    }
                }
                pos = pos.saturating_add(offset);
                let repl = bytes(sent, k, count, "delta-row bytes")?;
                for (j, &b) in repl.iter().enumerate() {
                    if let Some(slot) = r.get_mut(pos + j) {
                        *slot = b;
                    }
                }
                k += count;
                pos = pos.saturating_add(count);
            }
            r
        }
        m => return fail(format!("PCL compression mode {m} is not decoded here")),
    };
    r.resize(wb.max(r.len()), 0);
    Ok(r)
}

// ---------------------------------------------------------------------------------------
// ESC/POS

/// What an ESC/POS stream prints.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Receipt {
    /// Raster rows in order, feeds as blank rows (one motion unit = one dot), as wide as the
    /// widest `GS v 0` band (whole bytes).
    pub bitmap: Bitmap,
    /// Heights of the `GS v 0` bands, in order.
    pub bands: Vec<usize>,
    /// Whether the stream cuts the paper (`GS V`).
    pub cut: bool,
}

/// Decodes the ESC/POS commands halftone (and python-escpos) send: `ESC @`, `ESC J n`,
/// `ESC a n`, `GS P x y`, `GS v 0 m xL xH yL yH d…` and `GS V`.
pub fn escpos(data: &[u8]) -> Result<Receipt> {
    let mut rows: Vec<&[u8]> = Vec::new();
    let mut bands = Vec::new();
    let mut width_bytes = 0;
    let mut cut = false;
    let mut i = 0;
    while i < data.len() {
        match (data[i], data.get(i + 1).copied()) {
            (0x1b, Some(b'@')) => i += 2,
            (0x1b, Some(b'J')) => {
                let n = byte(data, i + 2, "ESC J")?;
                rows.extend(std::iter::repeat_n(&[][..], n as usize));
                i += 3;
            }
            (0x1b, Some(b'a')) => i += 3,
            (0x1d, Some(b'P')) => i += 4,
            (0x1d, Some(b'v')) => {
                let head = bytes(data, i, 8, "GS v 0")?;
                if head[2] != b'0' {
                    return fail(format!("GS v {:#04x} at byte {i}", head[2]));
                }
                let x = head[4] as usize | (head[5] as usize) << 8;
                let y = head[6] as usize | (head[7] as usize) << 8;
                i += 8;
                let image = bytes(data, i, x * y, "GS v 0 data")?;
                width_bytes = width_bytes.max(x);
                rows.extend(image.chunks_exact(x.max(1)).take(y));
                bands.push(y);
                i += x * y;
            }
            (0x1d, Some(b'V')) => {
                cut = true;
                let m = byte(data, i + 2, "GS V")?;
                i += if matches!(m, 65 | 66) { 4 } else { 3 };
            }
            (b, _) => return fail(format!("unexpected byte {b:#04x} at {i}")),
        }
    }
    Ok(Receipt {
        bitmap: Bitmap::from_rows(width_bytes * 8, &rows),
        bands,
        cut,
    })
}

// ---------------------------------------------------------------------------------------
// ZPL II

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
pub fn zpl(data: &[u8]) -> Result<Vec<Bitmap>> {
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
        let bounded = |s: &str, max: usize| -> Result<usize> {
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
fn zpl_hex(body: &str, total: usize, stride: usize) -> Result<Vec<u8>> {
    let row_digits = stride * 2;
    let mut digits: Vec<u8> = Vec::with_capacity(total * 2);
    let mut row_start = 0;
    let mut count = 0usize;
    let finish_row = |digits: &mut Vec<u8>, row_start: &mut usize, fill: u8| -> Result<()> {
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
fn zpl_z64(z: &str, total: usize) -> Result<Vec<u8>> {
    let Some((b64, crc)) = z.rsplit_once(':') else {
        return fail("a :Z64: field without its CRC");
    };
    let want = u16::from_str_radix(crc.trim(), 16).or_else(|_| fail("a bad :Z64: CRC"))?;
    if super::zpl::crc16_xmodem(b64.as_bytes()) != want {
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
fn base64_decode(s: &str) -> Result<Vec<u8>> {
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
    fn base64_round_trips() {
        for n in 0..20u8 {
            let data: Vec<u8> = (0..n).map(|i| i.wrapping_mul(37)).collect();
            let text = super::super::zpl::base64(&data);
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

    #[test]
    fn truncated_streams_are_errors_not_panics() {
        let pcl_stream = b"\x1b*r8S\x1b*r1A\x1b*b2m9W\x05ab";
        for n in 0..pcl_stream.len() {
            let _ = pcl(&pcl_stream[..n]);
        }
        assert!(pcl(pcl_stream).is_err());
        assert!(escpos(b"\x1dv0\x00\x02\x00\x02\x00\xff").is_err());
        assert!(zpl(b"^XA^PW8^LL1^GFA,1,1,1,FF^FS").is_err());
    }
}
