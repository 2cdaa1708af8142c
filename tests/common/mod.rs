//! What the photo tests (`tests/photos.rs`, `tests/shrink.rs`) share: the real photographs
//! they run on, a camera-like grain, and the binary's `compare` score.
#![allow(dead_code)] // each test binary uses its own part

use std::path::Path;

use assert_cmd::Command;

/// Grace Hopper (Debian's python-matplotlib-data, installed by .ci/run).
pub const HOPPER: &str = "/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg";
/// scikit-image's sample photos (Debian's python3-skimage).
pub const SKIMAGE: &str = "/usr/lib/python3/dist-packages/skimage/data";

/// The binary under test.
pub fn halftone() -> Command {
    Command::cargo_bin("halftone").unwrap()
}

/// `halftone convert INPUT -o OUT ARGS --max-memory BUDGET`, run to its end.
pub fn convert_with_budget(
    input: &Path,
    out: &Path,
    args: &[&str],
    budget: &str,
) -> std::process::Output {
    convert_cmd(input, out, args, budget).output().unwrap()
}

fn convert_cmd(input: &Path, out: &Path, args: &[&str], budget: &str) -> Command {
    let mut c = halftone();
    c.arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(args)
        .args(["--max-memory", budget]);
    c
}

/// The photos, decoded: Grace Hopper (required under CI) and whichever of `skimage` (file
/// names in [`SKIMAGE`]) are installed. HALFTONE_TEST_PHOTOS, a path list, replaces them.
pub fn photos(skimage: &[&str]) -> Vec<(String, image::RgbImage)> {
    let mut out = Vec::new();
    if let Some(extra) = std::env::var_os("HALFTONE_TEST_PHOTOS") {
        for p in std::env::split_paths(&extra) {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            out.push((name, image::open(&p).unwrap().to_rgb8()));
        }
        return out;
    }
    match image::open(HOPPER) {
        Ok(img) => out.push(("grace_hopper".into(), img.to_rgb8())),
        Err(_) => {
            assert!(
                std::env::var_os("CI").is_none(),
                "{HOPPER} is missing: apt-get install python-matplotlib-data"
            );
            eprintln!("skipped grace_hopper.jpg: apt-get install python-matplotlib-data");
        }
    }
    for name in skimage {
        match image::open(Path::new(SKIMAGE).join(name)) {
            Ok(img) => out.push((name.split('.').next().unwrap().into(), img.to_rgb8())),
            Err(_) => eprintln!("skipped {name}: apt-get install python3-skimage"),
        }
    }
    out
}

/// A fine grain of ±8 codes (a fixed xorshift sequence), as a camera's sensor leaves and an
/// enlarged small photo lacks.
pub fn grain<'a>(v: impl Iterator<Item = &'a mut u8>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for v in v {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        *v = (*v as i32 + (state % 17) as i32 - 8).clamp(0, 255) as u8;
    }
}

/// Runs the binary with `args`, which must succeed; its standard output.
pub fn ok(args: &[&std::ffi::OsStr]) -> String {
    let out = halftone().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "halftone {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// HVS-PSNR of `halftone` against `original`, by `halftone compare`.
pub fn hvs_psnr(original: &Path, halftone: &Path) -> f64 {
    let json = ok(&[
        "compare".as_ref(),
        original.as_os_str(),
        halftone.as_os_str(),
        "--json".as_ref(),
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    v["quality"]["hvs_psnr_db"].as_f64().unwrap()
}

/// Converts `input` with `args` under every `--max-memory` of `budgets`, on one thread and
/// on two, and asserts that every run succeeds with the same output bytes.
pub fn same_bytes_for_every_budget(input: &Path, args: &[&str], budgets: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.out");
    let mut first: Option<Vec<u8>> = None;
    for budget in budgets {
        for threads in [1, 2] {
            let o = convert_cmd(input, &out, args, budget)
                .env("RAYON_NUM_THREADS", threads.to_string())
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{input:?} {args:?} {budget}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let bytes = std::fs::read(&out).unwrap();
            match &first {
                None => first = Some(bytes),
                Some(f) => assert!(
                    *f == bytes,
                    "{input:?} {args:?}: budget {budget}, {threads} threads differ"
                ),
            }
        }
    }
}

/// The full decode `img` resized to `w × h` in linear light, as a 16-bit sRGB PGM of its
/// luminance at `out`.
pub fn reference(img: &halftone::Image, w: usize, h: usize, out: &Path) {
    let tone = halftone::ToneOptions::default();
    let small = halftone::resize::resize(img, w, h, &tone).unwrap();
    let y = small.to_luminance(&tone);
    let halftone::raster::Samples::U16(v) = &y.planes[0] else {
        panic!("16-bit linear luminance expected")
    };
    let mut pgm = format!("P5\n{w} {h}\n65535\n").into_bytes();
    for &c in v {
        let s = halftone::tone::linear_to_srgb(c as f64 / 65535.0);
        pgm.extend_from_slice(&((s * 65535.0).round() as u16).to_be_bytes());
    }
    std::fs::write(out, pgm).unwrap();
}

/// `jpeg` (a JPEG file's bytes, with no EXIF block) with an APP1 `Exif` block after its
/// start-of-image marker that gives EXIF orientation `o`.
pub fn with_orientation(jpeg: &[u8], o: u16) -> Vec<u8> {
    // Big-endian TIFF, one IFD0 entry: tag 0x0112 (orientation), SHORT, count 1.
    let mut tiff = b"MM\0\x2a\0\0\0\x08\0\x01".to_vec();
    tiff.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1]);
    tiff.extend_from_slice(&o.to_be_bytes());
    tiff.extend_from_slice(&[0, 0, 0, 0, 0, 0]);
    let mut seg = b"Exif\0\0".to_vec();
    seg.extend_from_slice(&tiff);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((seg.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&seg);
    out.extend_from_slice(&jpeg[2..]);
    out
}
