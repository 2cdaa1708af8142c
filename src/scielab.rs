//! The colour error a viewer sees on a display with real inks: S-CIELAB after adapting to the
//! display's white.
//!
//! A reflective panel's "white" is a light grey-blue and its black a dark grey. A viewer adapts
//! to both: the panel's white is seen as white. So the displayed picture is judged relative to
//! the panel:
//!
//! 1. Each displayed pixel (a linear-RGB colour measured on the panel) goes to CIE XYZ (D65),
//!    scaled so that the panel white has `Y = 1`.
//! 2. It is adapted from the panel white to D65 with the Bradford transform.
//! 3. Black-point compensation as Little CMS does it (`cmscnvrt.c`, per channel):
//!    `X' = (X − X_b) · X_w / (X_w − X_b)`, likewise Y and Z, with `X_b…` the panel black after
//!    steps 1–2 and `X_w…` the D65 white, so the panel's black is seen as black. For a neutral
//!    black this is `XYZ' = (XYZ − Y_b·W) / (1 − Y_b)`; a tinted black (a panel's is often a
//!    little blue or purple) is taken to black as well.
//!
//! The original (sRGB, white `Y = 1`, black 0) is taken as it is. Both images are then
//! filtered as the eye filters them (S-CIELAB: Zhang and Wandell's opponent channels, each
//! blurred by a sum of Gaussians, their spreads taken as full widths at half maximum in
//! degrees of visual angle) and compared pixel by pixel in CIELAB (D65): the mean CIEDE2000
//! and ΔE*ab, and the ratio of the mean lightness (displayed over original) to show over- or
//! under-exposure.
//!
//! Sources: X. Zhang and B. A. Wandell, "A spatial extension of CIELAB for digital color
//! image reproduction", SID Digest 1996 (opponent matrix, filter weights and spreads);
//! G. Sharma, W. Wu and E. N. Dalal, "The CIEDE2000 color-difference formula: implementation
//! notes, supplementary test data, and mathematical observations", Color Res. Appl. 30 (2005)
//! (the formula and its test pairs, used in the tests below).

use crate::error::{Error, Result};
use crate::fmath as fm;

/// Linear sRGB (D65) → XYZ, IEC 61966-2-1.
pub(crate) const RGB_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// The D65 white, `Y = 1` (the white of [`RGB_TO_XYZ`]).
pub const D65: [f64; 3] = [0.9505, 1.0, 1.089];

/// Bradford cone response matrix.
const BRADFORD: [[f64; 3]; 3] = [
    [0.8951, 0.2664, -0.1614],
    [-0.7502, 1.7135, 0.0367],
    [0.0389, -0.0685, 1.0296],
];

/// XYZ → Zhang–Wandell opponent channels (luminance, red–green, blue–yellow).
pub(crate) const XYZ_TO_OPP: [[f64; 3]; 3] = [
    [0.279, 0.72, -0.107],
    [-0.449, 0.29, -0.077],
    [0.086, -0.59, 0.501],
];

/// Each opponent channel's filter: (weight, spread in degrees) of each Gaussian.
pub(crate) const FILTERS: [&[(f64, f64)]; 3] = [
    &[(1.00327, 0.05), (0.114416, 0.225), (-0.117686, 7.0)],
    &[(0.616725, 0.0685), (0.383275, 0.826)],
    &[(0.567885, 0.0920), (0.432115, 0.6451)],
];

/// The display's inks as the viewer adapts to them: its white and black, linear RGB as
/// measured (the same scale as the displayed pixels).
#[derive(Clone, Copy, Debug)]
pub struct Adaptation {
    /// The panel's white ink.
    pub white: [f64; 3],
    /// The panel's black ink.
    pub black: [f64; 3],
}

/// The figures of a comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourError {
    /// Mean CIEDE2000 over the pixels.
    pub de2000: f64,
    /// Mean CIE 1976 ΔE*ab.
    pub de76: f64,
    /// Mean L* of the displayed image over that of the original.
    pub lightness_ratio: f64,
}

