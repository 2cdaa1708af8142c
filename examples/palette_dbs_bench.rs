//! Speed of palette DBS (`halftone::method::dbs::palette::refine`) on a synthetic colour
//! picture inside the hull of a 6-ink e-paper palette, seeded by plain Floyd–Steinberg:
//! `cargo run --release --example palette_dbs_bench [WIDTH HEIGHT [RUNS [PPD [PASSES [SWAPS [MAX_RADIUS]]]]]]`
//! (default 800 480 5 35 8 1 24). Prints the best and median time of RUNS, the passes run and the
//! cost before and after.
// A test or benchmark's own pictures: the standard library's functions are fine here.
#![allow(clippy::disallowed_methods)]

use std::time::Instant;

use halftone::method::dbs::palette::{cost, refine, PaletteDbsOptions};

/// Black, white, red, yellow, blue, green, linear RGB.
const INKS: [[f32; 3]; 6] = [
    [0.0, 0.0, 0.0],
    [1.0, 1.0, 1.0],
    [0.2, 0.003, 0.0],
    [0.6, 0.48, 0.0],
    [0.005, 0.03, 0.25],
    [0.04, 0.2, 0.03],
];

/// A photo-like picture: each pixel a convex mix of the inks with smoothly varying weights
/// (soft maxima of slow waves), plus a few sharp-edged discs.
fn picture(w: usize, h: usize) -> Vec<[f32; 3]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let mut a: [f32; 6] = std::array::from_fn(|k| {
                let k = k as f32;
                (2.5 * ((x / (61.0 + 13.0 * k)) + k).sin() * ((y / (47.0 + 7.0 * k)) - k).cos())
                    .exp()
            });
            for (cx, cy, r, k) in [
                (0.3, 0.4, 0.12, 2),
                (0.7, 0.6, 0.15, 4),
                (0.55, 0.25, 0.08, 1),
            ] {
                let (dx, dy) = (x / w as f32 - cx, y / h as f32 - cy);
                if dx * dx + dy * dy < r * r {
                    a[k] += 3.0;
                }
            }
            let s: f32 = a.iter().sum();
            std::array::from_fn(|c| (0..6).map(|k| a[k] / s * INKS[k][c]).sum())
        })
        .collect()
}

/// Plain Floyd–Steinberg in linear RGB, nearest ink by RGB distance.
fn floyd_steinberg(t: &[[f32; 3]], w: usize, h: usize) -> Vec<u8> {
    let mut err = vec![[0.0f32; 3]; (w + 2) * 2];
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        let (cur, next) = ((y % 2) * (w + 2), ((y + 1) % 2) * (w + 2));
        err[next..next + w + 2].fill([0.0; 3]);
        for x in 0..w {
            let v: [f32; 3] = std::array::from_fn(|c| t[y * w + x][c] + err[cur + x + 1][c]);
            let d = |k: usize| (0..3).map(|c| (v[c] - INKS[k][c]).powi(2)).sum::<f32>();
            let k = (0..INKS.len())
                .min_by(|&i, &j| d(i).total_cmp(&d(j)))
                .unwrap();
            out[y * w + x] = k as u8;
            for c in 0..3 {
                let e = v[c] - INKS[k][c];
                err[cur + x + 2][c] += e * 7.0 / 16.0;
                err[next + x][c] += e * 3.0 / 16.0;
                err[next + x + 1][c] += e * 5.0 / 16.0;
                err[next + x + 2][c] += e / 16.0;
            }
        }
    }
    out
}

/// The process's user + system CPU time so far, milliseconds (Linux; 0 elsewhere), all
/// threads: on a busy machine it shows the work better than the wall clock.
fn cpu_ms() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // Fields after the command's closing parenthesis; utime and stime are the 12th and 13th.
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // Clock ticks of 10 ms (USER_HZ = 100 on Linux).
    (tick(11) + tick(12)) * 10.0
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: f64| args.get(i).map_or(d, |s| s.parse().expect("a number"));
    let (w, h) = (arg(1, 800.0) as usize, arg(2, 480.0) as usize);
    let runs = arg(3, 5.0) as usize;
    let opts = PaletteDbsOptions {
        ppd: arg(4, 35.0),
        passes: arg(5, 8.0) as u32,
        swaps: arg(6, 1.0) != 0.0,
        max_radius: arg(7, 24.0) as usize,
        ..PaletteDbsOptions::default()
    };
    let t = picture(w, h);
    let seed = floyd_steinberg(&t, w, h);
    let mut times = Vec::new();
    let mut cpu = Vec::new();
    let mut out = Vec::new();
    let mut passes = 0;
    for _ in 0..runs.max(1) {
        let mut idx = seed.clone();
        let (start, cpu0) = (Instant::now(), cpu_ms());
        passes = refine(&t, w, h, &INKS, &mut idx, &opts).expect("refine");
        times.push(start.elapsed().as_secs_f64() * 1e3);
        cpu.push(cpu_ms() - cpu0);
        out = idx;
    }
    times.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    let start = Instant::now();
    let before = cost(&t, w, h, &INKS, &seed, &opts).expect("cost");
    let after = cost(&t, w, h, &INKS, &out, &opts).expect("cost");
    let cost_ms = start.elapsed().as_secs_f64() * 1e3 / 2.0;
    let changed = seed.iter().zip(&out).filter(|(a, b)| a != b).count();
    println!(
        "{w}x{h}, ppd {}: best {:.1} ms, median {:.1} ms over {} runs (process CPU time: best {:.0} ms); {passes} passes; \
         cost {before:.4e} -> {after:.4e} ({:.1}% lower); {:.1}% of pixels changed; one `cost` {cost_ms:.1} ms",
        opts.ppd,
        times[0],
        times[times.len() / 2],
        times.len(),
        cpu[0],
        100.0 * (1.0 - after / before),
        100.0 * changed as f64 / (w * h) as f64
    );
}
