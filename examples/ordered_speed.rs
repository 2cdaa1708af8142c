//! Throughput of ordered dithering on a 24-megapixel grey plane held in memory (no decoding,
//! no encoding): `cargo run --release --example ordered_speed [MASK] [LEVELS] [RUNS]`.
//! Prints the best of RUNS in milliseconds and megapixels per second.
// A test or benchmark's own pictures: the standard library's functions are fine here.
#![allow(clippy::disallowed_methods)]

use std::time::Instant;

use halftone::method::ordered::Ordered;
use halftone::raster::Image;
use halftone::{Mask, Method, ToneOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mask = args.get(1).map_or("bayer-8", String::as_str);
    let levels: u16 = args.get(2).map_or(2, |s| s.parse().expect("LEVELS"));
    let runs: usize = args.get(3).map_or(5, |s| s.parse().expect("RUNS"));
    let (w, h) = (6000usize, 4000usize);
    // A smooth photo-like plane: every code used, no long runs of one value.
    let px: Vec<u8> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (127.5 + 100.0 * (x / 397.0).sin() * (y / 211.0).cos() + 27.0 * (x * y / 9.1e5).sin())
                as u8
        })
        .collect();
    let img = Image::gray8(w, h, px);
    let tone = img.tone_table(&ToneOptions::default());
    let planes = img.planes(&tone);
    let method = Ordered::new(Mask::load(mask, false).expect("mask"), levels).expect("method");
    let mut best = f64::INFINITY;
    let mut check = 0u64;
    for _ in 0..runs {
        let t = Instant::now();
        let out = method.halftone(&planes).expect("halftone");
        best = best.min(t.elapsed().as_secs_f64());
        check = out.planes[0].iter().map(|&b| b.count_ones() as u64).sum();
    }
    println!(
        "{}: {w}x{h}, {} threads: best of {runs} {:.1} ms, {:.0} MP/s (set bits {check})",
        method.name(),
        rayon::current_num_threads(),
        best * 1e3,
        (w * h) as f64 / best / 1e6
    );
}
