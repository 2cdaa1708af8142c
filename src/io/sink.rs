//! The encoder interface: pages of packed rows in, a file format out.
//!
//! Every output format is a [`PageEncoder`]: it is told a page's size and levels
//! ([`PageHeader`]), then receives the page's packed rows in bands from top to bottom
//! ([`PageEncoder::write_rows`]), then the end of the page; [`PageEncoder::finish`] closes
//! the file (trailers, cross-reference tables). Multi-page formats (PDF, PostScript, PCL,
//! ZPL, ESC/POS) accept several pages; single-image formats refuse a second one.
//!
//! Rows arrive exactly as [`Halftone`] stores them (level indices, packed MSB first, 1 bit
//! a sample for bilevel, level 0 = ink), so a streaming pipeline can hand bands to an
//! encoder without ever holding the whole image, and [`encode_halftone`] runs a whole
//! image through the same path in one band. An encoder never knows the method.

use std::io::Write;

use super::EncodeResult;
use crate::raster::Halftone;

/// What an encoder knows of a page before its first row.
#[derive(Clone, Debug, PartialEq)]
pub struct PageHeader {
    /// Width in pixels.
    pub width: usize,
    /// Height in rows.
    pub height: usize,
    /// Planes: 1 (grey or palette indices) or 3 (red, green, blue).
    pub channels: usize,
    /// Levels per channel (2 = bilevel).
    pub levels: u16,
    /// Storage bits per sample: 1, 2, 4 or 8.
    pub bits: u8,
    /// Bytes per packed row of one plane.
    pub stride: usize,
    /// When set, the single plane holds indices into these sRGB colours.
    pub palette: Option<Vec<[u8; 3]>>,
    /// Resolution in dots per inch, when known.
    pub dpi: Option<f64>,
}

impl PageHeader {
    /// The header of a whole halftone, with the resolution to record.
    pub fn of(h: &Halftone, dpi: Option<f64>) -> PageHeader {
        PageHeader {
            width: h.width,
            height: h.height,
            channels: h.channels(),
            levels: h.levels,
            bits: h.bits,
            stride: h.stride,
            palette: h.palette.clone(),
            dpi,
        }
    }

    /// True for one plane of black and white.
    pub fn is_bilevel_grey(&self) -> bool {
        self.channels == 1 && self.palette.is_none() && self.levels == 2
    }

    /// An empty halftone of this page's shape (for encoders that must see the whole page).
    pub fn empty_halftone(&self) -> Halftone {
        let mut h = Halftone::new(self.width, self.height, self.channels, self.levels);
        h.palette = self.palette.clone();
        h
    }
}

/// A band of consecutive packed rows: `planes[c]` holds `rows × stride` bytes of plane `c`.
#[derive(Clone, Copy, Debug)]
pub struct Band<'a> {
    /// Index of the band's first row within the page.
    pub y: usize,
    /// Number of rows.
    pub rows: usize,
    /// One slice per plane, `rows × stride` bytes each.
    pub planes: &'a [&'a [u8]],
}

impl<'a> Band<'a> {
    /// Row `r` of the band in each plane (up to three; unused entries are empty), for rows
    /// of `stride` bytes.
    pub fn row(&self, r: usize, stride: usize) -> [&'a [u8]; 3] {
        let mut rows: [&[u8]; 3] = [&[]; 3];
        for (row, pl) in rows.iter_mut().zip(self.planes) {
            *row = &pl[r * stride..(r + 1) * stride];
        }
        rows
    }
}

/// An output format: pages of packed rows in, bytes out.
pub trait PageEncoder {
    /// Starts a page. Single-image formats refuse a second page.
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult;

    /// The next band of rows of the current page, top to bottom.
    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult;

    /// Ends the current page.
    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult;

    /// Ends the file after the last page (trailers, cross-references).
    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        out.flush()?;
        Ok(())
    }
}

/// Counts a page of a single-image format: an error from the second page on.
pub fn one_page_only(pages: &mut usize) -> Result<(), super::EncodeError> {
    if *pages > 0 {
        return Err(super::EncodeError::Other(
            "this format holds one image; write each page to its own file".into(),
        ));
    }
    *pages += 1;
    Ok(())
}

/// The page an encoder is writing, for a band of its rows: an error if no page was begun.
/// Every encoder's `write_rows` opens with it.
pub fn page_for_rows<P>(page: &mut Option<P>) -> Result<&mut P, super::EncodeError> {
    page.as_mut().ok_or_else(rows_before_a_page)
}

