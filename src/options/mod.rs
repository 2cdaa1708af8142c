//! The options of one conversion: everything [`crate::convert`] needs besides its input and
//! output, owned, with the same defaults as the command line. Every front door (the command
//! line, Python, the browser) fills one in and calls the library; none of them builds a
//! method itself.
//!
//! ```
//! let opts = halftone::Options {
//!     method: halftone::MethodKind::Ordered,
//!     mask: Some("bayer-8".into()),
//!     levels: 4,
//!     ..Default::default()
//! };
//! assert!(opts.validate().is_ok());
//! ```
//!
//! Errors name the option (`levels 1: …`), never a flag: each front door maps the name to
//! its own spelling ([`Error::Option`]).

pub mod lists;
pub mod preset;
pub mod settings;
pub mod table;
pub mod value;

pub use lists::Lists;
pub use settings::Settings;
pub use table::{describe, describe_json, OptionSpec};
pub use value::Value;

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::io::lang::PrintOptions;
use crate::io::{Compression, Format, ReadOptions, WriteOptions};
use crate::mask::screen::{Screen, ScreenSpec, Spot};
use crate::method::auto_palette::AutoPalette;
use crate::method::content::{Content, ContentAware};
use crate::method::dbs::{Dbs, DbsOptions};
use crate::method::device::{Dither, InkMethod};
use crate::method::diffusion::hysteresis::Hysteresis;
use crate::method::diffusion::tded::Tded;
use crate::method::diffusion::{Diffuse, DiffuseOptions};
use crate::method::ordered::Ordered;
use crate::method::ordered_palette::OrderedPalette;
use crate::method::pattern::{Cell, Pattern};
use crate::method::screen::ScreenMethod;
use crate::method::threshold::Threshold as ThresholdMethod;
use crate::method::transfer::WithTransfer;
use crate::press::transfer::Transfer;
use crate::press::RenderingIntent;
use crate::printer_model::PrinterModel;
use crate::quality::Viewing;
use crate::raster::ColorMode;
use crate::rendering::{Amount, Rendering};
use crate::resize::{FitMode, Rotate, SizeRequest};
use crate::tone::{srgb_to_linear, Encoding, ToneOptions};
use crate::{Mask, Method};

/// A screen's resolution when none is given: screens are described for a device.
pub const DEFAULT_SCREEN_DPI: f64 = 600.0;

/// The four process inks, in plate order.
pub const INKS: [&str; 4] = ["cyan", "magenta", "yellow", "black"];

