//! Ordered dithering: every pixel is compared with the threshold of its cell in a tiled mask
//! (Bayer, clustered dot, blue noise or a user's file).
//!
//! Thresholds live in linear light. With N cells, the cell of rank r has threshold
//! `t_r = (r + ½)/N`; a pixel of reflectance `v` on an L-level device sits at
//! `s = v·(L−1)`, between levels `b = ⌊s⌋` and `b + 1`, and takes the upper one when the
//! fraction `s − b ≥ t_r`. Over a whole tile a flat `v` therefore lights `round(f·N)` cells
//! of the upper level, so the mean reflectance is within ½/(N·(L−1)) of `v` (ImageMagick's
//! `o8x8,4` idea, placed in linear light).
//!
//! No conversion per pixel: the thresholds are mapped back into the input's code domain
//! once per plane. A bilevel plane whose tone table is monotonic (the usual case, and the
//! inverted one) costs one comparison of the raw code per pixel against a tiled row of
//! threshold codes, packed 8 pixels to a byte as it is made. Other cases (more levels, or a
//! table that goes up and down) look each code up once in a table of (lower level, rank of
//! the fraction) and compare that rank with the cell's, which is exactly the same decision.

use rayon::prelude::*;

use super::threshold::check_levels;
use super::{each_plane, Method, PlaneOut};
use crate::error::{Error, Result};
use crate::mask::Mask;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};

/// Tiled threshold rows are kept for the whole mask height up to this size (per plane);
/// above it (giant custom masks) a row is tiled when needed.
const TILED_ROWS_LIMIT: usize = 4 << 20;

/// Ordered dithering with a threshold mask.
#[derive(Clone, Debug)]
pub struct Ordered {
    mask: Mask,
    levels: u16,
}

impl Ordered {
    /// Ordered dithering with `mask` to `levels` (2..=256) output levels.
    pub fn new(mask: Mask, levels: u16) -> Result<Ordered> {
        check_levels(levels)?;
        if mask.is_empty() || mask.len() != mask.width * mask.height {
            return Err(Error::Invalid(format!("mask {}: no cells", mask.name)));
        }
        Ok(Ordered { mask, levels })
    }

    /// The mask in use.
    pub fn mask(&self) -> &Mask {
        &self.mask
    }

    /// Output levels per channel.
    pub fn levels(&self) -> u16 {
        self.levels
    }

    /// How far the mask is shifted for plane `c` (0, 1, 2 for red, green, blue), as
    /// `(dx, dy)`: plane c reads the mask at `(x + dx, y + dy)`. The shift is a third of the
    /// tile's cells per plane, counted row-major (`c·⌊N/3⌋` cells on), so for N ≥ 3 the
    /// three planes use different cells, hence different ranks, at every pixel and their
    /// dots do not stack. Grey (one plane) is not shifted.
    pub fn channel_offset(&self, c: usize) -> (usize, usize) {
        let (w, h) = (self.mask.width, self.mask.height);
        let d = c * (self.mask.len() / 3);
        (d % w, (d / w) % h)
    }

    /// The threshold of rank `r` in linear light: `(r + ½)/N`.
    #[inline]
    pub fn threshold(&self, rank: u32) -> f64 {
        (rank as f64 + 0.5) / self.mask.len() as f64
    }

    /// The output level for linear reflectance `v` at a cell of rank `rank`: the reference
    /// definition every fast path reproduces exactly.
    pub fn level_of(&self, v: f32, rank: u32) -> u8 {
        let (base, frac) = split(v, self.levels);
        base + (frac >= self.threshold(rank)) as u8
    }

    /// Every cell's threshold in linear light, row-major in the mask (not yet shifted for a
    /// colour plane; [`TiledRows`] does that).
    fn cell_thresholds(&self) -> Vec<f64> {
        self.mask.ranks.iter().map(|&r| self.threshold(r)).collect()
    }

