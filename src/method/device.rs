//! Halftoning for real inks: rendering intents, tone and gamut mapping, and a palette
//! diffusion that stays stable when the inks cannot make a colour.
//!
//! A reflective panel's inks are dull: its white is a light grey, its black a dark grey, its
//! red a brick. The viewer adapts to the panel's white and black, so the picture is rendered
//! **relative** to them: the inks are taken as that viewer sees them (Bradford adaptation to
//! the panel white and black-point compensation, [`Adaptation::adapted_linear`]), the panel
//! white being `[1, 1, 1]`. Then the picture is mapped into what the inks can show by
//! dithering (the hull of the inks in linear light, [`Hull`]) by the rendering intent:
//!
//! - **perceptual**: the tone range stretched to the panel's (`tone`, automatic from the
//!   luminance histogram) and colours compressed towards the neutral of their own luminance,
//!   hue kept, the outer part of the gamut softly (`gamut`, automatic from how far the
//!   picture's colours reach past the inks);
//! - **relative** (colorimetric, with black-point compensation): colours inside the inks'
//!   hull are kept, those outside clipped into it at their luminance;
//! - **saturation**: colours pushed out to fill the inks' gamut, then clipped;
//! - **absolute**: the picture as it is against the inks as measured (no mapping; the
//!   palette diffusion of [`super::diffusion`]).
//!
//! Then the mapped picture is dithered to the adapted inks: error diffusion measured against
//! the mapped target, the error kept in bounds, and neutral parts of the picture made with
//! the neutral inks only ([`Dither::Diffuse`]); palette DBS seeded from that diffusion
//! ([`Dither::Dbs`]); or ordered palette dithering ([`Dither::Ordered`]).
//!
//! The mapping runs through a 17³ table over the input's linear light (nodes spaced as the
//! square of their index, so dark colours get finer steps) with tetrahedral interpolation:
//! the identity is exact through it, and the map is computed at 4,913 nodes instead of every
//! pixel.

use rayon::prelude::*;

use super::diffusion::kernels::Kernel;
use super::gamut::{linear_of_oklab, oklab as oklab64, Cusps, Hull, Line, HUE_CHROMA, LUMA};
use super::Method;
use crate::error::{Error, Result};
use crate::mask::Mask;
use crate::press::RenderingIntent as Intent;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};
use crate::scielab::Adaptation;

/// A strength that may be chosen from the picture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Amount {
    /// Chosen from the picture's histogram.
    Auto,
    /// A fixed strength, 0 (off) to 1 (full).
    Fixed(f32),
}

impl std::str::FromStr for Amount {
    type Err = String;

    /// `auto`, or a number from 0 to 1.
    fn from_str(s: &str) -> std::result::Result<Amount, String> {
        let t = s.trim();
        if t.eq_ignore_ascii_case("auto") {
            return Ok(Amount::Auto);
        }
        if t.eq_ignore_ascii_case("off") {
            return Ok(Amount::Fixed(0.0));
        }
        match t.parse::<f32>() {
            Ok(v) if (0.0..=1.0).contains(&v) => Ok(Amount::Fixed(v)),
            _ => Err(format!(
                "'{s}': expected auto, off or a strength from 0 to 1"
            )),
        }
    }
}

impl std::fmt::Display for Amount {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Amount::Auto => write!(f, "auto"),
            Amount::Fixed(v) => write!(f, "{v}"),
        }
    }
}

/// How the picture is fitted to the inks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rendering {
    /// The rendering intent.
    pub intent: Intent,
    /// Exposure in stops (0: none; +1 doubles the light).
    pub exposure: f32,
    /// Chroma multiplier at constant luminance (1: none, 0: grey).
    pub saturation: f32,
    /// Tone-range stretch (perceptual intent).
    pub tone: Amount,
    /// Gamut compression (perceptual intent).
    pub gamut: Amount,
}

impl Default for Rendering {
    fn default() -> Self {
        Rendering {
            intent: Intent::Perceptual,
            exposure: 0.0,
            saturation: 1.0,
            tone: Amount::Auto,
            gamut: Amount::Auto,
        }
    }
}

/// How the mapped picture becomes ink indices.
#[derive(Clone, Debug)]
pub enum Dither {
    /// Error diffusion with a kernel.
    Diffuse {
        /// The kernel.
        kernel: Kernel,
        /// Alternate the direction every row.
        serpentine: bool,
        /// Share of the error passed on, 0..1.
        strength: f32,
    },
    /// Palette DBS seeded from Floyd–Steinberg diffusion.
    Dbs {
        /// At most this many passes.
        passes: u32,
    },
    /// Ordered palette dithering with a threshold mask.
    Ordered {
        /// The mask.
        mask: Mask,
    },
}

/// The picture mapped for the inks, ready to dither.
#[derive(Clone, Debug)]
pub struct Mapped {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear RGB, row-major, as the adapted viewer should see it.
    pub target: Vec<[f32; 3]>,
    /// Whether each pixel is neutral enough to be made with the neutral inks alone.
    pub neutral: Vec<bool>,
    /// The inks each pixel is not to be made with (bit `k`: ink `k`): the chromatic inks
    /// where it is neutral, and inks of a hue far from its own ([`HUE_APART`]); bit
    /// [`NEUTRAL_BIT`] marks it neutral.
    pub avoid: Vec<u32>,
    /// The inks as the adapted viewer sees them, linear RGB.
    pub inks: Vec<[f32; 3]>,
    /// Which inks are neutral (black, white, greys).
    pub neutral_inks: Vec<bool>,
}

/// Oklab chroma below which a mapped colour counts as neutral.
const NEUTRAL_CHROMA: f32 = 0.025;
/// Oklab chroma below which an ink counts as neutral.
const NEUTRAL_INK_CHROMA: f32 = 0.04;
/// A table node's colour: linear RGB and its Oklab.
type NodeColour = ([f64; 3], [f64; 3]);
/// Table nodes along each axis.
const NODES: usize = 17;
/// How far (a share of the way) a chromatic colour the perceptual map aims at is drawn in
/// towards the mean of the inks it may use, at chroma [`PULL_CHROMA`] and over (less below,
/// in proportion: no step). The cusp-directed map puts saturated colours on the hull's
/// surface, often on a face that holds the neutral axis (red, white and black): there an
/// ink off the face, once chosen, leaves an error diffusion can never pay back, and the
/// patch drifts (a flat red on bwry-3in97 went from dark red to orange-red down the patch,
/// CIEDE2000 7.8 between its top and bottom thirds). Drawn in, the aim is inside the hull
/// and the error settles.
const PULL: f64 = 0.04;
/// Oklab chroma from which a colour is drawn in by the whole of [`PULL`].
const PULL_CHROMA: f64 = 0.08;
/// The bit of an [`Mapped::avoid`] mask that marks a neutral pixel (inks use bits 0 to 15).
pub const NEUTRAL_BIT: u32 = 1 << 31;
/// Hues further apart than this (radians; a quarter turn) are opposite: an ink of such a hue
/// is not used for a colour, where both have an Oklab chroma of [`HUE_CHROMA`] or more and
/// another ink's hue is nearer the colour's. Red dots in green grass (yellow is nearer),
/// green or blue dots in a red: the eye sees them as a change of hue, not as the colour's
/// error made good. The nearest ink is never refused: a violet on black, white, red and
/// yellow inks fades towards a dull red-purple (see `Cusps::nearest_hue`) and may use red.
pub const HUE_APART: f64 = std::f64::consts::FRAC_PI_2;

/// A palette method for real inks: see the module docs.
#[derive(Clone, Debug)]
pub struct InkMethod {
    name: String,
    /// The inks as shown on the panel, linear RGB.
    shown: Vec<[f64; 3]>,
    /// The palette written with the halftone (the inks' colours as 8-bit sRGB).
    palette: Vec<[u8; 3]>,
    ppd: f64,
    rendering: Rendering,
    dither: Dither,
}

