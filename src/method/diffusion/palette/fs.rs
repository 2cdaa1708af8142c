//! Palette diffusion for kernels of Floyd–Steinberg's shape (one tap ahead, three in the row
//! below), with the error of the row below built in a sliding window.
//!
//! The general palette loop (`Diffuse::halftone_palette`) adds every tap into error rows kept
//! per channel, indexing a ring of rows for each of the three channels and each tap. Here the
//! three channels of a pixel sit side by side and the row below is written once a cell, when
//! it can receive nothing more: a cell's sum is built from the three pixels above it in the
//! order they are scanned, `((0 + w_ahead·e₁) + w_under·e₂) + w_behind·e₃`, exactly the order
//! of the general loop's `+=`, so every `f32` is the same and so is every output byte (tested
//! against the general loop in `diffusion::tests`).

use super::cells::CellTable;
use super::fast::{lms_of, FastNearest};
use crate::color::PaletteMatcher;
use crate::raster::{pack_row, PlaneRef};

/// The weights of a Floyd–Steinberg-shaped kernel (already scaled by the strength):
/// ahead in the row, and behind, under and ahead in the row below (in scan direction).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FsWeights {
    pub right: f32,
    pub behind: f32,
    pub under: f32,
    pub ahead: f32,
}

/// The input rows one run of a loop goes through: `n` rows of `kept` from its row `from`
/// (rows kept from earlier bands of the page), then rows of `planes`.
#[derive(Clone, Copy)]
pub(crate) struct Input<'a, 'p> {
    pub kept: Rows<'a, 'p>,
    pub planes: Rows<'a, 'p>,
}

/// Rows `from..from + n` of three planes.
#[derive(Clone, Copy)]
pub(crate) struct Rows<'a, 'p> {
    pub planes: [&'a PlaneRef<'p>; 3],
    pub from: usize,
    pub n: usize,
}

impl Input<'_, '_> {
    /// Rows in all.
    pub fn rows(&self) -> usize {
        self.kept.n + self.planes.n
    }

    /// Pixels a row.
    pub fn width(&self) -> usize {
        self.planes.planes[0].width
    }

    /// Row `r` in linear light, as [`linear_row`] gives it.
    pub fn row(&self, r: usize, grey: bool, lin: &mut [Vec<f32>; 3]) {
        let (k, p) = (&self.kept, &self.planes);
        match r.checked_sub(k.n) {
            None => linear_row(k.planes, k.from + r, grey, lin),
            Some(r) => linear_row(p.planes, p.from + r, grey, lin),
        }
    }
}

/// Packed output rows (one plane of palette indices): `stride` bytes a row, `bits` a sample.
pub(crate) struct Packed<'a> {
    pub bytes: &'a mut [u8],
    pub stride: usize,
    pub bits: u8,
}

impl Packed<'_> {
    /// Packs `idx` into row `r`.
    #[inline]
    pub fn put(&mut self, r: usize, idx: &[u8]) {
        pack_row(
            idx,
            self.bits,
            &mut self.bytes[r * self.stride..(r + 1) * self.stride],
        );
    }
}

/// One run of palette diffusion for a Floyd–Steinberg-shaped kernel (a band's rows, or some
/// of them, after its warm-up rows): what the loops take.
pub(crate) struct FsBand<'a, 'p> {
    /// Red, green and blue (linear light through their tables).
    pub input: Input<'a, 'p>,
    /// The page row of the input's first row.
    pub y0: usize,
    /// The input's first rows whose output is dropped (a band's warm-up).
    pub skip: usize,
    /// Diffuse luminance only (a palette of greys).
    pub grey: bool,
    pub wt: FsWeights,
    pub serpentine: bool,
    /// What the search answers (a code): its colour in linear RGB, and its palette index.
    pub linear: &'a [[f32; 3]],
    pub entry: &'a [u8],
    /// The error for the next row, carried from run to run within a band (zero at the
    /// band's start).
    pub err: &'a mut Vec<[f32; 3]>,
    /// Scratch of the same length.
    pub below: &'a mut Vec<[f32; 3]>,
    /// The output rows (input rows `skip..`).
    pub out: Packed<'a>,
}

/// Diffuses a run's rows to palette indices in its `out`; `nearest` is the nearest-colour
/// search, answering a code.
pub(crate) fn run<F: FnMut([f32; 3]) -> usize>(mut b: FsBand<'_, '_>, mut nearest: F) {
    let (w, h) = (b.input.width(), b.input.rows());
    let mut lin = [vec![0f32; w], vec![0f32; w], vec![0f32; w]];
    let mut idx = vec![0u8; w];
    for y in 0..h {
        b.input.row(y, b.grey, &mut lin);
        let fwd = !b.serpentine || (b.y0 + y).is_multiple_of(2);
        let mut carry = [0f32; 3];
        let mut pending = Pending::default();
        for i in 0..w {
            let x = if fwd { i } else { w - 1 - i };
            let mut v = [0f32; 3];
            for c in 0..3 {
                v[c] = (lin[c][x] + b.err[x][c] + carry[c]).clamp(-1.0, 2.0);
            }
            let k = nearest(v);
            idx[x] = b.entry[k];
            let q = b.linear[k];
            let e = [v[0] - q[0], v[1] - q[1], v[2] - q[2]];
            for c in 0..3 {
                carry[c] = e[c] * b.wt.right;
            }
            pending.add(x, e, &b.wt, b.below);
        }
        pending.finish(b.below);
        std::mem::swap(b.err, b.below);
        if y >= b.skip {
            b.out.put(y - b.skip, &idx);
        }
    }
}

