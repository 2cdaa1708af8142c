//! AM screens, CMYK plates, press separation and calibration (issue 11). Every figure is
//! measured from the output: the screen's frequency and angle from the 2-D spectrum of a
//! flat patch, tone from ink coverage, colour through the press model.
//!
//! Heavy parts (press tables) are meant for `cargo test --release`.

use std::path::Path;
use std::process::Command;

use halftone::mask::screen::{measure, Screen, ScreenSpec, Spot};
use halftone::method::screen::ScreenMethod;
use halftone::method::transfer::WithTransfer;
use halftone::press::separation::{separate_lab, Separation, SeparationOptions};
use halftone::press::transfer::Transfer;
use halftone::press::{delta_e76, srgb8_to_lab, Press, COLORCHECKER};
use halftone::raster::{PlaneRef, Planes, SamplesRef};
use halftone::tone::srgb_to_linear;
use halftone::Method;

fn screen(dpi: f64, lpi: f64, angle: f64, spot: Spot) -> Screen {
    Screen::new(ScreenSpec {
        dpi,
        lpi,
        angle,
        spot,
    })
    .unwrap()
}

/// Levels (0 = ink) of a flat patch of linear reflectance `v` through `m`.
fn flat(m: &dyn Method, v: f64, w: usize, h: usize) -> Vec<u8> {
    let code = (v * 65535.0).round() as u16;
    let samples = vec![code; w * h];
    let tone: Vec<f32> = (0..=65535u32).map(|c| c as f32 / 65535.0).collect();
    let planes = Planes {
        width: w,
        height: h,
        planes: vec![PlaneRef {
            width: w,
            height: h,
            samples: SamplesRef::U16(&samples),
            tone: &tone,
        }],
    };
    m.halftone(&planes).unwrap().levels_of(0)
}

fn coverage(levels: &[u8]) -> f64 {
    levels.iter().filter(|&&l| l == 0).count() as f64 / levels.len() as f64
}

fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(90.0);
    d.min(90.0 - d)
}

#[test]
fn geometry_is_the_requested_one() {
    let cases = [
        (600.0, 106.0, 0.0),
        (600.0, 106.0, 15.0),
        (600.0, 106.0, 45.0),
        (600.0, 106.0, 75.0),
        (1200.0, 150.0, 15.0),
        (300.0, 60.0, 45.0),
        (600.0, 133.0, 37.5),
        (2400.0, 175.0, 22.5),
    ];
    for (dpi, lpi, angle) in cases {
        let m = ScreenMethod::new(screen(dpi, lpi, angle, Spot::Round), 2).unwrap();
        let n = 512;
        let levels = flat(&m, 0.5, n, n);
        let got = measure(&levels, n, n);
        let got_lpi = dpi / got.period;
        eprintln!(
            "{dpi}/{lpi}/{angle}: measured {got_lpi:.3} lpi at {:.3}°",
            got.angle
        );
        assert!(
            (got_lpi / lpi - 1.0).abs() < 0.005,
            "{dpi}/{lpi}/{angle}: measured {got_lpi} lpi"
        );
        assert!(
            angle_diff(got.angle, angle) < 0.1,
            "{dpi}/{lpi}/{angle}: measured {}°",
            got.angle
        );
    }
}

/// The windowed discrete Fourier sum of the `n × n` levels (rows downwards, mean removed,
/// a Hann window both ways) at (`fx`, `fy`) cycles per `n` pixels, any real frequency: its
/// power, and that power as a share of all the windowed signal's (Parseval: the powers at
/// the `n²` whole frequencies add up to `n²` times the signal's energy). Written out here,
/// apart from the library's `measure`, as the reference for it.
fn fourier_power(levels: &[u8], n: usize, fx: f64, fy: f64) -> (f64, f64) {
    use std::f64::consts::PI;
    let hann: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * (i as f64 + 0.5) / n as f64).cos())
        .collect();
    let mean = levels.iter().map(|&v| v as f64).sum::<f64>() / (n * n) as f64;
    let turn = |f: f64| -> Vec<(f64, f64)> {
        (0..n)
            .map(|k| {
                let a = -2.0 * PI * f * k as f64 / n as f64;
                (a.cos(), a.sin())
            })
            .collect()
    };
    let (tx, ty) = (turn(fx), turn(fy));
    let (mut re, mut im, mut energy) = (0.0, 0.0, 0.0);
    for y in 0..n {
        let (mut rr, mut ri) = (0.0, 0.0);
        for x in 0..n {
            let v = (levels[y * n + x] as f64 - mean) * hann[x] * hann[y];
            energy += v * v;
            rr += v * tx[x].0;
            ri += v * tx[x].1;
        }
        re += rr * ty[y].0 - ri * ty[y].1;
        im += rr * ty[y].1 + ri * ty[y].0;
    }
    let power = re * re + im * im;
    (power, power / ((n * n) as f64 * energy))
}