impl InkMethod {
    /// A method for inks shown as `shown` (linear RGB, in index order; 2 to 16), written
    /// with `palette`, viewed at `ppd` pixels a degree.
    pub fn new(
        name: &str,
        shown: Vec<[f64; 3]>,
        palette: Vec<[u8; 3]>,
        ppd: f64,
        rendering: Rendering,
        dither: Dither,
    ) -> Result<InkMethod> {
        if !(2..=16).contains(&shown.len()) || shown.len() != palette.len() {
            return Err(Error::Invalid(format!(
                "{name}: a device needs 2 to 16 inks, not {}",
                shown.len()
            )));
        }
        if !(ppd.is_finite() && ppd > 0.0) {
            return Err(Error::Invalid(format!(
                "{name}: {ppd} pixels a degree: expected a positive number"
            )));
        }
        let check = |field: &'static str, v: f32, lo: f32, hi: f32| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(Error::Option {
                    field,
                    value: v.to_string(),
                    msg: format!("expected a number from {lo} to {hi}"),
                })
            }
        };
        check("exposure", rendering.exposure, -8.0, 8.0)?;
        check("saturation", rendering.saturation, 0.0, 4.0)?;
        for (field, a) in [("tone", rendering.tone), ("gamut", rendering.gamut)] {
            if let Amount::Fixed(v) = a {
                check(field, v, 0.0, 1.0)?;
            }
        }
        if let Dither::Diffuse { strength, .. } = dither {
            check("strength", strength, 0.0, 1.0)?;
        }
        Ok(InkMethod {
            name: name.to_string(),
            shown,
            palette,
            ppd,
            rendering,
            dither,
        })
    }

    /// The inks as the viewer sees them under the intent.
    fn viewed_inks(&self) -> Result<Vec<[f64; 3]>> {
        if self.rendering.intent == Intent::Absolute {
            return Ok(self.shown.clone());
        }
        let y = |c: &[f64; 3]| LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2];
        let white = *self
            .shown
            .iter()
            .max_by(|a, b| y(a).total_cmp(&y(b)))
            .expect("inks");
        let black = *self
            .shown
            .iter()
            .min_by(|a, b| y(a).total_cmp(&y(b)))
            .expect("inks");
        let a = Adaptation { white, black };
        self.shown
            .iter()
            .map(|c| a.adapted_linear(*c))
            .collect::<Result<Vec<_>>>()
            .map_err(|e| Error::Invalid(format!("{}: {e}", self.name)))
    }

    /// What maps the picture for the inks, row by row, and the inks as the viewer sees them
    /// (linear RGB) with which of them are neutral; with `table`, the nearest-ink table for
    /// diffusion too (built while the picture is sampled).
    fn prepare<'a>(&self, input: &'a Planes<'a>, table: bool) -> Result<Prepared<'a>> {
        let (w, h) = (input.width, input.height);
        let planes = input.rgb("a device")?;
        let inks = self.viewed_inks()?;
        let hull = Hull::new(&inks);
        let inks32: Vec<[f32; 3]> = inks.iter().map(|c| c.map(|v| v as f32)).collect();
        // The darkest and the lightest ink are the neutral axis; greys between them too.
        let neutral_inks: Vec<bool> = inks
            .iter()
            .map(|c| {
                let y = LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2];
                let lab = oklab(c.map(|v| v as f32));
                let grey = oklab(hull.anchor(y).map(|v| v as f32));
                (lab[1] - grey[1]).hypot(lab[2] - grey[2]) < NEUTRAL_INK_CHROMA
            })
            .collect();
        // Where a pixel is neutral, the inks not to use: the chromatic ones (none when fewer
        // than two inks are neutral: then every ink may make a grey).
        let chromatic = if neutral_inks.iter().filter(|&&g| g).count() >= 2 {
            neutral_inks
                .iter()
                .enumerate()
                .filter(|(_, &g)| !g)
                .fold(0u32, |m, (k, _)| m | 1 << k)
        } else {
            0
        };
        let (lut, table) = rayon::join(
            || self.map_table(planes, w, h, &hull, &inks, &neutral_inks),
            || table.then(|| NearestTable::of(&inks32, &neutral_inks)),
        );
        // Per-plane code → (node, weight) tables.
        let index = |p: &PlaneRef<'_>| -> Vec<(u8, f32)> {
            p.tone.iter().map(|&v| Lut::locate(v)).collect()
        };
        let idx: Vec<Vec<(u8, f32)>> = if input.planes.len() == 1 {
            vec![index(planes[0])]
        } else {
            planes.iter().map(|p| index(p)).collect()
        };
        let mapper = RowMapper {
            lut,
            chromatic,
            idx,
            planes,
            width: w,
            height: h,
        };
        Ok(Prepared {
            mapper,
            inks: inks32,
            neutral_inks,
            table,
        })
    }

    /// The table of the map from the picture's linear RGB to the colours aimed at, fitted
    /// to the picture (its statistics from a sample) as the intent says.
    fn map_table(
        &self,
        planes: [&PlaneRef<'_>; 3],
        w: usize,
        h: usize,
        hull: &Hull,
        inks: &[[f64; 3]],
        neutral_inks: &[bool],
    ) -> Lut {
        let r = self.rendering;
        let gain = 2f64.powf(r.exposure as f64);
        let sat = r.saturation as f64;
        // Before tone and gamut: exposure and saturation.
        let pre = move |c: [f64; 3]| -> [f64; 3] {
            let c = c.map(|v| v * gain);
            if sat == 1.0 {
                return c;
            }
            let y = LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2];
            c.map(|v| y + sat * (v - y))
        };
        let linear = |i: usize| -> [f64; 3] {
            std::array::from_fn(|c| {
                let p = planes[c];
                let code = match p.samples {
                    SamplesRef::U8(s) => s[i] as usize,
                    SamplesRef::U16(s) => s[i] as usize,
                };
                p.tone[code] as f64
            })
        };
        // Statistics from a sample of pixels (a fixed stride: deterministic), inside any
        // margins of white: a canvas padded to the panel's size renders its picture as the
        // picture alone would be.
        let (x0, y0, bw, bh) = content_box(planes, w, h);
        let n = bw * bh;
        let stride = (n / 10_000).max(1);
        let sample: Vec<[f64; 3]> = (0..n)
            .step_by(stride)
            .map(|j| pre(linear((y0 + j / bw) * w + x0 + j % bw)))
            .collect();
        let perceptual = r.intent == Intent::Perceptual;
        let tone = if perceptual {
            tone_curve(&sample, r.tone)
        } else {
            ToneCurve::IDENTITY
        };
        let toned = |c: [f64; 3]| tone.apply(c);
        // Perceptual: hues the inks lack moved to the nearest they make, and colours
        // compressed towards the lightness of the inks' cusp at their hue (a solid hull
        // only: a flat one has one lightness a hue).
        let cusps = (perceptual && hull.is_solid()).then(|| Cusps::new(inks));
        let hue_rule = |c: [f64; 3], lab: [f64; 3]| -> ([f64; 3], f64) {
            let own = LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2];
            let Some(cusps) = &cusps else {
                return (c, own);
            };
            let [l, a, b] = lab;
            let ch = (a * a + b * b).sqrt();
            if ch < 1e-6 {
                return (c, own);
            }
            // The hue rendered, the colour at it and its chroma.
            let (h, c, ch) = match cusps.nearest_hue(b.atan2(a), ch) {
                Some((_, 0.0, _)) => (b.atan2(a), c, ch),
                Some((h, _, keep)) => {
                    let ch = ch * keep;
                    (h, linear_of_oklab([l, ch * h.cos(), ch * h.sin()]), ch)
                }
                None => (0.0, linear_of_oklab([l, 0.0, 0.0]), 0.0),
            };
            // The luminance to compress from: the cusp's lightness as far as the colour's
            // chroma reaches the cusp's, its own for a grey.
            let (lc, cc) = cusps.at(h);
            let k = if cc > 1e-6 { (ch / cc).min(1.0) } else { 0.0 };
            let lf = l + k * (lc - l);
            (c, lf * lf * lf)
        };
        // A node's colour (before the squeeze): the table's nodes are at `Lut::position`.
        let colour = |i: usize| -> [f64; 3] {
            let (r, g, b) = (i % NODES, (i / NODES) % NODES, i / (NODES * NODES));
            toned(pre([r, g, b].map(|k| Lut::position(k) as f64)))
        };
        // The inks' hues (Oklab a, b over chroma) where they have one.
        let ink_hues: Vec<Option<[f64; 2]>> = inks
            .iter()
            .zip(neutral_inks)
            .map(|(c, &g)| {
                let [_, a, b] = oklab64(*c);
                let ch = a.hypot(b);
                (!g && ch >= HUE_CHROMA).then(|| [a / ch, b / ch])
            })
            .collect();
        // The inks of a hue opposite to `c`'s (see `HUE_APART`).
        let opposite = |lab: [f64; 3]| -> u32 {
            let [_, a, b] = lab;
            let ch = (a * a + b * b).sqrt();
            if ch < HUE_CHROMA || self.rendering.intent == Intent::Absolute {
                return 0;
            }
            let apart = HUE_APART.cos();
            let mut near = [f64::NEG_INFINITY; 16];
            for (d, u) in near.iter_mut().zip(&ink_hues) {
                if let Some([ua, ub]) = u {
                    *d = (a * ua + b * ub) / ch;
                }
            }
            let nearest = near.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            near.iter().enumerate().fold(0, |m, (k, &d)| {
                if d > f64::NEG_INFINITY && d < apart && d < nearest {
                    m | 1 << k
                } else {
                    m
                }
            })
        };
        // Each node's inks of an opposite hue, and the hull of the other inks for each set
        // of them: a colour is mapped into what the inks it may use can make, so that the
        // dithering (which refuses the others) reaches what the map aims at.
        let (nodes, avoid): (Vec<NodeColour>, Vec<u32>) = (0..NODES * NODES * NODES)
            .into_par_iter()
            .with_min_len(NODES * NODES)
            .map(|i| {
                let c = colour(i);
                let lab = oklab64(c);
                ((c, lab), opposite(lab))
            })
            .unzip();
        let mut hulls: Vec<(u32, Hull)> = vec![(0, hull.clone())];
        for &m in &avoid {
            if !hulls.iter().any(|(k, _)| *k == m) {
                let kept: Vec<[f64; 3]> = (0..inks.len())
                    .filter(|k| m >> k & 1 == 0)
                    .map(|k| inks[k])
                    .collect();
                hulls.push((m, Hull::new(&kept)));
            }
        }
        // The mean of the inks a set leaves (all of them when it leaves none).
        let centre_of = |m: u32| -> [f64; 3] {
            let kept: Vec<&[f64; 3]> = (0..inks.len())
                .filter(|k| m >> k & 1 == 0)
                .map(|k| &inks[k])
                .collect();
            let kept = if kept.is_empty() {
                inks.iter().collect()
            } else {
                kept
            };
            std::array::from_fn(|c| kept.iter().map(|v| v[c]).sum::<f64>() / kept.len() as f64)
        };
        let hull_of = |m: u32| -> &Hull {
            &hulls
                .iter()
                .find(|(k, _)| *k == m)
                .expect("a hull for every set")
                .1
        };
        // The line a colour is compressed along: from the neutral of its own luminance, or
        // (perceptual, solid hull) from the neutral at its cusp's lightness, its hue moved
        // by the hue rule first.
        let line_of = |c: [f64; 3], lab: Option<[f64; 3]>, hull: &Hull| -> ([f64; 3], Line) {
            if cusps.is_none() {
                return (c, hull.line(c));
            }
            let (c, yf) = hue_rule(c, lab.unwrap_or_else(|| oklab64(c)));
            (c, hull.line_from(c, yf))
        };
        // How far out the picture's colours reach, for the intents that scale by it; beside
        // it, where each node's line leaves the inks' hull (neither needs the other).
        let (mut reaches, lines): (Vec<f64>, Vec<([f64; 3], Line)>) = rayon::join(
            || {
                if matches!(r.intent, Intent::Perceptual | Intent::Saturation) {
                    sample
                        .par_iter()
                        .with_min_len(1024)
                        .map(|c| line_of(toned(*c), None, hull).1.reach.min(4.0))
                        .collect()
                } else {
                    Vec::new()
                }
            },
            || {
                (0..NODES * NODES * NODES)
                    .into_par_iter()
                    .with_min_len(NODES * NODES)
                    .map(|i| line_of(nodes[i].0, Some(nodes[i].1), hull_of(avoid[i])))
                    .collect()
            },
        );
        let mut pct = |p: f64| -> f64 {
            if reaches.is_empty() {
                0.0
            } else {
                let at = ((reaches.len() - 1) as f64 * p).round() as usize;
                *reaches.select_nth_unstable_by(at, f64::total_cmp).1
            }
        };
        let squeeze = match r.intent {
            Intent::Perceptual => Squeeze::compress(r.gamut, pct(0.99)),
            Intent::Saturation => Squeeze::Scale((1.0 / pct(0.75).max(0.2)).clamp(1.25, 2.5)),
            _ => Squeeze::Scale(1.0),
        };
        let node = |i: usize| -> ([f32; 4], u32) {
            let ((moved, line), hull) = (&lines[i], hull_of(avoid[i]));
            let scale = squeeze.factor(line.reach);
            let m = if line.dir == [0.0; 3] || scale == 1.0 {
                // Not moved: the line found is the one to clip along.
                hull.clip_line(line)
            } else if line.reach > 1.0 {
                // Outside: clipped (slid along the face it leaves by towards the hue the
                // inks have), then drawn in as its reach says (`scale · reach` of the way
                // out from the anchor): a colour far out keeps the clip's chroma instead of
                // stopping where its line first meets the hull.
                let (a, e) = (line.anchor, hull.clip_line(line).colour);
                let out = scale * line.reach;
                hull.clip(std::array::from_fn(|k| a[k] + out * (e[k] - a[k])))
            } else {
                let a = line.anchor;
                hull.clip(std::array::from_fn(|k| {
                    moved[k] + (scale - 1.0) * (moved[k] - a[k])
                }))
            }
            .colour;
            // Chroma against the neutral of the same luminance (the inks' own black may
            // keep a tint after black-point compensation).
            let chroma_of = |m: [f64; 3]| {
                let y = LUMA[0] * m[0] + LUMA[1] * m[1] + LUMA[2] * m[2];
                let lab = oklab(m.map(|v| v as f32));
                let grey = oklab(hull.anchor(y).map(|v| v as f32));
                (lab[1] - grey[1]).hypot(lab[2] - grey[2])
            };
            let mut chroma = chroma_of(m);
            let m = if cusps.is_some() && chroma > 0.0 {
                // Perceptual: a colour aimed at the hull's surface drawn in a little towards
                // the mean of the inks it may use (see `PULL`).
                let pull = PULL * (chroma as f64 / PULL_CHROMA).min(1.0);
                let c = centre_of(avoid[i]);
                let m: [f64; 3] = std::array::from_fn(|k| m[k] + pull * (c[k] - m[k]));
                chroma = chroma_of(m);
                m
            } else {
                m
            };
            let m = if cusps.is_some() && chroma < NEUTRAL_CHROMA {
                // Rendered with the neutral inks alone: aimed at the neutral of its
                // luminance (a faded hue keeps a trace of chroma the neutral inks cannot show).
                hull.anchor(LUMA[0] * m[0] + LUMA[1] * m[1] + LUMA[2] * m[2])
            } else {
                m
            };
            let m = m.map(|v| v as f32);
            ([m[0], m[1], m[2], chroma], avoid[i])
        };
        Lut::build(node)
    }

    /// The picture mapped for the inks: see the module docs.
    pub fn map(&self, input: &Planes<'_>) -> Result<Mapped> {
        let Prepared {
            mapper,
            inks,
            neutral_inks,
            ..
        } = self.prepare(input, false)?;
        let (w, h) = (mapper.width, mapper.height);
        let mut target = vec![[0f32; 3]; w * h];
        let mut avoid = vec![0u32; w * h];
        target
            .par_chunks_mut(w.max(1))
            .zip(avoid.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(y, (trow, arow))| mapper.rows(y, trow, arow));
        Ok(Mapped {
            width: w,
            height: h,
            target,
            neutral: avoid.iter().map(|&a| a & NEUTRAL_BIT != 0).collect(),
            avoid,
            inks,
            neutral_inks,
        })
    }

    /// [`diffuse`] of [`Self::map`]: for a Floyd–Steinberg-shaped kernel each band maps its
    /// own rows; for other kernels the two overlap, the rows mapped on one thread, block by
    /// block, while the diffusion (one row after another) takes them on another. The same
    /// values either way, so the same indices.
    fn diffuse_piped(
        &self,
        input: &Planes<'_>,
        kernel: &Kernel,
        serpentine: bool,
        strength: f32,
    ) -> Result<Vec<u8>> {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Mutex;
        let Prepared {
            mapper,
            inks,
            table,
            ..
        } = self.prepare(input, true)?;
        let (w, h) = (mapper.width, mapper.height);
        let table = table.expect("asked for");
        let d = Diffusion::new(&inks, table, kernel, serpentine, strength);
        if let Some(wt) = d.fs_weights() {
            // Each band maps its own rows as it goes.
            let fill = |y0: usize, block: &mut Block| mapper.rows(y0, &mut block.0, &mut block.1);
            return Ok(d.bands(wt, &fill, w, h));
        }
        let block_rows = (16_384 / w.max(1)).clamp(1, 64);
        let blocks = h.div_ceil(block_rows);
        let slots: Vec<Mutex<Option<Block>>> = (0..blocks).map(|_| Mutex::new(None)).collect();
        let ready = AtomicUsize::new(0);
        // Blocks handed back by the diffusion, for the mapping to fill again.
        let free: Mutex<Vec<Block>> = Mutex::new(Vec::new());
        /// Marks the mapping stopped if it unwinds, so the diffusion does not wait for it.
        struct Stopped<'a>(&'a AtomicUsize);
        impl Drop for Stopped<'_> {
            fn drop(&mut self) {
                if std::thread::panicking() {
                    self.0.store(usize::MAX, Ordering::Release);
                }
            }
        }
        // The mapping first: with one thread, it runs to the end before the diffusion starts.
        let ((), idx) = rayon::join(
            || {
                let _stop = Stopped(&ready);
                for (b, slot) in slots.iter().enumerate() {
                    let y0 = b * block_rows;
                    let n = (h - y0).min(block_rows) * w;
                    // A block the diffusion is done with, or a new one.
                    let spare = free.lock().unwrap_or_else(|e| e.into_inner()).pop();
                    let mut block = spare.unwrap_or_default();
                    block.0.resize(n, [0.0; 3]);
                    block.1.resize(n, 0);
                    mapper.rows(y0, &mut block.0, &mut block.1);
                    *slot.lock().unwrap_or_else(|e| e.into_inner()) = Some(block);
                    ready.store(b + 1, Ordering::Release);
                }
            },
            || {
                let mut rows = PipedRows {
                    width: w,
                    block_rows,
                    slots: &slots,
                    ready: &ready,
                    free: &free,
                    current: (usize::MAX, (Vec::new(), Vec::new())),
                };
                d.run(&mut rows, w, h)
            },
        );
        Ok(idx)
    }

    /// Ink indices (row-major) for a mapped picture.
    pub fn indices(&self, m: &Mapped) -> Result<Vec<u8>> {
        Ok(match &self.dither {
            Dither::Diffuse {
                kernel,
                serpentine,
                strength,
            } => diffuse(m, kernel, *serpentine, *strength),
            Dither::Dbs { passes } => {
                let fs = Kernel::builtin("floyd-steinberg").expect("built-in kernel");
                // Started from diffusion without the first band's priming (DBS settles the
                // pattern itself; primed starts left it drifting more at a patch's top).
                let mut idx = diffuse_primed(m, &fs, true, 1.0, 0);
                let mut opts = super::palette_dbs::PaletteDbsOptions {
                    ppd: self.ppd,
                    passes: *passes,
                    ..Default::default()
                };
                // Chroma weighed a little over luminance (measured best on photos with the
                // S-CIELAB score); neutral pixels keep to the neutral inks and no pixel takes
                // an ink of the opposite hue, as in diffusion.
                opts.weights = [1.0, 3.0, 3.0];
                let all = (1u32 << m.inks.len()) - 1;
                let allowed: Vec<u16> = m
                    .avoid
                    .iter()
                    .map(|&a| match all & !a {
                        0 => all as u16,
                        ok => ok as u16,
                    })
                    .collect();
                super::palette_dbs::refine_within(
                    &m.target,
                    m.width,
                    m.height,
                    &m.inks,
                    &mut idx,
                    Some(&allowed),
                    &opts,
                )?;
                idx
            }
            Dither::Ordered { mask } => {
                super::ordered_palette::ordered_indices(&m.target, m.width, m.height, &m.inks, mask)
            }
        })
    }
}

