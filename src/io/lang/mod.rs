//! What the printer languages share: their options (page size, head width, banding,
//! label length), the checks that refuse a page before a byte is written, and the row
//! conversions from level indices to the bits a printer prints (1 = a dot of ink).
//!
//! Every printer language is one file here holding both directions: its encoder, a
//! [`PageEncoder`](super::sink::PageEncoder) taking packed rows as they come and knowing
//! nothing of the method, and its reference decoder (`decode`), written from the same
//! manual and checked in the tests against independent encoders and decoders (netpbm's
//! `pbmtolj`, Ghostscript, python-escpos, zebrafy, poppler, qpdf). [`readback`] finds a
//! file's language from its first bytes and reads its pages back as images, so `compare`
//! measures exactly the bits a printer receives.
//!
//! The decoders decode what a printer would accept, not only halftone's own output, within
//! bounds on what a header may claim, and never panic: anything else is a [`DecodeError`].
//! What they share (the error, byte access, bitmaps, the image dictionaries of PDF and
//! PostScript) is at the end of this file.
//!
//! The raster formats IPP Everywhere and AirPrint clients send are read here too, as input
//! for the print server: [`pwg`] (PWG raster, `image/pwg-raster`, PWG 5102.4) and [`urf`]
//! (Apple raster, `image/urf`); [`cups_raster`] writes them, and CUPS raster v3, for
//! `halftone print` and printers that take raster.

pub mod cups_raster;
pub mod escpos;
pub mod pcl;
pub mod pdf;
pub mod ps;
pub mod pwg;
pub mod readback;
pub mod urf;
pub mod zpl;

use super::sink::PageHeader;
use crate::raster::Image;
use crate::tone::linear_to_srgb;

/// A physical page size in PostScript points (1/72 inch).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PageSize {
    /// Width in points.
    pub width: f64,
    /// Height in points.
    pub height: f64,
    /// The PCL 5 page size code (`ESC & l # A`), for the sizes PCL names.
    pub pcl_code: Option<u32>,
}

impl std::str::FromStr for PageSize {
    type Err = String;

    /// `a4`, `letter`, or `WxH` with a unit `in` or `mm` (`4x6in`, `210x297mm`).
    fn from_str(s: &str) -> Result<PageSize, String> {
        let bad =
            || format!("`page` {s}: expected a4, letter, or WxH in in or mm (4x6in, 100x150mm)");
        let t = s.trim().to_ascii_lowercase();
        match t.as_str() {
            // ISO 216: 210 × 297 mm; PCL 5 codes from the PCL 5 Technical Reference (Page Size).
            "a4" => {
                return Ok(PageSize {
                    width: 210.0 / 25.4 * 72.0,
                    height: 297.0 / 25.4 * 72.0,
                    pcl_code: Some(26),
                })
            }
            "letter" => {
                return Ok(PageSize {
                    width: 612.0,
                    height: 792.0,
                    pcl_code: Some(2),
                })
            }
            _ => {}
        }
        let (dims, per_unit) = if let Some(d) = t.strip_suffix("in") {
            (d, 72.0)
        } else if let Some(d) = t.strip_suffix("mm") {
            (d, 72.0 / 25.4)
        } else {
            return Err(bad());
        };
        let (w, h) = dims.split_once('x').ok_or_else(bad)?;
        let (w, h): (f64, f64) = (
            w.trim().parse().map_err(|_| bad())?,
            h.trim().parse().map_err(|_| bad())?,
        );
        if !(w.is_finite() && h.is_finite() && w > 0.0 && h > 0.0 && w < 1e4 && h < 1e4) {
            return Err(bad());
        }
        Ok(PageSize {
            width: w * per_unit,
            height: h * per_unit,
            pcl_code: None,
        })
    }
}

/// ZPL `^GF` data encodings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ZplEncoding {
    /// Hexadecimal with Zebra's ASCII compression (repeat counts G–Y, g–z, `,` `!` `:`).
    #[default]
    Hex,
    /// `:Z64:` zlib-compressed bytes in base64, with a CRC-16 of the base64 text.
    Z64,
}

