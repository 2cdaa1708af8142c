//! A synthetic photograph of the chart, for tests and demonstrations.

use super::*;

/// The conditions of a [`synthetic_photo`].
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Photo width in pixels.
    pub width: usize,
    /// Photo height in pixels.
    pub height: usize,
    /// The light's and camera's gain on each channel (a colour cast).
    pub gains: [f64; 3],
    /// The exposure: paper white in the middle of the photo reads `exposure × gains`.
    pub exposure: f64,
    /// Radial falloff: brightness at the photo's corners is `1 − vignetting` of the middle's.
    pub vignetting: f64,
    /// Standard deviation of the noise at paper white, linear (shot noise: it scales with
    /// the square root of the signal, plus a floor of a quarter of it).
    pub noise: f64,
    /// The noise's seed.
    pub seed: u64,
    /// Perspective: the far edge of the chart is shorter by this fraction, and the chart
    /// turned by 10 × this many degrees.
    pub tilt: f64,
    /// Standard deviation of a Gaussian blur, in photo pixels (0: none).
    pub blur: f64,
    /// Put a sheet of white paper (reflectance 1) beside the panel.
    pub paper: bool,
    /// Leave the chart out (the panel shows its white only).
    pub blank: bool,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            width: 640,
            height: 400,
            gains: [1.0, 0.92, 0.75],
            exposure: 0.8,
            vignetting: 0.25,
            noise: 0.006,
            seed: 1,
            tilt: 0.08,
            blur: 0.7,
            paper: true,
            blank: false,
        }
    }
}

