//! The nearest palette colour in Oklab, fast, with the exact search's own answer.
//!
//! Palette diffusion asks, for every pixel, which palette entry is nearest in Oklab to a
//! linear-RGB value (input plus carried error, clamped to −1..=2 per channel). The exact
//! search ([`PaletteMatcher::nearest`]) converts the value to Oklab with three `cbrtf` calls
//! and measures every entry, one after the other; each pixel's answer feeds the next pixel's
//! error, so the search's whole latency is paid at every pixel.
//!
//! Here the same question is answered with less latency:
//!
//! - The LMS values are computed exactly as the exact search computes them (the same `f32`
//!   operations in the same order), so both start from the same numbers; near zero the cube
//!   root magnifies any difference there.
//! - Their cube roots come from a table indexed by the top 16 bits of the `f32` (sign,
//!   exponent, 7 mantissa bits), the chord across the step: off by at most
//!   [`CBRT_ERROR`] (checked over every step by a test).
//! - Oklab `p = M₂·x` follows, with `L` clamped to 0..=1 as the `palette` crate clamps it,
//!   and every entry's squared distance, less the common `|p|²`, is one linear form:
//!   `s_k = |q_k|² − 2 p·q_k`. All entries are scored at once (the lanes of a vector).
//! - The lowest score wins **only when every other score is more than [`MARGIN`] above it**.
//!   Otherwise ([`FastNearest::nearest`] returns `None`) the caller runs the exact search.
//!
//! Why the answer is the exact search's: let `p*` be Oklab of the exact cube roots of the
//! shared LMS values (L clamped) and `D_k = |p* − q_k|²`. The exact search's `f32` distances
//! are within `E_ref` of `D_k` (its `cbrtf` is good to an ulp, and a handful of roundings on
//! values below 10 follow: `E_ref` < 2.5·10⁻⁴ even for `|p − q|` near its largest, about 9).
//! The scores here are within `E_fast` of `D_k − |p*|²` (the table's error through the Oklab
//! matrix, the `L` clamp being 1-Lipschitz, and the roundings of the score: `E_fast` <
//! 10⁻⁴). When `s_j − s_b > MARGIN ≥ 2·(E_ref + E_fast)` for every `j ≠ b`, then
//! `D_j − D_b > 2·E_ref`, so the exact search finds `b` strictly nearest too. Entries of
//! identical colour are scored once (the exact search keeps the first of them).

use crate::color::{Palette, PaletteMatcher};
use crate::color::{OKLAB_M1, OKLAB_M2};
use crate::fmath as fm;

/// `f32` bits dropped to make a cube-root table key (keeps sign, exponent and 7 mantissa
/// bits).
pub(crate) const KEY_SHIFT: u32 = 16;
/// Largest error of the table's cube root, absolute, over −4..=4 (LMS values lie within
/// −2..=2 after the clamp). The test `cube_root_table_error` measures the largest actual
/// error (about 2·10⁻⁶) and checks it stays below this.
#[cfg_attr(not(test), allow(dead_code))]
pub const CBRT_ERROR: f32 = 4e-6;
/// How much lower (in squared Oklab distance) the winning score must be than every other
/// for the answer to be taken without the exact search; see the module docs for the bound
/// it covers with room to spare.
pub const MARGIN: f32 = 1e-3;
/// Score of an unused lane: never within [`MARGIN`] of a real one.
const UNUSED: f32 = 1e30;
/// Most distinct colours served (lanes); larger palettes use the exact search.
pub const MAX_LANES: usize = 64;

/// A palette prepared for the fast search.
pub struct FastNearest {
    /// Lanes in use rounded up to a vector size (8, 16, 32 or 64).
    lanes: usize,
    /// Lanes in use (distinct colours).
    used: usize,
    /// Per lane: `|q|²`, and `−2·q` for `L`, `a` and `b` (unused lanes: [`UNUSED`], 0).
    c: [f32; MAX_LANES],
    g: [[f32; MAX_LANES]; 3],
    /// Palette index of each lane.
    entry: [u8; MAX_LANES],
    /// Lane of each palette index (identical colours share the lane of the first).
    lane_of: Vec<u8>,
    /// Cube root by key: the intercept and slope of the chord across the step.
    cbrt: &'static [[f32; 2]],
}