/// Options of the printer languages; each format reads the ones that concern it.
#[derive(Clone, Debug, PartialEq)]
pub struct PrintOptions {
    /// PDF, PostScript and PCL: a page to centre the image on (default: the image's own size).
    pub page: Option<PageSize>,
    /// ESC/POS: rows per `GS v 0` band (1..=960).
    pub band_rows: usize,
    /// ESC/POS: feed and cut after each page.
    pub cut: bool,
    /// ESC/POS: the print head's width in dots; a wider page is refused.
    pub paper_width: Option<usize>,
    /// ZPL: the `^GF` data encoding.
    pub zpl_encoding: ZplEncoding,
    /// ZPL: the printer's longest label in dots (`^LL` takes at most 32000).
    pub max_length: usize,
}

/// Longest `GS v 0` band: many printers' receive buffers hold no more (python-escpos and
/// LPrint use the same limit).
pub const MAX_BAND_ROWS: usize = 960;

/// The largest `^LL` label length ZPL II accepts, in dots (ZPL II Programming Guide, `^LL`).
pub const ZPL_MAX_LENGTH: usize = 32000;

impl Default for PrintOptions {
    fn default() -> Self {
        PrintOptions {
            page: None,
            band_rows: MAX_BAND_ROWS,
            cut: false,
            paper_width: None,
            zpl_encoding: ZplEncoding::Hex,
            max_length: ZPL_MAX_LENGTH,
        }
    }
}

/// The printer formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Language {
    /// PDF.
    Pdf,
    /// PostScript level 2.
    Ps,
    /// PCL 5 raster.
    Pcl,
    /// ESC/POS raster (`GS v 0`).
    EscPos,
    /// ZPL II graphic fields.
    Zpl,
    /// PWG raster (`RaS2`).
    Pwg,
    /// Apple raster (`UNIRAST`).
    Urf,
    /// CUPS raster version 3 (`RaS3`).
    CupsRaster,
}

impl Language {
    /// The printer language a file is written in, from its first bytes: `%PDF-`, `%!PS`,
    /// PCL's reset (`ESC E`) or a PJL job header, ESC/POS's initialise (`ESC @`), ZPL's `^XA`,
    /// the raster sync words `RaS2`, `UNIRAST`, `RaS3`.
    pub fn sniff(head: &[u8]) -> Option<Language> {
        let text = head.trim_ascii_start();
        if pwg::is_pwg(head) {
            Some(Language::Pwg)
        } else if urf::is_urf(head) {
            Some(Language::Urf)
        } else if head.starts_with(cups_raster::SYNC_V3) {
            Some(Language::CupsRaster)
        } else if head.starts_with(b"%PDF-") {
            Some(Language::Pdf)
        } else if head.starts_with(b"%!PS") {
            Some(Language::Ps)
        } else if head.starts_with(b"\x1bE") || head.starts_with(b"\x1b%-12345X") {
            Some(Language::Pcl)
        } else if head.starts_with(b"\x1b@") {
            Some(Language::EscPos)
        } else if text.starts_with(b"^XA") {
            Some(Language::Zpl)
        } else {
            None
        }
    }

    /// The pages of a printer-language file as images (see the module's notes on codes).
    pub fn pages(self, data: &[u8]) -> DecodeResult<Vec<Image>> {
        match self {
            Language::Pdf => pdf::decode(data),
            Language::Ps => ps::decode(data),
            Language::Pcl => Ok(pcl::decode(data)?
                .iter()
                .map(|r| {
                    let width = r.rows.iter().map(Vec::len).max().unwrap_or(0) * 8;
                    Bitmap::image(&r.bitmap(width), Some(r.dpi as f64))
                })
                .collect()),
            Language::EscPos => Ok(vec![Bitmap::image(&escpos::decode(data)?.bitmap, None)]),
            Language::Zpl => Ok(zpl::decode(data)?
                .iter()
                .map(|b| Bitmap::image(b, None))
                .collect()),
            Language::Pwg => {
                let name = std::path::Path::new("PWG raster");
                let pages = pwg::pages(data, name, &Default::default());
                pages
                    .and_then(|p| p.collect())
                    .map_err(|e| DecodeError(e.to_string()))
            }
            Language::Urf => {
                let name = std::path::Path::new("Apple raster");
                let pages = urf::pages(data, name, &Default::default());
                pages
                    .and_then(|p| p.collect())
                    .map_err(|e| DecodeError(e.to_string()))
            }
            Language::CupsRaster => cups_raster::decode_v3(data),
        }
    }

    /// The language's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Language::Pdf => "PDF",
            Language::Ps => "PostScript",
            Language::Pcl => "PCL",
            Language::EscPos => "ESC/POS",
            Language::Zpl => "ZPL",
            Language::Pwg => "PWG raster",
            Language::Urf => "Apple raster",
            Language::CupsRaster => "CUPS raster",
        }
    }
}

