//! Reading images (with a pixel limit checked before allocation) and writing halftones in
//! printer-ready formats, atomically.
//!
//! Reading goes through the `image` crate, except binary PGM/PBM (P5/P4), which have a
//! fast path of their own ([`pnm`]): a header parse and one read straight into the plane.
//! Writing is one small encoder per format; every encoder takes the packed rows of a
//! [`Halftone`] and maps them to the format's own bit meaning (1 = black in PBM and
//! WhiteIsZero TIFF, 1 = white in grey PNG, palette indices in BMP).

mod atomic;
pub mod codec;
pub mod lang;
mod limits;
pub mod panel;
pub mod sink;
mod stream;

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};
use crate::raster::Halftone;
use crate::tone::{linear_to_srgb, Encoding};

pub(crate) use atomic::write_atomic_with;
pub use atomic::{parse_temp_name, this_host, write_atomic, OutputFile, TempWriter};
#[cfg(feature = "cli")]
pub use atomic::{remove_temp_files, remove_temp_files_and_hold};
pub(crate) use codec::read::{composite16, composite8};
pub use codec::read::{
    decode_budget, decoding_on_this_thread, read_dimensions, read_image, read_image_bytes,
    read_text,
};
pub use limits::max_input_bytes;
pub(crate) use limits::{check_pixels, decode_err};
pub use stream::{is_stream, read_stream};

/// Limits and choices for decoding.
#[derive(Clone, Debug)]
pub struct ReadOptions {
    /// Refuse images whose header claims more pixels than this.
    pub max_pixels: u64,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            max_pixels: 1_000_000_000,
        }
    }
}

/// Output file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Netpbm bitmap, P4 (bilevel grey only; 1 = black ink).
    Pbm,
    /// Netpbm greymap, P5.
    Pgm,
    /// Netpbm pixmap, P6.
    Ppm,
    /// PNG: 1-bit grey for bilevel, 2/4/8-bit grey, 8-bit RGB or indexed colour.
    Png,
    /// TIFF: bilevel with G4/Deflate/LZW/PackBits/none; 8-bit grey or RGB otherwise.
    Tiff,
    /// BMP: 1-bit for bilevel, 8-bit indexed or 24-bit otherwise.
    Bmp,
    /// PDF: one image a page (bilevel, grey levels, RGB, palette, CMYK plates).
    Pdf,
    /// PostScript level 2: one image a page.
    Ps,
    /// PCL 5 raster (bilevel).
    Pcl,
    /// ESC/POS `GS v 0` raster for receipt printers (bilevel).
    EscPos,
    /// ZPL II graphic fields for label printers (bilevel).
    Zpl,
    /// PWG raster (`image/pwg-raster`): IPP Everywhere printers.
    Pwg,
    /// Apple raster (`image/urf`): AirPrint printers.
    Urf,
    /// CUPS raster version 3, uncompressed (`application/vnd.cups-raster`).
    CupsRaster,
    /// A panel's buffer: ink codes packed MSB first, rows padded to a byte, no header.
    Raw,
    /// The `Raw` bytes as a C header (`const uint8_t name[]`, width and height defines).
    CHeader,
    /// Black and colour bit planes, one after the other, for two- and three-ink panels.
    Planes,
    /// Four bits a pixel (16-grey panels, and colour panels that take 4-bit codes), two
    /// pixels a byte, even pixel in the low nibble (epdiy).
    Nibbles,
    /// Animated GIF of a clip (frames store what changed; see `crate::motion`).
    Gif,
    /// A YUV4MPEG2 stream of a clip, for ffmpeg (see `crate::motion`).
    Y4m,
    /// Animated PNG of a clip (frames store what changed; see `crate::motion`).
    Apng,
}

/// TIFF compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    /// CCITT Group 4 (bilevel only).
    G4,
    /// Deflate (zlib).
    Deflate,
    /// LZW.
    Lzw,
    /// PackBits run lengths.
    PackBits,
    /// Uncompressed.
    None,
}