/// [`run`] with the cell table ([`CellTable`]) and the fast nearest-colour search
/// ([`FastNearest`], `N` lanes; the band's `linear` and `entry` indexed by lane) where the
/// cell is not proven, the exact search `m` where neither can answer.
///
/// The next pixel's value depends on this pixel's answer only through the colour taken, so
/// while this pixel's answer is worked out, the next pixel's value (and its LMS) is worked out
/// for every lane at once; the answer then picks one. That takes the error's arithmetic and
/// the LMS matrix off the chain that runs from one pixel's answer to the next. Every value is
/// formed by the same operations in the same order as in [`run`], so the bytes are the same.
pub(crate) fn run_fast<const N: usize>(
    mut b: FsBand<'_, '_>,
    f: &FastNearest,
    m: &PaletteMatcher,
    cells: Option<&CellTable>,
) {
    let (w, h) = (b.input.width(), b.input.rows());
    let mut lin = [vec![0f32; w], vec![0f32; w], vec![0f32; w]];
    let mut idx = vec![0u8; w];
    // The lanes' colours, channel by channel.
    let mut q = [[0f32; N]; 3];
    for (lane, colour) in b.linear.iter().enumerate().take(N) {
        for c in 0..3 {
            q[c][lane] = colour[c];
        }
    }
    for y in 0..h {
        b.input.row(y, b.grey, &mut lin);
        let fwd = !b.serpentine || (b.y0 + y).is_multiple_of(2);
        let mut pending = Pending::default();
        let first = if fwd { 0 } else { w - 1 };
        let mut v = [0f32; 3];
        for c in 0..3 {
            v[c] = (lin[c][first] + b.err[first][c] + 0.0).clamp(-1.0, 2.0);
        }
        let mut lms = lms_of(v);
        // The next pixel's value and LMS for every lane.
        let mut next_v = [[0f32; N]; 3];
        let mut next_lms = [[0f32; N]; 3];
        for i in 0..w {
            let x = if fwd { i } else { w - 1 - i };
            let more = i + 1 < w;
            if more {
                let xn = if fwd { x + 1 } else { x - 1 };
                let base: [f32; 3] = std::array::from_fn(|c| lin[c][xn] + b.err[xn][c]);
                for lane in 0..N {
                    let mut vn = [0f32; 3];
                    for c in 0..3 {
                        vn[c] = (base[c] + (v[c] - q[c][lane]) * b.wt.right).clamp(-1.0, 2.0);
                    }
                    let l = lms_of(vn);
                    for c in 0..3 {
                        next_v[c][lane] = vn[c];
                        next_lms[c][lane] = l[c];
                    }
                }
            }
            let cell = cells.and_then(|t| t.lane(v));
            #[cfg(test)]
            if let (None, Some(t)) = (cell, &cells) {
                super::cells::count_value(t, v);
            }
            let lane = match cell.or_else(|| f.nearest_lms::<N>(lms)) {
                Some(lane) => lane,
                None => f.lane_of(m.nearest(v)),
            };
            idx[x] = b.entry[lane];
            let e = [v[0] - q[0][lane], v[1] - q[1][lane], v[2] - q[2][lane]];
            pending.add(x, e, &b.wt, b.below);
            if more {
                v = [next_v[0][lane], next_v[1][lane], next_v[2][lane]];
                lms = [next_lms[0][lane], next_lms[1][lane], next_lms[2][lane]];
            }
        }
        pending.finish(b.below);
        std::mem::swap(b.err, b.below);
        if y >= b.skip {
            b.out.put(y - b.skip, &idx);
        }
        #[cfg(test)]
        if cells.is_some() {
            super::cells::count(w, 0);
        }
    }
}

/// The row below, built in a sliding window: the sums pending at the pixel just scanned and
/// at the one after it; a cell is written once it can receive nothing more.
#[derive(Default)]
struct Pending {
    here: [f32; 3],
    next: [f32; 3],
    prev: Option<usize>,
}

impl Pending {
    /// Pixel `x`'s error `e`: the cell behind it (below the previous pixel) is complete.
    #[inline(always)]
    fn add(&mut self, x: usize, e: [f32; 3], wt: &FsWeights, below: &mut [[f32; 3]]) {
        let mut done = [0f32; 3];
        for c in 0..3 {
            done[c] = self.here[c] + wt.behind * e[c];
            self.here[c] = self.next[c] + wt.under * e[c];
            self.next[c] = 0.0 + wt.ahead * e[c];
        }
        if let Some(p) = self.prev {
            below[p] = done;
        }
        self.prev = Some(x);
    }

    /// The last pixel's cell gets nothing from beyond the row; what would go past the row's
    /// end is dropped, as in the general loop.
    fn finish(self, below: &mut [[f32; 3]]) {
        if let Some(p) = self.prev {
            below[p] = self.here;
        }
    }
}

/// Row `y` of `planes` in linear light, one vector a channel; with `grey`, the luminance in
/// all three (a palette of greys can render luminance only: diffuse that, or the chroma it
/// cannot render piles up as error and smears).
pub(crate) fn linear_row(
    planes: [&PlaneRef<'_>; 3],
    y: usize,
    grey: bool,
    lin: &mut [Vec<f32>; 3],
) {
    for (c, p) in planes.iter().enumerate() {
        p.row_linear(y, &mut lin[c]);
    }
    if grey {
        for x in 0..lin[0].len() {
            let l = 0.2126 * lin[0][x] + 0.7152 * lin[1][x] + 0.0722 * lin[2][x];
            for c in lin.iter_mut() {
                c[x] = l;
            }
        }
    }
}
