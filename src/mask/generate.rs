//! Mask generators: Bayer's dispersed-dot matrices, clustered dots from spot functions, and
//! blue noise by void-and-cluster.
//!
//! Every generator returns ranks 0..N−1 in the project's sense: rank 0 is the first cell to
//! be lit (paper), rank N−1 the last, so a flat area of reflectance `v` lights about `v·N`
//! cells of every tile.

use crate::error::{Error, Result};
use crate::fmath as fm;
use crate::mask::Mask;

/// Bayer's dispersed-dot ordered-dither matrix of `size × size` (a power of two, 2..=256),
/// from the recursive definition (Bayer 1973):
/// `M₁ = [0]`, `M₂ₙ = [[4Mₙ, 4Mₙ+2], [4Mₙ+3, 4Mₙ+1]]`, so `M₂ = [[0, 2], [3, 1]]`.
pub fn bayer(size: usize) -> Result<Mask> {
    if !(2..=256).contains(&size) || !size.is_power_of_two() {
        return Err(Error::Invalid(format!(
            "Bayer size {size}: must be a power of two from 2 to 256"
        )));
    }
    let mut m: Vec<u32> = vec![0];
    let mut n = 1;
    while n < size {
        let big = 2 * n;
        let mut next = vec![0u32; big * big];
        for y in 0..big {
            for x in 0..big {
                let base = 4 * m[(y % n) * n + (x % n)];
                // Quadrant offsets: top-left 0, top-right 2, bottom-left 3, bottom-right 1.
                let add = match (y >= n, x >= n) {
                    (false, false) => 0,
                    (false, true) => 2,
                    (true, false) => 3,
                    (true, true) => 1,
                };
                next[y * big + x] = base + add;
            }
        }
        m = next;
        n = big;
    }
    Ok(Mask {
        name: format!("bayer-{size}"),
        width: size,
        height: size,
        ranks: m,
    })
}

/// The shape of a clustered dot: a spot function in the PostScript sense (PLRM 3rd ed.,
/// §7.4.3 "Spot Functions"), defined on cell coordinates `x, y ∈ [−1, 1]`. The higher its
/// value, the nearer the pixel is to the dot's core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dot {
    /// Round dot, `1 − (x² + y²)`: round black dots in the highlights that join at 50%
    /// and leave round white holes in the shadows.
    Round,
    /// Elliptical dot, `1 − (0.6·x² + y²)`: dots 1.29× longer across than down, so they
    /// join in chains (first across, then down) and midtones do not jump.
    Ellipse,
    /// Line screen, `1 − |y|`: lines along the rows that thicken with the tone.
    Line,
    /// Diamond (square at 45°) dot, `1 − (|x| + |y|)`: checkerboard at 50%.
    Diamond,
}

impl Dot {
    /// The spot function's value at cell coordinates `(x, y)`.
    pub fn spot(self, x: f64, y: f64) -> f64 {
        match self {
            Dot::Round => 1.0 - (x * x + y * y),
            Dot::Ellipse => 1.0 - (0.6 * x * x + y * y),
            Dot::Line => 1.0 - y.abs(),
            Dot::Diamond => 1.0 - (x.abs() + y.abs()),
        }
    }

    /// The name used on the command line and in mask names.
    pub fn name(self) -> &'static str {
        match self {
            Dot::Round => "round",
            Dot::Ellipse => "ellipse",
            Dot::Line => "line",
            Dot::Diamond => "diamond",
        }
    }
}