/// The screen's geometry from the Fourier sum alone: at the requested frequency and
/// angle the power is a strong peak (a large share of all power; above the frequencies
/// 1% nearer and farther and 0.2° either side, so the true peak is within the 0.5% and
/// 0.1° that `geometry_is_the_requested_one` allows `measure`; above half and twice the
/// frequency and the lattice's diagonal).
#[test]
fn geometry_by_a_plain_fourier_sum() {
    let cases = [
        (600.0, 106.0, 0.0),
        (600.0, 106.0, 15.0),
        (600.0, 106.0, 45.0),
        (600.0, 106.0, 75.0),
        (1200.0, 150.0, 15.0),
        (300.0, 60.0, 45.0),
        (600.0, 133.0, 37.5),
        (2400.0, 175.0, 22.5),
    ];
    for (dpi, lpi, angle) in cases {
        let m = ScreenMethod::new(screen(dpi, lpi, angle, Spot::Round), 2).unwrap();
        let n = 512;
        let levels = flat(&m, 0.5, n, n);
        // Counter-clockwise with y up is clockwise in rows counted downwards.
        let r = n as f64 * lpi / dpi;
        let at = |scale: f64, turn: f64| {
            let a = (angle + turn).to_radians();
            fourier_power(&levels, n, scale * r * a.cos(), -scale * r * a.sin())
        };
        let (p0, share) = at(1.0, 0.0);
        eprintln!(
            "{dpi}/{lpi}/{angle}: {:.1}% of the power at the requested frequency",
            100.0 * share
        );
        assert!(share > 0.05, "{dpi}/{lpi}/{angle}: {share}");
        for (scale, turn, what) in [
            (1.01, 0.0, "1% finer"),
            (0.99, 0.0, "1% coarser"),
            (1.0, 0.2, "0.2° counter-clockwise"),
            (1.0, -0.2, "0.2° clockwise"),
            (0.5, 0.0, "half the frequency"),
            (2.0, 0.0, "twice the frequency"),
            (2f64.sqrt(), 45.0, "the diagonal"),
        ] {
            let (p, _) = at(scale, turn);
            assert!(
                p < p0,
                "{dpi}/{lpi}/{angle}: {what} has more power ({p:e} against {p0:e})"
            );
        }
    }
}

#[test]
fn tone_is_one_minus_reflectance_at_49_greys() {
    let m = ScreenMethod::new(screen(600.0, 106.0, 45.0, Spot::Round), 2).unwrap();
    let mut worst = 0.0f64;
    for k in 0..49 {
        // 8-bit sRGB codes spread over the range, through the sRGB decoding.
        let code = ((k as f64) * 255.0 / 48.0).round();
        let v = srgb_to_linear(code / 255.0);
        let c = coverage(&flat(&m, v, 256, 256));
        worst = worst.max((c - (1.0 - v)).abs());
    }
    eprintln!("600/106/45: worst tone error over 49 greys {worst:.5}");
    assert!(worst <= 0.003, "worst tone error {worst}");
}

