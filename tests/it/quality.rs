//! The quality figures on analytic cases: what `compare` must say is known exactly.

use halftone::method::pattern::{Cell, Pattern};
use halftone::quality::{
    compare, compare_halftone, decoded_halftone_reflectance, halftone_reflectance,
    image_reflectance, lstar, nasanen, Reflectance, Viewing,
};
use halftone::raster::{Halftone, Image, Samples};
use halftone::tone::{linear_to_srgb8, srgb_to_linear, Encoding};
use halftone::{Mask, Method, ToneOptions};

fn grey(width: usize, height: usize, f: impl Fn(usize, usize) -> f32) -> Reflectance {
    let mut p = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            p.push(f(x, y));
        }
    }
    Reflectance {
        width,
        height,
        planes: vec![p],
    }
}

#[test]
fn identical_images_are_perfect() {
    let a = grey(40, 30, |x, y| ((x * 7 + y * 3) % 17) as f32 / 16.0);
    let q = compare(&a, &a, &Viewing::default()).unwrap();
    assert_eq!(q.hvs_mse, 0.0);
    assert!(q.hvs_psnr_db.is_infinite());
    assert_eq!(q.tone_bias, 0.0);
    assert_eq!(q.lstar_rms, 0.0);
    assert_eq!(q.scale, [1, 1]);
}

#[test]
fn constant_offset_gives_exact_bias_psnr_and_lstar() {
    // The filter passes DC untouched, so a constant error of 0.125 is seen whole.
    let a = Reflectance::constant(37, 23, 0.375);
    let b = Reflectance::constant(37, 23, 0.5);
    let q = compare(&a, &b, &Viewing::default()).unwrap();
    assert!((q.tone_bias - 0.125).abs() < 1e-12, "{}", q.tone_bias);
    assert!((q.hvs_mse - 0.015625).abs() < 1e-12, "{}", q.hvs_mse);
    let expect_db = -10.0 * 0.015625f64.log10();
    assert!((q.hvs_psnr_db - expect_db).abs() < 1e-9);
    assert!((q.plain_psnr_db - expect_db).abs() < 1e-9);
    assert!((q.lstar_rms - (lstar(0.5) - lstar(0.375))).abs() < 1e-9);
    // L* of mid reflectance 0.18 is the photographer's middle grey, about 49.5.
    assert!((lstar(0.18) - 49.5).abs() < 0.1);
}

#[test]
fn sinusoid_is_attenuated_as_the_filter_predicts() {
    // cos(2π f (x + ½)) with 2·64·f whole is exactly mirror-symmetric at both edges, so the
    // padded plane is one pure frequency and the filtered error is A·H(f)·cos exactly.
    let view = Viewing::default();
    for &cycles in &[2usize, 4, 8, 16] {
        let f = cycles as f64 / 128.0; // cycles per pixel
        let amp = 0.25;
        let a = Reflectance::constant(64, 64, 0.5);
        let b = grey(64, 64, |x, _| {
            (0.5 + amp * (2.0 * std::f64::consts::PI * f * (x as f64 + 0.5)).cos()) as f32
        });
        let q = compare(&a, &b, &view).unwrap();
        let h = nasanen(f * view.pixels_per_degree());
        let predicted = amp * amp * h * h / 2.0;
        assert!(
            (q.hvs_mse / predicted - 1.0).abs() < 1e-4,
            "f={f}: mse {} predicted {predicted}",
            q.hvs_mse
        );
        // Unfiltered it is A²/2 (to f32 rounding).
        assert!((q.plain_psnr_db + 10.0 * (amp * amp / 2.0).log10()).abs() < 1e-4);
        assert!(q.tone_bias.abs() < 1e-6);
    }
    // Nearer, the same pattern is seen coarser in degrees... and less attenuated.
    let near = Viewing::new(300.0, 6.0).unwrap();
    assert!(near.hvs_gain(1.0 / 16.0) > view.hvs_gain(1.0 / 16.0));
}

#[test]
fn a_checkerboard_is_invisible_at_300_dpi() {
    // Half ink, half paper at the highest frequency: tone is right, texture unseen.
    let a = Reflectance::constant(64, 64, 0.5);
    let b = grey(64, 64, |x, y| ((x + y) % 2) as f32);
    let q = compare(&a, &b, &Viewing::default()).unwrap();
    assert!(q.hvs_psnr_db > 60.0, "{}", q.hvs_psnr_db);
    assert!(q.plain_psnr_db < 6.1);
    // The same checkerboard at 30 dpi is plainly visible.
    let q30 = compare(&a, &b, &Viewing::new(30.0, 12.0).unwrap()).unwrap();
    assert!(q30.hvs_psnr_db < 25.0, "{}", q30.hvs_psnr_db);
}

