//! Palette diffusion with AVX-512 (256-bit vectors) for Floyd–Steinberg-shaped kernels and
//! palettes of at most eight distinct colours: the loop of [`super::fs::run_fast`],
//! its answers and its bytes, with the chain from one pixel's answer to the next kept short.
//!
//! Each pixel's value depends on the previous pixel's answer, so the time a pixel takes is
//! the latency of that chain. Here one vector lane stands for one palette colour throughout:
//!
//! - **Off the chain**, while a pixel's answer is worked out, the next pixel's value is
//!   formed for every answer it could have (a lane each): the error `v − q`, the carry, the
//!   clamp and the LMS matrix, each the same `f32` operation in the same order as the
//!   reference loop, so the lane that is picked holds the exact search's own numbers.
//! - **On the chain**, the answer picks its lane (`vpermps`, the value arriving broadcast),
//!   the three cube roots come from [`FastNearest`]'s table, and all eight scores follow as
//!   linear forms of the cube roots ([`Consts`]), Oklab's `L` clamp done by one masked FMA:
//!   `L` capped at 1 by a minimum, its term left out where `L ≤ 0`. The lowest score is
//!   found by integer minimum on the scores' bits with the lane number in the low three bits,
//!   which leaves the next answer's lane in every lane of the vector, ready to pick with.
//! - **Checked, off the chain**: the answer stands only when every other score is more than
//!   [`MARGIN`] above the lowest (and all scores are positive, so that their bits order them
//!   as numbers, the lowest below 16). Otherwise the exact search answers (a branch the CPU
//!   rarely takes: 1.46% of the pixels of the benchmark photo).
//!
//! The chain, by instruction latencies on this kind of core, is about 47 cycles a pixel: the
//! pick (3), the root's key to a general register (4), the table load (7) and its chord
//! (4), `L` (12), its cap and masked FMA (8), the lane bits (1) and the minimum across the
//! vector (8). The loop runs at about 65 cycles a pixel; taking the cube roots off the chain
//! (a vector root for every lane, done while the previous answer is worked out) measured
//! slower, 71, because the next pixel's roots then wait on this pixel's value: the work
//! between two answers is the error, the clamp, the LMS matrix, the root and `L`, about 120
//! cycles across every two pixels.
//!
//! A certified cell table ([`super::cells`]) was tried here too, the chain put on two
//! loads (the next pixel's cell for every lane worked out off the chain, then the cell for
//! the lane answered, then its byte): 30% of a photo's pixels fall in cells it cannot prove,
//! each paying a mispredicted branch and this search, and the conversion of a 34-megapixel
//! photo took 1.22 s against 0.79 s with this loop (that module's docs have the figures).
//!
//! Why the answer is the exact search's: the scores are those of [`FastNearest`] (the same
//! table cube roots, the same clamp of `L`), computed with the Oklab matrix folded in and an
//! offset [`OFFSET`] that keeps them positive, so their errors stay within that module's
//! `E_fast`. Positive floats order as their bits do, so the integer minimum finds the lowest
//! score's lane (lanes whose scores differ only in the masked bits are within the margin of
//! each other, and the check sends them to the exact search). The masked lowest is within 7
//! units in the last place of the lowest score; accepting only when every other score is
//! above it plus [`MARGIN`] and [`SLACK`] means every other is more than [`MARGIN`] above the
//! lowest, which is [`FastNearest`]'s own condition.

use std::arch::x86_64::*;

use super::fast::{FastNearest, KEY_SHIFT, MARGIN};
use super::fs::FsBand;
use crate::color::PaletteMatcher;
use crate::color::{OKLAB_M1, OKLAB_M2};

/// Added to every score so that scores of values within the clamp (each channel −1..=2) are
/// at least 1: `|q|² − 2·p·q` is above −7 there (Oklab `a` and `b` of such values stay
/// within ±3.2, `|q|` of a palette colour within 1.05).
pub const OFFSET: f32 = 8.0;

/// Added to [`MARGIN`] for the lowest score's masked bits: 16 units in the last place of
/// scores below 16 (the masking moves a score by at most 7, the sum's rounding by half).
pub const SLACK: f32 = 16.0 / (1u32 << 20) as f32;

/// Bits of the largest lowest score the check covers (16.0: below it, a unit in the last
/// place is at most `2⁻²⁰`).
const LOWEST_BELOW: i32 = 0x4180_0000;

/// Whether the kernel runs now ([`crate::cpu`]'s level, `HALFTONE_CPU` included).
pub fn available() -> bool {
    crate::cpu::avx512()
}

