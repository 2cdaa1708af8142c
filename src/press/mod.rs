//! Colour separation for a press: a forward model of what the press prints for given ink
//! amounts, fitted to its characterisation data, and its inverse as a lookup table.
//!
//! The forward model is the Yule–Nielsen modified Neugebauer model in XYZ (Viggiano 1990;
//! Wyble & Berns 2000): with `n` the Yule–Nielsen factor, the 16 solid overprints `Pᵢ`
//! (paper, C, M, CM, …, CMYK) and Demichel weights `wᵢ` of the inks' *effective*
//! coverages, `XYZ^(1/n) = Σ wᵢ Pᵢ^(1/n)`. The effective coverage of each ink is a curve of
//! its nominal (plate) coverage, fitted from the single-ink ramps: it carries the press's
//! dot gain. `n` is chosen to minimise the mean ΔE76 over every patch of the data set.
//!
//! Colours are compared media-relative (ICC relative colorimetric): XYZ is scaled channel
//! by channel so that the paper is the D50 white, then converted to CIELAB (D50).

pub mod cgats;
#[cfg(feature = "icc")]
pub mod icc;
pub mod plates;
pub mod separation;
pub mod transfer;

/// Rendering intent: how colours outside the output's gamut are mapped (the ICC's four
/// names), for the sRGB → CMYK transform of an ICC profile and for a device's inks
/// ([`crate::rendering`], [`crate::method::device`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RenderingIntent {
    /// Perceptual: the whole sRGB gamut compressed into the press's.
    Perceptual,
    /// Media-relative colorimetric (the default): in-gamut colours exact, paper as white.
    #[default]
    Relative,
    /// Saturation: vivid colours for business graphics.
    Saturation,
    /// Absolute colorimetric: the paper's own tint simulated.
    Absolute,
}

impl RenderingIntent {
    /// The intent's name (`perceptual`, `relative`, `saturation`, `absolute`).
    pub fn name(self) -> &'static str {
        match self {
            RenderingIntent::Perceptual => "perceptual",
            RenderingIntent::Relative => "relative",
            RenderingIntent::Saturation => "saturation",
            RenderingIntent::Absolute => "absolute",
        }
    }
}

use crate::fmath as fm;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
pub use cgats::Patch;

/// ColorChecker Classic, sRGB values published by X-Rite (2009 formulation): the colours
/// the separation's accuracy is quoted on.
pub const COLORCHECKER: [[u8; 3]; 24] = [
    [115, 82, 68],
    [194, 150, 130],
    [98, 122, 157],
    [87, 108, 67],
    [133, 128, 177],
    [103, 189, 170],
    [214, 126, 44],
    [80, 91, 166],
    [193, 90, 99],
    [94, 60, 108],
    [157, 188, 64],
    [224, 163, 46],
    [56, 61, 150],
    [70, 148, 73],
    [175, 54, 60],
    [231, 199, 31],
    [187, 86, 149],
    [8, 133, 161],
    [243, 243, 242],
    [200, 200, 200],
    [160, 160, 160],
    [122, 122, 121],
    [85, 85, 85],
    [52, 52, 52],
];

/// The D50 white (ICC PCS), Y = 100.
pub const D50: [f64; 3] = [96.42, 100.0, 82.49];

/// sRGB (linear) to XYZ D50, Bradford-adapted: the matrix of the ICC's sRGB profile.
pub const SRGB_TO_XYZ_D50: [[f64; 3]; 3] = [
    [0.436_074_7, 0.385_064_9, 0.143_080_4],
    [0.222_504_5, 0.716_878_6, 0.060_616_9],
    [0.013_932_2, 0.097_104_5, 0.714_173_3],
];

/// CIELAB of `xyz` relative to `white`.
pub fn lab(xyz: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        if t > 216.0 / 24389.0 {
            fm::cbrt(t)
        } else {
            (24389.0 / 27.0 * t + 16.0) / 116.0
        }
    };
    let (fx, fy, fz) = (
        f(xyz[0] / white[0]),
        f(xyz[1] / white[1]),
        f(xyz[2] / white[2]),
    );
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIE 1976 colour difference.
pub fn delta_e76(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// XYZ (D50, Y = 100 for white) of linear sRGB `rgb` in 0..1.
pub fn srgb_linear_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    let m = SRGB_TO_XYZ_D50;
    let mut out = [0.0; 3];
    for (o, row) in out.iter_mut().zip(&m) {
        *o = 100.0 * (row[0] * rgb[0] + row[1] * rgb[1] + row[2] * rgb[2]);
    }
    out
}

