//! Preset files (TOML): the parser and a lookup of every preset it defines.
#![no_main]

use halftone::preset::Presets;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(p) = Presets::parse(text, std::path::Path::new("fuzz.toml")) {
        for name in ["thermal-203", "laser-600", "eink-4grey", "x"] {
            let _ = p.get(name);
        }
    }
});
