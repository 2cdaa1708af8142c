//! Direct binary search (method `dbs`): the halftone that minimises the eye-filtered error,
//! found by trying every toggle of a pixel and every swap with its 8 neighbours and keeping
//! each change that lowers the error, pass after pass until a pass changes nothing.
//!
//! Efficient DBS after Lieberman and Allebach, "Efficient model based halftoning using direct
//! binary search" (ICIP 1997), and Analoui and Allebach, "Model-based halftoning using direct
//! binary search" (SPIE 1666, 1992). The error `e = b − x` (halftone minus the tone-corrected
//! original, linear reflectance) is judged through the eye's filter `h`; the objective is
//! `E = Σ (h ⊛ e)² = Σ_m e[m]·c_ep[m]` with `c_pp = h ⋆ h` (the filter's autocorrelation) and
//! `c_ep = c_pp ⊛ e`. A change of `a` at pixel m changes E by `a²·c_pp[0] + 2a·c_ep[m]`; a swap
//! (a at m, −a at n) by `2a²·(c_pp[0] − c_pp[n−m]) + 2a·(c_ep[m] − c_ep[n])`. Only `c_ep` has to
//! be kept up to date: each accepted change adds `a·c_pp` around the pixel.
//!
//! The filter is Näsänen's, the one [`crate::quality::compare`] scores with, at the print's dpi
//! and viewing distance: `H(f) = exp(−f/f₀)` is the Fourier transform of a Poisson kernel of
//! scale `s = 1/(2π f₀)` (f₀ in cycles per pixel), so `|H|²` is the Poisson kernel of scale
//! `2s` and `c_pp(r) = 2s / (2π ((2s)² + r²)^{3/2})`, exactly, with no FFT.
//!
//! # Edges
//! [`crate::quality::compare`] filters the error mirrored out at the image's edges, so DBS
//! minimises the same thing: `ẽ`, the error reflected in each edge (within `radius` of it),
//! and `E = Σ_{m in the image} e[m]·(c_pp ⊛ ẽ)[m]`, a quarter of the filtered error energy of
//! one period of the mirrored plane. A change at m also changes its mirror images, so its own
//! cost `c_pp[0]` becomes `Σ c_pp[m − m']` over m and its images m' (and likewise between a
//! swap's two pixels), and the change is spread into `c_ep` from every image. Away from the
//! edges nothing differs.
//!
//! # Warm-up
//! By default DBS first searches for the print seen from ⅔ of the viewing distance (a filter
//! ⅔ the size), then refines that for the real distance: a plain search from Floyd–Steinberg
//! stops in a worse local minimum (0.2 dB on photos, docs/accuracy.md).
//!
//! # Printed output (model-based DBS)
//! With a [`PrinterModel`], `b` is replaced by the printed reflectance `P(b)` of every pixel,
//! which depends on its 3×3 neighbourhood: a toggle changes up to 9 printed pixels and a swap
//! up to 15, and the change in E is `Σ_i δ_i (2 c_ep[i] + Σ_j δ_j c_pp[i−j])` over them.
//!
//! # Threads and determinism
//! The image is cut into square tiles in four classes by the parity of their column and row.
//! A pass updates the four classes one after the other; the tiles of one class run in
//! parallel. A tile writes levels within 1 pixel of itself (a swap's partner) and `c_ep` within
//! `radius + 3` (mirror images of a pixel spread into the image no further than the pixel
//! itself does); tiles of one class are a whole tile apart, wider than twice that reach, so they
//! never touch each other's data and each tile sees the same data whatever the thread count:
//! the output is the same bytes for 1 or 2 threads.
//!
//! # Skipping settled pixels
//! A pixel's best change depends only on `c_ep` and the levels within one pixel of it; these
//! change only when something within `radius + 2` (+2 with a printer model) changes. The image
//! is kept as 8×8 blocks with a dirty flag; a pass visits only blocks that were dirty after the
//! previous one. Within a block, the 8 pixels of a row are judged side by side first
//! (`Ctx::row_bilevel`): most keep their level.
//!
//! # Tone
//! DBS with a truncated `c_pp` is known to bias tone (too few dots in highlights and shadows).
//! Lieberman and Allebach correct the input: [`DBS_TONE_TEXT`] holds the input that makes DBS
//! print each grey of a ramp of flats, measured by `halftone train dbs-tone`.

pub mod palette;

use crate::fmath as fm;
use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};

use rayon::prelude::*;

use super::diffusion::{Diffuse, DiffuseOptions};
use super::Method;
use crate::error::{Error, Result};
use crate::printer_model::PrinterModel;
use crate::quality::{Viewing, NASANEN_C, NASANEN_D, NASANEN_L};
use crate::raster::{pack_row, Halftone, PlaneRef, Planes};

/// Tile side, pixels (see the module documentation: must exceed twice the write reach).
const TILE: usize = 64;
/// Dirty-flag block side, pixels.
const BLOCK: usize = 8;
/// A change is kept only when it lowers E by more than this (f32 rounding of `c_ep` must
/// not let two states flip back and forth).
const EPS: f32 = 1e-6;

/// Default radius of `c_pp` (33 × 33 taps; see [`cpp_tapered`] and docs/accuracy.md).
pub const RADIUS: usize = 16;
/// Default σ of the window that tapers `c_pp` (docs/accuracy.md).
pub const SIGMA: f64 = 10.0;
/// Default warm-up distance, as a fraction of the viewing distance (docs/accuracy.md).
pub const WARM_UP: f64 = 2.0 / 3.0;
/// Radius for model-based DBS, whose every trial touches up to 15 printed pixels.
pub const MODEL_RADIUS: usize = 8;

/// Tone correction of bilevel DBS: the input reflectance that makes DBS print each of these
/// evenly spaced greys (0, 1/32, …, 1), made by `halftone train dbs-tone` (see
/// `kernels/dbs-tone.txt`).
pub const DBS_TONE_TEXT: &str = include_str!("../../../kernels/dbs-tone.txt");