#[test]
fn a_33_pixel_cell_gives_over_200_monotone_tones() {
    let m = ScreenMethod::new(screen(600.0, 106.0, 45.0, Spot::Round), 2).unwrap();
    let n = 128;
    let tone: Vec<f32> = (0..256)
        .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
        .collect();
    let mut inked = Vec::new();
    for code in 0..=255u8 {
        let samples = vec![code; n * n];
        let planes = Planes {
            width: n,
            height: n,
            planes: vec![PlaneRef {
                width: n,
                height: n,
                samples: SamplesRef::U8(&samples),
                tone: &tone,
            }],
        };
        let l = m.halftone(&planes).unwrap().levels_of(0);
        inked.push(l.iter().filter(|&&v| v == 0).count());
    }
    assert!(
        inked.windows(2).all(|w| w[1] <= w[0]),
        "ink must fall as the code rises"
    );
    let mut distinct = inked.clone();
    distinct.dedup();
    eprintln!(
        "600/106/45: {} distinct tones over 256 codes",
        distinct.len()
    );
    assert!(
        distinct.len() >= 200,
        "{} distinct tones over 256 codes",
        distinct.len()
    );
    assert_eq!(inked[0], n * n);
    assert_eq!(inked[255], 0);
}

#[test]
fn every_spot_function_renders_50_percent() {
    for spot in Spot::ALL {
        let m = ScreenMethod::new(screen(600.0, 85.0, 30.0, spot), 2).unwrap();
        let c = coverage(&flat(&m, 0.5, 256, 256));
        eprintln!("{}: 50% patch covers {c:.4}", spot.name());
        assert!((c - 0.5).abs() <= 0.01, "{}: {c}", spot.name());
    }
}

#[test]
fn transfer_coverage_is_the_inverse_of_the_wedge() {
    let wedge = "# nominal %, measured %\n0,0\n10,16\n25,37\n50,66\n75,88\n90,96\n100,100\n";
    let t = Transfer::parse(wedge, Path::new("wedge.csv")).unwrap();
    let m = WithTransfer {
        inner: Box::new(ScreenMethod::new(screen(600.0, 106.0, 45.0, Spot::Round), 2).unwrap()),
        transfer: t.clone(),
    };
    for target in [0.05, 0.2, 0.37, 0.5, 0.66, 0.8, 0.95] {
        let c = coverage(&flat(&m, 1.0 - target, 256, 256));
        let want = t.compensate(0, target);
        eprintln!("transfer: target {target}, inverse {want:.4}, plate coverage {c:.4}");
        // The compensated plate prints the target through the measured response.
        assert!((t.response(0, want) - target).abs() < 1e-6);
        assert!(
            (c - want).abs() <= 0.01,
            "target {target}: plate {c}, inverse {want}"
        );
        if target == 0.37 {
            // A wedge point: the inverse is its nominal value.
            assert!((want - 0.25).abs() < 1e-6);
        }
    }
}

#[test]
fn gcr_and_ink_limit() {
    let press = Press::load("fogra39").unwrap();
    let grey = srgb8_to_lab([128, 128, 128]);
    let full = separate_lab(&press, grey, &SeparationOptions { gcr: 1.0, tac: 3.0 });
    assert!(full[..3].iter().all(|&v| v < 0.01), "gcr 100: {full:?}");
    assert!(full[3] > 0.3, "gcr 100: {full:?}");
    let none = separate_lab(&press, grey, &SeparationOptions { gcr: 0.0, tac: 3.0 });
    assert_eq!(none[3], 0.0);
    assert!(none[..3].iter().all(|&v| v > 0.2), "gcr 0: {none:?}");
    assert!(delta_e76(press.lab(full), grey) < 1.0);
    assert!(delta_e76(press.lab(none), grey) < 1.0);
    // A deep violet under a 240% limit, through the table.
    let sep = Separation::model(&press, SeparationOptions { gcr: 0.0, tac: 2.4 });
    for violet in [[48u8, 0, 96], [40, 10, 70], [30, 0, 60]] {
        let c = sep.cmyk(violet);
        let total: f64 = c.iter().sum();
        assert!(total <= 2.4 + 1e-6, "{violet:?}: {c:?} = {total}");
    }
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_halftone"))
}

