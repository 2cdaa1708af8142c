//! Options from JavaScript: a JSON object whose keys are the command line's flag names
//! (`dot-gain` or `dot_gain`, `no-linearize`), set through the library's one option table
//! ([`Settings`]) over its defaults, then a preset's values for every key not given, as
//! `halftone convert --preset` does. Options that read a file are refused: the page has none.

use halftone::options::table;
use halftone::options::{Settings, Value};
use halftone::preset::Presets;
use halftone::Options;

/// The options that name a file to read, which a page cannot.
const FILES: [&str; 4] = ["transfer", "icc", "printer_table", "presets"];

/// Parses `json` into the library's options; an error names the key and the cause.
pub fn parse_options(json: &str) -> Result<Options, String> {
    let value: serde_json::Value =
        serde_json::from_str(json).map_err(|e| format!("options: {e}"))?;
    let serde_json::Value::Object(map) = value else {
        return Err("options: expected an object of option names and values".into());
    };
    let mut settings = Settings::new();
    settings.with_presets(Presets::builtin());
    for (key, v) in &map {
        if v.is_null() || v.as_str() == Some("") {
            continue;
        }
        let name = key.trim().replace('-', "_");
        let shown = name.replace('_', "-");
        let known = name == "preset"
            || table::find(&name).is_some_and(|(spec, _)| !FILES.contains(&spec.name));
        if !known {
            return Err(format!(
                "{shown}: not an option of halftone convert in the browser (files such as \
                 --transfer, --icc and --printer-table cannot be read here)"
            ));
        }
        let value = match v {
            serde_json::Value::Bool(b) => Value::Bool(*b),
            serde_json::Value::Number(n) => match n.as_i64() {
                Some(i) => Value::Int(i),
                None => Value::Float(n.as_f64().unwrap_or(f64::NAN)),
            },
            serde_json::Value::String(t) => Value::from(t.clone()),
            other => Value::from(other.to_string()),
        };
        settings.set_value(&name, &value).map_err(|e| match e {
            halftone::Error::Option { value, msg, .. } => format!("{shown}: '{value}': {msg}"),
            other => format!("{shown}: {other}"),
        })?;
    }
    let given = settings.given();
    let o = settings.finish().map_err(|e| e.to_string())?;
    // The format is chosen at download; the method is known now.
    o.check_used(&given, None).map_err(|e| e.to_string())?;
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::*;
    use halftone::press::RenderingIntent;
    use halftone::rendering::Amount;
    use halftone::Format;

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
        assert_eq!(
            e,
            "intent: 'vivid': expected perceptual, relative, saturation or absolute"
        );
        let e = parse_options(r#"{"tone":"2"}"#).unwrap_err();
        assert_eq!(e, "tone: '2': expected auto, off or a strength from 0 to 1");
        let o = parse_options(r#"{"device":"hanshow-bwr","fit-mode":"cover"}"#).unwrap();
        assert_eq!(o.fit_mode, Some(halftone::FitMode::Cover));
        let e = parse_options(r#"{"fit-mode":"fill"}"#).unwrap_err();
        assert_eq!(e, "fit-mode: 'fill': expected inside, pad or cover");
    }
}
