//! Kernel files: the parser, the text round trip, and error diffusion with the kernel on a
//! small ramp (every tap, both scan directions, levels 2 and 3).
#![no_main]

use halftone::method::diffusion::{Algorithm, Diffuse, DiffuseOptions, Kernel};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(k) = Kernel::parse(text, "fuzz.kernel") else {
        return;
    };
    assert!(k.weight_sum() > 0 && k.weight_sum() <= k.divisor);
    let back = Kernel::parse(&k.to_text(), "fuzz.kernel").unwrap();
    assert_eq!((back.taps.len(), back.divisor), (k.taps.len(), k.divisor));
    let img = halftone::Image::gray8(19, 7, (0..133).map(|i| (i * 2) as u8).collect());
    for (levels, serpentine) in [(2, true), (3, false)] {
        let options = DiffuseOptions {
            levels,
            serpentine,
            strength: 1.0,
            seed: 0,
        };
        let d = Diffuse::with_algorithm(Algorithm::Kernel(k.clone()), options).unwrap();
        let h = halftone::halftone_image(
            &img,
            &d,
            halftone::ColorMode::Gray,
            &halftone::ToneOptions::default(),
        )
        .unwrap();
        assert_eq!((h.width, h.height), (19, 7));
    }
});