/// An image in linear RGB, three planes of `width × height`.
#[derive(Clone, Copy, Debug)]
pub struct LinearRgb<'a> {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Red, green and blue, row-major, linear light (1 = the sRGB white).
    pub planes: [&'a [f32]; 3],
}

fn mul(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

fn inverse(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let [a, b, c] = *m;
    let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]);
    let cof = |r1: [f64; 3], r2: [f64; 3], i: usize, j: usize| r1[i] * r2[j] - r1[j] * r2[i];
    [
        [
            cof(b, c, 1, 2) / det,
            -cof(a, c, 1, 2) / det,
            cof(a, b, 1, 2) / det,
        ],
        [
            -cof(b, c, 0, 2) / det,
            cof(a, c, 0, 2) / det,
            -cof(a, b, 0, 2) / det,
        ],
        [
            cof(b, c, 0, 1) / det,
            -cof(a, c, 0, 1) / det,
            cof(a, b, 0, 1) / det,
        ],
    ]
}

fn matmul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// Black-point compensation as Little CMS computes it (`cmscnvrt.c`): each of X, Y and Z
/// scaled and offset so that the display's black (adapted XYZ `black`) goes to 0 and the white
/// (D65) stays: `X' = (X − X_b) · X_w / (X_w − X_b)`. For a neutral black (`X_b = Y_b·X_w`)
/// this is `XYZ' = (XYZ − Y_b·W) / (1 − Y_b)`; a tinted black is taken to black too.
fn compensate(xyz: [f64; 3], black: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| (xyz[c] - black[c]) * D65[c] / (D65[c] - black[c]))
}

impl Adaptation {
    /// No adaptation: an ideal display (white 1, black 0).
    pub const IDEAL: Adaptation = Adaptation {
        white: [1.0; 3],
        black: [0.0; 3],
    };

    /// The matrix from a displayed linear-RGB colour to adapted XYZ (before black-point
    /// compensation), and the display's black in that XYZ.
    fn transform(&self) -> Result<([[f64; 3]; 3], [f64; 3])> {
        let w = mul(&RGB_TO_XYZ, self.white);
        if !(w[1] > 0.0 && w.iter().all(|v| v.is_finite() && *v > 0.0)) {
            return Err(Error::Invalid(format!(
                "the display's white {:?} is not a colour with positive luminance",
                self.white
            )));
        }
        // Bradford: cone responses of the panel white → those of D65.
        let cw = mul(&BRADFORD, w.map(|v| v / w[1]));
        let cd = mul(&BRADFORD, D65);
        let scale = [
            [cd[0] / cw[0], 0.0, 0.0],
            [0.0, cd[1] / cw[1], 0.0],
            [0.0, 0.0, cd[2] / cw[2]],
        ];
        let adapt = matmul(&inverse(&BRADFORD), &matmul(&scale, &BRADFORD));
        let to_xyz = RGB_TO_XYZ.map(|row| row.map(|v| v / w[1]));
        let m = matmul(&adapt, &to_xyz);
        let black = mul(&m, self.black);
        let yb = black[1];
        if !(0.0..1.0).contains(&yb) || (0..3).any(|c| black[c] >= D65[c]) {
            return Err(Error::Invalid(format!(
                "the display's black {:?} is not darker than its white",
                self.black
            )));
        }
        Ok((m, black))
    }
}

impl Adaptation {
    /// The colour a viewer adapted to the display sees for a displayed linear-RGB colour, as
    /// linear sRGB (D65, 1 = white): steps 1–3 of the module docs. The display's white
    /// becomes `[1, 1, 1]` and its black has luminance 0.
    pub fn adapted_linear(&self, displayed: [f64; 3]) -> Result<[f64; 3]> {
        let (m, black) = self.transform()?;
        let xyz = mul(&m, displayed);
        let xyz = compensate(xyz, black);
        Ok(mul(&inverse(&RGB_TO_XYZ), xyz))
    }
}

