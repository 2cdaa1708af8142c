//! Palettes: nearest colour in Oklab, independence from the palette's order, tone kept.

use halftone::color::{Palette, PaletteMatcher};
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::tone::srgb_to_linear;
use halftone::{ColorMode, Halftone, Image, ToneOptions};

/// A colourful test image: hue across, lightness down, a few flat patches.
fn colourful(w: usize, h: usize) -> Image {
    let mut px = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let hue = x as f64 / w as f64 * 6.0;
            let light = y as f64 / (h - 1) as f64;
            let f = |k: f64| {
                let t = ((hue + k) % 6.0 - 3.0).abs() - 1.0;
                t.clamp(0.0, 1.0)
            };
            let (r, g, b) = (f(0.0), f(4.0), f(2.0));
            let mix = |c: f64| {
                if light < 0.5 {
                    c * light * 2.0
                } else {
                    c + (1.0 - c) * (light - 0.5) * 2.0
                }
            };
            px.extend([mix(r), mix(g), mix(b)].map(|c| (c * 255.0).round() as u8));
        }
    }
    Image::rgb8(w, h, &px)
}

fn dither(img: &Image, palette: Palette, kernel: &str) -> Halftone {
    let m = Diffuse::new(kernel, DiffuseOptions::default())
        .unwrap()
        .with_palette(palette);
    halftone::halftone_image(img, &m, ColorMode::Rgb, &ToneOptions::default()).unwrap()
}

/// The output as colours, whatever the indices.
fn colours_of(h: &Halftone) -> Vec<[u8; 3]> {
    let pal = h.palette.as_ref().unwrap();
    h.levels_of(0).iter().map(|&i| pal[i as usize]).collect()
}

#[test]
fn result_does_not_depend_on_palette_order() {
    let img = colourful(160, 90);
    for name in ["epaper-7", "rgb-8", "pico-8", "eink-4"] {
        let p = Palette::builtin(name).unwrap();
        let mut reversed = p.clone();
        reversed.colours.reverse();
        let mut rotated = p.clone();
        rotated.colours.rotate_left(3);
        for kernel in ["floyd-steinberg", "ostromoukhov", "sierra"] {
            let a = dither(&img, p.clone(), kernel);
            assert_eq!(a.levels as usize, p.len());
            assert_eq!(a.palette.as_ref().unwrap(), &p.colours);
            for q in [&reversed, &rotated] {
                let b = dither(&img, q.clone(), kernel);
                assert_eq!(colours_of(&a), colours_of(&b), "{name} {kernel}");
            }
        }
    }
}

#[test]
fn equal_distances_break_by_colour_value() {
    // Duplicates: the same colour twice gives the earlier index.
    let p = Palette::new("dup", vec![[255, 255, 255], [0, 0, 0], [0, 0, 0]]).unwrap();
    let m = PaletteMatcher::new(&p);
    assert_eq!(m.nearest([0.01, 0.01, 0.01]), 1);
    // Different colours at exactly the same distance: a grey between black and white where
    // the two f32 distances are equal (found by bisection, then a walk over neighbouring
    // f32 values): the smaller colour value, black, wins although white comes first.
    let dist = |probe: f32, c: [f32; 3]| {
        let p = halftone::color::oklab_of_linear([probe; 3]);
        let q = halftone::color::oklab_of_linear(c);
        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)
    };
    let gap = |t: f32| dist(t, [0.0; 3]) - dist(t, [1.0; 3]);
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) < 0.0 {
            lo = mid
        } else {
            hi = mid
        }
    }
    let tie = (0..4000u32)
        .flat_map(|k| [lo.to_bits() - 2000 + k])
        .map(f32::from_bits)
        .find(|&t| gap(t) == 0.0)
        .expect("an exact tie near the crossing");
    let p = Palette::new("bw", vec![[255, 255, 255], [0, 0, 0]]).unwrap();
    let m = PaletteMatcher::new(&p);
    assert_eq!(m.nearest([tie; 3]), 1, "tie at {tie}");
}

#[test]
fn nearest_is_chosen_in_oklab_not_srgb() {
    // sRGB (100, 100, 100) is nearer black in code values (100 < 155) and in linear light
    // (0.127 < 0.873), but its Oklab lightness 0.503 is nearer white's 1.0 than black's 0.
    let bw = Palette::builtin("bw").unwrap();
    let m = PaletteMatcher::new(&bw);
    let lin = srgb_to_linear(100.0 / 255.0) as f32;
    assert_eq!(bw.colours[m.nearest([lin; 3])], [255, 255, 255]);
    let lin = srgb_to_linear(98.0 / 255.0) as f32;
    assert_eq!(bw.colours[m.nearest([lin; 3])], [0, 0, 0]);
}