/// PCL 5 raster resolutions (`ESC * t # R`).
pub const PCL_RESOLUTIONS: [u32; 6] = [75, 100, 150, 200, 300, 600];

/// Resolution of a PDF, PostScript or PCL page when none is given and the image records
/// none: a common printer resolution, so a photo prints at a sensible size rather than one
/// pixel a point.
pub const DEFAULT_PAGE_DPI: f64 = 300.0;

/// The resolution a page in `lang` is written at when no `--dpi` is given: the image's
/// `recorded` one when the language can print at it, else [`DEFAULT_PAGE_DPI`]. `None`
/// for ESC/POS and ZPL, which print one dot a pixel whatever the resolution.
pub fn default_dpi(lang: Language, recorded: Option<f64>) -> Option<f64> {
    let usable = |d: f64| match lang {
        Language::Pcl => PCL_RESOLUTIONS.iter().any(|&r| r as f64 == d),
        _ => d.is_finite() && d > 0.0,
    };
    match lang {
        Language::EscPos | Language::Zpl => None,
        _ => Some(recorded.filter(|&d| usable(d)).unwrap_or(DEFAULT_PAGE_DPI)),
    }
}

/// The page's resolution for the page-description languages.
pub fn page_dpi(page: &PageHeader) -> f64 {
    page.dpi.unwrap_or(DEFAULT_PAGE_DPI)
}

/// Image size in points at `dpi`.
pub fn image_points(page: &PageHeader, dpi: f64) -> (f64, f64) {
    (
        page.width as f64 * 72.0 / dpi,
        page.height as f64 * 72.0 / dpi,
    )
}

/// Why `page` cannot be written in `lang` with `opts`, as one line a user can act on.
pub fn check(lang: Language, page: &PageHeader, opts: &PrintOptions) -> Option<String> {
    let grey = page.channels == 1 && page.palette.is_none();
    let bilevel = grey && page.levels == 2;
    let kind = || match (&page.palette, page.channels) {
        (Some(p), _) => format!("a {}-colour palette image", p.len()),
        (None, 3) => format!("RGB with {} levels a channel", page.levels),
        (None, 4) => format!("CMYK with {} levels a plate", page.levels),
        _ => format!("grey with {} levels", page.levels),
    };
    let page_fits = |dpi: f64| -> Option<String> {
        let p = opts.page?;
        let (w, h) = image_points(page, dpi);
        // A hundredth of a point of slack for sizes given in millimetres.
        if w > p.width + 0.01 || h > p.height + 0.01 {
            Some(format!(
                "the image is {:.2} x {:.2} in at {dpi} dpi, larger than the {:.2} x {:.2} in page; pass `width`, `size` or a larger `page`",
                w / 72.0,
                h / 72.0,
                p.width / 72.0,
                p.height / 72.0
            ))
        } else {
            None
        }
    };
    match lang {
        Language::Pdf => {
            if page.channels == 4 && page.palette.is_some() {
                return Some("a palette image has one plane".into());
            }
            page_fits(page_dpi(page))
        }
        Language::Pwg | Language::Urf | Language::CupsRaster => {
            if page.channels == 4 && page.palette.is_none() {
                return Some(format!(
                    "{} pages hold grey, RGB or palette images, this halftone is {}; write PDF for CMYK plates",
                    lang.name(),
                    kind()
                ));
            }
            page_fits(page_dpi(page))
        }
        Language::Ps => {
            if page.channels == 4 {
                return Some(format!(
                    "PostScript output holds grey, RGB or palette images, this halftone is {}; write PDF for CMYK plates",
                    kind()
                ));
            }
            page_fits(page_dpi(page))
        }
        Language::Pcl | Language::EscPos | Language::Zpl if !bilevel => Some(format!(
            "{} prints black and white only, this halftone is {}; use `levels` 2 and `color` gray",
            match lang {
                Language::Pcl => "PCL raster",
                Language::EscPos => "ESC/POS",
                _ => "ZPL",
            },
            kind()
        )),
        Language::Pcl => {
            let dpi = match page.dpi {
                None => {
                    return Some(format!(
                        "PCL raster needs a resolution: pass `dpi`, one of {}",
                        list(&PCL_RESOLUTIONS)
                    ))
                }
                Some(d) => d,
            };
            if !PCL_RESOLUTIONS.iter().any(|&r| r as f64 == dpi) {
                return Some(format!(
                    "PCL raster prints at {} dpi only, not {dpi}; pass one of them with `dpi` (and `width` or `size` to resize)",
                    list(&PCL_RESOLUTIONS)
                ));
            }
            page_fits(dpi)
        }
        Language::EscPos => {
            if !(1..=MAX_BAND_ROWS).contains(&opts.band_rows) {
                return Some(format!(
                    "`band_rows` {}: must be 1 to {MAX_BAND_ROWS}",
                    opts.band_rows
                ));
            }
            match opts.paper_width {
                Some(head) if page.width > head => Some(format!(
                    "the image is {} dots wide, wider than the {head}-dot print head; pass `width` {head} or a preset (thermal-203, thermal-80mm)",
                    page.width
                )),
                // `GS v 0` carries the width in bytes in two bytes.
                _ if page.stride > 0xFFFF => Some(format!(
                    "the image is {} dots wide, too wide for ESC/POS",
                    page.width
                )),
                _ => None,
            }
        }
        Language::Zpl => {
            if page.height > opts.max_length.min(ZPL_MAX_LENGTH) {
                return Some(format!(
                    "the label is {} dots long, over the printer's maximum of {} dots; pass `height`, `width` or `size` to shrink it",
                    page.height,
                    opts.max_length.min(ZPL_MAX_LENGTH)
                ));
            }
            if page.width > ZPL_MAX_LENGTH {
                return Some(format!(
                    "the label is {} dots wide, over ZPL's maximum of {ZPL_MAX_LENGTH}",
                    page.width
                ));
            }
            None
        }
    }
}