/// How a halftone is encoded.
#[derive(Clone, Debug)]
pub struct WriteOptions {
    /// The format.
    pub format: Format,
    /// Resolution to record, in dots per inch.
    pub dpi: Option<f64>,
    /// Options of the printer languages (page, head width, banding, ZPL encoding).
    pub print: lang::PrintOptions,
    /// PGM/PPM maxval; `None` = 255 (display codes), or levels − 1 (the device's own levels)
    /// with `device_levels`.
    pub maxval: Option<u16>,
    /// The panel whose ink codes the panel formats write (`raw`, `h`, `planes`, `nibbles`).
    pub device: Option<std::sync::Arc<panel::Device>>,
    /// With a device: write its palette in the inks' nominal colours instead of the
    /// colours the panel shows.
    pub nominal_colours: bool,
    /// TIFF compression; `None` = the format's default.
    pub compression: Option<Compression>,
    /// How level reflectance maps to codes when a format needs more codes than levels:
    /// `Srgb` encodes reflectance k/(L−1) to sRGB (correct tone on screen), `Linear` spaces
    /// codes evenly (for `--no-linearize`).
    pub display: Encoding,
    /// Multi-level PGM/PPM and 2/4-bit grey PNG hold device level numbers (maxval L−1, PNG
    /// grey samples = levels) instead of display codes. Off by default: a file that a viewer
    /// shows at the right tone is what most people expect.
    pub device_levels: bool,
}

impl WriteOptions {
    /// Options for `format` with everything else at its default (no dpi, sRGB display).
    pub fn new(format: Format) -> WriteOptions {
        WriteOptions {
            format,
            dpi: None,
            maxval: None,
            device: None,
            nominal_colours: false,
            compression: None,
            display: Encoding::Srgb,
            print: lang::PrintOptions::default(),
            device_levels: false,
        }
    }
}

impl<'de> serde::Deserialize<'de> for Format {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Format, D::Error> {
        let name = String::deserialize(d)?;
        Format::from_name(&name).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "unknown format '{name}' (known: {})",
                Format::WRITABLE.join(", ")
            ))
        })
    }
}

