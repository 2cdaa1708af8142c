//! Printer presets carry the transfer curves their printers need, and apply them.
//!
//! The wedges in `presets/*.csv` are the dot-overlap printer model (Pappas & Neuhoff 1995,
//! `src/printer_model.rs`) printing the preset's own halftone of flat patches:
//! `HALFTONE_WRITE_WEDGES=1 cargo test --release --test it screens_presets` rewrites them.

use std::path::{Path, PathBuf};
use std::process::Command;

use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::method::ordered::Ordered;
use halftone::press::transfer::Transfer;
use halftone::printer_model::PrinterModel;
use halftone::raster::{PlaneRef, Planes, SamplesRef};
use halftone::tone::{Encoding, ToneTable};
use halftone::{Mask, Method, ToneOptions};

/// A built-in wedge: file, the method its preset halftones with, the dot ratio of the model.
struct Wedge {
    file: &'static str,
    method: fn() -> Box<dyn Method>,
    rho: f64,
}

fn wedges() -> Vec<Wedge> {
    vec![
        // A 600-dpi laser's toner dot: ρ ≈ 1.25 (Pappas & Neuhoff measured 1.2–1.4 on
        // 300-dpi lasers; a 600-dpi engine is no sharper relative to its pixel).
        Wedge {
            file: "laser-600.csv",
            method: || Box::new(Ordered::new(Mask::load("cluster-8", false).unwrap(), 2).unwrap()),
            rho: 1.25,
        },
        // A 203-dpi thermal head burns dots about the size of the pixel pitch: ρ = 1, the
        // model's smallest dot (a disc just covering its square pixel). The patches are Floyd–Steinberg's, which keeps a flat patch's mean
        // exactly, so the curve is the head's dot gain alone; Atkinson (the presets'
        // kernel) drops a quarter of its error and would fold its own highlight and shadow
        // clipping into the curve.
        Wedge {
            file: "thermal-203.csv",
            method: || {
                Box::new(Diffuse::new("floyd-steinberg", DiffuseOptions::default()).unwrap())
            },
            rho: 1.0,
        },
    ]
}

fn presets_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("presets")
}

/// Printed ink coverage of `method`'s halftone of a flat patch at nominal coverage `a`,
/// through the dot-overlap model at `rho` (the interior, away from the unprinted border).
fn printed(method: &dyn Method, rho: f64, a: f64) -> f64 {
    let n = 192;
    let code = ((1.0 - a) * 65535.0).round() as u16;
    let samples = vec![code; n * n];
    let table = ToneTable::new(16, Encoding::Linear, &ToneOptions::default());
    let planes = Planes {
        width: n,
        height: n,
        planes: vec![PlaneRef {
            width: n,
            height: n,
            samples: SamplesRef::U16(&samples),
            tone: table.as_slice(),
        }],
    };
    let h = method.halftone(&planes).unwrap();
    let ink: Vec<u8> = h.levels_of(0).iter().map(|&l| (l == 0) as u8).collect();
    let model = PrinterModel::dot_overlap(rho).unwrap();
    let refl = model.print_ink(&ink, n, n);
    let m = 16;
    let mut sum = 0.0;
    for y in m..n - m {
        for x in m..n - m {
            sum += 1.0 - refl[y * n + x] as f64;
        }
    }
    sum / ((n - 2 * m) * (n - 2 * m)) as f64
}

#[test]
fn preset_wedges_are_their_printer_models() {
    let write = std::env::var_os("HALFTONE_WRITE_WEDGES").is_some();
    // Writing replaces the files this test checks: never under CI, where it would pass
    // whatever the model printed.
    assert!(
        !(write && crate::common::in_ci()),
        "HALFTONE_WRITE_WEDGES rewrites presets/*.csv instead of checking them: not under CI"
    );
    for w in wedges() {
        let method = (w.method)();
        let steps: Vec<f64> = (0..=20).map(|k| k as f64 * 5.0).collect();
        // Printed coverage never falls as nominal rises: where the model's print does
        // (diffusion's near-checkerboard at 50% prints darker than its neighbours), the
        // wedge holds the level, as a measured wedge is smoothed before use.
        let mut last = 0.0f64;
        let measured: Vec<f64> = steps
            .iter()
            .map(|&s| {
                last = last.max(100.0 * printed(method.as_ref(), w.rho, s / 100.0));
                last.min(100.0)
            })
            .collect();
        let path = presets_dir().join(w.file);
        if write {
            let mut text = format!(
                "# {}: printed ink coverage (%) of the preset's halftone ({}) of flat patches,\n\
                 # through the dot-overlap printer model at dot ratio {} (Pappas & Neuhoff 1995,\n\
                 # src/printer_model.rs). A model, not a measurement: replace it with your\n\
                 # printer's measured step wedge (--transfer FILE) when you have one.\n\
                 # Written by: HALFTONE_WRITE_WEDGES=1 cargo test --release --test it screens_presets\n\
                 # nominal %, printed %\n",
                w.file,
                method.name(),
                w.rho
            );
            for (s, m) in steps.iter().zip(&measured) {
                text += &format!("{s:.0}, {m:.2}\n");
            }
            std::fs::write(&path, text).unwrap();
            continue;
        }
        let t = Transfer::load(&path).unwrap();
        for (s, m) in steps.iter().zip(&measured) {
            let shipped = 100.0 * t.response(0, s / 100.0);
            assert!(
                (shipped - m).abs() < 0.5,
                "{}: at {s}% the model prints {m:.2}%, the file says {shipped:.2}%",
                w.file
            );
        }
        // Dot gain: mid-tones print darker than asked.
        assert!(t.response(0, 0.5) > 0.52, "{}", w.file);
    }
    if write {
        // The files were just written from the model, so comparing them with it would
        // prove nothing: this run checked none of them.
        crate::common::skip(
            "screens_presets::preset_wedges_are_their_printer_models",
            "HALFTONE_WRITE_WEDGES rewrote the wedges; run again without it to check them",
        );
    }
}