/// Declares a closed set of names: the enum, its `NAMES`, `name()`, `FromStr` with a
/// suggestion for a near miss, `Display` and serde (kebab-case, as on the command line).
macro_rules! named_enum {
    ($(#[$meta:meta])* $name:ident, $what:literal { $($(#[$vmeta:meta])* $variant:ident = $text:literal),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
        pub enum $name {
            $($(#[$vmeta])* #[serde(rename = $text)] $variant),+
        }

        impl $name {
            /// Every name, in the order of the variants.
            pub const NAMES: &'static [&'static str] = &[$($text),+];

            /// The name, as the command line spells it.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text),+
                }
            }
        }

        impl FromStr for $name {
            type Err = Error;

            fn from_str(s: &str) -> Result<Self> {
                match s.trim().to_ascii_lowercase().as_str() {
                    $($text => Ok($name::$variant),)+
                    _ => Err(crate::names::unknown($what, s, Self::NAMES)),
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

/// The memory budget (`--max-memory`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaxMemory {
    /// Whole-image when it fits easily, streaming beyond.
    #[default]
    Auto,
    /// At most this many bytes of image data in flight.
    Bytes(u64),
}

impl MaxMemory {
    /// Parses `auto` or a size: a number of bytes with an optional K, M, G or T suffix
    /// (powers of 1024; `KiB`, `MB` and the like are read the same way).
    pub fn parse(s: &str) -> Result<MaxMemory> {
        let t = s.trim();
        if t.eq_ignore_ascii_case("auto") {
            return Ok(MaxMemory::Auto);
        }
        let bad = || {
            Error::Invalid(format!(
                "`max_memory` {s}: expected a size such as 64M, 2G or 500000 (bytes), or auto"
            ))
        };
        let digits = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(t.len());
        let (num, unit) = t.split_at(digits);
        let n: f64 = num.parse().map_err(|_| bad())?;
        let unit = unit.trim().to_ascii_lowercase();
        let unit = unit.trim_end_matches("ib").trim_end_matches('b');
        let scale: f64 = match unit {
            "" => 1.0,
            "k" => 1024.0,
            "m" => 1024.0 * 1024.0,
            "g" => 1024.0 * 1024.0 * 1024.0,
            "t" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
            _ => return Err(bad()),
        };
        let bytes = n * scale;
        if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
            return Err(bad());
        }
        Ok(MaxMemory::Bytes(bytes as u64))
    }
}

named_enum!(
    /// The halftoning methods.
    MethodKind, "method" {
        /// One fixed threshold (quantisation to the nearest level with more than 2 levels).
        Threshold = "threshold",
        /// The lecture's halftone patterns: an n×n cell of a mask of pixel position numbers.
        Pattern = "pattern",
        /// Ordered dithering: one threshold a pixel from a tiled mask, in linear light.
        Ordered = "ordered",
        /// Error diffusion in linear light, to levels or a palette.
        Diffuse = "diffuse",
        /// Direct binary search: the halftone that minimises the eye-filtered error.
        Dbs = "dbs",
        /// An AM screen at `lpi`, `angle` and `spot` at the device's `dpi`.
        Screen = "screen",
    }
);

named_enum!(
    /// Colour handling.
    Color, "color" {
        /// Luminance in linear light, one output plane.
        Gray = "gray",
        /// Each of red, green and blue on its own.
        Rgb = "rgb",
        /// Separation into cyan, magenta, yellow and black plates.
        Cmyk = "cmyk",
    }
);

named_enum!(
    /// What the printed dot looks like, for model-based DBS and for scoring.
    PrinterModelKind, "printer model" {
        /// Every pixel prints as a square of its level.
        Ideal = "ideal",
        /// Pappas–Neuhoff circular dots of `dot_ratio` that spill onto their neighbours.
        DotOverlap = "dot-overlap",
        /// A measured 3×3-neighbourhood table (`printer_table`).
        Table = "table",
    }
);

named_enum!(
    /// How CMYK is separated.
    SeparationKind, "separation" {
        /// Through the press model's measured inks (`press`).
        Model = "model",
        /// The textbook formulas, for comparison.
        Naive = "naive",
    }
);

named_enum!(
    /// What the picture is: photo, line art, or both.
    ContentKind, "content" {
        /// Halftone everything with the method.
        Photo = "photo",
        /// Threshold everything: text, rules and barcodes stay crisp.
        LineArt = "line-art",
        /// Threshold the near-black-and-white regions, halftone the rest.
        Auto = "auto",
    }
);

named_enum!(
    /// Which colours a device's palette is written in (PNG and the other colour formats).
    InkColours, "ink colours" {
        /// What the panel shows: the measured colours (the nominal ones where none exist).
        Measured = "measured",
        /// What the driver expects: the inks' nominal sRGB colours.
        Nominal = "nominal",
    }
);

named_enum!(
    /// How a clip's frames are halftoned in time (read by [`crate::motion::ClipMethod`]; a
    /// still picture takes it and is unaffected).
    #[derive(Default)]
    Temporal, "temporal mode" {
        /// Error diffusion re-decides a dot only where the picture changed visibly
        /// ([`crate::motion::StableDiffusion`]); other methods are stable by construction.
        #[default]
        Stable = "stable",
        /// Every frame halftoned on its own (what a still converter does frame after frame).
        Frame = "frame",
    }
);

/// The threshold of [`MethodKind::Threshold`]: a pixel at or above it becomes paper.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    /// A fraction of reflectance (0.5 = half the light; linear unless `linearize` is off).
    Fraction(f32),
    /// A percentage of reflectance.
    Percent(f32),
    /// An 8-bit code of the input (128 = sRGB code 128).
    Code(u8),
}

impl Default for Threshold {
    fn default() -> Self {
        Threshold::Fraction(0.5)
    }
}

impl FromStr for Threshold {
    type Err = String;

    /// `0.5` (a fraction), `50%` (a percentage) or `128` (an 8-bit code; 0 and 1 are
    /// fractions).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let t = s.trim();
        let bad = || {
            format!(
                "'{s}': expected a fraction of reflectance (0.5), a percentage (50%) or an \
                 8-bit code (128)"
            )
        };
        if let Some(p) = t.strip_suffix('%') {
            let v: f32 = p.trim().parse().map_err(|_| bad())?;
            if !(0.0..=100.0).contains(&v) {
                return Err(format!("'{s}': a percentage must be from 0% to 100%"));
            }
            return Ok(Threshold::Percent(v));
        }
        if t.bytes().all(|b| b.is_ascii_digit()) && !t.is_empty() {
            let v: u32 = t.parse().map_err(|_| bad())?;
            if v > 1 {
                return u8::try_from(v)
                    .map(Threshold::Code)
                    .map_err(|_| format!("'{s}': an 8-bit code must be from 0 to 255"));
            }
        }
        let v: f32 = t.parse().map_err(|_| bad())?;
        if !(0.0..=1.0).contains(&v) {
            return Err(format!(
                "'{s}': a fraction must be from 0 to 1 (or write 50% or an 8-bit code)"
            ));
        }
        Ok(Threshold::Fraction(v))
    }
}

impl Threshold {
    /// The threshold as a reflectance in the planes' own terms: linear light when
    /// `linearize` (an 8-bit code is decoded from sRGB), the code's fraction otherwise.
    pub fn reflectance(self, linearize: bool) -> f32 {
        match self {
            Threshold::Fraction(v) => v,
            Threshold::Percent(p) => p / 100.0,
            Threshold::Code(c) if linearize => srgb_to_linear(c as f64 / 255.0) as f32,
            Threshold::Code(c) => c as f32 / 255.0,
        }
    }
}

/// Everything one conversion needs besides its input and output. `Default` gives the
/// command line's defaults: Floyd–Steinberg in linear light, bilevel, grey.
#[derive(Clone, Debug)]
pub struct Options {
    /// The halftoning method.
    pub method: MethodKind,
    /// Threshold of [`MethodKind::Threshold`].
    pub threshold: Threshold,
    /// Mask of pattern and ordered: a built-in name or a mask file (default: `seed-3x3`
    /// for pattern, `bayer-8` for ordered).
    pub mask: Option<String>,
    /// Error-diffusion kernel: a built-in name, `tded`, or a kernel file.
    pub kernel: String,
    /// Error diffusion: alternate direction every row.
    pub serpentine: bool,
    /// Error diffusion: share of the error passed on, 0..1.
    pub strength: f32,
    /// Diffuse or order-dither to a palette: a built-in name, a palette file, or `auto:N`
    /// (N from 2 to 256: a palette made from the image); implies RGB input.
    pub palette: Option<String>,
    /// An output device (`devices/*.toml` built-in name or a profile file): its inks become
    /// the palette (in the device's order), its size the fit box (turned by its rotation)
    /// unless a size is given, its ppi the resolution unless `dpi` is given.
    pub device: Option<String>,
    /// With a device: write its palette in the measured colours (what the panel shows) or
    /// the nominal ones (what the driver expects).
    pub ink_colours: InkColours,
    /// Seed for methods that draw noise.
    pub seed: u64,
    /// Output levels a pixel per channel (2 = bilevel).
    pub levels: u16,
    /// Grey, RGB or CMYK.
    pub color: Color,
    /// Pattern cells: expand (n× larger output) or fit (same size).
    pub cell: Cell,
    /// Decode sRGB codes to linear light (off: treat codes as linear, as most tools do).
    pub linearize: bool,
    /// Negative media: paper where the image is dark.
    pub invert: bool,
    /// Extra gamma on linear reflectance; 1 = none.
    pub gamma: f32,
    /// Dot gain to pre-compensate at 50% coverage, in percent (0 to 50).
    pub dot_gain: f32,
    /// A printer's transfer curve (`--transfer` wedge file) for grey work and CMYK plates.
    pub transfer: Option<PathBuf>,
    /// A preset's transfer curve: applies to grey work only (in CMYK the press model carries
    /// the press's dot gain).
    pub preset_transfer: Option<Transfer>,
    /// Output format; `None`: from the output file's extension.
    pub format: Option<Format>,
    /// Device resolution in dots per inch, recorded in the output.
    pub dpi: Option<f64>,
    /// PGM/PPM maxval; `None`: 255 (display codes) or levels − 1 with `device_levels`.
    pub maxval: Option<u16>,
    /// TIFF or PDF compression; `None`: the format's default.
    pub compression: Option<Compression>,
    /// Multi-level grey files hold device level numbers instead of display codes.
    pub device_levels: bool,
    /// Printer-language options (page, head width, banding, ZPL encoding).
    pub print: PrintOptions,
    /// What the picture is.
    pub content: ContentKind,
    /// Refuse images larger than this many pixels (checked from the header).
    pub max_pixels: u64,
    /// Resize to this width in pixels first (Lanczos-3 in linear light).
    pub width: Option<usize>,
    /// Resize to this height in pixels first.
    pub height: Option<usize>,
    /// Resize into this box, aspect kept, as `fit_mode` says.
    pub fit: Option<(usize, usize)>,
    /// How the picture goes into the box of `fit` or of a `device`'s panel: inside it,
    /// padded with white to exactly the box, or covering it, cropped. `None`:
    /// [`FitMode::Pad`] into a device's panel (a buffer of exactly the panel's size),
    /// [`FitMode::Inside`] into `fit`. An error without a box.
    pub fit_mode: Option<FitMode>,
    /// Resize to this physical width (`4in`, `100mm`), with `dpi`.
    pub size: Option<String>,
    /// Turn the image first.
    pub rotate: Rotate,
    /// Memory budget for image data.
    pub max_memory: MaxMemory,
    /// DBS: at most this many passes.
    pub passes: u32,
    /// DBS: viewing distance in inches.
    pub distance: f64,
    /// DBS: correct DBS's tone response.
    pub tone_correction: bool,
    /// Error diffusion: Levien's output-dependent feedback ("green noise"); 0 = plain.
    pub hysteresis: f32,
    /// Printer model for model-based DBS.
    pub printer_model: PrinterModelKind,
    /// Dot ratio of the dot-overlap model.
    pub dot_ratio: f64,
    /// Measured table of [`PrinterModelKind::Table`].
    pub printer_table: Option<PathBuf>,
    /// Screen frequency, lines per inch: one number, or `c=…,m=…,y=…,k=…` for CMYK plates.
    pub lpi: String,
    /// Screen angle in degrees.
    pub angle: f64,
    /// Spot function name.
    pub spot: String,
    /// CMYK plates' angles, `c=15,m=75,y=0,k=45`.
    pub angles: Option<String>,
    /// Press model for CMYK separation (built-in name or file).
    pub press: String,
    /// Grey component replacement, percent.
    pub gcr: f64,
    /// Total area coverage limit, percent.
    pub tac: f64,
    /// Separation by the press model or the naive formulas.
    pub separation: SeparationKind,
    /// An ICC output profile that separates instead of the press model.
    pub icc: Option<PathBuf>,
    /// Rendering intent of `icc` (default relative) and of a `device`'s or `palette`'s inks
    /// (default perceptual for a device, absolute for a palette: its colours as given).
    pub intent: Option<RenderingIntent>,
    /// With a device or palette: exposure in stops (0: none).
    pub exposure: f32,
    /// With a device or palette: chroma multiplier at constant luminance (1: none).
    pub saturation: f32,
    /// With a device or palette, perceptual intent: tone-range stretch, `auto` or 0..1.
    pub tone: Amount,
    /// With a device or palette, perceptual intent: gamut compression, `auto` or 0..1.
    pub gamut: Amount,
    /// CMYK: also render how the printed plates look (through the press model or the ICC
    /// profile).
    pub preview: bool,
    /// CMYK preview: pixels of the plates averaged into one preview pixel (`None`: about
    /// two screen periods).
    pub preview_block: Option<usize>,
    /// Clips: stable error diffusion over time, or every frame on its own.
    pub temporal: Temporal,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: MethodKind::Diffuse,
            threshold: Threshold::default(),
            mask: None,
            kernel: "floyd-steinberg".into(),
            serpentine: true,
            strength: 1.0,
            palette: None,
            device: None,
            ink_colours: InkColours::Measured,
            seed: 0,
            levels: 2,
            color: Color::Gray,
            cell: Cell::Fit,
            linearize: true,
            invert: false,
            gamma: 1.0,
            dot_gain: 0.0,
            transfer: None,
            preset_transfer: None,
            format: None,
            dpi: None,
            maxval: None,
            compression: None,
            device_levels: false,
            print: PrintOptions::default(),
            content: ContentKind::Photo,
            max_pixels: ReadOptions::default().max_pixels,
            width: None,
            height: None,
            fit: None,
            fit_mode: None,
            size: None,
            rotate: Rotate::None,
            max_memory: MaxMemory::Auto,
            passes: 40,
            distance: 12.0,
            tone_correction: true,
            hysteresis: 0.0,
            printer_model: PrinterModelKind::Ideal,
            dot_ratio: 1.25,
            printer_table: None,
            lpi: "106".into(),
            angle: 45.0,
            spot: "Round".into(),
            angles: None,
            press: "fogra39".into(),
            gcr: 50.0,
            tac: 300.0,
            separation: SeparationKind::Model,
            icc: None,
            intent: None,
            exposure: 0.0,
            saturation: 1.0,
            tone: Amount::Auto,
            gamut: Amount::Auto,
            preview: false,
            preview_block: None,
            temporal: Temporal::default(),
        }
    }
}

