//! Shrink-on-load for PNM, PNG and TIFF (boxes averaged in linear light while decoding):
//! within 0.3 dB HVS-PSNR of the full-decode path on photos, the same output size, the same
//! bytes for every budget and thread count, and flat grey kept exactly.
//!
//! The full-decode path is the same pixels as plain PNM (P2/P3), which is decoded whole and
//! never shrunk; the reference both halftones are measured against (`halftone compare`) is
//! that full decode resized in linear light by the library, as in tests/it/photos.rs.

use std::io::Write;
use std::path::{Path, PathBuf};

use halftone::io::ReadOptions;
use halftone::pipeline::shrink::{shrink_factor, SHRINK_MIN_PIXELS};

use crate::common::{
    convert_with_budget, grain, hvs_psnr, ok, photos, reference, same_bytes_for_every_budget,
};

/// `img` enlarged (Lanczos) by the smallest whole factor of at least 4 that makes it
/// camera-sized (at least [`SHRINK_MIN_PIXELS`]), with a fine grain of ±8 codes.
fn camera_sized(img: &image::RgbImage) -> image::RgbImage {
    let px = img.width() as usize * img.height() as usize;
    let k = (4..).find(|k| px * k * k >= SHRINK_MIN_PIXELS).unwrap() as u32;
    let (w, h) = (img.width() * k, img.height() * k);
    let mut big = image::imageops::resize(img, w, h, image::imageops::FilterType::Lanczos3);
    grain(big.iter_mut());
    big
}

/// Plain (text) PNM of interleaved `samples`: P2 for one channel, P3 for three. The
/// pipeline decodes it whole, never shrunk: the full-decode twin of a binary file.
fn write_plain(path: &Path, w: u32, h: u32, channels: usize, maxval: u32, samples: &[u32]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let magic = if channels == 1 { "P2" } else { "P3" };
    writeln!(f, "{magic}\n{w} {h}\n{maxval}").unwrap();
    for row in samples.chunks(w as usize * channels) {
        let line: Vec<String> = row.iter().map(u32::to_string).collect();
        writeln!(f, "{}", line.join(" ")).unwrap();
    }
}

/// Binary PNM: P5 or P6, 8 or 16 bits.
fn write_binary(path: &Path, w: u32, h: u32, channels: usize, maxval: u32, samples: &[u32]) {
    let magic = if channels == 1 { "P5" } else { "P6" };
    let mut bytes = format!("{magic}\n{w} {h}\n{maxval}\n").into_bytes();
    for &s in samples {
        if maxval > 255 {
            bytes.extend_from_slice(&(s as u16).to_be_bytes());
        } else {
            bytes.push(s as u8);
        }
    }
    std::fs::write(path, bytes).unwrap();
}

fn convert(input: &Path, out: &Path, extra: &[&str]) {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "convert".as_ref(),
        input.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
    ];
    args.extend(extra.iter().map(|a| std::ffi::OsStr::new(*a)));
    ok(&args);
}

/// One photo's pixels in the shapes the test writes: (kind, channels, maxval, samples).
fn kinds(img: &image::RgbImage) -> Vec<(&'static str, usize, u32, Vec<u32>)> {
    let dynamic = image::DynamicImage::ImageRgb8(img.clone());
    let rgb8: Vec<u32> = img.as_raw().iter().map(|&v| v as u32).collect();
    let grey8: Vec<u32> = dynamic
        .to_luma8()
        .as_raw()
        .iter()
        .map(|&v| v as u32)
        .collect();
    let grey16: Vec<u32> = dynamic
        .to_luma16()
        .as_raw()
        .iter()
        .map(|&v| v as u32)
        .collect();
    // 16-bit RGB with detail below the 8-bit step: each code spread by a second grain.
    let mut state = 0x1234_5678_9abc_def1u64;
    let rgb16: Vec<u32> = img
        .as_raw()
        .iter()
        .map(|&v| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (v as u32 * 257 + (state % 257) as u32).min(65535)
        })
        .collect();
    vec![
        ("rgb8", 3, 255, rgb8),
        ("grey8", 1, 255, grey8),
        ("grey16", 1, 65535, grey16),
        ("rgb16", 3, 65535, rgb16),
    ]
}