fn list(v: &[u32]) -> String {
    let s: Vec<String> = v.iter().map(u32::to_string).collect();
    s.join(", ")
}

/// A packed bilevel row (1 = paper) as printers take it: 1 = a dot of ink, padding bits
/// clear.
pub fn ink_row(row: &[u8], width: usize, out: &mut [u8]) {
    super::invert_bilevel_row(row, width, out);
}

/// Formats a length in points for PDF and PostScript: up to six decimals, no trailing zeros.
pub fn num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// Where the image goes on the page, in points: (x, y of the lower-left corner, page
/// width, page height). Centred on `--page`, else the page is the image.
pub fn placement(page: &PageHeader, opts: &PrintOptions, dpi: f64) -> (f64, f64, f64, f64) {
    let (w, h) = image_points(page, dpi);
    match opts.page {
        Some(p) => ((p.width - w) / 2.0, (p.height - h) / 2.0, p.width, p.height),
        None => (0.0, 0.0, w, h),
    }
}

/// Builds a row as an image of `bits` a sample with the planes interleaved (chunky), the
/// layout PDF and PostScript images take: one plane is its packed row unchanged.
pub struct Chunky {
    bits: u8,
    channels: usize,
    levels: Vec<u8>,
    mixed: Vec<u8>,
    /// The interleaved row.
    pub row: Vec<u8>,
}

impl Chunky {
    /// A builder for pages like `page`.
    pub fn new(page: &PageHeader) -> Chunky {
        let n = page.channels;
        Chunky {
            bits: page.bits,
            channels: n,
            levels: vec![0; page.width],
            mixed: vec![0; page.width * n],
            row: vec![0; (page.width * n * page.bits as usize).div_ceil(8)],
        }
    }

    /// Interleaves row `r` of the band's planes (each `stride` bytes a row) into `self.row`.
    pub fn build(&mut self, planes: &[&[u8]], stride: usize, r: usize) -> &[u8] {
        if self.channels == 1 {
            self.row.clear();
            self.row
                .extend_from_slice(&planes[0][r * stride..(r + 1) * stride]);
            return &self.row;
        }
        for (c, p) in planes.iter().enumerate() {
            crate::raster::unpack_row(
                &p[r * stride..(r + 1) * stride],
                self.bits,
                &mut self.levels,
            );
            for (x, &l) in self.levels.iter().enumerate() {
                self.mixed[x * self.channels + c] = l;
            }
        }
        self.row.fill(0);
        crate::raster::pack_row(&self.mixed, self.bits, &mut self.row);
        &self.row
    }
}

/// The `/Decode` range that maps level indices stored in `bits` bits to 0..1 (level L−1
/// = 1 = paper): `[0 d]` with d = (2^bits − 1)/(L − 1).
pub fn decode_max(bits: u8, levels: u16) -> f64 {
    ((1u32 << bits) - 1) as f64 / (levels - 1) as f64
}