#[test]
fn flat_colours_keep_their_mean_in_linear_light() {
    // Colours inside the palette's gamut come out with the right mean in linear light.
    let cases: [(&str, [u8; 3]); 5] = [
        ("rgb-8", [128, 128, 128]),
        ("rgb-8", [200, 90, 30]),
        ("bw", [60, 60, 60]),
        ("bw", [200, 200, 200]),
        ("eink-4", [100, 100, 100]),
    ];
    for (name, c) in cases {
        let (w, h) = (128, 160);
        let img = Image::rgb8(w, h, &c.repeat(w * h));
        let out = dither(&img, Palette::builtin(name).unwrap(), "floyd-steinberg");
        let cols = colours_of(&out);
        let mut mean = [0f64; 3];
        let mut n = 0;
        for y in 40..150 {
            for x in 16..112 {
                let q = cols[y * w + x];
                for k in 0..3 {
                    mean[k] += srgb_to_linear(q[k] as f64 / 255.0);
                }
                n += 1;
            }
        }
        for k in 0..3 {
            let want = srgb_to_linear(c[k] as f64 / 255.0);
            let got = mean[k] / n as f64;
            assert!(
                (got - want).abs() < 0.004,
                "{name} {c:?} channel {k}: {got:.4} vs {want:.4}"
            );
        }
    }
}

#[test]
fn palette_files_load_and_errors_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("two.gpl");
    std::fs::write(
        &good,
        "GIMP Palette\nName: two\n0 0 0 black\n255 255 255 white\n",
    )
    .unwrap();
    let p = Palette::load(good.to_str().unwrap()).unwrap();
    assert_eq!(p.colours, vec![[0, 0, 0], [255, 255, 255]]);
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "#000000\n#fffffff\n").unwrap();
    let e = Palette::load(bad.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.txt:2:"), "{e}");
    let e = Palette::load("no-such-palette").unwrap_err().to_string();
    assert!(e.starts_with("no-such-palette"), "{e}");
}

/// Writes palette outputs as PNGs for a look: `cargo test --release -- --ignored look`.
#[test]
#[ignore = "writes PNGs to /tmp for a look by eye; asserts nothing"]
fn look() {
    let img = colourful(384, 192);
    for name in Palette::builtin_names() {
        let out = dither(&img, Palette::builtin(name).unwrap(), "floyd-steinberg");
        let px: Vec<u8> = colours_of(&out).concat();
        image::RgbImage::from_raw(384, 192, px)
            .unwrap()
            .save(format!("/tmp/palette-{name}.png"))
            .unwrap();
    }
}

/// Throughput of palette diffusion on a 4-megapixel colour image:
/// `cargo test --release --test it palette -- --ignored --nocapture throughput`.
#[test]
#[ignore = "a timing; needs a quiet machine"]
fn throughput_4mp() {
    let img = colourful(2000, 2000);
    for name in ["bw", "epaper-7", "pico-8"] {
        let t = std::time::Instant::now();
        let out = dither(&img, Palette::builtin(name).unwrap(), "floyd-steinberg");
        let s = t.elapsed().as_secs_f64();
        std::hint::black_box(out);
        eprintln!("{name:>10}: {s:.3} s, {:.1} Mpx/s", 4.0 / s);
    }
}

/// The palette indices and the PLTE colours of an indexed PNG.
fn png_palette(path: &std::path::Path) -> (usize, usize, Vec<u8>, Vec<[u8; 3]>) {
    let mut dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut r = dec.read_info().unwrap();
    let info = r.info();
    assert_eq!(
        info.color_type,
        png::ColorType::Indexed,
        "{}",
        path.display()
    );
    let (w, h, bits) = (
        info.width as usize,
        info.height as usize,
        info.bit_depth as usize,
    );
    let plte: Vec<[u8; 3]> = info
        .palette
        .as_deref()
        .unwrap()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
    r.next_frame(&mut buf).unwrap();
    let stride = (w * bits).div_ceil(8);
    let mut idx = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let bit = x * bits;
            let byte = buf[y * stride + bit / 8];
            idx.push((byte >> (8 - bits - bit % 8)) & ((1u16 << bits) - 1) as u8);
        }
    }
    (w, h, idx, plte)
}

