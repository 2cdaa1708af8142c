//! Error diffusion (method `diffuse`), in linear light: each pixel is quantised to the nearest
//! output level and its error (value − level reflectance) is passed on to the pixels not yet
//! done, with the weights of a kernel.
//!
//! - Fixed kernels ([`kernels`]): Floyd–Steinberg and its relatives, or a user kernel file.
//! - Variable coefficients ([`variable`]): Ostromoukhov (2001) and Zhou–Fang (2003).
//! - Riemersma ([`riemersma`]): error carried along a Hilbert curve.
//! - Palettes ([`crate::color`]): nearest colour in Oklab, error carried in linear RGB.
//!
//! # State and accuracy
//!
//! The image is never copied to floats: each row's codes go through the tone table as they are
//! used, and the error lives in `f32` rows, one for the current row and one per row the kernel
//! reaches below (a ring, reused row after row).
//!
//! Grey levels need no clamp: with non-negative weights that sum to at most 1 and inputs in
//! 0..=1, every value seen by the quantiser stays within half a level step of 0..=1, so the error
//! stays within half a step; nothing can run away. Palette colours can lie inside the colour
//! cube, leaving colours they cannot reach; there each channel of the value (input + error) is
//! clamped to −1..=2 before it is quantised, which bounds the error that can pile up
//! ("bleeding"). Colours inside the palette's hull never reach the clamp (with black and
//! white, Oklab's nearest puts the decision at linear 0.125, so values stay within
//! −0.875..=1.125). The nearest colour is chosen for the unclamped-to-0..1 value: clamping
//! it there would hide a channel's debt from the quantiser and let it grow without bound.
//!
//! # Threads
//!
//! Colour planes run in parallel. A single plane scanned in raster order (no serpentine) runs
//! as a wavefront: rows are dealt round-robin to the threads and row `y` stays behind row
//! `y − 1` by the kernel's reach, so every pixel sees exactly the error it would see in one
//! thread: the bytes are the same for any thread count. Serpentine rows cannot overlap (row
//! `y + 1` starts where row `y` ends), so serpentine scans run on one thread per plane.

mod fixed;
mod fs;
pub mod hysteresis;
pub mod kernels;
pub(crate) mod palette;
pub mod riemersma;
mod stream;
pub mod tded;
pub mod variable;

use std::cell::Cell;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::LazyLock;

pub use kernels::{Kernel, Tap};

use super::{each_plane, Method, PlaneOut};

use crate::color::Palette;
use crate::error::{Error, Result};
use crate::raster::{pack_row, Halftone, Planes, SamplesRef};

/// The kernels that are not fixed weights, each built by a type of its own; `tded`
/// (trained tone-dependent diffusion, built by `tded::Tded`) last.
const VARIABLE: [&str; 4] = ["ostromoukhov", "zhou-fang", "riemersma", "tded"];

/// Every name `--kernel` accepts besides a file path: the fixed-weight kernels of
/// [`kernels::BUILTIN`] (one entry there adds one here), then the variable ones, `tded` last.
pub static NAMES: LazyLock<Vec<&'static str>> = LazyLock::new(|| {
    kernels::BUILTIN
        .iter()
        .map(|k| k.0)
        .chain(VARIABLE)
        .collect()
});

/// The names [`Diffuse::new`] builds: every one of [`NAMES`] but the trained `tded` (the
/// last), which `tded::Tded` builds.
pub static KERNELS: LazyLock<&'static [&'static str]> = LazyLock::new(|| &NAMES[..NAMES.len() - 1]);

/// How the error is spread.
#[derive(Clone, Debug, PartialEq)]
pub enum Algorithm {
    /// A fixed kernel (built-in or from a file).
    Kernel(Kernel),
    /// Ostromoukhov's variable coefficients (SIGGRAPH 2001).
    Ostromoukhov,
    /// Zhou and Fang's coefficients with threshold modulation (SIGGRAPH 2003).
    ZhouFang,
    /// Riemersma's error diffusion along a Hilbert curve.
    Riemersma,
}

impl Algorithm {
    /// The algorithm for a `--kernel` value: one of [`NAMES`], else a kernel file.
    pub fn load(name_or_path: &str) -> Result<Algorithm> {
        Ok(match name_or_path {
            "ostromoukhov" => Algorithm::Ostromoukhov,
            "zhou-fang" => Algorithm::ZhouFang,
            "riemersma" => Algorithm::Riemersma,
            "tded" => {
                return Err(crate::error::Error::Invalid(
                    "tded: trained tone-dependent diffusion is not a fixed kernel; build it with method::diffusion::tded::Tded".into(),
                ))
            }
            other => {
                if Kernel::builtin(other).is_none() {
                    crate::names::check_file_or_builtin("kernel", other, &NAMES)?;
                }
                Algorithm::Kernel(Kernel::load(other)?)
            }
        })
    }

    /// The name as given on the command line (or the kernel file).
    pub fn name(&self) -> String {
        match self {
            Algorithm::Kernel(k) => k.name.clone(),
            Algorithm::Ostromoukhov => "ostromoukhov".into(),
            Algorithm::ZhouFang => "zhou-fang".into(),
            Algorithm::Riemersma => "riemersma".into(),
        }
    }
}

/// Options of error diffusion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseOptions {
    /// Output levels per channel, 2..=256, evenly spaced in reflectance (ignored with a
    /// palette, whose size is the level count).
    pub levels: u16,
    /// Alternate the scan direction every row (`--serpentine`, the default).
    pub serpentine: bool,
    /// Share of the error passed on, 0..=1 (`--strength`).
    pub strength: f32,
    /// Seed of the noise of methods that draw noise (Zhou–Fang's threshold modulation).
    pub seed: u64,
}

impl Default for DiffuseOptions {
    fn default() -> Self {
        DiffuseOptions {
            levels: 2,
            serpentine: true,
            strength: 1.0,
            seed: 0,
        }
    }
}

/// The `diffuse` method.
#[derive(Clone, Debug)]
pub struct Diffuse {
    /// How the error is spread.
    pub algorithm: Algorithm,
    /// Levels, scan, strength, seed.
    pub options: DiffuseOptions,
    /// Output colours; when set the output is one plane of indices into it.
    pub palette: Option<Palette>,
}

impl Diffuse {
    /// Error diffusion with a `--kernel` value (one of [`NAMES`] or a kernel file).
    pub fn new(kernel: &str, options: DiffuseOptions) -> Result<Diffuse> {
        Diffuse::with_algorithm(Algorithm::load(kernel)?, options)
    }

    /// Error diffusion with an algorithm already chosen; checks the options.
    pub fn with_algorithm(algorithm: Algorithm, options: DiffuseOptions) -> Result<Diffuse> {
        crate::method::threshold::check_levels(options.levels)?;
        if !(0.0..=1.0).contains(&options.strength) {
            return Err(Error::Option {
                field: "strength",
                value: options.strength.to_string(),
                msg: "must be between 0 and 1".into(),
            });
        }
        Ok(Diffuse {
            algorithm,
            options,
            palette: None,
        })
    }

