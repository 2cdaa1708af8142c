//! Photographs: JPEG shrink-on-load (DCT scaling) stays within 0.3 dB HVS-PSNR of the
//! full-decode path.
//!
//! Photos: Grace Hopper (python-matplotlib-data, installed by .ci/run) and, when Debian's
//! python3-skimage is there, its astronaut, coffee, chelsea and hubble_deep_field. The
//! reference is the full decode (the `image` crate), resized in linear light by the library
//! to the output size; both halftones are compared with it by `halftone compare`.
#![cfg(halftone_libjpeg)]

use std::path::Path;

use halftone::io::ReadOptions;
use halftone::pipeline::jpeg::{JpegSource, SHRINK_MIN_PIXELS};
use halftone::pipeline::source::RowSource;

mod common;
use common::{grain, hvs_psnr, ok, photos, reference, same_bytes_for_every_budget};

/// `img` enlarged 4× (Lanczos) with a fine grain of ±8 codes, as a camera-sized photo.
fn camera_sized(img: &image::RgbImage) -> image::RgbImage {
    let (w, h) = (img.width() * 4, img.height() * 4);
    let mut big = image::imageops::resize(img, w, h, image::imageops::FilterType::Lanczos3);
    grain(big.iter_mut());
    big
}

fn save_jpeg(img: &image::RgbImage, path: &Path) {
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
        .encode_image(img)
        .unwrap();
    std::fs::write(path, bytes).unwrap();
}

/// Halftones `jpg` to widths `w / div` through shrink-on-load and through the full decode
/// (the same pixels as a BMP), returning (target width, denominator used, dB shrunk, dB full).
fn shrink_vs_full(dir: &Path, jpg: &Path, divs: &[f64]) -> Vec<(usize, usize, f64, f64)> {
    // The full decode as a lossless BMP: BMP input takes the full-decode path (PNG, TIFF
    // and PNM are shrunk on load too, by boxes in linear light: tests/shrink.rs).
    let full_img = image::open(jpg).unwrap().to_rgb8();
    let (w, h) = (full_img.width() as usize, full_img.height() as usize);
    let png = dir.join("full.bmp");
    full_img.save(&png).unwrap();
    let mut rows = Vec::new();
    for &div in divs {
        let tw = (w as f64 / div).round() as usize;
        let th = ((h as f64 * tw as f64 / w as f64).round() as usize).max(1);
        let mut src = JpegSource::open(jpg, jpg, &ReadOptions::default())
            .unwrap()
            .expect("libjpeg decodes it");
        src.shrink_to(tw, th);
        let denom = w.div_ceil(src.info().width);
        let refp = dir.join("ref.pgm");
        let full = halftone::io::read_image(&png, &ReadOptions::default()).unwrap();
        reference(&full, tw, th, &refp);
        let mut db = [0.0; 2];
        for (k, input) in [jpg, png.as_path()].into_iter().enumerate() {
            let out = dir.join(format!("o{k}.pbm"));
            ok(&[
                "convert".as_ref(),
                input.as_os_str(),
                "-o".as_ref(),
                out.as_os_str(),
                "--width".as_ref(),
                tw.to_string().as_ref(),
                "--method".as_ref(),
                "diffuse".as_ref(),
            ]);
            db[k] = hvs_psnr(&refp, &out);
        }
        eprintln!(
            "{} {w}x{h} → {tw}x{th} (1/{denom}): shrunk {:.2} dB, full {:.2} dB ({:+.2})",
            jpg.file_name().unwrap().to_string_lossy(),
            db[0],
            db[1],
            db[0] - db[1]
        );
        rows.push((tw, denom, db[0], db[1]));
    }
    rows
}

#[test]
fn shrink_on_load_is_within_0_3_db_of_the_full_decode() {
    let dir = tempfile::tempdir().unwrap();
    let photos = photos(&[
        "astronaut.png",
        "coffee.png",
        "chelsea.png",
        "hubble_deep_field.jpg",
    ]);
    assert!(!photos.is_empty() || std::env::var_os("CI").is_none());
    let (mut worst, mut shrunk) = (f64::INFINITY, 0);
    let mut failed = Vec::new();
    for (name, img) in &photos {
        // As they are (small: decoded whole, so only the decoders differ), and camera-sized
        // (shrunk on load by 2 and 4 for outputs 4 and 8 times smaller).
        let big = camera_sized(img);
        for (img, divs) in [(img, &[4.0, 8.0][..]), (&big, &[4.0, 8.0][..])] {
            let jpg = dir.path().join(format!("{name}-{}.jpg", img.width()));
            save_jpeg(img, &jpg);
            let camera = (img.width() * img.height()) as usize >= SHRINK_MIN_PIXELS;
            for (tw, denom, db_shrunk, db_full) in shrink_vs_full(dir.path(), &jpg, divs) {
                if camera {
                    shrunk += 1;
                    assert!(denom > 1, "{name} to {tw}: not shrunk on load");
                } else {
                    assert_eq!(denom, 1, "{name} to {tw}: small photos decode whole");
                }
                if db_shrunk < db_full - 0.3 {
                    failed.push(format!(
                        "{name} to {tw}: shrink-on-load {db_shrunk:.2} dB, full decode {db_full:.2} dB"
                    ));
                }
                worst = worst.min(db_shrunk - db_full);
            }
        }
    }
    eprintln!(
        "worst difference: {worst:+.2} dB over {} photos, {shrunk} outputs shrunk on load",
        photos.len()
    );
    assert!(failed.is_empty(), "{failed:#?}");
}

#[test]
fn shrink_needs_a_much_smaller_output() {
    use halftone::pipeline::jpeg::shrink_denominator;
    // At least twice the output's size is left to the resize.
    assert_eq!(shrink_denominator(6000, 4000, 100, 50), 4);
    assert_eq!(shrink_denominator(6000, 4000, 384, 256), 4);
    assert_eq!(shrink_denominator(6000, 4000, 750, 500), 4);
    assert_eq!(shrink_denominator(6000, 4000, 751, 10), 2);
    assert_eq!(shrink_denominator(6000, 4000, 1501, 1000), 1);
    // Rounded up as libjpeg rounds: ⌈2001/4⌉ = 501.
    assert_eq!(shrink_denominator(2001, 2000, 250, 250), 4);
    assert_eq!(shrink_denominator(2001, 2000, 251, 250), 2);
    // Small images are decoded whole.
    assert_eq!(shrink_denominator(1999, 2000, 10, 10), 1);
}

#[test]
fn streamed_jpeg_is_the_same_for_every_budget_and_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    // A photo-like RGB image whose height is no multiple of a band or an MCU row.
    let (w, h) = (333u32, 251u32);
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        let v = |k: u32| ((x * k + y * (k + 3) + (x * y) % 97) % 256) as u8;
        image::Rgb([v(3), v(5), v(7)])
    });
    let jpg = dir.path().join("p.jpg");
    save_jpeg(&img, &jpg);
    for args in [
        &["--method", "diffuse", "--format", "pbm"][..],
        &["--method", "diffuse", "--color", "rgb", "--format", "ppm"][..],
        &["--method", "ordered", "--levels", "4", "--format", "pgm"][..],
    ] {
        // 1G: the whole image; auto: streamed (JPEG prefers it); the rest: many bands.
        same_bytes_for_every_budget(&jpg, args, &["1G", "auto", "2M", "300K", "80K"]);
    }
}
