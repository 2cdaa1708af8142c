//! Writing the CUPS raster family: PWG raster (`RaS2`, PWG 5102.4, `image/pwg-raster`),
//! Apple raster (`UNIRAST`, `image/urf`) and CUPS raster version 3 (`RaS3`, uncompressed,
//! `application/vnd.cups-raster`), the raster formats IPP Everywhere and AirPrint printers
//! and CUPS drivers take. Their readers are [`super::pwg`] and [`super::urf`] (and
//! [`decode_v3`] here); the line compression written is the one they read.
//!
//! What a page becomes (PWG 5102.4 §4.3, the `pwg-raster-document-type-supported` names):
//! - a bilevel grey halftone: `black_1` (colour space 3 = K, 1 bit, 1 = ink), exactly the
//!   halftone's dots; in Apple raster, which has no 1-bit type, `sgray_8` with 0 and 255;
//! - grey levels: `sgray_8` (colour space 18), each level's sRGB code as PGM writes it;
//! - RGB levels or a palette: `srgb_8` (colour space 19; Apple raster sRGB 24 bits).
//!
//! CMYK plates are refused (write PDF). With `page` the raster is the whole page at the
//! resolution and the image is centred on white, as PDF and PostScript place it; without,
//! the page is the image. Pages are kept until the file ends so that each PWG header
//! carries `TotalPageCount` and the Apple raster file header its page count.

use std::io::Write;

use super::pwg::{self, PageHeader as ReadHeader};
use super::{check, image_points, page_dpi, DecodeError, DecodeResult, Language, PrintOptions};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{level_codes8, EncodeError, EncodeResult};
use crate::raster::{unpack_row, Image};
use crate::tone::Encoding;

/// Which file of the family is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// PWG raster (`RaS2`), compressed lines.
    Pwg,
    /// Apple raster (`UNIRAST`), compressed lines, 8-bit grey or 24-bit sRGB.
    Urf,
    /// CUPS raster version 3 (`RaS3`): the same 1796-byte header, uncompressed lines.
    CupsV3,
}

impl Kind {
    fn language(self) -> Language {
        match self {
            Kind::Pwg => Language::Pwg,
            Kind::Urf => Language::Urf,
            Kind::CupsV3 => Language::CupsRaster,
        }
    }
}

/// The samples of a written page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Pixels {
    /// One bit a pixel, 1 = ink (`black_1`).
    Black1,
    /// One byte a pixel, 0 = black (`sgray_8`).
    Gray8,
    /// Three bytes a pixel, sRGB (`srgb_8`).
    Rgb8,
}

impl Pixels {
    fn bits_per_pixel(self) -> usize {
        match self {
            Pixels::Black1 => 1,
            Pixels::Gray8 => 8,
            Pixels::Rgb8 => 24,
        }
    }

    /// Bytes a compression unit (one pixel; one byte of eight pixels for `black_1`).
    fn unit(self) -> usize {
        self.bits_per_pixel().div_ceil(8)
    }

    fn bytes_per_line(self, width: usize) -> usize {
        (width * self.bits_per_pixel()).div_ceil(8)
    }

    /// The byte of a white line.
    fn white(self) -> u8 {
        match self {
            Pixels::Black1 => 0,
            Pixels::Gray8 | Pixels::Rgb8 => 0xff,
        }
    }
}

/// Streaming writer of PWG raster, Apple raster or CUPS raster v3.
pub struct RasterEncoder {
    kind: Kind,
    opts: PrintOptions,
    display: Encoding,
    /// Every page so far (headers and lines), written out by `finish`.
    body: Vec<u8>,
    /// Where each page's header starts in `body`.
    headers: Vec<usize>,
    page: Option<Page>,
}