/// A clustered-dot mask of `size × size` (2..=256) grown from the spot function `dot`.
///
/// Ink dots sit at the cell's centre. Cells light in order of *increasing* spot value, so
/// the dot's core is the last to be lit: a light area (most cells lit) keeps a small black
/// dot at the centre, a dark area (few cells lit) is a big black dot whose only light pixels
/// are the cell's corners, which meet the corners of the neighbouring cells as a small white
/// dot — the print convention, and the lecture's "on pixels near the centre of the grid for
/// low levels" with the grid shifted by half a cell. Equal spot values are lit in order of
/// angle round the dot's centre, then by position, so a dot grows evenly on all sides.
///
/// With `angle45` the cell holds two dots on a 45° lattice, one at the centre and one at
/// the corners (which tile as one dot), like a screen turned 45°: the period along the
/// diagonals is `size/√2`. For an even `size` both dots sample alike and grow together.
pub fn cluster(size: usize, dot: Dot, angle45: bool) -> Result<Mask> {
    if !(2..=256).contains(&size) {
        return Err(Error::Invalid(format!(
            "cluster size {size}: must be from 2 to 256"
        )));
    }
    let n = size as f64;
    let mut keys: Vec<(f64, f64, usize)> = Vec::with_capacity(size * size);
    for j in 0..size {
        for i in 0..size {
            // Pixel centres in [−1, 1].
            let x = 2.0 * (i as f64 + 0.5) / n - 1.0;
            let y = 2.0 * (j as f64 + 0.5) / n - 1.0;
            let (u, v) = if angle45 {
                // Coordinates along the diagonals, folded to the nearest dot (period 2):
                // dots at (0, 0) and (±1, ±1).
                let (p, q) = (x + y, y - x);
                (p - 2.0 * (p / 2.0).round(), q - 2.0 * (q / 2.0).round())
            } else {
                (x, y)
            };
            // Quantised so that mirror-image cells compare equal despite rounding.
            let spot = (dot.spot(u, v) * 1e9).round();
            keys.push((spot, fm::atan2(v, u), j * size + i));
        }
    }
    keys.sort_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(a.1.total_cmp(&b.1))
            .then(a.2.cmp(&b.2))
    });
    let mut ranks = vec![0u32; size * size];
    for (r, k) in keys.iter().enumerate() {
        ranks[k.2] = r as u32;
    }
    let name = if angle45 {
        format!("dot45-{size}")
    } else {
        format!("cluster-{size}")
    };
    Ok(Mask {
        name,
        width: size,
        height: size,
        ranks,
    })
}

/// σ of the void-and-cluster energy filter (Ulichney 1993).
const SIGMA: f64 = 1.5;

/// Filter values are scaled by 2⁴⁰ and rounded to integers, so energies are exact sums: no
/// rounding order, no platform's `exp` in its last bit, can change which cell wins.
const ENERGY_SCALE: f64 = (1u64 << 40) as f64;

/// splitmix64 (Steele, Lea & Flood 2014): a small, fully specified PRNG, so a seed gives
/// the same mask everywhere.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in 0..n (Lemire's multiply-shift; the bias is below 2⁻⁴⁸ for our sizes).
    fn below(&mut self, n: usize) -> usize {
        ((self.next() as u128 * n as u128) >> 64) as usize
    }
}

/// The binary pattern with its energy: `energy[p] = Σ_{q one} f(p − q)` with the toroidal
/// Gaussian `f`, updated incrementally as cells are set and cleared.
struct Pattern {
    size: usize,
    /// `filter[dy·size + dx]` for wrapped offsets.
    filter: Vec<i64>,
    ones: Vec<bool>,
    energy: Vec<i64>,
}

impl Pattern {
    fn new(size: usize) -> Pattern {
        let mut filter = vec![0i64; size * size];
        for dy in 0..size {
            for dx in 0..size {
                // Wrap-around: the distance to the nearest copy, so the mask tiles.
                let wx = dx.min(size - dx) as f64;
                let wy = dy.min(size - dy) as f64;
                let f = fm::exp(-(wx * wx + wy * wy) / (2.0 * SIGMA * SIGMA));
                filter[dy * size + dx] = (f * ENERGY_SCALE).round() as i64;
            }
        }
        Pattern {
            size,
            filter,
            ones: vec![false; size * size],
            energy: vec![0; size * size],
        }
    }

