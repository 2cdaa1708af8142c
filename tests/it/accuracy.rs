//! Direct binary search, printer models, green noise and tone-dependent error diffusion.

use assert_cmd::Command;

use halftone::lab::train;
use halftone::method::dbs::{self, Dbs, DbsOptions};
use halftone::method::diffusion::hysteresis::Hysteresis;
use halftone::method::diffusion::tded;
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::printer_model::{overlap_areas, PrinterModel};
use halftone::quality::Viewing;
use halftone::{Image, Method, ToneOptions};

/// A deterministic pseudo-random byte stream (xorshift).
fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut s = seed | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 56) as u8
        })
        .collect()
}

/// A small "photo": smooth shading, an edge and some texture, 8-bit sRGB.
fn scene(w: usize, h: usize) -> Image {
    let tex = noise(w * h, 7);
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let base = 40.0 + 180.0 * (x / w as f32) * (0.5 + 0.5 * (y / 9.0).sin().abs());
            let edge = if (x - 0.6 * y) > 0.4 * w as f32 {
                30.0
            } else {
                0.0
            };
            (base + edge + (tex[i] as f32 - 128.0) * 0.1).clamp(0.0, 255.0) as u8
        })
        .collect();
    Image::gray8(w, h, data)
}

fn halftone_with(m: &dyn Method, img: &Image) -> halftone::Halftone {
    let tone = ToneOptions::default();
    let t = img.tone_table(&tone);
    m.halftone(&img.planes(&t)).unwrap()
}

#[test]
fn dot_overlap_model_matches_supersampled_discs() {
    let (w, h) = (20, 20);
    let ink: Vec<u8> = noise(w * h, 3).iter().map(|&b| (b < 110) as u8).collect();
    for rho in [1.0, 1.1, 1.25, 1.35, std::f64::consts::SQRT_2] {
        let model = PrinterModel::dot_overlap(rho).unwrap();
        let printed = model.print_ink(&ink, w, h);
        let r2 = (rho / std::f64::consts::SQRT_2).powi(2);
        let n = 40; // 40 × 40 samples a pixel
        let mut worst = 0f64;
        let (mut sum_model, mut sum_raster) = (0.0, 0.0);
        for y in 0..h {
            for x in 0..w {
                let mut covered = 0;
                for sy in 0..n {
                    for sx in 0..n {
                        let px = x as f64 + (sx as f64 + 0.5) / n as f64;
                        let py = y as f64 + (sy as f64 + 0.5) / n as f64;
                        let mut hit = false;
                        for dy in -2i64..=2 {
                            for dx in -2i64..=2 {
                                let (qx, qy) = (x as i64 + dx, y as i64 + dy);
                                if qx < 0 || qy < 0 || qx >= w as i64 || qy >= h as i64 {
                                    continue;
                                }
                                if ink[qy as usize * w + qx as usize] == 0 {
                                    continue;
                                }
                                let (cx, cy) = (qx as f64 + 0.5, qy as f64 + 0.5);
                                if (px - cx).powi(2) + (py - cy).powi(2) <= r2 {
                                    hit = true;
                                }
                            }
                        }
                        covered += hit as usize;
                    }
                }
                let raster = covered as f64 / (n * n) as f64;
                let modelled = 1.0 - printed[y * w + x] as f64;
                worst = worst.max((raster - modelled).abs());
                sum_model += modelled;
                sum_raster += raster;
            }
        }
        // A 40 × 40 grid misjudges a disc's edge by about its length / 40 of a sample.
        assert!(worst < 0.02, "rho {rho}: a pixel off by {worst}");
        let mean_diff = (sum_model - sum_raster).abs() / (w * h) as f64;
        assert!(mean_diff < 0.002, "rho {rho}: mean off by {mean_diff}");
    }
}