/// An [`Error::Option`] for `field`.
fn bad(field: &'static str, value: impl fmt::Display, msg: impl Into<String>) -> Error {
    Error::Option {
        field,
        value: value.to_string(),
        msg: msg.into(),
    }
}

impl Options {
    /// Checks the values that have a range, before any work.
    pub fn validate(&self) -> Result<()> {
        self.tone()?;
        self.device_profile()?;
        Ok(())
    }

    /// The tone options these options ask for.
    pub fn tone(&self) -> Result<ToneOptions> {
        if !(self.gamma > 0.0 && self.gamma.is_finite()) {
            return Err(bad("gamma", self.gamma, "must be a positive number"));
        }
        if !(0.0..50.0).contains(&self.dot_gain) {
            return Err(bad(
                "dot_gain",
                self.dot_gain,
                "must be a percentage from 0 to 50",
            ));
        }
        Ok(ToneOptions {
            linearize: self.linearize,
            gamma: self.gamma,
            dot_gain: self.dot_gain / 100.0,
            invert: self.invert,
        })
    }

    /// Grey or RGB planes for the method (a palette and CMYK work from RGB).
    pub fn color_mode(&self) -> ColorMode {
        if self.palette.is_some() || self.device.is_some() {
            return ColorMode::Rgb;
        }
        match self.color {
            Color::Gray => ColorMode::Gray,
            Color::Rgb | Color::Cmyk => ColorMode::Rgb,
        }
    }