    /// Sets (`sign = 1`) or clears (`sign = −1`) cell `p`, updating every cell's energy.
    fn toggle(&mut self, p: usize, sign: i64) {
        self.ones[p] = sign > 0;
        let n = self.size;
        let (px, py) = (p % n, p / n);
        for y in 0..n {
            // Offset (y − py) mod n, then a run of the filter's row, split where it wraps.
            let frow = &self.filter[((y + n - py) % n) * n..][..n];
            let erow = &mut self.energy[y * n..(y + 1) * n];
            let (head, tail) = erow.split_at_mut(px);
            // x ≥ px: offset x − px = 0..; x < px: offset n − px + x.
            for (e, &f) in tail.iter_mut().zip(&frow[..n - px]) {
                *e += sign * f;
            }
            for (e, &f) in head.iter_mut().zip(&frow[n - px..]) {
                *e += sign * f;
            }
        }
    }

    /// The tightest cluster: the one with the highest energy (first on ties).
    fn tightest_cluster(&self) -> usize {
        let mut best = (i64::MIN, 0);
        for (p, (&e, &one)) in self.energy.iter().zip(&self.ones).enumerate() {
            if one && e > best.0 {
                best = (e, p);
            }
        }
        best.1
    }

    /// The largest void: the zero with the lowest energy (first on ties).
    fn largest_void(&self) -> usize {
        let mut best = (i64::MAX, 0);
        for (p, (&e, &one)) in self.energy.iter().zip(&self.ones).enumerate() {
            if !one && e < best.0 {
                best = (e, p);
            }
        }
        best.1
    }
}