impl Method for InkMethod {
    fn name(&self) -> String {
        let how = match &self.dither {
            Dither::Diffuse { kernel, .. } => kernel.name.clone(),
            Dither::Dbs { .. } => "dbs".into(),
            Dither::Ordered { mask } => format!("ordered {}", mask.name),
        };
        format!("{} ({}, {})", self.name, self.rendering.intent.name(), how)
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        let (w, h) = (input.width, input.height);
        let idx = match &self.dither {
            Dither::Diffuse {
                kernel,
                serpentine,
                strength,
            } => self.diffuse_piped(input, kernel, *serpentine, *strength)?,
            _ => self.indices(&self.map(input)?)?,
        };
        let mut out = Halftone::new(w, h, 1, self.palette.len() as u16);
        let (bits, stride) = (out.bits, out.stride);
        if w > 0 {
            out.planes[0]
                .chunks_mut(stride)
                .zip(idx.chunks(w))
                .for_each(|(row, levels)| pack_row(levels, bits, row));
        }
        out.palette = Some(self.palette.clone());
        Ok(out)
    }
}

/// The box `(x, y, width, height)` of a picture inside margins that are white (the largest
/// code) in every plane: a canvas's padding (`--fit-mode pad`) or a scan's margins. The whole
/// picture when it has none, or is white throughout.
fn content_box(planes: [&PlaneRef<'_>; 3], w: usize, h: usize) -> (usize, usize, usize, usize) {
    let white = |i: usize| {
        planes.iter().all(|p| match p.samples {
            SamplesRef::U8(s) => s[i] as usize == p.tone.len() - 1,
            SamplesRef::U16(s) => s[i] as usize == p.tone.len() - 1,
        })
    };
    let row_white = |y: usize| (0..w).all(|x| white(y * w + x));
    let Some(top) = (0..h).find(|&y| !row_white(y)) else {
        return (0, 0, w, h);
    };
    let bottom = (top..h).rev().find(|&y| !row_white(y)).unwrap_or(top) + 1;
    let col_white = |x: usize| (top..bottom).all(|y| white(y * w + x));
    let left = (0..w).find(|&x| !col_white(x)).unwrap_or(0);
    let right = (left..w).rev().find(|&x| !col_white(x)).unwrap_or(left) + 1;
    (left, top, right - left, bottom - top)
}

/// What [`InkMethod::prepare`] makes.
struct Prepared<'a> {
    mapper: RowMapper<'a>,
    /// The inks as the viewer sees them, linear RGB.
    inks: Vec<[f32; 3]>,
    neutral_inks: Vec<bool>,
    table: Option<NearestTable>,
}