/// Options of direct binary search.
#[derive(Clone, Debug)]
pub struct DbsOptions {
    /// Output levels, 2..=256.
    pub levels: u16,
    /// How the print is viewed (sets the filter).
    pub view: Viewing,
    /// Upper bound on the number of passes (DBS stops earlier when a pass changes nothing).
    pub passes: u32,
    /// Radius of the truncated filter autocorrelation `c_pp`, pixels.
    pub radius: usize,
    /// σ of the Gaussian window that tapers `c_pp`, pixels (see [`cpp_tapered`]).
    pub sigma: f64,
    /// Warm-up: first search for the print seen from this fraction of the viewing distance
    /// (a sharper eye), then refine for the real one from there (`None`: one search from
    /// Floyd–Steinberg). See docs/accuracy.md.
    pub warm_up: Option<f64>,
    /// Optimise the printed result under this model (bilevel only).
    pub printer: Option<PrinterModel>,
    /// Apply the tone correction table (bilevel without a printer model).
    pub tone_correct: bool,
}

impl DbsOptions {
    /// Model-based DBS for `printer` with the other options at their defaults.
    pub fn for_printer(printer: PrinterModel) -> DbsOptions {
        DbsOptions {
            printer: Some(printer),
            radius: MODEL_RADIUS,
            sigma: MODEL_RADIUS as f64 / 2.0,
            warm_up: None,
            ..DbsOptions::default()
        }
    }
}

impl Default for DbsOptions {
    fn default() -> Self {
        DbsOptions {
            levels: 2,
            view: Viewing::default(),
            passes: 40,
            radius: RADIUS,
            sigma: SIGMA,
            warm_up: Some(WARM_UP),
            printer: None,
            tone_correct: true,
        }
    }
}

/// The `dbs` method.
#[derive(Clone, Debug)]
pub struct Dbs {
    /// The options.
    pub options: DbsOptions,
    tone: Vec<f32>,
}

/// Parses a tone table: `#` comments, whitespace-separated numbers, first and last 0 and 1.
pub fn parse_tone_table(text: &str) -> Vec<f32> {
    text.lines()
        .flat_map(|l| l.split('#').next().unwrap_or("").split_whitespace())
        .filter_map(|w| w.parse().ok())
        .collect()
}

/// Applies a tone table of evenly spaced entries by linear interpolation.
pub fn apply_tone_table(table: &[f32], v: f32) -> f32 {
    if table.len() < 2 {
        return v;
    }
    let n = (table.len() - 1) as f32;
    let t = (v.clamp(0.0, 1.0) * n).min(n - 1e-6);
    let i = t as usize;
    let f = t - i as f32;
    table[i] + (table[i + 1] - table[i]) * f
}

impl Dbs {
    /// DBS with these options; checks them.
    pub fn new(options: DbsOptions) -> Result<Dbs> {
        crate::method::threshold::check_levels(options.levels)?;
        if options.printer.is_some() && options.levels != 2 {
            return Err(Error::Invalid(
                "a printer model works with bilevel output only (`levels` 2)".into(),
            ));
        }
        if options.radius == 0 || 2 * (options.radius + 4) >= TILE {
            return Err(Error::Invalid(format!(
                "DBS filter radius {}: must be 1..={}",
                options.radius,
                TILE / 2 - 5
            )));
        }
        let tone = if options.tone_correct && options.levels == 2 && options.printer.is_none() {
            parse_tone_table(DBS_TONE_TEXT)
        } else {
            Vec::new()
        };
        Ok(Dbs { options, tone })
    }
}

/// The autocorrelation of Näsänen's filter at `view`, `(2r+1)²` taps, row-major, centre at
/// `(r, r)` (see the module documentation), tapered by a Gaussian window.
///
/// Cutting the slowly decaying `c_pp` off at a radius makes its spectrum ripple below zero at
/// high frequencies, and DBS then *rewards* error there (it drew stripes at r = 6). Multiplying
/// by a Gaussian keeps it a positive-definite kernel (a product of two is one, Schur), so every
/// frequency is penalised. The window must still be cut somewhere: σ = r/3 keeps the cut
/// table's spectrum positive, σ = r/2 leaves it dipping to −0.06% of its DC value (against −3%
/// for a hard cut at r = 6) and scored 0.24 dB better on photos (docs/accuracy.md), so it is
/// the default.
pub fn cpp_table(view: &Viewing, radius: usize) -> Vec<f32> {
    cpp_tapered(view, radius, radius as f64 / 2.0)
}

/// [`cpp_table`] with the Gaussian window's σ given (pixels; infinite = a hard cut).
pub fn cpp_tapered(view: &Viewing, radius: usize, sigma: f64) -> Vec<f32> {
    let f0 = (NASANEN_C * fm::ln(NASANEN_L) + NASANEN_D) / view.pixels_per_degree();
    let s2 = 2.0 / (2.0 * std::f64::consts::PI * f0);
    let n = 2 * radius + 1;
    let mut t = vec![0f32; n * n];
    for (i, v) in t.iter_mut().enumerate() {
        let dx = (i % n) as f64 - radius as f64;
        let dy = (i / n) as f64 - radius as f64;
        let r2 = dx * dx + dy * dy;
        let window = fm::exp(-r2 / (2.0 * sigma * sigma));
        *v = (window * s2 / (2.0 * std::f64::consts::PI * fm::powf(s2 * s2 + r2, 1.5))) as f32;
    }
    t
}

impl Method for Dbs {
    fn name(&self) -> String {
        let mut s = "dbs".to_string();
        if self.options.levels != 2 {
            s.push_str(&format!("(levels {})", self.options.levels));
        }
        if let Some(p) = &self.options.printer {
            s.push_str(&format!("(printer {})", p.name));
        }
        s
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        // The start: Floyd–Steinberg in linear light.
        let fs = Diffuse::new(
            "floyd-steinberg",
            DiffuseOptions {
                levels: self.options.levels,
                ..DiffuseOptions::default()
            },
        )?
        .halftone(input)?;
        let levels = self.options.levels;
        // Planes run one after the other; each uses every thread.
        let mut out = Halftone::new(input.width, input.height, input.planes.len(), levels);
        for (c, plane) in input.planes.iter().enumerate() {
            let target = self.target(plane);
            let result = self.search_plane(&target, fs.levels_of(c), plane.width, plane.height)?;
            let (bits, stride) = (out.bits, out.stride);
            for (y, row) in out.planes[c].chunks_exact_mut(stride).enumerate() {
                pack_row(&result[y * plane.width..(y + 1) * plane.width], bits, row);
            }
        }
        Ok(out)
    }
}

