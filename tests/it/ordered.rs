//! Ordered dithering: tone kept at every grey level for every shipped mask, output identical
//! for any thread count, colour planes offset, inversion.

use halftone::method::ordered::Ordered;
use halftone::raster::Image;
use halftone::{halftone_image, ColorMode, Halftone, Mask, Method, ToneOptions};

/// Mean reflectance of plane `c` (levels k/(L−1)).
fn mean_reflectance(h: &Halftone, c: usize) -> f64 {
    let levels = h.levels_of(c);
    let sum: u64 = levels.iter().map(|&l| l as u64).sum();
    sum as f64 / (levels.len() as f64 * (h.levels - 1) as f64)
}

/// A smooth, photo-like grey image: soft gradients and a few round highlights.
fn photo(w: usize, h: usize) -> Image {
    let mut px = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f64 / w as f64, y as f64 / h as f64);
            let mut l = 0.5 + 0.3 * (6.0 * u).sin() * (4.0 * v).cos();
            let d = ((u - 0.3).powi(2) + (v - 0.6).powi(2)).sqrt();
            l += 0.4 * (-d * d * 40.0).exp() - 0.2 * u * v;
            px.push((l.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    Image::gray8(w, h, px)
}

/// For every constant 8-bit code, the mean reflectance over whole tiles is within
/// ½/(N·(L−1)) (so within the required 1/N) of the code's linear value.
fn check_tone(mask: &Mask, levels: u16, opts: &ToneOptions) {
    let n = mask.len() as f64;
    let bound = 0.5 / (n * (levels - 1) as f64) + 1e-9;
    let o = Ordered::new(mask.clone(), levels).unwrap();
    // Small masks: two tiles across and down, so the tiling itself is exercised.
    let tiles = if mask.len() <= 256 { 2 } else { 1 };
    let (w, h) = (tiles * mask.width, tiles * mask.height);
    let table = Image::gray8(1, 1, vec![0]).tone_table(opts);
    for code in 0..=255u8 {
        let img = Image::gray8(w, h, vec![code; w * h]);
        let out = halftone_image(&img, &o, ColorMode::Gray, opts).unwrap();
        let want = table.as_slice()[code as usize] as f64;
        let got = mean_reflectance(&out, 0);
        assert!(
            (got - want).abs() <= bound,
            "{} L={levels} code {code}: mean {got:.6}, linear value {want:.6}",
            mask.name
        );
    }
}

#[test]
fn tone_at_every_level_for_every_shipped_mask() {
    let names: Vec<&str> = Mask::builtin_names().collect();
    for want in [
        "bayer-2",
        "bayer-4",
        "bayer-8",
        "bayer-16",
        "cluster-4",
        "cluster-6",
        "cluster-8",
        "cluster-16",
        "dot45-8",
        "blue-noise-64",
        "blue-noise-128",
    ] {
        assert!(names.contains(&want), "{want} is not shipped");
    }
    for name in names {
        let mask = Mask::builtin(name).unwrap();
        for levels in [2, 3, 4] {
            check_tone(&mask, levels, &ToneOptions::default());
        }
    }
}

#[test]
fn tone_holds_inverted_and_without_linearising() {
    let mask = Mask::builtin("bayer-8").unwrap();
    for levels in [2, 3, 4] {
        check_tone(
            &mask,
            levels,
            &ToneOptions {
                invert: true,
                ..Default::default()
            },
        );
        check_tone(
            &mask,
            levels,
            &ToneOptions {
                linearize: false,
                ..Default::default()
            },
        );
    }
}

#[test]
fn invert_swaps_paper_and_ink() {
    let mask = Mask::builtin("bayer-4").unwrap();
    let o = Ordered::new(mask, 2).unwrap();
    let inv = ToneOptions {
        invert: true,
        ..Default::default()
    };
    let white = Image::gray8(8, 8, vec![255; 64]);
    let black = Image::gray8(8, 8, vec![0; 64]);
    let run = |img: &Image, t: &ToneOptions| {
        halftone_image(img, &o, ColorMode::Gray, t)
            .unwrap()
            .levels_of(0)
    };
    assert!(run(&white, &ToneOptions::default()).iter().all(|&l| l == 1));
    assert!(run(&white, &inv).iter().all(|&l| l == 0));
    assert!(run(&black, &inv).iter().all(|&l| l == 1));
    // Code 188 is about 50% linear: inverted it is still about half paper.
    let mid = Image::gray8(8, 8, vec![188; 64]);
    let a = run(&mid, &ToneOptions::default());
    let b = run(&mid, &inv);
    assert_eq!(a.iter().filter(|&&l| l == 1).count(), 8 * 4);
    assert_eq!(b.iter().filter(|&&l| l == 1).count(), 8 * 4);
}

#[test]
fn same_bytes_for_any_thread_count() {
    let img = photo(997, 611);
    let rgb = {
        let g = match &img.planes[0] {
            halftone::raster::Samples::U8(v) => v.clone(),
            _ => unreachable!(),
        };
        let inter: Vec<u8> = g
            .iter()
            .enumerate()
            .flat_map(|(i, &c)| [c, (i % 256) as u8, 255 - c])
            .collect();
        Image::rgb8(img.width, img.height, &inter)
    };
    let run = |threads: usize, mask: &str, levels: u16, color: ColorMode, img: &Image| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let o = Ordered::new(Mask::builtin(mask).unwrap(), levels).unwrap();
        pool.install(|| halftone_image(img, &o, color, &ToneOptions::default()).unwrap())
    };
    for (mask, levels, color, im) in [
        ("bayer-8", 2, ColorMode::Gray, &img),
        ("blue-noise-128", 2, ColorMode::Gray, &img),
        ("cluster-6", 4, ColorMode::Gray, &img),
        ("dot45-8", 2, ColorMode::Rgb, &rgb),
        ("bayer-16", 3, ColorMode::Rgb, &rgb),
    ] {
        let one = run(1, mask, levels, color, im);
        let two = run(2, mask, levels, color, im);
        assert_eq!(one, two, "{mask} L={levels} {color:?}");
        let three = run(3, mask, levels, color, im);
        assert_eq!(one, three, "{mask} L={levels} {color:?}");
    }
}

