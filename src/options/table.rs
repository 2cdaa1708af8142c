//! The one table of options: every option's name, parser, default, help line and the
//! methods or formats that read it. The command line's flags are generated from it, Python's
//! keyword arguments and the page's JSON keys go through [`Options::set`], presets and queue
//! files are partial options in TOML applied by [`Settings`](super::Settings), and listings read
//! [`describe`]. A new option is one field of [`Options`] and one entry here.

use std::path::PathBuf;

use super::value::Value;
use super::{Color, ContentKind, InkColours, MaxMemory, MethodKind, Options, PrinterModelKind};
use super::{SeparationKind, Temporal, Threshold};
use crate::error::{Error, Result};
use crate::io::lang::{PageSize, ZplEncoding, MAX_BAND_ROWS, ZPL_MAX_LENGTH};
use crate::io::{Compression, Format};
use crate::method::pattern::Cell;
use crate::press::RenderingIntent;
use crate::rendering::Amount;
use crate::resize::{FitMode, Rotate};

/// How an option is written on a command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// `--name VALUE`.
    Value,
    /// `--name` alone sets it true (a boolean that is false by default).
    Switch,
    /// `--FLAG` alone sets it false (a boolean that is true by default; FLAG is `no-…`).
    Negative(&'static str),
    /// Both `--name` and `--FLAG` (`--serpentine` / `--no-serpentine`), the last one wins.
    Both(&'static str),
    /// The door writes its own flag (an output format chosen with the output's name, a
    /// preview written to a file); every other door takes `name=value`.
    Door,
}

/// The values an option takes, for help, listings and completion.
#[derive(Clone, Copy, Debug)]
pub enum Choices {
    /// Any value its parser accepts (numbers, sizes, paths).
    Open,
    /// One of these names, each with a help line.
    Fixed(&'static [(&'static str, &'static str)]),
    /// A built-in name from this list, or a file.
    Named(fn() -> Vec<String>),
}

/// The typed value an option takes from a door that passes typed values (Python,
/// JavaScript, TOML), for type stubs, forms and listings. Text is taken too, parsed as on a
/// command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// True or false.
    Bool,
    /// A whole number.
    Int,
    /// A number.
    Number,
    /// Text: one of the listed names, a size, a list.
    Text,
    /// A file's path, or one of the built-in names listed.
    Path,
    /// A number, or text (`50%`, `auto`, `c=150,k=175`).
    NumberOrText,
    /// A whole number, or text (`auto`).
    IntOrText,
    /// Text (`800x480`), or a pair of whole numbers.
    TextOrPair,
}

impl Kind {
    /// Its name in listings (`options --json`): `bool`, `int`, `number`, `text`, `path`,
    /// `number|text`, `int|text`, `text|pair`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Bool => "bool",
            Kind::Int => "int",
            Kind::Number => "number",
            Kind::Text => "text",
            Kind::Path => "path",
            Kind::NumberOrText => "number|text",
            Kind::IntOrText => "int|text",
            Kind::TextOrPair => "text|pair",
        }
    }
}

/// Who reads an option: given where nobody reads it, it is an error, not a silent no-op.
#[derive(Clone, Copy, Debug)]
pub enum UsedBy {
    /// Every method and format.
    All,
    /// Only these methods.
    Methods(&'static [MethodKind]),
    /// Only these output formats.
    Formats(&'static [Format]),
    /// Any method or format, but not together with this other option, which takes over.
    NotWith(&'static str),
}

/// One option.
#[derive(Clone, Copy)]
pub struct OptionSpec {
    /// Its one name: the flag's, with underscores (`dot_gain`; the flag is `--dot-gain`).
    pub name: &'static str,
    /// Other names that set it (`no_linearize` sets `linearize` to the opposite).
    pub aliases: &'static [&'static str],
    /// A one-letter flag, if it has one (`-m`).
    pub short: Option<char>,
    /// What the value is, in help (`N`, `WxH`, `FILE`).
    pub value_name: &'static str,
    /// The help line(s).
    pub help: &'static str,
    /// How a command line writes it.
    pub form: Form,
    /// The values it takes.
    pub choices: Choices,
    /// The typed value it takes.
    pub kind: Kind,
    /// Who reads it.
    pub used_by: UsedBy,
    /// Sets it from a value (the message names neither the option nor the value).
    pub set: fn(&mut Options, &Value) -> std::result::Result<(), String>,
    /// Its value in `o` as text, `None` when unset.
    pub get: fn(&Options) -> Option<String>,
}

impl std::fmt::Debug for OptionSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OptionSpec")
            .field("name", &self.name)
            .finish()
    }
}

impl OptionSpec {
    /// The flag's long name (`dot-gain`).
    pub fn flag(&self) -> String {
        self.name.replace('_', "-")
    }

    /// Its default, as text (`None`: unset by default).
    pub fn default_text(&self) -> Option<String> {
        (self.get)(&Options::default())
    }

    /// Parses `value` as this option would, on a scratch set of options: the check a door
    /// makes while reading its input.
    pub fn check(&self, value: &Value) -> std::result::Result<(), String> {
        (self.set)(&mut Options::default(), value)
    }

    /// The names of its fixed or built-in values (empty for an open option).
    pub fn values(&self) -> Vec<String> {
        match self.choices {
            Choices::Open => Vec::new(),
            Choices::Fixed(list) => list.iter().map(|(n, _)| n.to_string()).collect(),
            Choices::Named(f) => f(),
        }
    }
}

/// Every option, in the order of the command line's help.
pub fn describe() -> &'static [OptionSpec] {
    TABLE
}

/// Every option as JSON, in the order of [`describe`]: its `name`, `flag`, `aliases`,
/// `kind` ([`Kind::name`]), `choices` (`fixed`, `named` or `open`), `values`, `default`,
/// `help` and `used_by` (`"all"`, `{"methods": […]}`, `{"formats": […]}` or
/// `{"not_with": NAME}`): what `halftone options --json` prints under `options`, and what
/// the Python package's docstring and type stub are made from.
pub fn describe_json() -> serde_json::Value {
    let used_by = |u: &UsedBy| match u {
        UsedBy::All => serde_json::json!("all"),
        UsedBy::Methods(ms) => {
            serde_json::json!({ "methods": ms.iter().map(|m| m.name()).collect::<Vec<_>>() })
        }
        UsedBy::Formats(fs) => {
            serde_json::json!({ "formats": fs.iter().map(|f| f.name()).collect::<Vec<_>>() })
        }
        UsedBy::NotWith(o) => serde_json::json!({ "not_with": o }),
    };
    TABLE
        .iter()
        .map(|s| {
            serde_json::json!({
                "name": s.name,
                "flag": format!("--{}", s.flag()),
                "aliases": s.aliases,
                "kind": s.kind.name(),
                "choices": match s.choices {
                    Choices::Open => "open",
                    Choices::Fixed(_) => "fixed",
                    Choices::Named(_) => "named",
                },
                "values": s.values(),
                "default": s.default_text(),
                "help": s.help,
                "used_by": used_by(&s.used_by),
            })
        })
        .collect()
}

