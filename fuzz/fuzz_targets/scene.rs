//! Scene files (TOML): the parser, then a render at 6×4 pixels without antialiasing (a
//! scene's own size is not used: a fuzzed scene may ask for anything).
#![no_main]

use halftone::render::{self, Antialias, RenderOptions, Scene};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scene) = Scene::from_toml(text, std::path::Path::new("fuzz.toml")) {
        let frame = render::render(
            &scene,
            &RenderOptions {
                size: Some((6, 4)),
                aa: Some(Antialias::None),
            },
        );
        assert_eq!(frame.pixels.len(), 6 * 4 * 3);
    }
});