/// Maps rows of a picture for the inks: the table of the map, and each plane's code → cell.
struct RowMapper<'a> {
    lut: Lut,
    /// The chromatic inks (avoided where a pixel is neutral).
    chromatic: u32,
    idx: Vec<Vec<(u8, f32)>>,
    planes: [&'a PlaneRef<'a>; 3],
    width: usize,
    height: usize,
}

impl RowMapper<'_> {
    /// Rows from `y0` (as many as `target` holds) mapped: linear RGB, and the inks to avoid
    /// (see [`Mapped::avoid`]).
    fn rows(&self, y0: usize, target: &mut [[f32; 3]], neutral: &mut [u32]) {
        let w = self.width;
        if w == 0 {
            return;
        }
        let t = |c: usize| &self.idx[c.min(self.idx.len() - 1)][..];
        let tables = [t(0), t(1), t(2)];
        for (dy, (trow, nrow)) in target.chunks_mut(w).zip(neutral.chunks_mut(w)).enumerate() {
            let at = (y0 + dy) * w..(y0 + dy + 1) * w;
            let s = |c: usize| self.planes[c].samples;
            match (s(0), s(1), s(2)) {
                (SamplesRef::U8(r), SamplesRef::U8(g), SamplesRef::U8(b)) => {
                    self.row([&r[at.clone()], &g[at.clone()], &b[at]], tables, trow, nrow)
                }
                (SamplesRef::U16(r), SamplesRef::U16(g), SamplesRef::U16(b)) => {
                    self.row([&r[at.clone()], &g[at.clone()], &b[at]], tables, trow, nrow)
                }
                _ => {
                    // Planes of mixed depths (not made by this crate's readers): widened.
                    let wide = |c: usize| -> Vec<u16> {
                        match s(c) {
                            SamplesRef::U8(v) => v[at.clone()].iter().map(|&k| k as u16).collect(),
                            SamplesRef::U16(v) => v[at.clone()].to_vec(),
                        }
                    };
                    let (r, g, b) = (wide(0), wide(1), wide(2));
                    self.row([&r, &g, &b], tables, trow, nrow)
                }
            }
        }
    }

    /// One row: each pixel's codes through its plane's table, then the map.
    #[inline(always)]
    fn row<T: Copy + Into<usize>>(
        &self,
        codes: [&[T]; 3],
        tables: [&[(u8, f32)]; 3],
        trow: &mut [[f32; 3]],
        nrow: &mut [u32],
    ) {
        let [r, g, b] = codes;
        let [tr, tg, tb] = tables;
        for ((((o, n), &r), &g), &b) in trow.iter_mut().zip(nrow.iter_mut()).zip(r).zip(g).zip(b) {
            let (r, g, b) = (tr[r.into()], tg[g.into()], tb[b.into()]);
            let v = self.lut.sample(r, g, b);
            *o = [v[0], v[1], v[2]];
            // The nearest node's inks of an opposite hue; neutral as the interpolated chroma
            // says.
            let a = self.lut.avoid_at(r, g, b);
            *n = if v[3] < NEUTRAL_CHROMA {
                a | self.chromatic | NEUTRAL_BIT
            } else {
                a
            };
        }
    }
}

/// A tone curve on luminance: `y → (y − lo) / (hi − lo)` blended in by a strength.
#[derive(Clone, Copy, Debug)]
struct ToneCurve {
    lo: f64,
    hi: f64,
}

impl ToneCurve {
    const IDENTITY: ToneCurve = ToneCurve { lo: 0.0, hi: 1.0 };

    fn apply(&self, c: [f64; 3]) -> [f64; 3] {
        if self.lo == 0.0 && self.hi == 1.0 {
            return c;
        }
        let y = LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2];
        let t = ((y - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0);
        if y > 1e-9 {
            c.map(|v| v * t / y)
        } else {
            [t; 3]
        }
    }
}

/// The tone stretch of `sample` (linear RGB): the 0.5th and 99.5th percentiles of its
/// luminance towards black and white, by `amount`. `Auto` stretches only a picture that does
/// not use the range, at most by 1.1.
fn tone_curve(sample: &[[f64; 3]], amount: Amount) -> ToneCurve {
    let mut ys: Vec<f64> = sample
        .iter()
        .map(|c| LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2])
        .collect();
    if ys.is_empty() {
        return ToneCurve::IDENTITY;
    }
    let mut at = |p: f64| {
        let k = ((ys.len() - 1) as f64 * p).round() as usize;
        *ys.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let (lo, hi) = (at(0.005).max(0.0), at(0.995).min(1.0));
    if hi - lo < 0.05 {
        return ToneCurve::IDENTITY;
    }
    let s = match amount {
        Amount::Fixed(s) => s as f64,
        Amount::Auto => {
            // Full stretch when it is small; no more than 1.1× contrast otherwise.
            let full = 1.0 / (hi - lo);
            if full <= 1.1 {
                1.0
            } else {
                (0.1 / (full - 1.0)).min(1.0)
            }
        }
    };
    ToneCurve {
        lo: s * lo,
        hi: 1.0 - s * (1.0 - hi),
    }
}

/// How colours are moved towards (or away from) the neutral of their luminance before the
/// clip: a factor of their reach.
#[derive(Clone, Copy, Debug)]
enum Squeeze {
    /// Every colour scaled by this.
    Scale(f64),
    /// Reaches above `knee` compressed so that `top` lands on the hull's edge.
    Knee { knee: f64, top: f64 },
}

impl Squeeze {
    /// Gamut compression of strength `amount` for a picture whose colours reach `p99` of the
    /// way to the inks' edge (99th percentile).
    fn compress(amount: Amount, p99: f64) -> Squeeze {
        let s = match amount {
            Amount::Fixed(s) => s as f64,
            Amount::Auto => {
                if p99 > 1.0 {
                    1.0
                } else {
                    0.0
                }
            }
        };
        if s <= 0.0 || p99 <= 1.0 {
            return Squeeze::Scale(1.0);
        }
        Squeeze::Knee {
            knee: 1.0 - 0.25 * s,
            top: p99.min(4.0),
        }
    }

    /// The factor for a colour of reach `r`.
    fn factor(&self, r: f64) -> f64 {
        match *self {
            Squeeze::Scale(s) => s,
            Squeeze::Knee { knee, top } => {
                if r <= knee || !r.is_finite() {
                    1.0
                } else {
                    let out = knee + (r.min(top) - knee) * (1.0 - knee) / (top - knee);
                    out / r
                }
            }
        }
    }
}

/// A 3-D table over linear light, nodes at `(i / 16)²`, four values a node, and a mask of
/// inks to avoid a node (taken from the nearest node: masks do not interpolate).
struct Lut {
    values: Vec<[f32; 4]>,
    avoid: Vec<u32>,
}

impl Lut {
    fn position(i: usize) -> f32 {
        let t = i as f32 / (NODES - 1) as f32;
        t * t
    }

    /// The table of `f(i)` for node `i` (red fastest, then green, then blue).
    fn build(f: impl Fn(usize) -> ([f32; 4], u32) + Sync + Send) -> Lut {
        let (values, avoid) = (0..NODES * NODES * NODES)
            .into_par_iter()
            .with_min_len(NODES * NODES * NODES / 2)
            .map(f)
            .unzip();
        Lut { values, avoid }
    }

