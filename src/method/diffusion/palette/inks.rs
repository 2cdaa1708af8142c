//! Diffusion for real inks: the mapped picture ([`crate::rendering::Mapped`]) dithered to
//! the adapted inks, error measured against the mapped target and kept in bounds, neutral
//! parts of the picture made with the neutral inks only, the nearest ink found through a
//! table over Oklab ([`NearestTable`]). Bands of rows run in parallel with the same bytes for
//! any thread count; [`diffuse`] is the whole-picture entry.

use rayon::prelude::*;

use crate::color::{oklab, oklab8, oklab_signed};
use crate::mask::Mask;
use crate::method::diffusion::kernels::Kernel;

use super::fs::FsWeights;
use crate::rendering::{Mapped, NEUTRAL_BIT};

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
pub(crate) struct NearestTable {
    pub(crate) cells: Vec<u8>,
    /// The inks in Oklab.
    pub(crate) labs: Vec<[f32; 3]>,
}

/// Cells along each axis of [`NearestTable`] from 0 to `TOP`, and the light the last ends at.
pub(crate) const CELLS: usize = 32;

pub(crate) const TOP: f32 = 1.3;

/// Cells below zero along each axis, and their width in signed square roots (the last
/// reaches to -0.81, past which all values share it).
pub(crate) const NEG_CELLS: usize = 6;

pub(crate) const NEG_STEP: f32 = 0.15;

/// Cells along each axis.
pub(crate) const AXIS: usize = NEG_CELLS + CELLS;

/// `f32` bits dropped to make a value's key.
pub(crate) const KEY_SHIFT: u32 = 17;

/// The cell along one axis of every key: every 15-bit key (sign, exponent and six mantissa
/// bits), so that a value's key needs no clamping. Only the keys of the values a picture
/// takes are ever read (a few cache lines).
pub(crate) struct Coords([u8; 1 << (32 - KEY_SHIFT)]);

/// The cell along one axis of the value `v`.
pub(crate) fn axis_cell(v: f32) -> usize {
    if v >= 0.0 {
        let scale = CELLS as f32 / TOP.sqrt();
        NEG_CELLS + ((v.min(TOP).sqrt() * scale) as usize).min(CELLS - 1)
    } else {
        NEG_CELLS - 1 - (((-v).sqrt() / NEG_STEP) as usize).min(NEG_CELLS - 1)
    }
}

/// The centre of cell `i` along an axis (the middle of its signed square roots, squared).
pub(crate) fn axis_centre(i: usize) -> f32 {
    if i >= NEG_CELLS {
        let q = ((i - NEG_CELLS) as f32 + 0.5) / CELLS as f32 * TOP.sqrt();
        q * q
    } else {
        let q = ((NEG_CELLS - 1 - i) as f32 + 0.5) * NEG_STEP;
        -q * q
    }
}

pub(crate) fn coords() -> &'static Coords {
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
    pub(crate) fn of(&self, v: f32) -> usize {
        self.0[(v.to_bits() >> KEY_SHIFT) as usize] as usize
    }

    /// The table index of the cell holding `v`.
    #[inline(always)]
    pub(crate) fn cell(&self, v: [f32; 3]) -> usize {
        self.of(v[0]) + AXIS * self.of(v[1]) + AXIS * AXIS * self.of(v[2])
    }
}

