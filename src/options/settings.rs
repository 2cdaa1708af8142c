//! [`Settings`]: how a front door fills in [`Options`]: what its caller set through the
//! [table](super::table), then a preset for the rest.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use super::preset::Presets;
use super::table::find;
use super::value::Value;
use super::Options;
use crate::error::{Error, Result};

/// Options being filled in by a front door: what the caller set, then a preset for the
/// rest. Every door (the command line, Python, the page, a print queue) builds its
/// [`Options`] through one of these.
///
/// ```
/// let mut s = halftone::options::Settings::new();
/// s.set("preset", "thermal-203").unwrap();
/// s.set("kernel", "floyd-steinberg").unwrap();
/// let o = s.finish().unwrap();
/// assert_eq!(o.kernel, "floyd-steinberg"); // the caller's
/// assert_eq!(o.print.paper_width, Some(384)); // the preset's
/// ```
#[derive(Clone, Debug, Default)]
pub struct Settings {
    options: Options,
    given: BTreeSet<&'static str>,
    preset: Option<String>,
    presets_file: Option<PathBuf>,
    presets: Option<Presets>,
}

impl Settings {
    /// The defaults, nothing given yet.
    pub fn new() -> Settings {
        Settings::default()
    }

    /// Sets one option (or `preset` / `presets`) given by the caller.
    pub fn set<'a>(&mut self, name: &str, value: impl Into<Value<'a>>) -> Result<()> {
        self.set_value(name, &value.into())
    }

    /// [`Settings::set`] with a [`Value`] already made.
    pub fn set_value(&mut self, name: &str, value: &Value) -> Result<()> {
        match name.trim().replace('-', "_").as_str() {
            "preset" => {
                self.preset = Some(value.text().trim().to_string());
                return Ok(());
            }
            "presets" => {
                self.presets_file = Some(PathBuf::from(value.text().as_ref()));
                return Ok(());
            }
            _ => {}
        }
        self.options.set_value(name, value)?;
        if let Some((spec, _)) = find(name) {
            self.given.insert(spec.name);
        }
        Ok(())
    }

    /// Presets to choose from instead of the built-ins and `presets` (a door without files,
    /// or one that loaded them already).
    pub fn with_presets(&mut self, presets: Presets) {
        self.presets = Some(presets);
    }

    /// The names the caller set (one name each, as in [`describe`](super::describe)).
    pub fn given(&self) -> Vec<&'static str> {
        self.given.iter().copied().collect()
    }

    /// The options so far, before any preset.
    pub fn options(&self) -> &Options {
        &self.options
    }

    /// The preset chosen, if any.
    pub fn preset(&self) -> Option<&str> {
        self.preset.as_deref()
    }

    /// The options: the caller's, then the preset's for every option the caller did not set;
    /// checked ([`Options::validate`]) as every door checks them.
    pub fn finish(self) -> Result<Options> {
        let Settings {
            mut options,
            given,
            preset,
            presets_file,
            presets,
        } = self;
        if let Some(name) = preset {
            let presets = match presets {
                Some(p) => p,
                None => Presets::load(presets_file.as_deref())?,
            };
            presets
                .get(&name)?
                .apply(&name, &mut options, &|f| given.contains(f))
                .map_err(|e| Error::Invalid(format!("preset {name}: {e}")))?;
        } else if let Some(file) = presets_file {
            // A file of presets without one chosen: still read, so that a broken file is
            // reported where it is given.
            Presets::load(Some(Path::new(&file)))?;
        }
        options.validate()?;
        Ok(options)
    }
}