    /// The mask of the node nearest the point (in the cell's own fractions).
    #[inline(always)]
    fn avoid_at(&self, r: (u8, f32), g: (u8, f32), b: (u8, f32)) -> u32 {
        let at = |v: (u8, f32)| v.0 as usize + (v.1 > 0.5) as usize;
        self.avoid[at(r) + NODES * at(g) + NODES * NODES * at(b)]
    }

    /// The cell and the weight of its upper node for a linear value.
    fn locate(v: f32) -> (u8, f32) {
        let v = if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let i = ((v.sqrt() * (NODES - 1) as f32) as usize).min(NODES - 2);
        let (a, b) = (Lut::position(i), Lut::position(i + 1));
        (i as u8, ((v - a) / (b - a)).clamp(0.0, 1.0))
    }

    /// Tetrahedral interpolation (four nodes of the cell, chosen by the order of the
    /// fractions): exact for a linear map, as trilinear is, at half the reads.
    #[inline(always)]
    fn sample(&self, r: (u8, f32), g: (u8, f32), b: (u8, f32)) -> [f32; 4] {
        const SR: usize = 1;
        const SG: usize = NODES;
        const SB: usize = NODES * NODES;
        // Per order of the fractions (bits: r ≥ g, g ≥ b, r ≥ b): the offsets of the second
        // and third node (the step of the largest fraction's channel, then that and the
        // next largest one's); ties as the first listed in [r, g, b] order wins.
        const STEPS: [(usize, usize); 8] = [
            (SB, SB + SG),
            (SB, SB + SR),
            (SG, SG + SB),
            (SR, SR + SG),
            (SG, SG + SR),
            (SR, SR + SB),
            (SG, SG + SR),
            (SR, SR + SG),
        ];
        let base = r.0 as usize * SR + g.0 as usize * SG + b.0 as usize * SB;
        let (fr, fg, fb) = (r.1, g.1, b.1);
        let case = (fr >= fg) as usize | ((fg >= fb) as usize) << 1 | ((fr >= fb) as usize) << 2;
        let (s1, s2) = STEPS[case];
        // The fractions from the largest to the smallest (the values only: equal fractions
        // are interchangeable, so no order of ties is needed here).
        let (hi, lo) = (fr.max(fg), fr.min(fg));
        let f1 = hi.max(fb);
        let f3 = lo.min(fb);
        let f2 = hi.min(lo.max(fb));
        let v = &self.values[base..base + SR + SG + SB + 1];
        let (c0, c1, c2, c3) = (&v[0], &v[s1], &v[s2], &v[SR + SG + SB]);
        let (w0, w1, w2, w3) = (1.0 - f1, f1 - f2, f2 - f3, f3);
        #[cfg(target_arch = "x86_64")]
        {
            // The same products and sums in the same order, four lanes at once (SSE is part
            // of every x86-64 CPU): the same values as the lines below.
            use std::arch::x86_64::*;
            // SAFETY: SSE is in every x86-64 CPU's base set; each pointer is to an
            // `[f32; 4]` (four readable floats), and `out` holds four floats.
            unsafe {
                let load = |c: &[f32; 4]| _mm_loadu_ps(c.as_ptr());
                let sum = _mm_add_ps(
                    _mm_add_ps(
                        _mm_add_ps(
                            _mm_mul_ps(_mm_set1_ps(w0), load(c0)),
                            _mm_mul_ps(_mm_set1_ps(w1), load(c1)),
                        ),
                        _mm_mul_ps(_mm_set1_ps(w2), load(c2)),
                    ),
                    _mm_mul_ps(_mm_set1_ps(w3), load(c3)),
                );
                let mut out = [0f32; 4];
                _mm_storeu_ps(out.as_mut_ptr(), sum);
                out
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        std::array::from_fn(|k| w0 * c0[k] + w1 * c1[k] + w2 * c2[k] + w3 * c3[k])
    }
}

/// The nearest ink of every colour, looked up: a grid over the signed square roots of linear
/// light (close to lightness), each cell holding the ink nearest in Oklab to its centre.
/// Error diffusion corrects what a cell's rounding costs.
///
/// The grid reaches below zero: diffusion's error takes a channel negative where the inks
/// lack a colour (blue on a black, white, red and yellow panel), and the ink nearest such a
/// value (Oklab of negative light, cube roots keeping their sign) is what keeps the error
/// from running away. A table that stopped at zero would see every negative value as zero
/// and let the error grow until it was cut off.
///
/// A value's cell along each axis comes from its `f32` bits: the bits of its magnitude
/// shifted right by [`KEY_SHIFT`] (exponent and six mantissa bits: steps of 1.6% of the
/// value), and its sign, index [`Coords`], the cell of the step's middle. No square root on
/// the way, so the lookup is a few integer operations and two loads: the diffusion's chain
/// from one pixel to the next.
struct NearestTable {
    cells: Vec<u8>,
    /// The inks in Oklab.
    labs: Vec<[f32; 3]>,
}

/// Cells along each axis of [`NearestTable`] from 0 to `TOP`, and the light the last ends at.
const CELLS: usize = 32;
const TOP: f32 = 1.3;
/// Cells below zero along each axis, and their width in signed square roots (the last
/// reaches to -0.81, past which all values share it).
const NEG_CELLS: usize = 6;
const NEG_STEP: f32 = 0.15;
/// Cells along each axis.
const AXIS: usize = NEG_CELLS + CELLS;
/// `f32` bits dropped to make a value's key.
const KEY_SHIFT: u32 = 17;

/// The cell along one axis of every key: every 15-bit key (sign, exponent and six mantissa
/// bits), so that a value's key needs no clamping. Only the keys of the values a picture
/// takes are ever read (a few cache lines).
struct Coords([u8; 1 << (32 - KEY_SHIFT)]);

/// The cell along one axis of the value `v`.
fn axis_cell(v: f32) -> usize {
    if v >= 0.0 {
        let scale = CELLS as f32 / TOP.sqrt();
        NEG_CELLS + ((v.min(TOP).sqrt() * scale) as usize).min(CELLS - 1)
    } else {
        NEG_CELLS - 1 - (((-v).sqrt() / NEG_STEP) as usize).min(NEG_CELLS - 1)
    }
}

/// The centre of cell `i` along an axis (the middle of its signed square roots, squared).
fn axis_centre(i: usize) -> f32 {
    if i >= NEG_CELLS {
        let q = ((i - NEG_CELLS) as f32 + 0.5) / CELLS as f32 * TOP.sqrt();
        q * q
    } else {
        let q = ((NEG_CELLS - 1 - i) as f32 + 0.5) * NEG_STEP;
        -q * q
    }
}

fn coords() -> &'static Coords {
    static COORDS: std::sync::OnceLock<Box<Coords>> = std::sync::OnceLock::new();
    COORDS.get_or_init(|| {
        let mut t = Box::new(Coords([0; 1 << (32 - KEY_SHIFT)]));
        for (key, c) in t.0.iter_mut().enumerate() {
            // The middle of the key's step (the keys of infinities and NaNs: the end cells).
            let v = f32::from_bits(((key as u32) << KEY_SHIFT) | (1 << (KEY_SHIFT - 1)));
            let v = if v.is_nan() {
                f32::INFINITY.copysign(v)
            } else {
                v
            };
            *c = axis_cell(v) as u8;
        }
        t
    })
}

impl Coords {
    /// The cell of `v` along one axis.
    #[inline(always)]
    fn of(&self, v: f32) -> usize {
        self.0[(v.to_bits() >> KEY_SHIFT) as usize] as usize
    }

    /// The table index of the cell holding `v`.
    #[inline(always)]
    fn cell(&self, v: [f32; 3]) -> usize {
        self.of(v[0]) + AXIS * self.of(v[1]) + AXIS * AXIS * self.of(v[2])
    }
}

impl NearestTable {
    /// The table of `inks` (linear RGB), its second half among the `neutral` ones (all, when
    /// fewer than two are).
    fn of(inks: &[[f32; 3]], neutral: &[bool]) -> NearestTable {
        let labs: Vec<[f32; 3]> = inks.iter().map(|c| oklab(*c)).collect();
        let all: Vec<u8> = (0..inks.len() as u8).collect();
        let greys: Vec<u8> = all
            .iter()
            .copied()
            .filter(|&k| neutral[k as usize])
            .collect();
        let greys = if greys.len() >= 2 { greys } else { all.clone() };
        NearestTable::build(&labs, [&all, &greys])
    }

    /// The nearest ink among each of two lists of candidates, from one pass over the
    /// cells: a row of cells along red at a time, eight cells a vector.
    fn build(labs: &[[f32; 3]], lists: [&[u8]; 2]) -> NearestTable {
        let mut both = [vec![0u8; AXIS * AXIS * AXIS], vec![0u8; AXIS * AXIS * AXIS]];
        let [a, b] = &mut both;
        a.par_chunks_mut(AXIS)
            .zip(b.par_chunks_mut(AXIS))
            .enumerate()
            .for_each(|(row, (ta, tb))| {
                let (g, bl) = (axis_centre(row % AXIS), axis_centre(row / AXIS));
                for r0 in (0..AXIS).step_by(8) {
                    let n = (AXIS - r0).min(8);
                    let r: [f32; 8] = std::array::from_fn(|k| axis_centre((r0 + k).min(AXIS - 1)));
                    let q = oklab8(r, [g; 8], [bl; 8]);
                    for (t, list) in [(&mut *ta, lists[0]), (&mut *tb, lists[1])] {
                        let mut best = [f32::INFINITY; 8];
                        let mut which = [list[0]; 8];
                        for &k in list {
                            let p = labs[k as usize];
                            for l in 0..8 {
                                let d = [q[0][l] - p[0], q[1][l] - p[1], q[2][l] - p[2]];
                                let dist = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                                if dist < best[l] {
                                    best[l] = dist;
                                    which[l] = k;
                                }
                            }
                        }
                        t[r0..r0 + n].copy_from_slice(&which[..n]);
                    }
                }
            });
        // One byte a cell: the nearest of all inks low, of the neutral ones high (one table
        // to keep in the cache).
        let cells = both[0]
            .iter()
            .zip(&both[1])
            .map(|(a, n)| a | n << 4)
            .collect();
        NearestTable {
            cells,
            labs: labs.to_vec(),
        }
    }

