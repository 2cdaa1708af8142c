//! Printer models: what a bilevel halftone looks like once printed.
//!
//! A laser or inkjet does not print square pixels: each dot is a disc that spills onto its
//! neighbours, so dispersed patterns print much darker than their share of dots. A model here
//! gives the printed reflectance of a pixel from its 3×3 neighbourhood of dots: a table of
//! 512 entries, one for every neighbourhood. Two ways to get the table:
//!
//! - **dot overlap** (Pappas and Neuhoff, "Printer models and error diffusion", IEEE Trans.
//!   Image Processing 4(1), 1995): a dot is a disc of radius `r = ρ·T/√2` (T = pixel spacing)
//!   centred on its pixel; `ρ`, the dot ratio, runs from 1 (the disc just covers the pixel)
//!   to √2 (it reaches the neighbours' centres). An inked pixel prints black; a blank pixel
//!   prints the share of it covered by its neighbours' discs,
//!   `f1·α + f2·β − f3·γ`: `f1` inked orthogonal neighbours, each covering `α` of it; `f2`
//!   inked diagonal neighbours whose two adjacent orthogonal neighbours are both blank, each
//!   covering `β`; `f3` pairs of adjacent orthogonal neighbours both inked, whose discs
//!   overlap on `γ`. For ρ ≤ √2 this is the exact covered area (a diagonal disc inside the
//!   pixel lies within either orthogonal disc next to it, and opposite discs never meet), which
//!   `tests/it/accuracy.rs` checks against a supersampled rasterisation of the discs.
//! - **a measured table** (`--printer-table FILE`): the printed reflectance of the centre
//!   pixel for each of the 512 neighbourhoods, as measured on a real printer (the "3×3
//!   table" models of Wang, Pappas and others).
//!
//! Neighbourhood index: bit `k` is set when the pixel at `(dx, dy) = (k % 3 − 1, k / 3 − 1)`
//! holds ink (k = 4 is the centre pixel itself). Pixels outside the page hold no ink.

use std::path::Path;

use crate::error::{Error, Result};
use crate::quality::Reflectance;
use crate::raster::Halftone;

/// Number of 3×3 neighbourhoods.
pub const NEIGHBOURHOODS: usize = 512;

/// Bit of the centre pixel in a neighbourhood index.
pub const CENTRE: usize = 1 << 4;

/// A printer model: the printed reflectance of a pixel for each 3×3 neighbourhood of dots.
#[derive(Clone, Debug, PartialEq)]
pub struct PrinterModel {
    /// A short name for reports, e.g. `dot-overlap 1.25`.
    pub name: String,
    /// Printed reflectance (0 = black, 1 = paper) of the centre pixel, by neighbourhood index.
    pub table: Vec<f32>,
}

/// The overlap areas of the circular-dot model at dot ratio `rho`, as shares of one pixel's
/// area: `α` (an orthogonal neighbour's disc inside the pixel), `β` (a diagonal neighbour's),
/// `γ` (the overlap of two adjacent orthogonal neighbours' discs inside the pixel).
pub fn overlap_areas(rho: f64) -> (f64, f64, f64) {
    // The pixel is the unit square [0,1]²; neighbours sit at (−½, ½) (left), (−½, −½)
    // (diagonal) and (½, −½) (below). Integrate the covered height over x with the midpoint
    // rule: the integrands are continuous, so 200 000 strips give about 1e-9.
    let r = rho / std::f64::consts::SQRT_2;
    let half_chord = |dx: f64| {
        let h2 = r * r - dx * dx;
        if h2 > 0.0 {
            Some(h2.sqrt())
        } else {
            None
        }
    };
    let n = 200_000;
    let dx = 1.0 / n as f64;
    let (mut a, mut b, mut g) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let x = (i as f64 + 0.5) * dx;
        let left = half_chord(x + 0.5).map(|h| (0.5 - h, 0.5 + h));
        let diag = half_chord(x + 0.5).map(|h| (-0.5 - h, -0.5 + h));
        let below = half_chord(x - 0.5).map(|h| (-0.5 - h, -0.5 + h));
        let len = |lo: f64, hi: f64| (hi.min(1.0) - lo.max(0.0)).max(0.0);
        if let Some((lo, hi)) = left {
            a += len(lo, hi) * dx;
            if let Some((lo2, hi2)) = below {
                g += len(lo.max(lo2), hi.min(hi2)) * dx;
            }
        }
        if let Some((lo, hi)) = diag {
            b += len(lo, hi) * dx;
        }
    }
    (a, b, g)
}

