//! The nearest palette colour through a lookup table, with the same answer as the exact search.
//!
//! Palette diffusion asks, for every pixel, which palette entry is nearest in Oklab to a
//! linear-RGB value (input plus carried error, clamped to −1..=2 per channel). The exact
//! search ([`PaletteMatcher::nearest`]) converts the value to Oklab (three cube roots) and
//! measures every entry: most of the method's time.
//!
//! Here linear RGB −1..=2 is cut into a grid of boxes, classified the first time a value falls
//! in one: a box is *decided* when one entry is nearest in Oklab for every point of it, with a
//! margin far larger than the rounding of the exact search's `f32` arithmetic; otherwise it is
//! *ambiguous* and values in it go to the exact search. So the answer is always the exact
//! search's own answer: in a decided box that search could not return anything else.
//!
//! The grid is even in the cube root of each channel (signed), [`STEPS_PER_UNIT`] steps to a
//! unit, because Oklab takes cube roots: boxes are then of about one size in Oklab, and dark
//! colours (where an even linear grid is far too coarse) are as well served as light ones. No
//! cube root is taken per pixel: a channel's box is read from a table indexed by the top 17
//! bits of the `f32` (sign, exponent, 8 bits of mantissa), and every box boundary is such a
//! value, so a box's bounds are exact.
//!
//! The proof for a box: Oklab is `lab = M₂ · ∛(M₁ · rgb)` (Ottosson 2020, the matrices the
//! `palette` crate uses for linear sRGB), with `L` then clamped to 0..=1 by that crate (`a` and
//! `b` are not clamped). `M₁` has only positive entries, so the box maps into the box
//! `[∛(M₁·lo), ∛(M₁·hi)]` in cube-root LMS space (the cube root rises). For entries `i` and
//! `j`, `|p − qⱼ|² − |p − qᵢ|² = 2 p·(qᵢ − qⱼ) + |qⱼ|² − |qᵢ|²` is linear in `p`. While `L`
//! is not clamped anywhere in the box, it is linear in the cube-root LMS point `x` (`p = M₂ x`)
//! and its minimum over the box is taken coordinate by coordinate at a corner. Where one clamp
//! of `L` is active, the function is bounded below by one that is concave in `x` (see
//! [`one_sided_clamp`]), whose minimum is at one of the box's eight corners; where both are
//! (never in a small box), the three terms are bounded separately over their ranges. When the minimum exceeds [`MARGIN`] for every other entry `j`, `i` is the
//! nearest everywhere in the box.

use crate::color::{oklab_of_linear, Palette, PaletteMatcher};

/// Grid steps per unit of the signed cube root of a channel (fine steps; a box is
/// [`SUB`] fine steps on a side, and an ambiguous box is cut into SUB³ small boxes).
const STEPS_PER_UNIT: f64 = 256.0;
/// Fine steps along each side of a box.
const SUB: usize = 4;
/// Lowest and highest channel value (the diffusion clamps every channel to −1..=2).
const LOW: f64 = -1.0;
const HIGH: f64 = 2.0;
/// `f32` bits dropped to make a channel's table key (keeps sign, exponent, 8 mantissa bits).
const KEY_SHIFT: u32 = 15;
/// Box (or small box) not yet classified (zero, so the tables start as untouched pages).
const UNKNOWN: u16 = 0;
/// Small box where no single entry is provably nearest.
const AMBIGUOUS: u8 = 1;
/// Codes of decided boxes and small boxes: entry + 2.
const FIRST_ENTRY: u8 = 2;
/// Box codes from here on point at a block of small boxes.
const BLOCK: u16 = 256;
/// Box code of an ambiguous box once every block code is in use: the exact search serves it.
const NO_BLOCK: u16 = AMBIGUOUS as u16;
/// Boxes side by side in memory along each axis: a tile of TILE³ boxes is two cache lines,
/// so values that wander a little (as error diffusion's do) stay in a few lines.
const TILE: usize = 4;
/// Largest palette served by the table.
pub const MAX_ENTRIES: usize = 254;
/// How much further (squared Oklab distance) every other entry must be. The exact search's
/// `f32` distances are off by a few times 10⁻⁷ at most (values near 1, a handful of
/// roundings, cube roots good to an ulp); this is a hundred times that.
const MARGIN: f64 = 1e-4;

