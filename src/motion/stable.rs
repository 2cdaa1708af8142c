//! Error diffusion that stays put: a dot is re-decided only where the picture changed
//! enough for the eye to see it, or where keeping it would cost more than the eye can see.
//!
//! Frame by frame, error diffusion moves every dot downstream of any change: the error a
//! pixel passes on depends on every decision before it. Here each pixel remembers the
//! input it was last decided from (its reference) and its level. In a new frame:
//!
//! - a pixel whose input moved from its reference by more than the eye's single-pixel
//!   threshold `t` is quantised afresh;
//! - another keeps its level while the value it sees (input plus incoming error) stays
//!   near it, and is quantised afresh beyond: within half a step plus `t` where the eye
//!   box around it sees a change (so a kept dot carries at most `t` more error than
//!   rounding would, where the picture moves), within a whole step where the eye box sees
//!   none (so an error rerouted by a change elsewhere does not move dots in a still area).
//!
//! The error is accounted in every case: a kept pixel passes on `value + incoming error −
//! its level`, so the tone downstream stays right.
//!
//! The eye model is that of [`crate::quality`] at the viewing distance. Näsänen's contrast
//! sensitivity at zero frequency, a·L^b = 282.7 at the model's adaptation of 11 cd/m²,
//! gives a just-visible contrast c = 1/282.7 = 0.35% of the adapting luminance (the
//! frame's mean reflectance m). The eye sees through the low-pass exp(−f/f₀), in space a
//! Poisson kernel of scale s = ppd/(2π f₀) pixels whose noise-equivalent area is A = 8π s².
//! - One pixel's change of d reaches the eye as about d/A, so it is visible from
//!   `t = A·c·m` on: at 300 dpi and 12 in, A = 94 px and t = 0.33·m.
//! - A change spread over an area is seen through a box of that same area (side √A ≈ 5 s,
//!   radius 4 px at 300 dpi and 12 in): the eye box sees a change where the signed
//!   difference from the references, averaged over the box, exceeds c·m.
//!
//! A still clip gives identical frames (nothing changes, every pixel keeps its level and
//! sees the same error as before). A change in one region re-decides the dots of that
//! region and, within the eye box's radius of it, those the rerouted error pushes past the
//! narrow valve; beyond, a dot moves only if the error it sees strays a whole step, which
//! `tests/it/motion.rs` finds nowhere for a patch of +50 codes.

use crate::fmath as fm;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::method::diffusion::kernels::{Kernel, MAX_REACH};
use crate::options::{Color, ContentKind, MethodKind, Options};
use crate::quality::{nasanen_absolute, Viewing, NASANEN_C, NASANEN_D, NASANEN_L};
use crate::raster::{pack_row, ColorKind, ColorMode, Halftone, Image, PlaneRef};
use crate::tone::ToneOptions;

/// Stable error diffusion over a clip (grey or RGB levels, a fixed kernel).
pub struct StableDiffusion {
    kernel: Kernel,
    taps: Vec<(isize, usize, f32)>,
    levels: u16,
    serpentine: bool,
    /// The eye filter's noise-equivalent area, pixels.
    area: f32,
    /// Box radius of the eye filter, pixels.
    radius: usize,
    /// The just-visible contrast.
    contrast: f32,
    planes: Vec<State>,
}

/// One plane's memory of the frame before, and the buffers each frame reuses.
struct State {
    width: usize,
    height: usize,
    reference: Vec<f32>,
    level: Vec<u8>,
    /// The frame's values (linear light).
    values: Vec<f32>,
    /// The horizontal box sums of the change.
    sums: Vec<f32>,
    /// Where the eye box sees a change.
    mask: Vec<bool>,
}

impl StableDiffusion {
    /// True when `opts` ask for what this diffuses: error diffusion with a fixed kernel to
    /// grey or RGB levels (no palette, device, CMYK, transfer curve, content handling or
    /// hysteresis feedback).
    pub fn applies(opts: &Options) -> bool {
        opts.method == MethodKind::Diffuse
            && opts.palette.is_none()
            && opts.device.is_none()
            && opts.color != Color::Cmyk
            && opts.content == ContentKind::Photo
            && opts.transfer.is_none()
            && opts.preset_transfer.is_none()
            && opts.hysteresis == 0.0
            && Kernel::builtin(&opts.kernel).is_some()
    }