    fn plane(&self, c: usize, plane: &PlaneRef<'_>, out: &mut PlaneOut<'_>) {
        if out.stride == 0 || out.height == 0 {
            return;
        }
        let offset = self.channel_offset(c);
        let thresholds = self.cell_thresholds();
        if self.levels == 2 {
            match plane.samples {
                SamplesRef::U8(s) => {
                    if let Some((flip, codes)) = threshold_codes(plane.tone, &thresholds) {
                        let codes: Vec<u8> = codes.iter().map(|&c| c as u8).collect();
                        let rows = TiledRows::new(&self.mask, offset, &codes, plane.width);
                        return bilevel_plane(s, plane.width, flip as u8, &rows, out);
                    }
                }
                SamplesRef::U16(s) => {
                    if let Some((flip, codes)) = threshold_codes(plane.tone, &thresholds) {
                        let codes: Vec<u16> = codes.iter().map(|&c| c as u16).collect();
                        let rows = TiledRows::new(&self.mask, offset, &codes, plane.width);
                        return bilevel_plane(s, plane.width, flip as u16, &rows, out);
                    }
                }
            }
        }
        if (3..=MULTILEVEL_MAX).contains(&self.levels) {
            let done = match plane.samples {
                SamplesRef::U8(s) => self.multilevel_plane::<u8>(s, plane, offset, out),
                SamplesRef::U16(s) => self.multilevel_plane::<u16>(s, plane, offset, out),
            };
            if done {
                return;
            }
        }
        self.general_plane(plane, offset, &thresholds, out);
    }

    /// Multi-level, monotonic table: the level is counted directly as the number of the
    /// cell's L−1 code thresholds the (flipped) code reaches, `Σₖ [code ^ flip ≥ Cₖ(cell)]`,
    /// a few comparisons a pixel that vectorise, with no table lookup per pixel. `Cₖ(cell)`
    /// is the first flipped code whose reference level ([`Ordered::level_of`]) is at least
    /// `k`, found by bisection: the reference level rises with the code when the table
    /// does, so this is exactly the reference decision. False (nothing written) when the
    /// table goes both ways or some level is out of the codes' reach.
    fn multilevel_plane<T: MultiCode>(
        &self,
        samples: &[T],
        plane: &PlaneRef<'_>,
        offset: (usize, usize),
        out: &mut PlaneOut<'_>,
    ) -> bool {
        let Some((flip, per_level)) = self.level_codes(plane.tone) else {
            return false;
        };
        let rows: Vec<TiledRows<T>> = per_level
            .iter()
            .map(|codes| {
                let codes: Vec<T> = codes.iter().map(|&c| T::from_u32(c)).collect();
                TiledRows::new(&self.mask, offset, &codes, plane.width)
            })
            .collect();
        let (w, bits) = (plane.width, out.bits);
        let flip = T::from_u32(flip);
        out.data
            .par_chunks_mut(out.stride)
            .enumerate()
            .for_each_init(
                || (vec![Vec::new(); rows.len()], vec![0u8; w]),
                |(scratch, levels), (y, row)| {
                    let th: Vec<&[T]> = rows
                        .iter()
                        .zip(scratch.iter_mut())
                        .map(|(r, s)| r.row(y, s))
                        .collect();
                    multilevel_row(&samples[y * w..(y + 1) * w], &th, flip, levels);
                    pack_levels(levels, bits, row);
                },
            );
        true
    }