impl Dbs {
    /// DBS of one plane: `target` reflectance, `start` levels (one byte a pixel), with the
    /// warm-up search first when the options ask for one.
    pub fn search_plane(
        &self,
        target: &[f32],
        start: Vec<u8>,
        w: usize,
        h: usize,
    ) -> Result<Vec<u8>> {
        let o = &self.options;
        let mut levels = start;
        if let (Some(f), None) = (o.warm_up, &o.printer) {
            // The eye closer by f sees f times fewer pixels a degree: the filter shrinks by
            // f, and so do its radius and window.
            let view = Viewing::new(o.view.dpi, o.view.distance_in * f)?;
            let r = ((o.radius as f64 * f).round() as usize).max(1);
            let cpp = cpp_tapered(&view, r, r as f64 / 2.0);
            levels = search(
                target, &levels, w, h, o.levels, &cpp, r, None, o.passes, false,
            )
            .0;
        }
        let cpp = cpp_tapered(&o.view, o.radius, o.sigma);
        Ok(search(
            target,
            &levels,
            w,
            h,
            o.levels,
            &cpp,
            o.radius,
            o.printer.as_ref(),
            o.passes,
            false,
        )
        .0)
    }
}

impl Dbs {
    /// The plane as reflectance, tone-corrected.
    fn target(&self, plane: &PlaneRef<'_>) -> Vec<f32> {
        let (w, h) = (plane.width, plane.height);
        let mut t = vec![0f32; w * h];
        // Correct the tone table once, not every pixel.
        let table: Vec<f32> = if self.tone.is_empty() {
            plane.tone.to_vec()
        } else {
            plane
                .tone
                .iter()
                .map(|&v| apply_tone_table(&self.tone, v))
                .collect()
        };
        let p = PlaneRef {
            tone: &table,
            ..*plane
        };
        t.par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| p.row_linear(y, row));
        t
    }
}

/// The state of a search, in arrays padded by `pad` pixels on every side.
struct State {
    w: usize,
    h: usize,
    pad: usize,
    /// Padded row length.
    pw: usize,
    /// Level of every pixel; −1 outside the image.
    lev: Vec<i16>,
    /// `c_pp ⊛ ẽ`, the error mirrored out (module documentation); meaningful inside the
    /// image only.
    cep: Vec<f32>,
    /// Printer model only: neighbourhood index and printed reflectance of every pixel.
    cfg: Vec<u16>,
    printed: Vec<f32>,
}

/// Shared mutable access for the tiles of one class (see the module documentation on why
/// they never touch the same cells).
struct Shared {
    lev: *mut i16,
    cep: *mut f32,
    cfg: *mut u16,
    printed: *mut f32,
}
// SAFETY: tiles running at the same time read and write disjoint cells (module docs).
unsafe impl Sync for Shared {}
unsafe impl Send for Shared {}

/// Whether the AVX2 builds of the hot loops run (same arithmetic, wider vectors: no fused
/// multiply-add, so the bytes do not depend on it).
fn have_avx2() -> bool {
    crate::cpu::avx2()
}

/// The positions along one axis of length `n` at which pixel `p` appears in the mirrored
/// error `ẽ` within `r` of the image: itself, and its reflections in the near edges.
#[inline(always)]
fn axis_copies(p: usize, n: usize, r: usize) -> ([isize; 3], usize) {
    let mut c = [p as isize, 0, 0];
    let mut k = 1;
    if p < r {
        c[k] = -1 - p as isize;
        k += 1;
    }
    if p + r >= n {
        c[k] = 2 * n as isize - 1 - p as isize;
        k += 1;
    }
    (c, k)
}

/// Where padded position `p` (image coordinate, may be negative) reads the mirrored error:
/// the image pixel it reflects, if it is within `r` of the image (see [`axis_copies`]).
pub(crate) fn mirror_source(p: isize, n: usize, r: usize) -> Option<usize> {
    let n = n as isize;
    let s = if p < 0 {
        if p < -(r as isize) {
            return None;
        }
        -1 - p
    } else if p >= n {
        if p >= n + r as isize {
            return None;
        }
        2 * n - 1 - p
    } else {
        p
    };
    (0..n).contains(&s).then_some(s as usize)
}