impl Format {
    /// Every format with its name, the file extensions that name it (the first is the one
    /// written), and a line of description: the one list every front door reads.
    const TABLE: [(Format, &'static str, &'static [&'static str], &'static str); 21] = [
        (
            Format::Pbm,
            "pbm",
            &["pbm"],
            "Netpbm P4 bitmap (bilevel; 1 = black ink).",
        ),
        (
            Format::Pgm,
            "pgm",
            &["pgm"],
            "Netpbm P5 greymap (maxval levels−1 unless `maxval`).",
        ),
        (Format::Ppm, "ppm", &["ppm", "pnm"], "Netpbm P6 pixmap."),
        (
            Format::Png,
            "png",
            &["png"],
            "PNG: 1-bit grey for bilevel, 2/4-bit where the levels fit, 8-bit RGB for colour.",
        ),
        (
            Format::Tiff,
            "tiff",
            &["tif", "tiff"],
            "TIFF (bilevel: see `compression`).",
        ),
        (Format::Bmp, "bmp", &["bmp"], "BMP (1-bit for bilevel)."),
        (
            Format::Pdf,
            "pdf",
            &["pdf"],
            "PDF: one image a page at its physical size (see `page`, `compression` g4).",
        ),
        (
            Format::Ps,
            "ps",
            &["ps"],
            "PostScript level 2: one image a page.",
        ),
        (
            Format::Pcl,
            "pcl",
            &["pcl"],
            "PCL 5 raster for laser printers (75-600 dpi, see `dpi`).",
        ),
        (
            Format::EscPos,
            "escpos",
            &["escpos"],
            "ESC/POS raster for receipt printers (see `paper_width`, `cut`).",
        ),
        (
            Format::Zpl,
            "zpl",
            &["zpl"],
            "ZPL II for label printers (see `zpl_encoding`).",
        ),
        (
            Format::Pwg,
            "pwg",
            &["pwg"],
            "PWG raster for IPP Everywhere printers: black_1 for bilevel, sgray_8, srgb_8 (see `page`).",
        ),
        (
            Format::Urf,
            "urf",
            &["urf"],
            "Apple raster (URF) for AirPrint printers: 8-bit grey or 24-bit sRGB (see `page`).",
        ),
        (
            Format::CupsRaster,
            "ras",
            &["ras"],
            "CUPS raster v3, uncompressed, as PWG raster's pages (see `page`).",
        ),
        (
            Format::Raw,
            "raw",
            &["raw", "bin"],
            "A panel's buffer: the `device`'s ink codes packed MSB first, rows padded to a byte.",
        ),
        (
            Format::CHeader,
            "h",
            &["h"],
            "The raw panel buffer as a C header: const uint8_t array, width and height defines.",
        ),
        (
            Format::Planes,
            "planes",
            &["planes"],
            "Black then colour bit planes for two- and three-ink panels (see `device`).",
        ),
        (
            Format::Nibbles,
            "nibbles",
            &["nibbles"],
            "4-bit codes (16 greys, or a colour panel's inks), two pixels a byte, even pixel in the low nibble (epdiy).",
        ),
        (Format::Gif, "gif", &["gif"], "Animated GIF of a clip: each frame stores what changed."),
        (Format::Y4m, "y4m", &["y4m"], "YUV4MPEG2 stream of a clip (mono for grey), for ffmpeg."),
        (Format::Apng, "apng", &["apng"], "Animated PNG of a clip: each frame stores what changed."),
    ];

    /// Every format.
    pub const ALL: [Format; 21] = [
        Format::Pbm,
        Format::Pgm,
        Format::Ppm,
        Format::Png,
        Format::Tiff,
        Format::Bmp,
        Format::Pdf,
        Format::Ps,
        Format::Pcl,
        Format::EscPos,
        Format::Zpl,
        Format::Pwg,
        Format::Urf,
        Format::CupsRaster,
        Format::Raw,
        Format::CHeader,
        Format::Planes,
        Format::Nibbles,
        Format::Gif,
        Format::Y4m,
        Format::Apng,
    ];

    fn entry(self) -> &'static (Format, &'static str, &'static [&'static str], &'static str) {
        &Format::TABLE[Format::ALL
            .iter()
            .position(|&f| f == self)
            .expect("every format is listed")]
    }

    /// The format's name (`pbm`, `tiff`, `escpos`, …).
    pub fn name(self) -> &'static str {
        self.entry().1
    }

    /// The extension a file of this format is written with (`tif` for TIFF).
    pub fn extension(self) -> &'static str {
        self.entry().2[0]
    }

    /// A line on what the format holds, naming options as the library does.
    pub fn description(self) -> &'static str {
        self.entry().3
    }

    /// The printer language of a printer format (PDF, PostScript, PCL, ESC/POS, ZPL).
    pub fn language(self) -> Option<lang::Language> {
        Some(match self {
            Format::Pdf => lang::Language::Pdf,
            Format::Ps => lang::Language::Ps,
            Format::Pcl => lang::Language::Pcl,
            Format::EscPos => lang::Language::EscPos,
            Format::Zpl => lang::Language::Zpl,
            Format::Pwg => lang::Language::Pwg,
            Format::Urf => lang::Language::Urf,
            Format::CupsRaster => lang::Language::CupsRaster,
            _ => return None,
        })
    }

    /// True for a panel's buffers (raw, C header, planes, nibbles): ink codes for a
    /// display's driver, not an image file.
    pub fn is_panel_buffer(self) -> bool {
        matches!(
            self,
            Format::Raw | Format::CHeader | Format::Planes | Format::Nibbles
        )
    }

    /// True for the formats of a clip (animated GIF, YUV4MPEG2, APNG): frames in time, not
    /// one page.
    pub fn is_clip(self) -> bool {
        matches!(self, Format::Gif | Format::Y4m | Format::Apng)
    }

    /// True for formats that hold several pages in one file.
    pub fn is_multi_page(self) -> bool {
        self.language().is_some()
    }

    /// Every extension [`Format::from_name`] accepts, for error messages (checked against
    /// the table by a test).
    pub const WRITABLE: &'static [&'static str] = &[
        "pbm", "pgm", "ppm", "pnm", "png", "tif", "tiff", "bmp", "pdf", "ps", "pcl", "escpos",
        "zpl", "pwg", "urf", "ras", "raw", "bin", "h", "planes", "nibbles", "gif", "y4m", "apng",
    ];

    /// The format named by a path's extension.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Format::from_name(&ext)
    }

    /// The format of a name such as `pbm`, `png`, `tif`.
    pub fn from_name(name: &str) -> Option<Format> {
        let name = name.to_ascii_lowercase();
        Format::TABLE
            .iter()
            .find(|(_, _, exts, _)| exts.contains(&name.as_str()))
            .map(|e| e.0)
    }
}

