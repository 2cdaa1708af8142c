//! Rendering for real inks: how a picture is mapped into what a panel's inks can show.
//!
//! A reflective panel's inks are dull: its white is a light grey, its black a dark grey, its
//! red a brick. The viewer adapts to the panel's white and black, so the picture is rendered
//! **relative** to them: the inks are taken as that viewer sees them (Bradford adaptation to
//! the panel white and black-point compensation, [`crate::scielab::Adaptation`]), the panel
//! white being `[1, 1, 1]`. Then the picture is mapped into what the inks can show by
//! dithering (the hull of the inks in linear light, [`crate::method::gamut::Hull`]) by the
//! rendering intent:
//!
//! - **perceptual**: the tone range stretched to the panel's (`tone`, automatic from the
//!   luminance histogram) and colours compressed towards the neutral of their own luminance,
//!   hue kept, the outer part of the gamut softly (`gamut`, automatic from how far the
//!   picture's colours reach past the inks);
//! - **relative** (colorimetric, with black-point compensation): colours inside the inks'
//!   hull are kept, those outside clipped into it at their luminance;
//! - **saturation**: colours pushed out to fill the inks' gamut, then clipped;
//! - **absolute**: the picture as it is against the inks as measured (no mapping; the
//!   palette diffusion of [`crate::method::diffusion`]).
//!
//! The mapping runs through a 17³ table over the input's linear light (nodes spaced as the
//! square of their index, so dark colours get finer steps) with tetrahedral interpolation:
//! the identity is exact through it, and the map is computed at 4,913 nodes instead of every
//! pixel. The method that uses it is [`crate::method::device::InkMethod`]; the mapped picture
//! ([`Mapped`]) is dithered by `method::diffusion::palette::inks`.

use rayon::prelude::*;

use crate::method::gamut::LUMA;
use crate::press::RenderingIntent as Intent;

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
pub(crate) const NEUTRAL_CHROMA: f32 = 0.025;

/// Oklab chroma below which an ink counts as neutral.
pub(crate) const NEUTRAL_INK_CHROMA: f32 = 0.04;

/// Table nodes along each axis.
pub(crate) const NODES: usize = 17;

/// The bit of an [`Mapped::avoid`] mask that marks a neutral pixel (inks use bits 0 to 15).
pub const NEUTRAL_BIT: u32 = 1 << 31;

/// A tone curve on luminance: `y → (y − lo) / (hi − lo)` blended in by a strength.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ToneCurve {
    pub(crate) lo: f64,
    pub(crate) hi: f64,
}

impl ToneCurve {
    pub(crate) const IDENTITY: ToneCurve = ToneCurve { lo: 0.0, hi: 1.0 };

    pub(crate) fn apply(&self, c: [f64; 3]) -> [f64; 3] {
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
pub(crate) fn tone_curve(sample: &[[f64; 3]], amount: Amount) -> ToneCurve {
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
pub(crate) enum Squeeze {
    /// Every colour scaled by this.
    Scale(f64),
    /// Reaches above `knee` compressed so that `top` lands on the hull's edge.
    Knee { knee: f64, top: f64 },
}

impl Squeeze {
    /// Gamut compression of strength `amount` for a picture whose colours reach `p99` of the
    /// way to the inks' edge (99th percentile).
    pub(crate) fn compress(amount: Amount, p99: f64) -> Squeeze {
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
    pub(crate) fn factor(&self, r: f64) -> f64 {
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
pub(crate) struct Lut {
    pub(crate) values: Vec<[f32; 4]>,
    pub(crate) avoid: Vec<u32>,
}

impl Lut {
    pub(crate) fn position(i: usize) -> f32 {
        let t = i as f32 / (NODES - 1) as f32;
        t * t
    }

    /// The table of `f(i)` for node `i` (red fastest, then green, then blue).
    pub(crate) fn build(f: impl Fn(usize) -> ([f32; 4], u32) + Sync + Send) -> Lut {
        let (values, avoid) = (0..NODES * NODES * NODES)
            .into_par_iter()
            .with_min_len(NODES * NODES * NODES / 2)
            .map(f)
            .unzip();
        Lut { values, avoid }
    }

    /// The mask of the node nearest the point (in the cell's own fractions).
    #[inline(always)]
    pub(crate) fn avoid_at(&self, r: (u8, f32), g: (u8, f32), b: (u8, f32)) -> u32 {
        let at = |v: (u8, f32)| v.0 as usize + (v.1 > 0.5) as usize;
        self.avoid[at(r) + NODES * at(g) + NODES * NODES * at(b)]
    }

    /// The cell and the weight of its upper node for a linear value.
    pub(crate) fn locate(v: f32) -> (u8, f32) {
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
    pub(crate) fn sample(&self, r: (u8, f32), g: (u8, f32), b: (u8, f32)) -> [f32; 4] {
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
