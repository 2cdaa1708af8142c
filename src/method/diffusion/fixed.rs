//! Fixed-point bilevel error diffusion for the small kernels (Floyd–Steinberg, Sierra Lite,
//! false Floyd–Steinberg and any kernel of reach 1 with one row below).
//!
//! Floyd–Steinberg itself runs through [`super::fs`], which splits this loop in two passes
//! with the same numbers; this one-pass form is its reference in the tests and serves the
//! other kernels (in raster order also as a wavefront on several cores).
//!
//! Why: the float loop is bound by the latency of the error carried from one pixel to the
//! next (add, compare, int→float, multiply, subtract). In integers the chain is add, compare,
//! select, multiply-shift, with no conversion, and the two candidate errors (pixel off or on)
//! are weighted before the compare settles which one holds.
//!
//! Reflectance is scaled by [`ONE`] = 2^16; the error of a pixel stays within half of that
//! (same argument as for floats: non-negative weights summing to one, inputs in 0..=ONE), so
//! products with weights up to 2^12 stay far inside `i32`. Every tap but one is
//! `(weight × e) >> shift`; the last tap below takes what is left, so the taps sum to `e`
//! exactly: no error is lost or created by the rounding.

use super::{Code, ErrCell, Kernel, RowState, PAD, ROWS};

/// Reflectance 1 (paper) in fixed point.
pub(super) const ONE: i32 = 1 << 16;

/// Largest divisor taken: keeps `weight × error` well inside `i32`.
const MAX_SHIFT: u32 = 12;

/// A kernel of reach 1 and one row below, in fixed point, with the tone table scaled to it.
pub(super) struct FixedKernel {
    /// Reflectance of each code × [`ONE`], rounded.
    tone: Vec<i32>,
    /// Weight of the pixel ahead.
    ahead: i32,
    /// Weights of the row below at dx = −1, 0, +1 (in the scan direction).
    below: [i32; 3],
    /// Which tap below takes the remainder (the last one with a non-zero weight).
    rest: usize,
    /// log2 of the divisor.
    shift: u32,
}

impl FixedKernel {
    /// The fixed-point form of `k` for bilevel output at full strength, or `None` when the
    /// kernel does not fit: reach above 1, more than one row below, weights that do not sum to
    /// the divisor, or a divisor that is not a power of two up to 2^12.
    pub(super) fn new(k: &Kernel, tone: &[f32]) -> Option<FixedKernel> {
        let d = k.divisor;
        if !d.is_power_of_two()
            || d.trailing_zeros() > MAX_SHIFT
            || k.weight_sum() != d
            || k.reach() > 1
            || k.rows_below() != 1
        {
            return None;
        }
        let mut ahead = 0;
        let mut below = [0i32; 3];
        for t in &k.taps {
            match (t.dy, t.dx) {
                (0, 1) => ahead = t.weight as i32,
                (1, dx @ -1..=1) => below[(dx + 1) as usize] = t.weight as i32,
                _ => return None,
            }
        }
        let rest = below.iter().rposition(|&w| w != 0)?;
        Some(FixedKernel {
            tone: tone
                .iter()
                .map(|&v| (v as f64 * ONE as f64).round() as i32)
                .collect(),
            ahead,
            below,
            rest,
            shift: d.trailing_zeros(),
        })
    }

    /// The tone table, when this is Floyd–Steinberg (7 / 3 5 1, ÷16), which
    /// [`super::fs`] runs in two passes with the same numbers.
    pub(super) fn floyd_steinberg_tone(&self) -> Option<&[i32]> {
        (self.ahead == 7 && self.below == [3, 5, 1] && self.shift == 4 && self.rest == 2)
            .then_some(&self.tone[..])
    }

