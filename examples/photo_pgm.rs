//! Writes a photo-like 8-bit PGM of any size to standard output, one row at a time, so a
//! gigapixel test image never has to fit in memory (`scripts/gigapixel.sh`).
//!
//! Usage: `photo_pgm WIDTH HEIGHT > out.pgm`. The picture: soft light falling across the
//! frame, a few large shaded discs with sharp rims, fine stripes, and film grain from a
//! fixed-seed generator: smooth areas, edges and texture, like a photograph, and the same
//! bytes on every run.
// A test or benchmark's own pictures: the standard library's functions are fine here.
#![allow(clippy::disallowed_methods)]

use std::io::Write;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("WIDTH HEIGHT"))
        .collect();
    let [w, h] = args[..] else {
        panic!("usage: photo_pgm WIDTH HEIGHT")
    };
    let out = std::io::stdout();
    let mut out = std::io::BufWriter::with_capacity(1 << 20, out.lock());
    write!(out, "P5\n{w} {h}\n255\n").unwrap();
    let (wf, hf) = (w as f32, h as f32);
    // Discs: centre x, centre y, radius (fractions of the height), brightness.
    let discs = [
        (0.30, 0.35, 0.22, 0.85f32),
        (0.70, 0.55, 0.30, 0.25),
        (0.50, 0.80, 0.15, 0.60),
    ];
    // Light across the frame, per column (cheap per pixel afterwards).
    let light: Vec<f32> = (0..w)
        .map(|x| 0.25 + 0.5 * (x as f32 / wf) + 0.08 * (x as f32 * 0.013).sin())
        .collect();
    let mut row = vec![0u8; w];
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for y in 0..h {
        let yf = y as f32;
        let shade = 0.15 * (yf / hf - 0.5);
        for (x, o) in row.iter_mut().enumerate() {
            let xf = x as f32;
            let mut v = light[x] + shade;
            for &(cx, cy, r, b) in &discs {
                let (dx, dy) = ((xf - cx * wf) / hf, yf / hf - cy);
                let d2 = dx * dx + dy * dy;
                if d2 < r * r {
                    // A lit sphere: brighter towards its upper left, dark rim.
                    let t = 1.0 - d2 / (r * r);
                    v = b * (0.4 + 0.6 * t.sqrt()) + 0.1 * (-dx - dy) / r;
                }
            }
            if (x / 3 + y / 97) % 41 == 0 {
                v *= 0.7;
            }
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            v += ((seed >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.06;
            *o = (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        }
        out.write_all(&row).unwrap();
    }
    out.flush().unwrap();
}