impl NearestTable {
    /// The table of `inks` (linear RGB), its second half among the `neutral` ones (all, when
    /// fewer than two are).
    pub(crate) fn of(inks: &[[f32; 3]], neutral: &[bool]) -> NearestTable {
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
    pub(crate) fn build(labs: &[[f32; 3]], lists: [&[u8]; 2]) -> NearestTable {
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
    pub(crate) fn avoiding(&self, coords: &Coords, v: [f32; 3], avoid: u32) -> u8 {
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
    pub(crate) fn nearest_allowed(&self, v: [f32; 3], avoid: u32) -> u8 {
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

impl FsWeights {
    /// A four-tap kernel's weights scaled by `scale`, if it has Floyd–Steinberg's shape.
    pub(crate) fn of(kernel: &Kernel, scale: f32) -> Option<FsWeights> {
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
pub(crate) fn max_f(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The smaller of two numbers that are not NaN: see [`max_f`].
#[inline(always)]
pub(crate) fn min_f(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// Inks the Floyd–Steinberg loop serves (a vector lane an ink).
pub(crate) const LANES: usize = 8;

/// Side of the threshold modulation's tile (the built-in `blue-noise-64` mask).
pub(crate) const MOD_SIZE: usize = 64;

/// Peak-to-peak amplitude of the threshold modulation (linear light, added to all three
/// channels) where the target is at the ends of the tone scale.
pub(crate) const MOD_AMPLITUDE: f32 = 0.12;

/// Luminance below which (and above one minus which) the modulation is at full strength, and
/// the width over which it fades out.
pub(crate) const MOD_EDGE: f32 = 0.02;

pub(crate) const MOD_FADE: f32 = 0.05;

/// The blue-noise threshold modulation, `MOD_SIZE`² values from −½ to ½ (the ranks of the
/// built-in `blue-noise-64` mask).
///
/// Error diffusion lays the sparse dots of a near-black or near-white flat in lines (worms):
/// the error left by each dot travels the same way. A blue-noise perturbation of the value
/// the ink is chosen for (not of the error; Knox and Eschbach's threshold modulation) breaks
/// the lines and keeps the dots spread, at no cost to the mean.
pub(crate) fn modulation() -> &'static [f32] {
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
pub(crate) fn noise(t: [f32; 3], m: f32) -> f32 {
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
pub(crate) fn diffuse_primed(
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
pub(crate) trait Rows {
    fn row(&mut self, y: usize) -> (&[[f32; 3]], &[u32]);
}

/// The rows of a [`Mapped`].
pub(crate) struct MappedRows<'a>(&'a Mapped);

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
pub(crate) type Block = (Vec<[f32; 3]>, Vec<u32>);

/// Rows mapped on another thread, block by block, taken as they are ready.
pub(crate) struct PipedRows<'a> {
    pub(crate) width: usize,
    pub(crate) block_rows: usize,
    pub(crate) slots: &'a [std::sync::Mutex<Option<Block>>],
    pub(crate) ready: &'a std::sync::atomic::AtomicUsize,
    /// Where a block goes back once used.
    pub(crate) free: &'a std::sync::Mutex<Vec<Block>>,
    /// The block in use, and its number.
    pub(crate) current: (usize, Block),
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
pub(crate) const BAND: usize = 128;

/// Rows a band diffuses before its own (an even number: the scan directions stay those of
/// the page's rows).
pub(crate) const WARM: usize = 16;

/// Times the page's first band diffuses its first row before it (an even number), having no
/// rows above to settle on. Started with no error, a flat of a colour made mostly of one
/// ink (a saturated red: red ink and a few dots of the others) shows another mean in its
/// first rows while the error builds up to the balance of the inks: on bwry-3in97, twice
/// the yellow dots in the first 16 rows (CIEDE2000 5 between a patch's top and bottom
/// thirds); on acep7-5in65 the white dots come in over some 50 rows. A page of no more rows
/// than this is not primed: a strip shows no drift, and a row of the inks' own colours keeps
/// to them (the small error of each pixel's aim, piled up over the primed rows, turned one
/// of them black).
pub(crate) const PRIME: usize = 64;

/// Mapped rows, made in groups of this many as a band needs them.
pub(crate) const GROUP: usize = 16;

/// Maps page rows from `y0` into a block sized for them.
pub(crate) type Fill<'f> = dyn Fn(usize, &mut Block) + Sync + 'f;

/// A band's rows: `start..end` diffused, `keep..end` its own, after its first row diffused
/// `prime` times more (and dropped).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Band {
    pub(crate) start: usize,
    pub(crate) keep: usize,
    pub(crate) end: usize,
    pub(crate) prime: usize,
}

impl Band {
    /// Band `k` of a page `h` rows high (the first primed by `prime` rows when the page is
    /// taller than that: see [`PRIME`]).
    pub(crate) fn of(k: usize, h: usize, prime: usize) -> Band {
        let keep = k * BAND;
        Band {
            start: keep.saturating_sub(WARM),
            keep,
            end: (keep + BAND).min(h),
            prime: if k == 0 && h > prime { prime } else { 0 },
        }
    }

    /// Rows diffused, the primed ones included.
    pub(crate) fn rows(&self) -> usize {
        self.end - self.start + self.prime
    }

    /// The page row diffused at step `j`.
    pub(crate) fn row(&self, j: usize) -> usize {
        self.start + j.saturating_sub(self.prime)
    }

    /// The band's own row (from `keep`) step `j` gives, if any.
    pub(crate) fn own(&self, j: usize) -> Option<usize> {
        j.checked_sub(self.prime)
            .and_then(|j| (self.start + j).checked_sub(self.keep))
    }

    /// Whether step `j` runs right to left (serpentine): the page row's direction, the primed
    /// steps alternating before it ([`PRIME`] is even).
    pub(crate) fn right_to_left(&self, j: usize) -> bool {
        (self.start + j) % 2 == 1
    }
}

/// A band's mapped rows, a group at a time.
#[derive(Default)]
pub(crate) struct BandRows {
    pub(crate) y0: usize,
    pub(crate) block: Block,
}

impl BandRows {
    /// Makes sure row `y` is held (mapping the group from `y`, up to `end`, if not).
    pub(crate) fn load(&mut self, fill: &Fill<'_>, y: usize, end: usize, w: usize) {
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
    pub(crate) fn row(&self, y: usize, w: usize) -> (&[[f32; 3]], &[u32]) {
        let at = (y - self.y0) * w;
        (&self.block.0[at..at + w], &self.block.1[at..at + w])
    }
}

/// What the Floyd–Steinberg loop keeps from row to row of a band.
pub(crate) struct FsState {
    /// The error each cell of this row receives from the row above, and of the row below;
    /// page columns from 1 (0 and w + 1 take what falls past the edges).
    pub(crate) err: Vec<[f32; 3]>,
    pub(crate) below: Vec<[f32; 3]>,
    /// This row in scan order: target plus error (one spare), the inks to avoid, and the
    /// threshold modulation (one spare).
    pub(crate) base: [Vec<f32>; 3],
    pub(crate) avoid: Vec<u32>,
    pub(crate) noise: Vec<f32>,
}

impl FsState {
    pub(crate) fn new(w: usize) -> FsState {
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
pub(crate) struct Diffusion<'a> {
    pub(crate) inks: &'a [[f32; 3]],
    pub(crate) kernel: &'a Kernel,
    pub(crate) serpentine: bool,
    pub(crate) scale: f32,
    /// Nearest ink of every cell, among all inks and among the neutral ones (a nibble each).
    pub(crate) table: NearestTable,
    /// The range a pixel may aim at.
    pub(crate) lo: [f32; 3],
    pub(crate) hi: [f32; 3],
    /// Times the page's first row is diffused before it (see [`PRIME`]).
    pub(crate) prime: usize,
}

impl<'a> Diffusion<'a> {
    /// `table`: the inks' [`NearestTable::of`].
    pub(crate) fn new(
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
    pub(crate) fn fs_weights(&self) -> Option<FsWeights> {
        FsWeights::of(self.kernel, self.scale).filter(|_| self.inks.len() <= LANES)
    }

    /// Ink indices (row-major) of `w`×`h` rows, in order, by the general loop.
    pub(crate) fn run(&self, rows: &mut impl Rows, w: usize, h: usize) -> Vec<u8> {
        let mut out = vec![0u8; w * h];
        if w == 0 || h == 0 {
            return out;
        }
        self.any(rows, w, &mut out);
        out
    }

    /// Ink indices (row-major) of `w`×`h` rows by the Floyd–Steinberg loop, band by band:
    /// see [`BAND`]. `fill(y0, block)` maps the rows from `y0` that `block` is sized for.
    pub(crate) fn bands(&self, wt: FsWeights, fill: &Fill<'_>, w: usize, h: usize) -> Vec<u8> {
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
    pub(crate) fn fs<const N: usize>(
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
    pub(crate) fn fs_body<const N: usize>(
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
    pub(crate) fn fs_row<const N: usize>(
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
    pub(crate) fn any(&self, source: &mut impl Rows, w: usize, out: &mut [u8]) {
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