impl FastNearest {
    /// The fast search for `palette` (as `matcher` converts it); `None` when it has more
    /// than [`MAX_LANES`] distinct colours.
    pub fn new(palette: &Palette, matcher: &PaletteMatcher) -> Option<FastNearest> {
        let mut entries: Vec<usize> = Vec::new();
        for (i, c) in palette.colours.iter().enumerate() {
            // The exact search keeps the first of identical colours.
            if !entries.iter().any(|&j| palette.colours[j] == *c) {
                entries.push(i);
            }
        }
        if entries.len() > MAX_LANES {
            return None;
        }
        let lanes = entries.len().next_power_of_two().max(8);
        let mut f = FastNearest {
            lanes,
            used: entries.len(),
            c: [UNUSED; MAX_LANES],
            g: [[0.0; MAX_LANES]; 3],
            entry: [0; MAX_LANES],
            lane_of: vec![0; palette.len()],
            cbrt: cube_root_table(),
        };
        for (lane, &i) in entries.iter().enumerate() {
            let q = crate::color::oklab_of_linear(matcher.linear(i));
            f.c[lane] = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
            for (g, q) in f.g.iter_mut().zip(q) {
                g[lane] = -2.0 * q;
            }
            f.entry[lane] = i as u8;
            for (k, c) in palette.colours.iter().enumerate() {
                if *c == palette.colours[i] {
                    f.lane_of[k] = lane as u8;
                }
            }
        }
        Some(f)
    }

    /// Lanes scored per pixel (8, 16, 32 or 64): the `N` to call [`Self::nearest`] with.
    pub fn lanes(&self) -> usize {
        self.lanes
    }

    /// Lanes in use: the palette's distinct colours.
    pub fn colours(&self) -> usize {
        self.used
    }

    /// Cube root from the table (within [`CBRT_ERROR`] for |t| ≤ 4).
    #[inline(always)]
    fn cbrt(&self, t: f32) -> f32 {
        let [a, s] = self.cbrt[(t.to_bits() >> KEY_SHIFT) as usize];
        s * t + a
    }

    /// A lane's score terms: `|q|²` and `−2·q` (unused lanes: a score never near a real one,
    /// and zeros).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn lane_terms(&self, lane: usize) -> (f32, [f32; 3]) {
        (
            self.c[lane],
            [self.g[0][lane], self.g[1][lane], self.g[2][lane]],
        )
    }

    /// The cube-root table: the intercept and slope of each key's chord (`s·t + a`).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn cbrt_table(&self) -> &'static [[f32; 2]] {
        self.cbrt
    }

    /// Palette index of a lane.
    #[inline(always)]
    pub fn entry(&self, lane: usize) -> usize {
        self.entry[lane] as usize
    }

    /// Lane of a palette index (the exact search's answer as a lane).
    #[inline(always)]
    pub fn lane_of(&self, entry: usize) -> usize {
        self.lane_of[entry] as usize
    }

    /// The lane of the entry nearest in Oklab to `rgb` (each channel within −1..=2) when it
    /// is provably the exact search's answer, else `None`. `N` must be [`Self::lanes`].
    #[inline(always)]
    pub fn nearest<const N: usize>(&self, rgb: [f32; 3]) -> Option<usize> {
        self.nearest_lms::<N>(lms_of(rgb))
    }

    /// [`Self::nearest`] of the colour whose [`lms_of`] is `lms`.
    #[inline(always)]
    pub fn nearest_lms<const N: usize>(&self, lms: [f32; 3]) -> Option<usize> {
        debug_assert_eq!(N, self.lanes);
        let x = lms.map(|t| self.cbrt(t));
        let ok_l = (OKLAB_M2[0][0] * x[0] + OKLAB_M2[0][1] * x[1]) + OKLAB_M2[0][2] * x[2];
        let ok_a = (OKLAB_M2[1][0] * x[0] + OKLAB_M2[1][1] * x[1]) + OKLAB_M2[1][2] * x[2];
        let ok_b = (OKLAB_M2[2][0] * x[0] + OKLAB_M2[2][1] * x[1]) + OKLAB_M2[2][2] * x[2];
        // The lowest lane, and every lane within the margin of it: the answer stands when
        // that is the lowest lane alone (tested apart from the index, which the next pixel
        // waits for).
        let (lowest, near) = self.lowest::<N>([ok_l.clamp(0.0, 1.0), ok_a, ok_b]);
        if near & near.wrapping_sub(1) == 0 && near != 0 {
            Some(lowest.trailing_zeros() as usize & (MAX_LANES - 1))
        } else {
            None
        }
    }

    /// Lanes whose score is the lowest, and lanes within [`MARGIN`] of it, as bits.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn lowest<const N: usize>(&self, p: [f32; 3]) -> (u64, u64) {
        use std::arch::x86_64::*;
        // SAFETY: SSE is part of x86_64; every load reads 4 lanes at k < N ≤ MAX_LANES, a
        // multiple of 4, from arrays of MAX_LANES.
        unsafe {
            let ps = p.map(|v| _mm_set1_ps(v));
            let mut score = [_mm_setzero_ps(); MAX_LANES / 4];
            let mut best = _mm_set1_ps(UNUSED);
            for (v, k) in score.iter_mut().take(N / 4).zip((0..N).step_by(4)) {
                let at = |a: &[f32; MAX_LANES]| _mm_loadu_ps(a.as_ptr().add(k));
                *v = _mm_add_ps(
                    _mm_add_ps(at(&self.c), _mm_mul_ps(at(&self.g[0]), ps[0])),
                    _mm_add_ps(
                        _mm_mul_ps(at(&self.g[1]), ps[1]),
                        _mm_mul_ps(at(&self.g[2]), ps[2]),
                    ),
                );
                best = _mm_min_ps(best, *v);
            }
            best = _mm_min_ps(best, _mm_shuffle_ps::<0b01_00_11_10>(best, best));
            best = _mm_min_ps(best, _mm_shuffle_ps::<0b10_11_00_01>(best, best));
            let limit = _mm_add_ps(best, _mm_set1_ps(MARGIN));
            let (mut lowest, mut near) = (0u64, 0u64);
            for (i, v) in score.iter().take(N / 4).enumerate() {
                lowest |= (_mm_movemask_ps(_mm_cmpeq_ps(*v, best)) as u64) << (4 * i);
                near |= (_mm_movemask_ps(_mm_cmple_ps(*v, limit)) as u64) << (4 * i);
            }
            (lowest, near)
        }
    }

    /// Lanes whose score is the lowest, and lanes within [`MARGIN`] of it, as bits.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn lowest<const N: usize>(&self, p: [f32; 3]) -> (u64, u64) {
        let mut score = [0f32; N];
        for (k, s) in score.iter_mut().enumerate() {
            *s = (self.c[k] + self.g[0][k] * p[0]) + (self.g[1][k] * p[1] + self.g[2][k] * p[2]);
        }
        let best = score.iter().fold(UNUSED, |b, &v| if v < b { v } else { b });
        let limit = best + MARGIN;
        let (mut lowest, mut near) = (0u64, 0u64);
        for (k, &v) in score.iter().enumerate() {
            lowest |= ((v == best) as u64) << k;
            near |= ((v <= limit) as u64) << k;
        }
        (lowest, near)
    }
}