#[test]
fn compare_scores_a_checkerboard_at_the_pappas_neuhoff_tone() {
    let dir = tempfile::tempdir().unwrap();
    let n = 64;
    // A PBM checkerboard (1 = ink) and a 50% grey original.
    let mut pbm = format!("P4\n{n} {n}\n").into_bytes();
    for y in 0..n {
        for bx in 0..n / 8 {
            pbm.push(if y % 2 == 0 { 0b1010_1010 } else { 0b0101_0101 });
            let _ = bx;
        }
    }
    let ht = dir.path().join("checker.pbm");
    std::fs::write(&ht, pbm).unwrap();
    let mut pgm = format!("P5\n{n} {n}\n255\n").into_bytes();
    pgm.extend(std::iter::repeat_n(188u8, n * n));
    let orig = dir.path().join("grey.pgm");
    std::fs::write(&orig, pgm).unwrap();
    let out = Command::cargo_bin("halftone")
        .unwrap()
        .args(["compare", "--json", "--printer-model", "dot-overlap"])
        .args(["--dot-ratio", "1.25"])
        .arg(&orig)
        .arg(&ht)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let printed = v["printed_mean_reflectance"].as_f64().unwrap();
    // Pappas–Neuhoff: an inked pixel prints black; a blank one is covered f1·α − f3·γ by
    // its inked orthogonal neighbours (fewer at the page's edge).
    let (a, _, g) = overlap_areas(1.25);
    let mut ink = 0.0;
    for y in 0..n {
        for x in 0..n {
            if (x + y) % 2 == 0 {
                ink += 1.0;
                continue;
            }
            let [up, left, right, down] = [y > 0, x > 0, x + 1 < n, y + 1 < n];
            let f1 = [up, left, right, down].iter().filter(|&&b| b).count() as f64;
            let f3 = [up && right, right && down, down && left, left && up]
                .iter()
                .filter(|&&b| b)
                .count() as f64;
            ink += f1 * a - f3 * g;
        }
    }
    let expected = 1.0 - ink / (n * n) as f64;
    assert!(
        (printed - expected).abs() < 1e-4,
        "printed {printed}, expected {expected}"
    );
    // And the interior formula: (1 + 4α − 4γ)/2 ink.
    let m = PrinterModel::dot_overlap(1.25).unwrap();
    assert!((m.checkerboard_ink() - (1.0 + 4.0 * a - 4.0 * g) / 2.0).abs() < 1e-6);
}

#[test]
fn dbs_never_increases_the_objective() {
    let img = scene(72, 56);
    let tone = ToneOptions::default();
    let t = img.tone_table(&tone);
    let planes = img.planes(&t);
    let (w, h) = (img.width, img.height);
    let mut target = vec![0f32; w * h];
    for y in 0..h {
        planes.planes[0].row_linear(y, &mut target[y * w..(y + 1) * w]);
    }
    let fs = Diffuse::new("floyd-steinberg", DiffuseOptions::default())
        .unwrap()
        .halftone(&planes)
        .unwrap()
        .levels_of(0);
    let model = PrinterModel::dot_overlap(1.25).unwrap();
    for (levels, printer, radius) in [(2u16, None, 6), (3, None, 6), (2, Some(&model), 4)] {
        let cpp = dbs::cpp_table(&Viewing::default(), radius);
        let start: Vec<u8> = fs.iter().map(|&l| l * (levels as u8 - 1)).collect();
        let (_, trace) = dbs::search(
            &target, &start, w, h, levels, &cpp, radius, printer, 30, true,
        );
        assert!(trace.len() >= 3, "{trace:?}");
        for p in trace.windows(2) {
            assert!(
                p[1] <= p[0] + 1e-9 * p[0].abs(),
                "levels {levels}: objective rose {trace:?}"
            );
        }
        assert!(
            trace[trace.len() - 1] < 0.9 * trace[0],
            "levels {levels}: DBS should improve on its start: {trace:?}"
        );
    }
}

#[test]
fn dbs_is_the_same_bytes_on_one_and_two_threads() {
    // 150 × 140 is 3 × 3 tiles: every tile class runs more than one tile.
    let img = scene(150, 140);
    let model = PrinterModel::dot_overlap(1.25).unwrap();
    let methods = [
        Dbs::new(DbsOptions::default()).unwrap(),
        Dbs::new(DbsOptions {
            levels: 4,
            ..DbsOptions::default()
        })
        .unwrap(),
        Dbs::new(DbsOptions {
            printer: Some(model),
            radius: 4,
            ..DbsOptions::default()
        })
        .unwrap(),
    ];
    for m in &methods {
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| halftone_with(m, &img))
        };
        assert_eq!(run(1), run(2), "{}", m.name());
    }
}

#[test]
fn hysteresis_keeps_half_ink_and_prints_lighter_under_dot_gain() {
    // Code 188 is linear 0.503: half ink.
    let n = 128;
    let img = Image::gray8(n, n, vec![188; n * n]);
    let model = PrinterModel::dot_overlap(1.25).unwrap();
    let ink_share = |h: &halftone::Halftone| {
        h.levels_of(0).iter().filter(|&&l| l == 0).count() as f64 / (n * n) as f64
    };
    let printed_ink = |h: &halftone::Halftone| 1.0 - model.print_halftone(h).unwrap().mean();
    let green = Hysteresis::new("floyd-steinberg", DiffuseOptions::default(), 1.5).unwrap();
    let g = halftone_with(&green, &img);
    assert!((ink_share(&g) - 0.497).abs() < 0.01, "{}", ink_share(&g));
    assert!(printed_ink(&g) <= 0.72, "{}", printed_ink(&g));
    let fs = Diffuse::new("floyd-steinberg", DiffuseOptions::default()).unwrap();
    let f = halftone_with(&fs, &img);
    assert!(printed_ink(&f) > 0.9, "{}", printed_ink(&f));
    // H = 0 is plain error diffusion: the same ink share, the same dot gain.
    let plain = Hysteresis::new("floyd-steinberg", DiffuseOptions::default(), 0.0).unwrap();
    let p = halftone_with(&plain, &img);
    assert!((ink_share(&p) - ink_share(&f)).abs() < 0.005);
    assert!(printed_ink(&p) > 0.9);
}

