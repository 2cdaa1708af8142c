//! The names every front door lists: methods, kernels, palettes, masks, spots, formats,
//! intents, devices, presses and presets. The doors read them from here, never type them.

use serde::Serialize;

use super::preset::Presets;
use super::table::{describe, Choices};

/// Every list of names, with the presets' descriptions.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Lists {
    /// Halftoning methods (`method`).
    pub methods: Vec<String>,
    /// Error-diffusion kernels (`kernel`), `tded` included.
    pub kernels: Vec<String>,
    /// Built-in palettes (`palette`).
    pub palettes: Vec<String>,
    /// Built-in masks (`mask`).
    pub masks: Vec<String>,
    /// Spot functions (`spot`).
    pub spots: Vec<String>,
    /// Output formats' names (`format`), extensions included.
    pub formats: Vec<String>,
    /// Rendering intents (`intent`).
    pub intents: Vec<String>,
    /// Built-in e-paper panels (`device`).
    pub devices: Vec<String>,
    /// Built-in presses (`press`).
    pub presses: Vec<String>,
    /// Colour handling (`color`).
    pub colors: Vec<String>,
    /// Content kinds (`content`).
    pub contents: Vec<String>,
    /// Built-in presets: name and description.
    pub presets: Vec<(String, String)>,
}

/// The values of option `name` in the table.
fn values(name: &str) -> Vec<String> {
    describe()
        .iter()
        .find(|s| s.name == name)
        .map(|s| s.values())
        .unwrap_or_default()
}

impl Lists {
    /// The lists, from the option table and the built-in data.
    pub fn get() -> Lists {
        Lists {
            methods: values("method"),
            kernels: values("kernel"),
            palettes: values("palette"),
            masks: values("mask"),
            spots: values("spot"),
            formats: values("format"),
            intents: values("intent"),
            devices: values("device"),
            presses: values("press"),
            colors: values("color"),
            contents: values("content"),
            presets: Presets::builtin()
                .by_name
                .iter()
                .map(|(n, p)| (n.clone(), p.description.clone().unwrap_or_default()))
                .collect(),
        }
    }
}

/// True when the option `name` takes a value from a fixed or built-in list.
pub fn is_listed(name: &str) -> bool {
    describe()
        .iter()
        .any(|s| s.name == name && !matches!(s.choices, Choices::Open))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_hold_what_the_library_accepts() {
        let l = Lists::get();
        for k in ["ostromoukhov", "zhou-fang", "riemersma", "tded"] {
            assert!(l.kernels.iter().any(|n| n == k), "{k}");
        }
        assert_eq!(l.methods.len(), crate::MethodKind::NAMES.len());
        assert!(l.presets.iter().any(|(n, _)| n == "thermal-203"));
        assert!(l.intents.len() == 4 && is_listed("intent") && !is_listed("levels"));
        for name in &l.kernels {
            let mut o = crate::Options::default();
            o.set("kernel", name.as_str()).unwrap();
            assert!(o.method().is_ok(), "{name}");
        }
    }
}