/// The colour error of a displayed image file against its original on a display whose inks
/// are `inks` (linear RGB as measured; the lightest is its white, the darkest its black), at
/// `ppd` pixels a degree: [`colour_error`] on decoded files (grey images count as three equal
/// channels). The displayed image holds the inks' measured colours (what `convert` writes
/// for a device).
pub fn device_error(
    original: &crate::raster::Image,
    displayed: &crate::raster::Image,
    inks: &[[f64; 3]],
    ppd: f64,
) -> Result<ColourError> {
    let y = |c: &[f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let white = inks.iter().copied().max_by(|a, b| y(a).total_cmp(&y(b)));
    let black = inks.iter().copied().min_by(|a, b| y(a).total_cmp(&y(b)));
    let (Some(white), Some(black)) = (white, black) else {
        return Err(Error::Invalid("a display needs inks".into()));
    };
    let o = crate::quality::image_reflectance(original);
    let d = crate::quality::image_reflectance(displayed);
    let rgb = |r: &crate::quality::Reflectance| -> [Vec<f32>; 3] {
        std::array::from_fn(|c| r.planes[c.min(r.planes.len() - 1)].clone())
    };
    let (po, pd) = (rgb(&o), rgb(&d));
    colour_error(
        &LinearRgb {
            width: o.width,
            height: o.height,
            planes: [&po[0], &po[1], &po[2]],
        },
        &LinearRgb {
            width: d.width,
            height: d.height,
            planes: [&pd[0], &pd[1], &pd[2]],
        },
        &Adaptation { white, black },
        ppd,
    )
}

/// CIELAB (D65) of XYZ.
pub fn lab_of_xyz(xyz: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        const E: f64 = 216.0 / 24389.0;
        const K: f64 = 24389.0 / 27.0;
        if t > E {
            fm::cbrt(t)
        } else {
            (K * t + 16.0) / 116.0
        }
    };
    let [fx, fy, fz] = [f(xyz[0] / D65[0]), f(xyz[1] / D65[1]), f(xyz[2] / D65[2])];
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIEDE2000 colour difference of two CIELAB colours (kL = kC = kH = 1), as Sharma, Wu and
/// Dalal write it out.
pub fn ciede2000(a: [f64; 3], b: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let deg = |r: f64| r * 180.0 / PI;
    let rad = |d: f64| d * PI / 180.0;
    let c1 = fm::hypot(a[1], a[2]);
    let c2 = fm::hypot(b[1], b[2]);
    let cm = (c1 + c2) / 2.0;
    let g = 0.5 * (1.0 - (cm.powi(7) / (cm.powi(7) + 25f64.powi(7))).sqrt());
    let a1 = (1.0 + g) * a[1];
    let a2 = (1.0 + g) * b[1];
    let c1p = fm::hypot(a1, a[2]);
    let c2p = fm::hypot(a2, b[2]);
    let hue = |x: f64, y: f64| {
        if x == 0.0 && y == 0.0 {
            0.0
        } else {
            let h = deg(fm::atan2(y, x));
            if h < 0.0 {
                h + 360.0
            } else {
                h
            }
        }
    };
    let h1 = hue(a1, a[2]);
    let h2 = hue(a2, b[2]);
    let dl = b[0] - a[0];
    let dc = c2p - c1p;
    let dh = if c1p * c2p == 0.0 {
        0.0
    } else if (h2 - h1).abs() <= 180.0 {
        h2 - h1
    } else if h2 - h1 > 180.0 {
        h2 - h1 - 360.0
    } else {
        h2 - h1 + 360.0
    };
    let dhh = 2.0 * (c1p * c2p).sqrt() * fm::sin(rad(dh) / 2.0);
    let lm = (a[0] + b[0]) / 2.0;
    let cmp = (c1p + c2p) / 2.0;
    let hm = if c1p * c2p == 0.0 {
        h1 + h2
    } else if (h1 - h2).abs() <= 180.0 {
        (h1 + h2) / 2.0
    } else if h1 + h2 < 360.0 {
        (h1 + h2 + 360.0) / 2.0
    } else {
        (h1 + h2 - 360.0) / 2.0
    };
    let t = 1.0 - 0.17 * fm::cos(rad(hm - 30.0))
        + 0.24 * fm::cos(rad(2.0 * hm))
        + 0.32 * fm::cos(rad(3.0 * hm + 6.0))
        - 0.20 * fm::cos(rad(4.0 * hm - 63.0));
    let dtheta = 30.0 * fm::exp(-((hm - 275.0) / 25.0).powi(2));
    let rc = 2.0 * (cmp.powi(7) / (cmp.powi(7) + 25f64.powi(7))).sqrt();
    let sl = 1.0 + 0.015 * (lm - 50.0).powi(2) / (20.0 + (lm - 50.0).powi(2)).sqrt();
    let sc = 1.0 + 0.045 * cmp;
    let sh = 1.0 + 0.015 * cmp * t;
    let rt = -fm::sin(2.0 * rad(dtheta)) * rc;
    ((dl / sl).powi(2) + (dc / sc).powi(2) + (dhh / sh).powi(2) + rt * (dc / sc) * (dhh / sh))
        .sqrt()
}

/// A normalised 1-D Gaussian of full width at half maximum `fwhm` pixels, reaching three
/// standard deviations each side (at least one tap).
fn gaussian(fwhm: f64) -> Vec<f64> {
    let sigma = fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
    let r = (3.0 * sigma).ceil().max(0.0) as usize;
    let mut k: Vec<f64> = (0..=2 * r)
        .map(|i| {
            let x = i as f64 - r as f64;
            if sigma > 0.0 {
                fm::exp(-x * x / (2.0 * sigma * sigma))
            } else {
                f64::from(u8::from(i == r))
            }
        })
        .collect();
    let sum: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    k
}

/// Mirrors index `i` (possibly outside) into `0..n`.
fn mirror(i: isize, n: usize) -> usize {
    let n = n as isize;
    let period = 2 * n;
    let mut j = i.rem_euclid(period.max(1));
    if j >= n {
        j = period - 1 - j;
    }
    j as usize
}

/// Separable convolution of a `w × h` plane with `k` along both axes, mirrored at the edges.
fn blur(src: &[f64], w: usize, h: usize, k: &[f64]) -> Vec<f64> {
    let r = (k.len() / 2) as isize;
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        for x in 0..w {
            tmp[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * row[mirror(x as isize + i as isize - r, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = k
                .iter()
                .enumerate()
                .map(|(i, kv)| kv * tmp[mirror(y as isize + i as isize - r, h) * w + x])
                .sum();
        }
    }
    out
}

/// Opponent planes of XYZ pixels, filtered as the eye filters them at `ppd` pixels a degree,
/// back in XYZ.
fn filtered_xyz(xyz: &[[f64; 3]], w: usize, h: usize, ppd: f64) -> Vec<[f64; 3]> {
    let opp: Vec<[f64; 3]> = xyz.iter().map(|p| mul(&XYZ_TO_OPP, *p)).collect();
    let mut planes: [Vec<f64>; 3] = Default::default();
    for (c, filters) in FILTERS.iter().enumerate() {
        let plane: Vec<f64> = opp.iter().map(|p| p[c]).collect();
        let mut acc = vec![0.0; w * h];
        for &(weight, spread) in filters.iter() {
            let b = blur(&plane, w, h, &gaussian(spread * ppd));
            acc.iter_mut().zip(b).for_each(|(a, v)| *a += weight * v);
        }
        planes[c] = acc;
    }
    let back = inverse(&XYZ_TO_OPP);
    (0..w * h)
        .map(|i| mul(&back, [planes[0][i], planes[1][i], planes[2][i]]))
        .collect()
}

/// The colour error of `displayed` (pixels as measured on the display, linear RGB) against
/// `original`, as a viewer adapted to the display's white and black sees it at `ppd` pixels a
/// degree (S-CIELAB, mean CIEDE2000 and ΔE*ab, lightness ratio). See the module docs.
pub fn colour_error(
    original: &LinearRgb<'_>,
    displayed: &LinearRgb<'_>,
    inks: &Adaptation,
    ppd: f64,
) -> Result<ColourError> {
    let (w, h) = (original.width, original.height);
    if (displayed.width, displayed.height) != (w, h) {
        return Err(Error::Invalid(format!(
            "the images differ in size: {w}x{h} and {}x{}",
            displayed.width, displayed.height
        )));
    }
    if w == 0 || h == 0 {
        return Err(Error::Invalid("the images are empty".into()));
    }
    for img in [original, displayed] {
        if img.planes.iter().any(|p| p.len() != w * h) {
            return Err(Error::Invalid(format!(
                "a plane does not hold {w}x{h} pixels"
            )));
        }
    }
    if !(ppd > 0.0 && ppd.is_finite()) {
        return Err(Error::Invalid(format!(
            "{ppd} pixels a degree: expected a positive number"
        )));
    }
    let (m, black) = inks.transform()?;
    let px = |img: &LinearRgb<'_>, i: usize| -> [f64; 3] {
        [0, 1, 2].map(|c| f64::from(img.planes[c][i]))
    };
    let orig: Vec<[f64; 3]> = (0..w * h)
        .map(|i| mul(&RGB_TO_XYZ, px(original, i)))
        .collect();
    let disp: Vec<[f64; 3]> = (0..w * h)
        .map(|i| {
            let xyz = mul(&m, px(displayed, i));
            compensate(xyz, black)
        })
        .collect();
    let fo = filtered_xyz(&orig, w, h, ppd);
    let fd = filtered_xyz(&disp, w, h, ppd);
    let (mut de00, mut de76, mut lo, mut ld) = (0.0, 0.0, 0.0, 0.0);
    for (o, d) in fo.iter().zip(&fd) {
        let (a, b) = (lab_of_xyz(*o), lab_of_xyz(*d));
        de00 += ciede2000(a, b);
        de76 += ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        lo += a[0];
        ld += b[0];
    }
    let n = (w * h) as f64;
    Ok(ColourError {
        de2000: de00 / n,
        de76: de76 / n,
        lightness_ratio: if lo > 0.0 { ld / lo } else { f64::NAN },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ciede2000_matches_sharma_wu_dalal() {
        // Pairs 1, 2, 7, 13, 17, 19 and 25 of the paper's Table 1, to its four decimals.
        let pairs = [
            ([50.0, 2.6772, -79.7751], [50.0, 0.0, -82.7485], 2.0425),
            ([50.0, 3.1571, -77.2803], [50.0, 0.0, -82.7485], 2.8615),
            ([50.0, 0.0, 0.0], [50.0, -1.0, 2.0], 2.3669),
            ([50.0, 2.49, -0.001], [50.0, -2.49, 0.0009], 7.1792),
            ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0], 27.1492),
            ([50.0, 2.5, 0.0], [50.0, 0.0, -2.5], 4.3065),
            (
                [60.2574, -34.0099, 36.2677],
                [60.4626, -34.1751, 39.4387],
                1.2644,
            ),
        ];
        for (a, b, want) in pairs {
            let got = ciede2000(a, b);
            assert!((got - want).abs() < 5e-5, "{a:?} {b:?}: {got} != {want}");
            assert!((ciede2000(b, a) - want).abs() < 5e-5, "not symmetric");
        }
    }

    fn flat(w: usize, h: usize, rgb: [f32; 3]) -> [Vec<f32>; 3] {
        rgb.map(|v| vec![v; w * h])
    }

    fn img(p: &[Vec<f32>; 3], w: usize, h: usize) -> LinearRgb<'_> {
        LinearRgb {
            width: w,
            height: h,
            planes: [&p[0], &p[1], &p[2]],
        }
    }

    #[test]
    fn the_panel_white_and_black_are_seen_as_white_and_black() {
        let (w, h) = (24, 16);
        // A bluish, dim panel white and a black of the same hue (the compensation takes the
        // black as neutral once adapted), as e-paper measures.
        let white = [0.48, 0.59, 0.61];
        let inks = Adaptation {
            white,
            black: white.map(|v| v * 0.03),
        };
        for (orig, shown) in [([1.0, 1.0, 1.0], inks.white), ([0.0, 0.0, 0.0], inks.black)] {
            let o = flat(w, h, orig);
            let d = flat(w, h, shown.map(|v| v as f32));
            let e = colour_error(&img(&o, w, h), &img(&d, w, h), &inks, 35.0).unwrap();
            assert!(e.de2000 < 1e-3 && e.de76 < 1e-3, "{orig:?}: {e:?}");
        }
        // Without adaptation the same panel white is far from white, and darker.
        let o = flat(w, h, [1.0; 3]);
        let d = flat(w, h, inks.white.map(|v| v as f32));
        let e = colour_error(&img(&o, w, h), &img(&d, w, h), &Adaptation::IDEAL, 35.0).unwrap();
        assert!(e.de2000 > 10.0 && e.lightness_ratio < 0.9, "{e:?}");
    }

    #[test]
    fn fine_dither_is_seen_as_its_mean_and_a_coarse_one_is_not() {
        let (w, h) = (96, 96);
        // A checkerboard of black and white: a flat 50% grey in linear light from afar.
        let grey = flat(w, h, [0.5; 3]);
        let board = |cell: usize| -> [Vec<f32>; 3] {
            let p: Vec<f32> = (0..w * h)
                .map(|i| (((i % w) / cell + (i / w) / cell) % 2) as f32)
                .collect();
            [p.clone(), p.clone(), p]
        };
        let fine = board(1);
        let coarse = board(16);
        let at = |d: &[Vec<f32>; 3], ppd: f64| {
            colour_error(&img(&grey, w, h), &img(d, w, h), &Adaptation::IDEAL, ppd).unwrap()
        };
        let near = at(&fine, 60.0);
        let far = at(&coarse, 60.0);
        assert!(near.de2000 < 2.0, "{near:?}");
        assert!(far.de2000 > 5.0 * near.de2000, "{far:?} vs {near:?}");
        assert!((near.lightness_ratio - 1.0).abs() < 0.02, "{near:?}");
        // The same fine board seen from too close (few pixels a degree) shows its texture.
        assert!(at(&fine, 2.0).de2000 > 3.0 * near.de2000);
    }

    #[test]
    fn a_colour_cast_is_measured_and_bad_input_refused() {
        let (w, h) = (16, 16);
        let o = flat(w, h, [0.2, 0.2, 0.2]);
        let d = flat(w, h, [0.2, 0.2, 0.12]);
        let e = colour_error(&img(&o, w, h), &img(&d, w, h), &Adaptation::IDEAL, 35.0).unwrap();
        assert!(e.de2000 > 3.0, "{e:?}");
        let small = flat(8, 8, [0.2; 3]);
        assert!(
            colour_error(&img(&o, w, h), &img(&small, 8, 8), &Adaptation::IDEAL, 35.0).is_err()
        );
        let bad = Adaptation {
            white: [0.1; 3],
            black: [0.2; 3],
        };
        assert!(colour_error(&img(&o, w, h), &img(&o, w, h), &bad, 35.0).is_err());
        assert!(colour_error(&img(&o, w, h), &img(&o, w, h), &Adaptation::IDEAL, 0.0).is_err());
    }
}