/// Encodes `h` into `out`; `name` is used in error messages.
pub fn encode(h: &Halftone, opts: &WriteOptions, name: &Path, out: &mut dyn Write) -> Result<()> {
    check(h, opts, name)?;
    encode_checked(h, opts, name, out)
}

/// Encodes after [`check`] passed.
fn encode_checked(
    h: &Halftone,
    opts: &WriteOptions,
    name: &Path,
    out: &mut dyn Write,
) -> Result<()> {
    let mut enc = page_encoder(opts);
    sink::encode_halftone(enc.as_mut(), h, opts.dpi, out)
        .and_then(|()| enc.finish(out))
        .map_err(|e| e.named(name))
}

/// The encoder for `opts.format`: every output format behind one interface
/// ([`sink::PageEncoder`]), so a whole image and a stream of row bands take the same road.
pub fn page_encoder(opts: &WriteOptions) -> Box<dyn sink::PageEncoder> {
    let opts = opts.clone();
    // A device's palette in its inks' nominal colours: every format that writes colours.
    if let (true, Some(device)) = (opts.nominal_colours, opts.device.clone()) {
        let inner = page_encoder(&WriteOptions {
            nominal_colours: false,
            ..opts
        });
        return Box::new(panel::buffer::NominalColours::new(inner, device));
    }
    match opts.format {
        Format::Pbm | Format::Pgm | Format::Ppm => Box::new(codec::pnm::PnmEncoder::new(&opts)),
        Format::Png => Box::new(codec::png::PngEncoder::new(&opts)),
        Format::Tiff => Box::new(codec::tiff::TiffEncoder::new(&opts)),
        Format::Bmp => Box::new(sink::WholePage::new(move |h, _, out| {
            codec::bmp::write(h, &opts, out)
        })),
        Format::Pdf => Box::new(lang::pdf::PdfEncoder::new(opts.print, opts.compression)),
        Format::Ps => Box::new(lang::ps::PsEncoder::new(opts.print)),
        Format::Pcl => Box::new(lang::pcl::PclEncoder::new(opts.print)),
        Format::EscPos => Box::new(lang::escpos::EscPosEncoder::new(opts.print)),
        Format::Zpl => Box::new(lang::zpl::ZplEncoder::new(opts.print)),
        Format::Pwg | Format::Urf | Format::CupsRaster => {
            let kind = match opts.format {
                Format::Pwg => lang::cups_raster::Kind::Pwg,
                Format::Urf => lang::cups_raster::Kind::Urf,
                _ => lang::cups_raster::Kind::CupsV3,
            };
            Box::new(lang::cups_raster::RasterEncoder::new(
                kind,
                opts.print,
                opts.display,
            ))
        }
        Format::Raw | Format::CHeader | Format::Planes | Format::Nibbles => {
            panel::buffer::encoder(&opts)
        }
        Format::Gif | Format::Y4m | Format::Apng => Box::new(sink::WholePage::new(
            |_: &Halftone, _, _: &mut dyn Write| {
                Err(EncodeError::Other(
                    "a clip format: write clips with `motion`".into(),
                ))
            },
        )),
    }
}

/// Writes `h` to `path` atomically (temp file in the same folder, then rename).
pub fn write_halftone(h: &Halftone, path: &Path, opts: &WriteOptions) -> Result<()> {
    // Refuse impossible combinations before any file is created.
    check(h, opts, path)?;
    atomic::write_atomic_with(path, |out| encode_checked(h, opts, path, out))
}