/// Takes the page an encoder is writing, for a band of its rows (the encoder puts it back
/// after): an error if no page was begun.
pub fn take_page_for_rows<P>(page: &mut Option<P>) -> Result<P, super::EncodeError> {
    page.take().ok_or_else(rows_before_a_page)
}

fn rows_before_a_page() -> super::EncodeError {
    super::EncodeError::Other("rows before a page".into())
}

/// Takes the page an encoder was writing, at its end: an error if no page was begun or if
/// fewer or more rows arrived than the page has. `rows(page)` gives (rows written, height).
pub fn take_complete_page<P>(
    page: &mut Option<P>,
    rows: impl FnOnce(&P) -> (usize, usize),
) -> Result<P, super::EncodeError> {
    let p = page
        .take()
        .ok_or_else(|| super::EncodeError::Other("end of a page never begun".into()))?;
    let (done, height) = rows(&p);
    if done != height {
        return Err(super::EncodeError::Other(format!(
            "page of {height} rows ended after {done}"
        )));
    }
    Ok(p)
}

/// Runs a whole halftone through an encoder as one page of one band.
pub fn encode_halftone(
    enc: &mut dyn PageEncoder,
    h: &Halftone,
    dpi: Option<f64>,
    out: &mut dyn Write,
) -> EncodeResult {
    enc.begin_page(&PageHeader::of(h, dpi), out)?;
    let planes: Vec<&[u8]> = h.planes.iter().map(Vec::as_slice).collect();
    enc.write_rows(
        &Band {
            y: 0,
            rows: h.height,
            planes: &planes,
        },
        out,
    )?;
    enc.end_page(out)
}

/// An encoder for a format that needs the whole page at once: gathers the bands into a
/// [`Halftone`], then hands it to `write` at the end of the page. One page only.
pub struct WholePage<F> {
    write: F,
    page: Option<(Halftone, Option<f64>)>,
    pages: usize,
    filled: usize,
}

impl<F> WholePage<F>
where
    F: FnMut(&Halftone, Option<f64>, &mut dyn Write) -> EncodeResult,
{
    /// An encoder that calls `write(halftone, dpi, out)` once the page is complete.
    pub fn new(write: F) -> WholePage<F> {
        WholePage {
            write,
            page: None,
            pages: 0,
            filled: 0,
        }
    }
}

impl<F> PageEncoder for WholePage<F>
where
    F: FnMut(&Halftone, Option<f64>, &mut dyn Write) -> EncodeResult,
{
    fn begin_page(&mut self, page: &PageHeader, _out: &mut dyn Write) -> EncodeResult {
        one_page_only(&mut self.pages)?;
        self.filled = 0;
        self.page = Some((page.empty_halftone(), page.dpi));
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, _out: &mut dyn Write) -> EncodeResult {
        let (h, _) = page_for_rows(&mut self.page)?;
        let (start, len) = (band.y * h.stride, band.rows * h.stride);
        for (dst, src) in h.planes.iter_mut().zip(band.planes) {
            dst[start..start + len].copy_from_slice(&src[..len]);
        }
        self.filled += band.rows;
        Ok(())
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let filled = self.filled;
        let (h, dpi) = take_complete_page(&mut self.page, |(h, _)| (filled, h.height))?;
        (self.write)(&h, dpi, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_page_gathers_bands_in_order() {
        let mut h = Halftone::new(10, 5, 1, 2);
        for y in 0..5 {
            for x in 0..10 {
                h.set(0, x, y, ((x + 2 * y) % 3 == 0) as u8);
            }
        }
        let mut got = None;
        let mut enc = WholePage::new(|page: &Halftone, _dpi, _out: &mut dyn Write| {
            got = Some(page.clone());
            Ok(())
        });
        let mut sink = Vec::new();
        enc.begin_page(&PageHeader::of(&h, None), &mut sink)
            .unwrap();
        for (y, rows) in [(0usize, 2usize), (2, 1), (3, 2)] {
            let planes = [&h.planes[0][y * h.stride..(y + rows) * h.stride]];
            enc.write_rows(
                &Band {
                    y,
                    rows,
                    planes: &planes,
                },
                &mut sink,
            )
            .unwrap();
        }
        enc.end_page(&mut sink).unwrap();
        assert!(enc
            .begin_page(&PageHeader::of(&h, None), &mut sink)
            .is_err());
        drop(enc);
        assert_eq!(got.unwrap(), h);
    }
}