/// The scores from the cube roots `x` of LMS, a lane a palette colour: `s = c + g_L·L' +
/// h'·x`, with `L'` Oklab `L` clamped to 0..=1 and `h'` the `a` and `b` rows of the Oklab
/// matrix weighted by the lane's `−2·q`.
struct Consts {
    c: [f32; 8],
    gl: [f32; 8],
    hp: [[f32; 8]; 3],
    /// The lanes' colours in linear RGB, channel by channel, and colour by colour.
    q: [[f32; 8]; 3],
    q4: [[f32; 4]; 8],
}

impl Consts {
    fn new(f: &FastNearest, linear: &[[f32; 3]]) -> Consts {
        let mut k = Consts {
            c: [0.0; 8],
            gl: [0.0; 8],
            hp: [[0.0; 8]; 3],
            q: [[0.0; 8]; 3],
            q4: [[0.0; 4]; 8],
        };
        for (lane, colour) in linear.iter().enumerate().take(8) {
            let (c, g) = f.lane_terms(lane);
            k.c[lane] = c + OFFSET;
            k.gl[lane] = g[0];
            for ch in 0..3 {
                let part: f64 = (1..3).map(|j| g[j] as f64 * OKLAB_M2[j][ch] as f64).sum();
                k.hp[ch][lane] = part as f32;
                k.q[ch][lane] = colour[ch];
                k.q4[lane][ch] = colour[ch];
            }
        }
        k
    }
}

/// [`super::fs::run_fast`] for 8 lanes with AVX-512: the same bytes.
pub(crate) fn run(b: FsBand<'_, '_>, f: &FastNearest, m: &PaletteMatcher) {
    // The CPU's features, not the level now: the level may drop while a band runs.
    assert!(crate::cpu::detected() >= crate::cpu::Level::Avx512);
    assert!(f.lanes() == 8 && b.linear.len() >= 8);
    // SAFETY: the features the kernel is compiled for are present (checked above).
    unsafe { run_avx512([b], f, m) }
}

/// [`run`] of two independent bands at once, a pixel of one and a pixel of the other in
/// turn: the two chains from pixel to pixel overlap. Each band's bytes are those of [`run`].
pub(crate) fn run2(a: FsBand<'_, '_>, b: FsBand<'_, '_>, f: &FastNearest, m: &PaletteMatcher) {
    assert!(crate::cpu::detected() >= crate::cpu::Level::Avx512);
    assert!(f.lanes() == 8 && a.linear.len() >= 8 && b.linear.len() >= 8);
    // SAFETY: as in `run`.
    unsafe { run_avx512([a, b], f, m) }
}

/// One band's rows as the loop works on them.
struct Stream {
    lin: [Vec<f32>; 3],
    /// The row in scan order, input plus the error from the row above (one spare at the end).
    base: [Vec<f32>; 3],
    idx: Vec<u8>,
}

#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
unsafe fn run_avx512<const N: usize>(
    mut bands: [FsBand<'_, '_>; N],
    f: &FastNearest,
    m: &PaletteMatcher,
) {
    let k = Consts::new(f, bands[0].linear);
    let table = f.cbrt_table();
    let mut st: [Stream; N] = std::array::from_fn(|s| {
        let w = bands[s].input.width();
        Stream {
            lin: [vec![0f32; w], vec![0f32; w], vec![0f32; w]],
            base: [vec![0f32; w + 1], vec![0f32; w + 1], vec![0f32; w + 1]],
            idx: vec![0u8; w],
        }
    });
    let rows: [usize; N] = std::array::from_fn(|s| bands[s].input.rows());
    let longest = rows.iter().copied().max().unwrap_or(0);
    for y in 0..longest {
        let mut fwd = [true; N];
        for s in (0..N).filter(|&s| y < rows[s]) {
            let (b, t) = (&mut bands[s], &mut st[s]);
            let w = t.idx.len();
            b.input.row(y, b.grey, &mut t.lin);
            fwd[s] = !b.serpentine || (b.y0 + y).is_multiple_of(2);
            for (c, (base, lin)) in t.base.iter_mut().zip(&t.lin).enumerate() {
                for ((s, l), e) in base[..w].iter_mut().zip(lin).zip(&b.err[..w]) {
                    *s = l + e[c];
                }
                if !fwd[s] {
                    base[..w].reverse();
                }
            }
        }
        if N == 2 && y < rows[0] && y < rows[1] {
            let [t0, t1] = &mut st[..] else {
                unreachable!()
            };
            let [b0, b1] = &mut bands[..] else {
                unreachable!()
            };
            row(
                &k,
                table,
                b0.wt,
                [&t0.base, &t1.base],
                [fwd[0], fwd[N - 1]],
                f,
                m,
                [b0.entry, b1.entry],
                [&mut t0.idx, &mut t1.idx],
                [&mut b0.below[..], &mut b1.below[..]],
            );
        } else {
            for s in (0..N).filter(|&s| y < rows[s]) {
                let (b, t) = (&mut bands[s], &mut st[s]);
                row(
                    &k,
                    table,
                    b.wt,
                    [&t.base],
                    [fwd[s]],
                    f,
                    m,
                    [b.entry],
                    [&mut t.idx],
                    [&mut b.below[..]],
                );
            }
        }
        for s in (0..N).filter(|&s| y < rows[s]) {
            let (b, t) = (&mut bands[s], &st[s]);
            std::mem::swap(b.err, b.below);
            if y >= b.skip {
                b.out.put(y - b.skip, &t.idx);
            }
        }
    }
}

