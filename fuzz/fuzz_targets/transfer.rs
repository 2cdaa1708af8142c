//! `--transfer` step-wedge files: the parser and the compensation curves it builds, which
//! must map [0, 1] into [0, 1], never fall, and invert the measured response.
#![no_main]

use halftone::press::transfer::Transfer;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(t) = Transfer::parse(text, Path::new("fuzz.csv")) else {
        return;
    };
    assert!(t.columns() >= 1);
    for c in 0..t.columns() {
        let mut last = 0.0f64;
        for i in 0..=64 {
            let a = i as f64 / 64.0;
            let plate = t.compensate(c, a);
            assert!((0.0..=1.0).contains(&plate), "column {c}: {a} -> {plate}");
            assert!(plate >= last - 1e-9, "column {c} falls at {a}: {last} -> {plate}");
            last = plate;
            let r = t.response(c, a);
            assert!((0.0..=1.0 + 1e-9).contains(&r), "column {c}: response {r} at {a}");
        }
    }
});