    /// The nearest ink to `v` unless `avoid` holds it (bit `k`: ink `k`); then the nearest
    /// neutral ink. For a neutral pixel (every chromatic ink avoided) that is the nearest
    /// neutral ink whichever ink is nearest.
    /// Where a pixel that is not neutral avoids the nearest ink (one of an opposite hue),
    /// the nearest of the inks it may use, found the long way ([`Self::nearest_allowed`]):
    /// falling back to a neutral ink there would leave the error of the inks it may use
    /// unspent, and the mean off the colour aimed at.
    #[inline(always)]
    fn avoiding(&self, coords: &Coords, v: [f32; 3], avoid: u32) -> u8 {
        let cell = self.cells[coords.cell(v)];
        let hit = (avoid >> (cell & 15)) & 1;
        if hit != 0 && avoid & NEUTRAL_BIT == 0 {
            return self.nearest_allowed(v, avoid);
        }
        (cell >> (hit << 2)) & 15
    }

    /// The ink nearest `v` in Oklab among those `avoid` does not hold.
    #[cold]
    #[inline(never)]
    fn nearest_allowed(&self, v: [f32; 3], avoid: u32) -> u8 {
        let q = oklab_signed(v);
        let mut best = (f32::INFINITY, 0u8);
        for (k, p) in self.labs.iter().enumerate() {
            let d = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
            if (avoid >> k) & 1 == 0 && d < best.0 {
                best = (d, k as u8);
            }
        }
        best.1
    }
}

/// Cube root of `x ≥ 0` to about 1e-6 relative: a first guess from the exponent bits, then
/// three Newton steps (several times faster than `cbrt`).
#[inline(always)]
fn cbrt(x: f32) -> f32 {
    let mut y = f32::from_bits(x.to_bits() / 3 + 709_921_077);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    if x <= 1e-30 {
        0.0
    } else {
        y
    }
}

/// Oklab of a linear RGB colour (Ottosson's matrices; negative light clamped to 0).
#[inline(always)]
fn oklab(c: [f32; 3]) -> [f32; 3] {
    oklab_signed(c.map(|v| v.max(0.0)))
}

/// Oklab of a linear RGB colour whose channels may be negative: the cube roots keep their
/// sign (for colours without negative light, the plain cube roots: [`oklab`]).
#[inline(always)]
fn oklab_signed(c: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = c;
    let root = |x: f32| cbrt(x.abs()).copysign(x);
    let l = root(0.412_221_46 * r + 0.536_332_55 * g + 0.051_445_995 * b);
    let m = root(0.211_903_5 * r + 0.680_699_5 * g + 0.107_396_96 * b);
    let s = root(0.088_302_46 * r + 0.281_718_85 * g + 0.629_978_7 * b);
    [
        0.210_454_26 * l + 0.793_617_8 * m - 0.004_072_047 * s,
        1.977_998_5 * l - 2.428_592_2 * m + 0.450_593_7 * s,
        0.025_904_037 * l + 0.782_771_77 * m - 0.808_675_77 * s,
    ]
}

/// [`oklab_signed`] of eight colours, a channel an array (the same operations, so the same
/// values).
#[inline(always)]
fn oklab8(r: [f32; 8], g: [f32; 8], b: [f32; 8]) -> [[f32; 8]; 3] {
    let mut out = [[0f32; 8]; 3];
    for k in 0..8 {
        let o = oklab_signed([r[k], g[k], b[k]]);
        for (c, v) in o.into_iter().enumerate() {
            out[c][k] = v;
        }
    }
    out
}

/// The weights of a kernel shaped like Floyd–Steinberg's, scaled: ahead in the row, and
/// behind, under and ahead in the row below (in scan direction).
#[derive(Clone, Copy, Debug)]
struct FsWeights {
    right: f32,
    behind: f32,
    under: f32,
    ahead: f32,
}

impl FsWeights {
    fn of(kernel: &Kernel, scale: f32) -> Option<FsWeights> {
        let tap = |dx: i32, dy: u32| {
            kernel
                .taps
                .iter()
                .find(|t| t.dx == dx && t.dy == dy)
                .map(|t| t.weight as f32 * scale)
        };
        if kernel.taps.len() != 4 {
            return None;
        }
        Some(FsWeights {
            right: tap(1, 0)?,
            behind: tap(-1, 1)?,
            under: tap(0, 1)?,
            ahead: tap(1, 1)?,
        })
    }
}

/// The larger of two numbers that are not NaN (one vector instruction, where `f32::max`
/// adds the NaN cases to the diffusion's chain).
#[inline(always)]
fn max_f(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The smaller of two numbers that are not NaN: see [`max_f`].
#[inline(always)]
fn min_f(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Inks the Floyd–Steinberg loop serves (a vector lane an ink).
const LANES: usize = 8;

/// Side of the threshold modulation's tile (the built-in `blue-noise-64` mask).
const MOD_SIZE: usize = 64;
/// Peak-to-peak amplitude of the threshold modulation (linear light, added to all three
/// channels) where the target is at the ends of the tone scale.
const MOD_AMPLITUDE: f32 = 0.12;
/// Luminance below which (and above one minus which) the modulation is at full strength, and
/// the width over which it fades out.
const MOD_EDGE: f32 = 0.02;
const MOD_FADE: f32 = 0.05;

/// The blue-noise threshold modulation, `MOD_SIZE`² values from −½ to ½ (the ranks of the
/// built-in `blue-noise-64` mask).
///
/// Error diffusion lays the sparse dots of a near-black or near-white flat in lines (worms):
/// the error left by each dot travels the same way. A blue-noise perturbation of the value
/// the ink is chosen for (not of the error; Knox and Eschbach's threshold modulation) breaks
/// the lines and keeps the dots spread, at no cost to the mean.
fn modulation() -> &'static [f32] {
    static TILE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TILE.get_or_init(|| {
        let m = Mask::builtin("blue-noise-64").expect("built-in mask");
        assert_eq!((m.width, m.height), (MOD_SIZE, MOD_SIZE));
        let n = m.ranks.len() as f32;
        m.ranks
            .iter()
            .map(|&r| (r as f32 + 0.5) / n - 0.5)
            .collect()
    })
}

/// The modulation of a pixel aiming at `t` (linear RGB) from its tile value `m`: full near
/// black and white, none in the middle tones (where the picture's own detail breaks lines).
#[inline(always)]
fn noise(t: [f32; 3], m: f32) -> f32 {
    let y = 0.2126 * t[0] + 0.7152 * t[1] + 0.0722 * t[2];
    let end = min_f(y, 1.0 - y);
    let w = min_f(
        max_f((MOD_EDGE + MOD_FADE - end) * (1.0 / MOD_FADE), 0.0),
        1.0,
    );
    MOD_AMPLITUDE * w * m
}

/// Error diffusion of a mapped picture: the error measured against the mapped target, the
/// value a pixel aims at kept within a margin of the inks' range, and neutral pixels made
/// with the neutral inks only.
pub fn diffuse(m: &Mapped, kernel: &Kernel, serpentine: bool, strength: f32) -> Vec<u8> {
    diffuse_primed(m, kernel, serpentine, strength, PRIME)
}

/// [`diffuse`] with the page's first band primed by `prime` rows (see [`PRIME`]).
fn diffuse_primed(
    m: &Mapped,
    kernel: &Kernel,
    serpentine: bool,
    strength: f32,
    prime: usize,
) -> Vec<u8> {
    let table = NearestTable::of(&m.inks, &m.neutral_inks);
    let mut d = Diffusion::new(&m.inks, table, kernel, serpentine, strength);
    d.prime = prime;
    let w = m.width;
    match d.fs_weights() {
        Some(wt) => {
            let fill = |y0: usize, block: &mut Block| {
                let at = y0 * w;
                let n = block.0.len();
                block.0.copy_from_slice(&m.target[at..at + n]);
                block.1.copy_from_slice(&m.avoid[at..at + n]);
            };
            d.bands(wt, &fill, w, m.height)
        }
        None => d.run(&mut MappedRows(m), w, m.height),
    }
}

/// Rows of a mapped picture, in order: the target (linear RGB) and the inks to avoid.
trait Rows {
    fn row(&mut self, y: usize) -> (&[[f32; 3]], &[u32]);
}

/// The rows of a [`Mapped`].
struct MappedRows<'a>(&'a Mapped);

impl Rows for MappedRows<'_> {
    fn row(&mut self, y: usize) -> (&[[f32; 3]], &[u32]) {
        let w = self.0.width;
        (
            &self.0.target[y * w..(y + 1) * w],
            &self.0.avoid[y * w..(y + 1) * w],
        )
    }
}

/// A block of mapped rows: target and inks to avoid.
type Block = (Vec<[f32; 3]>, Vec<u32>);

/// Rows mapped on another thread, block by block, taken as they are ready.
struct PipedRows<'a> {
    width: usize,
    block_rows: usize,
    slots: &'a [std::sync::Mutex<Option<Block>>],
    ready: &'a std::sync::atomic::AtomicUsize,
    /// Where a block goes back once used.
    free: &'a std::sync::Mutex<Vec<Block>>,
    /// The block in use, and its number.
    current: (usize, Block),
}