/// The binary files of one kind that shrink on load.
fn shrinking_files(
    dir: &Path,
    name: &str,
    (kind, channels, maxval, samples): (&str, usize, u32, &[u32]),
    w: u32,
    h: u32,
) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let pnm = dir.join(format!(
        "{name}-{kind}.{}",
        if channels == 1 { "pgm" } else { "ppm" }
    ));
    write_binary(&pnm, w, h, channels, maxval, samples);
    files.push(pnm);
    let png = dir.join(format!("{name}-{kind}.png"));
    let tiff = dir.join(format!("{name}-{kind}.tif"));
    match (channels, maxval) {
        (3, 255) => {
            let v: Vec<u8> = samples.iter().map(|&s| s as u8).collect();
            let img = image::RgbImage::from_raw(w, h, v).unwrap();
            img.save(&png).unwrap();
            img.save(&tiff).unwrap();
            files.push(tiff);
        }
        (1, 255) => {
            let v: Vec<u8> = samples.iter().map(|&s| s as u8).collect();
            image::GrayImage::from_raw(w, h, v)
                .unwrap()
                .save(&png)
                .unwrap();
        }
        (1, _) => {
            let v: Vec<u16> = samples.iter().map(|&s| s as u16).collect();
            let img = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, v).unwrap();
            img.save(&png).unwrap();
        }
        _ => {
            let v: Vec<u16> = samples.iter().map(|&s| s as u16).collect();
            let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(w, h, v).unwrap();
            img.save(&png).unwrap();
            img.save(&tiff).unwrap();
            files.push(tiff);
        }
    }
    files.push(png);
    files
}

#[test]
fn shrink_on_load_is_within_0_3_db_of_the_full_decode() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let photos = photos(&["astronaut.png", "coffee.png", "chelsea.png"]);
    assert!(!photos.is_empty() || !crate::common::in_ci());
    let (mut worst, mut runs) = (f64::INFINITY, 0);
    let mut failed = Vec::new();
    let mut factors = [false; 5];
    for (name, img) in &photos {
        let big = camera_sized(img);
        let (w, h) = (big.width(), big.height());
        for (kind, channels, maxval, samples) in kinds(&big) {
            // The full-decode twin, and its reference for each output size.
            let twin = dir.join(format!("{name}-{kind}-plain.pnm"));
            write_plain(&twin, w, h, channels, maxval, &samples);
            let files = shrinking_files(dir, name, (kind, channels, maxval, &samples), w, h);
            drop(samples);
            let full = halftone::io::read_image(&twin, &ReadOptions::default()).unwrap();
            // Outputs a quarter, a seventh and a ninth as wide: boxes of 2, 3 and 4.
            for div in [4, 7, 9] {
                let tw = w as usize / div;
                let th = ((h as f64 * tw as f64 / w as f64).round() as usize).max(1);
                let f = shrink_factor(w as usize, h as usize, tw, th);
                assert!(f > 1, "{name} to {tw}: no shrink");
                factors[f] = true;
                let refp = dir.join("ref.pgm");
                reference(&full, tw, th, &refp);
                let width = tw.to_string();
                let args = ["--width", &width, "--method", "diffuse", "--format", "pbm"];
                let full_out = dir.join("full.pbm");
                convert(&twin, &full_out, &args);
                let full_bytes = std::fs::read(&full_out).unwrap();
                let db_full = hvs_psnr(&refp, &full_out);
                for file in &files {
                    let out = dir.join("shrunk.pbm");
                    convert(file, &out, &args);
                    let bytes = std::fs::read(&out).unwrap();
                    // The same size (the PBM header), by another path (other bytes).
                    let header = |b: &[u8]| b.split(|&c| c == b'\n').take(2).count();
                    assert_eq!(header(&bytes), header(&full_bytes));
                    assert_eq!(bytes.len(), full_bytes.len(), "{file:?} to {tw}: size");
                    assert!(bytes != full_bytes, "{file:?} to {tw}: not shrunk on load");
                    let db = hvs_psnr(&refp, &out);
                    let ext = file.extension().unwrap().to_string_lossy();
                    eprintln!(
                        "{name} {kind} {ext} {w}x{h} → {tw}x{th} (box {f}): shrunk {db:.2} dB, full {db_full:.2} dB ({:+.2})",
                        db - db_full
                    );
                    if db < db_full - 0.3 {
                        failed.push(format!(
                            "{name} {kind} {ext} to {tw}: shrink-on-load {db:.2} dB, full decode {db_full:.2} dB"
                        ));
                    }
                    worst = worst.min(db - db_full);
                    runs += 1;
                }
            }
            for f in files.iter().chain([&twin]) {
                std::fs::remove_file(f).unwrap();
            }
        }
    }
    eprintln!(
        "worst difference: {worst:+.2} dB over {} photos, {runs} outputs shrunk on load",
        photos.len()
    );
    assert!(failed.is_empty(), "{failed:#?}");
    assert!(
        photos.is_empty() || factors[2..] == [true; 3],
        "boxes used: {factors:?}"
    );
}