/// Changes of level between horizontal neighbours over those between vertical ones: about 1
/// for clusters with no preferred direction, far from 1 for stripes.
fn run_anisotropy(levels: &[u8], n: usize) -> f64 {
    let mut h = 0usize;
    let mut v = 0usize;
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let l = levels[y * n + x];
            h += (l != levels[y * n + x + 1]) as usize;
            v += (l != levels[(y + 1) * n + x]) as usize;
        }
    }
    h as f64 / v as f64
}

#[test]
fn hysteresis_clusters_have_no_preferred_direction() {
    // Linear 0.503 and 0.250 (codes 188 and 137). Feedback shaped like Floyd–Steinberg's
    // weights drew horizontal stripes here (ratios 0.18 and 0.53).
    let n = 192;
    for code in [188u8, 137] {
        let img = Image::gray8(n, n, vec![code; n * n]);
        let green = Hysteresis::new("floyd-steinberg", DiffuseOptions::default(), 1.5).unwrap();
        let a = run_anisotropy(&halftone_with(&green, &img).levels_of(0), n);
        assert!((0.7..1.4).contains(&a), "code {code}: {a}");
    }
}

#[test]
fn tded_tables_regenerate_from_training() {
    let shipped = tded::parse_table(tded::TABLE_TEXT).unwrap();
    // The file names the training run it keeps; retrain that run's every row with the
    // shipped settings (each row starts from the one before), smooth, and compare. (Choosing
    // the run needs every run's whole table: `halftone train tded` prints each run's
    // validation score.)
    let margin = tded::table_margin(tded::TABLE_TEXT).expect("a `# margin N:` line");
    assert!(tded::TRAIN_MARGINS.contains(&margin));
    let rows = train::smooth(&train::train_first(
        tded::ROWS,
        train::TRAIN_ITERATIONS,
        margin,
    ));
    assert_eq!((rows.len(), shipped.len()), (tded::ROWS, tded::ROWS));
    for (k, row) in rows.iter().enumerate() {
        for (a, b) in row.iter().zip(&shipped[k]) {
            assert!(
                (a - b).abs() < 2e-6,
                "row {k}: trained {row:?}, shipped {:?}",
                shipped[k]
            );
        }
    }
    // The weights are a distribution.
    for r in &shipped {
        assert!((r[..4].iter().sum::<f32>() - 1.0).abs() < 1e-4);
        assert!(r[..4].iter().all(|&w| w >= 0.0));
    }
}

#[test]
fn printer_model_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("in.pgm");
    let mut pgm = b"P5\n8 8\n255\n".to_vec();
    pgm.extend([128u8; 64]);
    std::fs::write(&src, pgm).unwrap();
    let out = dir.path().join("out.pbm");
    let res = Command::cargo_bin("halftone")
        .unwrap()
        .args(["convert", "--method", "dbs", "--levels", "4"])
        .args(["--printer-model", "dot-overlap", "-o"])
        .arg(&out)
        .arg(&src)
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    assert!(!out.exists());
    let res = Command::cargo_bin("halftone")
        .unwrap()
        .args(["convert", "--method", "dbs", "--dot-ratio", "1.6"])
        .args(["--printer-model", "dot-overlap", "-o"])
        .arg(&out)
        .arg(&src)
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    let res = Command::cargo_bin("halftone")
        .unwrap()
        .args(["convert", "--method", "dbs", "-o"])
        .arg(&out)
        .arg(&src)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
}

#[test]
fn model_based_dbs_prints_the_right_tone_under_its_model() {
    // Flats at several greys: the bitmap is lighter than the original by design (it
    // pre-compensates the dots' spread), and what the model prints matches the original.
    let model = PrinterModel::dot_overlap(1.25).unwrap();
    let m = Dbs::new(DbsOptions {
        printer: Some(model.clone()),
        radius: 4,
        ..DbsOptions::default()
    })
    .unwrap();
    let n = 64;
    let tone = ToneOptions::default();
    for code in [64u8, 128, 188, 230] {
        let img = Image::gray8(n, n, vec![code; n * n]);
        let target = img.tone_table(&tone).as_slice()[code as usize] as f64;
        let h = halftone_with(&m, &img);
        let printed = model.print_halftone(&h).unwrap().mean();
        assert!(
            (printed - target).abs() < 0.02,
            "code {code}: printed {printed:.4}, original {target:.4}"
        );
    }
}