/// A blue-noise mask of `size × size` (8..=256) by void-and-cluster (Ulichney, "The
/// void-and-cluster method for dither array generation", SPIE 1913, 1993), deterministic
/// for a `seed`.
///
/// Energy filter: Gaussian, σ = 1.5, wrapped around the edges so the mask tiles. A random
/// initial pattern of N/10 ones is relaxed by moving the tightest cluster to the largest
/// void until the two coincide. Phase 1 ranks the initial ones by removing tightest
/// clusters; phase 2 fills largest voids up to half; phase 3 ranks the rest by setting the
/// tightest cluster of *zeros*. Since the filter sums to the same constant K everywhere,
/// the zeros' energy is K minus the ones' energy, so phase 3's tightest cluster of zeros is
/// exactly the ones' largest void: phases 2 and 3 share one search.
pub fn blue_noise(size: usize, seed: u64) -> Result<Mask> {
    if !(8..=256).contains(&size) {
        return Err(Error::Invalid(format!(
            "blue-noise size {size}: must be from 8 to 256"
        )));
    }
    let n = size * size;
    let mut rng = SplitMix64(seed);
    let mut proto = Pattern::new(size);

    // Initial binary pattern: N/10 ones at random distinct cells.
    let initial = n / 10;
    let mut placed = 0;
    while placed < initial {
        let p = rng.below(n);
        if !proto.ones[p] {
            proto.toggle(p, 1);
            placed += 1;
        }
    }
    // Relax: tightest cluster → largest void, until removing and refilling is a no-op.
    // Each move lowers the total energy, so this ends; the cap is a guard only.
    for _ in 0..n * 10 {
        let c = proto.tightest_cluster();
        proto.toggle(c, -1);
        let v = proto.largest_void();
        proto.toggle(v, 1);
        if v == c {
            break;
        }
    }

    let mut ranks = vec![0u32; n];
    // Phase 1: remove tightest clusters; the last removed is rank 0.
    let mut pat = Pattern {
        size,
        filter: proto.filter.clone(),
        ones: proto.ones.clone(),
        energy: proto.energy.clone(),
    };
    for rank in (0..initial).rev() {
        let c = pat.tightest_cluster();
        pat.toggle(c, -1);
        ranks[c] = rank as u32;
    }
    // Phases 2 and 3: from the initial pattern, fill the largest void each time.
    let mut pat = proto;
    for rank in initial..n {
        let v = pat.largest_void();
        pat.toggle(v, 1);
        ranks[v] = rank as u32;
    }
    Ok(Mask {
        name: format!("blue-noise-{size}"),
        width: size,
        height: size,
        ranks,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn is_permutation(m: &Mask) -> bool {
        let mut seen = vec![false; m.len()];
        for &r in &m.ranks {
            if r as usize >= m.len() || seen[r as usize] {
                return false;
            }
            seen[r as usize] = true;
        }
        m.len() == m.width * m.height
    }

    #[test]
    fn bayer_2x2() {
        assert_eq!(bayer(2).unwrap().ranks, vec![0, 2, 3, 1]);
    }

    #[test]
    fn bayer_4x4_is_the_classic_table() {
        #[rustfmt::skip]
        let want = vec![
             0,  8,  2, 10,
            12,  4, 14,  6,
             3, 11,  1,  9,
            15,  7, 13,  5,
        ];
        assert_eq!(bayer(4).unwrap().ranks, want);
    }

    #[test]
    fn bayer_recursion_holds_at_every_size() {
        let mut prev = bayer(2).unwrap();
        let mut size = 4;
        while size <= 256 {
            let m = bayer(size).unwrap();
            assert!(is_permutation(&m), "bayer {size}");
            let h = size / 2;
            for y in 0..size {
                for x in 0..size {
                    let add = [[0, 2], [3, 1]][y / h][x / h];
                    assert_eq!(m.rank(x, y), 4 * prev.rank(x % h, y % h) + add);
                }
            }
            prev = m;
            size *= 2;
        }
        assert!(bayer(3).is_err() && bayer(1).is_err() && bayer(512).is_err());
    }

    #[test]
    fn clusters_are_permutations_growing_from_the_centre() {
        for size in [2, 3, 4, 5, 6, 8, 16, 33] {
            for dot in [Dot::Round, Dot::Ellipse, Dot::Line, Dot::Diamond] {
                for a45 in [false, true] {
                    let m = cluster(size, dot, a45).unwrap();
                    assert!(is_permutation(&m), "{size} {dot:?} {a45}");
                }
            }
        }
        // 8×8 round: the four centre pixels are lit last (the ink dot's core), the four
        // corners first.
        let m = cluster(8, Dot::Round, false).unwrap();
        let mut centre: Vec<u32> = [(3, 3), (4, 3), (3, 4), (4, 4)]
            .iter()
            .map(|&(x, y)| m.rank(x, y))
            .collect();
        centre.sort();
        assert_eq!(centre, vec![60, 61, 62, 63]);
        let mut corners: Vec<u32> = [(0, 0), (7, 0), (0, 7), (7, 7)]
            .iter()
            .map(|&(x, y)| m.rank(x, y))
            .collect();
        corners.sort();
        assert_eq!(corners, vec![0, 1, 2, 3]);
        // Round dots are 4-fold symmetric: mirror cells have ranks within the same group of 4
        // or 8 equal spot values.
        let spot = |x: usize, y: usize| {
            let c = |i: usize| 2.0 * (i as f64 + 0.5) / 8.0 - 1.0;
            Dot::Round.spot(c(x), c(y))
        };
        for y in 0..8 {
            for x in 0..8 {
                for y2 in 0..8 {
                    for x2 in 0..8 {
                        if spot(x, y) < spot(x2, y2) - 1e-9 {
                            assert!(m.rank(x, y) < m.rank(x2, y2));
                        }
                    }
                }
            }
        }
        // 45°: two dots, lit last at the centre and at the corners.
        let m = cluster(8, Dot::Round, true).unwrap();
        let last: Vec<u32> = [(3, 3), (4, 4), (0, 0), (7, 7)]
            .iter()
            .map(|&(x, y)| m.rank(x, y))
            .collect();
        assert!(last.iter().all(|&r| r >= 56), "{last:?}");
        assert!(cluster(1, Dot::Round, false).is_err());
    }

    #[test]
    fn blue_noise_is_a_permutation_and_seeded() {
        let a = blue_noise(16, 7).unwrap();
        assert!(is_permutation(&a));
        assert_eq!(a, blue_noise(16, 7).unwrap());
        assert_ne!(a.ranks, blue_noise(16, 8).unwrap().ranks);
        assert!(blue_noise(4, 1).is_err());
    }

    #[test]
    fn filter_wraps_around() {
        let p = Pattern::new(8);
        assert_eq!(p.filter[1], p.filter[7]);
        assert_eq!(p.filter[8], p.filter[7 * 8]);
        assert_eq!(p.filter[0], ENERGY_SCALE as i64);
    }
}