struct Page {
    header: PageHeader,
    pixels: Pixels,
    /// The page's size in pixels and where the image's corner is on it.
    width: usize,
    height: usize,
    left: usize,
    top: usize,
    /// Image rows received.
    rows: usize,
    /// Page lines emitted (margins included).
    lines: usize,
    /// The line waiting to be written and how many more times it repeats.
    pending: Option<(Vec<u8>, usize)>,
    table: [u8; 256],
    levels: Vec<u8>,
}

impl RasterEncoder {
    /// A writer of `kind`; `display` maps grey and colour levels to codes as PGM and PNG do.
    pub fn new(kind: Kind, opts: PrintOptions, display: Encoding) -> RasterEncoder {
        RasterEncoder {
            kind,
            opts,
            display,
            body: Vec::new(),
            headers: Vec::new(),
            page: None,
        }
    }

    /// Appends one page line, merging repeats (compressed kinds) or writing it raw (v3).
    fn push_line(kind: Kind, body: &mut Vec<u8>, p: &mut Page, line: Vec<u8>) {
        p.lines += 1;
        if kind == Kind::CupsV3 {
            body.extend_from_slice(&line);
            return;
        }
        match &mut p.pending {
            Some((prev, rep)) if *prev == line && *rep < 255 => *rep += 1,
            _ => {
                Self::flush(body, p);
                p.pending = Some((line, 0));
            }
        }
    }

    fn flush(body: &mut Vec<u8>, p: &mut Page) {
        if let Some((line, rep)) = p.pending.take() {
            body.push(rep as u8);
            compress_line(&line, p.pixels.unit(), body);
        }
    }

    fn white_line(p: &Page) -> Vec<u8> {
        vec![p.pixels.white(); p.pixels.bytes_per_line(p.width)]
    }
}

/// Compresses one line as PWG and Apple raster read it: runs of whole units, a control
/// byte below 128 repeating the next unit (control + 1) times, above 128 (257 − control)
/// units following as they are.
pub fn compress_line(line: &[u8], unit: usize, out: &mut Vec<u8>) {
    let n = line.len() / unit;
    let px = |i: usize| &line[i * unit..(i + 1) * unit];
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && j - i < 128 && px(j) == px(i) {
            j += 1;
        }
        if j - i >= 2 {
            out.push((j - i - 1) as u8);
            out.extend_from_slice(px(i));
            i = j;
            continue;
        }
        let start = i;
        i += 1;
        while i < n && i - start < 128 && !(i + 1 < n && px(i) == px(i + 1)) {
            i += 1;
        }
        let count = i - start;
        out.push(if count == 1 { 0 } else { (257 - count) as u8 });
        out.extend_from_slice(&line[start * unit..i * unit]);
    }
}

fn put(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_be_bytes());
}

fn put_str(b: &mut [u8], at: usize, s: &str) {
    b[at..at + s.len()].copy_from_slice(s.as_bytes());
}

/// Offset of `TotalPageCount` in a PWG page header.
const TOTAL_PAGE_COUNT: usize = 452;