    /// Decoding limits.
    pub fn read_options(&self) -> ReadOptions {
        ReadOptions {
            max_pixels: self.max_pixels,
        }
    }

    /// The device profile of `device`, loaded (a built-in or a file).
    pub fn device_profile(&self) -> Result<Option<crate::io::panel::Device>> {
        self.device
            .as_deref()
            .map(crate::io::panel::Device::load)
            .transpose()
    }

    /// The turns and resizing asked for: with a device and no size given, the picture
    /// turned by the device's rotation (unless `rotate` says otherwise) and fitted into the
    /// panel, padded to its size unless `fit_mode` says otherwise.
    pub fn size_request(&self) -> SizeRequest<'_> {
        let mut req = SizeRequest {
            width: self.width,
            height: self.height,
            fit: self.fit,
            fit_mode: self.fit_mode,
            size: self.size.as_deref(),
            dpi: self.dpi,
            rotate: self.rotate,
            max_pixels: self.max_pixels,
            device: None,
        };
        let sized =
            req.width.is_some() || req.height.is_some() || req.fit.is_some() || req.size.is_some();
        // A profile that fails to load is reported by `method` and `validate`.
        if let Some(d) = self.device_profile().ok().flatten() {
            req.dpi = req.dpi.or(Some(d.ppi));
            if !sized {
                req.device = self.device.as_deref();
                req.fit = Some((d.width, d.height));
                req.fit_mode = Some(self.fit_mode.unwrap_or(FitMode::Pad));
                if self.rotate == Rotate::None && d.quarter_turns() != 0 {
                    req.rotate = Rotate::Clockwise(d.quarter_turns());
                }
            }
        }
        req
    }

    /// How the halftone is encoded as `format`.
    pub fn write_options(&self, format: Format) -> WriteOptions {
        let device = self
            .device_profile()
            .ok()
            .flatten()
            .map(std::sync::Arc::new);
        WriteOptions {
            format,
            dpi: self.dpi.or(device.as_ref().map(|d| d.ppi)),
            nominal_colours: device.is_some() && self.ink_colours == InkColours::Nominal,
            device,
            maxval: self.maxval,
            compression: self.compression,
            print: self.print.clone(),
            display: if self.linearize {
                Encoding::Srgb
            } else {
                Encoding::Linear
            },
            device_levels: self.device_levels,
        }
    }

    /// The method these options ask for: calibrated by the transfer curve, wrapped for
    /// the content.
    pub fn method(&self) -> Result<Box<dyn Method>> {
        let calibrated = self.with_transfer(self.plain_method()?)?;
        Ok(match self.content {
            ContentKind::Photo => calibrated,
            ContentKind::LineArt => Box::new(ContentAware::new(calibrated, Content::LineArt)),
            ContentKind::Auto => Box::new(ContentAware::new(calibrated, Content::Auto)),
        })
    }

    /// The method alone, without transfer curve or content handling.
    fn plain_method(&self) -> Result<Box<dyn Method>> {
        if self.device.is_none() && self.ink_colours == InkColours::Nominal {
            return Err(bad(
                "ink_colours",
                self.ink_colours,
                "chooses the colours of a `device`'s inks: give a device",
            ));
        }
        if let Some(name) = &self.device {
            if self.palette.is_some() {
                return Err(bad(
                    "device",
                    name,
                    "sets the palette to the device's inks: give `device` or `palette`, not both",
                ));
            }
            if !matches!(
                self.method,
                MethodKind::Diffuse | MethodKind::Dbs | MethodKind::Ordered
            ) {
                return Err(bad(
                    "device",
                    name,
                    "works with methods diffuse, dbs and ordered",
                ));
            }
            if self.color == Color::Cmyk {
                return Err(bad(
                    "device",
                    name,
                    "prints with the device's inks, not CMYK plates",
                ));
            }
        }
        if let Some(m) = self.ink_method()? {
            return Ok(m);
        }
        if self.palette.is_some()
            && !matches!(self.method, MethodKind::Diffuse | MethodKind::Ordered)
        {
            return Err(bad(
                "palette",
                self.palette.as_deref().unwrap_or(""),
                "works with method diffuse or ordered",
            ));
        }
        // `auto:N`: a palette made from the image, by the method (N checked here).
        let auto = self
            .palette
            .as_deref()
            .and_then(crate::color::auto_palette_size)
            .transpose()?;
        Ok(match self.method {
            MethodKind::Threshold => Box::new(ThresholdMethod::new(
                self.threshold.reflectance(self.linearize),
                self.levels,
            )?),
            MethodKind::Pattern => {
                let mask = Mask::load(self.mask.as_deref().unwrap_or("seed-3x3"), true)?;
                Box::new(Pattern::new(mask, self.levels, self.cell)?)
            }
            MethodKind::Ordered => {
                let mask = Mask::load(self.mask.as_deref().unwrap_or("bayer-8"), false)?;
                match (&self.palette, auto) {
                    (_, Some(n)) => Box::new(AutoPalette::ordered(mask, n)?),
                    (Some(p), None) => {
                        Box::new(OrderedPalette::new(mask, crate::color::Palette::load(p)?)?)
                    }
                    (None, None) => Box::new(Ordered::new(mask, self.levels)?),
                }
            }
            MethodKind::Diffuse => {
                let options = DiffuseOptions {
                    levels: self.levels,
                    serpentine: self.serpentine,
                    strength: self.strength,
                    seed: self.seed,
                };
                if self.kernel == "tded" || self.hysteresis != 0.0 {
                    return self.green_or_trained(options);
                }
                let d = Diffuse::new(&self.kernel, options)?;
                if let Some(device) = self.device_profile()? {
                    let palette = crate::color::Palette::new(&device.name, device.shown_colours())?;
                    return Ok(Box::new(d.with_palette(palette)));
                }
                match (&self.palette, auto) {
                    (_, Some(n)) => Box::new(AutoPalette::diffuse(d, n)?),
                    (Some(p), None) => Box::new(d.with_palette(crate::color::Palette::load(p)?)),
                    (None, None) => Box::new(d),
                }
            }
            MethodKind::Dbs => {
                let base = match self.printer()? {
                    Some(p) => DbsOptions::for_printer(p),
                    None => DbsOptions::default(),
                };
                Box::new(Dbs::new(DbsOptions {
                    levels: self.levels,
                    view: self.view()?,
                    passes: self.passes,
                    tone_correct: self.tone_correction,
                    ..base
                })?)
            }
            MethodKind::Screen => Box::new(ScreenMethod::new(self.screen()?, self.levels)?),
        })
    }

    /// The rendering of a device's or palette's inks these options ask for: `None` for a
    /// plain palette (absolute intent, no steering) and for no inks at all.
    fn rendering(&self) -> Result<Option<Rendering>> {
        let device = self.device.is_some();
        let steered = self.exposure != 0.0
            || self.saturation != 1.0
            || self.tone != Amount::Auto
            || self.gamut != Amount::Auto;
        if !device && self.palette.is_none() {
            if steered {
                return Err(Error::Invalid(
                    "`exposure`, `saturation`, `tone` and `gamut` work with a `device` or \
                     `palette`"
                        .into(),
                ));
            }
            return Ok(None);
        }
        let intent = self.intent.unwrap_or(if device {
            RenderingIntent::Perceptual
        } else {
            RenderingIntent::Absolute
        });
        if intent == RenderingIntent::Absolute
            && !steered
            && (self.method == MethodKind::Diffuse
                || (!device && self.method == MethodKind::Ordered))
        {
            // The plain palette diffusion or ordered dithering: the inks' colours as they are.
            return Ok(None);
        }
        if !device
            && self
                .palette
                .as_deref()
                .is_some_and(|p| p.starts_with("auto:"))
        {
            return Err(bad(
                "palette",
                self.palette.as_deref().unwrap_or(""),
                "a palette made from the image works with methods diffuse and ordered, \
                 without `intent`, `exposure`, `saturation`, `tone` or `gamut`",
            ));
        }
        if intent != RenderingIntent::Perceptual
            && (self.tone != Amount::Auto || self.gamut != Amount::Auto)
        {
            return Err(bad(
                "intent",
                intent.name(),
                "`tone` and `gamut` steer the perceptual intent",
            ));
        }
        Ok(Some(Rendering {
            intent,
            exposure: self.exposure,
            saturation: self.saturation,
            tone: self.tone,
            gamut: self.gamut,
        }))
    }

    /// A device's inks (or a palette's, when an intent or DBS asks for it) rendered by
    /// [`InkMethod`].
    fn ink_method(&self) -> Result<Option<Box<dyn Method>>> {
        Ok(self.inks()?.map(|m| Box::new(m) as Box<dyn Method>))
    }

    /// The [`InkMethod`] of a device (or of a palette with an intent or DBS); `None` for
    /// other options.
    pub(crate) fn inks(&self) -> Result<Option<InkMethod>> {
        let Some(rendering) = self.rendering()? else {
            return Ok(None);
        };
        let (name, shown, palette, ppd) = match self.device_profile()? {
            Some(d) => {
                let shown: Vec<[f64; 3]> = d.inks.iter().map(|i| i.shown_linear()).collect();
                (
                    d.name.clone(),
                    shown,
                    d.shown_colours(),
                    d.pixels_per_degree(),
                )
            }
            None => {
                let p = crate::color::Palette::load(self.palette.as_deref().unwrap_or(""))?;
                let shown = p
                    .colours
                    .iter()
                    .map(|c| c.map(|v| crate::tone::srgb_to_linear(v as f64 / 255.0)))
                    .collect();
                (
                    p.name.clone(),
                    shown,
                    p.colours.clone(),
                    self.view()?.pixels_per_degree(),
                )
            }
        };
        let dither = match self.method {
            MethodKind::Diffuse => {
                if self.kernel == "tded" || self.hysteresis != 0.0 {
                    return Err(Error::Invalid(
                        "hysteresis and the tded kernel do not work with a palette".into(),
                    ));
                }
                if matches!(
                    self.kernel.as_str(),
                    "ostromoukhov" | "zhou-fang" | "riemersma"
                ) {
                    return Err(bad(
                        "kernel",
                        &self.kernel,
                        format!(
                            "{} works with the fixed kernels ({}) or a kernel file",
                            if self.device.is_some() {
                                "a device"
                            } else {
                                "a palette with an intent or DBS"
                            },
                            crate::method::diffusion::kernels::Kernel::builtin_names()
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ));
                }
                Dither::Diffuse {
                    kernel: crate::method::diffusion::kernels::Kernel::load(&self.kernel)?,
                    serpentine: self.serpentine,
                    strength: self.strength,
                }
            }
            // Palette DBS converges in fewer passes than grey DBS: 8 unless `passes` is set.
            MethodKind::Dbs => Dither::Dbs {
                passes: if self.passes == Options::default().passes {
                    8
                } else {
                    self.passes
                },
            },
            MethodKind::Ordered => Dither::Ordered {
                mask: Mask::load(self.mask.as_deref().unwrap_or("bayer-8"), false)?,
            },
            other => {
                return Err(bad(
                    if self.device.is_some() {
                        "device"
                    } else {
                        "palette"
                    },
                    name,
                    format!("works with methods diffuse, dbs and ordered, not {}", other),
                ))
            }
        };
        Ok(Some(InkMethod::new(
            &name, shown, palette, ppd, rendering, dither,
        )?))
    }

    /// Error diffusion with hysteresis or the trained `tded` kernel.
    fn green_or_trained(&self, options: DiffuseOptions) -> Result<Box<dyn Method>> {
        if self.palette.is_some() || self.device.is_some() {
            return Err(Error::Invalid(
                "hysteresis and the tded kernel do not work with a palette".into(),
            ));
        }
        if self.kernel == "tded" {
            if self.hysteresis != 0.0 {
                return Err(bad(
                    "hysteresis",
                    self.hysteresis,
                    "works with fixed kernels, not tded",
                ));
            }
            return Ok(Box::new(Tded::new(options)?));
        }
        Ok(Box::new(Hysteresis::new(
            &self.kernel,
            options,
            self.hysteresis,
        )?))
    }

    /// `method` calibrated by the transfer curve (grey and RGB work; CMYK plates apply
    /// their own).
    fn with_transfer(&self, method: Box<dyn Method>) -> Result<Box<dyn Method>> {
        if self.icc.is_some() && self.color != Color::Cmyk {
            return Err(bad(
                "icc",
                self.icc
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default(),
                "separates into CMYK plates: set color to cmyk",
            ));
        }
        if self.color == Color::Cmyk {
            return Ok(method);
        }
        Ok(match self.transfer_curve()? {
            Some(transfer) => Box::new(WithTransfer {
                inner: method,
                transfer,
            }),
            None => method,
        })
    }

    /// The transfer curve in force: the file's, or the preset's.
    pub fn transfer_curve(&self) -> Result<Option<Transfer>> {
        match &self.transfer {
            Some(path) => Ok(Some(Transfer::load(path)?)),
            None => Ok(self.preset_transfer.clone()),
        }
    }

    /// The printer model asked for; `None` for an ideal printer.
    pub fn printer(&self) -> Result<Option<PrinterModel>> {
        Ok(match self.printer_model {
            PrinterModelKind::Ideal => None,
            PrinterModelKind::DotOverlap => Some(PrinterModel::dot_overlap(self.dot_ratio)?),
            PrinterModelKind::Table => match &self.printer_table {
                Some(p) => Some(PrinterModel::load_table(p)?),
                None => return Err(bad("printer_model", "table", "needs a printer_table file")),
            },
        })
    }

    /// Viewing conditions for DBS's eye model (300 dpi when none is given).
    pub fn view(&self) -> Result<Viewing> {
        Viewing::new(self.dpi.unwrap_or(300.0), self.distance)
    }

    /// The spot function.
    pub fn spot(&self) -> Result<Spot> {
        Spot::from_name(&self.spot)
    }

    /// One number of `lpi`.
    fn lpi_number(&self) -> Result<f64> {
        self.lpi
            .trim()
            .parse()
            .map_err(|_| bad("lpi", &self.lpi, "must be a number"))
    }

    /// The AM screen of [`MethodKind::Screen`].
    pub fn screen(&self) -> Result<Screen> {
        Screen::new(ScreenSpec {
            dpi: self.dpi.unwrap_or(DEFAULT_SCREEN_DPI),
            lpi: self.lpi_number()?,
            angle: self.angle,
            spot: self.spot()?,
        })
    }

    /// The four screens of CMYK plates: per-ink angles (c 15°, m 75°, y 0°, k 45° unless
    /// `angles` says otherwise) and frequencies.
    pub fn plate_screens(&self) -> Result<[Screen; 4]> {
        let angles = per_ink(self.angles.as_deref(), [15.0, 75.0, 0.0, 45.0], "angles")?;
        let lpis = if self.lpi.contains('=') {
            per_ink(Some(&self.lpi), [f64::NAN; 4], "lpi")?
        } else {
            [self.lpi_number()?; 4]
        };
        if let Some(i) = lpis.iter().position(|l| l.is_nan()) {
            return Err(bad(
                "lpi",
                &self.lpi,
                format!("give all four inks (missing {})", INKS[i]),
            ));
        }
        let spot = self.spot()?;
        let dpi = self.dpi.unwrap_or(DEFAULT_SCREEN_DPI);
        let mk = |i: usize| {
            Screen::new(ScreenSpec {
                dpi,
                lpi: lpis[i],
                angle: angles[i],
                spot,
            })
        };
        Ok([mk(0)?, mk(1)?, mk(2)?, mk(3)?])
    }
}

