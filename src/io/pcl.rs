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

use super::print::{self, Language, PrintOptions};
use super::sink::{Band, PageEncoder, PageHeader};
use super::{EncodeError, EncodeResult};

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
        if let Some(msg) = print::check(Language::Pcl, page, &self.opts) {
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
                let (w, h) = print::image_points(page, dpi as f64);
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
        let p = super::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        let mut buf = Vec::new();
        for r in 0..band.rows {
            print::ink_row(
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
        super::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
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