    /// For a monotonic table: `(flip, C)` with `C[k − 1][cell]` the first code (counted in
    /// the flipped domain) at which the cell's level reaches `k`, for k = 1..L−1. `None`
    /// when the table is not monotonic or a level is never reached by any code.
    fn level_codes(&self, tone: &[f32]) -> Option<(u32, Vec<Vec<u32>>)> {
        let max = tone.len() as u32 - 1;
        let flip = if tone.windows(2).all(|w| w[0] <= w[1]) {
            0
        } else if tone.windows(2).all(|w| w[0] >= w[1]) {
            max
        } else {
            return None;
        };
        let n = self.mask.len();
        let mut per_level = vec![vec![0u32; n]; self.levels as usize - 1];
        for (cell, &rank) in self.mask.ranks.iter().enumerate() {
            let level = |k: u32| self.level_of(tone[(k ^ flip) as usize], rank);
            for (k, codes) in per_level.iter_mut().enumerate() {
                // First code in 0..=max+1 whose level is at least k + 1 (max + 1: never).
                let (mut lo, mut hi) = (0u32, max + 1);
                while lo < hi {
                    let mid = lo + (hi - lo) / 2;
                    if level(mid) as usize > k {
                        hi = mid;
                    } else {
                        lo = mid + 1;
                    }
                }
                if lo > max {
                    return None;
                }
                codes[cell] = lo;
            }
        }
        Some((flip, per_level))
    }

    /// Any level count, any tone table: `level = base[code] + (key[code] >= q[cell])`, where
    /// `key` ranks the code's fraction among all fractions the table can give and `q[cell]`
    /// counts the fractions below the cell's threshold. One lookup a pixel.
    fn general_plane(
        &self,
        plane: &PlaneRef<'_>,
        offset: (usize, usize),
        thresholds: &[f64],
        out: &mut PlaneOut<'_>,
    ) {
        let split_codes: Vec<(u8, f64)> =
            plane.tone.iter().map(|&v| split(v, self.levels)).collect();
        let mut fracs: Vec<f64> = split_codes.iter().map(|&(_, f)| f).collect();
        fracs.sort_by(f64::total_cmp);
        fracs.dedup();
        // (base << 24) | key; key < 65536.
        let lut: Vec<u32> = split_codes
            .iter()
            .map(|&(b, f)| {
                let key = fracs.partition_point(|&g| g < f) as u32;
                ((b as u32) << 24) | key
            })
            .collect();
        let q: Vec<u32> = thresholds
            .iter()
            .map(|&t| fracs.partition_point(|&g| g < t) as u32)
            .collect();
        let rows = TiledRows::new(&self.mask, offset, &q, plane.width);
        let (w, bits) = (plane.width, out.bits);
        let level = |p: u32, q: u32| ((p >> 24) + ((p & 0xFF_FFFF) >= q) as u32) as u8;
        out.data
            .par_chunks_mut(out.stride)
            .enumerate()
            .for_each_init(
                || (vec![0u8; w], Vec::new()),
                |(levels, scratch), (y, row)| {
                    let th = rows.row(y, scratch);
                    match plane.samples {
                        SamplesRef::U8(s) => {
                            for ((l, &c), &q) in
                                levels.iter_mut().zip(&s[y * w..(y + 1) * w]).zip(th)
                            {
                                *l = level(lut[c as usize], q);
                            }
                        }
                        SamplesRef::U16(s) => {
                            for ((l, &c), &q) in
                                levels.iter_mut().zip(&s[y * w..(y + 1) * w]).zip(th)
                            {
                                *l = level(lut[c as usize], q);
                            }
                        }
                    }
                    pack_row(levels, bits, row);
                },
            );
    }
}

/// Splits reflectance `v` on an L-level device into the lower level `b` (at most L−2) and
/// the fraction of the way to `b + 1` (1 at full paper, so paper is always the top level).
#[inline]
fn split(v: f32, levels: u16) -> (u8, f64) {
    let top = (levels - 1) as f64;
    let s = (v as f64 * top).clamp(0.0, top);
    let b = s.floor().min(top - 1.0);
    (b as u8, s - b)
}