/// `c_ep = c_pp ⊛ ẽ` over the image, from the levels (or printed values) and the target:
/// the error is mirrored out by `radius` as [`crate::quality::compare`] mirrors it.
fn correlate(st: &State, xt: &[f32], top: f32, cpp: &[f32], r: usize, avx2: bool) -> Vec<f32> {
    let (w, h, pad, pw) = (st.w, st.h, st.pad, st.pw);
    let ph = h + 2 * pad;
    let at = |i: usize| {
        if st.printed.is_empty() {
            st.lev[i] as f32 / top - xt[i]
        } else {
            st.printed[i] - xt[i]
        }
    };
    let mut e = vec![0f32; pw * ph];
    for py in 0..ph {
        let Some(sy) = mirror_source(py as isize - pad as isize, h, r) else {
            continue;
        };
        for px in 0..pw {
            if let Some(sx) = mirror_source(px as isize - pad as isize, w, r) {
                e[py * pw + px] = at((sy + pad) * pw + sx + pad);
            }
        }
    }
    let mut out = vec![0f32; pw * ph];
    out.par_chunks_mut(pw)
        .enumerate()
        .skip(pad)
        .take(h)
        .for_each_init(
            || vec![0f32; (r + 1) * (w + 2 * r)],
            |fold, (y, row)| {
                #[cfg(target_arch = "x86_64")]
                if avx2 {
                    // SAFETY: the CPU has AVX2 (checked by the caller).
                    unsafe { convolve_row_avx2(&e, row, fold, y, pw, pad, w, cpp, r) };
                    return;
                }
                let _ = avx2;
                convolve_row(&e, row, fold, y, pw, pad, w, cpp, r);
            },
        );
    out
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn convolve_row_avx2(
    e: &[f32],
    row: &mut [f32],
    fold: &mut [f32],
    y: usize,
    pw: usize,
    pad: usize,
    w: usize,
    k: &[f32],
    r: usize,
) {
    convolve_row(e, row, fold, y, pw, pad, w, k, r)
}

/// One image row of `k ⊛ e` (padded row `y`, columns `pad..pad + w`). `k` is even in both
/// axes, so the rows `y ± dy` are added first and then the columns `x ± dx`: 169 multiplies
/// a pixel for the 625 taps of radius 12.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn convolve_row(
    e: &[f32],
    row: &mut [f32],
    fold: &mut [f32],
    y: usize,
    pw: usize,
    pad: usize,
    w: usize,
    k: &[f32],
    r: usize,
) {
    let n = 2 * r + 1;
    let fw = w + 2 * r;
    let x0 = pad - r;
    for dy in 0..=r {
        let f = &mut fold[dy * fw..(dy + 1) * fw];
        let a = &e[(y + dy) * pw + x0..][..fw];
        if dy == 0 {
            f.copy_from_slice(a);
        } else {
            let b = &e[(y - dy) * pw + x0..][..fw];
            for ((o, &a), &b) in f.iter_mut().zip(a).zip(b) {
                *o = a + b;
            }
        }
    }
    let out = &mut row[pad..pad + w];
    out.fill(0.0);
    for dy in 0..=r {
        let f = &fold[dy * fw..(dy + 1) * fw];
        let kr = &k[(r + dy) * n + r..][..r + 1];
        let c = kr[0];
        for (o, &v) in out.iter_mut().zip(&f[r..r + w]) {
            *o += c * v;
        }
        for (dx, &c) in kr.iter().enumerate().skip(1) {
            let lo = &f[r - dx..r - dx + w];
            let hi = &f[r + dx..r + dx + w];
            for ((o, &a), &b) in out.iter_mut().zip(lo).zip(hi) {
                *o += c * (a + b);
            }
        }
    }
}

/// Runs DBS from the levels `start` (one byte a pixel) towards `target` (reflectance,
/// `w × h`). Returns the levels and, when `trace` is set, the objective E after each pass
/// (the first entry is E at the start, each recomputed from scratch); otherwise the number
/// of changes in each pass.
#[allow(clippy::too_many_arguments)]
pub fn search(
    target: &[f32],
    start: &[u8],
    w: usize,
    h: usize,
    levels: u16,
    cpp: &[f32],
    radius: usize,
    printer: Option<&PrinterModel>,
    passes: u32,
    trace: bool,
) -> (Vec<u8>, Vec<f64>) {
    if w == 0 || h == 0 {
        return (Vec::new(), Vec::new());
    }
    let avx2 = have_avx2();
    // Mirror copies sit up to `radius` outside the image and spread `radius` further.
    let pad = 2 * radius + 4;
    let pw = w + 2 * pad;
    let ph = h + 2 * pad;
    let top = (levels - 1) as f32;
    let mut st = State {
        w,
        h,
        pad,
        pw,
        lev: vec![-1; pw * ph],
        cep: Vec::new(),
        cfg: Vec::new(),
        printed: Vec::new(),
    };
    for y in 0..h {
        for x in 0..w {
            st.lev[(y + pad) * pw + x + pad] = start[y * w + x] as i16;
        }
    }
    // The target, padded.
    let mut xt = vec![0f32; pw * ph];
    for y in 0..h {
        xt[(y + pad) * pw + pad..(y + pad) * pw + pad + w].copy_from_slice(&target[y * w..][..w]);
    }
    if let Some(model) = printer {
        st.cfg = vec![0; pw * ph];
        st.printed = vec![0.0; pw * ph];
        for y in pad..pad + h {
            for x in pad..pad + w {
                let i = y * pw + x;
                let mut c = 0u16;
                for k in 0..9 {
                    let j = (i + (k / 3) * pw + k % 3) - pw - 1;
                    if st.lev[j] == 0 {
                        c |= 1 << k;
                    }
                }
                st.cfg[i] = c;
                st.printed[i] = model.table[c as usize];
            }
        }
    }
    st.cep = correlate(&st, &xt, top, cpp, radius, avx2);

    let bw = w.div_ceil(BLOCK);
    let bh = h.div_ceil(BLOCK);
    let mut dirty: Vec<u8> = vec![1; bw * bh];
    let next: Vec<AtomicU8> = (0..bw * bh).map(|_| AtomicU8::new(0)).collect();
    let tw = w.div_ceil(TILE);
    let th = h.div_ceil(TILE);
    let n = 2 * radius as isize + 1;
    let k8 = NEIGHBOURS
        .map(|(dx, dy)| cpp[((dy + radius as isize) * n + dx + radius as isize) as usize]);
    let mut out_trace = Vec::new();
    if trace {
        out_trace.push(objective(&st, &xt, top, cpp, radius));
    }
    for _ in 0..passes {
        let changes = AtomicUsize::new(0);
        for class in 0..4 {
            let tiles: Vec<(usize, usize)> = (0..th)
                .flat_map(|ty| (0..tw).map(move |tx| (tx, ty)))
                .filter(|&(tx, ty)| (tx % 2) + 2 * (ty % 2) == class)
                .collect();
            let shared = Shared {
                lev: st.lev.as_mut_ptr(),
                cep: st.cep.as_mut_ptr(),
                cfg: st.cfg.as_mut_ptr(),
                printed: st.printed.as_mut_ptr(),
            };
            let ctx = Ctx {
                w,
                h,
                pad,
                pw,
                step: 1.0 / top,
                top: levels as i16 - 1,
                cpp,
                k8,
                reach: if printer.is_some() {
                    radius + 5
                } else {
                    radius + 3
                },
                radius,
                dirty: &dirty,
                next: &next,
                bw,
                model: printer,
            };
            let shared = &shared;
            let ctx = &ctx;
            let n: usize = tiles
                .par_iter()
                .map(|&(tx, ty)| {
                    // SAFETY: see `Shared`; AVX2 is checked.
                    unsafe {
                        #[cfg(target_arch = "x86_64")]
                        if avx2 {
                            return ctx.tile_avx2(shared, tx * TILE, ty * TILE);
                        }
                        ctx.tile(shared, tx * TILE, ty * TILE)
                    }
                })
                .sum();
            changes.fetch_add(n, Ordering::Relaxed);
        }
        for (d, n) in dirty.iter_mut().zip(&next) {
            *d = n.swap(0, Ordering::Relaxed);
        }
        let n = changes.into_inner();
        if trace {
            out_trace.push(objective(&st, &xt, top, cpp, radius));
        } else {
            out_trace.push(n as f64);
        }
        if n == 0 {
            break;
        }
    }
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = st.lev[(y + pad) * pw + x + pad] as u8;
        }
    }
    (out, out_trace)
}