// ---------------------------------------------------------------------------------------
// Decoding: what the decoders share

/// What a reference decoder could not decode.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct DecodeError(String);

/// A decoder's result.
pub type DecodeResult<T> = std::result::Result<T, DecodeError>;

fn fail<T>(msg: impl Into<String>) -> DecodeResult<T> {
    Err(DecodeError(msg.into()))
}

/// The byte at `i`, or an error naming what was cut short.
fn byte(data: &[u8], i: usize, what: &str) -> DecodeResult<u8> {
    match data.get(i) {
        Some(&b) => Ok(b),
        None => fail(format!("cut short in {what} at byte {i}")),
    }
}

/// `n` bytes at `i`, or an error naming what was cut short.
fn bytes<'a>(data: &'a [u8], i: usize, n: usize, what: &str) -> DecodeResult<&'a [u8]> {
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

impl Bitmap {
    /// A bilevel bitmap (1 = ink) as grey codes: ink 0, paper 255.
    fn image(b: &Bitmap, dpi: Option<f64>) -> Image {
        let mut codes = Vec::with_capacity(b.width * b.height);
        for y in 0..b.height {
            codes.extend((0..b.width).map(|x| if b.get(x, y) { 0 } else { 255 }));
        }
        let mut img = Image::gray8(b.width, b.height, codes);
        img.dpi = dpi;
        img
    }
}

/// Largest image a page may declare here, in samples: beyond any page halftone writes
/// within its own pixel limit, so a corrupt header cannot ask for unbounded memory.
const MAX_SAMPLES: u64 = 3 << 30;

/// What an image's samples mean.
#[derive(Clone, Debug, PartialEq)]
enum Space {
    Gray,
    Rgb,
    /// Palette entries, sRGB `r g b`.
    Indexed(Vec<[u8; 3]>),
}

/// One decoded image's header.
#[derive(Clone, Debug)]
struct ImageHead {
    width: usize,
    height: usize,
    bits: u32,
    space: Space,
    /// `/Decode`: the low and high value of each component (ignored for a palette).
    decode: Vec<f64>,
}

impl ImageHead {
    fn components(&self) -> usize {
        if self.space == Space::Rgb {
            3
        } else {
            1
        }
    }

    fn stride(&self) -> usize {
        (self.width * self.components() * self.bits as usize).div_ceil(8)
    }

    fn check(&self) -> DecodeResult<()> {
        if !matches!(self.bits, 1 | 2 | 4 | 8) {
            return fail(format!("{} bits a sample", self.bits));
        }
        let samples = self.width as u64 * self.height as u64 * self.components() as u64;
        if self.width == 0 || self.height == 0 || samples > MAX_SAMPLES {
            return fail(format!("an image of {}x{}", self.width, self.height));
        }
        Ok(())
    }

    /// The image from its rows of packed samples (`stride` bytes each; shorter data is an
    /// error).
    fn image(&self, data: &[u8]) -> DecodeResult<Image> {
        let stride = self.stride();
        if data.len() < stride * self.height {
            return fail(format!(
                "image data cut short: {} bytes of {}",
                data.len(),
                stride * self.height
            ));
        }
        let max = ((1u32 << self.bits) - 1) as f64;
        let sample = |row: &[u8], i: usize| -> u32 {
            let bit = i * self.bits as usize;
            let byte = row[bit / 8] as u32;
            (byte >> (8 - self.bits as usize - bit % 8)) & ((1 << self.bits) - 1)
        };
        // Each component's code for each sample value: the value through /Decode is linear
        // reflectance, stored as its sRGB code like the image files convert writes.
        let tables: Vec<Vec<u8>> = (0..self.components())
            .map(|c| {
                let (lo, hi) = (
                    self.decode.get(2 * c).copied().unwrap_or(0.0),
                    self.decode.get(2 * c + 1).copied().unwrap_or(1.0),
                );
                (0..=max as u32)
                    .map(|v| {
                        let r = (lo + v as f64 * (hi - lo) / max).clamp(0.0, 1.0);
                        (linear_to_srgb(r) * 255.0).round() as u8
                    })
                    .collect()
            })
            .collect();
        let (w, h) = (self.width, self.height);
        let rows = data.chunks_exact(stride).take(h);
        match &self.space {
            Space::Gray => {
                let mut codes = Vec::with_capacity(w * h);
                for row in rows {
                    codes.extend((0..w).map(|x| tables[0][sample(row, x) as usize]));
                }
                Ok(Image::gray8(w, h, codes))
            }
            Space::Rgb => {
                let mut rgb = Vec::with_capacity(w * h * 3);
                for row in rows {
                    rgb.extend((0..w * 3).map(|i| tables[i % 3][sample(row, i) as usize]));
                }
                Ok(Image::rgb8(w, h, &rgb))
            }
            Space::Indexed(pal) => {
                let mut rgb = Vec::with_capacity(w * h * 3);
                for row in rows {
                    for x in 0..w {
                        let i = sample(row, x) as usize;
                        let Some(c) = pal.get(i) else {
                            return fail(format!("palette index {i} of {} colours", pal.len()));
                        };
                        rgb.extend_from_slice(c);
                    }
                }
                Ok(Image::rgb8(w, h, &rgb))
            }
        }
    }
}