    /// Built from the options' kernel, levels, scan, strength and viewing (`dpi`,
    /// `distance`).
    pub fn new(opts: &Options) -> Result<StableDiffusion> {
        if !(2..=256).contains(&opts.levels) {
            return Err(Error::Option {
                field: "levels",
                value: opts.levels.to_string(),
                msg: "must be from 2 to 256".into(),
            });
        }
        let kernel = Kernel::load(&opts.kernel)?;
        let view = opts.view()?;
        let div = kernel.divisor as f32;
        let taps = kernel
            .taps
            .iter()
            .map(|t| {
                (
                    t.dx as isize,
                    t.dy as usize,
                    t.weight as f32 / div * opts.strength,
                )
            })
            .collect();
        Ok(StableDiffusion {
            kernel,
            taps,
            levels: opts.levels,
            serpentine: opts.serpentine,
            area: eye_area(&view) as f32,
            radius: eye_box_radius(&view),
            contrast: just_visible_contrast() as f32,
            planes: Vec::new(),
        })
    }

    /// The name for reports.
    pub fn name(&self) -> String {
        format!(
            "stable diffusion ({}{}, eye area {:.0} px, contrast {:.2}%)",
            self.kernel.name,
            if self.serpentine { ", serpentine" } else { "" },
            self.area,
            self.contrast * 100.0
        )
    }

    /// Halftones the next frame.
    pub fn next(&mut self, img: &Image, color: ColorMode, tone: &ToneOptions) -> Result<Halftone> {
        let gray;
        let src = if color == ColorMode::Gray && img.color == ColorKind::Rgb {
            gray = img.to_luminance(tone);
            &gray
        } else {
            img
        };
        let table = src.tone_table(tone);
        let planes = src.planes(&table);
        let mut refs: Vec<PlaneRef<'_>> = planes.planes.clone();
        if color == ColorMode::Rgb && refs.len() == 1 {
            refs = vec![refs[0]; 3];
        }
        let (w, h) = (src.width, src.height);
        if self.planes.len() != refs.len()
            || self.planes.iter().any(|s| (s.width, s.height) != (w, h))
        {
            self.planes = (0..refs.len())
                .map(|_| State {
                    width: w,
                    height: h,
                    reference: Vec::new(),
                    level: vec![0; w * h],
                    values: vec![0f32; w * h],
                    sums: Vec::new(),
                    mask: Vec::new(),
                })
                .collect();
        }
        let mut out = Halftone::new(w, h, refs.len(), self.levels);
        let (area, radius, contrast, levels, serp) = (
            self.area,
            self.radius,
            self.contrast,
            self.levels,
            self.serpentine,
        );
        let taps = &self.taps;
        let rows_below = self.kernel.rows_below();
        self.planes
            .par_iter_mut()
            .zip(out.planes.par_iter_mut())
            .zip(refs.par_iter())
            .for_each(|((state, packed), plane)| {
                let mut v = std::mem::take(&mut state.values);
                v.par_chunks_mut(w.max(1))
                    .enumerate()
                    .for_each(|(y, row)| plane.row_linear(y, row));
                // The mean from row sums added in order: the same whatever the thread count.
                let rows: Vec<f64> = v
                    .par_chunks(w.max(1))
                    .map(|row| row.iter().map(|&x| x as f64).sum::<f64>())
                    .collect();
                let mean = rows.iter().sum::<f64>() / v.len().max(1) as f64;
                let t = area * contrast * mean.max(1e-4) as f32;
                let first = state.reference.len() != w * h;
                let mut mask = std::mem::take(&mut state.mask);
                if first {
                    state.reference = vec![0f32; w * h];
                } else {
                    change_mask(
                        &v,
                        &state.reference,
                        (w, h),
                        radius,
                        contrast * mean.max(1e-4) as f32,
                        &mut state.sums,
                        &mut mask,
                    );
                }
                let seen = (!first).then_some((t, &mask[..]));
                diffuse(&v, seen, state, taps, rows_below, levels, serp);
                state.mask = mask;
                state.values = v;
                let stride = packed.len() / h.max(1);
                let bits = crate::raster::bits_for_levels(levels);
                for (y, row) in packed.chunks_exact_mut(stride.max(1)).enumerate() {
                    pack_row(&state.level[y * w..(y + 1) * w], bits, row);
                }
            });
        Ok(out)
    }
}

