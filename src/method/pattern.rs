//! The lecture's halftone patterns ("Halftone Approximations"): a mask of pixel position
//! numbers 1..N; level k lights every pixel whose number is at most k. On a device with L
//! levels a pixel, a cell gives N(L−1)+1 levels: level k sets every pixel to ⌊k/N⌋ plus one
//! on the pixels whose number is at most k mod N. Levels count light: level 0 is solid ink.

use rayon::prelude::*;

use super::threshold::check_levels;
use super::Method;
use crate::error::{Error, Result};
use crate::mask::Mask;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};

/// How cells map onto the output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cell {
    /// Each input pixel becomes a whole cell: output is (mask size)× larger, for a device of
    /// that much more resolution.
    Expand,
    /// Output keeps the input's size: each cell-sized block is averaged in linear light and
    /// drawn as one pattern (resolution reduced by the cell size, as the lecture says).
    Fit,
}

/// Pattern halftoning with a position mask.
#[derive(Clone, Debug)]
pub struct Pattern {
    mask: Mask,
    levels: u16,
    cell: Cell,
    /// `cells[k]` is level k's cell, row-major, one device level per pixel.
    cells: Vec<Vec<u8>>,
}

impl Pattern {
    /// A pattern method for `mask` on a device of `levels` levels a pixel.
    pub fn new(mask: Mask, levels: u16, cell: Cell) -> Result<Pattern> {
        check_levels(levels)?;
        let total = mask.len() * (levels as usize - 1);
        if total > 65535 {
            return Err(Error::Invalid(format!(
                "mask {} with {levels} levels gives {} patterns; at most 65536 are supported",
                mask.name,
                total + 1
            )));
        }
        let cells = pattern_table(&mask, levels);
        Ok(Pattern {
            mask,
            levels,
            cell,
            cells,
        })
    }

    /// Number of tones the cell can show: N(L−1)+1.
    pub fn tones(&self) -> usize {
        self.cells.len()
    }

    /// The mask in use.
    pub fn mask(&self) -> &Mask {
        &self.mask
    }

    /// Nearest representable tone for linear reflectance `v`.
    #[inline]
    fn tone_of(&self, v: f32) -> usize {
        let top = (self.cells.len() - 1) as f32;
        (v * top).round().clamp(0.0, top) as usize
    }

    fn expand_plane(&self, plane: &PlaneRef<'_>, data: &mut [u8], bits: u8, stride: usize) {
        let (mw, mh) = (self.mask.width, self.mask.height);
        let lut: Vec<u16> = plane.tone.iter().map(|&v| self.tone_of(v) as u16).collect();
        let w = plane.width;
        let out_w = w * mw;
        data.par_chunks_mut(stride).enumerate().for_each_init(
            || (vec![0u8; out_w], vec![0u16; w]),
            |(levels, tones), (oy, row)| {
                let (y, cy) = (oy / mh, oy % mh);
                match plane.samples {
                    SamplesRef::U8(s) => {
                        for (t, &c) in tones.iter_mut().zip(&s[y * w..(y + 1) * w]) {
                            *t = lut[c as usize];
                        }
                    }
                    SamplesRef::U16(s) => {
                        for (t, &c) in tones.iter_mut().zip(&s[y * w..(y + 1) * w]) {
                            *t = lut[c as usize];
                        }
                    }
                }
                for (chunk, &t) in levels.chunks_exact_mut(mw).zip(tones.iter()) {
                    chunk.copy_from_slice(&self.cells[t as usize][cy * mw..(cy + 1) * mw]);
                }
                pack_row(levels, bits, row);
            },
        );
    }

    fn fit_plane(&self, plane: &PlaneRef<'_>, data: &mut [u8], bits: u8, stride: usize) {
        let (mw, mh) = (self.mask.width, self.mask.height);
        let (w, h) = (plane.width, plane.height);
        let blocks_x = w.div_ceil(mw);
        data.par_chunks_mut(stride * mh).enumerate().for_each_init(
            || (vec![0f32; w], vec![0f64; blocks_x], vec![0u8; w]),
            |(vals, sums, levels), (by, band)| {
                let y0 = by * mh;
                let rows = (h - y0).min(mh);
                sums.iter_mut().for_each(|s| *s = 0.0);
                for y in y0..y0 + rows {
                    plane.row_linear(y, vals);
                    for (bx, chunk) in vals.chunks(mw).enumerate() {
                        sums[bx] += chunk.iter().map(|&v| v as f64).sum::<f64>();
                    }
                }
                let tones: Vec<usize> = sums
                    .iter()
                    .enumerate()
                    .map(|(bx, &s)| {
                        let cols = (w - bx * mw).min(mw);
                        self.tone_of((s / (cols * rows) as f64) as f32)
                    })
                    .collect();
                for (cy, row) in band.chunks_mut(stride).enumerate() {
                    for (x, l) in levels.iter_mut().enumerate() {
                        *l = self.cells[tones[x / mw]][cy * mw + x % mw];
                    }
                    pack_row(levels, bits, row);
                }
            },
        );
    }
}