/// Finds `needle` in `hay` from `from`.
fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

/// The text of a dictionary value after `key` (up to the next `/` or `>>`, or the whole
/// bracketed array), within `dict`.
fn value<'a>(dict: &'a str, key: &str) -> Option<&'a str> {
    let mut at = 0;
    // A key is followed by a space or a delimiter, so /Width does not match /WidthX.
    loop {
        let p = dict[at..].find(key)? + at;
        let rest = &dict[p + key.len()..];
        if rest.starts_with([' ', '[', '/', '<', '\n']) {
            let rest = rest.trim_start();
            if rest.starts_with('[') {
                return rest.find(']').map(|e| &rest[..=e]);
            }
            let end = rest[1..]
                .find(['/', '>', '['])
                .map_or(rest.len(), |e| e + 1);
            return Some(rest[..end].trim());
        }
        at = p + key.len();
    }
}

fn number(dict: &str, key: &str) -> DecodeResult<usize> {
    value(dict, key)
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .map_or_else(|| fail(format!("no {key} number")), Ok)
}

fn numbers(array: &str) -> Vec<f64> {
    array
        .trim_matches(['[', ']'])
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// The colour space of an image from its `/ColorSpace` text and (for `/Indexed`) the hex
/// palette that follows it.
fn space(cs: &str, after: &str) -> DecodeResult<Space> {
    if cs.starts_with("/DeviceGray") {
        return Ok(Space::Gray);
    }
    if cs.starts_with("/DeviceRGB") {
        return Ok(Space::Rgb);
    }
    if cs.starts_with("[/Indexed") || cs.starts_with("[ /Indexed") {
        let open = after.find('<').map(|i| i + 1);
        let hex = open
            .and_then(|o| after[o..].find('>').map(|e| &after[o..o + e]))
            .unwrap_or("");
        let bytes: Option<Vec<u8>> = hex
            .as_bytes()
            .chunks(2)
            .map(|p| {
                std::str::from_utf8(p)
                    .ok()
                    .and_then(|s| u8::from_str_radix(s, 16).ok())
            })
            .collect();
        let Some(bytes) = bytes.filter(|b| !b.is_empty() && b.len() % 3 == 0) else {
            return fail("an /Indexed colour space without an RGB palette");
        };
        return Ok(Space::Indexed(
            bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        ));
    }
    if cs.contains("/Separation") {
        return fail("CMYK separations; compare reads grey, RGB and palette pages");
    }
    fail(format!("colour space {cs}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_sizes() {
        let a4: PageSize = "A4".parse().unwrap();
        assert!((a4.width - 595.2756).abs() < 1e-3 && (a4.height - 841.8898).abs() < 1e-3);
        let l: PageSize = "4x6in".parse().unwrap();
        assert_eq!((l.width, l.height), (288.0, 432.0));
        let m: PageSize = "100x150mm".parse().unwrap();
        assert!((m.width - 283.4646).abs() < 1e-3);
        for bad in ["4x6", "x6in", "0x6in", "a5", "-1x2mm", "4by6in"] {
            assert!(bad.parse::<PageSize>().is_err(), "{bad}");
        }
    }

    #[test]
    fn numbers() {
        assert_eq!(num(240.0), "240");
        assert_eq!(num(0.24), "0.24");
        assert_eq!(num(1.0 / 3.0), "0.333333");
        assert_eq!(num(-0.0000001), "0");
    }
}