/// E = Σ e·(c_pp ⊛ ẽ) over the image, recomputed from scratch (for tests and traces): a
/// quarter of the eye-filtered error energy of the mirrored-out error over one period, the
/// quantity [`crate::quality::compare`] averages.
fn objective(st: &State, xt: &[f32], top: f32, cpp: &[f32], r: usize) -> f64 {
    let c = correlate(st, xt, top, cpp, r, false);
    let mut e = 0.0f64;
    for y in st.pad..st.pad + st.h {
        for x in st.pad..st.pad + st.w {
            let i = y * st.pw + x;
            let b = if st.printed.is_empty() {
                st.lev[i] as f32 / top
            } else {
                st.printed[i]
            };
            e += (b - xt[i]) as f64 * c[i] as f64;
        }
    }
    e
}

/// What every tile of a pass shares.
struct Ctx<'a> {
    w: usize,
    h: usize,
    pad: usize,
    pw: usize,
    step: f32,
    top: i16,
    cpp: &'a [f32],
    /// `c_pp` at the 8 [`NEIGHBOURS`].
    k8: [f32; 8],
    /// How far from a change pixels must be looked at again (module documentation).
    reach: usize,
    radius: usize,
    dirty: &'a [u8],
    next: &'a [AtomicU8],
    bw: usize,
    model: Option<&'a PrinterModel>,
}

/// Offsets of the 8 neighbours as (dx, dy).
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