impl PrinterModel {
    /// The circular-dot overlap model at dot ratio `rho` (1 ≤ ρ ≤ √2).
    pub fn dot_overlap(rho: f64) -> Result<PrinterModel> {
        if !(1.0..=std::f64::consts::SQRT_2 + 1e-9).contains(&rho) {
            return Err(Error::Option {
                field: "dot_ratio",
                value: rho.to_string(),
                msg: "must be between 1 and 1.414 (√2)".into(),
            });
        }
        let (alpha, beta, gamma) = overlap_areas(rho);
        let bit = |i: usize, k: usize| (i >> k) & 1 == 1;
        let table = (0..NEIGHBOURHOODS)
            .map(|i| {
                if bit(i, 4) {
                    return 0.0;
                }
                let (nw, n, ne, w, e, sw, s, se) = (
                    bit(i, 0),
                    bit(i, 1),
                    bit(i, 2),
                    bit(i, 3),
                    bit(i, 5),
                    bit(i, 6),
                    bit(i, 7),
                    bit(i, 8),
                );
                let f1 = [n, w, e, s].iter().filter(|&&b| b).count() as f64;
                let f2 = [
                    nw && !n && !w,
                    ne && !n && !e,
                    sw && !s && !w,
                    se && !s && !e,
                ]
                .iter()
                .filter(|&&b| b)
                .count() as f64;
                let f3 = [n && e, e && s, s && w, w && n]
                    .iter()
                    .filter(|&&b| b)
                    .count() as f64;
                (1.0 - (f1 * alpha + f2 * beta - f3 * gamma)) as f32
            })
            .collect();
        Ok(PrinterModel {
            name: format!("dot-overlap {rho}"),
            table,
        })
    }

