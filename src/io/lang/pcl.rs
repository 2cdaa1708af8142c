//! PCL 5 raster graphics for laser printers (PCL 5 Technical Reference Manual, ch. 15
//! "Raster Graphics"): reset, resolution, then one `ESC * b # W` transfer a row, each in
//! compression mode 2 (TIFF PackBits) or 3 (delta row, against the previous row), whichever
//! is smaller for that row, then end of raster and a form feed. Rows stream with one row
//! of state (the seed row of mode 3).
//!
//! Raster rows are shortened: trailing blank bytes are left out (the printer fills the row
//! with zeros, §15 "Transfer Raster Data"), and a mode-3 row equal to the one before is
//! an empty transfer.

use std::io::Write;

use super::{byte, bytes, fail, Bitmap, DecodeResult};
use super::{Language, PrintOptions};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{EncodeError, EncodeResult};

/// Streaming PCL 5 writer.
pub struct PclEncoder {
    opts: PrintOptions,
    pages: usize,
    page: Option<PclPage>,
}

struct PclPage {
    header: PageHeader,
    /// The previous row, as the printer holds it (1 = ink), for delta rows.
    seed: Vec<u8>,
    row: Vec<u8>,
    mode: u8,
    rows: usize,
    m2: Vec<u8>,
    m3: Vec<u8>,
}

impl PclEncoder {
    /// A PCL 5 writer.
    pub fn new(opts: PrintOptions) -> PclEncoder {
        PclEncoder {
            opts,
            pages: 0,
            page: None,
        }
    }
}