#[test]
fn colour_is_the_mean_of_the_channels_mean_squares() {
    let a = Reflectance {
        width: 20,
        height: 10,
        planes: vec![vec![0.5; 200]; 3],
    };
    let b = Reflectance {
        width: 20,
        height: 10,
        planes: vec![vec![0.5; 200], vec![0.6; 200], vec![0.8; 200]],
    };
    let q = compare(&a, &b, &Viewing::default()).unwrap();
    let expect = (0.0 + 0.01 + 0.09) / 3.0;
    assert!((q.hvs_mse - expect).abs() < 1e-7, "{}", q.hvs_mse);
    assert!((q.tone_bias - 0.4 / 3.0).abs() < 1e-7);
}

#[test]
fn halftone_levels_are_evenly_spaced_in_light() {
    let mut h = Halftone::new(3, 1, 1, 4);
    h.set(0, 1, 0, 1);
    h.set(0, 2, 0, 3);
    let r = halftone_reflectance(&h);
    assert_eq!(r.planes[0], vec![0.0, 1.0 / 3.0, 1.0]);
    // A palette halftone gives the palette's linear colours.
    let mut p = Halftone::new(2, 1, 1, 2);
    p.set(0, 1, 0, 1);
    p.palette = Some(vec![[0, 0, 0], [255, 128, 0]]);
    let r = halftone_reflectance(&p);
    assert_eq!(r.planes.len(), 3);
    assert_eq!(r.planes[0], vec![0.0, 1.0]);
    assert!((r.planes[1][1] as f64 - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
}

#[test]
fn a_halftone_file_decodes_to_its_levels() {
    // Four levels written as the sRGB codes of 0, 1/3, 2/3, 1 decode back to those.
    let codes: Vec<u8> = (0..4).map(|k| linear_to_srgb8(k as f64 / 3.0)).collect();
    let img = Image::gray8(4, 1, codes);
    let r = decoded_halftone_reflectance(&img, Encoding::Srgb);
    for (k, &v) in r.planes[0].iter().enumerate() {
        assert!((v as f64 - k as f64 / 3.0).abs() < 2e-3, "{k}: {v}");
    }
    // The same levels written evenly spaced (PGM with maxval 3, scaled to 0, 85, 170, 255).
    let img = Image::gray8(4, 1, vec![0, 85, 170, 255]);
    let r = decoded_halftone_reflectance(&img, Encoding::Linear);
    assert_eq!(r.planes[0], vec![0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0]);
    // 16-bit originals go through the 16-bit table.
    let img16 = Image {
        width: 1,
        height: 1,
        color: halftone::raster::ColorKind::Gray,
        planes: vec![Samples::U16(vec![32896])],
        encoding: Encoding::Srgb,
        dpi: None,
    };
    assert!((image_reflectance(&img16).planes[0][0] - 0.2158).abs() < 1e-3);
}

#[test]
fn expanded_halftone_is_compared_with_the_box_enlarged_original() {
    // Every code the 3x3 pattern can show exactly: 10 tones k/9; a ramp of them expanded.
    let codes: Vec<u8> = (0..10).map(|k| linear_to_srgb8(k as f64 / 9.0)).collect();
    let mut px = Vec::new();
    for _ in 0..6 {
        px.extend_from_slice(&codes);
    }
    let img = Image::gray8(10, 6, px);
    let method = Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, Cell::Expand).unwrap();
    let tone = img.tone_table(&ToneOptions::default());
    let h = method.halftone(&img.planes(&tone)).unwrap();
    assert_eq!((h.width, h.height), (30, 18));
    let q = compare_halftone(&img, &h, &Viewing::default()).unwrap();
    assert_eq!(q.scale, [3, 3]);
    // Each cell holds its tone exactly: only the 8-bit rounding of the codes remains.
    assert!(q.tone_bias.abs() < 2e-3, "{}", q.tone_bias);
    assert!(q.hvs_psnr_db > 30.0, "{}", q.hvs_psnr_db);
}

#[test]
fn sizes_that_do_not_fit_are_refused() {
    let a = Reflectance::constant(10, 10, 0.5);
    let b = Reflectance::constant(15, 10, 0.5);
    let err = compare(&a, &b, &Viewing::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("15x10") && err.contains("10x10"), "{err}");
    assert!(Viewing::new(0.0, 12.0).is_err());
    assert!(Viewing::new(300.0, f64::NAN).is_err());
}

#[test]
fn grey_halftone_of_a_colour_original_is_compared_as_luminance() {
    // Pure green: luminance 0.7152; a grey halftone at that reflectance has no bias.
    let img = Image::rgb8(8, 8, &[0, 255, 0].repeat(64));
    let r = image_reflectance(&img).luminance();
    assert!((r.planes[0][0] - 0.7152).abs() < 1e-4);
    let mut h = Halftone::new(8, 8, 1, 256);
    for y in 0..8 {
        for x in 0..8 {
            h.set(0, x, y, (0.7152f64 * 255.0).round() as u8);
        }
    }
    let q = compare_halftone(&img, &h, &Viewing::default()).unwrap();
    assert!(q.tone_bias.abs() < 2e-3, "{}", q.tone_bias);
}
