//! Every input a fuzz target found a defect with (tests/fuzz-regressions/), read again: an
//! error naming the file, never a panic. Kept small; each file is named after its defect.

use std::path::Path;

use halftone::color::Palette;
use halftone::io::{read_image_bytes, ReadOptions};
use halftone::Mask;

/// The files of one target's findings.
fn findings(target: &str) -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz-regressions")
        .join(target);
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    assert!(!v.is_empty(), "no regression inputs in {}", dir.display());
    v
}

#[test]
fn image_findings_are_errors_not_panics() {
    let mut n = 0;
    for path in findings("read") {
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
    assert!(n >= 1);
}

#[test]
fn mask_findings_parse_or_fail_cleanly() {
    // Each finding as found, and spoilt at its end by a line that is no row of numbers (so
    // that every finding reaches the error path too).
    let mut errors = 0;
    for path in findings("mask") {
        let found = std::fs::read_to_string(&path).unwrap();
        let lines = found.lines().count();
        for (text, spoilt) in [(found.clone(), false), (format!("{found}\n1 x 2\n"), true)] {
            for strict in [true, false] {
                let m = if strict {
                    Mask::parse(&text, &path)
                } else {
                    Mask::parse_ranks(&text, &path)
                };
                match m {
                    Ok(m) => {
                        assert!(!spoilt, "{}: the spoilt text parsed", path.display());
                        assert!(m.width > 0 && m.height > 0, "{}", path.display());
                        let t = halftone::method::pattern::pattern_table(&m, 2);
                        assert_eq!(t.len(), m.len() + 1);
                    }
                    Err(e) => {
                        // One line naming the file (and, for the spoilt line, its number).
                        let msg = e.to_string();
                        assert_eq!(msg.lines().count(), 1, "{msg}");
                        assert!(msg.starts_with(&path.display().to_string()), "{msg}");
                        if spoilt {
                            let line = format!(":{}:", lines + 2);
                            assert!(msg.contains(&line), "wanted {line} in {msg}");
                        }
                        errors += 1;
                    }
                }
            }
        }
    }
    assert!(errors >= 2, "{errors} parse errors seen");
}

#[test]
fn a_row_of_separators_is_a_blank_line() {
    let m = Mask::parse("1 2\n,\n4 3\n", Path::new("m.mask")).unwrap();
    assert_eq!((m.width, m.height), (2, 2));
    let e = Mask::parse(", ,\n", Path::new("m.mask"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("holds no numbers"), "{e}");
}

#[test]
fn palette_findings_parse_or_fail_cleanly() {
    for path in findings("palette") {
        let text = std::fs::read_to_string(&path).unwrap();
        if let Err(e) = Palette::parse(&text, "p.txt") {
            assert!(e.to_string().starts_with("p.txt:"), "{e}");
        }
    }
    let e = Palette::parse("#000000\nݜaaaa\n", "p.txt")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("p.txt:2: `ݜaaaa` is not a colour"), "{e}");
}

#[test]
fn png_palette_of_a_partial_entry_is_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz-regressions/read/png-plte-not-multiple-of-3.png");
    let bytes = std::fs::read(&path).unwrap();
    let e = read_image_bytes(&bytes, Path::new("p.png"), &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("p.png: bad PNG file: a palette (PLTE) of 461 bytes"),
        "{e}"
    );
}

#[test]
fn ti3_findings_are_errors_naming_the_file() {
    for path in findings("ti3") {
        let name = path.to_str().unwrap();
        let err = halftone::press::Press::load(name)
            .err()
            .unwrap_or_else(|| panic!("{name}: loaded"));
        let msg = err.to_string();
        assert!(msg.contains(name), "{msg}");
        assert!(!msg.contains('\n') && !msg.contains("NaN"), "{msg}");
    }
}

#[test]
fn ipp_findings_are_bad_requests() {
    use halftone::serve::{Config, Limits, Printer};
    let dir = tempfile::tempdir().unwrap();
    let config = Config::parse(&format!(
        "[queue.q]\npreset = \"thermal-203\"\nbackend = \"file://{}\"\n",
        dir.path().display()
    ))
    .unwrap();
    let printer = Printer::new(config, "127.0.0.1:8631", Limits::default());
    for path in findings("ipp") {
        let resp = printer.handle_bytes(std::fs::read(&path).unwrap(), false);
        let parsed =
            ipp::parser::IppParser::new(ipp::reader::IppReader::new(std::io::Cursor::new(resp)))
                .parse()
                .unwrap_or_else(|e| panic!("{}: the response: {e}", path.display()));
        assert_eq!(
            parsed.header().status_code(),
            ipp::model::StatusCode::ClientErrorBadRequest,
            "{}",
            path.display()
        );
    }
    // The printer answers the next request (a seed of the fuzz target).
    let seed = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus/ipp_request/get-printer-attributes");
    let resp = printer.handle_bytes(std::fs::read(seed).unwrap(), false);
    let parsed =
        ipp::parser::IppParser::new(ipp::reader::IppReader::new(std::io::Cursor::new(resp)))
            .parse()
            .unwrap();
    assert!(parsed.header().status_code().is_success());
}
