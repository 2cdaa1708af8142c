//! Halftoning for real inks: the method that joins the rendering intents
//! ([`crate::rendering`]: adaptation to the panel's white and black, tone and gamut mapping)
//! to a dither for the adapted inks: error diffusion measured against the mapped target
//! ([`Dither::Diffuse`], `method::diffusion::palette::inks`), palette DBS seeded
//! from that diffusion ([`Dither::Dbs`], [`crate::method::dbs::palette`]), or ordered palette
//! dithering ([`Dither::Ordered`]).

use crate::fmath as fm;
use rayon::prelude::*;

use super::diffusion::kernels::Kernel;
use super::diffusion::palette::inks::{
    diffuse, diffuse_primed, Block, Diffusion, NearestTable, PipedRows,
};
use super::gamut::{
    linear_of_oklab, nearest_mix, oklab as oklab64, Cusps, Hull, Line, HUE_CHROMA, LUMA,
};
use super::Method;
use crate::color::oklab;
use crate::error::{Error, Result};
use crate::mask::Mask;
use crate::press::RenderingIntent as Intent;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};
use crate::rendering::{
    tone_curve, Amount, Lut, Mapped, Rendering, Squeeze, ToneCurve, NEUTRAL_BIT, NEUTRAL_CHROMA,
    NEUTRAL_INK_CHROMA, NODES,
};
use crate::scielab::Adaptation;

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

/// A table node's colour: linear RGB and its Oklab.
type NodeColour = ([f64; 3], [f64; 3]);

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

/// How far (a share of the way) the perceptual map moves the lightness it compresses a
/// colour from towards the lightness of the inks' cusp at its hue, for a colour at least as
/// chromatic as the cusp (less in proportion below). All the way (1), every colour past a
/// dull cusp was aimed from the same lightness: on spectra6-7in3-v2, whose green ink is
/// Oklab L 0.51 and chroma 0.10, the foliage of mate-LadyBird (L 0.40 to 0.72) became wide
/// areas of solid green ink, flat as a poster. Half way keeps a bright yellow on the yellow
/// ink (`tests/it/hues.rs`) and measured better on all 14 Spectra 6 photos of the corpus
/// and 38 of 48 on bwry-4in2 (S-CIELAB CIEDE2000 means 11.64 → 10.68 and 15.88 → 15.36).
const CUSP_LIGHTNESS: f64 = 0.5;

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
                fm::hypot(lab[1] - grey[1], lab[2] - grey[2]) < NEUTRAL_INK_CHROMA
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
        let gain = fm::powf(2f64, r.exposure as f64);
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
            let (h, c, ch) = match cusps.nearest_hue(fm::atan2(b, a), ch) {
                Some((_, 0.0, _)) => (fm::atan2(b, a), c, ch),
                Some((h, _, keep)) => {
                    let ch = ch * keep;
                    (
                        h,
                        linear_of_oklab([l, ch * fm::cos(h), ch * fm::sin(h)]),
                        ch,
                    )
                }
                None => (0.0, linear_of_oklab([l, 0.0, 0.0]), 0.0),
            };
            // The luminance to compress from: [`CUSP_LIGHTNESS`] of the way to the cusp's
            // lightness as far as the colour's chroma reaches the cusp's, its own for a grey.
            let (lc, cc) = cusps.at(h);
            let k = CUSP_LIGHTNESS * if cc > 1e-6 { (ch / cc).min(1.0) } else { 0.0 };
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
                let ch = fm::hypot(a, b);
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
            let apart = fm::cos(HUE_APART);
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
            let m = if r.intent == Intent::Absolute {
                // Colours as given: inside the hull kept, outside the nearest mix of the
                // inks (by CIEDE2000), not a clip at the colour's luminance. (A flat hull's
                // reach is measured in its plane, so every colour goes to the nearest mix; a
                // segment's, black, white and greys, to the grey of its luminance.)
                match hull.dimension() {
                    3 if line.reach <= 1.0 => *moved,
                    2 | 3 => nearest_mix(inks, *moved),
                    _ => hull.clip_line(line).colour,
                }
            } else if line.dir == [0.0; 3] || scale == 1.0 {
                // Not moved: the line found is the one to clip along.
                hull.clip_line(line).colour
            } else if line.reach > 1.0 && r.intent == Intent::Saturation {
                // Saturation, a colour already outside: where its line leaves the hull (the
                // most the inks give). Drawn further out along the line as below, its
                // luminance ran away from the anchor's and the clip of that point was black:
                // saturated reds and greens rendered as black balls.
                hull.clip_line(line).colour
            } else if line.reach > 1.0 {
                // Outside: clipped (slid along the face it leaves by towards the hue the
                // inks have), then drawn in as its reach says (`scale · reach` of the way
                // out from the anchor): a colour far out keeps the clip's chroma instead of
                // stopping where its line first meets the hull.
                let (a, e) = (line.anchor, hull.clip_line(line).colour);
                let out = scale * line.reach;
                hull.clip(std::array::from_fn(|k| a[k] + out * (e[k] - a[k])))
                    .colour
            } else {
                let a = line.anchor;
                hull.clip(std::array::from_fn(|k| {
                    moved[k] + (scale - 1.0) * (moved[k] - a[k])
                }))
                .colour
            };
            // Chroma against the neutral of the same luminance (the inks' own black may
            // keep a tint after black-point compensation).
            let chroma_of = |m: [f64; 3]| {
                let y = LUMA[0] * m[0] + LUMA[1] * m[1] + LUMA[2] * m[2];
                let lab = oklab(m.map(|v| v as f32));
                let grey = oklab(hull.anchor(y).map(|v| v as f32));
                fm::hypot(lab[1] - grey[1], lab[2] - grey[2])
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
                let mut opts = super::dbs::palette::PaletteDbsOptions {
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
                super::dbs::palette::refine_within(
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