/// Reads a 1-bit plate TIFF: (width, height, ink bits (1 = ink), x dpi, InkNames).
fn read_plate(path: &Path) -> (usize, usize, Vec<u8>, f64, String) {
    use tiff::decoder::{Decoder, DecodingResult};
    use tiff::tags::Tag;
    let mut d = Decoder::new(std::fs::File::open(path).unwrap()).unwrap();
    let (w, h) = d.dimensions().unwrap();
    let photometric = d.get_tag_u32(Tag::PhotometricInterpretation).unwrap();
    assert_eq!(photometric, 0, "WhiteIsZero: 1 = ink");
    let xres = match d.get_tag(Tag::XResolution).unwrap() {
        tiff::decoder::ifd::Value::Rational(n, d) => n as f64 / d as f64,
        v => panic!("XResolution {v:?}"),
    };
    let ink = d.get_tag_ascii_string(Tag::Unknown(333)).unwrap();
    let DecodingResult::U8(packed) = d.read_image().unwrap() else {
        panic!("8-bit buffer expected for 1-bit data");
    };
    let (w, h) = (w as usize, h as usize);
    let stride = w.div_ceil(8);
    let mut bits = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            // The tiff crate hands WhiteIsZero data back normalised to 0 = black (checked
            // against netpbm's tifftopnm): 0 is ink here.
            bits[y * w + x] = 1 - ((packed[y * stride + x / 8] >> (7 - x % 8)) & 1);
        }
    }
    (w, h, bits, xres, ink.trim_end_matches('\0').to_string())
}

