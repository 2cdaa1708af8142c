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
use crate::io::Format;
use crate::options::{Options, Value};

/// The built-in presets' file.
pub const BUILTIN: &str = include_str!("../../presets/builtin.toml");

/// One preset: a description, a transfer curve, and partial options by their one name
/// (the flag's, with underscores), read and applied through the option table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Preset {
    /// What the preset is for.
    pub description: Option<String>,
    /// The printer's compensation curve (see [`PresetTransfer`]), as `--transfer` gives one.
    pub transfer: Option<PresetTransfer>,
    /// The options it sets, by name, as written in the file.
    pub options: BTreeMap<String, toml::Value>,
}

impl Preset {
    /// The value it gives option `name`, if any.
    pub fn get(&self, name: &str) -> Option<&toml::Value> {
        self.options.get(name)
    }

    /// The output format it names, if any.
    pub fn format(&self) -> Option<Format> {
        self.get("format")
            .and_then(|v| v.as_str())
            .and_then(Format::from_name)
    }

    /// Reads one preset's table; `line` gives the line of a key in errors.
    fn from_table(
        table: BTreeMap<String, toml::Spanned<toml::Value>>,
        source: &Path,
        line: &dyn Fn(usize) -> usize,
    ) -> Result<Preset> {
        let mut p = Preset::default();
        for (key, value) in table {
            let at = line(value.span().start);
            let value = value.into_inner();
            match key.as_str() {
                "description" => {
                    p.description = Some(
                        value
                            .as_str()
                            .ok_or_else(|| Error::parse(source, at, "description: expected text"))?
                            .to_string(),
                    )
                }
                "transfer" => {
                    p.transfer = Some(value.try_into().map_err(|e: toml::de::Error| {
                        Error::parse(source, at, format!("transfer: {}", e.message().trim()))
                    })?)
                }
                _ => {
                    let Some((spec, _)) = crate::options::table::find(&key) else {
                        let mut names = crate::options::table::accepted_names();
                        names.extend(["description", "transfer"]);
                        let hint = crate::names::closest(&key, &names)
                            .map(|c| format!("; did you mean `{c}`?"))
                            .unwrap_or_default();
                        return Err(Error::parse(
                            source,
                            at,
                            format!("unknown field `{key}` (not an option){hint}"),
                        ));
                    };
                    let mut scratch = Options::default();
                    scratch
                        .set_value(spec.name, &Value::from_toml(&value))
                        .map_err(|e| Error::parse(source, at, e.to_string()))?;
                    p.options.insert(spec.name.to_string(), value);
                }
            }
        }
        Ok(p)
    }
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
    ("laser-600.csv", include_str!("../../presets/laser-600.csv")),
    (
        "thermal-203.csv",
        include_str!("../../presets/thermal-203.csv"),
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
    /// Fills in `o` from the preset (named `name` in errors), leaving alone every option for
    /// which `explicit(name)` is true: what the caller set itself wins. The size options
    /// (`width`, `height`, `fit`, `size`) go together: any one set by the caller keeps the
    /// preset's sizing out. A preset's format is taken only when `o.format` is `None`.
    pub fn apply(
        &self,
        name: &str,
        o: &mut Options,
        explicit: &dyn Fn(&str) -> bool,
    ) -> Result<()> {
        const SIZES: [&str; 4] = ["width", "size", "height", "fit"];
        let sized = SIZES.iter().any(|f| explicit(f));
        for (key, value) in &self.options {
            let skip = if key == "format" {
                o.format.is_some()
            } else if SIZES.contains(&key.as_str()) {
                sized
            } else {
                explicit(key)
            };
            if !skip {
                o.set_value(key, &Value::from_toml(value))?;
            }
        }
        if let (Some(t), false) = (&self.transfer, explicit("transfer")) {
            o.preset_transfer = Some(t.curve(name)?);
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
        let line = |at: usize| text[..at.min(text.len())].matches('\n').count() + 1;
        type Tables = BTreeMap<String, BTreeMap<String, toml::Spanned<toml::Value>>>;
        let tables: Tables = toml::from_str(text).map_err(|e| {
            let at = e.span().map(|s| line(s.start)).unwrap_or(0);
            let msg = e.message().trim().replace('\n', " ");
            Error::parse(source, at, msg)
        })?;
        let by_name = tables
            .into_iter()
            .map(|(name, table)| Ok((name, Preset::from_table(table, source, &line)?)))
            .collect::<Result<_>>()?;
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
        let int = |p: &Preset, k: &str| p.get(k).and_then(|v| v.as_integer());
        assert_eq!(int(t, "width"), Some(384));
        assert_eq!(int(t, "dpi"), Some(203));
        assert!(p.get("laser-600").is_ok() && p.get("eink-4grey").is_ok());
        // Printer presets state their head width (or label size), dpi and format.
        assert_eq!(int(t, "paper_width"), Some(384));
        let t80 = p.get("thermal-80mm").unwrap();
        assert_eq!(
            (int(t80, "width"), int(t80, "paper_width"), int(t80, "dpi")),
            (Some(576), Some(576), Some(203))
        );
        let l = p.get("label-300").unwrap();
        assert_eq!(
            (int(l, "width"), int(l, "max_length"), int(l, "dpi")),
            (Some(1200), Some(1800), Some(300))
        );
        assert_eq!(p.get("label-203").unwrap().format(), Some(Format::Zpl));
        assert_eq!(p.get("laser-600").unwrap().format(), Some(Format::Pcl));
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