/// Ottosson's linear sRGB → LMS matrix (as in the `palette` crate).
const M1: [[f64; 3]; 3] = [
    [0.4122214708, 0.5363325363, 0.0514459929],
    [0.2119034982, 0.6806995451, 0.1073969566],
    [0.0883024619, 0.2817188376, 0.6299787005],
];
/// Ottosson's cube-root LMS → Oklab matrix.
const M2: [[f64; 3]; 3] = [
    [0.2104542553, 0.7936177850, -0.0040720468],
    [1.9779984951, -2.4285922050, 0.4505937099],
    [0.0259040371, 0.7827717662, -0.8086757660],
];

/// The grid along one channel: the step of every `f32` key, and each step's value range.
struct Axis {
    step_of_key: Vec<u16>,
    /// Lowest and highest value of each step (inclusive).
    bounds: Vec<(f64, f64)>,
}

impl Axis {
    fn new() -> Axis {
        let cbrt_low = LOW.cbrt();
        let steps = ((HIGH.cbrt() - cbrt_low) * STEPS_PER_UNIT).ceil() as usize;
        let steps = steps.next_multiple_of(SUB);
        let mut step_of_key = vec![0u16; 1 << (32 - KEY_SHIFT)];
        let mut bounds = vec![(f64::INFINITY, f64::NEG_INFINITY); steps];
        for (key, step) in step_of_key.iter_mut().enumerate() {
            let first = f32::from_bits((key as u32) << KEY_SHIFT) as f64;
            let last = f32::from_bits(((key as u32) << KEY_SHIFT) | ((1 << KEY_SHIFT) - 1)) as f64;
            let (a, b) = (first.min(last), first.max(last));
            if !(a <= HIGH && b >= LOW) {
                // Outside −1..=2 (or not a number): never looked up.
                continue;
            }
            let s = ((a.max(LOW).cbrt() - cbrt_low) * STEPS_PER_UNIT) as usize;
            let s = s.min(steps - 1);
            *step = s as u16;
            let bound = &mut bounds[s];
            *bound = (bound.0.min(a.max(LOW)), bound.1.max(b.min(HIGH)));
        }
        // A step no key falls in (none here, but keep the bounds well formed).
        for i in 1..steps {
            if bounds[i].0 > bounds[i].1 {
                bounds[i] = (bounds[i - 1].1, bounds[i - 1].1);
            }
        }
        Axis {
            step_of_key,
            bounds,
        }
    }

    /// Value range of fine steps `first..first + n`.
    fn range(&self, first: usize, n: usize) -> (f64, f64) {
        self.bounds[first..first + n]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(c, d)| {
                (a.min(c), b.max(d))
            })
    }

    #[inline(always)]
    fn step(&self, v: f32) -> usize {
        self.step_of_key[(v.to_bits() >> KEY_SHIFT) as usize] as usize
    }
}

/// A lazily filled nearest-colour table over one palette.
pub struct NearestLut<'m> {
    matcher: &'m PaletteMatcher,
    /// Palette colours, for ties between identical entries.
    srgb: Vec<[u8; 3]>,
    /// Entries in Oklab, in `f64`.
    oklab: Vec<[f64; 3]>,
    axis: Axis,
    /// Boxes along an axis.
    side: usize,
    /// One code a box, in tiles of TILE³: [`UNKNOWN`], [`FIRST_ENTRY`] + entry, [`NO_BLOCK`],
    /// or [`BLOCK`] + block index.
    boxes: Vec<u16>,
    /// Small boxes of ambiguous boxes, SUB³ a block: 0 (unknown), [`AMBIGUOUS`] or
    /// [`FIRST_ENTRY`] + entry.
    blocks: Vec<[u8; SUB * SUB * SUB]>,
}

