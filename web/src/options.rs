//! Options from JavaScript: a JSON object whose keys are the command line's flag names
//! (`dot-gain` or `dot_gain`, `no-linearize`), filled in over the command line's defaults,
//! then a preset's values for every key not given, as `halftone convert --preset` does.

use std::collections::BTreeSet;

use halftone::io::print::{PageSize, ZplEncoding};
use halftone::method::device::Amount;
use halftone::method::pattern::Cell;
use halftone::preset::Presets;
use halftone::press::RenderingIntent;
use halftone::resize::Rotate;
use halftone::{Compression, Format, Options};
use serde_json::Value;

/// Parses `json` into the library's options; an error names the key and the cause.
pub fn parse_options(json: &str) -> Result<Options, String> {
    let value: Value = serde_json::from_str(json).map_err(|e| format!("options: {e}"))?;
    let Value::Object(map) = value else {
        return Err("options: expected an object of option names and values".into());
    };
    let mut o = Options::default();
    let mut given = BTreeSet::new();
    let mut preset = None;
    for (key, v) in &map {
        if v.is_null() || v.as_str() == Some("") {
            continue;
        }
        let key = key.replace('-', "_");
        set(&mut o, &key, v).map_err(|e| format!("{}: {e}", key.replace('_', "-")))?;
        if key == "preset" {
            preset = Some(text(v));
        }
        // The command line's field of a negated flag is the positive one.
        given.insert(key.strip_prefix("no_").unwrap_or(&key).to_string());
    }
    if let Some(name) = preset {
        let presets = Presets::builtin();
        let explicit = |field: &str| given.contains(field);
        presets
            .get(&name)
            .and_then(|p| p.apply(&name, &mut o, &explicit))
            .map_err(|e| format!("preset {name}: {e}"))?;
    }
    o.validate().map_err(|e| e.to_string())?;
    Ok(o)
}

/// A value as text (numbers as written).
fn text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

fn num<T: std::str::FromStr>(v: &Value) -> Result<T, String> {
    let t = text(v);
    t.trim()
        .parse()
        .map_err(|_| format!("'{t}' is not a valid number"))
}

fn flag(v: &Value) -> Result<bool, String> {
    match v {
        Value::Bool(b) => Ok(*b),
        Value::String(s) if s == "true" => Ok(true),
        Value::String(s) if s == "false" => Ok(false),
        other => Err(format!("'{other}': expected true or false")),
    }
}

fn named<T: serde::de::DeserializeOwned>(v: &Value, what: &str) -> Result<T, String> {
    let t = text(v).to_ascii_lowercase();
    serde_json::from_value(Value::String(t.clone())).map_err(|_| format!("'{t}' is not a {what}"))
}