/// A photograph of `device`'s chart with the inks showing `inks` (linear-light sRGB, one
/// an ink, relative to paper white = 1), on a dark desk in a dark bezel, beside a sheet of
/// white paper, taken under `scene`'s light (cast, exposure, vignetting), tilted in
/// perspective (sampled bilinearly, 2×2 a pixel), blurred, with deterministic noise: 8-bit
/// sRGB. The chart fills the left 55% of the photo, the paper the right 30%.
pub fn synthetic_photo(device: &Device, inks: &[[f64; 3]], scene: &Scene) -> Result<Image> {
    if inks.len() != device.inks.len() {
        return Err(Error::Invalid(format!(
            "{} ink colours for the {} inks of device '{}'",
            inks.len(),
            device.inks.len(),
            device.name
        )));
    }
    let (pw, ph) = (scene.width, scene.height);
    if pw < 64 || ph < 64 {
        return Err(Error::Invalid(format!(
            "a synthetic photo of {pw}x{ph} is too small: at least 64x64"
        )));
    }
    let layout = Layout::new(device)?;
    let idx = layout.indices();
    let (cw, ch) = (layout.width, layout.height);
    let refl: Vec<[f64; 3]> = idx
        .iter()
        .map(|&i| {
            if scene.blank {
                inks[layout.white]
            } else {
                inks[i as usize]
            }
        })
        .collect();
    // Where the chart goes: a box in the left 55%, keystoned and turned.
    let bezel = 0.06 * cw.max(ch) as f64;
    let (bx0, by0, bx1, by1) = (
        0.05 * pw as f64,
        0.08 * ph as f64,
        0.58 * pw as f64,
        0.92 * ph as f64,
    );
    let s = ((bx1 - bx0) / (cw as f64 + 2.0 * bezel)).min((by1 - by0) / (ch as f64 + 2.0 * bezel));
    let (w2, h2) = (cw as f64 * s / 2.0, ch as f64 * s / 2.0);
    let centre = [(bx0 + bx1) / 2.0, (by0 + by1) / 2.0];
    let k = scene.tilt;
    let rough = [
        [-w2 * (1.0 - k), -h2],
        [w2 * (1.0 - k), -h2],
        [w2, h2],
        [-w2, h2],
    ];
    let a = (10.0 * k).to_radians();
    let to = rough.map(|[x, y]| {
        [
            centre[0] + x * a.cos() - y * a.sin(),
            centre[1] + x * a.sin() + y * a.cos(),
        ]
    });
    let from = [
        [0.0, 0.0],
        [cw as f64, 0.0],
        [cw as f64, ch as f64],
        [0.0, ch as f64],
    ];
    let inv = Homography::from_points(&from, &to)
        .and_then(|h| h.inverse())
        .ok_or_else(|| Error::Invalid(format!("`tilt` {k}: the chart folds")))?;
    // The paper: a slightly turned rectangle in the right 30%.
    let pc = [0.79 * pw as f64, 0.5 * ph as f64];
    let (pw2, ph2) = (0.13 * pw as f64, 0.38 * ph as f64);
    let pa = 2f64.to_radians();
    let in_paper = |x: f64, y: f64| {
        let (dx, dy) = (x - pc[0], y - pc[1]);
        let (u, v) = (
            dx * pa.cos() + dy * pa.sin(),
            -dx * pa.sin() + dy * pa.cos(),
        );
        scene.paper && u.abs() < pw2 && v.abs() < ph2
    };
    let chart_at = |u: f64, v: f64| -> [f64; 3] {
        // Bilinear between chart pixel centres.
        let fx = (u - 0.5).clamp(0.0, (cw - 1) as f64);
        let fy = (v - 0.5).clamp(0.0, (ch - 1) as f64);
        let (x0, y0) = (fx as usize, fy as usize);
        let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        [0, 1, 2].map(|c| {
            let p = |x: usize, y: usize| refl[y * cw + x][c];
            (p(x0, y0) * (1.0 - tx) + p(x1, y0) * tx) * (1.0 - ty)
                + (p(x0, y1) * (1.0 - tx) + p(x1, y1) * tx) * ty
        })
    };
    let desk = |x: f64, y: f64| {
        let t = 1.0 + 0.15 * (x * 0.05).sin() * (y * 0.031).cos();
        [0.13 * t, 0.10 * t, 0.075 * t]
    };
    let rmax = (pw as f64).hypot(ph as f64) / 2.0;
    let mut img = vec![[0f64; 3]; pw * ph];
    for y in 0..ph {
        for x in 0..pw {
            let mut acc = [0.0; 3];
            for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                let (u, v) = (x as f64 + sx, y as f64 + sy);
                let r = if in_paper(u, v) {
                    [1.0; 3]
                } else {
                    let [cu, cv] = inv.apply([u, v]);
                    if cu >= 0.0 && cv >= 0.0 && cu < cw as f64 && cv < ch as f64 {
                        chart_at(cu, cv)
                    } else if cu >= -bezel
                        && cv >= -bezel
                        && cu < cw as f64 + bezel
                        && cv < ch as f64 + bezel
                    {
                        [0.03, 0.03, 0.035]
                    } else {
                        desk(u, v)
                    }
                };
                for c in 0..3 {
                    acc[c] += r[c] / 4.0;
                }
            }
            let d =
                (x as f64 + 0.5 - pw as f64 / 2.0).hypot(y as f64 + 0.5 - ph as f64 / 2.0) / rmax;
            let light = scene.exposure * (1.0 - scene.vignetting * d * d);
            img[y * pw + x] = [0, 1, 2].map(|c| acc[c] * light * scene.gains[c]);
        }
    }
    if scene.blur > 0.0 {
        let rad = (3.0 * scene.blur).ceil() as isize;
        let kern: Vec<f64> = (-rad..=rad)
            .map(|i| (-(i * i) as f64 / (2.0 * scene.blur * scene.blur)).exp())
            .collect();
        let sum: f64 = kern.iter().sum();
        let kern: Vec<f64> = kern.iter().map(|v| v / sum).collect();
        for pass in 0..2 {
            let src = img.clone();
            for y in 0..ph as isize {
                for x in 0..pw as isize {
                    let mut acc = [0.0; 3];
                    for (i, kv) in kern.iter().enumerate() {
                        let o = i as isize - rad;
                        let (sx, sy) = if pass == 0 {
                            ((x + o).clamp(0, pw as isize - 1), y)
                        } else {
                            (x, (y + o).clamp(0, ph as isize - 1))
                        };
                        let v = src[sy as usize * pw + sx as usize];
                        for c in 0..3 {
                            acc[c] += kv * v[c];
                        }
                    }
                    img[y as usize * pw + x as usize] = acc;
                }
            }
        }
    }
    let mut state = scene.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(pw * ph * 3);
    for px in &img {
        for &v in px {
            let (u1, u2) = (uniform(), uniform());
            let gauss = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            let sd = scene.noise * (v.max(0.0).sqrt() + 0.25);
            out.push(linear_to_srgb8((v + sd * gauss).clamp(0.0, 1.0)));
        }
    }
    Ok(Image::rgb8(pw, ph, &out))
}