/// The just-visible contrast of Näsänen's model: 1 / its sensitivity at zero frequency.
pub fn just_visible_contrast() -> f64 {
    1.0 / nasanen_absolute(0.0)
}

/// The noise-equivalent area, in pixels, of the Näsänen filter at `view` (module docs):
/// 8π s² with s = ppd / (2π f₀).
pub fn eye_area(view: &Viewing) -> f64 {
    let f0 = NASANEN_C * fm::ln(NASANEN_L) + NASANEN_D;
    let s = view.pixels_per_degree() / (2.0 * std::f64::consts::PI * f0);
    8.0 * std::f64::consts::PI * s * s
}

/// The radius of the box with the noise-equivalent area of the Näsänen filter at `view`
/// (module docs).
pub fn eye_box_radius(view: &Viewing) -> usize {
    let f0 = NASANEN_C * fm::ln(NASANEN_L) + NASANEN_D;
    let s = view.pixels_per_degree() / (2.0 * std::f64::consts::PI * f0);
    let side = (8.0 * std::f64::consts::PI).sqrt() * s;
    (((side - 1.0) / 2.0).round().max(1.0) as usize).min(64)
}

/// Where the input differs visibly from the reference: the signed difference averaged over
/// a (2r+1)² box, against `contrast` times the frame's mean reflectance. `sums` and `mask`
/// are reused from frame to frame.
fn change_mask(
    v: &[f32],
    reference: &[f32],
    (w, h): (usize, usize),
    r: usize,
    limit: f32,
    sums: &mut Vec<f32>,
    mask: &mut Vec<bool>,
) {
    // Horizontal box sums of the difference, row by row.
    sums.resize(w * h, 0.0);
    sums.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let d = |x: usize| v[y * w + x] - reference[y * w + x];
        let mut acc = 0f32;
        for x in 0..r.min(w) {
            acc += d(x);
        }
        for (x, o) in out.iter_mut().enumerate() {
            if x + r < w {
                acc += d(x + r);
            }
            *o = acc;
            if x >= r {
                acc -= d(x - r);
            }
        }
    });
    let hs = &sums[..];
    // Vertical sums over bands of columns, each sum divided by the full box's area (the
    // border counts what is missing as unchanged).
    let area = ((2 * r + 1) * (2 * r + 1)) as f32;
    mask.clear();
    mask.resize(w * h, false);
    let mut acc = vec![0f32; w];
    for y in 0..r.min(h) {
        for (a, &s) in acc.iter_mut().zip(&hs[y * w..(y + 1) * w]) {
            *a += s;
        }
    }
    for y in 0..h {
        if y + r < h {
            for (a, &s) in acc.iter_mut().zip(&hs[(y + r) * w..(y + r + 1) * w]) {
                *a += s;
            }
        }
        for (m, &a) in mask[y * w..(y + 1) * w].iter_mut().zip(&acc) {
            *m = (a / area).abs() > limit;
        }
        if y >= r {
            for (a, &s) in acc.iter_mut().zip(&hs[(y - r) * w..(y - r + 1) * w]) {
                *a -= s;
            }
        }
    }
}