/// The option called `name` (or one of its aliases; hyphens read as underscores), and
/// whether the alias negates it.
pub fn find(name: &str) -> Option<(&'static OptionSpec, bool)> {
    let name = name.trim().replace('-', "_");
    for spec in TABLE {
        if spec.name == name {
            return Some((spec, false));
        }
        if spec.aliases.contains(&name.as_str()) {
            return Some((spec, true));
        }
    }
    None
}

/// Every name a door accepts: the options' names and aliases and the preset pair.
pub fn accepted_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = TABLE
        .iter()
        .flat_map(|s| std::iter::once(s.name).chain(s.aliases.iter().copied()))
        .collect();
    names.extend(PRESET_NAMES);
    names
}

/// The two names that choose a preset rather than set an option: `preset` (a name) and
/// `presets` (a TOML file adding to the built-ins).
pub const PRESET_NAMES: [&str; 2] = ["preset", "presets"];

/// An unknown option's error, with the nearest name.
fn unknown(name: &str) -> Error {
    let names = accepted_names();
    let key = name.replace('-', "_");
    let hint = crate::names::closest(&key, &names)
        .map(|c| format!("; did you mean '{c}'?"))
        .unwrap_or_default();
    Error::Invalid(format!("unknown option '{name}'{hint}"))
}