fn set(o: &mut Options, key: &str, v: &Value) -> Result<(), String> {
    let e = |err: halftone::Error| err.to_string();
    match key {
        "method" => o.method = text(v).parse().map_err(e)?,
        "threshold" => o.threshold = text(v).parse()?,
        "mask" => o.mask = Some(text(v)),
        "kernel" => o.kernel = text(v),
        "serpentine" => o.serpentine = flag(v)?,
        "no_serpentine" => o.serpentine = !flag(v)?,
        "strength" => o.strength = num(v)?,
        "palette" => o.palette = Some(text(v)),
        "device" => o.device = Some(text(v)),
        "ink_colours" => o.ink_colours = text(v).to_ascii_lowercase().parse().map_err(e)?,
        "seed" => o.seed = num(v)?,
        "levels" => o.levels = num(v)?,
        "color" => o.color = text(v).parse().map_err(e)?,
        "cell" => {
            o.cell = match text(v).as_str() {
                "fit" => Cell::Fit,
                "expand" => Cell::Expand,
                t => return Err(format!("'{t}': expected fit or expand")),
            }
        }
        "linearize" => o.linearize = flag(v)?,
        "no_linearize" => o.linearize = !flag(v)?,
        "invert" => o.invert = flag(v)?,
        "gamma" => o.gamma = num(v)?,
        "dot_gain" => o.dot_gain = num(v)?,
        "format" => {
            let t = text(v);
            o.format = Some(Format::from_name(&t).ok_or_else(|| {
                format!(
                    "'{t}' is not a format halftone writes; formats: {}",
                    Format::WRITABLE.join(", ")
                )
            })?)
        }
        "dpi" => o.dpi = Some(num(v)?),
        "maxval" => o.maxval = Some(num(v)?),
        "compression" => o.compression = Some(named::<Compression>(v, "compression")?),
        "device_levels" => o.device_levels = flag(v)?,
        "page" => o.print.page = Some(text(v).parse::<PageSize>()?),
        "band_rows" => o.print.band_rows = num(v)?,
        "cut" => o.print.cut = flag(v)?,
        "paper_width" => o.print.paper_width = Some(num(v)?),
        "zpl_encoding" => {
            o.print.zpl_encoding = match text(v).to_ascii_lowercase().as_str() {
                "hex" => ZplEncoding::Hex,
                "z64" => ZplEncoding::Z64,
                t => return Err(format!("'{t}': expected hex or z64")),
            }
        }
        "max_length" => o.print.max_length = num(v)?,
        "content" => o.content = text(v).parse().map_err(e)?,
        "max_pixels" => o.max_pixels = num(v)?,
        "width" => o.width = Some(num(v)?),
        "height" => o.height = Some(num(v)?),
        "fit" => o.fit = Some(halftone::resize::parse_box(&text(v)).map_err(e)?),
        "fit_mode" => o.fit_mode = Some(text(v).parse().map_err(e)?),
        "size" => o.size = Some(text(v)),
        "rotate" => {
            o.rotate = match text(v).trim().to_ascii_lowercase().as_str() {
                "auto" => Rotate::Auto,
                "0" | "none" => Rotate::None,
                "90" => Rotate::Clockwise(1),
                "180" => Rotate::Clockwise(2),
                "270" | "-90" => Rotate::Clockwise(3),
                t => return Err(format!("'{t}': expected auto, 90, 180 or 270")),
            }
        }
        "passes" => o.passes = num(v)?,
        "distance" => o.distance = num(v)?,
        "tone_correction" => o.tone_correction = flag(v)?,
        "no_tone_correction" => o.tone_correction = !flag(v)?,
        "hysteresis" => o.hysteresis = num(v)?,
        "printer_model" => o.printer_model = text(v).parse().map_err(e)?,
        "dot_ratio" => o.dot_ratio = num(v)?,
        "lpi" => o.lpi = text(v),
        "angle" => o.angle = num(v)?,
        "spot" => o.spot = text(v),
        "angles" => o.angles = Some(text(v)),
        "press" => o.press = text(v),
        "gcr" => o.gcr = num(v)?,
        "tac" => o.tac = num(v)?,
        "separation" => o.separation = text(v).parse().map_err(e)?,
        "intent" => {
            o.intent = Some(named::<RenderingIntent>(
                v,
                "rendering intent (perceptual, relative, saturation or absolute)",
            )?)
        }
        "exposure" => o.exposure = num(v)?,
        "saturation" => o.saturation = num(v)?,
        "tone" => o.tone = text(v).parse::<Amount>()?,
        "gamut" => o.gamut = text(v).parse::<Amount>()?,
        "preview" => o.preview = flag(v)?,
        "preview_block" => o.preview_block = Some(num(v)?),
        "preset" => {}
        _ => {
            return Err(
                "not an option of halftone convert in the browser (files such as --transfer, \
                 --icc and --printer-table cannot be read here)"
                    .into(),
            )
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_defaults() {
        let o =
            parse_options(r#"{"method":"screen","lpi":"85","dot-gain":"12","no-linearize":true}"#)
                .unwrap();
        assert_eq!(o.method, halftone::MethodKind::Screen);
        assert_eq!(o.lpi, "85");
        assert_eq!(o.dot_gain, 12.0);
        assert!(!o.linearize);
        assert_eq!(o.kernel, "floyd-steinberg");
        let e = parse_options(r#"{"levles":4}"#).unwrap_err();
        assert!(e.starts_with("levles: not an option"), "{e}");
        let e = parse_options(r#"{"method":"difuse"}"#).unwrap_err();
        assert!(e.contains("diffuse"), "{e}");
    }

    #[test]
    fn preset_fills_what_was_not_given() {
        let o = parse_options(r#"{"preset":"thermal-203","levels":2,"kernel":"stucki"}"#).unwrap();
        assert_eq!(o.kernel, "stucki");
        assert_eq!(o.format, Some(Format::EscPos));
    }

    #[test]
    fn device_and_its_rendering() {
        let o = parse_options(
            r#"{"device":"hanshow-bwr","ink-colours":"nominal","intent":"relative",
                "exposure":"-0.5","saturation":"1.2","tone":"off","gamut":"0.25"}"#,
        )
        .unwrap();
        assert_eq!(o.device.as_deref(), Some("hanshow-bwr"));
        assert_eq!(o.ink_colours, halftone::options::InkColours::Nominal);
        assert_eq!(o.intent, Some(RenderingIntent::Relative));
        assert_eq!((o.exposure, o.saturation), (-0.5, 1.2));
        assert_eq!((o.tone, o.gamut), (Amount::Fixed(0.0), Amount::Fixed(0.25)));
        let e = parse_options(r#"{"device":"no-such-panel"}"#).unwrap_err();
        assert!(e.contains("no-such-panel"), "{e}");
        let e = parse_options(r#"{"intent":"vivid"}"#).unwrap_err();
        assert!(
            e.starts_with("intent: 'vivid' is not a rendering intent"),
            "{e}"
        );
        let e = parse_options(r#"{"tone":"2"}"#).unwrap_err();
        assert!(e.starts_with("tone: '2': expected auto, off"), "{e}");
        let o = parse_options(r#"{"device":"hanshow-bwr","fit-mode":"cover"}"#).unwrap();
        assert_eq!(o.fit_mode, Some(halftone::FitMode::Cover));
        let e = parse_options(r#"{"fit-mode":"fill"}"#).unwrap_err();
        assert!(e.starts_with("fit-mode: fill: no built-in fit mode"), "{e}");
    }
}