    /// Pixels `from..to` of one row in scan order (`dir` ±1), levels (0 or 1) into `out`
    /// indexed by x. The current row's cells are read and cleared; the row below gets each
    /// cell once, one pixel behind, when this row can add nothing more to it (so a wavefront
    /// row above may still be writing ahead of us). `state.fixed` carries the error for the
    /// next pixel and the two pending sums below between chunks.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn run<C: ErrCell, S: Code>(
        &self,
        codes: &[S],
        rows: &[&[C]; ROWS],
        out: &mut [u8],
        from: usize,
        to: usize,
        dir: isize,
        state: &mut RowState,
    ) {
        // Direction, remainder tap and (for Floyd–Steinberg) the weights become constants,
        // so the loop carries no branch on them and multiplies by 7, 3, 5 as shifts and adds.
        macro_rules! go {
            ($w:expr, $s:expr) => {
                match (dir > 0, self.rest) {
                    (true, 2) => {
                        self.row::<C, S, true, 2>(codes, rows, out, from, to, $w, $s, state)
                    }
                    (true, 1) => {
                        self.row::<C, S, true, 1>(codes, rows, out, from, to, $w, $s, state)
                    }
                    (true, _) => {
                        self.row::<C, S, true, 0>(codes, rows, out, from, to, $w, $s, state)
                    }
                    (false, 2) => {
                        self.row::<C, S, false, 2>(codes, rows, out, from, to, $w, $s, state)
                    }
                    (false, 1) => {
                        self.row::<C, S, false, 1>(codes, rows, out, from, to, $w, $s, state)
                    }
                    (false, _) => {
                        self.row::<C, S, false, 0>(codes, rows, out, from, to, $w, $s, state)
                    }
                }
            };
        }
        let [wl, wd, wr] = self.below;
        if [self.ahead, wl, wd, wr, self.shift as i32] == [7, 3, 5, 1, 4] {
            go!([7, 3, 5, 1], 4)
        } else {
            go!([self.ahead, wl, wd, wr], self.shift)
        }
    }

    /// [`FixedKernel::run`] with the direction (`FWD`) and the remainder tap (`REST`) fixed;
    /// `wt` = (ahead, below −1, below 0, below +1), `s` = log2 of the divisor.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn row<C: ErrCell, S: Code, const FWD: bool, const REST: usize>(
        &self,
        codes: &[S],
        rows: &[&[C]; ROWS],
        out: &mut [u8],
        from: usize,
        to: usize,
        wt: [i32; 4],
        s: u32,
        state: &mut RowState,
    ) {
        let w = codes.len();
        let tone = &self.tone[..];
        let cur = &rows[0][PAD..PAD + w];
        // The cell one pixel behind x (x − dir) sits at `back[x]`.
        let back = if FWD {
            &rows[1][PAD - 1..PAD - 1 + w]
        } else {
            &rows[1][PAD + 1..PAD + 1 + w]
        };
        let out = &mut out[..w];
        let [wa, wl, wd, wr] = wt;
        let [mut carry, mut acc0, mut acc1] = state.fixed;
        for i in from..to {
            let x = if FWD { i } else { w - 1 - i };
            let cell = &cur[x];
            let v = tone[codes[x].into()] + cell.get_raw() as i32 + carry;
            cell.set_raw(0);
            // Both candidate errors and their carried share are ready before the compare.
            let on = v >= ONE / 2;
            let e = if on { v - ONE } else { v };
            let ahead = if on {
                ((v - ONE) * wa) >> s
            } else {
                (v * wa) >> s
            };
            out[x] = on as u8;
            let mut b = [(e * wl) >> s, (e * wd) >> s, (e * wr) >> s];
            b[REST] = 0;
            b[REST] = e - ahead - b[0] - b[1] - b[2];
            carry = ahead;
            let done = &back[x];
            done.set_raw((done.get_raw() as i32 + acc0 + b[0]) as u32);
            acc0 = acc1 + b[1];
            acc1 = b[2];
        }
        if to == w && from < to {
            // The row is done: the pending sums go to x_last and x_last + dir (the latter may
            // be padding, which is dropped).
            let dir = if FWD { 1 } else { -1 };
            let x_last = (if FWD { w - 1 } else { 0 }) as isize;
            for (j, sum) in [acc0, acc1].into_iter().enumerate() {
                let at = (PAD as isize + x_last + dir * j as isize) as usize;
                let c = &rows[1][at];
                c.set_raw((c.get_raw() as i32 + sum) as u32);
            }
            state.fixed = [0; 3];
        } else {
            state.fixed = [carry, acc0, acc1];
        }
    }
}