impl<'m> NearestLut<'m> {
    /// A table for `palette` (matched by `matcher`); `None` when the palette has more than
    /// [`MAX_ENTRIES`] colours.
    pub fn new(palette: &Palette, matcher: &'m PaletteMatcher) -> Option<NearestLut<'m>> {
        if palette.len() > MAX_ENTRIES {
            return None;
        }
        let oklab = (0..palette.len())
            .map(|i| oklab_of_linear(matcher.linear(i)).map(f64::from))
            .collect();
        let axis = Axis::new();
        let side = (axis.bounds.len() / SUB).next_multiple_of(TILE);
        Some(NearestLut {
            matcher,
            srgb: palette.colours.clone(),
            oklab,
            axis,
            side,
            // Zeroed memory: pages are only touched where values fall.
            boxes: zeroed_huge(side * side * side),
            blocks: Vec::new(),
        })
    }

    /// Index of the entry nearest in Oklab to `rgb` (each channel within −1..=2): exactly
    /// [`PaletteMatcher::nearest`].
    #[inline]
    pub fn nearest(&mut self, rgb: [f32; 3]) -> usize {
        debug_assert!(rgb.iter().all(|v| (-1.0..=2.0).contains(v)));
        let fine = rgb.map(|v| self.axis.step(v));
        let at = fine.map(|f| f / SUB);
        let b = self.box_index(at);
        let mut code = self.boxes[b];
        if code == UNKNOWN {
            code = match self.classify(at.map(|a| a * SUB), SUB) {
                Some(i) => (i as u8 + FIRST_ENTRY) as u16,
                None if self.blocks.len() < (u16::MAX - BLOCK) as usize => {
                    self.blocks.push([UNKNOWN as u8; SUB * SUB * SUB]);
                    BLOCK + (self.blocks.len() - 1) as u16
                }
                None => NO_BLOCK,
            };
            self.boxes[b] = code;
        }
        if code == NO_BLOCK {
            return self.matcher.nearest(rgb);
        }
        if code < BLOCK {
            return code as usize - FIRST_ENTRY as usize;
        }
        let s = fine.map(|f| f % SUB);
        let small = (s[0] * SUB + s[1]) * SUB + s[2];
        let block = (code - BLOCK) as usize;
        let mut c = self.blocks[block][small];
        if c == UNKNOWN as u8 {
            c = self
                .classify(fine, 1)
                .map_or(AMBIGUOUS, |i| i as u8 + FIRST_ENTRY);
            self.blocks[block][small] = c;
        }
        if c == AMBIGUOUS {
            self.matcher.nearest(rgb)
        } else {
            (c - FIRST_ENTRY) as usize
        }
    }

    /// Share of the space (in small boxes) classified so far that is decided (for
    /// measurements and tests).
    pub fn decided_share(&self) -> f64 {
        let whole = (SUB * SUB * SUB) as f64;
        let (mut seen, mut decided) = (0.0, 0.0);
        for &c in &self.boxes {
            if c == UNKNOWN {
                continue;
            }
            if c == NO_BLOCK {
                seen += whole;
            } else if c < BLOCK {
                seen += whole;
                decided += whole;
            } else {
                for &s in &self.blocks[(c - BLOCK) as usize] {
                    if s != UNKNOWN as u8 {
                        seen += 1.0;
                        decided += (s != AMBIGUOUS) as u8 as f64;
                    }
                }
            }
        }
        if seen == 0.0 {
            1.0
        } else {
            decided / seen
        }
    }

    /// Where the code of the box at `at` lives: tile by tile, then within the tile.
    #[inline(always)]
    fn box_index(&self, at: [usize; 3]) -> usize {
        let tiles = self.side / TILE;
        let t = at.map(|a| a / TILE);
        let i = at.map(|a| a % TILE);
        (((t[0] * tiles + t[1]) * tiles + t[2]) * TILE + i[0]) * TILE * TILE + i[1] * TILE + i[2]
    }

    /// The entry nearest everywhere in the box of `n` fine steps a side from fine steps
    /// `at`, if one is provably so.
    fn classify(&self, at: [usize; 3], n: usize) -> Option<usize> {
        let range = at.map(|a| self.axis.range(a, n));
        let lo = range.map(|r| r.0);
        let hi = range.map(|r| r.1);
        let centre: [f32; 3] = std::array::from_fn(|c| ((lo[c] + hi[c]) / 2.0) as f32);
        let best = self.matcher.nearest(centre);
        let root_lms = |rgb: [f64; 3]| M1.map(|row| dot(row, rgb).cbrt());
        let (x_lo, x_hi) = (root_lms(lo), root_lms(hi));
        // The range of each Oklab coordinate over the box (each is linear in x).
        let range = |row: [f64; 3]| {
            let (mut a, mut b) = (0.0, 0.0);
            for c in 0..3 {
                let (u, v) = (row[c] * x_lo[c], row[c] * x_hi[c]);
                a += u.min(v);
                b += u.max(v);
            }
            (a, b)
        };
        let ranges = M2.map(range);
        let l_free = ranges[0].0 >= 0.0 && ranges[0].1 <= 1.0;
        // L as the exact search sees it: clamped to 0..=1.
        let l_range = (ranges[0].0.clamp(0.0, 1.0), ranges[0].1.clamp(0.0, 1.0));
        let qi = self.oklab[best];
        for (j, qj) in self.oklab.iter().enumerate() {
            if j == best || self.srgb[j] == self.srgb[best] {
                // An identical colour is never chosen over `best` (the exact search keeps
                // the first of equal colours).
                continue;
            }
            // f(p) = 2 p·(qᵢ − qⱼ) + |qⱼ|² − |qᵢ|².
            let d = [qi[0] - qj[0], qi[1] - qj[1], qi[2] - qj[2]];
            let mut min = dot(*qj, *qj) - dot(qi, qi);
            if l_free {
                // Linear in x: the minimum at a corner, coordinate by coordinate.
                for c in 0..3 {
                    let a = 2.0 * (M2[0][c] * d[0] + M2[1][c] * d[1] + M2[2][c] * d[2]);
                    min += a * if a > 0.0 { x_lo[c] } else { x_hi[c] };
                }
            } else if let Some(phi) = one_sided_clamp(ranges[0], d[0]) {
                // One clamp of L is active in the box. With `phi` chosen so that
                // 2·d_L·clamp(L) ≥ 2·d_L·phi(L) and the right side concave (phi is the clamp
                // itself where that term is concave, else L, which bounds it), the bound is
                // concave in x: its minimum over the box is at one of the eight corners.
                let mut corner_min = f64::INFINITY;
                for k in 0..8 {
                    let x: [f64; 3] =
                        std::array::from_fn(|c| if k >> c & 1 == 0 { x_lo[c] } else { x_hi[c] });
                    let lab = M2.map(|row| dot(row, x));
                    let v = 2.0 * (d[0] * phi(lab[0]) + d[1] * lab[1] + d[2] * lab[2]);
                    corner_min = corner_min.min(v);
                }
                min += corner_min;
            } else {
                let term = |(lo, hi): (f64, f64), d: f64| 2.0 * d * if d > 0.0 { lo } else { hi };
                min += term(l_range, d[0]) + term(ranges[1], d[1]) + term(ranges[2], d[2]);
            }
            if min <= MARGIN {
                return None;
            }
        }
        Some(best)
    }
}

/// For a box whose L range is `l` (not inside 0..=1) and an entry pair with L difference
/// `d_l`: a function `phi` with `d_l·clamp(L, 0, 1) ≥ d_l·phi(L)` over the box and `d_l·phi`
/// concave, when only one of the two clamps is active in the box. Above 1 only, `clamp` is
/// `min(L, 1)` (concave): kept when `d_l > 0`, else replaced by `L ≥ min(L, 1)`. Below 0
/// only, `clamp` is `max(L, 0)` (convex): kept when `d_l < 0`, else replaced by
/// `L ≤ max(L, 0)`. `None` when both clamps are active.
fn one_sided_clamp((lo, hi): (f64, f64), d_l: f64) -> Option<fn(f64) -> f64> {
    let keep_min: fn(f64) -> f64 = |l| l.min(1.0);
    let keep_max: fn(f64) -> f64 = |l| l.max(0.0);
    let linear: fn(f64) -> f64 = |l| l;
    if lo >= 0.0 {
        Some(if d_l > 0.0 { keep_min } else { linear })
    } else if hi <= 1.0 {
        Some(if d_l < 0.0 { keep_max } else { linear })
    } else {
        None
    }
}

/// `n` zeroed codes, backed by 2 MiB pages where the kernel agrees: the table is a few
/// megabytes read at random, and with 4 KiB pages most lookups would also miss the TLB.
fn zeroed_huge(n: usize) -> Vec<u16> {
    let v = vec![0u16; n];
    #[cfg(target_os = "linux")]
    {
        let start = v.as_ptr() as usize & !4095;
        let len = v.as_ptr() as usize + n * 2 - start;
        // SAFETY: the range is `v`'s buffer widened down to the start of its first page, all
        // mapped by this process. MADV_HUGEPAGE is advice on how pages are backed: it changes
        // no contents, here or in whatever else shares that first page.
        unsafe {
            libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        }
    }
    v
}

#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (LCG), uniform in 0..1.
    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    #[test]
    fn same_answer_as_the_exact_search() {
        let mut next = rng(1);
        let mut palettes: Vec<Palette> = Palette::builtin_names()
            .map(|n| Palette::builtin(n).unwrap())
            .collect();
        for n in [2usize, 3, 5, 9, 16, 40, 200] {
            let colours = (0..n)
                .map(|_| std::array::from_fn(|_| (next() * 256.0) as u8))
                .collect();
            palettes.push(Palette::new("random", colours).unwrap());
        }
        // Duplicated entries and near-duplicates.
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
            let mut lut = NearestLut::new(p, &m).unwrap();
            for i in 0..20_000 {
                // Mostly in 0..1 (where pixels are), some across the whole clamped range,
                // some exactly on cube boundaries.
                let v: [f32; 3] = match i % 5 {
                    0 => std::array::from_fn(|_| next() * 3.0 - 1.0),
                    1 => std::array::from_fn(|_| (next() * 96.0).floor() / 32.0 - 1.0),
                    // Dark colours and small negative values, where Oklab is steepest.
                    2 => std::array::from_fn(|_| (next() - 0.3) * next().powi(4)),
                    _ => std::array::from_fn(|_| next() * 1.2 - 0.1),
                };
                assert_eq!(lut.nearest(v), m.nearest(v), "{} at {v:?}", p.name);
            }
            assert!(
                lut.decided_share() > 0.5,
                "{}: {}",
                p.name,
                lut.decided_share()
            );
        }
    }

    #[test]
    fn most_boxes_of_a_small_palette_are_decided() {
        let p = Palette::builtin("rgb-8").unwrap();
        let m = PaletteMatcher::new(&p);
        let mut lut = NearestLut::new(&p, &m).unwrap();
        let mut next = rng(7);
        for _ in 0..50_000 {
            lut.nearest(std::array::from_fn(|_| next()));
        }
        assert!(lut.decided_share() > 0.95, "{}", lut.decided_share());
    }
}