impl PageEncoder for PclEncoder {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = super::check(Language::Pcl, page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        let dpi = page.dpi.unwrap_or(300.0).round() as u32;
        let mut head = Vec::new();
        if self.pages == 0 {
            // Reset.
            head.extend_from_slice(b"\x1bE");
        } else {
            head.push(b'\x0c');
        }
        self.pages += 1;
        if let Some(size) = self.opts.page.and_then(|p| p.pcl_code) {
            write!(head, "\x1b&l{size}A")?;
        }
        // Top margin 0, units of measure = the raster's dots (7200 is a multiple of every
        // allowed resolution), cursor to the image's corner.
        write!(head, "\x1b&l0E\x1b&u{dpi}D")?;
        let (x, y) = match self.opts.page {
            Some(p) => {
                let (w, h) = super::image_points(page, dpi as f64);
                // Points to dots, measured from the page's corner; PCL positions from the
                // logical page, which starts 1/4 in from the left edge on letter and A4
                // portrait (PCL 5 Technical Reference, "Logical Page").
                let left = ((p.width - w) / 2.0 - 18.0).max(0.0);
                let top = ((p.height - h) / 2.0).max(0.0);
                (
                    (left * dpi as f64 / 72.0).round() as u64,
                    (top * dpi as f64 / 72.0).round() as u64,
                )
            }
            None => (0, 0),
        };
        write!(
            head,
            "\x1b*p{x}x{y}Y\x1b*t{dpi}R\x1b*r{}S\x1b*r{}T\x1b*r1A\x1b*b0M",
            page.width, page.height
        )?;
        out.write_all(&head)?;
        self.page = Some(PclPage {
            header: page.clone(),
            seed: vec![0; page.stride],
            row: vec![0; page.stride],
            mode: 0,
            rows: 0,
            m2: Vec::new(),
            m3: Vec::new(),
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        let mut buf = Vec::new();
        for r in 0..band.rows {
            super::ink_row(
                &band.planes[0][r * stride..(r + 1) * stride],
                p.header.width,
                &mut p.row,
            );
            p.m2.clear();
            p.m3.clear();
            let used = p.row.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
            super::ps::run_length(&p.row[..used], &mut p.m2);
            delta_row(&p.seed, &p.row, &mut p.m3);
            // A mode change costs its own command (5 bytes).
            let cost = |m: u8, len: usize| len + if m == p.mode { 0 } else { 5 };
            let (mode, data) = if cost(3, p.m3.len()) < cost(2, p.m2.len()) {
                (3, &p.m3)
            } else {
                (2, &p.m2)
            };
            if mode != p.mode {
                write!(buf, "\x1b*b{mode}M")?;
                p.mode = mode;
            }
            write!(buf, "\x1b*b{}W", data.len())?;
            buf.extend_from_slice(data);
            std::mem::swap(&mut p.seed, &mut p.row);
        }
        p.rows += band.rows;
        out.write_all(&buf)?;
        Ok(())
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        crate::io::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
        // End raster graphics (`ESC * r B`, which every PCL 5 printer knows).
        out.write_all(b"\x1b*rB")?;
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        if self.pages == 0 {
            return Err(EncodeError::Other("no pages to write".into()));
        }
        // Eject the last page and reset, as pbmtolj does.
        out.write_all(b"\x0c\x1bE")?;
        out.flush()?;
        Ok(())
    }
}

/// PCL compression mode 3 (delta row): for each stretch of bytes that differ from the seed
/// row, a command byte (bits 7–5: count − 1, 1..8 bytes; bits 4–0: offset from the end of
/// the last stretch, 31 meaning "more offset bytes follow", each added, until one below
/// 255), then the new bytes. Bytes not mentioned keep the seed row's value.
pub fn delta_row(seed: &[u8], row: &[u8], out: &mut Vec<u8>) {
    let mut last = 0; // first byte after the previous stretch
    let mut i = 0;
    while i < row.len() {
        if row[i] == seed[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i < row.len() && i - start < 8 && row[i] != seed[i] {
            i += 1;
        }
        let count = i - start;
        let offset = start - last;
        out.push((((count - 1) as u8) << 5) | offset.min(31) as u8);
        if offset >= 31 {
            let mut rest = offset - 31;
            loop {
                out.push(rest.min(255) as u8);
                if rest < 255 {
                    break;
                }
                rest -= 255;
            }
        }
        out.extend_from_slice(&row[start..i]);
        last = i;
    }
}

// ---------------------------------------------------------------------------------------
// Decoding

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
pub fn decode(data: &[u8]) -> DecodeResult<Vec<PclRaster>> {
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
fn pcl_row(mode: u8, sent: &[u8], seed: &[u8], wb: usize) -> DecodeResult<Vec<u8>> {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Mode 3 as the PCL 5 Technical Reference describes it (decoder side).
    fn apply_delta(seed: &[u8], data: &[u8]) -> Vec<u8> {
        let mut row = seed.to_vec();
        let (mut k, mut pos) = (0, 0);
        while k < data.len() {
            let count = (data[k] >> 5) as usize + 1;
            let mut offset = (data[k] & 31) as usize;
            k += 1;
            if offset == 31 {
                loop {
                    offset += data[k] as usize;
                    k += 1;
                    if data[k - 1] != 255 {
                        break;
                    }
                }
            }
            pos += offset;
            row[pos..pos + count].copy_from_slice(&data[k..k + count]);
            k += count;
            pos += count;
        }
        row
    }

    #[test]
    fn delta_rows_round_trip_with_long_offsets() {
        let seed: Vec<u8> = (0..1500).map(|i| (i * 7 % 251) as u8).collect();
        // Changes after gaps of 0, 30, 31, 285, 286 and 600 bytes, runs of 1 to 12 bytes.
        let mut row = seed.clone();
        let mut at = 0;
        for (gap, run) in [
            (0, 1),
            (30, 8),
            (31, 9),
            (285, 2),
            (286, 12),
            (255, 3),
            (300, 1),
        ] {
            at += gap;
            for b in &mut row[at..at + run] {
                *b ^= 0x5A;
            }
            at += run;
        }
        let mut d = Vec::new();
        delta_row(&seed, &row, &mut d);
        assert_eq!(apply_delta(&seed, &d), row);
        // An unchanged row is an empty transfer.
        d.clear();
        delta_row(&seed, &seed, &mut d);
        assert!(d.is_empty());
    }
}