impl Ctx<'_> {
    #[inline(always)]
    fn cpp_at(&self, dx: isize, dy: isize) -> f32 {
        let r = self.radius as isize;
        if dx.abs() > r || dy.abs() > r {
            return 0.0;
        }
        let n = 2 * r + 1;
        self.cpp[((dy + r) * n + dx + r) as usize]
    }

    /// Whether image pixel (x, y) or a neighbour has a mirror copy within reach.
    #[inline(always)]
    fn near_edge(&self, x: usize, y: usize) -> bool {
        let r = self.radius + 1;
        x < r || y < r || x + r >= self.w || y + r >= self.h
    }

    /// The quadratic form of the mirrored objective between image pixels (x0, y0) and
    /// (x1, y1): `c_pp` summed over the mirror copies of (x1, y1). Symmetric in the two
    /// pixels; `c_pp` itself away from the edges.
    fn kern(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> f32 {
        let (cx, nx) = axis_copies(x1, self.w, self.radius);
        let (cy, ny) = axis_copies(y1, self.h, self.radius);
        let mut s = 0.0;
        for &qy in &cy[..ny] {
            for &qx in &cx[..nx] {
                s += self.cpp_at(x0 as isize - qx, y0 as isize - qy);
            }
        }
        s
    }

    /// Marks the blocks within reach of image pixel (x, y) dirty for the next pass.
    fn mark(&self, x: usize, y: usize) {
        // c_ep changes within radius (+2 for printed neighbours) of a change, and a pixel's
        // choice reads c_ep and levels within 2 (+1 for the swap partner).
        let reach = self.reach;
        let bx0 = x.saturating_sub(reach) / BLOCK;
        let by0 = y.saturating_sub(reach) / BLOCK;
        let bx1 = (x + reach).min(self.w - 1) / BLOCK;
        let by1 = (y + reach).min(self.h - 1) / BLOCK;
        for by in by0..=by1 {
            for bx in bx0..=bx1 {
                self.next[by * self.bw + bx].store(1, Ordering::Relaxed);
            }
        }
    }

    /// Adds `a·c_pp` centred on padded index `m` to `c_ep`.
    ///
    /// # Safety
    /// The caller owns the cells within `radius` of `m` (module docs).
    #[inline(always)]
    unsafe fn spread(&self, s: &Shared, m: usize, a: f32) {
        let r = self.radius;
        let n = 2 * r + 1;
        let mut base = s.cep.add(m - r * self.pw - r);
        for k in self.cpp.chunks_exact(n) {
            let row = std::slice::from_raw_parts_mut(base, n);
            for (o, &c) in row.iter_mut().zip(k) {
                *o += a * c;
            }
            base = base.add(self.pw);
        }
    }

    /// Adds `a` at image pixel (x, y) and its mirror copies to `c_ep`.
    ///
    /// # Safety
    /// As [`Ctx::spread`].
    #[inline(always)]
    unsafe fn spread_at(&self, s: &Shared, x: usize, y: usize, a: f32) {
        let (cx, nx) = axis_copies(x, self.w, self.radius);
        let (cy, ny) = axis_copies(y, self.h, self.radius);
        let pad = self.pad as isize;
        for &qy in &cy[..ny] {
            for &qx in &cx[..nx] {
                self.spread(s, ((qy + pad) * self.pw as isize + qx + pad) as usize, a);
            }
        }
    }

    /// [`Ctx::tile`] built for AVX2.
    ///
    /// # Safety
    /// As [`Ctx::tile`], and the CPU must have AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn tile_avx2(&self, s: &Shared, x0: usize, y0: usize) -> usize {
        self.tile(s, x0, y0)
    }

    /// Processes the dirty blocks of the tile at image (x0, y0); returns the changes made.
    ///
    /// # Safety
    /// Only tiles of one class may run at the same time (module docs).
    #[inline(always)]
    unsafe fn tile(&self, s: &Shared, x0: usize, y0: usize) -> usize {
        let mut changes = 0;
        let x1 = (x0 + TILE).min(self.w);
        let y1 = (y0 + TILE).min(self.h);
        let fast = self.model.is_none() && self.top == 1;
        for by in (y0 / BLOCK)..y1.div_ceil(BLOCK) {
            for bx in (x0 / BLOCK)..x1.div_ceil(BLOCK) {
                if self.dirty[by * self.bw + bx] == 0 {
                    continue;
                }
                let xs = bx * BLOCK;
                let xe = ((bx + 1) * BLOCK).min(x1);
                for y in by * BLOCK..((by + 1) * BLOCK).min(y1) {
                    if fast
                        && xe - xs == BLOCK
                        && !self.near_edge(xs, y)
                        && !self.near_edge(xe - 1, y)
                    {
                        changes += self.row_bilevel(s, xs, y);
                        continue;
                    }
                    for x in xs..xe {
                        let changed = if self.model.is_some() {
                            self.pixel_model(s, x, y)
                        } else if fast && !self.near_edge(x, y) {
                            self.pixel_bilevel(s, x, y)
                        } else {
                            self.pixel(s, x, y)
                        };
                        if changed {
                            changes += 1;
                        }
                    }
                }
            }
        }
        changes
    }

    /// [`Ctx::pixel_bilevel`] on the 8 pixels (x..x + 8, y), all away from the edges. Most
    /// pixels keep their level, so the best change of all 8 is first found side by side
    /// (the same arithmetic as [`Ctx::pixel_bilevel`], so the same decisions); only from the
    /// first pixel that would change on are they processed one by one, since each change
    /// moves `c_ep` under the next. Returns the changes made.
    ///
    /// # Safety
    /// As [`Ctx::tile`].
    #[inline(always)]
    unsafe fn row_bilevel(&self, s: &Shared, x: usize, y: usize) -> usize {
        const N: usize = BLOCK;
        let pw = self.pw as isize;
        let m = (y + self.pad) * self.pw + x + self.pad;
        let c0 = self.cpp[self.cpp.len() / 2];
        let lv = &*(s.lev.add(m) as *const [i16; N]);
        let cm = &*(s.cep.add(m) as *const [f32; N]);
        let mut a = [0f32; N];
        let mut best = [0f32; N];
        for i in 0..N {
            a[i] = if lv[i] == 0 { 1.0 } else { -1.0 };
            best[i] = c0 + 2.0 * a[i] * cm[i];
        }
        for (j, &(dx, dy)) in NEIGHBOURS.iter().enumerate() {
            let n = (m as isize + dy * pw + dx) as usize;
            let ln = &*(s.lev.add(n) as *const [i16; N]);
            let cn = &*(s.cep.add(n) as *const [f32; N]);
            let k = c0 - self.k8[j];
            for i in 0..N {
                let de = 2.0 * (k + a[i] * (cm[i] - cn[i]));
                let de = if ln[i] == lv[i] { f32::MAX } else { de };
                best[i] = if de < best[i] { de } else { best[i] };
            }
        }
        let Some(first) = best.iter().position(|&b| b < -EPS) else {
            return 0;
        };
        let mut changes = 0;
        for xx in x + first..x + N {
            if self.pixel_bilevel(s, xx, y) {
                changes += 1;
            }
        }
        changes
    }

    /// [`Ctx::pixel`] for bilevel output away from the edges: the toggle flips the pixel
    /// (a = ±1) and a swap is worth trying only with a neighbour of the other level.
    ///
    /// # Safety
    /// As [`Ctx::tile`].
    #[inline(always)]
    unsafe fn pixel_bilevel(&self, s: &Shared, x: usize, y: usize) -> bool {
        let pw = self.pw as isize;
        let m = (y + self.pad) * self.pw + x + self.pad;
        let l = *s.lev.add(m);
        let cm = *s.cep.add(m);
        let c0 = self.cpp[self.cpp.len() / 2];
        let a = if l == 0 { 1.0f32 } else { -1.0 };
        let mut best = c0 + 2.0 * a * cm;
        let mut choice = if best < -EPS { 0 } else { usize::MAX };
        best = best.min(-EPS);
        for (j, &(dx, dy)) in NEIGHBOURS.iter().enumerate() {
            let n = (m as isize + dy * pw + dx) as usize;
            // Branch-free: about half the neighbours hold the other level, unpredictably.
            let de = 2.0 * ((c0 - self.k8[j]) + a * (cm - *s.cep.add(n)));
            let de = if *s.lev.add(n) == l { f32::MAX } else { de };
            if de < best {
                best = de;
                choice = j + 1;
            }
        }
        if choice == usize::MAX {
            return false;
        }
        *s.lev.add(m) = 1 - l;
        self.spread(s, m, a);
        if choice > 0 {
            let (dx, dy) = NEIGHBOURS[choice - 1];
            let n = (m as isize + dy * pw + dx) as usize;
            *s.lev.add(n) = l;
            self.spread(s, n, -a);
        }
        self.mark(x, y);
        true
    }

    /// Tries the toggles and swaps of image pixel (x, y); applies the best that lowers E.
    ///
    /// # Safety
    /// As [`Ctx::tile`].
    #[inline(always)]
    unsafe fn pixel(&self, s: &Shared, x: usize, y: usize) -> bool {
        let pw = self.pw as isize;
        let m = (y + self.pad) * self.pw + x + self.pad;
        let l = *s.lev.add(m);
        let cm = *s.cep.add(m);
        let kmm = self.kern(x, y, x, y);
        let step = self.step;
        let mut best = -EPS;
        // (change at m in steps, partner offset or 0)
        let mut choice: Option<(i16, isize, isize)> = None;
        for d in [-1i16, 1] {
            let nl = l + d;
            if nl < 0 || nl > self.top {
                continue;
            }
            let a = d as f32 * step;
            let de = a * (a * kmm + 2.0 * cm);
            if de < best {
                best = de;
                choice = Some((d, 0, 0));
            }
        }
        for &(dx, dy) in &NEIGHBOURS {
            let off = dy * pw + dx;
            let n = (m as isize + off) as usize;
            let ln = *s.lev.add(n);
            if ln < 0 || ln == l && self.top == 1 {
                continue;
            }
            let (nx, ny) = ((x as isize + dx) as usize, (y as isize + dy) as usize);
            let cn = *s.cep.add(n);
            let q = kmm + self.kern(nx, ny, nx, ny) - 2.0 * self.kern(x, y, nx, ny);
            for d in [-1i16, 1] {
                let (nl, nn) = (l + d, ln - d);
                if nl < 0 || nl > self.top || nn < 0 || nn > self.top {
                    continue;
                }
                let a = d as f32 * step;
                let de = a * (a * q + 2.0 * (cm - cn));
                if de < best {
                    best = de;
                    choice = Some((d, dx, dy));
                }
            }
        }
        let Some((d, dx, dy)) = choice else {
            return false;
        };
        let a = d as f32 * step;
        *s.lev.add(m) = l + d;
        self.spread_at(s, x, y, a);
        if (dx, dy) != (0, 0) {
            let n = (m as isize + dy * pw + dx) as usize;
            *s.lev.add(n) -= d;
            self.spread_at(
                s,
                (x as isize + dx) as usize,
                (y as isize + dy) as usize,
                -a,
            );
        }
        self.mark(x, y);
        true
    }

    /// Model-based version of [`Ctx::pixel`] (bilevel): the change in E counts every printed
    /// pixel the toggle or swap alters.
    ///
    /// # Safety
    /// As [`Ctx::tile`].
    unsafe fn pixel_model(&self, s: &Shared, x: usize, y: usize) -> bool {
        let Some(model) = self.model else {
            return false;
        };
        let pw = self.pw as isize;
        let m = ((y + self.pad) * self.pw + x + self.pad) as isize;
        let at = |dx: isize, dy: isize| (m + dy * pw + dx) as usize;
        let img = |dx: isize, dy: isize| ((x as isize + dx) as usize, (y as isize + dy) as usize);
        let edge = self.near_edge(x, y);
        let l = *s.lev.add(m as usize);
        let mut best = -EPS;
        // None: keep; Some((0, 0)): toggle; Some((dx, dy)): swap with that neighbour.
        let mut choice: Option<(isize, isize)> = None;
        // Printed pixels a candidate alters: (dx, dy) from m, change of printed reflectance.
        let mut deltas: [(isize, isize, f32); 15] = [(0, 0, 0.0); 15];
        for cand in 0..9usize {
            let (ox, oy) = if cand == 0 {
                (0, 0)
            } else {
                NEIGHBOURS[cand - 1]
            };
            if cand != 0 {
                let ln = *s.lev.add(at(ox, oy));
                if ln < 0 || ln == l {
                    continue;
                }
            }
            let mut count = 0;
            let mut consider = |px: isize, py: isize| {
                if deltas[..count].iter().any(|d| d.0 == px && d.1 == py) {
                    return;
                }
                let p = at(px, py);
                if *s.lev.add(p) < 0 {
                    return;
                }
                let mut c = *s.cfg.add(p) as usize;
                let flips: &[(isize, isize)] = if cand == 0 {
                    &[(0, 0)]
                } else {
                    &[(0, 0), (ox, oy)]
                };
                for &(fx, fy) in flips {
                    let (dx, dy) = (fx - px, fy - py);
                    if dx.abs() <= 1 && dy.abs() <= 1 {
                        c ^= 1 << ((dy + 1) * 3 + dx + 1);
                    }
                }
                let dp = model.table[c] - *s.printed.add(p);
                if dp != 0.0 {
                    deltas[count] = (px, py, dp);
                    count += 1;
                }
            };
            for k in 0..9isize {
                consider(k % 3 - 1, k / 3 - 1);
            }
            if cand != 0 {
                for k in 0..9isize {
                    consider(ox + k % 3 - 1, oy + k / 3 - 1);
                }
            }
            let mut de = 0.0f32;
            for &(ix, iy, di) in &deltas[..count] {
                let mut q = 2.0 * *s.cep.add(at(ix, iy));
                for &(jx, jy, dj) in &deltas[..count] {
                    let k = if edge {
                        let (a, b) = img(ix, iy);
                        let (c, d) = img(jx, jy);
                        self.kern(a, b, c, d)
                    } else {
                        self.cpp_at(jx - ix, jy - iy)
                    };
                    q += dj * k;
                }
                de += di * q;
            }
            if de < best {
                best = de;
                choice = Some((ox, oy));
            }
        }
        let Some((ox, oy)) = choice else {
            return false;
        };
        let flips: &[(isize, isize)] = if (ox, oy) == (0, 0) {
            &[(0, 0)]
        } else {
            &[(0, 0), (ox, oy)]
        };
        for &(fx, fy) in flips {
            let f = at(fx, fy);
            *s.lev.add(f) = 1 - *s.lev.add(f);
            for k in 0..9usize {
                let p = f + (k / 3) * self.pw + k % 3 - self.pw - 1;
                // The flipped pixel sits at (−dx, −dy) seen from p: bit 8 − k.
                *s.cfg.add(p) ^= 1 << (8 - k);
            }
        }
        // Recompute the printed values around the flips and spread their changes.
        let mut seen = [usize::MAX; 15];
        let mut count = 0;
        for &(fx, fy) in flips {
            for k in 0..9isize {
                let (px, py) = (fx + k % 3 - 1, fy + k / 3 - 1);
                let p = at(px, py);
                if *s.lev.add(p) < 0 || seen[..count].contains(&p) {
                    continue;
                }
                seen[count] = p;
                count += 1;
                let np = model.table[*s.cfg.add(p) as usize];
                let dp = np - *s.printed.add(p);
                if dp != 0.0 {
                    *s.printed.add(p) = np;
                    let (ix, iy) = img(px, py);
                    self.spread_at(s, ix, iy, dp);
                }
            }
        }
        self.mark(x, y);
        true
    }
}