/// Writes one page a halftone into one multi-page file (PDF, PostScript, PCL, ESC/POS,
/// ZPL) at `path`, pages in the iterator's order. A file is
/// written atomically: any failing page leaves nothing behind. Returns the page count.
pub fn write_book<I>(path: &Path, opts: &WriteOptions, pages: I) -> Result<usize>
where
    I: IntoIterator<Item = Result<Halftone>>,
{
    let mut pages = pages.into_iter();
    write_pages(path, opts, |enc, out| {
        let Some(page) = pages.next() else {
            return Ok(false);
        };
        let h = page?;
        check(&h, opts, path)?;
        sink::encode_halftone(enc, &h, opts.dpi, out).map_err(|e| e.named(path))?;
        Ok(true)
    })
}

/// The book writer under [`write_book`], for sources that stream rows: `next_page(encoder,
/// out)` writes one whole page through the encoder (`begin_page`, bands of rows,
/// `end_page`; [`check_page`] first) and returns `Ok(false)` when there are no more
/// pages. The file is finished after the last page, atomically as in [`write_book`].
pub fn write_pages<F>(path: &Path, opts: &WriteOptions, mut next_page: F) -> Result<usize>
where
    F: FnMut(&mut dyn sink::PageEncoder, &mut dyn Write) -> Result<bool>,
{
    if !opts.format.is_multi_page() {
        return Err(Error::Encode {
            path: path.to_path_buf(),
            msg: "this format holds one image; write a folder of files instead".into(),
        });
    }
    let mut n = 0;
    atomic::write_atomic_with(path, |out| {
        n = fill_pages(path, opts, &mut next_page, out)?;
        Ok(())
    })?;
    Ok(n)
}

/// [`write_pages`] into a writer that is not a file (a pipe, standard output, a socket):
/// written straight, buffered, and flushed at the end; `name` names it in messages.
pub fn write_pages_to<F>(
    out: &mut dyn Write,
    name: &Path,
    opts: &WriteOptions,
    mut next_page: F,
) -> Result<usize>
where
    F: FnMut(&mut dyn sink::PageEncoder, &mut dyn Write) -> Result<bool>,
{
    if !opts.format.is_multi_page() {
        return Err(Error::Encode {
            path: name.to_path_buf(),
            msg: "this format holds one image; write a folder of files instead".into(),
        });
    }
    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
    let n = fill_pages(name, opts, &mut next_page, &mut out)?;
    out.flush().map_err(|e| Error::io(name, e))?;
    Ok(n)
}

/// One encoder over every page `next_page` writes, finished after the last.
fn fill_pages<F>(
    path: &Path,
    opts: &WriteOptions,
    next_page: &mut F,
    out: &mut dyn Write,
) -> Result<usize>
where
    F: FnMut(&mut dyn sink::PageEncoder, &mut dyn Write) -> Result<bool>,
{
    let mut enc = page_encoder(opts);
    let mut n = 0;
    while next_page(enc.as_mut(), out)? {
        n += 1;
    }
    enc.finish(out).map_err(|e| e.named(path))?;
    Ok(n)
}

/// Why an encoder failed, before the file name is attached.
#[derive(Debug)]
pub enum EncodeError {
    /// Writing failed.
    Io(std::io::Error),
    /// The halftone cannot be written this way.
    Other(String),
}

impl EncodeError {
    /// The library error for this failure while writing `name`.
    pub fn named(self, name: &Path) -> Error {
        match self {
            EncodeError::Io(source) => Error::io(name, source),
            EncodeError::Other(msg) => Error::Encode {
                path: name.to_path_buf(),
                msg,
            },
        }
    }
}

impl From<std::io::Error> for EncodeError {
    fn from(e: std::io::Error) -> Self {
        EncodeError::Io(e)
    }
}

/// Result of an encoder.
pub type EncodeResult = std::result::Result<(), EncodeError>;