/// One plane diffused: with no threshold (the first frame) every pixel is quantised
/// afresh; with one, `t` (module docs), a pixel whose input moved from its reference by
/// more than `t` is, and another keeps its level while the value it sees is within half a
/// step plus `t` of it.
fn diffuse(
    v: &[f32],
    seen: Option<(f32, &[bool])>,
    state: &mut State,
    taps: &[(isize, usize, f32)],
    rows_below: usize,
    levels: u16,
    serpentine: bool,
) {
    let (w, h) = (state.width, state.height);
    let pad = MAX_REACH;
    let stride = w + 2 * pad;
    let nrows = rows_below + 1;
    let top = (levels - 1) as f32;
    let step = 1.0 / top;
    let binary = levels == 2;
    // Level of a value: round(u·top) within the levels (for two levels, u ≥ ½, the same
    // without a call to round).
    let quantise = |u: f32| -> u8 {
        if binary {
            (u >= 0.5) as u8
        } else {
            (u * top).round().clamp(0.0, top) as u8
        }
    };
    // The error rows, a ring: row y's at (y mod nrows).
    let mut err = vec![0f32; nrows * stride];
    let mut offs: Vec<(isize, f32)> = Vec::with_capacity(taps.len());
    for y in 0..h {
        let rtl = serpentine && y % 2 == 1;
        let dir: isize = if rtl { -1 } else { 1 };
        offs.clear();
        offs.extend(
            taps.iter()
                .map(|&(dx, dy, wt)| ((((y + dy) % nrows) * stride + pad) as isize + dir * dx, wt)),
        );
        let cur = (y % nrows) * stride + pad;
        let vrow = &v[y * w..(y + 1) * w];
        let lrow = &mut state.level[y * w..(y + 1) * w];
        let rrow = &mut state.reference[y * w..(y + 1) * w];
        for i in 0..w {
            let x = if rtl { w - 1 - i } else { i };
            let u = vrow[x] + err[cur + x];
            let keep = match seen {
                Some((t, boxed)) if (vrow[x] - rrow[x]).abs() <= t => {
                    let lim = if boxed[y * w + x] {
                        0.5 * step + t
                    } else {
                        step
                    };
                    (u - lrow[x] as f32 * step).abs() <= lim
                }
                _ => false,
            };
            let q = if keep {
                lrow[x]
            } else {
                rrow[x] = vrow[x];
                quantise(u)
            };
            lrow[x] = q;
            let e = u - q as f32 * step;
            for &(off, wt) in &offs {
                err[(off + x as isize) as usize] += e * wt;
            }
        }
        let row = (y % nrows) * stride;
        err[row..row + stride].fill(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eye_figures() {
        // 1/282.7: Näsänen's peak sensitivity at 11 cd/m².
        assert!((just_visible_contrast() - 0.003537).abs() < 1e-5);
        // 300 dpi at 12 inches: s = 62.8/(2π·5.169) = 1.93 px, 8π s² = 94 px.
        assert!((eye_area(&Viewing::default()) - 94.0).abs() < 1.0);
    }

    #[test]
    fn still_frames_repeat_and_changes_stay_local() {
        let opts = Options::default();
        let mut s = StableDiffusion::new(&opts).unwrap();
        let (w, h) = (96, 64);
        let grad: Vec<u8> = (0..w * h).map(|i| (i % w * 255 / w) as u8).collect();
        let tone = opts.tone().unwrap();
        let a = s
            .next(&Image::gray8(w, h, grad.clone()), ColorMode::Gray, &tone)
            .unwrap();
        let b = s
            .next(&Image::gray8(w, h, grad.clone()), ColorMode::Gray, &tone)
            .unwrap();
        assert_eq!(a, b);
        // A box in the middle turns white.
        let mut moved = grad.clone();
        for y in 20..30 {
            for x in 40..50 {
                moved[y * w + x] = 255;
            }
        }
        let c = s
            .next(&Image::gray8(w, h, moved), ColorMode::Gray, &tone)
            .unwrap();
        assert_ne!(b, c);
        // The eye box's radius and the kernel's reach (Floyd–Steinberg: one pixel).
        let r = s.radius + 1;
        let mut far = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let near = (20 - r..30 + r).contains(&y) && (40 - r..50 + r).contains(&x);
                if !near && b.get(0, x, y) != c.get(0, x, y) {
                    far.push((x, y));
                }
            }
        }
        assert!(far.is_empty(), "{} dots moved outside: {far:?}", far.len());
    }
}
