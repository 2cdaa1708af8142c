//! Printer presets: named sets of options in TOML (`--preset NAME`, `--presets FILE`).
//!
//! ```toml
//! [thermal-203]
//! description = "58 mm thermal receipt printer"
//! width = 384          # pixels; or size = "48mm" with dpi
//! dpi = 203
//! method = "diffuse"
//! kernel = "atkinson"
//! format = "pbm"
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::io::{Compression, Format};
use crate::options::{Color, ContentKind, MethodKind, Options};

/// The built-in presets' file.
pub const BUILTIN: &str = include_str!("../presets/builtin.toml");

/// One preset; every field optional. Names of methods, kernels, masks, palettes and
/// formats are the command line's own words.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// What the preset is for.
    pub description: Option<String>,
    /// Output width in pixels (the image is resized in linear light).
    pub width: Option<usize>,
    /// Output width as a physical length (`4in`, `48mm`), with `dpi`.
    pub size: Option<String>,
    /// Resize into this box, aspect kept (`800x480`); `--fit`.
    pub fit: Option<String>,
    /// Device resolution, dots per inch.
    pub dpi: Option<f64>,
    /// Halftoning method.
    pub method: Option<MethodKind>,
    /// Mask for pattern/ordered.
    pub mask: Option<String>,
    /// Error-diffusion kernel.
    pub kernel: Option<String>,
    /// Output levels a pixel.
    pub levels: Option<u16>,
    /// `gray`, `rgb` or `cmyk`.
    pub color: Option<Color>,
    /// Palette name or file.
    pub palette: Option<String>,
    /// Output format (`pbm`, `png`, `tiff`, ...).
    pub format: Option<Format>,
    /// TIFF compression.
    pub compression: Option<Compression>,
    /// Dot gain to pre-compensate, percent at 50%.
    pub dot_gain: Option<f32>,
    /// Extra gamma on linear reflectance.
    pub gamma: Option<f32>,
    /// ESC/POS print head width in dots.
    pub paper_width: Option<usize>,
    /// ZPL: the printer's longest label in dots.
    pub max_length: Option<usize>,
    /// `photo`, `line-art` or `auto`.
    pub content: Option<ContentKind>,
    /// The printer's compensation curve (see [`PresetTransfer`]), as `--transfer` gives one.
    pub transfer: Option<PresetTransfer>,
    /// Screen frequency, lines per inch (`--method screen`).
    pub lpi: Option<f64>,
    /// Screen angle, degrees (`--method screen`).
    pub angle: Option<f64>,
    /// Spot function (`--method screen`).
    pub spot: Option<String>,
}

/// A preset's transfer curve: what its printer prints for each nominal coverage (a measured
/// step wedge, or a model of one), inverted before halftoning exactly as `--transfer` is.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum PresetTransfer {
    /// `"press:NAME"`: the black ink's ramp of a built-in press model (`presses/NAME.toml`,
    /// the measured nominal → effective coverage of its characterisation data); otherwise a
    /// wedge file: one of `presets/*.csv` by name, or a path.
    File(String),
    /// Inline `[nominal %, measured %]` points.
    Points(Vec<[f64; 2]>),
}

/// Wedge files that ship with the built-in presets (`presets/*.csv`).
const BUILTIN_WEDGES: [(&str, &str); 2] = [
    ("laser-600.csv", include_str!("../presets/laser-600.csv")),
    (
        "thermal-203.csv",
        include_str!("../presets/thermal-203.csv"),
    ),
];

impl PresetTransfer {
    /// The compensation curve; `preset` names the preset in errors.
    pub fn curve(&self, preset: &str) -> Result<crate::press::transfer::Transfer> {
        use crate::press::transfer::Transfer;
        let source = format!("preset {preset}: transfer");
        match self {
            PresetTransfer::Points(points) => {
                let text: String = points
                    .iter()
                    .map(|p| format!("{}, {}\n", p[0], p[1]))
                    .collect();
                Transfer::parse(&text, Path::new(&source))
            }
            PresetTransfer::File(name) => {
                if let Some(press) = name.strip_prefix("press:") {
                    let press = crate::press::Press::load(press)?;
                    let k = &press.params().curves[3];
                    let text: String = k
                        .iter()
                        .map(|p| {
                            format!("{}, {}\n", p[0] * 100.0, (p[1] * 100.0).clamp(0.0, 100.0))
                        })
                        .collect();
                    return Transfer::parse(&text, Path::new(&source));
                }
                if let Some((file, text)) = BUILTIN_WEDGES.iter().find(|(n, _)| n == name) {
                    return Transfer::parse(text, Path::new(&format!("presets/{file}")));
                }
                Transfer::load(Path::new(name))
            }
        }
    }
}