/// The 1796-byte page header of PWG raster (PWG 5102.4 §4.3) or CUPS raster v3
/// (`cups_page_header2_t`), big-endian.
fn full_header(kind: Kind, p: &Page, dpi: u32) -> Vec<u8> {
    let mut h = vec![0u8; pwg::HEADER_BYTES];
    let (cs, colors) = match p.pixels {
        Pixels::Black1 => (3, 1),
        Pixels::Gray8 => (18, 1),
        Pixels::Rgb8 => (19, 3),
    };
    let bpp = p.pixels.bits_per_pixel() as u32;
    // Points, as PWG and CUPS round them.
    let pts = |px: usize| (px as f64 * 72.0 / dpi as f64).round() as u32;
    let (pw, ph) = (pts(p.width), pts(p.height));
    if kind == Kind::Pwg {
        put_str(&mut h, 0, "PwgRaster");
    }
    put(&mut h, 276, dpi); // HWResolution
    put(&mut h, 280, dpi);
    put(&mut h, 340, 1); // NumCopies
    put(&mut h, 352, pw); // PageSize, points
    put(&mut h, 356, ph);
    put(&mut h, 372, p.width as u32);
    put(&mut h, 376, p.height as u32);
    put(&mut h, 384, if bpp == 1 { 1 } else { 8 }); // BitsPerColor
    put(&mut h, 388, bpp);
    put(&mut h, 392, p.pixels.bytes_per_line(p.width) as u32);
    put(&mut h, 396, 0); // chunky
    put(&mut h, 400, cs);
    put(&mut h, 420, colors); // NumColors
    match kind {
        Kind::Pwg => {
            // TotalPageCount (452) is filled in at the end of the file.
            put(&mut h, 456, 1); // CrossFeedTransform
            put(&mut h, 460, 1); // FeedTransform
            put(&mut h, 464, p.left as u32); // ImageBox, pixels
            put(&mut h, 468, p.top as u32);
            put(&mut h, 472, (p.left + p.header.width) as u32);
            put(&mut h, 476, (p.top + p.header.height) as u32);
            put(&mut h, 480, 0x00ff_ffff); // AlternatePrimary: white
        }
        Kind::CupsV3 | Kind::Urf => {
            // ImagingBoundingBox in points, then the same as floats.
            put(&mut h, 292, pw);
            put(&mut h, 296, ph);
            put(&mut h, 424, 1.0f32.to_bits()); // cupsBorderlessScalingFactor
            put(&mut h, 428, (pw as f32).to_bits()); // cupsPageSize
            put(&mut h, 432, (ph as f32).to_bits());
            put(&mut h, 444, (pw as f32).to_bits()); // cupsImagingBBox right, top
            put(&mut h, 448, (ph as f32).to_bits());
        }
    }
    h
}

/// The 32-byte page header of Apple raster.
fn urf_header(p: &Page, dpi: u32) -> Vec<u8> {
    let mut h = vec![0u8; super::urf::HEADER_BYTES];
    let (bits, cs) = match p.pixels {
        Pixels::Rgb8 => (24, 1),
        _ => (8, 0),
    };
    h[0] = bits;
    h[1] = cs;
    put(&mut h, 12, p.width as u32);
    put(&mut h, 16, p.height as u32);
    put(&mut h, 20, dpi);
    h
}

