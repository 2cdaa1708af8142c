//! CGATS / `.ti3` press characterisation files: the parser, and the press-model fit with
//! what it returns (a model that loads, and colours that are finite).
#![no_main]

use halftone::press::{cgats, fit, Press};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(patches) = cgats::parse(text, Path::new("fuzz.ti3")) else {
        return;
    };
    for p in &patches {
        assert!(p.cmyk.iter().chain(&p.xyz).all(|v| v.is_finite()), "{p:?}");
    }
    if patches.len() > 256 {
        return;
    }
    let Ok(params) = fit(&patches, "fuzz", "fuzz.ti3") else {
        return;
    };
    let Ok(press) = Press::new(params) else {
        return;
    };
    for cmyk in [[0.0; 4], [1.0; 4], [0.5, 0.2, 0.7, 0.1], [0.0, 0.0, 0.0, 1.0]] {
        let lab = press.lab(cmyk);
        assert!(lab.iter().all(|v| v.is_finite()), "{cmyk:?} -> {lab:?}");
    }
});