impl Rows for PipedRows<'_> {
    fn row(&mut self, y: usize) -> (&[[f32; 3]], &[u32]) {
        use std::sync::atomic::Ordering;
        let (w, b) = (self.width, y / self.block_rows);
        if self.current.0 != b {
            let mut spins = 0u32;
            // `usize::MAX`: the mapping stopped (a panic, resumed by the join).
            while self.ready.load(Ordering::Acquire) <= b {
                if spins < 100 {
                    std::hint::spin_loop();
                    spins += 1;
                } else {
                    std::thread::yield_now();
                }
            }
            let rows = self.block_rows * w;
            let block = self.slots[b]
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
                .unwrap_or_else(|| (vec![[0.0; 3]; rows], vec![0; rows]));
            let (_, used) = std::mem::replace(&mut self.current, (b, block));
            if !used.0.is_empty() {
                self.free
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(used);
            }
        }
        let at = (y - b * self.block_rows) * w;
        let (t, n) = &self.current.1;
        (&t[at..at + w], &n[at..at + w])
    }
}

/// Page rows a band of the Floyd–Steinberg loop keeps (the last band may be shorter).
///
/// Bands are diffused independently, so that they can run at once (on two threads, and two
/// on each thread, their chains from pixel to pixel overlapping): each band but the first
/// starts [`WARM`] rows above its own with no error, diffuses them to let its error settle
/// into the pattern the picture makes there, drops what they gave and goes on into its own
/// rows; what leaves a band's last row is dropped. The layout depends on the page alone,
/// so the output is the same whatever the number of threads.
const BAND: usize = 128;
/// Rows a band diffuses before its own (an even number: the scan directions stay those of
/// the page's rows).
const WARM: usize = 16;
/// Times the page's first band diffuses its first row before it (an even number), having no
/// rows above to settle on. Started with no error, a flat of a colour made mostly of one
/// ink (a saturated red: red ink and a few dots of the others) shows another mean in its
/// first rows while the error builds up to the balance of the inks: on bwry-3in97, twice
/// the yellow dots in the first 16 rows (CIEDE2000 5 between a patch's top and bottom
/// thirds); on acep7-5in65 the white dots come in over some 50 rows. A page of no more rows
/// than this is not primed: a strip shows no drift, and a row of the inks' own colours keeps
/// to them (the small error of each pixel's aim, piled up over the primed rows, turned one
/// of them black).
const PRIME: usize = 64;
/// Mapped rows, made in groups of this many as a band needs them.
const GROUP: usize = 16;

/// Maps page rows from `y0` into a block sized for them.
type Fill<'f> = dyn Fn(usize, &mut Block) + Sync + 'f;

/// A band's rows: `start..end` diffused, `keep..end` its own, after its first row diffused
/// `prime` times more (and dropped).
#[derive(Clone, Copy, Debug)]
struct Band {
    start: usize,
    keep: usize,
    end: usize,
    prime: usize,
}

impl Band {
    /// Band `k` of a page `h` rows high (the first primed by `prime` rows when the page is
    /// taller than that: see [`PRIME`]).
    fn of(k: usize, h: usize, prime: usize) -> Band {
        let keep = k * BAND;
        Band {
            start: keep.saturating_sub(WARM),
            keep,
            end: (keep + BAND).min(h),
            prime: if k == 0 && h > prime { prime } else { 0 },
        }
    }

    /// Rows diffused, the primed ones included.
    fn rows(&self) -> usize {
        self.end - self.start + self.prime
    }

    /// The page row diffused at step `j`.
    fn row(&self, j: usize) -> usize {
        self.start + j.saturating_sub(self.prime)
    }

    /// The band's own row (from `keep`) step `j` gives, if any.
    fn own(&self, j: usize) -> Option<usize> {
        j.checked_sub(self.prime)
            .and_then(|j| (self.start + j).checked_sub(self.keep))
    }

    /// Whether step `j` runs right to left (serpentine): the page row's direction, the primed
    /// steps alternating before it ([`PRIME`] is even).
    fn right_to_left(&self, j: usize) -> bool {
        (self.start + j) % 2 == 1
    }
}

/// A band's mapped rows, a group at a time.
#[derive(Default)]
struct BandRows {
    y0: usize,
    block: Block,
}

impl BandRows {
    /// Makes sure row `y` is held (mapping the group from `y`, up to `end`, if not).
    fn load(&mut self, fill: &Fill<'_>, y: usize, end: usize, w: usize) {
        let held = self.block.1.len() / w.max(1);
        if y < self.y0 || y >= self.y0 + held {
            let n = (end - y).min(GROUP) * w;
            self.block.0.resize(n, [0.0; 3]);
            self.block.1.resize(n, 0);
            self.y0 = y;
            fill(y, &mut self.block);
        }
    }

    /// Row `y` (held: see [`Self::load`]).
    fn row(&self, y: usize, w: usize) -> (&[[f32; 3]], &[u32]) {
        let at = (y - self.y0) * w;
        (&self.block.0[at..at + w], &self.block.1[at..at + w])
    }
}

/// What the Floyd–Steinberg loop keeps from row to row of a band.
struct FsState {
    /// The error each cell of this row receives from the row above, and of the row below;
    /// page columns from 1 (0 and w + 1 take what falls past the edges).
    err: Vec<[f32; 3]>,
    below: Vec<[f32; 3]>,
    /// This row in scan order: target plus error (one spare), the inks to avoid, and the
    /// threshold modulation (one spare).
    base: [Vec<f32>; 3],
    avoid: Vec<u32>,
    noise: Vec<f32>,
}

impl FsState {
    fn new(w: usize) -> FsState {
        FsState {
            err: vec![[0f32; 3]; w + 2],
            below: vec![[0f32; 3]; w + 2],
            base: [vec![0f32; w + 1], vec![0f32; w + 1], vec![0f32; w + 1]],
            avoid: vec![0u32; w],
            noise: vec![0f32; w + 1],
        }
    }
}

/// Error diffusion to a set of inks, ready to run: see [`diffuse`].
struct Diffusion<'a> {
    inks: &'a [[f32; 3]],
    kernel: &'a Kernel,
    serpentine: bool,
    scale: f32,
    /// Nearest ink of every cell, among all inks and among the neutral ones (a nibble each).
    table: NearestTable,
    /// The range a pixel may aim at.
    lo: [f32; 3],
    hi: [f32; 3],
    /// Times the page's first row is diffused before it (see [`PRIME`]).
    prime: usize,
}