/// Side of the flats `halftone train dbs-tone` measures.
pub const TONE_FLAT: usize = 128;

/// Measures bilevel DBS's tone response on flats (greys 0, 1/64, …, 1, no correction, the
/// default viewing) and inverts it: the input reflectance that prints each of 33 evenly
/// spaced greys. The mean is taken away from the flat's edges (8 pixels).
pub fn train_tone() -> Vec<f32> {
    let n = TONE_FLAT;
    let view = Viewing::default();
    let dbs = Dbs::new(DbsOptions {
        passes: 100,
        tone_correct: false,
        view,
        ..DbsOptions::default()
    })
    .expect("the default options are valid");
    let greys: Vec<f32> = (0..=64).map(|i| i as f32 / 64.0).collect();
    let response: Vec<f32> = greys
        .iter()
        .map(|&g| {
            let target = vec![g; n * n];
            // Start from Floyd–Steinberg, as `dbs` does.
            let codes: Vec<u16> = vec![(g * 65535.0).round() as u16; n * n];
            let tone: Vec<f32> = (0..=65535u32).map(|c| c as f32 / 65535.0).collect();
            let plane = PlaneRef {
                width: n,
                height: n,
                samples: crate::raster::SamplesRef::U16(&codes),
                tone: &tone,
            };
            let start = Diffuse::new("floyd-steinberg", DiffuseOptions::default())
                .and_then(|d| {
                    d.halftone(&Planes {
                        width: n,
                        height: n,
                        planes: vec![plane],
                    })
                })
                .map(|h| h.levels_of(0))
                .unwrap_or_else(|_| vec![0; n * n]);
            let lev = dbs.search_plane(&target, start, n, n).unwrap_or_default();
            let m = 8;
            let mut s = 0u32;
            for y in m..n - m {
                for x in m..n - m {
                    s += lev[y * n + x] as u32;
                }
            }
            s as f32 / ((n - 2 * m) * (n - 2 * m)) as f32
        })
        .collect();
    // Make the response non-decreasing, then invert it by linear interpolation.
    let mut r = response;
    for i in 1..r.len() {
        r[i] = r[i].max(r[i - 1]);
    }
    (0..=32)
        .map(|j| {
            let t = j as f32 / 32.0;
            if j == 0 || j == 32 {
                return t;
            }
            match r.iter().position(|&v| v >= t) {
                Some(0) => 0.0,
                Some(i) => {
                    let (r0, r1) = (r[i - 1], r[i]);
                    let f = if r1 > r0 { (t - r0) / (r1 - r0) } else { 0.0 };
                    ((i - 1) as f32 + f) / 64.0
                }
                None => 1.0,
            }
        })
        .map(|v| (v * 1e6).round() / 1e6)
        .collect()
}

