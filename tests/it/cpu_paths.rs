//! Every method with a vector loop gives the same bytes on the portable path and on the
//! CPU's own (`halftone::cpu::with_level`), on a page large enough for every loop to run:
//! DBS (plain and through a printer model: AVX2), Floyd–Steinberg (AVX2), palette
//! diffusion (AVX-512). On a CPU without a path the comparison is skipped, loudly (a
//! failure under CI, whose machine has AVX-512).

use halftone::cpu::{detected, with_level, Level};
use halftone::method::dbs::{Dbs, DbsOptions};
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::printer_model::PrinterModel;
use halftone::raster::{ColorKind, Samples};
use halftone::tone::Encoding;
use halftone::{halftone_image, ColorMode, Image, Method, ToneOptions};

/// A colour page with smooth fields, edges and noise, `w × h`.
fn page(w: usize, h: usize) -> Image {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let planes = (0..3)
        .map(|c| {
            Samples::U8(
                (0..w * h)
                    .map(|i| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        let (px, py) = (i % w, i / w);
                        let smooth = (px * 255 / w + py * 90 / h + c * 70) % 256;
                        let edge = if (px / 23 + py / 17 + c) % 4 == 0 {
                            200
                        } else {
                            0
                        };
                        ((smooth + edge) % 256) as u8 ^ (x % 8) as u8
                    })
                    .collect(),
            )
        })
        .collect();
    Image {
        width: w,
        height: h,
        color: ColorKind::Rgb,
        planes,
        encoding: Encoding::Srgb,
        dpi: None,
    }
}

/// Whether this CPU has `level`; if not, the comparison is skipped with a SKIPPED line.
fn has(level: Level, check: &str) -> bool {
    if detected() >= level {
        return true;
    }
    // Not `common::skip`: no install gives a CPU an instruction set, so CI's machine runs
    // the paths it has (`.ci/run` prints which) and says which it could not.
    eprintln!(
        "SKIPPED {check}: this CPU has no {} (it has {})",
        level.name(),
        detected().name()
    );
    false
}

fn same_on_both_paths(level: Level, m: &dyn Method, mode: ColorMode, what: &str) {
    let img = page(203, 141);
    let tone = ToneOptions::default();
    let run = |l: Level| with_level(l, || halftone_image(&img, m, mode, &tone).unwrap());
    let (portable, vector) = (run(Level::Portable), run(level));
    assert!(portable == vector, "{what}: portable and {level:?} differ");
}

#[test]
fn dbs_is_the_same_on_the_portable_and_the_avx2_path() {
    if !has(
        Level::Avx2,
        "cpu_paths::dbs_is_the_same_on_the_portable_and_the_avx2_path",
    ) {
        return;
    }
    let plain = Dbs::new(DbsOptions::default()).unwrap();
    same_on_both_paths(Level::Avx2, &plain, ColorMode::Gray, "dbs");
    let model = PrinterModel::dot_overlap(1.25).unwrap();
    let model = Dbs::new(DbsOptions::for_printer(model)).unwrap();
    same_on_both_paths(Level::Avx2, &model, ColorMode::Gray, "model-based dbs");
}

#[test]
fn floyd_steinberg_is_the_same_on_the_portable_and_the_avx2_path() {
    let check = "cpu_paths::floyd_steinberg_is_the_same_on_the_portable_and_the_avx2_path";
    if !has(Level::Avx2, check) {
        return;
    }
    for serpentine in [true, false] {
        let opts = DiffuseOptions {
            serpentine,
            ..Default::default()
        };
        let fs = Diffuse::new("floyd-steinberg", opts).unwrap();
        same_on_both_paths(Level::Avx2, &fs, ColorMode::Rgb, "floyd-steinberg");
    }
}

#[test]
fn palette_diffusion_is_the_same_on_the_portable_and_the_avx512_path() {
    let check = "cpu_paths::palette_diffusion_is_the_same_on_the_portable_and_the_avx512_path";
    if !has(Level::Avx512, check) {
        return;
    }
    for name in ["epaper-7", "rgb-8", "eink-4"] {
        let p = halftone::color::Palette::builtin(name).unwrap();
        let d = Diffuse::new("floyd-steinberg", DiffuseOptions::default())
            .unwrap()
            .with_palette(p);
        same_on_both_paths(Level::Avx512, &d, ColorMode::Rgb, name);
    }
}