/// LMS of a linear-RGB colour exactly as the exact search computes it, operation for
/// operation (the `palette` crate's `linear_srgb_to_oklab`).
#[inline(always)]
pub fn lms_of([r, g, b]: [f32; 3]) -> [f32; 3] {
    [
        OKLAB_M1[0][0] * r + OKLAB_M1[0][1] * g + OKLAB_M1[0][2] * b,
        OKLAB_M1[1][0] * r + OKLAB_M1[1][1] * g + OKLAB_M1[1][2] * b,
        OKLAB_M1[2][0] * r + OKLAB_M1[2][1] * g + OKLAB_M1[2][2] * b,
    ]
}

/// The cube root of every key's step as the chord from the step's start (the key's bits with
/// the low bits zero) to the next step's start, `s·t + a`: intercept `a` and slope `s`, for
/// |t| ≤ 4; zero elsewhere. The intercept form needs no start to subtract (one `FMA` in
/// the vector loop); `a` and `s·t` are each within a small multiple of the root itself, so
/// the two roundings stay near an ulp of it. Built once a process (512 KiB), shared by
/// every page and palette.
fn cube_root_table() -> &'static [[f32; 2]] {
    static TABLE: std::sync::OnceLock<Box<[[f32; 2]]>> = std::sync::OnceLock::new();
    TABLE.get_or_init(build_cube_root_table)
}