impl PageEncoder for RasterEncoder {
    fn begin_page(&mut self, page: &PageHeader, _out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = check(self.kind.language(), page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        if self.page.is_some() {
            return Err(EncodeError::Other("a page begun inside a page".into()));
        }
        let dpi = page_dpi(page);
        let rdpi = dpi.round();
        if !(1.0..=10_000.0).contains(&rdpi) || (dpi - rdpi).abs() > 1e-6 {
            return Err(EncodeError::Other(format!(
                "raster pages take a whole resolution from 1 to 10000 dpi, not {dpi}; pass `dpi`"
            )));
        }
        let pixels = if page.palette.is_some() || page.channels == 3 {
            Pixels::Rgb8
        } else if page.levels == 2 && self.kind != Kind::Urf {
            Pixels::Black1
        } else {
            Pixels::Gray8
        };
        let (mut width, mut height, mut left, mut top) = (page.width, page.height, 0, 0);
        if let Some(size) = self.opts.page {
            let (w, h) = image_points(page, dpi);
            let px = |pt: f64| (pt * dpi / 72.0).round().max(0.0) as usize;
            width = px(size.width).max(page.width);
            height = px(size.height).max(page.height);
            left = px((size.width - w) / 2.0).min(width - page.width);
            top = px((size.height - h) / 2.0).min(height - page.height);
        }
        let table = if pixels == Pixels::Black1 || page.palette.is_some() {
            [0; 256]
        } else {
            level_codes8(page.levels, self.display)
        };
        let mut p = Page {
            header: page.clone(),
            pixels,
            width,
            height,
            left,
            top,
            rows: 0,
            lines: 0,
            pending: None,
            table,
            levels: vec![0; page.width],
        };
        self.headers.push(self.body.len());
        let head = match self.kind {
            Kind::Urf => urf_header(&p, rdpi as u32),
            _ => full_header(self.kind, &p, rdpi as u32),
        };
        self.body.extend_from_slice(&head);
        for _ in 0..top {
            let white = Self::white_line(&p);
            Self::push_line(self.kind, &mut self.body, &mut p, white);
        }
        self.page = Some(p);
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, _out: &mut dyn Write) -> EncodeResult {
        let mut p = crate::io::sink::take_page_for_rows(&mut self.page)?;
        let h = &p.header;
        let (stride, bits, w) = (h.stride, h.bits, h.width);
        for r in 0..band.rows {
            if p.rows == p.header.height {
                self.page = Some(p);
                return Err(EncodeError::Other("more rows than the page has".into()));
            }
            let mut line = Self::white_line(&p);
            let rows = band.row(r, stride);
            match p.pixels {
                Pixels::Black1 => {
                    unpack_row(rows[0], bits, &mut p.levels);
                    for (x, &l) in p.levels.iter().enumerate() {
                        if l == 0 {
                            let at = p.left + x;
                            line[at / 8] |= 0x80 >> (at % 8);
                        }
                    }
                }
                Pixels::Gray8 => {
                    unpack_row(rows[0], bits, &mut p.levels);
                    for (x, &l) in p.levels.iter().enumerate() {
                        line[p.left + x] = p.table[l as usize];
                    }
                }
                Pixels::Rgb8 => {
                    if let Some(pal) = &p.header.palette {
                        unpack_row(rows[0], bits, &mut p.levels);
                        for (x, &l) in p.levels.iter().enumerate() {
                            let at = (p.left + x) * 3;
                            line[at..at + 3].copy_from_slice(&pal[l as usize]);
                        }
                    } else {
                        for (c, row) in rows.iter().enumerate().take(3) {
                            unpack_row(row, bits, &mut p.levels);
                            for x in 0..w {
                                line[(p.left + x) * 3 + c] = p.table[p.levels[x] as usize];
                            }
                        }
                    }
                }
            }
            Self::push_line(self.kind, &mut self.body, &mut p, line);
            p.rows += 1;
        }
        self.page = Some(p);
        Ok(())
    }

    fn end_page(&mut self, _out: &mut dyn Write) -> EncodeResult {
        let mut p = crate::io::sink::take_complete_page(&mut self.page, |p: &Page| {
            (p.rows, p.header.height)
        })?;
        while p.lines < p.height {
            let white = Self::white_line(&p);
            Self::push_line(self.kind, &mut self.body, &mut p, white);
        }
        Self::flush(&mut self.body, &mut p);
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        if self.page.is_some() {
            return Err(EncodeError::Other("the file ended inside a page".into()));
        }
        let pages = self.headers.len() as u32;
        match self.kind {
            Kind::Pwg => {
                for &at in &self.headers {
                    put(&mut self.body, at + TOTAL_PAGE_COUNT, pages);
                }
                out.write_all(pwg::SYNC)?;
            }
            Kind::CupsV3 => out.write_all(SYNC_V3)?,
            Kind::Urf => {
                out.write_all(super::urf::SYNC)?;
                out.write_all(&pages.to_be_bytes())?;
            }
        }
        out.write_all(&self.body)?;
        self.body = Vec::new();
        self.headers.clear();
        out.flush()?;
        Ok(())
    }
}

/// The first bytes of a CUPS raster version 3 file (big-endian, uncompressed).
pub const SYNC_V3: &[u8; 4] = b"RaS3";

/// The pages of a big-endian CUPS raster version 3 file (uncompressed lines), as images:
/// the reference decoder of what [`RasterEncoder`] writes with [`Kind::CupsV3`].
pub fn decode_v3(data: &[u8]) -> DecodeResult<Vec<Image>> {
    if !data.starts_with(SYNC_V3) {
        return Err(DecodeError("not a CUPS raster v3 file (no RaS3)".into()));
    }
    let mut pos = SYNC_V3.len();
    let mut pages = Vec::new();
    while pos < data.len() {
        let n = pages.len() + 1;
        let err = |m: String| DecodeError(format!("page {n}: {m}"));
        let head = super::bytes(data, pos, pwg::HEADER_BYTES, "a page header")?;
        let h: ReadHeader = pwg::parse_header(head).map_err(err)?;
        let pixels = h.width as u64 * h.height as u64;
        if pixels > super::MAX_SAMPLES {
            return Err(err(format!("a page of {}x{}", h.width, h.height)));
        }
        pos += pwg::HEADER_BYTES;
        let img = pwg::decode_lines(data, &mut pos, &h, false).map_err(err)?;
        pages.push(img);
    }
    Ok(pages)
}

#[cfg(test)]
mod tests {
    use super::pwg::Space;
    use super::*;
    use crate::io::{self, Format, WriteOptions};
    use crate::raster::{Halftone, Samples};
    use std::path::Path;