#[test]
fn rgb_planes_use_offset_masks() {
    // A flat mid grey in all three channels: each plane keeps the tone, but the dots sit
    // in different places, so the planes differ pairwise.
    let img = Image::rgb8(64, 64, &[150u8; 64 * 64 * 3]);
    for name in ["bayer-8", "cluster-8", "blue-noise-64"] {
        let o = Ordered::new(Mask::builtin(name).unwrap(), 2).unwrap();
        let h = halftone_image(&img, &o, ColorMode::Rgb, &ToneOptions::default()).unwrap();
        assert_eq!(h.channels(), 3);
        let p: Vec<Vec<u8>> = (0..3).map(|c| h.levels_of(c)).collect();
        assert_ne!(p[0], p[1], "{name}");
        assert_ne!(p[1], p[2], "{name}");
        assert_ne!(p[0], p[2], "{name}");
        let m0 = mean_reflectance(&h, 0);
        for c in 1..3 {
            assert!((mean_reflectance(&h, c) - m0).abs() < 1e-12, "{name}");
        }
        // Plane 1 is plane 0 read at the offset cell.
        let (dx, dy) = o.channel_offset(1);
        let w = 64;
        for y in 0..w {
            for x in 0..w {
                let (sx, sy) = ((x + dx) % w, (y + dy) % w);
                assert_eq!(p[1][y * w + x], p[0][sy * w + sx], "{name}");
            }
        }
    }
}

#[test]
fn custom_mask_file_with_ties() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("odd.mask");
    // Any numbers: ranks by value, ties by position; 3x2, not square.
    std::fs::write(&path, "# custom\n0.5 0.5 0.1\n0.9 0.2 0.7\n").unwrap();
    let mask = Mask::load(path.to_str().unwrap(), false).unwrap();
    assert_eq!(mask.ranks, vec![2, 3, 0, 5, 1, 4]);
    for levels in [2, 3, 4] {
        check_tone(&mask, levels, &ToneOptions::default());
    }
}

#[test]
fn multi_level_places_pixels_between_neighbouring_levels() {
    // Every output level is one of the two levels around the input's value.
    let img = photo(200, 150);
    let table = img.tone_table(&ToneOptions::default());
    let codes = match &img.planes[0] {
        halftone::raster::Samples::U8(v) => v.clone(),
        _ => unreachable!(),
    };
    for levels in [3u16, 4, 16] {
        let o = Ordered::new(Mask::builtin("bayer-8").unwrap(), levels).unwrap();
        let h = o.halftone(&img.planes(&table)).unwrap();
        let top = (levels - 1) as f64;
        for (&l, &c) in h.levels_of(0).iter().zip(&codes) {
            let s = table.as_slice()[c as usize] as f64 * top;
            assert!(
                (l as f64) >= s.floor().min(top - 1.0) && (l as f64) <= s.ceil(),
                "L={levels} code {c}: level {l}"
            );
        }
    }
}

#[test]
fn bad_levels_are_refused() {
    let m = Mask::builtin("bayer-2").unwrap();
    assert!(Ordered::new(m.clone(), 1).is_err());
    assert!(Ordered::new(m, 257).is_err());
}
