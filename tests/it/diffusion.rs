//! Error diffusion: tone at every grey level, thread-count independence, user kernels.

use halftone::method::diffusion::{Diffuse, DiffuseOptions, KERNELS};
use halftone::{Halftone, Image, Method, ToneOptions};
use rayon::prelude::*;

/// Patch size, and the part measured: away from the edges and from the first rows, where
/// sparse tones have not started yet (error diffusion's known start-up delay).
const W: usize = 128;
const H: usize = 256;
const MEASURED_X: std::ops::Range<usize> = 16..112;
const MEASURED_Y: std::ops::Range<usize> = 96..240;

fn run(method: &dyn Method, img: &Image) -> Halftone {
    let table = img.tone_table(&ToneOptions::default());
    method.halftone(&img.planes(&table)).unwrap()
}

/// Mean output reflectance minus input reflectance, over the centre of a flat patch.
fn tone_error(method: &dyn Method, code: u8) -> f64 {
    let img = Image::gray8(W, H, vec![code; W * H]);
    let table = img.tone_table(&ToneOptions::default());
    let want = table.as_slice()[code as usize] as f64;
    let h = method.halftone(&img.planes(&table)).unwrap();
    let mut sum = 0.0;
    let mut n = 0usize;
    for y in MEASURED_Y {
        for x in MEASURED_X {
            sum += h.reflectance(h.get(0, x, y));
            n += 1;
        }
    }
    sum / n as f64 - want
}

fn worst_tone_error(method: &dyn Method, step: usize) -> (f64, u8) {
    (0..=255u8)
        .into_par_iter()
        .filter(|c| (*c as usize).is_multiple_of(step) || *c == 255)
        .map(|c| (tone_error(method, c), c))
        .reduce(
            || (0.0, 0),
            |a, b| if b.0.abs() > a.0.abs() { b } else { a },
        )
}

fn diffuse(name: &str, opts: DiffuseOptions) -> Diffuse {
    Diffuse::new(name, opts).unwrap()
}