/// `v` clamped as the reference clamps it (−1..=2; values are never NaN).
#[inline(always)]
unsafe fn clamp(v: __m256) -> __m256 {
    _mm256_min_ps(_mm256_max_ps(v, _mm256_set1_ps(-1.0)), _mm256_set1_ps(2.0))
}

/// LMS of linear RGB, lane by lane, as [`super::fast::lms_of`] computes it.
#[inline(always)]
unsafe fn lms(v: [__m256; 3]) -> [__m256; 3] {
    let row = |r: [f32; 3]| {
        _mm256_add_ps(
            _mm256_add_ps(
                _mm256_mul_ps(_mm256_set1_ps(r[0]), v[0]),
                _mm256_mul_ps(_mm256_set1_ps(r[1]), v[1]),
            ),
            _mm256_mul_ps(_mm256_set1_ps(r[2]), v[2]),
        )
    };
    [row(OKLAB_M1[0]), row(OKLAB_M1[1]), row(OKLAB_M1[2])]
}

/// The table's cube root of `t` (every lane the same value), broadcast.
#[inline(always)]
unsafe fn cbrt(table: &[[f32; 2]], t: __m256) -> __m256 {
    let key = bits(_mm256_castps256_ps128(t)) >> KEY_SHIFT;
    // SAFETY: the table has an entry for every 16-bit key.
    let [a, s] = *table.get_unchecked(key as usize);
    _mm256_fmadd_ps(_mm256_set1_ps(s), t, _mm256_set1_ps(a))
}

/// The bits of lane 0 (`vmovd`: the compiler's own choice, `vextractps`, takes two
/// micro-operations).
#[inline(always)]
unsafe fn bits(v: __m128) -> u32 {
    let r: u32;
    std::arch::asm!("vmovd {0:e}, {1}", out(reg) r, in(xmm_reg) v, options(pure, nomem, nostack));
    r
}

#[inline(always)]
fn load(a: &[f32; 8]) -> __m256 {
    // SAFETY: 8 floats; unaligned load.
    unsafe { _mm256_loadu_ps(a.as_ptr()) }
}

/// Lane 0 of a vector.
#[inline(always)]
unsafe fn first(v: __m256) -> f32 {
    _mm_cvtss_f32(_mm256_castps256_ps128(v))
}