    /// A measured table: plain text, `#` comments, 512 numbers (printed reflectance of the
    /// centre pixel, 0..=1) in neighbourhood-index order (see the module documentation).
    pub fn parse_table(text: &str, origin: &str) -> Result<PrinterModel> {
        let mut table = Vec::with_capacity(NEIGHBOURHOODS);
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("");
            for word in line.split_whitespace() {
                let v: f32 = word.parse().map_err(|_| {
                    Error::parse(origin, i + 1, format!("'{word}' is not a number"))
                })?;
                if !(0.0..=1.0).contains(&v) {
                    return Err(Error::parse(
                        origin,
                        i + 1,
                        format!("{v}: a reflectance must be between 0 and 1"),
                    ));
                }
                if table.len() == NEIGHBOURHOODS {
                    return Err(Error::parse(
                        origin,
                        i + 1,
                        format!("more than {NEIGHBOURHOODS} entries"),
                    ));
                }
                table.push(v);
            }
        }
        if table.len() != NEIGHBOURHOODS {
            return Err(Error::parse(
                origin,
                text.lines().count(),
                format!(
                    "{} entries; a 3x3 table needs {NEIGHBOURHOODS}",
                    table.len()
                ),
            ));
        }
        Ok(PrinterModel {
            name: format!("table {origin}"),
            table,
        })
    }

    /// Reads a measured table file (see [`PrinterModel::parse_table`]).
    pub fn load_table(path: &Path) -> Result<PrinterModel> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse_table(&text, &path.display().to_string())
    }

    /// The table as a file [`PrinterModel::parse_table`] reads back: eight entries a line.
    pub fn to_table_text(&self) -> String {
        let mut s = format!(
            "# halftone 3x3 printer table: {}\n# printed reflectance of the centre pixel by \
             neighbourhood index (bit k = ink at dx = k%3-1, dy = k/3-1)\n",
            self.name
        );
        for chunk in self.table.chunks(8) {
            let line: Vec<String> = chunk.iter().map(|v| format!("{v:.6}")).collect();
            s.push_str(&line.join(" "));
            s.push('\n');
        }
        s
    }

    /// Neighbourhood index of every pixel of an ink map (`ink[i]` = 1 where a dot is
    /// printed), `width × height`, row-major.
    pub fn neighbourhoods(ink: &[u8], width: usize, height: usize) -> Vec<u16> {
        let mut out = vec![0u16; width * height];
        for y in 0..height {
            for x in 0..width {
                let mut idx = 0u16;
                for k in 0..9 {
                    let (dx, dy) = (k % 3, k / 3);
                    let (sx, sy) = ((x + dx).wrapping_sub(1), (y + dy).wrapping_sub(1));
                    if sx < width && sy < height && ink[sy * width + sx] != 0 {
                        idx |= 1 << k;
                    }
                }
                out[y * width + x] = idx;
            }
        }
        out
    }

    /// Printed reflectance of an ink map (`ink[i]` = 1 where a dot is printed).
    pub fn print_ink(&self, ink: &[u8], width: usize, height: usize) -> Vec<f32> {
        Self::neighbourhoods(ink, width, height)
            .iter()
            .map(|&i| self.table[i as usize])
            .collect()
    }

    /// Printed reflectance of a bilevel halftone's planes (level 0 = ink).
    pub fn print_halftone(&self, h: &Halftone) -> Result<Reflectance> {
        if h.levels != 2 || h.palette.is_some() {
            return Err(Error::Invalid(
                "a printer model applies to bilevel halftones only".into(),
            ));
        }
        let planes = (0..h.channels())
            .map(|c| {
                let ink: Vec<u8> = h.levels_of(c).iter().map(|&l| (l == 0) as u8).collect();
                self.print_ink(&ink, h.width, h.height)
            })
            .collect();
        Ok(Reflectance {
            width: h.width,
            height: h.height,
            planes,
        })
    }

    /// Printed reflectance of a halftone read back as reflectance (every sample 0 or 1;
    /// below one half is ink). Refuses multi-level images.
    pub fn print_reflectance(&self, r: &Reflectance) -> Result<Reflectance> {
        let planes = r
            .planes
            .iter()
            .map(|p| {
                if p.iter().any(|&v| v > 0.001 && v < 0.999) {
                    return Err(Error::Invalid(
                        "a printer model applies to bilevel halftones only; this one has \
                         grey levels"
                            .into(),
                    ));
                }
                let ink: Vec<u8> = p.iter().map(|&v| (v < 0.5) as u8).collect();
                Ok(self.print_ink(&ink, r.width, r.height))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Reflectance {
            width: r.width,
            height: r.height,
            planes,
        })
    }

    /// The ink share a 50% checkerboard prints at (Pappas–Neuhoff: (1 + 4α − 4γ)/2).
    pub fn checkerboard_ink(&self) -> f64 {
        // A blank pixel with its four orthogonal neighbours inked (bits 1, 3, 5, 7), and an
        // inked one with its four diagonal neighbours inked (bits 0, 2, 4, 6, 8).
        let blank = self.table[0b0_1010_1010] as f64;
        let inked = self.table[0b1_0101_0101] as f64;
        ((1.0 - blank) + (1.0 - inked)) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_areas_at_the_ends_of_the_range() {
        // ρ = 1: r = T/√2, the disc reaches x = r − ½ ≈ 0.207 into the neighbour.
        let (a, b, g) = overlap_areas(1.0);
        assert!(a > 0.0 && b == 0.0 && g == 0.0, "{a} {b} {g}");
        // At ρ = √2 (r = T) a 50% checkerboard covers its blank pixels fully:
        // 4α − 4γ = 1 (every point of the blank pixel is within T of one of its neighbours).
        let (a, _, g) = overlap_areas(std::f64::consts::SQRT_2);
        assert!((4.0 * a - 4.0 * g - 1.0).abs() < 1e-6, "{a} {g}");
        // Monotone in ρ.
        let (a1, b1, g1) = overlap_areas(1.2);
        let (a2, b2, g2) = overlap_areas(1.3);
        assert!(a2 > a1 && b2 >= b1 && g2 >= g1);
    }

    #[test]
    fn table_round_trips_and_checks() {
        let m = PrinterModel::dot_overlap(1.25).unwrap();
        let back = PrinterModel::parse_table(&m.to_table_text(), "t").unwrap();
        for (a, b) in m.table.iter().zip(&back.table) {
            assert!((a - b).abs() < 1e-6);
        }
        assert!(PrinterModel::parse_table("0.5 0.5", "t").is_err());
        assert!(PrinterModel::parse_table(&"2 ".repeat(512), "t").is_err());
        assert!(PrinterModel::dot_overlap(1.5).is_err());
        assert!(PrinterModel::dot_overlap(0.9).is_err());
    }
}