/// For a bilevel plane whose tone table is monotonic: `(flip, codes)` such that a pixel of
/// code `k` is lit (paper) in the cell of threshold `t` exactly when `k ^ flip >= code`.
/// `flip` is 0 for a rising table and all ones for a falling (inverted) one. `None` when the
/// table goes both ways, or when some cell would never light (its code would not fit).
fn threshold_codes(tone: &[f32], thresholds: &[f64]) -> Option<(u32, Vec<u32>)> {
    let max = tone.len() as u32 - 1;
    let flip = if tone.windows(2).all(|w| w[0] <= w[1]) {
        0
    } else if tone.windows(2).all(|w| w[0] >= w[1]) {
        max
    } else {
        return None;
    };
    // The table read in the flipped domain rises; lit ⇔ v >= t (see `split` for L = 2).
    let rising: Vec<f64> = (0..=max)
        .map(|k| tone[(k ^ flip) as usize] as f64)
        .collect();
    let codes: Vec<u32> = thresholds
        .iter()
        .map(|&t| rising.partition_point(|&v| v < t) as u32)
        .collect();
    if codes.iter().any(|&c| c > max) {
        return None;
    }
    Some((flip, codes))
}

/// Per-cell values laid out along whole image rows: row `y` holds, for every `x`, the value
/// of mask cell `((x + dx) % w, (y + dy) % h)`.
struct TiledRows<T> {
    /// The mask rows already rotated by `dx`, `h × w`.
    cells: Vec<T>,
    mask_w: usize,
    mask_h: usize,
    dy: usize,
    width: usize,
    /// All `h` tiled rows, `h × width`, when small enough.
    rows: Option<Vec<T>>,
}

impl<T: Copy + Default> TiledRows<T> {
    fn new(mask: &Mask, (dx, dy): (usize, usize), per_cell: &[T], width: usize) -> Self {
        let (mw, mh) = (mask.width, mask.height);
        let mut cells = Vec::with_capacity(per_cell.len());
        for my in 0..mh {
            let row = &per_cell[my * mw..(my + 1) * mw];
            cells.extend_from_slice(&row[dx..]);
            cells.extend_from_slice(&row[..dx]);
        }
        let mut t = TiledRows {
            cells,
            mask_w: mw,
            mask_h: mh,
            dy,
            width,
            rows: None,
        };
        if mh * width * std::mem::size_of::<T>() <= TILED_ROWS_LIMIT {
            let mut rows = vec![T::default(); mh * width];
            for (my, row) in rows.chunks_exact_mut(width.max(1)).enumerate() {
                t.fill(my, row);
            }
            t.rows = Some(rows);
        }
        t
    }

    /// Tiles mask row `my` (already shifted) across `out`.
    fn fill(&self, my: usize, out: &mut [T]) {
        let src = &self.cells[my * self.mask_w..(my + 1) * self.mask_w];
        for chunk in out.chunks_mut(self.mask_w) {
            chunk.copy_from_slice(&src[..chunk.len()]);
        }
    }

    /// Image row `y`'s values, tiled into `scratch` if not kept.
    fn row<'a>(&'a self, y: usize, scratch: &'a mut Vec<T>) -> &'a [T] {
        let my = (y + self.dy) % self.mask_h;
        match &self.rows {
            Some(rows) => &rows[my * self.width..(my + 1) * self.width],
            None => {
                scratch.resize(self.width, T::default());
                self.fill(my, scratch);
                scratch
            }
        }
    }
}

/// Bilevel, monotonic table: one comparison of the raw code a pixel, rows in parallel.
fn bilevel_plane<T>(
    samples: &[T],
    width: usize,
    flip: T,
    rows: &TiledRows<T>,
    out: &mut PlaneOut<'_>,
) where
    T: Copy + Default + PartialOrd + std::ops::BitXor<Output = T> + Send + Sync,
{
    out.data
        .par_chunks_mut(out.stride)
        .enumerate()
        .for_each_init(Vec::new, |scratch, (y, row)| {
            let th = rows.row(y, scratch);
            bilevel_row(&samples[y * width..(y + 1) * width], th, flip, row);
        });
}