#[test]
fn plates_have_names_dpi_and_angles() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("grey.png");
    image::GrayImage::from_pixel(512, 512, image::Luma([100]))
        .save(&input)
        .unwrap();
    let out = dir.path().join("poster.tif");
    let st = bin()
        .args(["convert"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args([
            "--method",
            "screen",
            "--color",
            "cmyk",
            "--separation",
            "naive",
            "--gcr",
            "50",
            "--dpi",
            "600",
            "--lpi",
            "106",
        ])
        .status()
        .unwrap();
    assert!(st.success());
    assert!(!out.exists(), "plates only, no composite");
    for (ink, name, angle) in [
        ("cyan", "Cyan", 15.0),
        ("magenta", "Magenta", 75.0),
        ("yellow", "Yellow", 0.0),
        ("black", "Black", 45.0),
    ] {
        let p = dir.path().join(format!("poster-{ink}.tif"));
        let (w, h, bits, dpi, inkname) = read_plate(&p);
        assert_eq!((w, h), (512, 512));
        assert_eq!(dpi, 600.0);
        assert_eq!(inkname, name);
        let m = measure(&bits, w, h);
        assert!(
            (600.0 / m.period / 106.0 - 1.0).abs() < 0.005,
            "{ink}: {} lpi",
            600.0 / m.period
        );
        assert!(angle_diff(m.angle, angle) < 0.1, "{ink}: {}°", m.angle);
        // Naive, 50% GCR on code 100: C = M = Y = K ≈ 0.304.
        let cov = bits.iter().map(|&b| b as f64).sum::<f64>() / bits.len() as f64;
        let want = 0.5 * (1.0 - 100.0 / 255.0);
        assert!((cov - want).abs() < 0.005, "{ink}: coverage {cov}");
    }
}

/// Mean coverage of a plate over a square patch interior.
fn patch_cov(bits: &[u8], w: usize, x0: usize, y0: usize, side: usize) -> f64 {
    let mut s = 0.0;
    for y in y0..y0 + side {
        for x in x0..x0 + side {
            s += bits[y * w + x] as f64;
        }
    }
    s / (side * side) as f64
}

#[test]
fn colorchecker_through_the_fogra39_model() {
    let press = Press::load("fogra39").unwrap();
    // In gamut: the press can print the colour (exact inversion within 1 ΔE).
    let opts = SeparationOptions::default();
    let in_gamut: Vec<usize> = (0..24)
        .filter(|&i| {
            let lab = srgb8_to_lab(COLORCHECKER[i]);
            delta_e76(press.lab(separate_lab(&press, lab, &opts)), lab) < 1.0
        })
        .collect();
    assert!(in_gamut.len() >= 18, "in gamut: {in_gamut:?}");
    // A 6×4 chart, 96-pixel patches at 600 dpi.
    let p = 96;
    let (w, h) = (6 * p, 4 * p);
    let mut img = image::RgbImage::new(w as u32, h as u32);
    for (x, y, px) in img.enumerate_pixels_mut() {
        let i = (y as usize / p) * 6 + x as usize / p;
        *px = image::Rgb(COLORCHECKER[i]);
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("chart.png");
    img.save(&input).unwrap();
    let mut mean = [0.0; 2];
    for (s, sep) in ["model", "naive"].iter().enumerate() {
        let out = dir.path().join(format!("{sep}.tif"));
        let preview = dir.path().join(format!("{sep}-preview.png"));
        let st = bin()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["--method", "screen", "--color", "cmyk", "--dpi", "600"])
            .args(["--lpi", "106", "--separation", sep, "--preview"])
            .arg(&preview)
            .status()
            .unwrap();
        assert!(st.success());
        let plates: Vec<Vec<u8>> = ["cyan", "magenta", "yellow", "black"]
            .iter()
            .map(|ink| read_plate(&dir.path().join(format!("{sep}-{ink}.tif"))).2)
            .collect();
        let prev = image::open(&preview).unwrap().to_rgb8();
        let block = (
            prev.width() as f64 / w as f64,
            prev.height() as f64 / h as f64,
        );
        let mut sum = 0.0;
        let mut sum_preview = 0.0;
        for &i in &in_gamut {
            let (x0, y0) = ((i % 6) * p + 16, (i / 6) * p + 16);
            let cmyk = [0, 1, 2, 3].map(|k| patch_cov(&plates[k], w, x0, y0, p - 32));
            let want = srgb8_to_lab(COLORCHECKER[i]);
            sum += delta_e76(press.lab(cmyk), want);
            let c = prev.get_pixel(
                (((i % 6) * p + p / 2) as f64 * block.0) as u32,
                (((i / 6) * p + p / 2) as f64 * block.1) as u32,
            );
            sum_preview += delta_e76(srgb8_to_lab(c.0), want);
        }
        mean[s] = sum / in_gamut.len() as f64;
        let mean_preview = sum_preview / in_gamut.len() as f64;
        eprintln!(
            "{sep}: {} in-gamut ColorChecker colours, mean ΔE76 {:.2}, preview {:.2}",
            in_gamut.len(),
            mean[s],
            mean_preview
        );
        if s == 0 {
            assert!(mean[0] <= 2.5, "model separation: mean ΔE76 {}", mean[0]);
            assert!(mean_preview <= 4.0, "preview: mean ΔE76 {mean_preview}");
        }
    }
    assert!(
        mean[1] > 2.0 * mean[0],
        "naive {} vs model {}",
        mean[1],
        mean[0]
    );
}

#[test]
fn unknown_spot_lists_the_names() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("g.png");
    image::GrayImage::from_pixel(8, 8, image::Luma([100]))
        .save(&input)
        .unwrap();
    let out = bin()
        .arg("convert")
        .arg(&input)
        .args(["-o", "-", "--format", "pbm", "--method", "screen"])
        .args(["--spot", "roundish"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("roundish") && err.contains("InvertedEllipseC"),
        "{err}"
    );
    assert!(out.stdout.is_empty());
}

#[test]
fn patterns_screen_reports_geometry_and_writes_a_mask() {
    let dir = tempfile::tempdir().unwrap();
    let mask = dir.path().join("screen.txt");
    let out = bin()
        .args(["patterns", "--screen", "--dpi", "600", "--lpi", "100"])
        .args(["--angle", "0", "--spot", "round", "-o"])
        .arg(&mask)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    // 600/100 at 0°: a 6-pixel cell; with 16×16 staggered cells the repeat is 96×96.
    assert!(text.contains("repeat on the pixel grid: 96x96"), "{text}");
    assert!(text.contains("pixels a cell: 36.000"), "{text}");
    // The mask tiles into the same screen through --method ordered.
    let input = dir.path().join("g.png");
    image::GrayImage::from_pixel(192, 192, image::Luma([128]))
        .save(&input)
        .unwrap();
    let a = dir.path().join("a.pbm");
    let b = dir.path().join("b.pbm");
    let run = |args: &[&str], o: &Path| {
        let st = bin()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(o)
            .args(args)
            .status()
            .unwrap();
        assert!(st.success());
    };
    run(
        &["--method", "ordered", "--mask", mask.to_str().unwrap()],
        &a,
    );
    run(
        &[
            "--method", "screen", "--dpi", "600", "--lpi", "100", "--angle", "0",
        ],
        &b,
    );
    let (ia, ib) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let diff = ia.iter().zip(&ib).filter(|(x, y)| x != y).count();
    assert!(diff * 100 < ia.len(), "{diff} of {} bytes differ", ia.len());
}