    fn be(b: &[u8], at: usize) -> u32 {
        u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
    }

    fn pattern(w: usize, h: usize, levels: u16) -> Halftone {
        let mut ht = Halftone::new(w, h, 1, levels);
        for y in 0..h {
            for x in 0..w {
                let v = ((x * 7 + y * 3 + x * y) % 11 % levels as usize) as u8;
                ht.set(0, x, y, v);
            }
        }
        ht
    }

    fn encode(h: &Halftone, f: Format, dpi: f64, page: Option<&str>) -> Vec<u8> {
        let mut o = WriteOptions::new(f);
        o.dpi = Some(dpi);
        o.print.page = page.map(|p| p.parse().unwrap());
        let mut out = Vec::new();
        io::encode(h, &o, Path::new("t"), &mut out).unwrap();
        out
    }

    fn grey(img: &Image) -> Vec<u8> {
        match &img.planes[0] {
            Samples::U8(v) => v.clone(),
            Samples::U16(_) => panic!("16-bit"),
        }
    }

    #[test]
    fn compressed_lines_decode_to_themselves() {
        let lines: [&[u8]; 6] = [
            &[1, 1, 1, 1, 2, 3, 4, 4, 5],
            &[9],
            &[0; 300],
            &[1, 2, 1, 2, 1, 2, 1, 2, 1, 2, 1, 2],
            &[7, 7],
            &[1, 2, 3, 3],
        ];
        for line in lines {
            let mut c = vec![0u8];
            compress_line(line, 1, &mut c);
            let h = ReadHeader {
                width: line.len() as u32,
                height: 1,
                bits_per_color: 8,
                space: Space::Gray,
                dpi: (300, 300),
            };
            let img = pwg::decode_lines(&c, &mut 0, &h, true).unwrap();
            assert_eq!(grey(&img), line);
        }
        // Long literal and long runs split at 128 units.
        let line: Vec<u8> = (0..1000).map(|i| (i * 37 % 251) as u8).collect();
        let mut c = vec![0u8];
        compress_line(&line, 1, &mut c);
        assert!(c.len() < line.len() + 20);
    }