/// Gathers 8 bytes of 0/1 into one byte, the first byte in the most significant bit: the
/// multiplier puts byte i's bit at position 63 − i and no two partial products overlap.
#[inline(always)]
fn pack8(lit: &[u8]) -> u8 {
    let x = u64::from_le_bytes(lit.try_into().expect("8 bytes"));
    (x.wrapping_mul(0x8040_2010_0804_0201) >> 56) as u8
}

/// One packed row: bit = `(code ^ flip) >= threshold`. Blocks of 64 pixels compare into a
/// byte array (a loop the compiler vectorises) and are then packed 8 to a byte.
#[inline]
fn bilevel_row<T>(codes: &[T], th: &[T], flip: T, out: &mut [u8])
where
    T: Copy + PartialOrd + std::ops::BitXor<Output = T>,
{
    let blocks = codes.len() / 64;
    for ((c, t), o) in codes
        .chunks_exact(64)
        .zip(th.chunks_exact(64))
        .zip(out.chunks_exact_mut(8))
    {
        let mut lit = [0u8; 64];
        for ((l, &c), &t) in lit.iter_mut().zip(c).zip(t) {
            *l = ((c ^ flip) >= t) as u8;
        }
        for (o, l) in o.iter_mut().zip(lit.chunks_exact(8)) {
            *o = pack8(l);
        }
    }
    let start = blocks * 64;
    let tail = &mut out[blocks * 8..];
    tail.fill(0);
    for (i, (&c, &t)) in codes[start..].iter().zip(&th[start..]).enumerate() {
        tail[i / 8] |= (((c ^ flip) >= t) as u8) << (7 - i % 8);
    }
}

/// Level counts served by [`Ordered::multilevel_plane`]: up to 4 bits a sample (at most 15
/// comparisons a pixel); more levels take the table path.
const MULTILEVEL_MAX: u16 = 16;

/// Input code types of the multi-level path.
trait MultiCode: Copy + Default + PartialOrd + std::ops::BitXor<Output = Self> + Send + Sync {
    /// The code `v` (known to fit).
    fn from_u32(v: u32) -> Self;
}
impl MultiCode for u8 {
    fn from_u32(v: u32) -> Self {
        v as u8
    }
}
impl MultiCode for u16 {
    fn from_u32(v: u32) -> Self {
        v as u16
    }
}

/// One row of levels: for each level threshold row, one more level where the flipped code
/// reaches it. Blocks of 64 keep the running counts in a small array the compiler keeps in
/// vector registers.
#[inline]
fn multilevel_row<T: MultiCode>(codes: &[T], th: &[&[T]], flip: T, levels: &mut [u8]) {
    for (start, (c, l)) in codes
        .chunks(64)
        .zip(levels.chunks_mut(64))
        .enumerate()
        .map(|(i, b)| (i * 64, b))
    {
        let n = c.len();
        let mut flipped = [T::default(); 64];
        for (f, &c) in flipped.iter_mut().zip(c) {
            *f = c ^ flip;
        }
        let mut acc = [0u8; 64];
        for t in th {
            let t = &t[start..start + n];
            for ((a, &f), &t) in acc.iter_mut().zip(&flipped[..n]).zip(t) {
                *a += (f >= t) as u8;
            }
        }
        l.copy_from_slice(&acc[..n]);
    }
}