/// The registry of configured methods: one key a configuration (the key `bench --methods`
/// selects by), every method and its main variants, as [`Options`] so that each is built by
/// the one constructor ([`Options::method`]) every front door uses.
pub fn registry() -> Vec<(&'static str, Options)> {
    use MethodKind::*;
    let o = |method: MethodKind| Options {
        method,
        ..Default::default()
    };
    let pattern = |mask: &str, cell: Cell, levels: u16| Options {
        mask: Some(mask.into()),
        cell,
        levels,
        ..o(Pattern)
    };
    let ordered = |mask: &str, levels: u16| Options {
        mask: Some(mask.into()),
        levels,
        ..o(Ordered)
    };
    let diffuse = |kernel: &str, levels: u16| Options {
        kernel: kernel.into(),
        levels,
        ..o(Diffuse)
    };
    vec![
        ("threshold", o(Threshold)),
        (
            "threshold-4",
            Options {
                levels: 4,
                ..o(Threshold)
            },
        ),
        ("pattern-3x3-fit", pattern("seed-3x3", Cell::Fit, 2)),
        ("pattern-3x3-expand", pattern("seed-3x3", Cell::Expand, 2)),
        ("pattern-2x2-fit-4", pattern("seed-2x2", Cell::Fit, 4)),
        ("pattern-2x2-expand-4", pattern("seed-2x2", Cell::Expand, 4)),
        ("ordered-bayer-8", ordered("bayer-8", 2)),
        ("ordered-cluster-8", ordered("cluster-8", 2)),
        ("ordered-blue-noise-64", ordered("blue-noise-64", 2)),
        ("ordered-bayer-8-4", ordered("bayer-8", 4)),
        ("diffuse-floyd-steinberg", diffuse("floyd-steinberg", 2)),
        (
            "diffuse-jarvis-judice-ninke",
            diffuse("jarvis-judice-ninke", 2),
        ),
        ("diffuse-stucki", diffuse("stucki", 2)),
        ("diffuse-sierra-lite", diffuse("sierra-lite", 2)),
        ("diffuse-atkinson", diffuse("atkinson", 2)),
        ("diffuse-shiau-fan-2", diffuse("shiau-fan-2", 2)),
        ("diffuse-ostromoukhov", diffuse("ostromoukhov", 2)),
        ("diffuse-zhou-fang", diffuse("zhou-fang", 2)),
        ("diffuse-riemersma", diffuse("riemersma", 2)),
        ("diffuse-floyd-steinberg-4", diffuse("floyd-steinberg", 4)),
        ("diffuse-tded", diffuse("tded", 2)),
        (
            "diffuse-hysteresis-1.5",
            Options {
                hysteresis: 1.5,
                ..diffuse("floyd-steinberg", 2)
            },
        ),
        ("dbs", o(Dbs)),
        (
            "model-dbs-1.25",
            Options {
                printer_model: PrinterModelKind::DotOverlap,
                dot_ratio: 1.25,
                ..o(Dbs)
            },
        ),
    ]
}