    #[test]
    fn pwg_headers_say_what_the_spec_asks() {
        let ht = pattern(37, 11, 2);
        let f = encode(&ht, Format::Pwg, 203.0, None);
        assert_eq!(&f[..4], b"RaS2");
        let h = &f[4..4 + 1796];
        assert_eq!(&h[..10], b"PwgRaster\0");
        assert_eq!((be(h, 276), be(h, 280)), (203, 203));
        assert_eq!((be(h, 372), be(h, 376)), (37, 11));
        // PageSize in points: 37 px at 203 dpi = 13.1 pt.
        assert_eq!((be(h, 352), be(h, 356)), (13, 4));
        // black_1: colour space K, 1 bit, 5 bytes a line, one colour.
        assert_eq!((be(h, 384), be(h, 388), be(h, 392)), (1, 1, 5));
        assert_eq!((be(h, 396), be(h, 400), be(h, 420)), (0, 3, 1));
        assert_eq!((be(h, 452), be(h, 456), be(h, 460)), (1, 1, 1));
        assert_eq!((be(h, 472), be(h, 476)), (37, 11));
        // Levels: sgray_8; colour: srgb_8.
        let f = encode(&pattern(5, 3, 4), Format::Pwg, 300.0, None);
        assert_eq!((be(&f, 4 + 384), be(&f, 4 + 400)), (8, 18));
        // Two pages: each header counts both.
        let mut o = WriteOptions::new(Format::Pwg);
        o.dpi = Some(300.0);
        let mut enc = io::page_encoder(&o);
        let mut out = Vec::new();
        for _ in 0..2 {
            io::sink::encode_halftone(enc.as_mut(), &ht, o.dpi, &mut out).unwrap();
        }
        enc.finish(&mut out).unwrap();
        let pages: Vec<Image> = pwg::pages(&out, Path::new("t"), &Default::default())
            .unwrap()
            .collect::<crate::error::Result<_>>()
            .unwrap();
        assert_eq!(pages.len(), 2);
        let second = out.len() - (out.len() - 4) / 2;
        assert_eq!(be(&out, 4 + 452), 2);
        assert_eq!(be(&out, second + 452), 2);
    }

    #[test]
    fn every_kind_reads_back_the_bits_and_levels() {
        for levels in [2u16, 4] {
            let ht = pattern(37, 11, levels);
            let want: Vec<u8> = ht
                .levels_of(0)
                .iter()
                .map(|&k| io::level_code(k, levels, 255, Encoding::Srgb) as u8)
                .collect();
            for f in [Format::Pwg, Format::Urf, Format::CupsRaster] {
                let data = encode(&ht, f, 300.0, None);
                let lang = Language::sniff(&data).unwrap();
                let pages = lang.pages(&data).unwrap();
                assert_eq!(pages.len(), 1);
                assert_eq!((pages[0].width, pages[0].height), (37, 11), "{f:?}");
                assert_eq!(grey(&pages[0]), want, "{f:?} {levels}");
                assert_eq!(pages[0].dpi, Some(300.0));
            }
        }
        // URF's file header counts the pages.
        let data = encode(&pattern(3, 2, 2), Format::Urf, 300.0, None);
        assert_eq!(be(&data, 8), 1);
        assert_eq!(data[12], 8);
    }

    #[test]
    fn a_page_centres_the_image_on_white() {
        let ht = pattern(10, 4, 2);
        // 1x1 in at 20 dpi: 20x20 pixels, the image at (5, 8).
        let data = encode(&ht, Format::Pwg, 20.0, Some("1x1in"));
        let img = Language::Pwg.pages(&data).unwrap().pop().unwrap();
        assert_eq!((img.width, img.height), (20, 20));
        assert_eq!((be(&data, 4 + 352), be(&data, 4 + 356)), (72, 72));
        let g = grey(&img);
        let lv = ht.levels_of(0);
        for y in 0..20 {
            for x in 0..20 {
                let inside = (5..15).contains(&x) && (8..12).contains(&y);
                let want = if inside {
                    lv[(y - 8) * 10 + x - 5] * 255
                } else {
                    255
                };
                assert_eq!(g[y * 20 + x], want, "{x},{y}");
            }
        }
        // A page smaller than the image: refused with a line naming the sizes.
        let mut o = WriteOptions::new(Format::Pwg);
        o.dpi = Some(2.0);
        o.print.page = Some("1x1in".parse().unwrap());
        let e = io::encode(&ht, &o, Path::new("t.pwg"), &mut Vec::new()).unwrap_err();
        assert!(e.to_string().contains("larger than"), "{e}");
    }
}
