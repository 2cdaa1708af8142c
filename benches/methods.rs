//! Per-method throughput on a 4-megapixel grey image, in pixels per second
//! (`cargo bench --bench methods`; divan reports items/s = pixels/s).
// A test or benchmark's own pictures: the standard library's functions are fine here.
#![allow(clippy::disallowed_methods)]

use divan::counter::ItemsCount;
use divan::Bencher;
use halftone::method::pattern::{Cell, Pattern};
use halftone::method::threshold::Threshold;
use halftone::{halftone_image, ColorMode, Image, Mask, Method, ToneOptions};

const W: usize = 2048;
const H: usize = 2048;

fn main() {
    divan::main();
}

/// A smooth photo-like grey image with some texture: deterministic, no files.
fn photo() -> Image {
    let mut px = Vec::with_capacity(W * H);
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for y in 0..H {
        for x in 0..W {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let base = 128.0
                + 90.0 * ((x as f64 / 300.0).sin() * (y as f64 / 210.0).cos())
                + (seed % 17) as f64
                - 8.0;
            px.push(base.clamp(0.0, 255.0) as u8);
        }
    }
    Image::gray8(W, H, px)
}

fn run(bencher: Bencher, method: &dyn Method) {
    let img = photo();
    let tone = ToneOptions::default();
    bencher
        .counter(ItemsCount::new(W * H))
        .bench(|| halftone_image(&img, method, ColorMode::Gray, &tone).unwrap());
}

#[divan::bench]
fn threshold(bencher: Bencher) {
    run(bencher, &Threshold::new(0.5, 2).unwrap());
}

#[divan::bench(args = ["fit", "expand"])]
fn pattern_seed_3x3(bencher: Bencher, cell: &str) {
    let cell = if cell == "fit" {
        Cell::Fit
    } else {
        Cell::Expand
    };
    run(
        bencher,
        &Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, cell).unwrap(),
    );
}

#[divan::bench]
fn pattern_seed_2x2_four_levels(bencher: Bencher) {
    run(
        bencher,
        &Pattern::new(Mask::builtin("seed-2x2").unwrap(), 4, Cell::Fit).unwrap(),
    );
}