fn build_cube_root_table() -> Box<[[f32; 2]]> {
    let mut t = vec![[0f32; 2]; 1 << (32 - KEY_SHIFT)];
    for (key, e) in t.iter_mut().enumerate() {
        let a = f32::from_bits((key as u32) << KEY_SHIFT);
        let b = f32::from_bits(((key as u32) + 1) << KEY_SHIFT);
        if !(a.abs() <= 4.0 && b.is_finite()) || a.is_sign_negative() != b.is_sign_negative() {
            continue;
        }
        let (a, b) = (a as f64, b as f64);
        let slope = (fm::cbrt(b) - fm::cbrt(a)) / (b - a);
        *e = [(fm::cbrt(a) - slope * a) as f32, slope as f32];
    }
    t.into_boxed_slice()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table's cube root against f64's over every step in −4..=4: 33 points a step and
    /// both ends. The chord of a concave (or convex) arc is furthest from it inside the step,
    /// and 33 points see that furthest point to well under the bound's margin.
    #[test]
    fn cube_root_table_error() {
        let p = Palette::builtin("rgb-8").unwrap();
        let f = FastNearest::new(&p, &PaletteMatcher::new(&p)).unwrap();
        let mut worst = 0f64;
        for key in 0u32..1 << (32 - KEY_SHIFT) {
            let a = f32::from_bits(key << KEY_SHIFT);
            if a.is_nan() || a.abs() > 4.0 {
                continue;
            }
            let last = f32::from_bits((key << KEY_SHIFT) | ((1 << KEY_SHIFT) - 1));
            for i in 0..=33u32 {
                let t = if i == 33 {
                    last
                } else {
                    f32::from_bits((key << KEY_SHIFT) | (i * ((1 << KEY_SHIFT) - 1) / 32))
                };
                let err = (f.cbrt(t) as f64 - fm::cbrt(t as f64)).abs();
                worst = worst.max(err);
            }
        }
        assert!(worst < CBRT_ERROR as f64, "worst {worst:e}");
        assert!(worst > 0.0);
    }

    /// A small deterministic generator (xorshift), uniform in 0..1.
    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn check<const N: usize>(f: &FastNearest, m: &PaletteMatcher, v: [f32; 3]) -> bool {
        match f.nearest::<N>(v) {
            Some(lane) => {
                assert_eq!(f.entry(lane), m.nearest(v), "at {v:?}");
                assert_eq!(f.lane_of(f.entry(lane)), lane);
                true
            }
            None => false,
        }
    }

    /// Wherever the fast search answers, it answers as the exact search does; and it answers
    /// nearly everywhere for a small palette.
    #[test]
    fn same_answer_as_the_exact_search() {
        let mut next = rng(1);
        let mut palettes: Vec<Palette> = Palette::builtin_names()
            .map(|n| Palette::builtin(n).unwrap())
            .collect();
        for n in [2usize, 3, 5, 9, 16, 40, 64] {
            let colours = (0..n)
                .map(|_| std::array::from_fn(|_| (next() * 256.0) as u8))
                .collect();
            palettes.push(Palette::new("random", colours).unwrap());
        }
        palettes.push(
            Palette::new(
                "dups",
                vec![
                    [0, 0, 0],
                    [255, 255, 255],
                    [0, 0, 0],
                    [128, 0, 0],
                    [128, 0, 1],
                ],
            )
            .unwrap(),
        );
        for p in &palettes {
            let m = PaletteMatcher::new(p);
            let f = FastNearest::new(p, &m).unwrap();
            let mut answered = 0;
            let total = 200_000;
            for i in 0..total {
                // Mostly in 0..1 (where pixels are), some across the whole clamped range,
                // some on exact fractions, dark and slightly negative values (where the cube
                // root is steepest), and values whose LMS is zero or nearly.
                let v: [f32; 3] = match i % 6 {
                    0 => std::array::from_fn(|_| next() * 3.0 - 1.0),
                    1 => std::array::from_fn(|_| (next() * 96.0).floor() / 32.0 - 1.0),
                    2 => std::array::from_fn(|_| (next() - 0.3) * next().powi(4)),
                    3 => {
                        let t = (next() - 0.5) * 1e-3;
                        [t, t, t]
                    }
                    _ => std::array::from_fn(|_| next() * 1.2 - 0.1),
                };
                let hit = match f.lanes() {
                    8 => check::<8>(&f, &m, v),
                    16 => check::<16>(&f, &m, v),
                    32 => check::<32>(&f, &m, v),
                    _ => check::<64>(&f, &m, v),
                };
                answered += hit as usize;
            }
            if p.len() <= 16 && p.name != "dups" {
                assert!(answered * 100 > total * 95, "{}: {answered}", p.name);
            }
        }
    }

    /// Too many colours: no fast search (the caller keeps the exact one).
    #[test]
    fn large_palettes_are_left_to_the_exact_search() {
        let colours: Vec<[u8; 3]> = (0..65u32).map(|i| [i as u8, 0, 255 - i as u8]).collect();
        let p = Palette::new("big", colours).unwrap();
        assert!(FastNearest::new(&p, &PaletteMatcher::new(&p)).is_none());
    }
}