/// Ink coverage of a PBM (P4) file.
fn pbm_ink(bytes: &[u8]) -> f64 {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]).to_string();
    let mut it = text.split_ascii_whitespace();
    assert_eq!(it.next(), Some("P4"));
    let w: usize = it.next().unwrap().parse().unwrap();
    let h: usize = it.next().unwrap().parse().unwrap();
    let data = &bytes[bytes.len() - w.div_ceil(8) * h..];
    let stride = w.div_ceil(8);
    let mut ink = 0usize;
    for y in 0..h {
        for x in 0..w {
            ink += ((data[y * stride + x / 8] >> (7 - x % 8)) & 1) as usize;
        }
    }
    ink as f64 / (w * h) as f64
}

fn flat_pgm(dir: &Path, code: u8) -> PathBuf {
    let p = dir.join(format!("flat{code}.pgm"));
    let (w, h) = (256, 256);
    let mut b = format!("P5\n{w} {h}\n255\n").into_bytes();
    b.extend(std::iter::repeat_n(code, w * h));
    std::fs::write(&p, b).unwrap();
    p
}

fn convert(args: &[&str]) -> Vec<u8> {
    let o = Command::new(env!("CARGO_BIN_EXE_halftone"))
        .arg("convert")
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o.stdout
}

#[test]
fn presets_apply_their_transfer_curves() {
    let dir = tempfile::tempdir().unwrap();
    // (preset, method to measure with, the curve it must apply). The laser's own 8×8
    // cluster gives only 65 tones, too coarse to see one point, and Atkinson (the thermal
    // presets' kernel) drops a quarter of its error; Floyd–Steinberg keeps a flat patch's
    // mean exactly, and the preset's curve applies whatever the method.
    let cases: [(&str, &[&str], Transfer); 3] = [
        (
            "laser-600",
            &["--method", "diffuse"],
            Transfer::load(&presets_dir().join("laser-600.csv")).unwrap(),
        ),
        (
            "thermal-203",
            &[
                "--method",
                "diffuse",
                "--kernel",
                "floyd-steinberg",
                "--content",
                "photo",
            ],
            Transfer::load(&presets_dir().join("thermal-203.csv")).unwrap(),
        ),
        ("newsprint", &["--method", "screen"], tr002_black()),
    ];
    for (preset, method, curve) in cases {
        for code in [40u8, 90, 128, 170, 220] {
            let input = flat_pgm(dir.path(), code);
            let input = input.to_str().unwrap();
            let mut args = vec![input, "-o", "-", "--preset", preset, "--format", "pbm"];
            args.extend_from_slice(method);
            // The thermal preset's width is the head's; the laser and plate keep the input's.
            let got = pbm_ink(&convert(&args));
            let v = code as f64 / 255.0;
            let linear = if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            };
            let want = curve.compensate(0, 1.0 - linear);
            assert!(
                (got - want).abs() < 0.01,
                "{preset} at code {code}: ink {got:.4}, the inverse curve says {want:.4} \
                 (uncompensated {:.4})",
                1.0 - linear
            );
            // The curve did something: dot gain means less ink than the plain tone.
            if (60..=200).contains(&code) {
                assert!(got < 1.0 - linear - 0.02, "{preset} at {code}: {got:.4}");
            }
        }
    }
}

/// The newsprint preset's curve: TR002's black ramp (presses/tr002.toml).
fn tr002_black() -> Transfer {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("presses/tr002.toml"))
            .unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    let k = v["curves"][3].as_array().unwrap();
    let csv: String = k
        .iter()
        .map(|p| {
            let p = p.as_array().unwrap();
            format!(
                "{}, {}\n",
                p[0].as_float().unwrap() * 100.0,
                (p[1].as_float().unwrap() * 100.0).clamp(0.0, 100.0)
            )
        })
        .collect();
    Transfer::parse(&csv, Path::new("tr002")).unwrap()
}

#[test]
fn a_command_line_transfer_wins_over_the_presets() {
    let dir = tempfile::tempdir().unwrap();
    let input = flat_pgm(dir.path(), 128);
    let wedge = dir.path().join("flat.csv");
    std::fs::write(&wedge, "0, 0\n100, 100\n").unwrap();
    let args = [
        input.to_str().unwrap(),
        "-o",
        "-",
        "--preset",
        "laser-600",
        "--format",
        "pbm",
        "--method",
        "diffuse",
        "--transfer",
        wedge.to_str().unwrap(),
    ];
    let got = pbm_ink(&convert(&args));
    let want = 1.0 - ((128.0 / 255.0 + 0.055) / 1.055f64).powf(2.4);
    assert!((got - want).abs() < 0.005, "{got} against {want}");
}
