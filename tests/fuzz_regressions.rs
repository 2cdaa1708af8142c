//! Every input a fuzz target found a defect with (tests/fuzz-regressions/), read again: an
//! error naming the file, never a panic. Kept small; each file is named after its defect.

use std::path::Path;

use halftone::io::{read_image_bytes, ReadOptions};

#[test]
fn fuzz_findings_are_errors_not_panics() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        let opts = ReadOptions {
            max_pixels: 1 << 22,
        };
        let err = read_image_bytes(&bytes, &path, &opts)
            .err()
            .unwrap_or_else(|| panic!("{}: decoded", path.display()));
        let msg = err.to_string();
        assert!(msg.starts_with(&path.display().to_string()), "{msg}");
        assert!(!msg.contains('\n'), "{msg}");
        n += 1;
    }
    assert!(n >= 1, "no regression inputs found in {}", dir.display());
}

#[test]
fn png_palette_of_a_partial_entry_is_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz-regressions/png-plte-not-multiple-of-3.png");
    let bytes = std::fs::read(&path).unwrap();
    let e = read_image_bytes(&bytes, Path::new("p.png"), &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("p.png: bad PNG file: a palette (PLTE) of 461 bytes"),
        "{e}"
    );
}