    /// Quantises to the colours of `palette` instead of levels per channel. The input should
    /// be three planes (`ColorMode::Rgb`); a single grey plane is taken as grey colours.
    pub fn with_palette(mut self, palette: Palette) -> Diffuse {
        self.palette = Some(palette);
        self
    }
}

impl Method for Diffuse {
    fn name(&self) -> String {
        let mut s = format!("diffuse({}", self.algorithm.name());
        if let Some(p) = &self.palette {
            s.push_str(&format!(", palette {}", p.name));
        } else if self.options.levels != 2 {
            s.push_str(&format!(", levels {}", self.options.levels));
        }
        if !self.options.serpentine {
            s.push_str(", raster");
        }
        if self.options.strength != 1.0 {
            s.push_str(&format!(", strength {}", self.options.strength));
        }
        s.push(')');
        s
    }

    fn rows(&self) -> Option<Box<dyn crate::method::rows::RowMethod + '_>> {
        // Riemersma's curve needs the whole image.
        if self.algorithm == Algorithm::Riemersma {
            return None;
        }
        match &self.palette {
            Some(p) => palette::PaletteRows::new(self, p)
                .ok()
                .map(|r| Box::new(r) as _),
            None => Some(Box::new(stream::DiffuseRows::new(self))),
        }
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        if let Some(palette) = &self.palette {
            return palette::PaletteRun::new(self, palette, true, true)?.band(input);
        }
        let levels = self.options.levels;
        if self.algorithm == Algorithm::Riemersma {
            return Ok(each_plane(
                input,
                input.width,
                input.height,
                levels,
                |_, plane, out| riemersma::plane(plane, levels, self.options.strength, out),
            ));
        }
        let threads = rayon::current_num_threads();
        let per_plane = (threads / input.planes.len().max(1)).max(1);
        Ok(each_plane(
            input,
            input.width,
            input.height,
            levels,
            |_, plane, out| {
                let engine = Engine::new(self, plane.tone, levels);
                let t = per_plane.min(plane.height).min(16);
                if let Some(tone) = engine.fixed.as_ref().and_then(|f| f.floyd_steinberg_tone()) {
                    let serpentine = self.options.serpentine;
                    match plane.samples {
                        SamplesRef::U8(s) => fs::plane(tone, s, plane.width, out, serpentine),
                        SamplesRef::U16(s) => fs::plane(tone, s, plane.width, out, serpentine),
                    }
                } else if t > 1 && !self.options.serpentine && engine.wavefront_safe() {
                    match plane.samples {
                        SamplesRef::U8(s) => engine.wavefront(s, plane.width, out, t),
                        SamplesRef::U16(s) => engine.wavefront(s, plane.width, out, t),
                    }
                } else {
                    match plane.samples {
                        SamplesRef::U8(s) => engine.sequential(s, plane.width, out),
                        SamplesRef::U16(s) => engine.sequential(s, plane.width, out),
                    }
                }
            },
        ))
    }
}

/// Columns of padding either side of every error row, so taps need no bounds checks.
const PAD: usize = kernels::MAX_REACH;
/// Error rows handed to the row loop (the current row and up to three below).
const ROWS: usize = kernels::MAX_ROWS_BELOW + 1;
/// Pixels a wavefront row processes between two progress reports.
const CHUNK: usize = 256;

/// One cell of an error row: a plain `Cell` on one thread, a relaxed atomic in a wavefront
/// (where the progress counters order the accesses; relaxed loads and stores compile to plain
/// moves).
trait ErrCell {
    fn get(&self) -> f32;
    fn set(&self, v: f32);
    /// The cell's 32 bits as they are (the fixed-point path keeps an `i32` there).
    fn get_raw(&self) -> u32;
    /// Stores 32 raw bits.
    fn set_raw(&self, v: u32);
    #[inline(always)]
    fn add(&self, v: f32) {
        self.set(self.get() + v);
    }
}

impl ErrCell for Cell<f32> {
    #[inline(always)]
    fn get(&self) -> f32 {
        Cell::get(self)
    }
    #[inline(always)]
    fn set(&self, v: f32) {
        Cell::set(self, v)
    }
    #[inline(always)]
    fn get_raw(&self) -> u32 {
        Cell::get(self).to_bits()
    }
    #[inline(always)]
    fn set_raw(&self, v: u32) {
        Cell::set(self, f32::from_bits(v))
    }
}

impl ErrCell for AtomicU32 {
    #[inline(always)]
    fn get(&self) -> f32 {
        f32::from_bits(self.load(Ordering::Relaxed))
    }
    #[inline(always)]
    fn set(&self, v: f32) {
        self.store(v.to_bits(), Ordering::Relaxed)
    }
    #[inline(always)]
    fn get_raw(&self) -> u32 {
        self.load(Ordering::Relaxed)
    }
    #[inline(always)]
    fn set_raw(&self, v: u32) {
        self.store(v, Ordering::Relaxed)
    }
}

/// A code type of an input plane.
trait Code: Copy + Into<usize> + Sync {
    /// How many codes there are (the length of a tone table).
    const COUNT: usize;
}
impl Code for u8 {
    const COUNT: usize = 1 << 8;
}
impl Code for u16 {
    const COUNT: usize = 1 << 16;
}

/// How the weights are chosen.
enum Weights {
    /// Same weights everywhere. `right` is the tap one pixel ahead (kept in a register, it is
    /// the loop's critical path); `taps` are the others as (dx, row, weight).
    Fixed {
        right: f32,
        taps: Vec<(isize, usize, f32)>,
    },
    /// Three taps (right, down-left, down) by input level; `level_of_code` maps each code to
    /// the row of `table`; `modulation` is Zhou–Fang's threshold-modulation strength by row.
    Variable {
        table: Vec<[f32; 3]>,
        level_of_code: Vec<u8>,
        modulation: Option<Vec<f32>>,
    },
}

/// Window weights of a fixed kernel whose reach is at most [`WINDOW_REACH`]: the pending error
/// of the pixels ahead and of the rows below is kept in registers and each cell of a row below
/// is written once, when it can receive nothing more from this row.
struct WindowWeights {
    /// Weights of the pixels 1..=reach ahead in the current row.
    ahead: [f32; WINDOW_REACH],
    /// Weights of rows 1..=3 below, at dx = j − reach.
    below: [[f32; 2 * WINDOW_REACH + 1]; kernels::MAX_ROWS_BELOW],
}

/// Largest kernel reach served by the register window (every built-in kernel).
const WINDOW_REACH: usize = 3;

/// Error a row carries from one chunk of pixels to the next: for the pixels ahead in this
/// row, and (window path) pending sums for the rows below.
#[derive(Clone, Copy, Default)]
struct RowState {
    ahead: [f32; WINDOW_REACH],
    below: [[f32; 2 * WINDOW_REACH + 1]; kernels::MAX_ROWS_BELOW],
    /// Fixed-point path: error for the next pixel and the two pending sums below.
    fixed: [i32; 3],
}