#[test]
fn tone_is_kept_at_every_grey_level() {
    let mut failures = Vec::new();
    for &name in KERNELS.iter() {
        for serpentine in [true, false] {
            let opts = DiffuseOptions {
                serpentine,
                ..Default::default()
            };
            // Every level in the default (serpentine) scan; every 4th in raster order, to keep
            // the test short in debug builds.
            let step = if serpentine { 1 } else { 4 };
            let (err, code) = worst_tone_error(&diffuse(name, opts), step);
            let bound = if name == "atkinson" {
                ATKINSON_TONE_LOSS
            } else {
                0.004
            };
            eprintln!(
                "{name:>20} serpentine {serpentine:5}: worst tone error {err:+.5} at code {code}"
            );
            if err.abs() >= bound {
                failures.push(format!(
                    "{name} serpentine {serpentine}: {err:.5} at code {code}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Atkinson drops 2/8 of every error, so mid-tones drift: measured worst case (see the
/// kernel table's documentation).
const ATKINSON_TONE_LOSS: f64 = 0.13;

#[test]
fn tone_is_kept_with_four_levels() {
    for name in ["floyd-steinberg", "ostromoukhov", "zhou-fang", "riemersma"] {
        let opts = DiffuseOptions {
            levels: 4,
            ..Default::default()
        };
        let (err, code) = worst_tone_error(&diffuse(name, opts), 1);
        assert!(
            err.abs() < 0.004,
            "{name}: tone error {err:.5} at code {code}"
        );
    }
}

/// A test image with detail: a ramp with a diagonal sine pattern and a few edges.
fn photo_like(w: usize, h: usize) -> Image {
    let mut v = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let ramp = x as f64 / (w - 1) as f64;
            let wave = 0.15 * ((x as f64 * 0.09 + y as f64 * 0.05).sin());
            let disc =
                if (x as f64 - w as f64 * 0.7).hypot(y as f64 - h as f64 * 0.4) < h as f64 * 0.2 {
                    0.3
                } else {
                    0.0
                };
            v.push(((ramp + wave + disc).clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    Image::gray8(w, h, v)
}

#[test]
fn same_bytes_for_one_and_two_threads() {
    let img = photo_like(301, 97);
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    for &name in KERNELS.iter() {
        for serpentine in [false, true] {
            for levels in [2, 3] {
                let m = diffuse(
                    name,
                    DiffuseOptions {
                        serpentine,
                        levels,
                        seed: 7,
                        ..Default::default()
                    },
                );
                let one = pool(1).install(|| run(&m, &img));
                for threads in [2, 3] {
                    let many = pool(threads).install(|| run(&m, &img));
                    assert!(
                        one == many,
                        "{name} serpentine {serpentine} levels {levels}: {threads} threads differ"
                    );
                }
            }
        }
    }
}

#[test]
fn rgb_planes_are_diffused_on_their_own() {
    // Three different planes (the photo-like field, turned and inverted): each output
    // plane is that plane halftoned alone as grey, so no error crosses between channels.
    let (w, h) = (120, 40);
    let base = photo_like(w, h);
    let halftone::raster::Samples::U8(p0) = &base.planes[0] else {
        panic!("8-bit planes expected")
    };
    let p1: Vec<u8> = p0.iter().rev().copied().collect();
    let p2: Vec<u8> = p0.iter().map(|&v| 255 - v / 2).collect();
    let planes = [p0.clone(), p1, p2];
    let rgb_img = Image {
        color: halftone::raster::ColorKind::Rgb,
        planes: planes
            .iter()
            .map(|p| halftone::raster::Samples::U8(p.clone()))
            .collect(),
        ..Image::gray8(w, h, p0.clone())
    };
    let tone = ToneOptions::default();
    for name in ["floyd-steinberg", "ostromoukhov", "zhou-fang"] {
        let m = diffuse(name, DiffuseOptions::default());
        let rgb = halftone::halftone_image(&rgb_img, &m, halftone::ColorMode::Rgb, &tone).unwrap();
        assert_eq!(rgb.channels(), 3);
        for (c, p) in planes.iter().enumerate() {
            let alone = run(&m, &Image::gray8(w, h, p.clone()));
            assert_eq!(rgb.planes[c], alone.planes[0], "{name}: plane {c}");
        }
        assert_ne!(rgb.planes[0], rgb.planes[1], "{name}: the planes differ");
    }
}

#[test]
fn zhou_fang_seed_changes_the_noise_only() {
    let img = photo_like(200, 60);
    let a = run(
        &diffuse(
            "zhou-fang",
            DiffuseOptions {
                seed: 1,
                ..Default::default()
            },
        ),
        &img,
    );
    let b = run(
        &diffuse(
            "zhou-fang",
            DiffuseOptions {
                seed: 2,
                ..Default::default()
            },
        ),
        &img,
    );
    let a2 = run(
        &diffuse(
            "zhou-fang",
            DiffuseOptions {
                seed: 1,
                ..Default::default()
            },
        ),
        &img,
    );
    assert_eq!(a, a2);
    assert_ne!(a, b);
}

#[test]
fn strength_zero_is_a_plain_threshold() {
    let img = photo_like(100, 30);
    let m = diffuse(
        "jarvis-judice-ninke",
        DiffuseOptions {
            strength: 0.0,
            ..Default::default()
        },
    );
    let h = run(&m, &img);
    let table = img.tone_table(&ToneOptions::default());
    let p = img.planes(&table);
    for y in 0..30 {
        for x in 0..100 {
            assert_eq!(h.get(0, x, y), (p.planes[0].value(x, y) >= 0.5) as u8);
        }
    }
}

#[test]
fn user_kernel_file_equals_the_builtin() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fs.kernel");
    std::fs::write(&path, "# Floyd-Steinberg by hand\n- X 7\n3 5 1\n/ 16\n").unwrap();
    let img = photo_like(90, 50);
    let mine = run(
        &diffuse(path.to_str().unwrap(), DiffuseOptions::default()),
        &img,
    );
    let builtin = run(&diffuse("floyd-steinberg", DiffuseOptions::default()), &img);
    assert_eq!(mine, builtin);
}

#[test]
fn bad_options_and_files_are_errors() {
    let bad = |k: &str, o: DiffuseOptions| Diffuse::new(k, o).unwrap_err().to_string();
    assert!(bad("no-such-kernel", DiffuseOptions::default()).starts_with("no-such-kernel"));
    let e = bad(
        "floyd-steinberg",
        DiffuseOptions {
            strength: 1.5,
            ..Default::default()
        },
    );
    assert!(e.contains("strength 1.5"), "{e}");
    let e = bad(
        "floyd-steinberg",
        DiffuseOptions {
            levels: 1,
            ..Default::default()
        },
    );
    assert!(e.contains("levels 1"), "{e}");
}

/// Writes a few outputs as PNGs for a look: `cargo test --release -- --ignored look`.
#[test]
#[ignore = "writes PNGs to /tmp for a look by eye; asserts nothing"]
fn look() {
    let ramp = Image::gray8(
        512,
        64,
        (0..64)
            .flat_map(|_| (0..512).map(|x| (x / 2) as u8))
            .collect(),
    );
    let photo = photo_like(512, 256);
    for &name in KERNELS.iter() {
        for (tag, img, levels) in [
            ("ramp", &ramp, 2),
            ("photo", &photo, 2),
            ("ramp4", &ramp, 4),
        ] {
            let opts = DiffuseOptions {
                levels,
                ..Default::default()
            };
            let h = run(&diffuse(name, opts), img);
            let px: Vec<u8> = h
                .levels_of(0)
                .iter()
                .map(|&l| (l as u32 * 255 / (levels as u32 - 1)) as u8)
                .collect();
            image::GrayImage::from_raw(h.width as u32, h.height as u32, px)
                .unwrap()
                .save(format!("/tmp/diffuse-{tag}-{name}.png"))
                .unwrap();
        }
    }
}

/// Throughput on a 24-megapixel grey plane, one and two threads (the second thread only
/// helps raster scans, as a wavefront):
/// `cargo test --release --test it diffusion -- --ignored --nocapture throughput`.
#[test]
#[ignore = "a timing for docs/speed.md; needs a quiet machine"]
fn throughput_24mp() {
    let (w, h) = (6000, 4000);
    let img = photo_like(w, h);
    let table = img.tone_table(&ToneOptions::default());
    let planes = img.planes(&table);
    for name in [
        "floyd-steinberg",
        "jarvis-judice-ninke",
        "ostromoukhov",
        "riemersma",
    ] {
        for (serpentine, threads) in [(true, 1), (false, 1), (false, 2)] {
            let m = diffuse(
                name,
                DiffuseOptions {
                    serpentine,
                    ..Default::default()
                },
            );
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut best = f64::INFINITY;
            for _ in 0..3 {
                let t = std::time::Instant::now();
                let out = pool.install(|| m.halftone(&planes).unwrap());
                best = best.min(t.elapsed().as_secs_f64());
                std::hint::black_box(out);
            }
            eprintln!(
                "{name:>20} serpentine {serpentine:5} threads {threads}: {best:.3} s, {:.0} Mpx/s",
                (w * h) as f64 / best / 1e6
            );
        }
    }
}

#[test]
fn example_kernel_files_load() {
    let k =
        halftone::method::diffusion::Kernel::load("kernels/false-floyd-steinberg.kernel").unwrap();
    assert_eq!((k.weight_sum(), k.divisor, k.rows_below()), (8, 8, 1));
}

#[test]
fn tiny_images_and_thread_counts() {
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    for (w, h) in [(1, 1), (1, 6), (6, 1), (2, 3), (5, 5)] {
        let img = Image::gray8(w, h, (0..w * h).map(|i| (i * 37 % 256) as u8).collect());
        for &name in KERNELS.iter() {
            for serpentine in [false, true] {
                let m = diffuse(
                    name,
                    DiffuseOptions {
                        serpentine,
                        ..Default::default()
                    },
                );
                let one = pool(1).install(|| run(&m, &img));
                let two = pool(2).install(|| run(&m, &img));
                assert_eq!(one, two, "{name} {w}x{h}");
                assert_eq!((one.width, one.height), (w, h));
            }
        }
    }
}

#[test]
fn sixteen_bit_input_keeps_tone() {
    use halftone::raster::{ColorKind, Samples};
    let (w, h) = (128, 256);
    for code in [300u16, 9000, 32768, 60000] {
        let img = Image {
            width: w,
            height: h,
            color: ColorKind::Gray,
            planes: vec![Samples::U16(vec![code; w * h])],
            encoding: halftone::tone::Encoding::Srgb,
            dpi: None,
        };
        let table = img.tone_table(&ToneOptions::default());
        let want = table.as_slice()[code as usize] as f64;
        for name in ["floyd-steinberg", "ostromoukhov", "stucki"] {
            let out = run(&diffuse(name, DiffuseOptions::default()), &img);
            let mut sum = 0.0;
            for y in MEASURED_Y {
                for x in MEASURED_X {
                    sum += out.reflectance(out.get(0, x, y));
                }
            }
            let got = sum / (MEASURED_X.len() * MEASURED_Y.len()) as f64;
            assert!(
                (got - want).abs() < 0.004,
                "{name} code {code}: {got} vs {want}"
            );
        }
    }
}