/// Linear sRGB of XYZ (D50, Y = 100 for white), unclipped.
pub fn xyz_to_srgb_linear(xyz: [f64; 3]) -> [f64; 3] {
    let inv = invert3(SRGB_TO_XYZ_D50);
    let mut out = [0.0; 3];
    for (o, row) in out.iter_mut().zip(&inv) {
        *o = (row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2]) / 100.0;
    }
    out
}

/// CIELAB (D50) of an 8-bit sRGB colour.
pub fn srgb8_to_lab(rgb: [u8; 3]) -> [f64; 3] {
    let l = rgb.map(|c| crate::tone::srgb_to_linear(c as f64 / 255.0));
    lab(srgb_linear_to_xyz(l), D50)
}

fn invert3(m: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let c = |a: usize, b: usize, c: usize, d: usize| m[a][b] * m[c][d];
    [
        [
            (c(1, 1, 2, 2) - c(1, 2, 2, 1)) / det,
            (c(0, 2, 2, 1) - c(0, 1, 2, 2)) / det,
            (c(0, 1, 1, 2) - c(0, 2, 1, 1)) / det,
        ],
        [
            (c(1, 2, 2, 0) - c(1, 0, 2, 2)) / det,
            (c(0, 0, 2, 2) - c(0, 2, 2, 0)) / det,
            (c(0, 2, 1, 0) - c(0, 0, 1, 2)) / det,
        ],
        [
            (c(1, 0, 2, 1) - c(1, 1, 2, 0)) / det,
            (c(0, 1, 2, 0) - c(0, 0, 2, 1)) / det,
            (c(0, 0, 1, 1) - c(0, 1, 1, 0)) / det,
        ],
    ]
}

/// The fitted parameters of a press: what ships in `presses/*.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PressParams {
    /// Short name, e.g. `fogra39`.
    pub name: String,
    /// Where the measurements come from, and their licence.
    pub source: String,
    /// Yule–Nielsen factor.
    pub n: f64,
    /// Mean ΔE76 of the model over the data set it was fitted to.
    pub fit_mean_de: f64,
    /// XYZ of the 16 overprints, index `c + 2m + 4y + 8k` (0 = paper).
    pub primaries: Vec<[f64; 3]>,
    /// Per ink (C, M, Y, K): `[nominal, effective]` coverage pairs, nominal rising from 0 to 1.
    pub curves: Vec<Vec<[f64; 2]>>,
}

/// Built-in presses: name, parameters (TOML), and what the name stands for.
const BUILTIN: [(&str, &str); 4] = [
    ("fogra39", include_str!("../../presses/fogra39.toml")),
    ("fogra29", include_str!("../../presses/fogra29.toml")),
    ("tr002", include_str!("../../presses/tr002.toml")),
    ("gracol", include_str!("../../presses/gracol.toml")),
];

/// A press model ready to evaluate.
#[derive(Clone, Debug)]
pub struct Press {
    params: PressParams,
    /// `Pᵢ^(1/n)`.
    roots: [[f64; 3]; 16],
    /// Effective-coverage tables, 1025 entries a ink, over nominal 0..1.
    tables: [Vec<f64>; 4],
    /// Media-relative white scaling (D50 / paper).
    rel: [f64; 3],
}

const TABLE: usize = 1024;

impl Press {
    /// A model from fitted parameters.
    pub fn new(params: PressParams) -> Result<Press> {
        if params.primaries.len() != 16 || params.curves.len() != 4 || params.n <= 0.0 {
            return Err(Error::Invalid(format!(
                "press {}: needs 16 primaries, 4 curves and n > 0",
                params.name
            )));
        }
        if !params.n.is_finite()
            || params
                .primaries
                .iter()
                .flatten()
                .any(|v| !v.is_finite() || *v < 0.0)
        {
            return Err(Error::Invalid(format!(
                "press {}: the overprints' XYZ must be finite and not negative",
                params.name
            )));
        }
        if params
            .curves
            .iter()
            .flatten()
            .any(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(Error::Invalid(format!(
                "press {}: a coverage curve is not finite",
                params.name
            )));
        }
        if params.primaries[0].iter().any(|&v| v <= 0.0) {
            return Err(Error::Invalid(format!(
                "press {}: the paper's XYZ must be positive (it is {:?})",
                params.name, params.primaries[0]
            )));
        }
        let inv = 1.0 / params.n;
        let mut roots = [[0.0; 3]; 16];
        for (r, p) in roots.iter_mut().zip(&params.primaries) {
            *r = p.map(|v| fm::powf(v.max(0.0), inv));
        }
        let tables = [0, 1, 2, 3].map(|i| {
            let curve = &params.curves[i];
            (0..=TABLE)
                .map(|k| interpolate(curve, k as f64 / TABLE as f64))
                .collect()
        });
        let paper = params.primaries[0];
        let rel = [D50[0] / paper[0], D50[1] / paper[1], D50[2] / paper[2]];
        Ok(Press {
            params,
            roots,
            tables,
            rel,
        })
    }