/// The tone table as the file `kernels/dbs-tone.txt` holds it.
pub fn tone_table_text(t: &[f32]) -> String {
    let mut s = String::from(
        "# Tone correction of bilevel DBS: input reflectance that prints grey j/32, j = 0..=32.\n\
         # Made by `halftone train dbs-tone` (src/method/dbs.rs, train_tone): DBS on flats of\n\
         # 65 greys, 128x128, 300 dpi at 12 in; mean of the interior; response inverted.\n",
    );
    for chunk in t.chunks(11) {
        let line: Vec<String> = chunk.iter().map(|v| format!("{v:.6}")).collect();
        s.push_str(&line.join(" "));
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lowest value of an even table's spectrum (a cosine sum) on a 64 × 64 grid, over its
    /// value at DC.
    fn spectrum_floor(t: &[f32], radius: usize) -> f64 {
        let n = 2 * radius + 1;
        let m = 64;
        let at = |u: usize, v: usize| {
            let mut s = 0.0f64;
            for (i, &c) in t.iter().enumerate() {
                let dx = (i % n) as f64 - radius as f64;
                let dy = (i / n) as f64 - radius as f64;
                let ph = 2.0 * std::f64::consts::PI * (u as f64 * dx + v as f64 * dy) / m as f64;
                s += c as f64 * fm::cos(ph);
            }
            s
        };
        let dc = at(0, 0);
        let mut lo = f64::INFINITY;
        for v in 0..=m / 2 {
            for u in 0..=m / 2 {
                lo = lo.min(at(u, v));
            }
        }
        lo / dc
    }

    #[test]
    fn tapered_cpp_is_symmetric_and_nearly_positive_definite() {
        let view = Viewing::default();
        let t = cpp_table(&view, RADIUS);
        let n = 2 * RADIUS + 1;
        for y in 0..n {
            for x in 0..n {
                assert_eq!(t[y * n + x], t[x * n + y]);
                assert_eq!(t[y * n + x], t[y * n + n - 1 - x]);
            }
        }
        // The default dips below zero by less than 0.1% of DC; σ = r/3 not at all; a hard cut
        // at r = 6 by 3% (the stripes it drew).
        let floor = spectrum_floor(&t, RADIUS);
        assert!(floor > -1e-3, "{floor}");
        let third = spectrum_floor(&cpp_tapered(&view, RADIUS, RADIUS as f64 / 3.0), RADIUS);
        assert!(third > 0.0, "{third}");
        let hard = spectrum_floor(&cpp_tapered(&view, 6, f64::INFINITY), 6);
        assert!(hard < -0.02, "{hard}");
    }

    #[test]
    fn tone_table_interpolates() {
        let t = [0.0, 0.6, 1.0];
        assert_eq!(apply_tone_table(&t, 0.0), 0.0);
        assert!((apply_tone_table(&t, 0.25) - 0.3).abs() < 1e-6);
        assert!((apply_tone_table(&t, 1.0) - 1.0).abs() < 1e-6);
        let shipped = parse_tone_table(DBS_TONE_TEXT);
        assert_eq!(shipped.len(), 33);
        assert!(shipped.windows(2).all(|w| w[1] >= w[0]));
    }
}