/// Checks that `h` can be written with `opts`: the errors a user can fix by choosing
/// another format or option.
fn check(h: &Halftone, opts: &WriteOptions, name: &Path) -> Result<()> {
    let fail = |msg: String| {
        Err(Error::Encode {
            path: name.to_path_buf(),
            msg,
        })
    };
    if h.width == 0 || h.height == 0 {
        return fail(format!(
            "the halftone is {}x{}: no pixels",
            h.width, h.height
        ));
    }
    if h.width > u32::MAX as usize || h.height > u32::MAX as usize {
        return fail(format!("{}x{} is too large", h.width, h.height));
    }
    // PDF also takes the four plates of a CMYK halftone (cyan, magenta, yellow, black).
    let plates = h.channels() == 4 && h.palette.is_none() && opts.format == Format::Pdf;
    if !plates && (!matches!(h.channels(), 1 | 3) || (h.palette.is_some() && h.channels() != 1)) {
        return fail(format!(
            "{} planes: expected 1 (grey or palette) or 3 (RGB)",
            h.channels()
        ));
    }
    if let Some(p) = &h.palette {
        if p.len() < h.levels as usize {
            return fail(format!(
                "the palette has {} colours for {} levels",
                p.len(),
                h.levels
            ));
        }
    }
    if let Some(d) = opts.dpi {
        if !(d.is_finite() && d > 0.0 && d < 1e6) {
            return fail(format!("resolution {d} dpi: must be a positive number"));
        }
    }
    if let Some(lang) = opts.format.language() {
        // Printer languages check their pages themselves (head width, page, resolution).
        if let Some(msg) = lang::check(lang, &sink::PageHeader::of(h, opts.dpi), &opts.print) {
            return fail(msg);
        }
    }
    if let Some(msg) = panel::buffer::check(&sink::PageHeader::of(h, opts.dpi), opts) {
        return fail(msg);
    }
    let grey = h.channels() == 1 && h.palette.is_none();
    match opts.format {
        Format::Pbm if !(grey && h.levels == 2) => {
            fail(format!(
                "PBM holds black and white only, this halftone is {}; write PGM, PPM or PNG instead",
                describe(h)
            ))
        }
        Format::Pgm if !grey => fail(format!(
            "PGM holds grey only, this halftone is {}; write PPM or PNG instead",
            describe(h)
        )),
        Format::Pgm | Format::Ppm => match opts.maxval {
            Some(m) if h.palette.is_some() && m != 255 => fail(format!(
                "`maxval` {m}: a palette halftone is written with its sRGB colours at maxval 255"
            )),
            Some(m) if (m as u32) < h.levels as u32 - 1 => fail(format!(
                "`maxval` {m} is below the {} levels of the halftone (at least {})",
                h.levels,
                h.levels - 1
            )),
            _ => Ok(()),
        },
        Format::Pdf
            if matches!(
                opts.compression,
                Some(Compression::Lzw | Compression::PackBits | Compression::None)
            ) =>
        {
            fail("PDF images are compressed with deflate (the default) or g4 (black and white); pass `compression` deflate or g4".into())
        }
        Format::Tiff | Format::Pdf
            if opts.compression == Some(Compression::G4) && !(grey && h.levels == 2) =>
        {
            fail(format!(
                "Group 4 compression is for black and white only, this halftone is {}; use `compression` deflate",
                describe(h)
            ))
        }
        _ => Ok(()),
    }
}

/// Checks that a page of this shape can be written with `opts`, as a whole halftone is
/// checked, before its rows exist: the streaming pipeline's check.
pub fn check_page(page: &sink::PageHeader, opts: &WriteOptions, name: &Path) -> Result<()> {
    // The shape alone: `check` reads sizes, planes, levels and palette, never the rows.
    let shape = Halftone {
        width: page.width,
        height: page.height,
        levels: page.levels,
        bits: page.bits,
        stride: page.stride,
        planes: vec![Vec::new(); page.channels],
        palette: page.palette.clone(),
    };
    check(&shape, opts, name)
}

/// A few words on what kind of halftone `h` is, for error messages.
fn describe(h: &Halftone) -> String {
    match (&h.palette, h.channels()) {
        (Some(p), _) => format!("a {}-colour palette image", p.len()),
        (None, 3) => format!("RGB with {} levels a channel", h.levels),
        _ => format!("grey with {} levels", h.levels),
    }
}

/// The code, out of `max`, that shows level `k` of `levels`: its linear reflectance
/// k/(L−1), sRGB-encoded when `display` is `Srgb` (so a viewer shows the intended tone),
/// evenly spaced when `Linear`.
pub fn level_code(k: u8, levels: u16, max: u32, display: Encoding) -> u32 {
    let r = k as f64 / (levels - 1) as f64;
    let v = match display {
        Encoding::Srgb => linear_to_srgb(r),
        Encoding::Linear => r.clamp(0.0, 1.0),
    };
    (v * max as f64).round() as u32
}