/// Adds the error `e` with weights `w` to a row's window of pending sums (dx = −R..=R) and
/// slides it one pixel on, returning the sum that is complete (dx = −R).
#[inline(always)]
fn slide<const R: usize>(
    acc: &mut [f32; 2 * WINDOW_REACH + 1],
    w: &[f32; 2 * WINDOW_REACH + 1],
    e: f32,
) -> f32 {
    let done = acc[0] + w[0] * e;
    *acc = std::array::from_fn(|j| {
        if j < 2 * R {
            acc[j + 1] + w[j + 1] * e
        } else {
            0.0
        }
    });
    done
}

/// Everything a plane's rows need, built once per plane.
struct Engine<'t> {
    tone: &'t [f32],
    top: f32,
    top_i: i32,
    inv_top: f32,
    weights: Weights,
    window: Option<WindowWeights>,
    /// Fixed-point fast path (bilevel, full strength, small kernels), used before `window`.
    fixed: Option<fixed::FixedKernel>,
    reach: usize,
    below: usize,
    serpentine: bool,
    seed: u64,
}

/// Uniform noise in 0..0.5 from the seed and the pixel position (splitmix64), so that noise
/// does not depend on the scan order or the threads.
#[inline(always)]
fn noise(seed: u64, x: usize, y: usize) -> f32 {
    let mut z = seed ^ ((y as u64) << 32 | x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 * (1.0 / (1u64 << 25) as f32)
}

impl<'t> Engine<'t> {
    fn new(d: &Diffuse, tone: &'t [f32], levels: u16) -> Engine<'t> {
        let top = (levels - 1) as f32;
        let strength = d.options.strength;
        let variable = |table: Vec<[f32; 3]>, modulation: Option<Vec<f32>>| {
            // The tables are indexed by the input level: in multi-level output, by where the
            // input lies between its two neighbouring output levels.
            let level_of_code = tone
                .iter()
                .map(|&v| {
                    let f = v * top;
                    let frac = if levels == 2 { v } else { f - f.floor() };
                    (frac.clamp(0.0, 1.0) * 255.0).round() as u8
                })
                .collect();
            Weights::Variable {
                table: table.iter().map(|w| w.map(|v| v * strength)).collect(),
                level_of_code,
                modulation,
            }
        };
        let (weights, reach, below) = match &d.algorithm {
            Algorithm::Kernel(k) => {
                let div = k.divisor as f32;
                let mut right = 0.0;
                let mut taps = Vec::new();
                for t in &k.taps {
                    let w = t.weight as f32 / div * strength;
                    if t.dx == 1 && t.dy == 0 {
                        right = w;
                    } else {
                        taps.push((t.dx as isize, t.dy as usize, w));
                    }
                }
                (Weights::Fixed { right, taps }, k.reach(), k.rows_below())
            }
            Algorithm::Ostromoukhov => (
                variable(
                    (0..=255).map(variable::ostromoukhov_weights).collect(),
                    None,
                ),
                1,
                1,
            ),
            Algorithm::ZhouFang => (
                variable(
                    (0..=255).map(variable::zhou_fang_weights).collect(),
                    Some((0..=255).map(variable::zhou_fang_strength).collect()),
                ),
                1,
                1,
            ),
            Algorithm::Riemersma => unreachable!("Riemersma has its own path"),
        };
        let window = match &weights {
            Weights::Fixed { .. } if reach <= WINDOW_REACH => {
                let Algorithm::Kernel(k) = &d.algorithm else {
                    unreachable!()
                };
                let r = reach.max(1);
                let mut ww = WindowWeights {
                    ahead: [0.0; WINDOW_REACH],
                    below: [[0.0; 2 * WINDOW_REACH + 1]; kernels::MAX_ROWS_BELOW],
                };
                for t in &k.taps {
                    let wt = t.weight as f32 / k.divisor as f32 * strength;
                    if t.dy == 0 {
                        ww.ahead[t.dx as usize - 1] = wt;
                    } else {
                        ww.below[t.dy as usize - 1][(t.dx + r as i32) as usize] = wt;
                    }
                }
                Some(ww)
            }
            _ => None,
        };
        let fixed = match &d.algorithm {
            Algorithm::Kernel(k) if levels == 2 && strength == 1.0 => {
                fixed::FixedKernel::new(k, tone)
            }
            _ => None,
        };
        Engine {
            tone,
            top,
            top_i: (levels - 1) as i32,
            inv_top: 1.0 / top,
            weights,
            window,
            fixed,
            reach,
            below,
            serpentine: d.options.serpentine,
            seed: d.options.seed,
        }
    }

    /// Level index of value `v` with threshold `t` (fraction of a step): the level below `v`,
    /// plus one when `v` is at least `t` of the way to the next.
    #[inline(always)]
    fn quantise<const BILEVEL: bool>(&self, v: f32, t: f32) -> i32 {
        if BILEVEL {
            (v >= t) as i32
        } else {
            // Truncation equals floor here: negative values clamp to level 0 anyway.
            (((v * self.top) + (1.0 - t)).max(0.0) as i32).min(self.top_i)
        }
    }

    /// Processes pixels `from..to` of row `y` in scan order (`dir` 1: left to right, −1:
    /// right to left), writing levels into `out` (indexed by x). `state` holds the error bound
    /// for the next pixel in scan order.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn run<C: ErrCell, S: Code, const BILEVEL: bool>(
        &self,
        codes: &[S],
        rows: &[&[C]; ROWS],
        out: &mut [u8],
        y: usize,
        from: usize,
        to: usize,
        dir: isize,
        state: &mut RowState,
    ) {
        let w = codes.len();
        let tone = self.tone;
        let inv_top = if BILEVEL { 1.0 } else { self.inv_top };
        let mut c = state.ahead[0];
        match &self.weights {
            Weights::Fixed { right, taps } => {
                for i in from..to {
                    let x = if dir > 0 { i } else { w - 1 - i };
                    let cell = &rows[0][PAD + x];
                    let v = tone[codes[x].into()] + cell.get() + c;
                    cell.set(0.0);
                    let q = self.quantise::<BILEVEL>(v, 0.5);
                    out[x] = q as u8;
                    let e = v - q as f32 * inv_top;
                    c = e * right;
                    let base = (PAD + x) as isize;
                    for &(dx, dy, wt) in taps {
                        rows[dy][(base + dir * dx) as usize].add(wt * e);
                    }
                }
            }
            Weights::Variable {
                table,
                level_of_code,
                modulation,
            } => {
                for i in from..to {
                    let x = if dir > 0 { i } else { w - 1 - i };
                    let code: usize = codes[x].into();
                    let level = level_of_code[code] as usize;
                    let cell = &rows[0][PAD + x];
                    let v = tone[code] + cell.get() + c;
                    cell.set(0.0);
                    let t = match modulation {
                        // Zhou–Fang: threshold 128 + rand(0..128) × strength on a 0..255 scale.
                        Some(m) => 0.5 + noise(self.seed, x, y) * m[level],
                        None => 0.5,
                    };
                    let q = self.quantise::<BILEVEL>(v, t);
                    out[x] = q as u8;
                    let e = v - q as f32 * inv_top;
                    let [r, dl, d] = table[level];
                    c = e * r;
                    let base = (PAD + x) as isize;
                    rows[1][(base - dir) as usize].add(e * dl);
                    rows[1][base as usize].add(e * d);
                }
            }
        }
        state.ahead[0] = c;
    }

    /// The register-window loop for fixed kernels of reach `R` (1..=3) and `N` rows below
    /// (1..=3). The current row is only read (and cleared) in memory: its pending error stays
    /// in `state`, so rows above may keep writing ahead of us. A cell of a row below is added
    /// to once per pixel, `R` pixels behind, when this row can add nothing more to it; that is
    /// also what keeps a wavefront's rows from touching the same cells at the same time. The
    /// rest is flushed when the row ends (`to == w`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn run_window<C: ErrCell, S: Code, const BILEVEL: bool, const R: usize, const N: usize>(
        &self,
        ww: &WindowWeights,
        codes: &[S],
        rows: &[&[C]; ROWS],
        out: &mut [u8],
        from: usize,
        to: usize,
        dir: isize,
        state: &mut RowState,
    ) {
        let w = codes.len();
        let tone = self.tone;
        let inv_top = if BILEVEL { 1.0 } else { self.inv_top };
        let cur = rows[0];
        let mut ahead = state.ahead;
        let [mut acc0, mut acc1, mut acc2] = state.below;
        for i in from..to {
            let x = if dir > 0 { i } else { w - 1 - i };
            let cell = &cur[PAD + x];
            let v = tone[codes[x].into()] + cell.get() + ahead[0];
            cell.set(0.0);
            let q = self.quantise::<BILEVEL>(v, 0.5);
            out[x] = q as u8;
            let e = v - q as f32 * inv_top;
            ahead = std::array::from_fn(|k| {
                let next = if k + 1 < R { ahead[k + 1] } else { 0.0 };
                if k < R {
                    next + ww.ahead[k] * e
                } else {
                    0.0
                }
            });
            let done = (PAD as isize + x as isize - dir * R as isize) as usize;
            rows[1][done].add(slide::<R>(&mut acc0, &ww.below[0], e));
            if N > 1 {
                rows[2][done].add(slide::<R>(&mut acc1, &ww.below[1], e));
            }
            if N > 2 {
                rows[3][done].add(slide::<R>(&mut acc2, &ww.below[2], e));
            }
        }
        let acc = [acc0, acc1, acc2];
        if to == w && from < to {
            // The row is done: pending sums go to their cells (x_last + dir·(j + 1 − R)).
            let x_last = (if dir > 0 { w - 1 } else { 0 }) as isize;
            for (row, pending) in rows[1..=N].iter().zip(&acc) {
                for (j, &sum) in pending[..2 * R].iter().enumerate() {
                    let at = PAD as isize + x_last + dir * (j as isize + 1 - R as isize);
                    row[at as usize].add(sum);
                }
            }
            // Error pushed past the row's end is dropped.
            *state = RowState::default();
        } else {
            state.ahead = ahead;
            state.below = acc;
        }
    }

    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn run_row<C: ErrCell, S: Code>(
        &self,
        codes: &[S],
        rows: &[&[C]; ROWS],
        out: &mut [u8],
        y: usize,
        from: usize,
        to: usize,
        dir: isize,
        state: &mut RowState,
    ) {
        if let Some(fk) = &self.fixed {
            fk.run(codes, rows, out, from, to, dir, state)
        } else if let Some(ww) = &self.window {
            macro_rules! window {
                ($($r:literal, $n:literal);*) => {
                    match (self.reach.max(1), self.below.max(1), self.top_i == 1) {
                        $(
                            ($r, $n, true) => self.run_window::<C, S, true, $r, $n>(
                                ww, codes, rows, out, from, to, dir, state,
                            ),
                            ($r, $n, false) => self.run_window::<C, S, false, $r, $n>(
                                ww, codes, rows, out, from, to, dir, state,
                            ),
                        )*
                        _ => unreachable!("window reach and rows are 1..=3"),
                    }
                };
            }
            window!(1, 1; 1, 2; 1, 3; 2, 1; 2, 2; 2, 3; 3, 1; 3, 2; 3, 3);
        } else if self.top_i == 1 {
            self.run::<C, S, true>(codes, rows, out, y, from, to, dir, state)
        } else {
            self.run::<C, S, false>(codes, rows, out, y, from, to, dir, state)
        }
    }

    /// True when rows may run as a wavefront: the register window (fixed kernels) or the
    /// three-tap variable kernels, which never write ahead into their own row.
    fn wavefront_safe(&self) -> bool {
        self.fixed.is_some()
            || self.window.is_some()
            || matches!(self.weights, Weights::Variable { .. })
    }

    /// One thread, one row after another (serpentine or raster).
    fn sequential<S: Code>(&self, codes: &[S], w: usize, out: &mut PlaneOut<'_>) {
        let n = self.below + 1;
        let span = w + 2 * PAD;
        let mut buf = vec![0f32; n * span];
        let cells = Cell::from_mut(&mut buf[..]).as_slice_of_cells();
        let slot = |r: usize| &cells[r * span..(r + 1) * span];
        let mut levels = vec![0u8; w];
        let (bits, stride) = (out.bits, out.stride);
        for y in 0..out.height {
            let dir = if self.serpentine && y % 2 == 1 { -1 } else { 1 };
            let rows: [&[Cell<f32>]; ROWS] =
                std::array::from_fn(|d| slot((y + d.min(self.below)) % n));
            let mut state = RowState::default();
            self.run_row(
                &codes[y * w..(y + 1) * w],
                &rows,
                &mut levels,
                y,
                0,
                w,
                dir,
                &mut state,
            );
            // Error pushed past the edges is dropped.
            for c in rows[0][..PAD].iter().chain(&rows[0][PAD + w..]) {
                c.set(0.0);
            }
            pack_row(&levels, bits, &mut out.data[y * stride..(y + 1) * stride]);
        }
    }

    /// Raster rows dealt round-robin to `threads` threads; row `y` waits until row `y − 1`
    /// is `reach + 1` pixels ahead. Same bytes as [`Engine::sequential`] in raster order.
    fn wavefront<S: Code>(&self, codes: &[S], w: usize, out: &mut PlaneOut<'_>, threads: usize) {
        let h = out.height;
        // Rows in flight: at most `threads` consecutive rows, writing `below` rows further.
        let n = threads + self.below;
        let span = w + 2 * PAD;
        let slots: Vec<AtomicU32> = (0..n * span).map(|_| AtomicU32::new(0)).collect();
        // Progress of the row in each slot: (row + 1) << 32 | pixels done.
        let progress: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(0)).collect();
        let (bits, stride) = (out.bits, out.stride);
        let mut mine: Vec<Vec<(usize, &mut [u8])>> = (0..threads).map(|_| Vec::new()).collect();
        for (y, row) in out.data.chunks_mut(stride).take(h).enumerate() {
            mine[y % threads].push((y, row));
        }
        let reach = self.reach;
        std::thread::scope(|s| {
            for rows_of_thread in mine {
                let (slots, progress) = (&slots, &progress);
                s.spawn(move || {
                    let slot = |r: usize| &slots[r * span..(r + 1) * span];
                    let mut levels = vec![0u8; w];
                    for (y, packed) in rows_of_thread {
                        let rows: [&[AtomicU32]; ROWS] =
                            std::array::from_fn(|d| slot((y + d.min(self.below)) % n));
                        let row_codes = &codes[y * w..(y + 1) * w];
                        let mut state = RowState::default();
                        let mut x = 0;
                        while x < w {
                            let mut end = w;
                            if y > 0 {
                                let above = &progress[(y - 1) % n];
                                let need = ((y as u64) << 32) | (x + reach + 1).min(w) as u64;
                                let mut spins = 0u32;
                                let mut got = above.load(Ordering::Acquire);
                                while got < need {
                                    spins += 1;
                                    if spins < 64 {
                                        std::hint::spin_loop();
                                    } else {
                                        std::thread::yield_now();
                                    }
                                    got = above.load(Ordering::Acquire);
                                }
                                let done = (got & 0xFFFF_FFFF) as usize;
                                if done < w {
                                    end = done - reach;
                                }
                            }
                            let end = end.min(x + CHUNK);
                            self.run_row(row_codes, &rows, &mut levels, y, x, end, 1, &mut state);
                            x = end;
                            if x == w {
                                // Nobody writes this slot any more: clear the edges for reuse.
                                for c in rows[0][..PAD].iter().chain(&rows[0][PAD + w..]) {
                                    c.set(0.0);
                                }
                            }
                            progress[y % n]
                                .store(((y as u64 + 1) << 32) | x as u64, Ordering::Release);
                        }
                        pack_row(&levels, bits, packed);
                    }
                });
            }
        });
    }
}

