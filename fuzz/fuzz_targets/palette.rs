//! Palette files (hex colours or GIMP .gpl): the parser, then diffusion to the palette.
#![no_main]

use halftone::color::Palette;
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(p) = Palette::parse(text, "fuzz.gpl") else {
        return;
    };
    assert!(p.len() >= 2);
    let options = DiffuseOptions {
        levels: 2,
        serpentine: true,
        strength: 1.0,
        seed: 0,
    };
    let d = Diffuse::new("floyd-steinberg", options)
        .unwrap()
        .with_palette(p);
    let img = halftone::Image::gray8(9, 4, (0..36).map(|i| (i * 7) as u8).collect());
    let _ = halftone::halftone_image(
        &img,
        &d,
        halftone::ColorMode::Rgb,
        &halftone::ToneOptions::default(),
    );
});