/// A table from level to 8-bit code (see [`level_code`]), 256 entries.
fn level_codes8(levels: u16, display: Encoding) -> [u8; 256] {
    let mut t = [255u8; 256];
    for (k, c) in t.iter_mut().enumerate().take(levels as usize) {
        *c = level_code(k as u8, levels, 255, display) as u8;
    }
    t
}

/// Dots per inch to pixels per metre, as PNG pHYs and BMP headers store it.
fn dots_per_metre(dpi: f64) -> u32 {
    (dpi / 0.0254).round() as u32
}

/// The packed bilevel row `row` with every bit inverted and the padding bits cleared: the
/// row as PBM and WhiteIsZero TIFF store it (1 = ink), from level bits (1 = paper).
fn invert_bilevel_row(row: &[u8], width: usize, out: &mut [u8]) {
    for (o, &b) in out.iter_mut().zip(row) {
        *o = !b;
    }
    let tail = width % 8;
    if tail != 0 {
        if let Some(last) = out.last_mut() {
            *last &= 0xFFu8 << (8 - tail);
        }
    }
}

/// Row `y` of `h` as 8-bit codes, interleaved: grey and RGB levels through `table` (see
/// [`level_codes8`]), palette indices as their colours. `levels` is scratch space of `width`
/// bytes; `out` holds `width` × 1 (grey) or 3 (RGB, palette) bytes.
fn row8(h: &Halftone, y: usize, table: &[u8; 256], levels: &mut [u8], out: &mut [u8]) {
    if let Some(pal) = &h.palette {
        h.unpack_row(0, y, levels);
        for (o, &l) in out.chunks_exact_mut(3).zip(levels.iter()) {
            o.copy_from_slice(&pal[l as usize]);
        }
        return;
    }
    let n = h.channels();
    for c in 0..n {
        h.unpack_row(c, y, levels);
        for (o, &l) in out.iter_mut().skip(c).step_by(n).zip(levels.iter()) {
            *o = table[l as usize];
        }
    }
}

/// [`row8`] for packed rows of a page arriving in bands: `rows` holds the row of every
/// plane.
fn row8_of(
    page: &sink::PageHeader,
    rows: &[&[u8]],
    table: &[u8; 256],
    levels: &mut [u8],
    out: &mut [u8],
) {
    if let Some(pal) = &page.palette {
        crate::raster::unpack_row(rows[0], page.bits, levels);
        for (o, &l) in out.chunks_exact_mut(3).zip(levels.iter()) {
            o.copy_from_slice(&pal[l as usize]);
        }
        return;
    }
    let n = page.channels;
    for (c, row) in rows.iter().enumerate().take(n) {
        crate::raster::unpack_row(row, page.bits, levels);
        for (o, &l) in out.iter_mut().skip(c).step_by(n).zip(levels.iter()) {
            *o = table[l as usize];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_codes_srgb_and_linear() {
        // Level 1 of 3 is 50% reflectance: sRGB code 188, linear code 128.
        assert_eq!(level_code(1, 3, 255, Encoding::Srgb), 188);
        assert_eq!(level_code(1, 3, 255, Encoding::Linear), 128);
        assert_eq!(level_code(0, 3, 255, Encoding::Srgb), 0);
        assert_eq!(level_code(2, 3, 65535, Encoding::Srgb), 65535);
    }

    #[test]
    fn one_list_of_formats() {
        let exts: Vec<&str> = Format::ALL
            .iter()
            .flat_map(|f| f.entry().2.iter().copied())
            .collect();
        assert_eq!(exts, Format::WRITABLE);
        for f in Format::ALL {
            assert_eq!(f.entry().0, f);
            assert_eq!(Format::from_name(f.name()), Some(f));
            assert_eq!(Format::from_name(f.extension()), Some(f));
        }
    }

    #[test]
    fn inverted_row_clears_padding() {
        let mut out = [0u8; 2];
        invert_bilevel_row(&[0b1010_0000, 0b0000_0000], 11, &mut out);
        assert_eq!(out, [0b0101_1111, 0b1110_0000]);
    }
}