    /// The built-in presses' names.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(n, _)| *n)
    }

    /// A built-in press by name (`fogra39`, `fogra29`, `tr002`, `gracol`) or a `.ti3` file,
    /// fitted on the spot.
    pub fn load(name: &str) -> Result<Press> {
        let key = name.to_ascii_lowercase();
        if let Some((_, text)) = BUILTIN.iter().find(|(n, _)| *n == key) {
            let params: PressParams = toml::from_str(text)
                .map_err(|e| Error::Invalid(format!("built-in press {name}: {e}")))?;
            return Press::new(params);
        }
        let path = Path::new(name);
        if path.exists() || name.contains('.') || name.contains('/') {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            // CGATS files are ASCII but some carry Latin-1 in their comments.
            let text = String::from_utf8_lossy(&bytes);
            let patches = cgats::parse(&text, path)?;
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            return fit(&patches, &stem, &format!("fitted from {name}"))
                .and_then(Press::new)
                .map_err(|e| Error::Invalid(format!("{}: {e}", path.display())));
        }
        let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
        Err(Error::Invalid(format!(
            "unknown press '{name}' (built-in: {}; or a .ti3 file)",
            names.join(", ")
        )))
    }

    /// The parameters.
    pub fn params(&self) -> &PressParams {
        &self.params
    }

    /// Effective coverage of ink `i` at nominal coverage `a` (0..1).
    #[inline]
    pub fn effective(&self, i: usize, a: f64) -> f64 {
        let t = a.clamp(0.0, 1.0) * TABLE as f64;
        let k = (t as usize).min(TABLE - 1);
        let f = t - k as f64;
        let tab = &self.tables[i];
        tab[k] + (tab[k + 1] - tab[k]) * f
    }

    /// Absolute XYZ (D50) printed at nominal coverages `cmyk` (0..1).
    pub fn xyz(&self, cmyk: [f64; 4]) -> [f64; 3] {
        let e = [0, 1, 2, 3].map(|i| self.effective(i, cmyk[i]));
        let mut acc = [0.0; 3];
        for (idx, r) in self.roots.iter().enumerate() {
            let mut w = 1.0;
            for (bit, &ei) in e.iter().enumerate() {
                w *= if idx & (1 << bit) != 0 { ei } else { 1.0 - ei };
            }
            if w != 0.0 {
                for c in 0..3 {
                    acc[c] += w * r[c];
                }
            }
        }
        acc.map(|v| fm::powf(v.max(0.0), self.params.n))
    }

    /// Media-relative XYZ (paper = D50 white).
    pub fn xyz_relative(&self, cmyk: [f64; 4]) -> [f64; 3] {
        let x = self.xyz(cmyk);
        [x[0] * self.rel[0], x[1] * self.rel[1], x[2] * self.rel[2]]
    }

    /// Media-relative CIELAB printed at `cmyk`.
    pub fn lab(&self, cmyk: [f64; 4]) -> [f64; 3] {
        lab(self.xyz_relative(cmyk), D50)
    }

    /// The 8-bit sRGB a screen shows for `cmyk` (paper as white), clipped to the gamut.
    pub fn preview_srgb8(&self, cmyk: [f64; 4]) -> [u8; 3] {
        xyz_to_srgb_linear(self.xyz_relative(cmyk)).map(crate::tone::linear_to_srgb8)
    }

    /// Mean ΔE76 (absolute colorimetry) of the model over measured patches.
    pub fn mean_delta_e(&self, patches: &[Patch]) -> f64 {
        let paper = self.params.primaries[0];
        let white = [
            D50[0] * paper[1] / 100.0,
            paper[1],
            D50[2] * paper[1] / 100.0,
        ];
        let sum: f64 = patches
            .iter()
            .map(|p| delta_e76(lab(self.xyz(p.cmyk), white), lab(p.xyz, white)))
            .sum();
        sum / patches.len() as f64
    }
}