impl Options {
    /// Sets the option `name` (its one name, an alias, hyphens or underscores) from text or
    /// a typed value; an error names the option and the value.
    ///
    /// ```
    /// let mut o = halftone::Options::default();
    /// o.set("method", "ordered").unwrap();
    /// o.set("levels", 4i64).unwrap();
    /// o.set("dot-gain", "15").unwrap();
    /// assert_eq!((o.levels, o.dot_gain), (4, 15.0));
    /// assert!(o.set("levels", "1").unwrap_err().to_string().contains("2 to 256"));
    /// ```
    pub fn set<'a>(&mut self, name: &str, value: impl Into<Value<'a>>) -> Result<()> {
        self.set_value(name, &value.into())
    }

    /// [`Options::set`] with a [`Value`] already made.
    pub fn set_value(&mut self, name: &str, value: &Value) -> Result<()> {
        let Some((spec, negated)) = find(name) else {
            return Err(unknown(name));
        };
        let result = if negated {
            match value.boolean() {
                Ok(b) => (spec.set)(self, &Value::Bool(!b)),
                Err(e) => Err(e),
            }
        } else {
            (spec.set)(self, value)
        };
        result.map_err(|msg| Error::Option {
            field: spec.name,
            value: value.to_string(),
            msg: strip_quoted(&msg, value).to_string(),
        })
    }

    /// The option `name`'s value as text (`None`: unset), for listings and round trips.
    pub fn get(&self, name: &str) -> Result<Option<String>> {
        let (spec, negated) = find(name).ok_or_else(|| unknown(name))?;
        let v = (spec.get)(self);
        Ok(if negated {
            v.map(|t| (t != "true").to_string())
        } else {
            v
        })
    }

    /// Fails on the first option in `given` (names from [`describe`]) that the chosen
    /// method or `format` does not read (`format` is `None` when not known yet), or that
    /// another given option takes over.
    pub fn check_used(&self, given: &[&str], format: Option<Format>) -> Result<()> {
        for written in given {
            let Some((spec, _)) = find(written) else {
                continue;
            };
            let name = written.replace('-', "_");
            match spec.used_by {
                UsedBy::Methods(ms) if !ms.contains(&self.method) => {
                    let users: Vec<&str> = ms.iter().map(|m| m.name()).collect();
                    return Err(Error::Invalid(format!(
                        "`{name}`: the {} method does not use it (it is for `method` {}); leave \
                         it out or choose that method",
                        self.method.name(),
                        users.join(" or ")
                    )));
                }
                UsedBy::NotWith(other) if given.iter().any(|g| g.replace('-', "_") == other) => {
                    return Err(Error::Invalid(format!(
                        "`{name}`: `{other}` decides it (the profile's own black generation, \
                         ink limit and separation); leave one of them out"
                    )));
                }
                UsedBy::Formats(fs) => {
                    if let Some(f) = format.filter(|f| !fs.contains(f)) {
                        let name = |f: Format| format!("{f:?}").to_ascii_uppercase();
                        let users: Vec<String> = fs.iter().map(|&f| name(f)).collect();
                        return Err(Error::Invalid(format!(
                            "`{}`: {} output does not use it (it is for {} output)",
                            written.replace('-', "_"),
                            name(f),
                            users.join(" or ")
                        )));
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// A message that opens with the value quoted (`'x': expected …`) loses the quote: the
/// error already names the value.
fn strip_quoted<'m>(msg: &'m str, value: &Value) -> &'m str {
    let quoted = format!("'{}': ", value.text());
    msg.strip_prefix(quoted.as_str()).unwrap_or(msg)
}

// ---- parsers ------------------------------------------------------------------------------

fn text(v: &Value) -> std::result::Result<String, String> {
    match v {
        Value::Text(t) => Ok(t.to_string()),
        Value::Bool(_) => Err(format!("'{v}': expected text")),
        other => Ok(other.to_string()),
    }
}

fn float(v: &Value) -> std::result::Result<f64, String> {
    v.number()
}

/// A number from `lo` to `hi`, in the words the device mapping's own check uses (a
/// non-finite value is out of range too, so every door names the range).
fn float_in(v: &Value, lo: f64, hi: f64) -> std::result::Result<f64, String> {
    let x = v.any_number()?;
    if (lo..=hi).contains(&x) {
        Ok(x)
    } else {
        Err(format!("expected a number from {lo} to {hi}"))
    }
}

fn usize_in(v: &Value, lo: usize, hi: usize) -> std::result::Result<usize, String> {
    v.whole(lo as i128, hi as i128).map(|n| n as usize)
}

fn show<T: std::fmt::Display>(v: T) -> Option<String> {
    Some(v.to_string())
}

fn amount(v: &Value) -> std::result::Result<Amount, String> {
    match v {
        Value::Int(_) | Value::Float(_) => format!("{}", v.number()?).parse(),
        _ => text(v)?.parse(),
    }
}

fn rotate(v: &Value) -> std::result::Result<Rotate, String> {
    let s = text(v)?;
    Ok(match s.trim().to_ascii_lowercase().as_str() {
        "auto" => Rotate::Auto,
        "0" | "none" => Rotate::None,
        "90" => Rotate::Clockwise(1),
        "180" => Rotate::Clockwise(2),
        "270" | "-90" => Rotate::Clockwise(3),
        _ => return Err(format!("'{s}': expected auto, 90, 180 or 270")),
    })
}

fn rotate_text(r: Rotate) -> Option<String> {
    match r {
        Rotate::None => None,
        Rotate::Auto => show("auto"),
        Rotate::Clockwise(q) => show(q as u32 * 90),
    }
}

fn fixed<T: Copy>(
    v: &Value,
    list: &[(&str, &str)],
    values: &[T],
) -> std::result::Result<T, String> {
    let s = text(v)?;
    let key = s.trim().to_ascii_lowercase();
    list.iter()
        .position(|(n, _)| *n == key)
        .map(|i| values[i])
        .ok_or_else(|| {
            let names: Vec<&str> = list.iter().map(|(n, _)| *n).collect();
            format!("'{s}': expected {}", or_list(&names))
        })
}

fn or_list(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => one.to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

fn kernels() -> Vec<String> {
    crate::method::diffusion::NAMES
        .iter()
        .map(|s| s.to_string())
        .collect()
}

fn palettes() -> Vec<String> {
    crate::color::Palette::builtin_names()
        .map(String::from)
        .collect()
}

fn masks() -> Vec<String> {
    crate::Mask::builtin_names().map(String::from).collect()
}

fn devices() -> Vec<String> {
    crate::io::panel::Device::builtin_names()
        .map(String::from)
        .collect()
}

fn spots() -> Vec<String> {
    crate::mask::screen::Spot::ALL
        .iter()
        .map(|s| s.name().to_string())
        .collect()
}

fn presses() -> Vec<String> {
    crate::press::Press::builtin_names()
        .map(String::from)
        .collect()
}

const METHODS: &[(&str, &str)] = &[
    (
        "threshold",
        "One fixed threshold (quantisation to the nearest level when --levels > 2)",
    ),
    (
        "pattern",
        "The lecture's halftone patterns: an n×n cell of a mask of pixel position numbers",
    ),
    (
        "ordered",
        "Ordered dithering: one threshold a pixel from a tiled mask (Bayer, clustered dot, blue \
         noise, or a file), placed in linear light",
    ),
    (
        "diffuse",
        "Error diffusion in linear light (see --kernel), to levels or a palette",
    ),
    (
        "dbs",
        "Direct binary search: the halftone that minimises the eye-filtered error (slow, best)",
    ),
    (
        "screen",
        "An AM screen at --lpi, --angle and --spot at the device --dpi (exact at any angle)",
    ),
];
const METHOD_KINDS: &[MethodKind] = &[
    MethodKind::Threshold,
    MethodKind::Pattern,
    MethodKind::Ordered,
    MethodKind::Diffuse,
    MethodKind::Dbs,
    MethodKind::Screen,
];

const COLORS: &[(&str, &str)] = &[
    ("gray", "Luminance in linear light, one output plane"),
    ("rgb", "Each of red, green and blue on its own"),
    (
        "cmyk",
        "Separation into cyan, magenta, yellow and black plates (see --press, --gcr, --tac)",
    ),
];
const COLOR_KINDS: &[Color] = &[Color::Gray, Color::Rgb, Color::Cmyk];

const CELLS: &[(&str, &str)] = &[
    (
        "expand",
        "Each input pixel becomes an n×n cell: output n× larger (a device of n× the resolution)",
    ),
    (
        "fit",
        "Output keeps the input's size; each n×n block is averaged and drawn as one pattern",
    ),
];
const CELL_KINDS: &[Cell] = &[Cell::Expand, Cell::Fit];

const COMPRESSIONS: &[(&str, &str)] = &[
    (
        "g4",
        "CCITT Group 4: what fax software and printers expect; best on text and line art",
    ),
    (
        "deflate",
        "Deflate: several times smaller than G4 on dithered photos",
    ),
    ("lzw", "LZW"),
    ("packbits", "PackBits"),
    ("none", "No compression"),
];
const COMPRESSION_KINDS: &[Compression] = &[
    Compression::G4,
    Compression::Deflate,
    Compression::Lzw,
    Compression::PackBits,
    Compression::None,
];

const CONTENTS: &[(&str, &str)] = &[
    ("photo", "Halftone everything with the method"),
    (
        "line-art",
        "Threshold everything: text, rules, barcodes and QR codes stay crisp",
    ),
    (
        "auto",
        "Threshold the regions that are already near black and white, halftone the rest",
    ),
];
const CONTENT_KINDS: &[ContentKind] =
    &[ContentKind::Photo, ContentKind::LineArt, ContentKind::Auto];

const ZPL_ENCODINGS: &[(&str, &str)] = &[
    (
        "hex",
        "Hexadecimal with Zebra's ASCII compression (every ZPL printer)",
    ),
    (
        "z64",
        "zlib + base64 with a CRC (`:Z64:`; smaller, firmware from about 2008 on)",
    ),
];
const ZPL_KINDS: &[ZplEncoding] = &[ZplEncoding::Hex, ZplEncoding::Z64];

const PRINTER_MODELS: &[(&str, &str)] = &[
    (
        "ideal",
        "Ideal printer: every pixel prints as a square of its level",
    ),
    (
        "dot-overlap",
        "Pappas–Neuhoff circular dots of --dot-ratio that spill onto their neighbours",
    ),
    (
        "table",
        "A measured 3×3-neighbourhood table (--printer-table FILE)",
    ),
];
const PRINTER_MODEL_KINDS: &[PrinterModelKind] = &[
    PrinterModelKind::Ideal,
    PrinterModelKind::DotOverlap,
    PrinterModelKind::Table,
];

const SEPARATIONS: &[(&str, &str)] = &[
    (
        "model",
        "Invert a model of the press (Yule–Nielsen Neugebauer) through a 3-D lookup table",
    ),
    (
        "naive",
        "The plain complement (C = 1 − R …) with grey component replacement: fast, off-colour",
    ),
];
const SEPARATION_KINDS: &[SeparationKind] = &[SeparationKind::Model, SeparationKind::Naive];

const INTENTS: &[(&str, &str)] = &[
    (
        "perceptual",
        "Compress the whole sRGB gamut into the press's (or the panel's)",
    ),
    (
        "relative",
        "Media-relative colorimetric: in-gamut colours exact, paper (or the panel's white) as \
         white, black-point compensated for a device",
    ),
    ("saturation", "Vivid colours (business graphics)"),
    (
        "absolute",
        "Absolute colorimetric: simulates the paper's tint",
    ),
];
const INTENT_KINDS: &[RenderingIntent] = &[
    RenderingIntent::Perceptual,
    RenderingIntent::Relative,
    RenderingIntent::Saturation,
    RenderingIntent::Absolute,
];

const INK_COLOURS: &[(&str, &str)] = &[
    (
        "measured",
        "The inks' measured colours: what the panel shows",
    ),
    (
        "nominal",
        "The inks' nominal colours: what the driver expects",
    ),
];
const INK_COLOUR_KINDS: &[InkColours] = &[InkColours::Measured, InkColours::Nominal];

const FIT_MODES: &[(&str, &str)] = &[
    ("inside", "Aspect kept, one side may fall short"),
    ("pad", "As inside, centred on white to exactly the box"),
    (
        "cover",
        "Aspect kept, the overflow cropped about the centre",
    ),
];
const FIT_MODE_KINDS: &[FitMode] = &[FitMode::Inside, FitMode::Pad, FitMode::Cover];

const TEMPORALS: &[(&str, &str)] = &[
    (
        "stable",
        "Error diffusion re-decides a dot only where the picture changed visibly; the other \
         methods are stable by construction",
    ),
    ("frame", "Every frame halftoned on its own"),
];
const TEMPORAL_KINDS: &[Temporal] = &[Temporal::Stable, Temporal::Frame];

fn name_of<T: PartialEq + Copy>(list: &[(&'static str, &str)], kinds: &[T], v: T) -> String {
    let i = kinds.iter().position(|&k| k == v).unwrap_or(0);
    list[i].0.to_string()
}

use MethodKind::{Dbs, Diffuse, Ordered, Pattern, Screen};

const fn spec(name: &'static str) -> OptionSpec {
    OptionSpec {
        name,
        aliases: &[],
        short: None,
        value_name: "",
        help: "",
        form: Form::Value,
        choices: Choices::Open,
        kind: Kind::Text,
        used_by: UsedBy::All,
        set: |_, _| Ok(()),
        get: |_| None,
    }
}

/// The table. Field by field of [`Options`] (and of its printer options).
static TABLE: &[OptionSpec] = &[
    OptionSpec {
        short: Some('m'),
        value_name: "METHOD",
        help: "Halftoning method [default: diffuse, Floyd–Steinberg in linear light, serpentine]",
        choices: Choices::Fixed(METHODS),
        set: |o, v| {
            o.method = fixed(v, METHODS, METHOD_KINDS)?;
            Ok(())
        },
        get: |o| show(o.method),
        ..spec("method")
    },
    OptionSpec {
        value_name: "0.5|50%|128",
        help: "Threshold for `--method threshold`; a pixel at or above it becomes paper: a \
               fraction of reflectance (0.5 = half the light, linear unless --no-linearize), a \
               percentage (50%, the same), or an 8-bit code of the input (128 = sRGB code 128, \
               21.6% of the light)",
        used_by: UsedBy::Methods(&[MethodKind::Threshold]),
        set: |o, v| {
            o.threshold = match v {
                // A float from a typed door is a fraction even when whole (1.0).
                Value::Float(x) => format!("{x:?}").parse::<Threshold>()?,
                other => text(other)?.parse::<Threshold>()?,
            };
            Ok(())
        },
        get: |o| {
            show(match o.threshold {
                Threshold::Fraction(f) => format!("{f}"),
                Threshold::Percent(p) => format!("{p}%"),
                Threshold::Code(c) => format!("{c}"),
            })
        },
        kind: Kind::NumberOrText,
        ..spec("threshold")
    },
    OptionSpec {
        value_name: "MASK",
        help: "Mask: a built-in name (see `halftone masks list`) or a mask file [default: \
               seed-3x3 for pattern, bayer-8 for ordered]",
        choices: Choices::Named(masks),
        used_by: UsedBy::Methods(&[Pattern, Ordered]),
        set: |o, v| {
            o.mask = Some(text(v)?);
            Ok(())
        },
        get: |o| o.mask.clone(),
        kind: Kind::Path,
        ..spec("mask")
    },
    OptionSpec {
        short: Some('k'),
        value_name: "KERNEL",
        help: "Error-diffusion kernel: a built-in name, tded (trained), or a kernel file (see \
               kernels/README.md)",
        choices: Choices::Named(kernels),
        used_by: UsedBy::Methods(&[Diffuse]),
        set: |o, v| {
            o.kernel = text(v)?;
            Ok(())
        },
        get: |o| Some(o.kernel.clone()),
        kind: Kind::Path,
        ..spec("kernel")
    },
    OptionSpec {
        aliases: &["no_serpentine"],
        help: "Error diffusion: alternate direction every row (the default; reduces worms); \
               --no-serpentine: every row left to right (lets raster kernels use two cores)",
        form: Form::Both("no-serpentine"),
        used_by: UsedBy::Methods(&[Diffuse]),
        set: |o, v| {
            o.serpentine = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.serpentine),
        kind: Kind::Bool,
        ..spec("serpentine")
    },
    OptionSpec {
        value_name: "STRENGTH",
        help: "Error diffusion: share of the error passed on, 0..1",
        used_by: UsedBy::Methods(&[Diffuse]),
        set: |o, v| {
            let x = float(v)?;
            if !(0.0..=1.0).contains(&x) {
                return Err("must be from 0 to 1".into());
            }
            o.strength = x as f32;
            Ok(())
        },
        get: |o| show(o.strength),
        kind: Kind::Number,
        ..spec("strength")
    },
    OptionSpec {
        value_name: "PALETTE",
        help: "Diffuse (or, with --method ordered, pattern-dither) to a palette: a built-in, a \
               file of hex colours or a GIMP .gpl, or auto:N for N colours made from the image \
               (2 to 256). Implies --color rgb",
        choices: Choices::Named(palettes),
        used_by: UsedBy::Methods(&[Diffuse, Dbs, Ordered]),
        set: |o, v| {
            o.palette = Some(text(v)?);
            Ok(())
        },
        get: |o| o.palette.clone(),
        kind: Kind::Path,
        ..spec("palette")
    },
    OptionSpec {
        value_name: "NAME|FILE",
        help: "An e-paper panel: a built-in profile (see `halftone devices list`) or a profile \
               file. Its inks become the palette (in the panel's order), the picture is fitted \
               into the panel (turned by its rotation) unless a size is given, and its ppi is \
               recorded unless --dpi is. Panel buffers: --format raw, h, planes or nibbles",
        choices: Choices::Named(devices),
        used_by: UsedBy::Methods(&[Diffuse, Dbs, Ordered]),
        set: |o, v| {
            o.device = Some(text(v)?);
            Ok(())
        },
        get: |o| o.device.clone(),
        kind: Kind::Path,
        ..spec("device")
    },
    OptionSpec {
        value_name: "WHICH",
        help: "With --device: write PNG (and the other colour formats) in the inks' measured \
               colours (what the panel shows) or their nominal ones (what the driver expects)",
        choices: Choices::Fixed(INK_COLOURS),
        set: |o, v| {
            o.ink_colours = fixed(v, INK_COLOURS, INK_COLOUR_KINDS)?;
            Ok(())
        },
        get: |o| Some(name_of(INK_COLOURS, INK_COLOUR_KINDS, o.ink_colours)),
        ..spec("ink_colours")
    },
    OptionSpec {
        value_name: "STOPS",
        help: "With --device or --palette: exposure in stops (+1 doubles the light)",
        set: |o, v| {
            o.exposure = float_in(v, -8.0, 8.0)? as f32;
            Ok(())
        },
        get: |o| show(o.exposure),
        kind: Kind::Number,
        ..spec("exposure")
    },
    OptionSpec {
        value_name: "FACTOR",
        help: "With --device or --palette: chroma multiplier at constant lightness (0 grey, 1 \
               as is)",
        set: |o, v| {
            o.saturation = float_in(v, 0.0, 4.0)? as f32;
            Ok(())
        },
        get: |o| show(o.saturation),
        kind: Kind::Number,
        ..spec("saturation")
    },
    OptionSpec {
        value_name: "auto|off|STRENGTH",
        help: "With --device (perceptual intent): stretch the picture's tone range to the \
               panel's: auto (from its histogram), off, or a strength 0..1",
        set: |o, v| {
            o.tone = amount(v)?;
            Ok(())
        },
        get: |o| show(o.tone),
        kind: Kind::NumberOrText,
        ..spec("tone")
    },
    OptionSpec {
        value_name: "auto|off|STRENGTH",
        help: "With --device (perceptual intent): compress colours the inks cannot show \
               towards the gamut's cusp, hue kept: auto (as far as the picture reaches), off \
               (clip), or 0..1",
        set: |o, v| {
            o.gamut = amount(v)?;
            Ok(())
        },
        get: |o| show(o.gamut),
        kind: Kind::NumberOrText,
        ..spec("gamut")
    },
    OptionSpec {
        value_name: "SEED",
        help: "Seed for methods that draw noise (zhou-fang's threshold modulation)",
        used_by: UsedBy::Methods(&[Diffuse]),
        set: |o, v| {
            o.seed = v.whole(0, u64::MAX as i128)? as u64;
            Ok(())
        },
        get: |o| show(o.seed),
        kind: Kind::Int,
        ..spec("seed")
    },
    OptionSpec {
        short: Some('l'),
        value_name: "LEVELS",
        help: "Output levels a pixel per channel (2 = bilevel; 4 for a 4-level device)",
        set: |o, v| {
            let n = v
                .whole(i64::MIN as i128, i64::MAX as i128)
                .map_err(|_| "expected a whole number of levels from 2 to 256".to_string())?;
            if !(2..=256).contains(&n) {
                return Err("levels must be from 2 to 256 (2 is bilevel)".into());
            }
            o.levels = n as u16;
            Ok(())
        },
        get: |o| show(o.levels),
        kind: Kind::Int,
        ..spec("levels")
    },
    OptionSpec {
        value_name: "COLOR",
        help: "Grey (luminance in linear light) or each RGB channel on its own",
        choices: Choices::Fixed(COLORS),
        set: |o, v| {
            o.color = fixed(v, COLORS, COLOR_KINDS)?;
            Ok(())
        },
        get: |o| show(o.color),
        ..spec("color")
    },
    OptionSpec {
        value_name: "CELL",
        help: "Pattern cells: expand (output n× larger) or fit (same size, resolution reduced \
               by n)",
        choices: Choices::Fixed(CELLS),
        used_by: UsedBy::Methods(&[Pattern]),
        set: |o, v| {
            o.cell = fixed(v, CELLS, CELL_KINDS)?;
            Ok(())
        },
        get: |o| Some(name_of(CELLS, CELL_KINDS, o.cell)),
        ..spec("cell")
    },
    OptionSpec {
        aliases: &["no_linearize"],
        help: "--no-linearize: treat codes as linear (the naive behaviour of most tools) \
               instead of decoding sRGB",
        form: Form::Negative("no-linearize"),
        set: |o, v| {
            o.linearize = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.linearize),
        kind: Kind::Bool,
        ..spec("linearize")
    },
    OptionSpec {
        help: "Negative media: paper where the image is dark",
        form: Form::Switch,
        set: |o, v| {
            o.invert = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.invert),
        kind: Kind::Bool,
        ..spec("invert")
    },
    OptionSpec {
        value_name: "GAMMA",
        help: "Extra gamma on linear reflectance (r' = r^gamma); 1 = none",
        set: |o, v| {
            let x = float(v)?;
            if x <= 0.0 {
                return Err("must be a positive number".into());
            }
            o.gamma = x as f32;
            Ok(())
        },
        get: |o| show(o.gamma),
        kind: Kind::Number,
        ..spec("gamma")
    },
    OptionSpec {
        value_name: "PERCENT",
        help: "Pre-compensate this dot gain at 50% coverage, in percent (e.g. 15)",
        set: |o, v| {
            let x = float(v)?;
            if !(0.0..50.0).contains(&x) {
                return Err("must be a percentage from 0 to 50".into());
            }
            o.dot_gain = x as f32;
            Ok(())
        },
        get: |o| show(o.dot_gain),
        kind: Kind::Number,
        ..spec("dot_gain")
    },
    OptionSpec {
        value_name: "FILE.csv",
        help: "A measured step wedge (CSV: nominal %, measured %; one measured column per ink \
               for CMYK; `#` comments): inverted into a compensation curve applied before \
               halftoning",
        set: |o, v| {
            o.transfer = Some(PathBuf::from(text(v)?));
            Ok(())
        },
        get: |o| o.transfer.as_ref().map(|p| p.display().to_string()),
        kind: Kind::Path,
        ..spec("transfer")
    },
    OptionSpec {
        value_name: "FORMAT",
        help: "Output format; default from the output's extension",
        form: Form::Door,
        choices: Choices::Named(|| Format::WRITABLE.iter().map(|s| s.to_string()).collect()),
        set: |o, v| {
            let s = text(v)?;
            o.format = Some(Format::from_name(s.trim()).ok_or_else(|| {
                format!(
                    "'{s}': not a format halftone writes; formats: {}",
                    Format::WRITABLE.join(", ")
                )
            })?);
            Ok(())
        },
        get: |o| o.format.map(|f| f.name().to_string()),
        ..spec("format")
    },
    OptionSpec {
        value_name: "DPI",
        help: "Resolution recorded in the output (PNG pHYs, TIFF and BMP resolution), dots per \
               inch",
        set: |o, v| {
            let x = v
                .number()
                .map_err(|_| "expected a number of dots per inch (e.g. 300)".to_string())?;
            if x <= 0.0 {
                return Err(
                    "a resolution must be a positive number of dots per inch (e.g. 300)".into(),
                );
            }
            o.dpi = Some(x);
            Ok(())
        },
        get: |o| o.dpi.map(|d| d.to_string()),
        kind: Kind::Number,
        ..spec("dpi")
    },
    OptionSpec {
        value_name: "MAXVAL",
        help: "PGM/PPM maxval [default: 255, display codes; levels−1 with --device-levels]",
        used_by: UsedBy::Formats(&[Format::Pgm, Format::Ppm]),
        set: |o, v| {
            o.maxval = Some(v.whole(1, 65535)? as u16);
            Ok(())
        },
        get: |o| o.maxval.map(|m| m.to_string()),
        kind: Kind::Int,
        ..spec("maxval")
    },
    OptionSpec {
        value_name: "COMPRESSION",
        help: "TIFF compression (bilevel); PDF takes deflate (the default) or g4",
        choices: Choices::Fixed(COMPRESSIONS),
        used_by: UsedBy::Formats(&[Format::Tiff, Format::Pdf]),
        set: |o, v| {
            o.compression = Some(fixed(v, COMPRESSIONS, COMPRESSION_KINDS)?);
            Ok(())
        },
        get: |o| {
            o.compression
                .map(|c| name_of(COMPRESSIONS, COMPRESSION_KINDS, c))
        },
        ..spec("compression")
    },
    OptionSpec {
        help: "Store device level numbers (0..L−1) in multi-level PGM/PPM and 2/4-bit PNG \
               instead of display codes (sRGB-encoded reflectance, which every viewer shows at \
               the right tone)",
        form: Form::Switch,
        used_by: UsedBy::Formats(&[Format::Pgm, Format::Ppm, Format::Png]),
        set: |o, v| {
            o.device_levels = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.device_levels),
        kind: Kind::Bool,
        ..spec("device_levels")
    },
    OptionSpec {
        value_name: "PIXELS",
        help: "Refuse images larger than this many pixels (checked from the header, before \
               decoding)",
        set: |o, v| {
            o.max_pixels = v.whole(1, u64::MAX as i128)? as u64;
            Ok(())
        },
        get: |o| show(o.max_pixels),
        kind: Kind::Int,
        ..spec("max_pixels")
    },
    OptionSpec {
        value_name: "WIDTH",
        help: "Resize to this width in pixels first (in linear light, Lanczos-3; aspect kept)",
        set: |o, v| {
            o.width = Some(usize_in(v, 1, 1 << 31)?);
            Ok(())
        },
        get: |o| o.width.map(|w| w.to_string()),
        kind: Kind::Int,
        ..spec("width")
    },
    OptionSpec {
        value_name: "HEIGHT",
        help: "Resize to this height in pixels first (aspect kept unless --width is given too; \
               both together set an exact size)",
        set: |o, v| {
            o.height = Some(usize_in(v, 1, 1 << 31)?);
            Ok(())
        },
        get: |o| o.height.map(|h| h.to_string()),
        kind: Kind::Int,
        ..spec("height")
    },
    OptionSpec {
        value_name: "WxH",
        help: "Resize to the largest size inside this box with the aspect ratio kept, e.g. \
               800x480 for a panel (enlarges small images too)",
        set: |o, v| {
            o.fit = Some(match v {
                Value::Pair(w, h) if *w > 0 && *h > 0 => (*w as usize, *h as usize),
                other => crate::resize::parse_box(&text(other)?).map_err(|e| e.to_string())?,
            });
            Ok(())
        },
        get: |o| o.fit.map(|(w, h)| format!("{w}x{h}")),
        kind: Kind::TextOrPair,
        ..spec("fit")
    },
    OptionSpec {
        value_name: "inside|pad|cover",
        help: "How the picture goes into the --fit box or a --device's panel: inside (aspect \
               kept, one side may fall short), pad (as inside, centred on white to exactly the \
               box) or cover (aspect kept, the overflow cropped about the centre) [default: pad \
               for a --device with no size given, inside for --fit]",
        choices: Choices::Fixed(FIT_MODES),
        set: |o, v| {
            o.fit_mode = Some(fixed(v, FIT_MODES, FIT_MODE_KINDS)?);
            Ok(())
        },
        get: |o| o.fit_mode.map(|m| name_of(FIT_MODES, FIT_MODE_KINDS, m)),
        ..spec("fit_mode")
    },
    OptionSpec {
        value_name: "SIZE",
        help: "Resize to this physical width first (4in, 100mm, 10cm), with --dpi",
        set: |o, v| {
            o.size = Some(text(v)?);
            Ok(())
        },
        get: |o| o.size.clone(),
        ..spec("size")
    },
    OptionSpec {
        value_name: "auto|90|180|270",
        help: "Turn the image first: auto (a portrait photo turned a quarter clockwise for a \
               landscape --fit box, and the other way round), or 90, 180, 270 degrees clockwise",
        set: |o, v| {
            o.rotate = rotate(v)?;
            Ok(())
        },
        get: |o| rotate_text(o.rotate),
        kind: Kind::IntOrText,
        ..spec("rotate")
    },
    OptionSpec {
        value_name: "SIZE",
        help: "Memory for image data: a size such as 64M or 2G, or auto. Images that do not fit \
               are streamed in bands of rows (PNM, PNG and TIFF-strip input; threshold, ordered, \
               pattern and error diffusion except Riemersma and palettes); work that needs the \
               whole image and does not fit is refused before decoding [default: auto: whole \
               images up to a quarter of the free memory (at most 1 GiB), streaming beyond]",
        set: |o, v| {
            o.max_memory = MaxMemory::parse(&text(v)?).map_err(|e| e.to_string())?;
            Ok(())
        },
        get: |o| match o.max_memory {
            MaxMemory::Auto => None,
            MaxMemory::Bytes(b) => show(b),
        },
        ..spec("max_memory")
    },
    OptionSpec {
        value_name: "PASSES",
        help: "DBS: at most this many passes (it stops earlier when a pass changes nothing)",
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.passes = v.whole(0, u32::MAX as i128)? as u32;
            Ok(())
        },
        get: |o| show(o.passes),
        kind: Kind::Int,
        ..spec("passes")
    },
    OptionSpec {
        value_name: "INCHES",
        help: "DBS: viewing distance in inches for the eye model (with --dpi, default 300)",
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.distance = float(v)?;
            Ok(())
        },
        get: |o| show(o.distance),
        kind: Kind::Number,
        ..spec("distance")
    },
    OptionSpec {
        aliases: &["no_tone_correction"],
        help: "--no-tone-correction: DBS without the correction of its tone response",
        form: Form::Negative("no-tone-correction"),
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.tone_correction = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.tone_correction),
        kind: Kind::Bool,
        ..spec("tone_correction")
    },
    OptionSpec {
        value_name: "HYSTERESIS",
        help: "Error diffusion: output-dependent feedback (Levien's hysteresis) that clusters \
               dots into small aperiodic groups (\"green noise\") that survive dot gain; 0 = plain",
        used_by: UsedBy::Methods(&[Diffuse]),
        set: |o, v| {
            o.hysteresis = float(v)? as f32;
            Ok(())
        },
        get: |o| show(o.hysteresis),
        kind: Kind::Number,
        ..spec("hysteresis")
    },
    OptionSpec {
        value_name: "MODEL",
        help: "Printer model: what the bitmap looks like once printed. With --method dbs, DBS \
               optimises the printed result (model-based DBS); `compare` scores the printed \
               result",
        choices: Choices::Fixed(PRINTER_MODELS),
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.printer_model = fixed(v, PRINTER_MODELS, PRINTER_MODEL_KINDS)?;
            Ok(())
        },
        get: |o| show(o.printer_model),
        ..spec("printer_model")
    },
    OptionSpec {
        value_name: "RATIO",
        help: "Dot ratio of the dot-overlap model: dot diameter over the pixel's diagonal (1 = \
               the dot just covers its pixel, 1.414 = it reaches the neighbours' centres). \
               Lasers: about 1.25",
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.dot_ratio = float(v)?;
            Ok(())
        },
        get: |o| show(o.dot_ratio),
        kind: Kind::Number,
        ..spec("dot_ratio")
    },
    OptionSpec {
        value_name: "FILE",
        help: "Measured printer table for `--printer-model table`: 512 printed reflectances, one \
               for each 3×3 neighbourhood (see docs/accuracy.md)",
        used_by: UsedBy::Methods(&[Dbs]),
        set: |o, v| {
            o.printer_table = Some(PathBuf::from(text(v)?));
            Ok(())
        },
        get: |o| o.printer_table.as_ref().map(|p| p.display().to_string()),
        kind: Kind::Path,
        ..spec("printer_table")
    },
    OptionSpec {
        value_name: "LPI",
        help: "Screen frequency in lines per inch (`--method screen`, CMYK plates); with \
               --color cmyk also per ink: `c=150,m=150,y=133,k=175`",
        used_by: UsedBy::Methods(&[Screen]),
        set: |o, v| {
            o.lpi = text(v)?;
            Ok(())
        },
        get: |o| Some(o.lpi.clone()),
        kind: Kind::NumberOrText,
        ..spec("lpi")
    },
    OptionSpec {
        value_name: "DEGREES",
        help: "Screen angle in degrees, counter-clockwise from the x axis (PostScript's sense)",
        used_by: UsedBy::Methods(&[Screen]),
        set: |o, v| {
            o.angle = float(v)?;
            Ok(())
        },
        get: |o| show(o.angle),
        kind: Kind::Number,
        ..spec("angle")
    },
    OptionSpec {
        value_name: "SPOT",
        help: "Spot function: a PDF name (Round, SimpleDot, Ellipse, Diamond, Line, …; any \
               case, kebab-case too)",
        choices: Choices::Named(spots),
        used_by: UsedBy::Methods(&[Screen]),
        set: |o, v| {
            o.spot = text(v)?;
            Ok(())
        },
        get: |o| Some(o.spot.clone()),
        ..spec("spot")
    },
    OptionSpec {
        value_name: "ANGLES",
        help: "CMYK plate angles, e.g. `c=15,m=75,y=0,k=45` (the default)",
        used_by: UsedBy::Methods(&[Screen]),
        set: |o, v| {
            o.angles = Some(text(v)?);
            Ok(())
        },
        get: |o| o.angles.clone(),
        ..spec("angles")
    },
    OptionSpec {
        value_name: "PRESS",
        help: "Press to separate for: fogra39 (coated offset, the default), fogra29 (uncoated), \
               tr002 (newsprint), gracol, or a characterisation file (.ti3, CGATS with CMYK and \
               XYZ)",
        choices: Choices::Named(presses),
        used_by: UsedBy::NotWith("icc"),
        set: |o, v| {
            o.press = text(v)?;
            Ok(())
        },
        get: |o| Some(o.press.clone()),
        kind: Kind::Path,
        ..spec("press")
    },
    OptionSpec {
        value_name: "PERCENT",
        help: "Grey component replacement, percent: 0 builds greys from C, M, Y; 100 from black \
               alone",
        used_by: UsedBy::NotWith("icc"),
        set: |o, v| {
            o.gcr = float(v)?;
            Ok(())
        },
        get: |o| show(o.gcr),
        kind: Kind::Number,
        ..spec("gcr")
    },
    OptionSpec {
        value_name: "PERCENT",
        help: "Total area coverage limit, percent (sum of the four inks)",
        used_by: UsedBy::NotWith("icc"),
        set: |o, v| {
            o.tac = float(v)?;
            Ok(())
        },
        get: |o| show(o.tac),
        kind: Kind::Number,
        ..spec("tac")
    },
    OptionSpec {
        value_name: "SEPARATION",
        help: "Separation: the press model (default) or the naive complement",
        choices: Choices::Fixed(SEPARATIONS),
        used_by: UsedBy::NotWith("icc"),
        set: |o, v| {
            o.separation = fixed(v, SEPARATIONS, SEPARATION_KINDS)?;
            Ok(())
        },
        get: |o| show(o.separation),
        ..spec("separation")
    },
    OptionSpec {
        value_name: "FILE.icc",
        help: "Separate through a vendor's ICC output profile (CMYK, class 'prtr') instead of \
               the press model; black generation and ink limit are the profile's (no --gcr, \
               --tac)",
        set: |o, v| {
            o.icc = Some(PathBuf::from(text(v)?));
            Ok(())
        },
        get: |o| o.icc.as_ref().map(|p| p.display().to_string()),
        kind: Kind::Path,
        ..spec("icc")
    },
    OptionSpec {
        value_name: "INTENT",
        help: "Rendering intent: with --icc [default: relative]; with --device [default: \
               perceptual] or --palette [default: absolute, the colours as given]",
        choices: Choices::Fixed(INTENTS),
        set: |o, v| {
            o.intent = Some(fixed(v, INTENTS, INTENT_KINDS)?);
            Ok(())
        },
        get: |o| o.intent.map(|i| name_of(INTENTS, INTENT_KINDS, i)),
        ..spec("intent")
    },
    OptionSpec {
        help: "CMYK: also render how the printed plates look (the command line writes it to \
               --preview FILE.png)",
        form: Form::Door,
        set: |o, v| {
            o.preview = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.preview),
        kind: Kind::Bool,
        ..spec("preview")
    },
    OptionSpec {
        value_name: "N",
        help: "Device pixels averaged into one preview pixel [default: two screen periods; 1 \
               shows every dot in the press's colours, a magnified rosette]",
        set: |o, v| {
            o.preview_block = Some(usize_in(v, 1, 1 << 16)?);
            Ok(())
        },
        get: |o| o.preview_block.map(|b| b.to_string()),
        kind: Kind::Int,
        ..spec("preview_block")
    },
    OptionSpec {
        value_name: "MODE",
        help: "Clips (animations, streams, frame series): how frames are halftoned in time; a \
               still picture is unaffected",
        choices: Choices::Fixed(TEMPORALS),
        set: |o, v| {
            o.temporal = fixed(v, TEMPORALS, TEMPORAL_KINDS)?;
            Ok(())
        },
        get: |o| show(o.temporal),
        ..spec("temporal")
    },
    OptionSpec {
        value_name: "CONTENT",
        help: "Photo: halftone everything; line-art: threshold everything; auto: threshold the \
               near-black-and-white regions (text, barcodes) and halftone the rest",
        choices: Choices::Fixed(CONTENTS),
        set: |o, v| {
            o.content = fixed(v, CONTENTS, CONTENT_KINDS)?;
            Ok(())
        },
        get: |o| show(o.content),
        ..spec("content")
    },
    OptionSpec {
        value_name: "SIZE",
        help: "PDF, PostScript, PCL, PWG/Apple/CUPS raster: the page to centre the image on (a4, \
               letter, or WxH with in or mm, e.g. 4x6in); default: the image's own size at --dpi",
        used_by: UsedBy::Formats(&[
            Format::Pdf,
            Format::Ps,
            Format::Pcl,
            Format::Pwg,
            Format::Urf,
            Format::CupsRaster,
        ]),
        set: |o, v| {
            let s = text(v)?;
            o.print.page = Some(s.parse::<PageSize>()?);
            Ok(())
        },
        get: |o| o.print.page.map(|p| format!("{p:?}")),
        ..spec("page")
    },
    OptionSpec {
        value_name: "N",
        help: "ESC/POS: rows per `GS v 0` raster band (at most 960; smaller for printers with \
               small buffers)",
        used_by: UsedBy::Formats(&[Format::EscPos]),
        set: |o, v| {
            o.print.band_rows = usize_in(v, 1, MAX_BAND_ROWS)?;
            Ok(())
        },
        get: |o| show(o.print.band_rows),
        kind: Kind::Int,
        ..spec("band_rows")
    },
    OptionSpec {
        help: "ESC/POS: feed and cut the paper after each image",
        form: Form::Switch,
        used_by: UsedBy::Formats(&[Format::EscPos]),
        set: |o, v| {
            o.print.cut = v.boolean()?;
            Ok(())
        },
        get: |o| show(o.print.cut),
        kind: Kind::Bool,
        ..spec("cut")
    },
    OptionSpec {
        value_name: "DOTS",
        help: "ESC/POS: print head width in dots (384 for 58 mm and 576 for 80 mm paper at 203 \
               dpi, 512 at 180 dpi); a wider image is refused",
        used_by: UsedBy::Formats(&[Format::EscPos]),
        set: |o, v| {
            o.print.paper_width = Some(usize_in(v, 1, 65535)?);
            Ok(())
        },
        get: |o| o.print.paper_width.map(|w| w.to_string()),
        kind: Kind::Int,
        ..spec("paper_width")
    },
    OptionSpec {
        value_name: "ENCODING",
        help: "ZPL: graphic field encoding",
        choices: Choices::Fixed(ZPL_ENCODINGS),
        used_by: UsedBy::Formats(&[Format::Zpl]),
        set: |o, v| {
            o.print.zpl_encoding = fixed(v, ZPL_ENCODINGS, ZPL_KINDS)?;
            Ok(())
        },
        get: |o| Some(name_of(ZPL_ENCODINGS, ZPL_KINDS, o.print.zpl_encoding)),
        ..spec("zpl_encoding")
    },
    OptionSpec {
        value_name: "DOTS",
        help: "ZPL: the printer's longest label in dots; a longer one is refused",
        used_by: UsedBy::Formats(&[Format::Zpl]),
        set: |o, v| {
            o.print.max_length = usize_in(v, 1, ZPL_MAX_LENGTH)?;
            Ok(())
        },
        get: |o| show(o.print.max_length),
        kind: Kind::Int,
        ..spec("max_length")
    },
];

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn names_are_unique_and_flag_shaped() {
        let names = accepted_names();
        let set: BTreeSet<&str> = names.iter().copied().collect();
        assert_eq!(set.len(), names.len(), "a name twice");
        for n in names {
            assert!(
                n.bytes().all(|b| b.is_ascii_lowercase() || b == b'_'),
                "{n}"
            );
        }
    }

    /// Each option's kind agrees with its form, its choices and its parser: a switch is a
    /// boolean, a fixed list is text, the default handed over as the typed value its kind
    /// names is taken, and a value of the wrong type is refused.
    #[test]
    fn every_kind_matches_its_parser() {
        for spec in describe() {
            let n = spec.name;
            if !matches!(spec.form, Form::Value | Form::Door) {
                assert_eq!(spec.kind, Kind::Bool, "{n}: a switch");
            }
            if let Choices::Fixed(_) = spec.choices {
                assert_eq!(spec.kind, Kind::Text, "{n}: a fixed list");
            }
            match spec.kind {
                Kind::Bool | Kind::Int => {
                    assert!(spec.check(&Value::Float(0.5)).is_err(), "{n} took 0.5")
                }
                Kind::Number => {
                    assert!(spec.check(&Value::Bool(true)).is_err(), "{n} took true")
                }
                _ => {}
            }
            let Some(d) = spec.default_text() else {
                continue;
            };
            let typed = match spec.kind {
                Kind::Bool => Value::Bool(d.parse().expect(n)),
                Kind::Int => Value::Int(d.parse().expect(n)),
                Kind::Number => Value::Float(d.parse().expect(n)),
                Kind::IntOrText => d
                    .parse()
                    .map(Value::Int)
                    .unwrap_or_else(|_| d.clone().into()),
                Kind::NumberOrText => d
                    .parse()
                    .map(Value::Float)
                    .unwrap_or_else(|_| d.clone().into()),
                _ => Value::from(d.clone()),
            };
            spec.check(&typed)
                .unwrap_or_else(|e| panic!("{n}: its default {typed:?}: {e}"));
            if let Value::Float(x) = typed {
                // A number, not a whole number in disguise: a fraction beside the default is
                // taken.
                let near = [x - 0.25, x + 0.25];
                assert!(
                    near.iter().any(|&y| spec.check(&Value::Float(y)).is_ok()),
                    "{n}: a number that takes no fraction is an int"
                );
            }
        }
    }

    #[test]
    fn every_option_round_trips_its_default() {
        for spec in describe() {
            if let Some(text) = spec.default_text() {
                let mut o = Options::default();
                o.set(spec.name, text.as_str())
                    .unwrap_or_else(|e| panic!("{}: {e}", spec.name));
                assert_eq!((spec.get)(&o), Some(text), "{}", spec.name);
            }
        }
    }

    #[test]
    fn every_fixed_value_sets_and_reads_back() {
        for spec in describe() {
            if let Choices::Fixed(list) = spec.choices {
                for (name, _) in list {
                    let mut o = Options::default();
                    o.set(spec.name, *name).unwrap();
                    assert_eq!((spec.get)(&o).as_deref(), Some(*name), "{}", spec.name);
                }
            }
        }
    }

    /// An option whose values are a closed enum lists exactly the enum's names.
    #[test]
    fn fixed_lists_are_the_enums_names() {
        let names = |n: &str| find(n).unwrap().0.values();
        assert_eq!(names("method"), MethodKind::NAMES);
        assert_eq!(names("color"), Color::NAMES);
        assert_eq!(names("printer_model"), PrinterModelKind::NAMES);
        assert_eq!(names("separation"), SeparationKind::NAMES);
        assert_eq!(names("content"), ContentKind::NAMES);
        assert_eq!(names("ink_colours"), InkColours::NAMES);
        assert_eq!(names("temporal"), Temporal::NAMES);
        assert_eq!(
            Options::default().get("temporal").unwrap().as_deref(),
            Some("stable")
        );
        let e = Options::default().set("temporal", "still").unwrap_err();
        assert_eq!(e.to_string(), "temporal still: expected stable or frame");
    }

    #[test]
    fn typed_and_text_values_agree() {
        let mut a = Options::default();
        let mut b = Options::default();
        a.set("levels", 4i64).unwrap();
        b.set("levels", "4").unwrap();
        a.set("no_linearize", true).unwrap();
        b.set("linearize", "false").unwrap();
        a.set("fit", Value::Pair(800, 480)).unwrap();
        b.set("fit", "800x480").unwrap();
        a.set("threshold", 0.25f64).unwrap();
        b.set("threshold", "0.25").unwrap();
        for spec in describe() {
            assert_eq!((spec.get)(&a), (spec.get)(&b), "{}", spec.name);
        }
        let e = a.set("levels", 70000i64).unwrap_err().to_string();
        assert_eq!(
            e,
            "levels 70000: levels must be from 2 to 256 (2 is bilevel)"
        );
        let e = a.set("seed", -1i64).unwrap_err().to_string();
        assert!(e.contains("from 0 to 18446744073709551615"), "{e}");
        let e = a.set("seed", "1".repeat(60)).unwrap_err().to_string();
        assert!(
            e.contains("too large: must be a whole number from 0 to"),
            "{e}"
        );
        assert!(a.set("nope", 1i64).is_err());
    }

    #[test]
    fn ranged_numbers_name_their_range_for_every_bad_number() {
        let mut o = Options::default();
        for bad in ["inf", "-inf", "NaN", "9"] {
            let e = o.set("exposure", bad).unwrap_err().to_string();
            assert!(e.ends_with("expected a number from -8 to 8"), "{bad}: {e}");
        }
        let e = o.set("exposure", f64::INFINITY).unwrap_err().to_string();
        assert!(e.ends_with("expected a number from -8 to 8"), "{e}");
        let e = o.set("exposure", "abc").unwrap_err().to_string();
        assert!(e.ends_with("abc: expected a number"), "{e}");
        o.set("exposure", "-8").unwrap();
        o.set("saturation", 4.0f64).unwrap();
    }

    #[test]
    fn unused_options_are_named() {
        let o = Options {
            method: MethodKind::Ordered,
            ..Default::default()
        };
        let e = o.check_used(&["kernel"], None).unwrap_err().to_string();
        assert!(e.contains("`kernel`: the ordered method"), "{e}");
        assert!(o.check_used(&["mask"], None).is_ok());
        let e = o
            .check_used(&["maxval"], Some(Format::Pbm))
            .unwrap_err()
            .to_string();
        assert!(e.contains("PBM output does not use it"), "{e}");
    }
}
