//! Blue noise by void-and-cluster: deterministic for a seed, little low-frequency energy,
//! and the shipped masks reproducible from the command in their comments.

use halftone::mask::generate::blue_noise;
use halftone::Mask;

/// The seed named in a built-in mask's comment (`... --seed S`).
fn shipped_seed(name: &str) -> u64 {
    let about = Mask::builtin_description(name).unwrap();
    let after = about
        .split("--seed ")
        .nth(1)
        .expect("comment names the seed");
    after
        .split_whitespace()
        .next()
        .unwrap()
        .trim_end_matches(|c: char| !c.is_ascii_digit())
        .parse()
        .unwrap()
}

/// Radially averaged power spectrum of a square binary pattern (mean removed), by a plain
/// separable DFT; `bands[k]` averages the frequencies whose radius rounds to k.
fn radial_spectrum(bits: &[bool], n: usize) -> Vec<f64> {
    let mean = bits.iter().filter(|&&b| b).count() as f64 / bits.len() as f64;
    let (cos, sin): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|k| {
            let a = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            (a.cos(), a.sin())
        })
        .unzip();
    // Rows first: row y's DFT over x.
    let mut rows = vec![(0.0f64, 0.0f64); n * n];
    for y in 0..n {
        for u in 0..n {
            let (mut re, mut im) = (0.0, 0.0);
            for x in 0..n {
                let v = bits[y * n + x] as u8 as f64 - mean;
                re += v * cos[(u * x) % n];
                im -= v * sin[(u * x) % n];
            }
            rows[y * n + u] = (re, im);
        }
    }
    let half = n / 2;
    let mut sum = vec![0.0f64; half + 1];
    let mut count = vec![0usize; half + 1];
    for u in 0..n {
        for v in 0..n {
            let (mut re, mut im) = (0.0, 0.0);
            for y in 0..n {
                let (a, b) = rows[y * n + u];
                let (c, s) = (cos[(v * y) % n], -sin[(v * y) % n]);
                re += a * c - b * s;
                im += a * s + b * c;
            }
            let fu = if u <= half { u } else { n - u } as f64;
            let fv = if v <= half { v } else { n - v } as f64;
            let r = (fu * fu + fv * fv).sqrt().round() as usize;
            if r <= half {
                sum[r] += (re * re + im * im) / (n * n) as f64;
                count[r] += 1;
            }
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(&s, &c)| if c > 0 { s / c as f64 } else { 0.0 })
        .collect()
}

/// White noise of exactly `ones` ones among `n·n` cells (a shuffled pattern, xorshift64*).
fn white_noise(n: usize, ones: usize, seed: u64) -> Vec<bool> {
    let mut s = seed | 1;
    let mut next = move || {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        s.wrapping_mul(0x2545_F491_4F6C_DD1D)
    };
    let mut cells: Vec<bool> = (0..n * n).map(|i| i < ones).collect();
    for i in (1..cells.len()).rev() {
        let j = (next() % (i as u64 + 1)) as usize;
        cells.swap(i, j);
    }
    cells
}

/// Mean power in bands 1..=k (the lowest frequencies, DC excluded).
fn low_bands(spec: &[f64], k: usize) -> f64 {
    spec[1..=k].iter().sum::<f64>() / k as f64
}

#[test]
fn spectrum_has_little_low_frequency_energy() {
    // Measured: the low bands hold 1.4%, 2% and 5% of white noise's power at 1/2, 1/4, 1/8.
    let mask = Mask::builtin("blue-noise-64").unwrap();
    let n = 64;
    for fraction in [2usize, 4, 8] {
        // The pattern the mask gives for a flat 1/2, 1/4, 1/8 of paper.
        let ones = n * n / fraction;
        let blue: Vec<bool> = mask.ranks.iter().map(|&r| (r as usize) < ones).collect();
        let spec = radial_spectrum(&blue, n);
        let mut white_low = 0.0;
        let mut white_high = 0.0;
        for seed in 1..=4 {
            let ws = radial_spectrum(&white_noise(n, ones, seed), n);
            white_low += low_bands(&ws, 4) / 4.0;
            white_high += ws[24..=32].iter().sum::<f64>() / 9.0 / 4.0;
        }
        let blue_low = low_bands(&spec, 4);
        let blue_high = spec[24..=32].iter().sum::<f64>() / 9.0;
        assert!(
            blue_low < 0.1 * white_low,
            "1/{fraction}: low-band power {blue_low:.4} vs white {white_low:.4}"
        );
        // The energy went to high frequencies, where blue noise has more than white.
        assert!(
            blue_high > white_high,
            "1/{fraction}: high-band power {blue_high:.4} vs white {white_high:.4}"
        );
    }
}

#[test]
fn deterministic_for_a_seed() {
    let a = blue_noise(32, 42).unwrap();
    let b = blue_noise(32, 42).unwrap();
    assert_eq!(a, b);
    let c = blue_noise(32, 43).unwrap();
    assert_ne!(a.ranks, c.ranks);
    assert_eq!((a.width, a.height), (32, 32));
}

#[test]
fn shipped_blue_noise_64_is_reproducible() {
    let shipped = Mask::builtin("blue-noise-64").unwrap();
    let seed = shipped_seed("blue-noise-64");
    assert_eq!(shipped.ranks, blue_noise(64, seed).unwrap().ranks);
}

/// A few seconds in a release build (the CI's), slow in a debug build.
#[test]
fn shipped_blue_noise_128_is_reproducible() {
    let shipped = Mask::builtin("blue-noise-128").unwrap();
    let seed = shipped_seed("blue-noise-128");
    assert_eq!(shipped.ranks, blue_noise(128, seed).unwrap().ranks);
}