/// Piecewise-linear interpolation in a rising `[x, y]` table.
fn interpolate(curve: &[[f64; 2]], x: f64) -> f64 {
    if curve.is_empty() {
        return x;
    }
    if x <= curve[0][0] {
        return curve[0][1];
    }
    for w in curve.windows(2) {
        if x <= w[1][0] {
            let t = (x - w[0][0]) / (w[1][0] - w[0][0]).max(1e-12);
            return w[0][1] + t * (w[1][1] - w[0][1]);
        }
    }
    curve[curve.len() - 1][1]
}

/// Fits the model to measured patches: the 16 overprints, then for each candidate `n` the
/// effective-coverage curves from the single-ink ramps, keeping the `n` with the lowest
/// mean ΔE76 over all patches.
pub fn fit(patches: &[Patch], name: &str, source: &str) -> Result<PressParams> {
    let on = |v: f64| (v - 1.0).abs() < 1e-6;
    let off = |v: f64| v.abs() < 1e-6;
    let mut primaries = vec![[f64::NAN; 3]; 16];
    for (idx, slot) in primaries.iter_mut().enumerate() {
        let found: Vec<&Patch> = patches
            .iter()
            .filter(|p| {
                (0..4).all(|b| {
                    if idx & (1 << b) != 0 {
                        on(p.cmyk[b])
                    } else {
                        off(p.cmyk[b])
                    }
                })
            })
            .collect();
        if found.is_empty() {
            return Err(Error::Invalid(format!(
                "{source}: no patch for the overprint C{} M{} Y{} K{} (need all 16 solid overprints)",
                idx & 1,
                (idx >> 1) & 1,
                (idx >> 2) & 1,
                (idx >> 3) & 1
            )));
        }
        let mut m = [0.0; 3];
        for p in &found {
            for (mc, v) in m.iter_mut().zip(p.xyz) {
                *mc += v / found.len() as f64;
            }
        }
        *slot = m;
    }
    // Single-ink ramps: (ink, nominal, xyz), averaged by nominal value.
    let mut ramps: [Vec<(f64, [f64; 3], usize)>; 4] = Default::default();
    for p in patches {
        let inked: Vec<usize> = (0..4).filter(|&i| !off(p.cmyk[i])).collect();
        if inked.len() == 1 {
            let i = inked[0];
            let a = p.cmyk[i];
            if let Some(e) = ramps[i].iter_mut().find(|e| (e.0 - a).abs() < 1e-6) {
                for c in 0..3 {
                    e.1[c] += p.xyz[c];
                }
                e.2 += 1;
            } else {
                ramps[i].push((a, p.xyz, 1));
            }
        }
    }
    for r in ramps.iter_mut() {
        for e in r.iter_mut() {
            e.1 = e.1.map(|v| v / e.2 as f64);
        }
        r.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let mut best: Option<PressParams> = None;
    for step in 0..=140 {
        let n = 1.0 + step as f64 * 0.05;
        let inv = 1.0 / n;
        let mut curves = Vec::with_capacity(4);
        for (i, ramp) in ramps.iter().enumerate() {
            let p0 = primaries[0].map(|v| fm::powf(v, inv));
            let p1 = primaries[1 << i].map(|v| fm::powf(v, inv));
            let mut curve = vec![[0.0, 0.0]];
            let mut last = 0.0f64;
            for &(a, xyz, _) in ramp {
                if a <= 0.0 || a >= 1.0 {
                    continue;
                }
                let x = xyz.map(|v| fm::powf(v.max(0.0), inv));
                let (mut num, mut den) = (0.0, 0.0);
                for c in 0..3 {
                    num += (x[c] - p0[c]) * (p1[c] - p0[c]);
                    den += (p1[c] - p0[c]).powi(2);
                }
                // Monotone: a printed ramp never gets lighter as the plate gets more ink. An
                // ink whose solid measures as the paper tells nothing about its ramp.
                let e = if den > 1e-12 {
                    (num / den).clamp(last, 1.0)
                } else {
                    last
                };
                last = e;
                curve.push([a, e]);
            }
            curve.push([1.0, 1.0]);
            curves.push(curve);
        }
        let params = PressParams {
            name: name.to_string(),
            source: source.to_string(),
            n,
            fit_mean_de: 0.0,
            primaries: primaries.clone(),
            curves,
        };
        let press = Press::new(params)?;
        let de = press.mean_delta_e(patches);
        if best.as_ref().is_none_or(|b| de < b.fit_mean_de) {
            let mut p = press.params;
            p.fit_mean_de = (de * 1000.0).round() / 1000.0;
            best = Some(p);
        }
    }
    best.ok_or_else(|| Error::Invalid(format!("{source}: nothing to fit")))
}