/// Every level's cell for `mask` on a device of `levels` levels a pixel: N(L−1)+1 cells,
/// each row-major with one device level (0..L−1) per pixel.
pub fn pattern_table(mask: &Mask, levels: u16) -> Vec<Vec<u8>> {
    let n = mask.len();
    let total = n * (levels as usize - 1);
    (0..=total)
        .map(|k| {
            let (base, extra) = (k / n, k % n);
            mask.ranks
                .iter()
                .map(|&r| {
                    let lit = (r as usize) < extra; // position number r+1 <= k mod N
                    (base + lit as usize).min(levels as usize - 1) as u8
                })
                .collect()
        })
        .collect()
}

impl Method for Pattern {
    fn rows(&self) -> Option<Box<dyn super::rows::RowMethod + '_>> {
        // Bands start where the cells' rows restart.
        Some(Box::new(super::rows::BandLocal::new(
            self,
            self.mask.height,
            0,
        )))
    }

    fn name(&self) -> String {
        let cell = match self.cell {
            Cell::Expand => "expand",
            Cell::Fit => "fit",
        };
        if self.levels == 2 {
            format!("pattern({}, {cell})", self.mask.name)
        } else {
            format!(
                "pattern({}, {cell}, levels {})",
                self.mask.name, self.levels
            )
        }
    }

    fn output_size(&self, width: usize, height: usize) -> (usize, usize) {
        match self.cell {
            // Saturating: an impossible size then fails the output-size check rather than
            // wrapping to a small one.
            Cell::Expand => (
                width.saturating_mul(self.mask.width),
                height.saturating_mul(self.mask.height),
            ),
            Cell::Fit => (width, height),
        }
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        let (ow, oh) = self.output_size(input.width, input.height);
        let mut h = Halftone::new(ow, oh, input.planes.len(), self.levels);
        let (bits, stride) = (h.bits, h.stride);
        if stride == 0 || oh == 0 {
            return Ok(h);
        }
        h.planes
            .par_iter_mut()
            .zip(&input.planes)
            .for_each(|(data, plane)| match self.cell {
                Cell::Expand => self.expand_plane(plane, data, bits, stride),
                Cell::Fit => self.fit_plane(plane, data, bits, stride),
            });
        Ok(h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Image;
    use crate::tone::ToneOptions;

    #[test]
    fn lecture_3x3_levels() {
        let t = pattern_table(&Mask::builtin("seed-3x3").unwrap(), 2);
        assert_eq!(t.len(), 10);
        assert_eq!(t[0], vec![0; 9]);
        assert_eq!(t[1], vec![0, 0, 0, 0, 1, 0, 0, 0, 0]);
        assert_eq!(t[9], vec![1; 9]);
    }

    #[test]
    fn fit_keeps_size_and_averages_blocks() {
        // A 4x4 grey image (code 255 except one black pixel) with 2x2 cells.
        let mut px = vec![255u8; 16];
        px[0] = 0;
        let img = Image::gray8(4, 4, px);
        let tone = img.tone_table(&ToneOptions::default());
        let p = Pattern::new(Mask::builtin("seed-2x2").unwrap(), 2, Cell::Fit).unwrap();
        let h = p.halftone(&img.planes(&tone)).unwrap();
        assert_eq!((h.width, h.height), (4, 4));
        // Top-left block averages 0.75: level 3 lights numbers 1..3.
        let lv = h.levels_of(0);
        assert_eq!(&lv[0..2], &[1, 1]);
        assert_eq!(&lv[4..6], &[1, 0]);
        assert!(lv[2..4].iter().all(|&l| l == 1));
    }
}
