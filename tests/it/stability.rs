//! Where methods fail, held to bounds: a regression in tone, texture, moiré, flicker or an
//! edge case fails here. Patches are 48 pixels, a multiple of every built-in cell (2, 3, 4),
//! so pattern `fit` draws whole cells and its tone bound is exact.

use halftone::bench::registry;
use halftone::stability::{edge_cases, measure, to_markdown, Stability, StabilityOptions};

const PATCH: usize = 48;

/// Bounds for one method. Tone bounds are analytic where the method allows: nearest of T
/// evenly spaced tones errs by at most 1/(2(T−1)).
struct Bounds {
    tone_max: f64,
    tone_mean: f64,
    startup: [Option<usize>; 2],
    periods: [Option<[usize; 2]>; 3],
    clumping_max: f64,
    /// Green noise clusters its dots on purpose: a floor as well as a ceiling.
    clumping_min: f64,
    moire_min_db: f64,
    flicker_max: f64,
}

fn bounds(key: &str) -> Option<Bounds> {
    let eps = 1e-6;
    Some(match key {
        // One threshold: every tone but black and white is wrong, by up to the threshold.
        "threshold" => Bounds {
            tone_max: 0.5,
            tone_mean: 0.19,
            startup: [None, None],
            periods: [Some([1, 1]); 3],
            clumping_max: 0.0,
            clumping_min: 0.0,
            moire_min_db: 34.5,
            flicker_max: 0.02,
        },
        "threshold-4" => Bounds {
            tone_max: 1.0 / 6.0 + eps,
            tone_mean: 0.075,
            startup: [None, None],
            periods: [Some([1, 1]); 3],
            clumping_max: 0.0,
            clumping_min: 0.0,
            moire_min_db: 36.5,
            // Three level boundaries: about 3 in the ramp's ~94 distinct codes move.
            flicker_max: 0.045,
        },
        // 3×3 cells: 10 tones, 63/64 rounds to paper and 1/64 to ink: no dots at all.
        "pattern-3x3-fit" | "pattern-3x3-expand" => Bounds {
            tone_max: 1.0 / 18.0 + eps,
            tone_mean: 0.027,
            startup: [None, None],
            periods: [Some([3, 3]); 3],
            clumping_max: 0.0,
            clumping_min: 0.0,
            // Fit averages 3×3 blocks of the zone plate: aliasing shows; expand keeps it.
            moire_min_db: if key.ends_with("fit") { 35.0 } else { 48.5 },
            flicker_max: 0.03,
        },
        // 2×2 cells on 4 levels: 13 tones; 1/3 is a device level, drawn flat.
        "pattern-2x2-fit-4" | "pattern-2x2-expand-4" => Bounds {
            tone_max: 1.0 / 24.0 + eps,
            tone_mean: 0.021,
            startup: [None, None],
            periods: [Some([2, 2]), Some([1, 1]), Some([2, 2])],
            clumping_max: 1.0,
            clumping_min: 0.0,
            moire_min_db: if key.contains("fit") { 41.0 } else { 46.5 },
            flicker_max: 0.03,
        },
        // Ordered: the bound, within 1/(mask cells) of the input over whole tiles
        // (48-pixel patches hold 6×6 whole 8×8 tiles). Start-up rows are where the mask puts
        // its first dot, not a delay.
        "ordered-bayer-8" => Bounds {
            tone_max: 1.0 / 64.0 + eps,
            tone_mean: 0.005,
            startup: [Some(7), Some(0)],
            periods: [Some([2, 2]), Some([8, 8]), Some([2, 2])],
            clumping_max: 0.01,
            clumping_min: 0.0,
            moire_min_db: 28.0,
            flicker_max: 0.01,
        },
        "ordered-cluster-8" => Bounds {
            tone_max: 1.0 / 64.0 + eps,
            tone_mean: 0.005,
            startup: [Some(4), Some(0)],
            periods: [Some([8, 8]); 3],
            clumping_max: 1.0,
            clumping_min: 0.0,
            moire_min_db: 31.0,
            flicker_max: 0.01,
        },
        // 48-pixel patches are not whole 64×64 tiles: the bound is measured (0.004), with room.
        "ordered-blue-noise-64" => Bounds {
            tone_max: 0.006,
            tone_mean: 0.002,
            startup: [Some(0), Some(1)],
            periods: [None; 3],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 29.5,
            flicker_max: 0.01,
        },
        // Four levels: within 1/(64·3) of the input.
        "ordered-bayer-8-4" => Bounds {
            tone_max: 1.0 / 192.0 + eps,
            tone_mean: 0.002,
            startup: [Some(3), Some(0)],
            periods: [Some([2, 2]), Some([1, 1]), Some([2, 2])],
            clumping_max: 1.0,
            clumping_min: 0.0,
            moire_min_db: 41.0,
            flicker_max: 0.02,
        },
        // Error diffusion, measured on 48-pixel patches (borders and start-up included, so
        // tone errors exceed the 0.004 that tests/it/diffusion.rs holds away from the borders).
        // Start-up rows and texture periods are exact: the methods are deterministic.
        // Atkinson passes on only 6/8 of the error: tones within 1/8 of black or white print
        // solid, the worst error is 0.125.
        "diffuse-floyd-steinberg" => Bounds {
            tone_max: 0.0109,
            tone_mean: 0.0059,
            startup: [Some(15), Some(17)],
            periods: [Some([2, 2]), None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 39.9,
            flicker_max: 0.304,
        },
        "diffuse-jarvis-judice-ninke" => Bounds {
            tone_max: 0.02,
            tone_mean: 0.0126,
            startup: [Some(28), Some(31)],
            periods: [None, Some([3, 2]), None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 41.0,
            flicker_max: 0.322,
        },
        "diffuse-stucki" => Bounds {
            tone_max: 0.0187,
            tone_mean: 0.0113,
            startup: [Some(26), Some(29)],
            periods: [None, None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 40.1,
            flicker_max: 0.313,
        },
        "diffuse-sierra-lite" => Bounds {
            tone_max: 0.0109,
            tone_mean: 0.0055,
            startup: [Some(14), Some(15)],
            periods: [Some([2, 2]), None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 41.0,
            flicker_max: 0.347,
        },
        "diffuse-atkinson" => Bounds {
            tone_max: 0.163,
            tone_mean: 0.0659,
            startup: [None, None],
            periods: [Some([4, 4]), None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 38.8,
            flicker_max: 0.258,
        },
        "diffuse-shiau-fan-2" => Bounds {
            tone_max: 0.0135,
            tone_mean: 0.0063,
            startup: [Some(14), Some(15)],
            periods: [Some([2, 2]), Some([3, 6]), None],
            clumping_max: 0.06,
            clumping_min: 0.0,
            moire_min_db: 43.4,
            flicker_max: 0.308,
        },
        "diffuse-ostromoukhov" => Bounds {
            tone_max: 0.0109,
            tone_mean: 0.0059,
            startup: [Some(11), Some(12)],
            periods: [Some([2, 2]), None, None],
            clumping_max: 0.06,
            clumping_min: 0.0,
            moire_min_db: 41.6,
            flicker_max: 0.314,
        },
        "diffuse-zhou-fang" => Bounds {
            tone_max: 0.0122,
            tone_mean: 0.0073,
            startup: [Some(10), Some(11)],
            periods: [None, None, None],
            clumping_max: 0.13,
            clumping_min: 0.0,
            moire_min_db: 39.6,
            flicker_max: 0.248,
        },
        "diffuse-riemersma" => Bounds {
            tone_max: 0.0018,
            tone_mean: 0.001,
            startup: [Some(0), Some(0)],
            periods: [None, None, None],
            clumping_max: 0.85,
            clumping_min: 0.0,
            moire_min_db: 35.7,
            flicker_max: 0.335,
        },
        "diffuse-floyd-steinberg-4" => Bounds {
            tone_max: 0.0044,
            tone_mean: 0.002,
            startup: [Some(5), Some(5)],
            periods: [Some([2, 2]), Some([1, 1]), None],
            clumping_max: 1.0,
            clumping_min: 0.0,
            moire_min_db: 53.8,
            flicker_max: 0.331,
        },
        // Measured like the error diffusions above (tone ×1.3, moiré −1 dB, flicker +0.03
        // of what each achieves on 48-pixel patches); start-up rows and periods are exact.
        // Tone-dependent error diffusion (tded): 0.006 / 0.0021, 44.3 dB, 27.7%.
        "diffuse-tded" => Bounds {
            tone_max: 0.008,
            tone_mean: 0.0028,
            startup: [Some(13), Some(15)],
            periods: [Some([2, 2]), None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 43.3,
            flicker_max: 0.307,
        },
        // Green noise (hysteresis 1.5): clustered dots, so nearly every dot touches another
        // (0.96 measured) and the tone is looser than Floyd–Steinberg's (0.015 / 0.0091);
        // 38.0 dB, 18.4%.
        "diffuse-hysteresis-1.5" => Bounds {
            tone_max: 0.0195,
            tone_mean: 0.0118,
            startup: [Some(23), Some(25)],
            periods: [None, None, None],
            clumping_max: 1.0,
            clumping_min: 0.9,
            moire_min_db: 37.0,
            flicker_max: 0.214,
        },
        // Direct binary search: 0.007 / 0.0014, 51.6 dB, 28.9%.
        "dbs" => Bounds {
            tone_max: 0.009,
            tone_mean: 0.0019,
            startup: [Some(3), Some(3)],
            periods: [Some([2, 2]), None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 50.6,
            flicker_max: 0.319,
        },
        // Model-based DBS makes the bitmap lighter on purpose, so that the printer's
        // spreading dots bring it back (its printed tone is held to 0.02 in
        // tests/it/accuracy.rs, model_based_dbs_prints_the_right_tone_under_its_model):
        // these bound the bitmap as it is, 0.332 / 0.2222, 12.1 dB against the unprinted
        // zone plate, 41.4%. No dot before the first row near black; none at all near
        // white (a lone dot spreads to more than 1/64 of its neighbourhood).
        "model-dbs-1.25" => Bounds {
            tone_max: 0.36,
            tone_mean: 0.235,
            startup: [None, Some(0)],
            periods: [None, None, None],
            clumping_max: 0.05,
            clumping_min: 0.0,
            moire_min_db: 11.1,
            flicker_max: 0.444,
        },
        _ => return None,
    })
}

fn check(r: &Stability, failures: &mut Vec<String>) {
    let mut fail = |what: String| failures.push(format!("{}: {what}", r.key));
    for e in r.edge_cases.iter().filter(|e| !e.ok) {
        fail(format!("edge case {}: {}", e.case, e.detail));
    }
    // Black stays black and white stays white, whatever the method.
    if r.tone.output[0] != 0.0 || r.tone.output[255] != 1.0 {
        fail(format!(
            "tone ends {} and {}, expected 0 and 1",
            r.tone.output[0], r.tone.output[255]
        ));
    }
    // Every registered method is held to bounds of its own: a new method without them fails
    // here until they are measured and written down.
    let Some(b) = bounds(&r.key) else {
        fail("no bounds of its own (add them to bounds() in tests/it/stability.rs)".into());
        return;
    };
    if r.tone.max_error > b.tone_max {
        fail(format!(
            "max tone error {:.5} at code {} > {:.5}",
            r.tone.max_error, r.tone.worst_code, b.tone_max
        ));
    }
    if r.tone.mean_error > b.tone_mean {
        fail(format!(
            "mean tone error {:.5} > {}",
            r.tone.mean_error, b.tone_mean
        ));
    }
    if [r.startup_white, r.startup_black] != b.startup {
        fail(format!(
            "start-up rows {:?}/{:?}, expected {:?}",
            r.startup_white, r.startup_black, b.startup
        ));
    }
    let periods: Vec<_> = r.texture.iter().map(|t| t.period).collect();
    if periods != b.periods {
        fail(format!("periods {periods:?}, expected {:?}", b.periods));
    }
    if r.clumping > b.clumping_max {
        fail(format!("clumping {:.3} > {}", r.clumping, b.clumping_max));
    }
    if r.clumping < b.clumping_min {
        fail(format!("clumping {:.3} < {}", r.clumping, b.clumping_min));
    }
    if r.moire_lf_psnr_db < b.moire_min_db {
        fail(format!(
            "zone plate low-frequency PSNR {:.2} dB < {}",
            r.moire_lf_psnr_db, b.moire_min_db
        ));
    }
    if r.flicker > b.flicker_max {
        fail(format!("flicker {:.4} > {}", r.flicker, b.flicker_max));
    }
}

#[test]
fn every_registered_method_within_its_bounds() {
    let opts = StabilityOptions {
        size: PATCH,
        ..Default::default()
    };
    let results: Vec<Stability> = registry()
        .iter()
        .map(|(k, m)| measure(k, m.as_ref(), &opts).unwrap())
        .collect();
    eprintln!("{}", to_markdown(&results));
    let mut failures = Vec::new();
    for r in &results {
        check(r, &mut failures);
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

/// A method that gets sizes wrong and cannot keep black black: the checks must catch it.
struct Broken;

impl halftone::Method for Broken {
    fn name(&self) -> String {
        "broken".into()
    }

    fn halftone(&self, input: &halftone::Planes<'_>) -> halftone::Result<halftone::Halftone> {
        if input.width == 1 {
            panic!("cannot do one column");
        }
        // Paper everywhere, one column short.
        let mut h = halftone::Halftone::new(input.width - 1, input.height, input.planes.len(), 2);
        for p in &mut h.planes {
            p.iter_mut().for_each(|b| *b = 0xFF);
        }
        Ok(h)
    }
}

#[test]
fn the_checks_catch_a_broken_method() {
    // Measuring stops with a one-line error rather than report figures of a wrong size...
    let err = measure(
        "broken",
        &Broken,
        &StabilityOptions {
            size: 16,
            ..Default::default()
        },
    )
    .expect_err("a method of the wrong size cannot be measured")
    .to_string();
    assert!(err.contains("15x16"), "{err}");
    // ...and the edge cases name every failure, panics included.
    let cases = edge_cases(&Broken);
    let failed: Vec<&str> = cases
        .iter()
        .filter(|e| !e.ok)
        .map(|e| e.case.as_str())
        .collect();
    for case in ["1x1", "1xN", "Nx1", "all black", "RGB input"] {
        assert!(failed.contains(&case), "{case} not caught: {failed:?}");
    }
    assert!(cases
        .iter()
        .any(|e| e.detail.contains("panicked: cannot do one column")));
    // A method that prints nothing fails the black-stays-black check.
    let r = measure(
        "all-paper",
        &AllPaper,
        &StabilityOptions {
            size: 16,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(r.tone.output[0], 1.0);
    let mut failures = Vec::new();
    check(&r, &mut failures);
    assert!(
        failures
            .iter()
            .any(|f| f.contains("all-paper: tone ends 1 and 1, expected 0 and 1")),
        "{failures:?}"
    );
}

/// A method of the right size that leaves the paper blank.
struct AllPaper;

impl halftone::Method for AllPaper {
    fn name(&self) -> String {
        "all-paper".into()
    }

    fn halftone(&self, input: &halftone::Planes<'_>) -> halftone::Result<halftone::Halftone> {
        let mut h = halftone::Halftone::new(input.width, input.height, input.planes.len(), 2);
        for p in &mut h.planes {
            p.iter_mut().for_each(|b| *b = 0xFF);
        }
        Ok(h)
    }
}

#[test]
fn heatmap_and_chart_are_written_and_decodable() {
    use halftone::bench::{summarise, write_chart, Measurement};
    use halftone::quality::{Quality, Viewing};
    let opts = StabilityOptions {
        size: 16,
        ..Default::default()
    };
    let results: Vec<Stability> = registry()
        .iter()
        .take(2)
        .map(|(k, m)| measure(k, m.as_ref(), &opts).unwrap())
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let (svg, png) = (
        dir.path().join("heatmap.svg"),
        dir.path().join("heatmap.png"),
    );
    halftone::stability::write_heatmap(&results, &svg, &png).unwrap();
    let img = image::open(&png).unwrap().to_rgb8();
    // Threshold prints every mid-tone too dark and then too light: saturated blue and red.
    assert!(img.pixels().any(|p| p.0 == [0, 0, 255]));
    assert!(img.pixels().any(|p| p.0 == [255, 0, 0]));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("threshold-4"));

    let q = |db: f64| Quality {
        hvs_psnr_db: db,
        hvs_mse: 0.0,
        tone_bias: 0.0,
        lstar_rms: 0.0,
        plain_psnr_db: 0.0,
        scale: [1, 1],
    };
    let m = |key: &str, mp_per_s: f64, db: f64| Measurement {
        key: key.into(),
        method: key.into(),
        image: "ramp".into(),
        megapixels: 1.0,
        median_seconds: 1.0 / mp_per_s,
        mp_per_s,
        quality: q(db),
        printed: None,
    };
    let sums = summarise(&[
        m("fast", 500.0, 15.0),
        m("good", 20.0, 35.0),
        m("poor", 10.0, 20.0),
    ]);
    assert_eq!(
        sums.iter().map(|s| s.pareto).collect::<Vec<_>>(),
        [true, true, false]
    );
    let (svg, png) = (dir.path().join("chart.svg"), dir.path().join("chart.png"));
    write_chart(&sums, &Viewing::default(), &svg, &png).unwrap();
    assert_eq!(image::open(&png).unwrap().width(), 900);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("good") && text.contains("Pareto front"));
}

/// Plain Floyd–Steinberg (1976) on one bilevel plane, left to right: the textbook case of
/// start-up delay and flicker, to show that the measures see them.
struct FloydSteinberg;

impl halftone::Method for FloydSteinberg {
    fn name(&self) -> String {
        "floyd-steinberg (test)".into()
    }

    fn halftone(&self, input: &halftone::Planes<'_>) -> halftone::Result<halftone::Halftone> {
        let (w, h) = (input.width, input.height);
        let mut out = halftone::Halftone::new(w, h, input.planes.len(), 2);
        for (c, plane) in input.planes.iter().enumerate() {
            let (mut cur, mut next) = (vec![0f32; w + 2], vec![0f32; w + 2]);
            let mut row = vec![0f32; w];
            for y in 0..h {
                plane.row_linear(y, &mut row);
                for x in 0..w {
                    let v = row[x] + cur[x + 1];
                    let level = (v >= 0.5) as u8;
                    let err = v - level as f32;
                    out.set(c, x, y, level);
                    cur[x + 2] += err * 7.0 / 16.0;
                    next[x] += err * 3.0 / 16.0;
                    next[x + 1] += err * 5.0 / 16.0;
                    next[x + 2] += err / 16.0;
                }
                std::mem::swap(&mut cur, &mut next);
                next.iter_mut().for_each(|e| *e = 0.0);
            }
        }
        Ok(out)
    }
}

#[test]
fn error_diffusion_weaknesses_are_measured() {
    let r = measure("fs", &FloydSteinberg, &StabilityOptions::default()).unwrap();
    eprintln!("{}", to_markdown(std::slice::from_ref(&r)));
    assert!(r.edge_cases_ok(), "{:?}", r.edge_cases);
    // Error diffusion keeps tone: far better than any pattern here.
    assert!(r.tone.mean_error < 0.01, "{}", r.tone.mean_error);
    // Near white the first ink dot waits for error to build up over several rows.
    let white = r.startup_white.expect("a dot appears within the patch");
    assert!(white >= 2, "start-up at near-white: {white} rows");
    // One code up reshuffles much of the output: flicker far above a threshold's.
    assert!(r.flicker > 0.1, "{}", r.flicker);
    // No short period at 1/3 (FS is aperiodic there); 1/2 gives the checkerboard.
    assert_eq!(r.texture[0].period, Some([2, 2]));
    assert_eq!(r.texture[1].period, None);
}

/// Saturated colours on real inks (`halftone::panel_stability`): on every built-in panel,
/// diffusion and DBS, the mean shown is within CIEDE2000 8 of the colour the gamut map aims
/// at, within 12° of its hue, and the same down the patch (top and bottom thirds within 1.5).
/// Colours the map sends to neutral are drawn with the neutral inks, which is where the
/// largest passing differences come from (cyan on the 6-colour panels: the aim's chroma is
/// under the neutral threshold, ΔE 6.5).
///
/// Diffusion passes everywhere. The cases listed in `KNOWN` (DBS on estimated inks) fail
/// those bounds today and are open defects: the test fails if one of them starts to pass
/// (take it off the list) or if any other case fails.
#[test]
fn every_panel_keeps_saturated_colours_near_their_aim() {
    const KNOWN: [&str; 12] = [
        // DBS on the estimated ACeP inks draws a saturated red (aimed at red ink with a few
        // dots of orange, black and white) a little more orange in its top rows, where its
        // filter meets the page's edge (drift 3.23, ΔE to the aim 3.17, hue 3.6°);
        // diffusion, primed, holds it.
        "acep7-5in65 dbs red",
        // DBS at the shelf tags' 23 pixels a degree: solid red ink for red and magenta
        // (too dark and too saturated), black with sparse white dots for blue (L* 9 for 29).
        // Its eye model trades the mean for less texture there, and the S-CIELAB score
        // agrees (flat blue on solum-bwr: ΔE 38.9 against diffusion's 38.8; red 21.1 against
        // 28.1): a choice of the model, not a runaway (the drift is within bounds).
        "solum-bwr dbs red",
        "solum-bwr dbs blue",
        "solum-bwr dbs magenta",
        "solum-bwr dbs sky",
        "hanshow-bwr dbs red",
        "hanshow-bwr dbs blue",
        "hanshow-bwr dbs magenta",
        "hanshow-bwr dbs sky",
        "hanshow-bwy dbs blue",
        "hanshow-bwy dbs magenta",
        "hanshow-bwy dbs sky",
    ];
    let cases = halftone::panel_stability::panels(96).unwrap();
    assert_eq!(
        cases.len(),
        halftone::panel::Device::builtin_names().count() * 2 * 7
    );
    let within = |c: &halftone::panel_stability::PanelCase| {
        c.de_aim <= 8.0 && c.hue_deg.abs() <= 12.0 && c.drift <= 1.5
    };
    let mut failing: Vec<String> = cases
        .iter()
        .filter(|c| !within(c))
        .map(|c| format!("{} {} {}", c.panel, c.method, c.colour))
        .collect();
    failing.sort();
    let mut known: Vec<String> = KNOWN.iter().map(|s| s.to_string()).collect();
    known.sort();
    let new: Vec<&String> = failing.iter().filter(|f| !known.contains(f)).collect();
    let fixed: Vec<&String> = known.iter().filter(|k| !failing.contains(k)).collect();
    let figures: Vec<String> = cases
        .iter()
        .filter(|c| new.contains(&&format!("{} {} {}", c.panel, c.method, c.colour)))
        .map(|c| {
            format!(
                "{} {} {}: ΔE aim {:.2}, hue {:.1}°, drift {:.2}, aim {:.1?}, seen {:.1?}",
                c.panel, c.method, c.colour, c.de_aim, c.hue_deg, c.drift, c.aim, c.seen
            )
        })
        .collect();
    assert!(new.is_empty(), "new failures: {figures:#?}");
    assert!(
        fixed.is_empty(),
        "now within bounds (take off KNOWN): {fixed:?}"
    );
    // Diffusion passes on every panel (no runaway where the inks lack a hue); the measured
    // panels pass everything, diffusion and DBS.
    let measured = ["spectra6-7in3-v2", "spectra6-7in3", "bwry-3in97"];
    for c in &cases {
        if c.method == "diffuse" || measured.contains(&c.panel.as_str()) {
            assert!(within(c), "{c:?}");
        }
    }
}
