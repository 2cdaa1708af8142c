//! ESC/POS raster for receipt printers (Epson "ESC/POS Command Reference"): `ESC @`
//! (initialise), `GS P` (motion units = the head's dots, so feeds count rows), then the
//! page as `GS v 0` raster bands of at most `--band-rows` rows (960 by default: larger
//! bands overrun many printers' buffers, which is the "garbage after tall images"
//! complaint), runs of blank rows as `ESC J n` paper feeds, and an optional `GS V` cut.
//!
//! The encoder holds one band of rows; a tall receipt streams through it.

use std::io::Write;

use super::{byte, bytes, fail, Bitmap, DecodeResult};
use super::{Language, PrintOptions};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{EncodeError, EncodeResult};

/// Blank rows fewer than this stay inside a band: a feed command and a new band header
/// cost more than a few rows of zeros.
const MIN_FEED_RUN: usize = 8;

/// Streaming ESC/POS writer.
pub struct EscPosEncoder {
    opts: PrintOptions,
    pages: usize,
    page: Option<EscPage>,
}

struct EscPage {
    header: PageHeader,
    /// Rows of the band being gathered (1 = dot), `stride` bytes each.
    band: Vec<u8>,
    band_rows: usize,
    /// Blank rows seen after the band, not yet placed.
    blank: usize,
    row: Vec<u8>,
    rows: usize,
}

impl EscPosEncoder {
    /// An ESC/POS writer.
    pub fn new(opts: PrintOptions) -> EscPosEncoder {
        EscPosEncoder {
            opts,
            pages: 0,
            page: None,
        }
    }
}

impl EscPage {
    /// Sends the gathered band as one `GS v 0` image.
    fn flush_band(&mut self, out: &mut Vec<u8>) {
        if self.band_rows == 0 {
            return;
        }
        let (x, y) = (self.header.stride, self.band_rows);
        out.extend_from_slice(&[
            0x1d,
            b'v',
            b'0',
            0,
            (x & 0xff) as u8,
            (x >> 8) as u8,
            (y & 0xff) as u8,
            (y >> 8) as u8,
        ]);
        out.extend_from_slice(&self.band);
        self.band.clear();
        self.band_rows = 0;
    }

    /// Sends the pending blank rows as feeds (`ESC J n`, n ≤ 255 dots each).
    fn flush_blank(&mut self, out: &mut Vec<u8>) {
        let mut n = self.blank;
        while n > 0 {
            let k = n.min(255);
            out.extend_from_slice(&[0x1b, b'J', k as u8]);
            n -= k;
        }
        self.blank = 0;
    }

    /// Adds one row (1 = dot).
    fn push_row(&mut self, blank: bool, band_limit: usize, out: &mut Vec<u8>) {
        if blank {
            self.blank += 1;
            return;
        }
        if self.blank >= MIN_FEED_RUN {
            self.flush_band(out);
            self.flush_blank(out);
        } else {
            // A short gap stays in the band as rows of zeros.
            for _ in 0..self.blank {
                if self.band_rows == band_limit {
                    self.flush_band(out);
                }
                self.band.extend(std::iter::repeat_n(0, self.header.stride));
                self.band_rows += 1;
            }
            self.blank = 0;
        }
        if self.band_rows == band_limit {
            self.flush_band(out);
        }
        self.band.extend_from_slice(&self.row);
        self.band_rows += 1;
    }
}

impl PageEncoder for EscPosEncoder {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = super::check(Language::EscPos, page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        if self.pages == 0 {
            out.write_all(b"\x1b@")?;
            // Motion units of one dot (GS P x y), so that ESC J n feeds n rows. A printer
            // whose resolution does not fit in a byte keeps its own units.
            let dpi = page.dpi.unwrap_or(203.0).round();
            if (1.0..=255.0).contains(&dpi) {
                out.write_all(&[0x1d, b'P', dpi as u8, dpi as u8])?;
            }
        }
        self.pages += 1;
        self.page = Some(EscPage {
            header: page.clone(),
            band: Vec::with_capacity(self.opts.band_rows * page.stride),
            band_rows: 0,
            blank: 0,
            row: vec![0; page.stride],
            rows: 0,
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let limit = self.opts.band_rows;
        let p = crate::io::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        let mut buf = Vec::new();
        for r in 0..band.rows {
            let mut row = std::mem::take(&mut p.row);
            super::ink_row(
                &band.planes[0][r * stride..(r + 1) * stride],
                p.header.width,
                &mut row,
            );
            let blank = row.iter().all(|&b| b == 0);
            p.row = row;
            p.push_row(blank, limit, &mut buf);
        }
        p.rows += band.rows;
        out.write_all(&buf)?;
        Ok(())
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let mut p =
            crate::io::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
        let mut buf = Vec::new();
        p.flush_band(&mut buf);
        p.flush_blank(&mut buf);
        if self.opts.cut {
            // GS V 66 n: feed to the cutter (plus n motion units) and cut partially, the
            // cut every receipt printer with a cutter supports.
            buf.extend_from_slice(&[0x1d, b'V', 66, 0]);
        }
        out.write_all(&buf)?;
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

// ---------------------------------------------------------------------------------------
// Decoding

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
pub fn decode(data: &[u8]) -> DecodeResult<Receipt> {
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