/// Packs one level per byte into a row of `bits`-bit samples, MSB first: 2- and 4-bit rows
/// with one multiply per output byte (each level's bits land in the top byte, the cross
/// products fall below it or overflow away), other widths through [`pack_row`].
fn pack_levels(levels: &[u8], bits: u8, row: &mut [u8]) {
    match bits {
        2 => {
            let mut chunks = levels.chunks_exact(4);
            for (o, c) in row.iter_mut().zip(&mut chunks) {
                let x = u32::from_le_bytes(c.try_into().expect("chunks of four"));
                *o = (x.wrapping_mul((1 << 30) | (1 << 20) | (1 << 10) | 1) >> 24) as u8;
            }
            let tail = chunks.remainder();
            if !tail.is_empty() {
                let mut b = 0u8;
                for (i, &l) in tail.iter().enumerate() {
                    b |= l << (6 - 2 * i);
                }
                row[levels.len() / 4] = b;
            }
        }
        4 => {
            let mut chunks = levels.chunks_exact(2);
            for (o, c) in row.iter_mut().zip(&mut chunks) {
                let x = u16::from_le_bytes(c.try_into().expect("chunks of two"));
                *o = (x.wrapping_mul((1 << 12) | 1) >> 8) as u8;
            }
            if let [l] = chunks.remainder() {
                row[levels.len() / 2] = l << 4;
            }
        }
        _ => pack_row(levels, bits, row),
    }
}

impl Method for Ordered {
    fn name(&self) -> String {
        if self.levels == 2 {
            format!("ordered({})", self.mask.name)
        } else {
            format!("ordered({}, levels {})", self.mask.name, self.levels)
        }
    }