impl<'a> Diffusion<'a> {
    /// `table`: the inks' [`NearestTable::of`].
    fn new(
        inks: &'a [[f32; 3]],
        table: NearestTable,
        kernel: &'a Kernel,
        serpentine: bool,
        strength: f32,
    ) -> Diffusion<'a> {
        // The inks' range per channel, a margin either side.
        let margin = 0.75;
        let lo = std::array::from_fn(|c| {
            inks.iter().map(|k| k[c]).fold(f32::INFINITY, f32::min) - margin
        });
        let hi = std::array::from_fn(|c| {
            inks.iter().map(|k| k[c]).fold(f32::NEG_INFINITY, f32::max) + margin
        });
        Diffusion {
            inks,
            kernel,
            serpentine,
            scale: strength / kernel.divisor as f32,
            table,
            lo,
            hi,
            prime: PRIME,
        }
    }

    /// The weights of the Floyd–Steinberg loop, when the kernel has that shape and the inks
    /// fit its lanes ([`Self::bands`] then runs); `None`: the general loop ([`Self::run`]).
    fn fs_weights(&self) -> Option<FsWeights> {
        FsWeights::of(self.kernel, self.scale).filter(|_| self.inks.len() <= LANES)
    }

    /// Ink indices (row-major) of `w`×`h` rows, in order, by the general loop.
    fn run(&self, rows: &mut impl Rows, w: usize, h: usize) -> Vec<u8> {
        let mut out = vec![0u8; w * h];
        if w == 0 || h == 0 {
            return out;
        }
        self.any(rows, w, &mut out);
        out
    }

    /// Ink indices (row-major) of `w`×`h` rows by the Floyd–Steinberg loop, band by band:
    /// see [`BAND`]. `fill(y0, block)` maps the rows from `y0` that `block` is sized for.
    fn bands(&self, wt: FsWeights, fill: &Fill<'_>, w: usize, h: usize) -> Vec<u8> {
        let mut out = vec![0u8; w * h];
        if w == 0 || h == 0 {
            return out;
        }
        // Two bands a task: one thread runs both, a pixel of one and a pixel of the other in
        // turn, so that the two chains from pixel to pixel overlap.
        out.par_chunks_mut(2 * BAND * w)
            .enumerate()
            .for_each(|(pair, chunk)| {
                let (a, b) = chunk.split_at_mut((BAND * w).min(chunk.len()));
                let first = Band::of(2 * pair, h, self.prime);
                if b.is_empty() {
                    self.fs(wt, fill, w, [first], [a]);
                } else {
                    self.fs(
                        wt,
                        fill,
                        w,
                        [first, Band::of(2 * pair + 1, h, self.prime)],
                        [a, b],
                    );
                }
            });
        out
    }

    /// The Floyd–Steinberg loop over `N` bands at once: see [`Self::fs_row`].
    fn fs<const N: usize>(
        &self,
        wt: FsWeights,
        fill: &Fill<'_>,
        w: usize,
        bands: [Band; N],
        outs: [&mut [u8]; N],
    ) {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::avx2() {
            // SAFETY: the CPU has AVX2 and FMA (checked by `cpu::avx2`).
            unsafe { self.fs_avx2(wt, fill, w, bands, outs) };
            return;
        }
        self.fs_body(wt, fill, w, bands, outs)
    }

    /// [`Self::fs`] compiled for AVX2: the same operations (no fused multiply-adds are formed),
    /// so the same values, with twice the vector width and registers to hold the lanes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fs_avx2<const N: usize>(
        &self,
        wt: FsWeights,
        fill: &Fill<'_>,
        w: usize,
        bands: [Band; N],
        outs: [&mut [u8]; N],
    ) {
        self.fs_body(wt, fill, w, bands, outs)
    }

    #[inline(always)]
    fn fs_body<const N: usize>(
        &self,
        wt: FsWeights,
        fill: &Fill<'_>,
        w: usize,
        bands: [Band; N],
        mut outs: [&mut [u8]; N],
    ) {
        let mut state: [FsState; N] = std::array::from_fn(|_| FsState::new(w));
        let mut blocks: [BandRows; N] = std::array::from_fn(|_| BandRows::default());
        // Where the rows a band diffuses only to settle its error go.
        let mut spare: [Vec<u8>; N] = std::array::from_fn(|_| vec![0u8; w]);
        let longest = bands.iter().map(Band::rows).max().unwrap_or(0);
        for j in 0..longest {
            // Both bands while both have rows, then the longer one alone.
            let live: [bool; N] = std::array::from_fn(|s| j < bands[s].rows());
            if live.iter().all(|&l| l) {
                let ys: [usize; N] = std::array::from_fn(|s| bands[s].row(j));
                let rows: [(&[[f32; 3]], &[u32]); N] = {
                    for (s, b) in blocks.iter_mut().enumerate() {
                        b.load(fill, ys[s], bands[s].end, w);
                    }
                    std::array::from_fn(|s| blocks[s].row(ys[s], w))
                };
                let mut dst: [&mut [u8]; N] = {
                    let mut it = outs.iter_mut().zip(spare.iter_mut());
                    std::array::from_fn(|s| {
                        let (o, sp) = it.next().expect("one a band");
                        match bands[s].own(j) {
                            Some(r) => &mut o[r * w..(r + 1) * w],
                            None => &mut sp[..],
                        }
                    })
                };
                let mut st: [&mut FsState; N] = {
                    let mut it = state.iter_mut();
                    std::array::from_fn(|_| it.next().expect("one a band"))
                };
                let rtl = std::array::from_fn(|s| bands[s].right_to_left(j));
                self.fs_row(wt, w, &mut st, rows, ys, rtl, &mut dst);
            } else {
                for s in (0..N).filter(|&s| live[s]) {
                    let y = bands[s].row(j);
                    blocks[s].load(fill, y, bands[s].end, w);
                    let row = blocks[s].row(y, w);
                    let dst: &mut [u8] = match bands[s].own(j) {
                        Some(r) => &mut outs[s][r * w..(r + 1) * w],
                        None => &mut spare[s],
                    };
                    let rtl = [bands[s].right_to_left(j)];
                    self.fs_row::<1>(wt, w, &mut [&mut state[s]], [row], [y], rtl, &mut [dst]);
                }
            }
        }
    }

    // The rows' page numbers and scan directions are separate arguments on purpose: the
    // primed rows repeat a page row in both directions.
    #[allow(clippy::too_many_arguments)]
    /// One row of each of `N` bands (page rows `ys`, right to left where `rtl` says), a pixel
    /// of each in turn.
    ///
    /// Each pixel's value waits for the previous pixel's ink; so, while a pixel's ink is
    /// looked up, the next pixel's value is formed for every ink it could be (a lane each,
    /// with no wait), and the ink found picks one. What remains from one pixel to the next is
    /// the cell lookup and that pick. The row below is built in a window of three cells
    /// (written once, when complete).
    #[inline(always)]
    fn fs_row<const N: usize>(
        &self,
        wt: FsWeights,
        w: usize,
        st: &mut [&mut FsState; N],
        rows: [(&[[f32; 3]], &[u32]); N],
        ys: [usize; N],
        rtl: [bool; N],
        outs: &mut [&mut [u8]; N],
    ) {
        let (inks, table, lo, hi) = (self.inks, &self.table, self.lo, self.hi);
        let coords = coords();
        // The inks by channel, unused lanes holding the first ink (never picked).
        let ink: [[f32; LANES]; 3] =
            std::array::from_fn(|c| std::array::from_fn(|l| inks[l.min(inks.len() - 1)][c]));
        let rtl: [bool; N] = std::array::from_fn(|s| self.serpentine && rtl[s]);
        let mask = modulation();
        for s in 0..N {
            let f = &mut *st[s];
            let (trow, nrow) = rows[s];
            let mrow = &mask[(ys[s] % MOD_SIZE) * MOD_SIZE..][..MOD_SIZE];
            for i in 0..w {
                let x = if rtl[s] { w - 1 - i } else { i };
                let (t, e) = (trow[x], f.err[x + 1]);
                for (c, b) in f.base.iter_mut().enumerate() {
                    b[i] = t[c] + e[c];
                }
                f.avoid[i] = nrow[x];
                f.noise[i] = noise(t, mrow[x % MOD_SIZE]);
            }
        }
        // `v`: the value a pixel aims at plus its threshold modulation (what the ink is
        // chosen for; the error is measured without it).
        let mut v: [[f32; 3]; N] = std::array::from_fn(|s| {
            std::array::from_fn(|c| st[s].base[c][0].clamp(lo[c], hi[c]) + st[s].noise[0])
        });
        let mut here = [[0f32; 3]; N];
        let mut next = [[0f32; 3]; N];
        // Cell of the row below the previous pixel (page column + 1); 0 for none.
        let mut prev = [0usize; N];
        for i in 0..w {
            for s in 0..N {
                let x = if rtl[s] { w - 1 - i } else { i };
                let f = &mut *st[s];
                let (n, n_next) = (f.noise[i], f.noise[i + 1]);
                // Off the chain: the next pixel's value for every ink this one may take.
                let mut cand = [[0f32; LANES]; 3];
                for c in 0..3 {
                    let b = f.base[c][i + 1];
                    let here = v[s][c] - n;
                    for l in 0..LANES {
                        cand[c][l] =
                            min_f(max_f(b + (here - ink[c][l]) * wt.right, lo[c]), hi[c]) + n_next;
                    }
                }
                let k = table.avoiding(coords, v[s], f.avoid[i]) as usize & (LANES - 1);
                outs[s][x] = k as u8;
                let e: [f32; 3] = std::array::from_fn(|c| v[s][c] - n - ink[c][k]);
                let mut done = [0f32; 3];
                for c in 0..3 {
                    done[c] = here[s][c] + wt.behind * e[c];
                    here[s][c] = next[s][c] + wt.under * e[c];
                    next[s][c] = wt.ahead * e[c];
                }
                f.below[prev[s]] = done;
                prev[s] = x + 1;
                v[s] = [cand[0][k], cand[1][k], cand[2][k]];
            }
        }
        for s in 0..N {
            let f = &mut *st[s];
            f.below[prev[s]] = here[s];
            // What fell past the row's ends is dropped.
            f.below[0] = [0.0; 3];
            f.below[w + 1] = [0.0; 3];
            std::mem::swap(&mut f.err, &mut f.below);
        }
    }

    /// [`Diffusion::run`] for any kernel: the error spread through rows of cells.
    fn any(&self, source: &mut impl Rows, w: usize, out: &mut [u8]) {
        let (kernel, scale, serpentine, table, lo, hi) = (
            self.kernel,
            self.scale,
            self.serpentine,
            &self.table,
            self.lo,
            self.hi,
        );
        let h = out.len() / w;
        let coords = coords();
        let reach = kernel.reach();
        let rows = kernel.rows_below() + 1;
        let pad = reach;
        let stride = w + 2 * pad;
        let mut err = vec![[0f32; 3]; rows * stride];
        let taps: Vec<(i32, usize, f32)> = kernel
            .taps
            .iter()
            .map(|t| (t.dx, t.dy as usize, t.weight as f32 * scale))
            .collect();
        let mut at: Vec<(isize, f32)> = Vec::with_capacity(taps.len());
        for y in 0..h {
            let rtl = serpentine && y % 2 == 1;
            // Each tap's place in the error rows, relative to the pixel's column.
            at.clear();
            at.extend(taps.iter().map(|&(dx, dy, wgt)| {
                let row = ((y + dy) % rows) * stride + pad;
                let dx = if rtl { -dx } else { dx };
                (row as isize + dx as isize, wgt)
            }));
            let here = (y % rows) * stride + pad;
            let (trow, nrow) = source.row(y);
            let orow = &mut out[y * w..(y + 1) * w];
            let mrow = &modulation()[(y % MOD_SIZE) * MOD_SIZE..][..MOD_SIZE];
            for i in 0..w {
                let x = if rtl { w - 1 - i } else { i };
                let e = err[here + x];
                let t = trow[x];
                let v: [f32; 3] = std::array::from_fn(|c| (t[c] + e[c]).clamp(lo[c], hi[c]));
                let n = noise(t, mrow[x % MOD_SIZE]);
                let k = table.avoiding(coords, v.map(|c| c + n), nrow[x]);
                orow[x] = k;
                let ink = self.inks[k as usize];
                let d = [v[0] - ink[0], v[1] - ink[1], v[2] - ink[2]];
                for &(off, wgt) in &at {
                    let cell = &mut err[(off + x as isize) as usize];
                    cell[0] += d[0] * wgt;
                    cell[1] += d[1] * wgt;
                    cell[2] += d[2] * wgt;
                }
            }
            // This row's slot becomes the row `rows` below: cleared.
            let s = (y % rows) * stride;
            err[s..s + stride].iter_mut().for_each(|c| *c = [0.0; 3]);
        }
    }
}