impl Preset {
    /// Fills in `o` from the preset (named `name` in errors), leaving alone every field for
    /// which `explicit(field)` is true: what the caller set itself wins. The size fields
    /// (`width`, `height`, `fit`, `size`) go together: any one set by the caller keeps the
    /// preset's sizing out. A preset's format is taken only when `o.format` is `None`.
    pub fn apply(
        &self,
        name: &str,
        o: &mut Options,
        explicit: &dyn Fn(&str) -> bool,
    ) -> Result<()> {
        macro_rules! take {
            ($field:ident) => {
                if let Some(v) = &self.$field {
                    if !explicit(stringify!($field)) {
                        o.$field = v.clone();
                    }
                }
            };
            ($field:ident, some) => {
                if let Some(v) = &self.$field {
                    if !explicit(stringify!($field)) {
                        o.$field = Some(v.clone());
                    }
                }
            };
        }
        take!(method);
        take!(color);
        take!(mask, some);
        take!(kernel);
        take!(palette, some);
        take!(levels);
        take!(dot_gain);
        take!(gamma);
        take!(dpi, some);
        take!(compression, some);
        take!(content);
        take!(angle);
        take!(spot);
        if let (Some(l), false) = (self.lpi, explicit("lpi")) {
            o.lpi = l.to_string();
        }
        if let (Some(w), false) = (self.paper_width, explicit("paper_width")) {
            o.print.paper_width = Some(w);
        }
        if let (Some(m), false) = (self.max_length, explicit("max_length")) {
            o.print.max_length = m;
        }
        if let (Some(t), false) = (&self.transfer, explicit("transfer")) {
            o.preset_transfer = Some(t.curve(name)?);
        }
        if o.format.is_none() {
            o.format = self.format;
        }
        if !["width", "size", "height", "fit"]
            .iter()
            .any(|f| explicit(f))
        {
            o.width = self.width;
            o.size = self.size.clone();
            o.fit = self
                .fit
                .as_deref()
                .map(crate::resize::parse_box)
                .transpose()?;
        }
        Ok(())
    }
}

/// A set of named presets.
#[derive(Clone, Debug, Default)]
pub struct Presets {
    /// Presets by name.
    pub by_name: BTreeMap<String, Preset>,
}

impl Presets {
    /// Parses a presets file; `source` names it in errors (with the line of the problem).
    pub fn parse(text: &str, source: &Path) -> Result<Presets> {
        let by_name: BTreeMap<String, Preset> = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1)
                .unwrap_or(0);
            let msg = e.message().trim().replace('\n', " ");
            Error::parse(source, line, msg)
        })?;
        Ok(Presets { by_name })
    }

    /// The built-in presets.
    pub fn builtin() -> Presets {
        Presets::parse(BUILTIN, Path::new("presets/builtin.toml")).expect("built-in presets parse")
    }

    /// Built-ins plus (overridden by) the presets of `file`, if given.
    pub fn load(file: Option<&Path>) -> Result<Presets> {
        let mut p = Presets::builtin();
        if let Some(path) = file {
            let text = crate::io::read_text(path, 1 << 20)?;
            p.by_name.extend(Presets::parse(&text, path)?.by_name);
        }
        Ok(p)
    }

    /// A preset by name, or an error listing the known names.
    pub fn get(&self, name: &str) -> Result<&Preset> {
        self.by_name.get(name).ok_or_else(|| {
            let names: Vec<&str> = self.by_name.keys().map(String::as_str).collect();
            let hint = crate::names::closest(name, &names)
                .map(|c| format!("; did you mean '{c}'?"))
                .unwrap_or_default();
            Error::Invalid(format!(
                "no preset named '{name}'{hint} (known: {})",
                names.join(", ")
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins() {
        let p = Presets::builtin();
        let t = p.get("thermal-203").unwrap();
        assert_eq!(t.width, Some(384));
        assert_eq!(t.dpi, Some(203.0));
        assert!(p.get("laser-600").is_ok() && p.get("eink-4grey").is_ok());
        // Printer presets state their head width (or label size), dpi and format.
        assert_eq!(t.paper_width, Some(384));
        let t80 = p.get("thermal-80mm").unwrap();
        assert_eq!(
            (t80.width, t80.paper_width, t80.dpi),
            (Some(576), Some(576), Some(203.0))
        );
        let l = p.get("label-300").unwrap();
        assert_eq!(
            (l.width, l.max_length, l.dpi),
            (Some(1200), Some(1800), Some(300.0))
        );
        assert_eq!(p.get("label-203").unwrap().format, Some(Format::Zpl));
        assert_eq!(p.get("laser-600").unwrap().format, Some(Format::Pcl));
        assert!(p
            .get("nope")
            .unwrap_err()
            .to_string()
            .contains("thermal-203"));
    }

    #[test]
    fn errors_name_the_line() {
        let text = "[a]\nwidth = 10\n\n[b]\ncolr = \"red\"\n";
        let e = Presets::parse(text, Path::new("my.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("my.toml:5: unknown field `colr`"), "{e}");
        let e = Presets::parse("[a]\nwidth = \"x\"\n", Path::new("p.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.toml:2:"), "{e}");
    }
}