/// The weights of a fixed kernel shaped like Floyd–Steinberg's (one tap ahead; behind, under
/// and ahead in the row below), which [`palette::fs`] runs.
fn fs_shape(weights: &Weights) -> Option<palette::fs::FsWeights> {
    let Weights::Fixed { right, taps } = weights else {
        return None;
    };
    let tap = |dx: isize| {
        taps.iter()
            .find(|&&(tx, dy, _)| tx == dx && dy == 1)
            .map(|t| t.2)
    };
    if taps.len() != 3 || *right == 0.0 {
        return None;
    }
    Some(palette::fs::FsWeights {
        right: *right,
        behind: tap(-1)?,
        under: tap(0)?,
        ahead: tap(1)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmath as fm;
    use crate::raster::PlaneRef;
    use crate::tone::srgb_to_linear;

    /// Packed output of one plane through `run`.
    fn packed<S: Code>(w: usize, h: usize, run: impl FnOnce(&mut PlaneOut<'_>)) -> Vec<u8> {
        let stride = w.div_ceil(8);
        let mut data = vec![0u8; stride * h];
        let mut out = PlaneOut {
            width: w,
            height: h,
            bits: 1,
            stride,
            data: &mut data,
        };
        run(&mut out);
        data
    }

    /// The two-pass Floyd–Steinberg gives the bytes of the one-pass fixed-point loop, for
    /// 8- and 16-bit codes, serpentine and raster, on sizes from one pixel up.
    #[test]
    fn two_pass_floyd_steinberg_matches_one_pass() {
        let tone8: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let tone16: Vec<f32> = (0..65536)
            .map(|c| srgb_to_linear(c as f64 / 65535.0) as f32)
            .collect();
        let mut next = xorshift(0x2545_F491_4F6C_DD1Du64);
        for (w, h) in [(1, 1), (1, 7), (7, 1), (2, 3), (9, 5), (64, 33), (333, 41)] {
            // A ramp with noise: every tone, both sides of the threshold, and sharp steps.
            let mut c8 = Vec::with_capacity(w * h);
            for i in 0..w * h {
                let c = ((i % w * 255 / w.max(2)) as u64 + next() % 64).min(255) as u8;
                c8.push(if next().is_multiple_of(17) {
                    255 - c
                } else {
                    c
                });
            }
            let c16: Vec<u16> = c8
                .iter()
                .map(|&c| (c as u16 * 257).wrapping_add((next() % 200) as u16))
                .collect();
            for serpentine in [true, false] {
                let d = Diffuse::new(
                    "floyd-steinberg",
                    DiffuseOptions {
                        serpentine,
                        ..Default::default()
                    },
                )
                .unwrap();
                for tone in [&tone8, &tone16] {
                    let engine = Engine::new(&d, tone, 2);
                    let fk = engine.fixed.as_ref().unwrap();
                    let t = fk.floyd_steinberg_tone().unwrap();
                    let (old, new) = if tone.len() == 256 {
                        (
                            packed::<u8>(w, h, |o| engine.sequential(&c8, w, o)),
                            packed::<u8>(w, h, |o| fs::plane(t, &c8, w, o, serpentine)),
                        )
                    } else {
                        (
                            packed::<u16>(w, h, |o| engine.sequential(&c16, w, o)),
                            packed::<u16>(w, h, |o| fs::plane(t, &c16, w, o, serpentine)),
                        )
                    };
                    assert_eq!(
                        old,
                        new,
                        "{w}×{h} serpentine {serpentine} codes {}",
                        tone.len()
                    );
                }
            }
        }
    }

    /// A small deterministic generator (xorshift) from `seed`.
    /// Floyd–Steinberg diffusion to `palette`, serpentine or raster.
    fn fs_palette(palette: &Palette, serpentine: bool) -> Diffuse {
        Diffuse::new(
            "floyd-steinberg",
            DiffuseOptions {
                serpentine,
                ..Default::default()
            },
        )
        .unwrap()
        .with_palette(palette.clone())
    }

    /// Bands and warm-up rows for testing banding on small pages: several bands a page, the
    /// warm-up odd (it starts on the other scan direction from its band).
    const TEST_BAND: usize = 22;
    const TEST_WARM: usize = 7;

    /// A palette run as the tests take it: bands of [`TEST_BAND`] rows.
    fn test_run<'d>(
        d: &'d Diffuse,
        palette: &'d Palette,
        fast: bool,
        fs_loop: bool,
    ) -> palette::PaletteRun<'d> {
        palette::PaletteRun::new(d, palette, fast, fs_loop)
            .unwrap()
            .with_bands(TEST_BAND, TEST_WARM)
    }

    fn xorshift(mut seed: u64) -> impl FnMut() -> u64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        }
    }

    /// Rows `y0..y0 + n` of a page of 8-bit planes `w` wide, as the pipeline hands a band over.
    fn rgb_band<'a>(
        planes: &'a [Vec<u8>],
        w: usize,
        tone: &'a [f32],
        y0: usize,
        n: usize,
    ) -> Planes<'a> {
        Planes {
            width: w,
            height: n,
            planes: planes
                .iter()
                .map(|p| PlaneRef {
                    width: w,
                    height: n,
                    samples: SamplesRef::U8(&p[y0 * w..(y0 + n) * w]),
                    tone,
                })
                .collect(),
        }
    }

    /// The vector loop (AVX-512, palettes of up to eight colours) against the exact search on
    /// a page built to reach its hard cases: a near-black third (values the error pushes
    /// below zero, Oklab `L` clamped to 0, LMS crossing zero), saturated hue sweeps in the
    /// middle, a near-white third (`L` clamped to 1), hard edges and noise; whole and handed
    /// over in bands of 3 and 17 rows, both scan orders (the page cut into bands of
    /// [`TEST_BAND`] rows, so that the loops are compared across band starts and warm-ups).
    #[test]
    fn palette_vector_loop_matches_exact_search() {
        use crate::cpu::{test_has, with_level, Level};
        let mut levels = vec![Level::Portable];
        if test_has(Level::Avx512, "palette_vector_loop_matches_exact_search") {
            levels.push(Level::Avx512);
        }
        let mut next = xorshift(0x2545_F491_4F6C_DD1Du64);
        let (w, h) = (320, 120);
        let planes: Vec<Vec<u8>> = (0..3)
            .map(|c| {
                (0..w * h)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        let noise = (next() % 17) as i32 - 8;
                        let v: i32 = if x < w / 3 {
                            ((x + y) % 23) as i32 / 2
                        } else if x < 2 * w / 3 {
                            // Each channel a phase of a triangle wave: saturated hues.
                            let t = (x * 6 + y * 2 + c * 170) % 512;
                            if t < 256 {
                                t as i32
                            } else {
                                511 - t as i32
                            }
                        } else {
                            240 + ((x * 3 + y + c * 5) % 16) as i32
                        };
                        let edge = if (x / 40 + y / 30) % 5 == 0 {
                            255 - v
                        } else {
                            v
                        };
                        (edge + noise).clamp(0, 255) as u8
                    })
                    .collect()
            })
            .collect();
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let band_of = |y0: usize, n: usize| rgb_band(&planes, w, &tone, y0, n);
        let mut palettes: Vec<Palette> = ["rgb-8", "epaper-7", "eink-4", "bw"]
            .iter()
            .map(|n| Palette::builtin(n).unwrap())
            .collect();
        let colours = (0..5)
            .map(|_| std::array::from_fn(|_| (next() % 256) as u8))
            .collect();
        palettes.push(Palette::new("random", colours).unwrap());
        for palette in &palettes {
            for serpentine in [true, false] {
                let d = fs_palette(palette, serpentine);
                let exact = test_run(&d, palette, false, false)
                    .band(&band_of(0, h))
                    .unwrap();
                for (rows, &level) in [h, 3, 17]
                    .into_iter()
                    .flat_map(|r| levels.iter().map(move |l| (r, l)))
                {
                    let mut r = test_run(&d, palette, true, true);
                    let mut got = Vec::new();
                    for y0 in (0..h).step_by(rows) {
                        let n = rows.min(h - y0);
                        let band = with_level(level, || r.band(&band_of(y0, n)).unwrap());
                        got.extend_from_slice(&band.planes[0]);
                    }
                    assert_eq!(
                        got, exact.planes[0],
                        "{} serpentine {serpentine} bands of {rows}, {level:?}",
                        palette.name
                    );
                }
            }
        }
    }

    /// Palette diffusion through the fast nearest-colour search gives the bytes of the exact search
    /// at every pixel: random photo-like images (smooth colour fields with noise, so values
    /// sweep through many cubes and their boundaries), built-in and random palettes, fixed
    /// and variable kernels, both scan orders; the page cut into bands of [`TEST_BAND`] rows.
    #[test]
    fn palette_table_matches_exact_search() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15u64);
        let (w, h) = (97, 61);
        let mut palettes: Vec<Palette> = ["rgb-8", "epaper-7", "pico-8", "eink-4", "bw"]
            .iter()
            .map(|n| Palette::builtin(n).unwrap())
            .collect();
        for n in [3usize, 6, 12, 30] {
            let colours = (0..n)
                .map(|_| std::array::from_fn(|_| (next() % 256) as u8))
                .collect();
            palettes.push(Palette::new("random", colours).unwrap());
        }
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        for (pi, palette) in palettes.into_iter().enumerate() {
            let planes: Vec<Vec<u8>> = (0..3)
                .map(|c| {
                    let (fx, fy) = (1 + (pi + c) % 4, 1 + (pi * 3 + c) % 5);
                    (0..w * h)
                        .map(|i| {
                            let (x, y) = (i % w, i / w);
                            let v = (x * fx * 255 / w + y * fy * 255 / h) % 256;
                            (v as u64 + next() % 24).min(255) as u8
                        })
                        .collect()
                })
                .collect();
            let band_of = |y0: usize, n: usize| rgb_band(&planes, w, &tone, y0, n);
            let refs = band_of(0, h);
            for (kernel, serpentine) in [
                ("floyd-steinberg", true),
                ("floyd-steinberg", false),
                ("jarvis-judice-ninke", true),
                ("ostromoukhov", true),
            ] {
                let d = Diffuse::new(
                    kernel,
                    DiffuseOptions {
                        serpentine,
                        ..Default::default()
                    },
                )
                .unwrap()
                .with_palette(palette.clone());
                let run = |fast: bool, fs_loop: bool| {
                    test_run(&d, &palette, fast, fs_loop).band(&refs).unwrap()
                };
                let exact = run(false, false);
                let scalar = test_run(&d, &palette, true, true)
                    .without_vector()
                    .band(&refs)
                    .unwrap();
                assert_eq!(
                    scalar.planes, exact.planes,
                    "palette {pi} {kernel} scalar loop"
                );
                for (fast, fs_loop) in [(true, true), (false, true), (true, false)] {
                    assert_eq!(
                        run(fast, fs_loop).planes,
                        exact.planes,
                        "palette {pi} ({}) {kernel} serpentine {serpentine} fast {fast}",
                        palette.name
                    );
                }
                // Band by band (as the streaming pipeline runs it): the same bytes for bands
                // of 1, 2, 7 and 61 rows (odd heights cross the serpentine's parity).
                let whole = run(true, true);
                for rows in [1usize, 2, 7, 61] {
                    let mut r = test_run(&d, &palette, true, true);
                    let mut got = Vec::new();
                    for y0 in (0..h).step_by(rows) {
                        let n = rows.min(h - y0);
                        let band = band_of(y0, n);
                        got.extend_from_slice(&r.band(&band).unwrap().planes[0]);
                    }
                    assert_eq!(
                        got, whole.planes[0],
                        "palette {pi} {kernel} bands of {rows}"
                    );
                }
            }
        }
    }

    /// A photo-like page (smooth colour fields, edges, fine texture and noise, dark and
    /// bright areas) for palette loops.
    fn photo_like(w: usize, h: usize, seed: u64) -> Vec<Vec<u8>> {
        let mut next = xorshift(seed);
        (0..3)
            .map(|c| {
                (0..w * h)
                    .map(|i| {
                        let (x, y) = (i as f64 / w as f64, (i / w) as f64 / h as f64);
                        let (xf, yf) = (x * 6.0 + c as f64, y * 5.0 - c as f64 * 0.7);
                        let smooth =
                            0.5 + 0.3 * (fm::sin(xf) * fm::cos(yf)) + 0.2 * fm::sin(x * y * 9.0);
                        let dark = if (x - 0.3).powi(2) + (y - 0.6).powi(2) < 0.04 {
                            0.1
                        } else {
                            1.0
                        };
                        let texture = 0.08 * fm::sin((i % w) as f64 * 0.9 + c as f64);
                        let noise = (next() % 13) as f64 / 255.0 - 6.0 / 255.0;
                        let v = (smooth * dark + texture + noise).clamp(0.0, 1.0);
                        (v * 255.0).round() as u8
                    })
                    .collect()
            })
            .collect()
    }

    /// The scalar loop with the cell table, without it, and the vector loop (AVX-512, where
    /// present) give the general loop's bytes on a photo-like page, serpentine and raster,
    /// for e-paper palettes (nominal and measured), a two-colour and a near-duplicate
    /// palette; the page cut into bands of [`TEST_BAND`] rows.
    #[test]
    fn palette_cell_loop_matches_general_loop() {
        use crate::cpu::{test_has, with_level, Level};
        use std::sync::atomic::Ordering::Relaxed;
        let (w, h) = (257, 90);
        let planes = photo_like(w, h, 0x5DEE_CE66_D1CE_4E5Bu64);
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let page = rgb_band(&planes, w, &tone, 0, h);
        let mut levels = vec![Level::Portable];
        if test_has(Level::Avx512, "palette_cell_loop_matches_general_loop") {
            levels.push(Level::Avx512);
        }
        let palettes = palette::cells::test_palettes();
        for palette in &palettes {
            for serpentine in [true, false] {
                let d = fs_palette(palette, serpentine);
                let general = test_run(&d, palette, false, false).band(&page).unwrap();
                for &level in &levels {
                    let before = palette::cells::COUNTS.each_ref().map(|c| c.load(Relaxed));
                    let got = with_level(level, || {
                        test_run(&d, palette, true, true).band(&page).unwrap()
                    });
                    assert_eq!(
                        got.planes, general.planes,
                        "{} serpentine {serpentine} {level:?}",
                        palette.name
                    );
                    let without = with_level(level, || {
                        test_run(&d, palette, true, true)
                            .without_table()
                            .band(&page)
                            .unwrap()
                    });
                    assert_eq!(without.planes, general.planes, "{}", palette.name);
                    let after = palette::cells::COUNTS.each_ref().map(|c| c.load(Relaxed));
                    // Other tests count too: report only, the bytes are the assertion.
                    eprintln!(
                        "{} serpentine {serpentine} {level:?}: {} looked up, {} not proven",
                        palette.name,
                        after[0] - before[0],
                        after[1] - before[1]
                    );
                }
            }
        }
    }

    /// The six inks of a Spectra 6 panel, nominal.
    fn six_colours() -> Palette {
        let colours = vec![
            [0, 0, 0],
            [255, 255, 255],
            [255, 255, 0],
            [255, 0, 0],
            [0, 0, 255],
            [0, 255, 0],
        ];
        Palette::new("six", colours).unwrap()
    }

    /// A page through `r` in handed bands of `rows` (cycled), as the streaming pipeline hands
    /// them over: the packed rows.
    fn streamed(
        mut r: palette::PaletteRun<'_>,
        planes: &[Vec<u8>],
        w: usize,
        h: usize,
        tone: &[f32],
        rows: &[usize],
    ) -> Vec<u8> {
        let mut got = Vec::new();
        let (mut y0, mut k) = (0, 0);
        while y0 < h {
            let n = rows[k % rows.len()].min(h - y0);
            got.extend_from_slice(&r.band(&rgb_band(planes, w, tone, y0, n)).unwrap().planes[0]);
            y0 += n;
            k += 1;
        }
        got
    }

    /// Banding at the real sizes ([`palette::BAND`], [`palette::WARM`]): the bytes do not
    /// depend on the threads (one or two) nor on the bands the page is handed over in; the
    /// first band is the unbanded run's, and every other band is the unbanded run over its
    /// warm-up rows and its own with the warm-up's output dropped. Floyd–Steinberg (each
    /// loop) and Jarvis–Judice–Ninke (the general loop), serpentine and raster.
    #[test]
    fn palette_bands_independent_of_threads_and_handover() {
        use crate::cpu::{test_has, with_level, Level};
        let (b, warm) = (palette::BAND, palette::WARM);
        let (w, h) = (150, 2 * b + 45);
        let planes = photo_like(w, h, 0x1234_5678_9ABC_DEF1u64);
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let page = rgb_band(&planes, w, &tone, 0, h);
        let pool = |n: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        };
        let (one, two) = (pool(1), pool(2));
        let palette = six_colours();
        let mut levels = vec![Level::Portable];
        if test_has(
            Level::Avx512,
            "palette_bands_independent_of_threads_and_handover",
        ) {
            levels.push(Level::Avx512);
        }
        for (kernel, serpentine) in [
            ("floyd-steinberg", true),
            ("floyd-steinberg", false),
            ("jarvis-judice-ninke", true),
        ] {
            let d = Diffuse::new(
                kernel,
                DiffuseOptions {
                    serpentine,
                    ..Default::default()
                },
            )
            .unwrap()
            .with_palette(palette.clone());
            let run = |fast| palette::PaletteRun::new(&d, &palette, fast, fast).unwrap();
            let whole = run(false).band(&page).unwrap();
            let stride = whole.stride;
            // Every band from its warm-up alone, unbanded (an even warm-up keeps the scan
            // directions of the page's rows).
            assert_eq!(warm % 2, 0);
            let unbanded = |from: usize, to: usize| {
                run(false)
                    .with_bands(usize::MAX, 0)
                    .band(&rgb_band(&planes, w, &tone, from, to - from))
                    .unwrap()
                    .planes
                    .remove(0)
            };
            for k in 0..h.div_ceil(b) {
                let (s, e) = (k * b, ((k + 1) * b).min(h));
                let from = s.saturating_sub(warm);
                let alone = unbanded(from, e);
                assert_eq!(
                    whole.planes[0][s * stride..e * stride],
                    alone[(s - from) * stride..],
                    "{kernel} serpentine {serpentine}: band {k}"
                );
            }
            assert_ne!(
                whole.planes[0],
                unbanded(0, h),
                "{kernel}: the bands change bytes"
            );
            for &level in &levels {
                for fast in [false, true] {
                    let (a, b2) = with_level(level, || {
                        (
                            one.install(|| run(fast).band(&page).unwrap()),
                            two.install(|| run(fast).band(&page).unwrap()),
                        )
                    });
                    let what = format!("{kernel} serpentine {serpentine} fast {fast} {level:?}");
                    assert_eq!(a.planes, whole.planes, "{what}: one thread");
                    assert_eq!(b2.planes, whole.planes, "{what}: two threads");
                    for rows in [
                        &[1usize][..],
                        &[5],
                        &[b],
                        &[b - 1],
                        &[b + 1],
                        &[3 * b],
                        &[warm / 2, 2 * b + 3, 7],
                        &[b - warm / 2, warm, 1],
                    ] {
                        let got = with_level(level, || {
                            two.install(|| streamed(run(fast), &planes, w, h, &tone, rows))
                        });
                        assert_eq!(got, whole.planes[0], "{what}: handed in bands of {rows:?}");
                    }
                }
            }
        }
    }

    /// 16-bit codes too: a page handed over in bands gives the whole page's bytes (the
    /// warm-up rows kept from call to call are 16-bit codes).
    #[test]
    fn palette_bands_of_16_bit_codes_stream_as_the_whole_page() {
        let (b, warm) = (palette::BAND, palette::WARM);
        let (w, h) = (70, 2 * b + 20);
        let planes: Vec<Vec<u16>> = photo_like(w, h, 0x0F0E_0D0C_0B0A_0908u64)
            .into_iter()
            .map(|p| p.iter().map(|&v| v as u16 * 257 + (v as u16 % 7)).collect())
            .collect();
        let tone: Vec<f32> = (0..65536)
            .map(|c| srgb_to_linear(c as f64 / 65535.0) as f32)
            .collect();
        let band_of = |y0: usize, n: usize| Planes {
            width: w,
            height: n,
            planes: planes
                .iter()
                .map(|p| PlaneRef {
                    width: w,
                    height: n,
                    samples: SamplesRef::U16(&p[y0 * w..(y0 + n) * w]),
                    tone: &tone,
                })
                .collect(),
        };
        let palette = six_colours();
        let d = fs_palette(&palette, true);
        let run = || palette::PaletteRun::new(&d, &palette, true, true).unwrap();
        let whole = run().band(&band_of(0, h)).unwrap();
        for rows in [1, warm / 2 + 1, b - 3] {
            let mut r = run();
            let mut got = Vec::new();
            for y0 in (0..h).step_by(rows) {
                let n = rows.min(h - y0);
                got.extend_from_slice(&r.band(&band_of(y0, n)).unwrap().planes[0]);
            }
            assert_eq!(got, whole.planes[0], "bands of {rows}");
        }
    }

    /// No seam: on a flat light grey (sRGB 235) through six inks, the mean linear luminance of
    /// the 16 rows about each band's first row is the flat's, as it is in the unbanded run.
    ///
    /// Tolerance 0.005: a strip of whole rows of a flat gets back the flat's mean less the
    /// error crossing its top and bottom edges, which varies from strip to strip; in the
    /// unbanded run the 16-row strips of this page (its first 48 rows aside, where the
    /// diffusion starts up) range over −0.0036..+0.0041 of the flat (measured), and the seams'
    /// strips are −0.0016 and −0.0024 banded (a band starts up as the page's top does) and
    /// +0.0009 and +0.0003 unbanded. A seam a row wide moves a strip by about a sixteenth of
    /// the row's change: a row without dots by +0.17/16 ≈ 0.011 (dots are a sixth of the
    /// pixels at this tone), one with twice its dots by about −0.011; 0.005 catches these.
    #[test]
    fn palette_bands_leave_no_seam() {
        let (b, warm) = (palette::BAND, palette::WARM);
        let (w, h) = (2048, 3 * b);
        let palette = six_colours();
        let planes: Vec<Vec<u8>> = (0..3).map(|_| vec![235u8; w * h]).collect();
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let flat = tone[235] as f64;
        let ink: Vec<f64> = palette
            .colours
            .iter()
            .map(|c| {
                let l = c.map(|v| srgb_to_linear(v as f64 / 255.0));
                0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2]
            })
            .collect();
        let d = fs_palette(&palette, true);
        let page = rgb_band(&planes, w, &tone, 0, h);
        let banded = palette::PaletteRun::new(&d, &palette, true, true)
            .unwrap()
            .band(&page)
            .unwrap();
        let unbanded = palette::PaletteRun::new(&d, &palette, true, true)
            .unwrap()
            .with_bands(usize::MAX, 0)
            .band(&page)
            .unwrap();
        let mean = |ht: &Halftone, rows: std::ops::Range<usize>| {
            let mut row = vec![0u8; w];
            let n = rows.len() * w;
            let sum: f64 = rows
                .map(|y| {
                    ht.unpack_row(0, y, &mut row);
                    row.iter().map(|&i| ink[i as usize]).sum::<f64>()
                })
                .sum();
            sum / n as f64
        };
        for seam in [b, 2 * b] {
            let rows = seam - warm / 2..seam + warm / 2;
            let (with, without) = (mean(&banded, rows.clone()), mean(&unbanded, rows));
            eprintln!("seam {seam}: flat {flat:.5}, banded {with:.5}, unbanded {without:.5}");
            assert!(
                (with - flat).abs() < 0.005,
                "seam {seam}: {with} against {flat}"
            );
            assert!(
                (without - flat).abs() < 0.005,
                "unbanded at {seam}: {without}"
            );
        }
    }

    /// The share of a photo's pixels the cell table does not answer (scalar loop): run on a binary
    /// PPM named by `HALFTONE_PPM` and a palette file `HALFTONE_PALETTE` (ignored: a figure
    /// for the docs, not a check).
    #[test]
    #[ignore]
    fn palette_cell_share_on_a_photo() {
        use std::sync::atomic::Ordering::Relaxed;
        let path = std::env::var("HALFTONE_PPM").expect("HALFTONE_PPM");
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes[..64]);
        let fields: Vec<&str> = text.split_ascii_whitespace().take(4).collect();
        let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
        let start = bytes.len() - 3 * w * h;
        let planes: Vec<Vec<u8>> = (0..3)
            .map(|c| (0..w * h).map(|i| bytes[start + 3 * i + c]).collect())
            .collect();
        let tone: Vec<f32> = (0..256)
            .map(|c| srgb_to_linear(c as f64 / 255.0) as f32)
            .collect();
        let name = std::env::var("HALFTONE_PALETTE").unwrap_or("epaper-7".into());
        let palette = Palette::builtin(&name).unwrap_or_else(|| {
            let text = std::fs::read_to_string(&name).unwrap();
            let colours = text
                .lines()
                .map(|l| {
                    let v = u32::from_str_radix(l.trim().trim_start_matches('#'), 16).unwrap();
                    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
                })
                .collect();
            Palette::new("file", colours).unwrap()
        });
        let d = Diffuse::new("floyd-steinberg", DiffuseOptions::default())
            .unwrap()
            .with_palette(palette.clone());
        let mut r = palette::PaletteRun::new(&d, &palette, true, true)
            .unwrap()
            .without_vector();
        let before = palette::cells::COUNTS.each_ref().map(|c| c.load(Relaxed));
        for y0 in (0..h).step_by(64) {
            r.band(&rgb_band(&planes, w, &tone, y0, 64.min(h - y0)))
                .unwrap();
        }
        let after = palette::cells::COUNTS.each_ref().map(|c| c.load(Relaxed));
        let (n, slow) = (after[0] - before[0], after[1] - before[1]);
        for c in 0..3 {
            let h: Vec<u64> = (0..palette::cells::G)
                .map(|k| palette::cells::HIST[c * palette::cells::G + k].load(Relaxed) / 1000)
                .collect();
            eprintln!("channel {c}: {h:?}");
        }
        eprintln!(
            "{path} {name}: {n} pixels, {slow} not proven ({:.2}%)",
            100.0 * slow as f64 / n as f64
        );
    }
}
