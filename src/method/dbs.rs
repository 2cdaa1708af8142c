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
//! # Printed output (model-based DBS)
//! With a [`PrinterModel`], `b` is replaced by the printed reflectance `P(b)` of every pixel,
//! which depends on its 3×3 neighbourhood: a toggle changes up to 9 printed pixels and a swap
//! up to 15, and the change in E is `Σ_i δ_i (2 c_ep[i] + Σ_j δ_j c_pp[i−j])` over them.
//!
//! # Threads and determinism
//! The image is cut into square tiles in four classes by the parity of their column and row.
//! A pass updates the four classes one after the other; the tiles of one class run in
//! parallel. A tile writes levels within 1 pixel of itself (a swap's partner) and `c_ep` within
//! `radius + 3`; tiles of one class are a whole tile apart, wider than twice that reach, so they
//! never touch each other's data and each tile sees the same data whatever the thread count:
//! the output is the same bytes for 1 or 2 threads.
//!
//! # Skipping settled pixels
//! A pixel's best change depends only on `c_ep` and the levels within one pixel of it; these
//! change only when something within `radius + 1` (+2 with a printer model) changes. The image
//! is kept as 8×8 blocks with a dirty flag; a pass visits only blocks that were dirty after the
//! previous one.
//!
//! # Tone
//! DBS with a truncated `c_pp` is known to bias tone (too few dots in highlights and shadows).
//! Lieberman and Allebach correct the input: [`DBS_TONE`] holds the input that makes DBS
//! print each grey of a ramp of flats, measured by `halftone train dbs-tone`.

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

/// Default radius of `c_pp` (25 × 25 taps; see [`cpp_table`] and docs/accuracy.md).
pub const RADIUS: usize = 12;
/// Radius for model-based DBS, whose every trial touches up to 15 printed pixels.
pub const MODEL_RADIUS: usize = 8;