/// Parses `c=15,m=75,y=0,k=45` over `defaults`.
fn per_ink(text: Option<&str>, defaults: [f64; 4], field: &'static str) -> Result<[f64; 4]> {
    let mut out = defaults;
    let Some(text) = text else {
        return Ok(out);
    };
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let Some((k, v)) = part.split_once('=') else {
            return Err(bad(
                field,
                text,
                "expected ink=value pairs such as c=15,m=75,y=0,k=45",
            ));
        };
        let i = match k.trim().to_ascii_lowercase().as_str() {
            "c" | "cyan" => 0,
            "m" | "magenta" => 1,
            "y" | "yellow" => 2,
            "k" | "black" => 3,
            other => {
                return Err(bad(
                    field,
                    text,
                    format!("unknown ink '{other}' (c, m, y, k)"),
                ))
            }
        };
        out[i] = v
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(field, text, format!("'{v}' is not a number")))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_suggest() {
        for &n in MethodKind::NAMES {
            assert_eq!(n.parse::<MethodKind>().unwrap().name(), n);
        }
        let e = "difuse".parse::<MethodKind>().unwrap_err().to_string();
        assert!(e.contains("diffuse"), "{e}");
        assert_eq!(
            "LINE-ART".parse::<ContentKind>().unwrap(),
            ContentKind::LineArt
        );
    }

    #[test]
    fn every_registered_configuration_builds() {
        for (key, o) in registry() {
            let m = o.method().unwrap_or_else(|e| panic!("{key}: {e}"));
            assert!(!m.name().is_empty(), "{key}");
        }
    }

    #[test]
    fn errors_name_the_option() {
        let o = Options {
            gamma: 0.0,
            ..Default::default()
        };
        let e = o.tone().unwrap_err();
        assert!(matches!(e, Error::Option { field: "gamma", .. }), "{e}");
        let o = Options {
            lpi: "c=100,m=100".into(),
            ..Default::default()
        };
        let e = o.plate_screens().unwrap_err().to_string();
        assert!(
            e.starts_with("lpi c=100,m=100: give all four inks (missing yellow)"),
            "{e}"
        );
    }

    #[test]
    fn three_ways_to_say_a_threshold() {
        let p = |s: &str| s.parse::<Threshold>();
        assert_eq!(p("0.5").unwrap().reflectance(true), 0.5);
        assert_eq!(p("50%").unwrap().reflectance(true), 0.5);
        assert_eq!(p("1").unwrap().reflectance(true), 1.0);
        assert_eq!(p("0").unwrap().reflectance(true), 0.0);
        let c = p("128").unwrap();
        assert!((c.reflectance(true) - 0.2158).abs() < 1e-3);
        assert!((c.reflectance(false) - 128.0 / 255.0).abs() < 1e-6);
        for bad in ["256", "1.5", "101%", "-0.1", "half", ""] {
            assert!(p(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn threshold_forms() {
        assert_eq!(
            "50%".parse::<Threshold>().unwrap(),
            Threshold::Percent(50.0)
        );
        assert_eq!("128".parse::<Threshold>().unwrap(), Threshold::Code(128));
        assert_eq!("1".parse::<Threshold>().unwrap(), Threshold::Fraction(1.0));
        assert!("300".parse::<Threshold>().is_err());
        let r = Threshold::Code(128).reflectance(true);
        assert!((r - 0.2158605).abs() < 1e-5, "{r}");
    }
}