/// `--method ordered --palette epaper-7` and `--palette auto:8` (diffuse and ordered) run
/// through the binary: indexed PNGs with the palette they used, every index valid, the same
/// bytes on one thread and on three; `auto:N` out of range is a one-line error naming the
/// flag.
#[test]
fn ordered_and_automatic_palettes_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/raytrace.png");
    let run = |name: &str, args: &[&str], threads: &str| {
        let out = dir.path().join(format!("{name}-{threads}.png"));
        let r = crate::common::halftone()
            .env("RAYON_NUM_THREADS", threads)
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(args)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        out
    };
    let epaper = Palette::builtin("epaper-7").unwrap().colours;
    for (name, args) in [
        (
            "ordered-epaper",
            vec!["--method", "ordered", "--palette", "epaper-7"],
        ),
        (
            "ordered-epaper-cluster",
            vec![
                "--method",
                "ordered",
                "--palette",
                "epaper-7",
                "--mask",
                "cluster-8",
            ],
        ),
        ("diffuse-auto", vec!["--palette", "auto:8"]),
        (
            "ordered-auto",
            vec!["--method", "ordered", "--palette", "auto:8"],
        ),
    ] {
        let one = run(name, &args, "1");
        let three = run(name, &args, "3");
        assert_eq!(
            std::fs::read(&one).unwrap(),
            std::fs::read(&three).unwrap(),
            "{name}: thread count changed the bytes"
        );
        let (w, h, idx, plte) = png_palette(&one);
        assert_eq!((w, h), (320, 240), "{name}");
        if name.contains("epaper") {
            assert_eq!(plte, epaper, "{name}");
        } else {
            // The picture has far more than 8 colours: all 8 are made, distinct.
            assert_eq!(plte.len(), 8, "{name}: {plte:?}");
            let mut d = plte.clone();
            d.sort();
            d.dedup();
            assert_eq!(d.len(), 8, "{name}");
        }
        assert!(idx.iter().all(|&i| (i as usize) < plte.len()), "{name}");
        let used = (0..plte.len() as u8).filter(|i| idx.contains(i)).count();
        assert!(used >= 4, "{name}: {used} colours used");
    }
    for (args, want) in [
        (
            vec!["--palette", "auto:0"],
            "--palette auto:0: an automatic palette has 2 to 256 colours",
        ),
        (
            vec!["--palette", "auto:300"],
            "--palette auto:300: an automatic palette has 2 to 256",
        ),
        (
            vec!["--palette", "auto:x"],
            "--palette auto:x: `x` is not a number of colours",
        ),
        (
            vec!["--method", "dbs", "--palette", "auto:8"],
            "--palette auto:8: a palette made from the image works with methods diffuse and ordered",
        ),
    ] {
        let r = crate::common::halftone()
            .arg("convert")
            .arg(&input)
            .args(["-o", "-", "--format", "png"])
            .args(&args)
            .output()
            .unwrap();
        assert!(!r.status.success(), "{args:?}");
        let err = String::from_utf8(r.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    // The library's loader names the field.
    for spec in ["auto:0", "auto:x", "auto:300", "auto:8"] {
        let e = Palette::load(spec).unwrap_err();
        assert!(
            matches!(
                e,
                halftone::Error::Option {
                    field: "palette",
                    ..
                }
            ),
            "{spec}: {e}"
        );
    }
}

/// Timings for the report: a 24-megapixel auto:16 palette, and ordered dithering of an
/// 800x480 picture to epaper-7:
/// `cargo test --release --test it palette -- --ignored --nocapture timing`.
#[test]
#[ignore = "a timing; needs a quiet machine"]
fn timing_auto_and_ordered_palettes() {
    let img = colourful(6000, 4000);
    let px: Vec<[f32; 3]> = {
        let tone = img.tone_table(&ToneOptions::default());
        let planes = img.planes(&tone);
        (0..6000 * 4000)
            .map(|i| [0, 1, 2].map(|c| planes.planes[c].value(i % 6000, i / 6000)))
            .collect()
    };
    for n in [16, 256] {
        let t = std::time::Instant::now();
        let p = halftone::quantize::auto_palette(&px, n).unwrap();
        eprintln!(
            "auto_palette 24 MP auto:{n}: {:.3} s ({} colours)",
            t.elapsed().as_secs_f64(),
            p.len()
        );
    }
    let small = colourful(800, 480);
    let tone = small.tone_table(&ToneOptions::default());
    let planes = small.planes(&tone);
    let target: Vec<[f32; 3]> = (0..800 * 480)
        .map(|i| [0, 1, 2].map(|c| planes.planes[c].value(i % 800, i / 800)))
        .collect();
    let inks: Vec<[f32; 3]> = Palette::builtin("epaper-7")
        .unwrap()
        .colours
        .iter()
        .map(|c| c.map(|v| srgb_to_linear(v as f64 / 255.0) as f32))
        .collect();
    let mask = halftone::Mask::builtin("bayer-8").unwrap();
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let idx =
            halftone::method::ordered_palette::ordered_indices(&target, 800, 480, &inks, &mask);
        eprintln!(
            "ordered_indices 800x480 epaper-7 bayer-8: {:.4} s",
            t.elapsed().as_secs_f64()
        );
        std::hint::black_box(idx);
    }
}