/// Tone correction of bilevel DBS: the input reflectance that makes DBS print each of these
/// evenly spaced greys (0, 1/32, …, 1), made by `halftone train dbs-tone` (see
/// `kernels/dbs-tone.txt`).
pub const DBS_TONE_TEXT: &str = include_str!("../../kernels/dbs-tone.txt");

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
                "a printer model works with bilevel output only (--levels 2)".into(),
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
    let f0 = (NASANEN_C * NASANEN_L.ln() + NASANEN_D) / view.pixels_per_degree();
    let s2 = 2.0 / (2.0 * std::f64::consts::PI * f0);
    let n = 2 * radius + 1;
    let mut t = vec![0f32; n * n];
    for (i, v) in t.iter_mut().enumerate() {
        let dx = (i % n) as f64 - radius as f64;
        let dy = (i / n) as f64 - radius as f64;
        let r2 = dx * dx + dy * dy;
        let window = (-r2 / (2.0 * sigma * sigma)).exp();
        *v = (window * s2 / (2.0 * std::f64::consts::PI * (s2 * s2 + r2).powf(1.5))) as f32;
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
        let cpp = cpp_table(&self.options.view, self.options.radius);
        // Planes run one after the other; each uses every thread.
        let mut out = Halftone::new(input.width, input.height, input.planes.len(), levels);
        for (c, plane) in input.planes.iter().enumerate() {
            let target = self.target(plane);
            let start = fs.levels_of(c);
            let (result, _) = search(
                &target,
                &start,
                plane.width,
                plane.height,
                levels,
                &cpp,
                self.options.radius,
                self.options.printer.as_ref(),
                self.options.passes,
                false,
            );
            let (bits, stride) = (out.bits, out.stride);
            for (y, row) in out.planes[c].chunks_exact_mut(stride).enumerate() {
                pack_row(&result[y * plane.width..(y + 1) * plane.width], bits, row);
            }
        }
        Ok(out)
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
    /// `c_pp ⊛ e`.
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

/// Runs DBS from the levels `start` (one byte a pixel) towards `target` (reflectance,
/// `w × h`). Returns the levels and, when `trace` is set, the objective E after each pass
/// (the first entry is E at the start); otherwise the number of changes in each pass.
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
    let pad = radius + 4;
    let pw = w + 2 * pad;
    let ph = h + 2 * pad;
    let top = (levels - 1) as f32;
    let mut st = State {
        w,
        h,
        pad,
        pw,
        lev: vec![-1; pw * ph],
        cep: vec![0.0; pw * ph],
        cfg: Vec::new(),
        printed: Vec::new(),
    };
    for y in 0..h {
        for x in 0..w {
            st.lev[(y + pad) * pw + x + pad] = start[y * w + x] as i16;
        }
    }
    // The target, padded (zero error outside).
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
    // The error, then c_ep = c_pp ⊛ e, row by row in parallel.
    let err: Vec<f32> = (0..pw * ph)
        .map(|i| {
            if st.lev[i] < 0 {
                0.0
            } else if printer.is_some() {
                st.printed[i] - xt[i]
            } else {
                st.lev[i] as f32 / top - xt[i]
            }
        })
        .collect();
    convolve(&err, &mut st.cep, pw, ph, pad, cpp, radius);
    drop(err);

    let bw = w.div_ceil(BLOCK);
    let bh = h.div_ceil(BLOCK);
    let mut dirty: Vec<u8> = vec![1; bw * bh];
    let next: Vec<AtomicU8> = (0..bw * bh).map(|_| AtomicU8::new(0)).collect();
    let tw = w.div_ceil(TILE);
    let th = h.div_ceil(TILE);
    let mut out_trace = Vec::new();
    if trace {
        out_trace.push(objective(&st, &xt, top, printer));
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
                    // SAFETY: see `Shared`.
                    unsafe { ctx.tile(shared, tx * TILE, ty * TILE) }
                })
                .sum();
            changes.fetch_add(n, Ordering::Relaxed);
        }
        for (d, n) in dirty.iter_mut().zip(&next) {
            *d = n.swap(0, Ordering::Relaxed);
        }
        let n = changes.into_inner();
        if trace {
            out_trace.push(objective(&st, &xt, top, printer));
        } else {
            out_trace.push(n as f64);
        }
        if n == 0 {
            break;
        }
    }
    let _ = (st.w, st.h);
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = st.lev[(y + pad) * pw + x + pad] as u8;
        }
    }
    (out, out_trace)
}

/// `out = k ⊛ e` over the padded plane (rows within 2 of the image only: no other row is
/// read), in parallel by rows.
fn convolve(e: &[f32], out: &mut [f32], pw: usize, ph: usize, pad: usize, k: &[f32], r: usize) {
    let n = 2 * r + 1;
    out.par_chunks_mut(pw).enumerate().for_each(|(y, row)| {
        if y + 2 < pad || y >= ph - pad + 2 {
            return;
        }
        for dy in 0..n {
            let sy = y + dy - r;
            let src = &e[sy * pw..(sy + 1) * pw];
            for dx in 0..n {
                let c = k[dy * n + dx];
                // row[x] += c·e[x + dx − r] for x in r..pw−r.
                let dst = &mut row[r..pw - r];
                let s = &src[dx..dx + pw - 2 * r];
                for (o, &v) in dst.iter_mut().zip(s) {
                    *o += c * v;
                }
            }
        }
    });
}