    fn rows(&self) -> Option<Box<dyn super::rows::RowMethod + '_>> {
        // Bands start where the mask's rows restart; tiled rows of up to u32 per pixel.
        let period = self.mask.height;
        Some(Box::new(super::rows::BandLocal::new(
            self,
            period,
            4 * period,
        )))
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        Ok(each_plane(
            input,
            input.width,
            input.height,
            self.levels,
            |c, plane, out| self.plane(c, plane, out),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Image;
    use crate::tone::ToneOptions;

    /// The reference: `level_of` on every pixel, no fast path.
    fn reference(o: &Ordered, planes: &Planes<'_>) -> Vec<Vec<u8>> {
        planes
            .planes
            .iter()
            .enumerate()
            .map(|(c, p)| {
                let (dx, dy) = o.channel_offset(c);
                let mut v = Vec::with_capacity(p.width * p.height);
                for y in 0..p.height {
                    for x in 0..p.width {
                        v.push(o.level_of(p.value(x, y), o.mask.rank(x + dx, y + dy)));
                    }
                }
                v
            })
            .collect()
    }

    fn ramp_image(w: usize, h: usize) -> Image {
        let px: Vec<u8> = (0..w * h)
            .map(|i| ((i * 7 + i / w * 13) % 256) as u8)
            .collect();
        Image::gray8(w, h, px)
    }

    #[test]
    fn fast_paths_match_the_reference() {
        let img = ramp_image(131, 37); // not a multiple of 64 or of the mask
        let img16 = Image {
            planes: vec![crate::raster::Samples::U16(match &img.planes[0] {
                crate::raster::Samples::U8(v) => v
                    .iter()
                    .map(|&c| (c as u16 * 257).saturating_sub(c as u16 % 5))
                    .collect(),
                _ => unreachable!(),
            })],
            ..img.clone()
        };
        for im in [&img, &img16] {
            for invert in [false, true] {
                let opts = ToneOptions {
                    invert,
                    ..Default::default()
                };
                let table = im.tone_table(&opts);
                // A table that goes up and down takes the general path.
                let wobbly_table: Vec<f32> = table
                    .as_slice()
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| if i % 2 == 0 { v } else { 1.0 - v })
                    .collect();
                for tone in [table.as_slice(), &wobbly_table[..]] {
                    let plane = PlaneRef {
                        width: im.width,
                        height: im.height,
                        samples: im.planes[0].as_ref(),
                        tone,
                    };
                    // Three planes: the colour offsets are checked too.
                    let planes = Planes {
                        width: im.width,
                        height: im.height,
                        planes: vec![plane; 3],
                    };
                    for mask in ["bayer-8", "cluster-6", "seed-3x3"] {
                        for levels in [2u16, 3, 4, 5, 16, 17] {
                            // 16-bit tables are slow to fold in a debug build: fewer cases.
                            if im.bits() == 16 && (mask != "bayer-8" || levels == 4) {
                                continue;
                            }
                            let o = Ordered::new(Mask::builtin(mask).unwrap(), levels).unwrap();
                            let h = o.halftone(&planes).unwrap();
                            let want = reference(&o, &planes);
                            for (c, want) in want.iter().enumerate() {
                                assert_eq!(
                                    &h.levels_of(c),
                                    want,
                                    "{mask} L{levels} invert {invert} bits {} plane {c}",
                                    im.bits()
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn monotonic_tables_fold_into_code_thresholds() {
        let o = Ordered::new(Mask::builtin("bayer-4").unwrap(), 2).unwrap();
        let t = o.cell_thresholds();
        let img = Image::gray8(1, 1, vec![0]);
        let rising = img.tone_table(&ToneOptions::default());
        let (flip, codes) = threshold_codes(rising.as_slice(), &t).unwrap();
        assert_eq!(flip, 0);
        // Rank 0's threshold is 1/32 linear: the first sRGB code at or above it is 50.
        assert_eq!(codes[0], 50);
        assert!(rising.as_slice()[49] < 1.0 / 32.0 && rising.as_slice()[50] >= 1.0 / 32.0);
        let inverted = img.tone_table(&ToneOptions {
            invert: true,
            ..Default::default()
        });
        let (flip, codes_inv) = threshold_codes(inverted.as_slice(), &t).unwrap();
        assert_eq!(flip, 255);
        assert!(codes_inv.iter().all(|&c| c <= 255));
        let mut wobbly = rising.as_slice().to_vec();
        wobbly.swap(10, 200);
        assert!(threshold_codes(&wobbly, &t).is_none());
        // A table that never reaches a cell's threshold cannot be folded into u8 codes.
        let dim: Vec<f32> = rising.as_slice().iter().map(|v| v * 0.5).collect();
        assert!(threshold_codes(&dim, &t).is_none());
    }

    #[test]
    fn pack_levels_matches_pack_row() {
        for levels in [3u16, 4, 5, 16] {
            let bits = crate::raster::bits_for_levels(levels);
            for w in [1usize, 2, 3, 4, 5, 7, 8, 9, 63, 64, 65, 130] {
                let src: Vec<u8> = (0..w)
                    .map(|i| ((i * 7 + w) % levels as usize) as u8)
                    .collect();
                let n = (w * bits as usize).div_ceil(8);
                let (mut a, mut b) = (vec![0xAAu8; n], vec![0x55u8; n]);
                pack_levels(&src, bits, &mut a);
                pack_row(&src, bits, &mut b);
                assert_eq!(a, b, "levels {levels} width {w}");
            }
        }
    }

    #[test]
    fn pack8_is_msb_first() {
        assert_eq!(pack8(&[1, 0, 0, 0, 0, 0, 0, 0]), 0x80);
        assert_eq!(pack8(&[0, 0, 0, 0, 0, 0, 0, 1]), 0x01);
        assert_eq!(pack8(&[1, 1, 0, 1, 0, 0, 1, 1]), 0b1101_0011);
        assert_eq!(pack8(&[1; 8]), 0xFF);
    }

    #[test]
    fn offsets_differ_for_every_plane() {
        for name in ["bayer-2", "bayer-8", "seed-3x3", "blue-noise-64"] {
            let o = Ordered::new(Mask::builtin(name).unwrap(), 2).unwrap();
            let offs: Vec<_> = (0..3).map(|c| o.channel_offset(c)).collect();
            assert_eq!(offs[0], (0, 0));
            assert!(
                offs[0] != offs[1] && offs[1] != offs[2] && offs[0] != offs[2],
                "{name}"
            );
        }
    }
}