/// A photo-like image of `w × h` (smooth gradients, edges and fine detail), interleaved.
fn synthetic(w: u32, h: u32, channels: usize) -> Vec<u8> {
    let mut v = Vec::with_capacity((w * h) as usize * channels);
    for y in 0..h {
        for x in 0..w {
            for c in 0..channels as u32 {
                let smooth = (x * 255 / w + y * 128 / h + c * 60) % 256;
                let edge = if (x / 97 + y / 61 + c) % 3 == 0 {
                    60
                } else {
                    0
                };
                let fine = (x * 7 + y * 13 + (x * y) % 31) % 23;
                v.push(((smooth + edge + fine) % 256) as u8);
            }
        }
    }
    grain(v.iter_mut());
    v
}

#[test]
fn shrunk_output_is_the_same_for_every_budget_and_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    // Camera-sized, and no multiple of any box in either direction.
    let (w, h) = (2411u32, 1703u32);
    assert!((w * h) as usize >= SHRINK_MIN_PIXELS);
    let grey = synthetic(w, h, 1);
    let rgb = synthetic(w, h, 3);
    let pgm = dir.join("g.pgm");
    let samples: Vec<u32> = grey.iter().map(|&v| v as u32).collect();
    write_binary(&pgm, w, h, 1, 255, &samples);
    let png = dir.join("c.png");
    let rgb_img = image::RgbImage::from_raw(w, h, rgb).unwrap();
    rgb_img.save(&png).unwrap();
    let tiff = dir.join("c.tif");
    rgb_img.save(&tiff).unwrap();
    for (input, args) in [
        (
            &pgm,
            &["--width", "300", "--method", "diffuse", "--format", "pbm"][..],
        ),
        (&pgm, &["--preset", "thermal-203", "--format", "pbm"][..]),
        (
            &png,
            &["--width", "500", "--method", "ordered", "--format", "pgm"][..],
        ),
        (
            &png,
            &["--width", "400", "--color", "rgb", "--format", "ppm"][..],
        ),
        (
            &tiff,
            &["--fit", "700x300", "--method", "diffuse", "--format", "pbm"][..],
        ),
    ] {
        same_bytes_for_every_budget(input, args, &["auto", "1G", "64M", "12M"]);
        // A budget that cannot hold the shrunk image is one line naming the file.
        let out = dir.join("o.out");
        let o = convert_with_budget(input, &out, args, "100K");
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(
            e.contains(input.file_name().unwrap().to_str().unwrap()),
            "{e}"
        );
        assert!(e.contains("--max-memory"), "{e}");
    }
}

#[test]
fn flat_grey_keeps_its_tone() {
    // A flat image shrinks to the very codes the full decode's resize makes of it, so the
    // halftone is the same, byte for byte, as the full-decode path's.
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let (w, h) = (2003u32, 2001u32);
    for (channels, maxval, code) in [(1, 255, 128), (1, 255, 7), (3, 255, 200), (1, 65535, 30000)] {
        let samples = vec![code; (w * h) as usize * channels];
        let bin = dir.join("flat.pnm");
        write_binary(&bin, w, h, channels, maxval, &samples);
        let twin = dir.join("flat-plain.pnm");
        write_plain(&twin, w, h, channels, maxval, &samples);
        for args in [
            &["--width", "250", "--method", "diffuse", "--format", "pbm"][..],
            &[
                "--width", "301", "--method", "ordered", "--levels", "4", "--format", "pgm",
            ],
        ] {
            let (a, b) = (dir.join("a.out"), dir.join("b.out"));
            convert(&bin, &a, args);
            convert(&twin, &b, args);
            assert!(
                std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
                "code {code}/{maxval}, {channels} channels, {args:?}"
            );
        }
    }
}

/// For measuring (docs/photos.md): `HALFTONE_SHRINK_REF=input:width:height:out.pgm` writes
/// the full decode of `input` resized to `width × height` in linear light, the reference
/// `halftone compare` measures both paths' halftones against.
#[test]
#[ignore = "writes a reference for docs/photos.md when HALFTONE_SHRINK_REF is set"]
fn reference_for_measuring() {
    let spec = std::env::var("HALFTONE_SHRINK_REF").expect("HALFTONE_SHRINK_REF=in:w:h:out");
    let f: Vec<&str> = spec.split(':').collect();
    let img = halftone::io::read_image(Path::new(f[0]), &ReadOptions::default()).unwrap();
    reference(
        &img,
        f[1].parse().unwrap(),
        f[2].parse().unwrap(),
        Path::new(f[3]),
    );
}