/// E = Σ e·c_ep over the image, recomputed from scratch (for tests and traces).
fn objective(st: &State, xt: &[f32], top: f32, printer: Option<&PrinterModel>) -> f64 {
    let _ = printer;
    let mut e = 0.0f64;
    for y in st.pad..st.pad + st.h {
        for x in st.pad..st.pad + st.w {
            let i = y * st.pw + x;
            let b = if st.printed.is_empty() {
                st.lev[i] as f32 / top
            } else {
                st.printed[i]
            };
            e += (b - xt[i]) as f64 * st.cep[i] as f64;
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

    /// Marks the blocks within reach of image pixel (x, y) dirty for the next pass.
    fn mark(&self, x: usize, y: usize) {
        // c_ep changes within radius (+2 for printed neighbours) of a change, and a pixel's
        // choice reads c_ep and levels within 2 (+1 for the swap partner).
        let reach = self.radius + 5;
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
        for dy in 0..n {
            let base = s.cep.add(m + dy * self.pw - r * self.pw - r);
            let k = &self.cpp[dy * n..dy * n + n];
            for (dx, &c) in k.iter().enumerate() {
                *base.add(dx) += a * c;
            }
        }
    }

    /// Processes the dirty blocks of the tile at image (x0, y0); returns the changes made.
    ///
    /// # Safety
    /// Only tiles of one class may run at the same time (module docs).
    unsafe fn tile(&self, s: &Shared, x0: usize, y0: usize) -> usize {
        let mut changes = 0;
        let x1 = (x0 + TILE).min(self.w);
        let y1 = (y0 + TILE).min(self.h);
        for by in (y0 / BLOCK)..y1.div_ceil(BLOCK) {
            for bx in (x0 / BLOCK)..x1.div_ceil(BLOCK) {
                if self.dirty[by * self.bw + bx] == 0 {
                    continue;
                }
                for y in by * BLOCK..((by + 1) * BLOCK).min(y1) {
                    for x in bx * BLOCK..((bx + 1) * BLOCK).min(x1) {
                        let changed = if self.model.is_some() {
                            self.pixel_model(s, x, y)
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
        let c0 = self.cpp_at(0, 0);
        let step = self.step;
        let mut best = -EPS;
        // (change at m in steps, partner offset or 0)
        let mut choice: Option<(i16, isize)> = None;
        for d in [-1i16, 1] {
            let nl = l + d;
            if nl < 0 || nl > self.top {
                continue;
            }
            let a = d as f32 * step;
            let de = a * (a * c0 + 2.0 * cm);
            if de < best {
                best = de;
                choice = Some((d, 0));
            }
        }
        for &(dx, dy) in &NEIGHBOURS {
            let off = dy * pw + dx;
            let n = (m as isize + off) as usize;
            let ln = *s.lev.add(n);
            if ln < 0 || ln == l && self.top == 1 {
                continue;
            }
            let cn = *s.cep.add(n);
            let k = self.cpp_at(dx, dy);
            for d in [-1i16, 1] {
                let (nl, nn) = (l + d, ln - d);
                if nl < 0 || nl > self.top || nn < 0 || nn > self.top {
                    continue;
                }
                let a = d as f32 * step;
                let de = 2.0 * a * (a * (c0 - k) + (cm - cn));
                if de < best {
                    best = de;
                    choice = Some((d, off));
                }
            }
        }
        let Some((d, off)) = choice else {
            return false;
        };
        let a = d as f32 * step;
        *s.lev.add(m) = l + d;
        self.spread(s, m, a);
        self.mark(x, y);
        if off != 0 {
            let n = (m as isize + off) as usize;
            *s.lev.add(n) -= d;
            self.spread(s, n, -a);
        }
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
                    q += dj * self.cpp_at(jx - ix, jy - iy);
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
                let p = at(fx + k % 3 - 1, fy + k / 3 - 1);
                if *s.lev.add(p) < 0 || seen[..count].contains(&p) {
                    continue;
                }
                seen[count] = p;
                count += 1;
                let np = model.table[*s.cfg.add(p) as usize];
                let dp = np - *s.printed.add(p);
                if dp != 0.0 {
                    *s.printed.add(p) = np;
                    self.spread(s, p, dp);
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
    let radius = DbsOptions::default().radius;
    let cpp = cpp_table(&view, radius);
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
            let (lev, _) = search(&target, &start, n, n, 2, &cpp, radius, None, 100, false);
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
                s += c as f64 * ph.cos();
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
