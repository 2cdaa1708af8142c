//! Bad input through the real binary: one line on stderr naming the file, a non-zero exit,
//! no panic, and nothing (not even a temp file) left in the output folder.

use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// CRC-32 (ISO 3309, as PNG chunks use it).
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG chunk with its length and CRC.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let mut crc_in = kind.to_vec();
    crc_in.extend_from_slice(data);
    out.extend_from_slice(&crc32(&crc_in).to_be_bytes());
    out
}

/// A valid 8-bit grey PNG made by the png crate.
fn small_png() -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, 64, 64);
    e.set_color(png::ColorType::Grayscale);
    e.set_depth(png::BitDepth::Eight);
    let mut w = e.write_header().unwrap();
    let data: Vec<u8> = (0..64 * 64).map(|i| (i * 7 % 251) as u8).collect();
    w.write_image_data(&data).unwrap();
    w.finish().unwrap();
    out
}

/// Runs `halftone convert IN -o OUT` and checks the failure contract; returns stderr.
fn fails(input: &Path, output: &Path, must_name: &Path) -> String {
    let out_dir = output.parent().unwrap().to_path_buf();
    let before = listing(&out_dir);
    let res = Command::cargo_bin("halftone")
        .unwrap()
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(output)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr).into_owned();
    assert!(!res.status.success(), "must fail: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "exactly one line: {stderr}");
    assert!(lines[0].starts_with("halftone: "), "{stderr}");
    assert!(
        lines[0].contains(&must_name.display().to_string()),
        "names {}: {stderr}",
        must_name.display()
    );
    assert_eq!(listing(&out_dir), before, "output folder changed");
    stderr
}

/// The names in a folder (empty when it does not exist), sorted.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|r| r.map(|e| e.unwrap().path()).collect())
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn empty_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("empty.png");
    std::fs::write(&input, b"").unwrap();
    let out = tempfile::tempdir().unwrap();
    let e = fails(&input, &out.path().join("o.pbm"), &input);
    assert!(e.contains("empty"), "{e}");
}

#[test]
fn truncated_png() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cut.png");
    let png = small_png();
    std::fs::write(&input, &png[..png.len() / 2]).unwrap();
    let out = tempfile::tempdir().unwrap();
    fails(&input, &out.path().join("o.pbm"), &input);
}

#[test]
fn text_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("notes.png");
    std::fs::write(&input, "Dear reader,\nthis is not a picture.\n").unwrap();
    let out = tempfile::tempdir().unwrap();
    let e = fails(&input, &out.path().join("o.png"), &input);
    assert!(e.contains("not an image format"), "{e}");
}

#[test]
fn header_claiming_ten_gigapixels() {
    let dir = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    // A PNG whose IHDR claims 100000×100000 (CRCs valid), followed by a tiny IDAT.
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(
        b"IDAT",
        &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
    ));
    png.extend(chunk(b"IEND", &[]));
    let input = dir.path().join("huge.png");
    std::fs::write(&input, &png).unwrap();
    let e = fails(&input, &out.path().join("o.pbm"), &input);
    assert!(e.contains("100000x100000") && e.contains("limit"), "{e}");
    // The same claim in a PGM header, through the fast path.
    let input = dir.path().join("huge.pgm");
    std::fs::write(&input, b"P5\n100000 100000\n255\n\0\0\0").unwrap();
    let e = fails(&input, &out.path().join("o.pbm"), &input);
    assert!(e.contains("100000x100000") && e.contains("limit"), "{e}");
}

#[test]
fn missing_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    std::fs::write(&input, small_png()).unwrap();
    let output = dir.path().join("no-such-folder").join("out.pbm");
    let e = fails(&input, &output, &output);
    assert!(e.contains("does not exist"), "{e}");
    assert!(!output.parent().unwrap().exists());
}

#[test]
fn writing_over_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("page.png");
    let png = small_png();
    std::fs::write(&input, &png).unwrap();
    fails(&input, &input, &input);
    assert_eq!(std::fs::read(&input).unwrap(), png, "input untouched");
}

#[test]
fn impossible_format_leaves_no_file() {
    // A 4-level halftone cannot be a PBM: refused before any file is created.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    std::fs::write(&input, small_png()).unwrap();
    let out = tempfile::tempdir().unwrap();
    let output = out.path().join("o.pbm");
    let before = listing(out.path());
    let res = Command::cargo_bin("halftone")
        .unwrap()
        .args(["convert", "--levels", "4"])
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(!res.status.success());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("o.pbm") && stderr.contains("PGM"),
        "{stderr}"
    );
    assert_eq!(listing(out.path()), before);
}

#[test]
fn good_input_writes_exactly_one_file() {
    // The control: the same run with a good input succeeds and leaves only the output.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    std::fs::write(&input, small_png()).unwrap();
    let out = tempfile::tempdir().unwrap();
    let output = out.path().join("o.pbm");
    Command::cargo_bin("halftone")
        .unwrap()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .assert()
        .success();
    assert_eq!(listing(out.path()), vec![output.clone()]);
    assert!(std::fs::read(&output).unwrap().starts_with(b"P4\n64 64\n"));
}