/// One row in scan order of each of `N` bands, a pixel of each in turn: `base` the row's
/// input plus error, `idx` written at page columns.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
unsafe fn row<const N: usize>(
    k: &Consts,
    table: &[[f32; 2]],
    wt: super::fs::FsWeights,
    base: [&[Vec<f32>; 3]; N],
    fwd: [bool; N],
    f: &FastNearest,
    m: &PaletteMatcher,
    entry: [&[u8]; N],
    idx: [&mut [u8]; N],
    below: [&mut [[f32; 3]]; N],
) {
    let (behind, under, ahead) = (
        _mm_set1_ps(wt.behind),
        _mm_set1_ps(wt.under),
        _mm_set1_ps(wt.ahead),
    );
    let mut here = [_mm_setzero_ps(); N];
    let mut next = [_mm_setzero_ps(); N];
    let mut prev: [Option<usize>; N] = [None; N];
    let w = idx[0].len();
    let q = [load(&k.q[0]), load(&k.q[1]), load(&k.q[2])];
    let right = _mm256_set1_ps(wt.right);
    let (c0, gl) = (load(&k.c), load(&k.gl));
    let hp = [load(&k.hp[0]), load(&k.hp[1]), load(&k.hp[2])];
    let lrow = OKLAB_M2[0].map(|v| _mm256_set1_ps(v));
    let low3 = _mm256_set1_epi32(!7);
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let near = _mm256_set1_ps(MARGIN + SLACK);
    // The first pixel has no carry: its value in every lane.
    let mut cv: [[__m256; 3]; N] = std::array::from_fn(|s| {
        std::array::from_fn(|c| {
            clamp(_mm256_add_ps(
                _mm256_set1_ps(base[s][c][0]),
                _mm256_setzero_ps(),
            ))
        })
    });
    let mut cl: [[__m256; 3]; N] = std::array::from_fn(|s| lms(cv[s]));
    let mut pick = [_mm256_setzero_si256(); N];
    for i in 0..w {
        for s in 0..N {
            let x = if fwd[s] { i } else { w - 1 - i };
            // This pixel's value and LMS: the lane of the previous pixel's answer.
            let v: [__m256; 3] =
                std::array::from_fn(|c| _mm256_permutevar8x32_ps(cv[s][c], pick[s]));
            let t: [__m256; 3] =
                std::array::from_fn(|c| _mm256_permutevar8x32_ps(cl[s][c], pick[s]));
            // Off the chain: the error for each answer, and the next pixel's value and LMS.
            let e: [__m256; 3] = std::array::from_fn(|c| _mm256_sub_ps(v[c], q[c]));
            cv[s] = std::array::from_fn(|c| {
                // SAFETY: base has w + 1 entries; i + 1 <= w.
                let bn = _mm256_set1_ps(*base[s][c].get_unchecked(i + 1));
                clamp(_mm256_add_ps(bn, _mm256_mul_ps(e[c], right)))
            });
            cl[s] = lms(cv[s]);
            // On the chain: cube roots, scores, the lowest.
            let xr = [cbrt(table, t[0]), cbrt(table, t[1]), cbrt(table, t[2])];
            let l = _mm256_fmadd_ps(
                lrow[2],
                xr[2],
                _mm256_fmadd_ps(lrow[1], xr[1], _mm256_mul_ps(lrow[0], xr[0])),
            );
            let lm = _mm256_min_ps(l, _mm256_set1_ps(1.0));
            let pos = _mm256_cmp_ps_mask::<_CMP_GT_OQ>(l, _mm256_setzero_ps());
            let sp = _mm256_add_ps(
                _mm256_fmadd_ps(hp[2], xr[2], c0),
                _mm256_fmadd_ps(hp[1], xr[1], _mm256_mul_ps(hp[0], xr[0])),
            );
            let sc = _mm256_mask3_fmadd_ps(gl, lm, sp, pos);
            let si = _mm256_ternarylogic_epi32::<0xEA>(_mm256_castps_si256(sc), low3, lanes);
            let mut lo = _mm256_min_epi32(si, _mm256_permute2x128_si256::<1>(si, si));
            lo = _mm256_min_epi32(lo, _mm256_shuffle_epi32::<0x4E>(lo));
            lo = _mm256_min_epi32(lo, _mm256_shuffle_epi32::<0xB1>(lo));
            // Checked: the lowest alone within the margin, and all scores positive (so that
            // the bits order them as numbers) with the lowest below 16.
            let within =
                _mm256_cmp_ps_mask::<_CMP_LE_OQ>(sc, _mm256_add_ps(_mm256_castsi256_ps(lo), near));
            let lowest = _mm_cvtsi128_si32(_mm256_castsi256_si128(lo));
            let lane =
                if within & within.wrapping_sub(1) == 0 && lowest > 0 && lowest < LOWEST_BELOW {
                    pick[s] = lo;
                    (lowest & 7) as usize
                } else {
                    let lane = slow(f, m, [first(v[0]), first(v[1]), first(v[2])]);
                    pick[s] = _mm256_set1_epi32(lane as i32);
                    lane
                };
            *idx[s].get_unchecked_mut(x) = *entry[s].get_unchecked(lane);
            // The error this pixel passes on, and the row below.
            let vx = _mm_blend_ps::<0b100>(
                _mm_blend_ps::<0b010>(_mm256_castps256_ps128(v[0]), _mm256_castps256_ps128(v[1])),
                _mm256_castps256_ps128(v[2]),
            );
            let e = _mm_sub_ps(vx, _mm_loadu_ps(k.q4[lane].as_ptr()));
            let done = _mm_add_ps(here[s], _mm_mul_ps(behind, e));
            here[s] = _mm_add_ps(next[s], _mm_mul_ps(under, e));
            next[s] = _mm_add_ps(_mm_setzero_ps(), _mm_mul_ps(ahead, e));
            if let Some(p) = prev[s] {
                // SAFETY: p < w = below.len(); three floats written.
                _mm_mask_storeu_ps(below[s].as_mut_ptr().add(p) as *mut f32, 0b111, done);
            }
            prev[s] = Some(x);
        }
    }
    for s in 0..N {
        if let Some(p) = prev[s] {
            let mut last = [0f32; 4];
            _mm_storeu_ps(last.as_mut_ptr(), here[s]);
            below[s][p] = [last[0], last[1], last[2]];
        }
    }
}

/// The answer where the scores are too close to call: the exact search (FastNearest's own
/// check, with its table roots, almost never settles these: it did for 1.6% of them on the
/// benchmark photo).
#[cold]
#[inline(never)]
fn slow(f: &FastNearest, m: &PaletteMatcher, v: [f32; 3]) -> usize {
    f.lane_of(m.nearest(v))
}
