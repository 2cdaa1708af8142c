//! Fixed error-diffusion kernels: the classic tables, and user kernels from a small text file.
//!
//! # Kernel file format
//!
//! Plain text, one kernel row per line, `#` starts a comment. The first row holds `X`, the
//! pixel being quantised; the columns line up with it, so the column of `X` is the current
//! pixel's column in every row. Weights are non-negative integers; `-` (or `.`) marks an
//! empty cell. Cells at or before `X` in its own row must be empty: error only goes forward.
//! An optional last line `/ N` gives the divisor; without it the divisor is the sum of the
//! weights. Floyd–Steinberg reads:
//!
//! ```text
//! # Floyd–Steinberg (1976)
//! - X 7
//! 3 5 1
//! / 16
//! ```
//!
//! At most [`MAX_ROWS_BELOW`] rows below the current one and [`MAX_REACH`] columns either side.
//! Kernels reaching at most 3 columns (every built-in) run with their pending error in
//! registers, and in raster order on several threads; wider ones run on one thread per plane.
//!
//! # Tone
//!
//! Every built-in kernel keeps the mean tone of flat grey within 0.004 in linear reflectance
//! at all 256 input levels (measured away from the edges and the first rows; see
//! `tests/it/diffusion.rs`), except Atkinson: it passes on only 6/8 of the error, so dark and
//! light tones are pushed towards the nearest level. Measured on flat 8-bit sRGB greys,
//! decoded to linear light: its worst error is −0.125 at code 99 (linear 0.125 prints as
//! solid black), and tones below linear ≈ 0.125 or above ≈ 0.875 come out solid.

use std::path::Path;

use crate::error::{Error, Result};

/// Rows below the current row a kernel may reach.
pub const MAX_ROWS_BELOW: usize = 3;
/// Columns left or right of the current pixel a kernel may reach.
pub const MAX_REACH: usize = 8;

/// One weight of a kernel: `dx` columns right (in scan direction), `dy` rows down.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tap {
    /// Column offset in the scan direction (mirrored on right-to-left rows).
    pub dx: i32,
    /// Row offset (0 = current row, then the rows below).
    pub dy: u32,
    /// Integer weight; the share of the error is `weight / divisor`.
    pub weight: u32,
}

/// An error-diffusion kernel: integer weights over a common divisor.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Kernel {
    /// Name on the command line, or the file it came from.
    pub name: String,
    /// The weights, in reading order.
    pub taps: Vec<Tap>,
    /// The divisor. Normally the sum of the weights; Atkinson's is larger (it drops 2/8).
    pub divisor: u32,
}

/// The built-in kernels, each with its source. Written in the kernel file format so that
/// one parser serves built-ins and user files alike.
pub const BUILTIN: &[(&str, &str, &str)] = &[
    (
        "floyd-steinberg",
        "R. W. Floyd, L. Steinberg, \"An adaptive algorithm for spatial greyscale\", Proc. SID 17(2), 75-77, 1976",
        "- X 7\n3 5 1\n/ 16",
    ),
    (
        "jarvis-judice-ninke",
        "J. F. Jarvis, C. N. Judice, W. H. Ninke, \"A survey of techniques for the display of continuous tone pictures on bilevel displays\", CGIP 5, 13-40, 1976",
        "- - X 7 5\n3 5 7 5 3\n1 3 5 3 1\n/ 48",
    ),
    (
        "stucki",
        "P. Stucki, \"MECCA - a multiple-error correcting computation algorithm for bilevel image hardcopy reproduction\", IBM Research RZ1060, 1981",
        "- - X 8 4\n2 4 8 4 2\n1 2 4 2 1\n/ 42",
    ),
    (
        "burkes",
        "D. Burkes, 1988, as published in L. Crocker's DHALF.TXT (1989)",
        "- - X 8 4\n2 4 8 4 2\n/ 32",
    ),
    (
        "sierra",
        "F. Sierra, 1989 (three-row filter), as published in L. Crocker's DHALF.TXT",
        "- - X 5 3\n2 4 5 4 2\n- 2 3 2 -\n/ 32",
    ),
    (
        "sierra-2",
        "F. Sierra, 1990 (two-row filter), as published in L. Crocker's DHALF.TXT",
        "- - X 4 3\n1 2 3 2 1\n/ 16",
    ),
    (
        "sierra-lite",
        "F. Sierra, 1990 (\"Filter Lite\", Sierra-2-4A), as published in L. Crocker's DHALF.TXT",
        "- X 2\n1 1 -\n/ 4",
    ),
    (
        "atkinson",
        "B. Atkinson, Apple MacPaint (1984); spreads 6/8 of the error, dropping the rest",
        "- X 1 1\n1 1 1 -\n- 1 - -\n/ 8",
    ),
    (
        "shiau-fan",
        "J. N. Shiau, Z. Fan, US patent 5,353,127 (1994); SPIE 2658, 222-225, 1996",
        "- - X 4\n1 1 2 -\n/ 8",
    ),
    (
        "shiau-fan-2",
        "J. N. Shiau, Z. Fan, US patent 5,353,127 (1994); SPIE 2658, 222-225, 1996",
        "- - - X 8\n1 1 2 4 -\n/ 16",
    ),
    (
        "fan",
        "Z. Fan, \"A simple modification of error diffusion weights\", IS&T 46th Annual Conference, 113-115, 1993",
        "- - X 7\n1 3 5 -\n/ 16",
    ),
];

impl Kernel {
    /// A built-in kernel by its command-line name.
    pub fn builtin(name: &str) -> Option<Kernel> {
        BUILTIN
            .iter()
            .find(|(n, _, _)| *n == name)
            .map(|(n, _, text)| Kernel::parse(text, n).expect("built-in kernels parse"))
    }

    /// The names of the built-in fixed kernels.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(n, _, _)| *n)
    }

    /// A built-in kernel by name, else a kernel file at that path.
    pub fn load(name_or_path: &str) -> Result<Kernel> {
        if let Some(k) = Kernel::builtin(name_or_path) {
            return Ok(k);
        }
        let path = Path::new(name_or_path);
        let text = crate::io::read_text(path, 1 << 20)?;
        Kernel::parse(&text, name_or_path)
    }

    /// Parses the kernel file format (see the module documentation). `origin` names the file
    /// in error messages and becomes the kernel's name.
    pub fn parse(text: &str, origin: &str) -> Result<Kernel> {
        let err = |line: usize, msg: String| Error::parse(origin, line, msg);
        let mut rows: Vec<(usize, Vec<&str>)> = Vec::new();
        let mut divisor: Option<(usize, u32)> = None;
        for (i, raw) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            if divisor.is_some() {
                return Err(err(line_no, "nothing may follow the divisor line".into()));
            }
            if let Some(d) = line.strip_prefix('/') {
                let d = d.trim();
                let v: u32 = d
                    .parse()
                    .map_err(|_| err(line_no, format!("divisor `{d}` is not a whole number")))?;
                if v == 0 {
                    return Err(err(line_no, "divisor must be positive".into()));
                }
                divisor = Some((line_no, v));
                continue;
            }
            rows.push((line_no, line.split_whitespace().collect()));
        }
        let Some((first_line, first)) = rows.first() else {
            return Err(err(0, "no kernel rows".into()));
        };
        let xs: Vec<usize> = first
            .iter()
            .enumerate()
            .filter(|(_, t)| t.eq_ignore_ascii_case("x"))
            .map(|(i, _)| i)
            .collect();
        if xs.len() != 1 {
            return Err(err(
                *first_line,
                "the first row must hold exactly one `X` (the current pixel)".into(),
            ));
        }
        let cx = xs[0];
        let width = first.len();
        if rows.len() > MAX_ROWS_BELOW + 1 {
            return Err(err(
                rows[MAX_ROWS_BELOW + 1].0,
                format!("at most {MAX_ROWS_BELOW} rows below the current pixel"),
            ));
        }
        let mut taps = Vec::new();
        for (dy, (line_no, cells)) in rows.iter().enumerate() {
            if cells.len() != width {
                return Err(err(
                    *line_no,
                    format!(
                        "{} cells, but the first row has {width}: columns must line up",
                        cells.len()
                    ),
                ));
            }
            for (col, cell) in cells.iter().enumerate() {
                let dx = col as i32 - cx as i32;
                if dy == 0 && col == cx {
                    continue;
                }
                if *cell == "-" || *cell == "." {
                    continue;
                }
                if cell.eq_ignore_ascii_case("x") {
                    return Err(err(*line_no, "only one `X` is allowed".into()));
                }
                let w: u32 = cell.parse().map_err(|_| {
                    err(
                        *line_no,
                        format!("`{cell}` is not a weight (a whole number, `-` or `X`)"),
                    )
                })?;
                if w == 0 {
                    continue;
                }
                if dy == 0 && dx < 0 {
                    return Err(err(
                        *line_no,
                        "weights left of `X` in its own row would go to pixels already done".into(),
                    ));
                }
                if dx.unsigned_abs() as usize > MAX_REACH {
                    return Err(err(
                        *line_no,
                        format!("a weight {dx} columns away: at most {MAX_REACH}"),
                    ));
                }
                taps.push(Tap {
                    dx,
                    dy: dy as u32,
                    weight: w,
                });
            }
        }
        // In u64: 36 weights of up to 2^32 − 1 cannot overflow it, and a sum past u32 is
        // refused rather than wrapped (a wrapped sum passed the growth check below).
        let sum: u64 = taps.iter().map(|t| t.weight as u64).sum();
        let Ok(sum) = u32::try_from(sum) else {
            return Err(err(
                *first_line,
                format!(
                    "the weights sum to {sum}, over the largest divisor ({}); use smaller weights",
                    u32::MAX
                ),
            ));
        };
        if sum == 0 {
            return Err(err(*first_line, "the kernel has no weights".into()));
        }
        let divisor = match divisor {
            Some((line_no, d)) if d < sum => {
                return Err(err(
                    line_no,
                    format!(
                        "divisor {d} is below the sum of the weights ({sum}): the error would grow"
                    ),
                ))
            }
            Some((_, d)) => d,
            None => sum,
        };
        Ok(Kernel {
            name: origin.to_string(),
            taps,
            divisor,
        })
    }

    /// Sum of the integer weights.
    pub fn weight_sum(&self) -> u32 {
        // Saturating: a kernel built by hand (not parsed) may hold any weights.
        self.taps
            .iter()
            .fold(0u32, |s, t| s.saturating_add(t.weight))
    }

    /// Rows below the current row that the kernel reaches.
    pub fn rows_below(&self) -> usize {
        self.taps.iter().map(|t| t.dy as usize).max().unwrap_or(0)
    }

    /// Largest horizontal offset of any weight.
    pub fn reach(&self) -> usize {
        self.taps
            .iter()
            .map(|t| t.dx.unsigned_abs() as usize)
            .max()
            .unwrap_or(0)
    }

    /// Writes the kernel back in the file format.
    pub fn to_text(&self) -> String {
        let reach = self.reach() as i32;
        let left = self.taps.iter().map(|t| -t.dx).max().unwrap_or(0).max(0);
        let right = reach.max(self.taps.iter().map(|t| t.dx).max().unwrap_or(0));
        let mut out = String::new();
        for dy in 0..=self.rows_below() as u32 {
            let cells: Vec<String> = (-left..=right)
                .map(|dx| {
                    if dy == 0 && dx == 0 {
                        "X".to_string()
                    } else {
                        self.taps
                            .iter()
                            .find(|t| t.dx == dx && t.dy == dy)
                            .map_or("-".to_string(), |t| t.weight.to_string())
                    }
                })
                .collect();
            out.push_str(&cells.join(" "));
            out.push('\n');
        }
        out.push_str(&format!("/ {}\n", self.divisor));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_sums_to_its_divisor() {
        for (name, _, _) in BUILTIN {
            let k = Kernel::builtin(name).unwrap();
            if *name == "atkinson" {
                // Atkinson passes on only 6/8 of the error by design.
                assert_eq!((k.weight_sum(), k.divisor), (6, 8));
            } else {
                assert_eq!(k.weight_sum(), k.divisor, "{name}");
            }
        }
    }

    #[test]
    fn weights_whose_sum_overflows_32_bits_are_refused() {
        // 4294967295 + 1 wraps to 0 in u32 ("no weights"); + 7 wraps to 6 and, with a
        // divisor of 16, passed the growth check as a kernel of pure noise.
        for text in ["- X 4294967295\n1 - -\n", "- X 4294967295\n3 5 -\n/ 16\n"] {
            let e = Kernel::parse(text, "big.kernel").unwrap_err().to_string();
            assert!(e.contains("weights sum to 42949"), "{e}");
        }
        let k = Kernel::parse("- X 4294967295\n", "max.kernel").unwrap();
        assert_eq!(k.weight_sum(), u32::MAX);
    }

    #[test]
    fn floyd_steinberg_taps() {
        let k = Kernel::builtin("floyd-steinberg").unwrap();
        let t: Vec<(i32, u32, u32)> = k.taps.iter().map(|t| (t.dx, t.dy, t.weight)).collect();
        assert_eq!(t, vec![(1, 0, 7), (-1, 1, 3), (0, 1, 5), (1, 1, 1)]);
        assert_eq!(k.divisor, 16);
    }

    #[test]
    fn divisors_of_the_table() {
        let want = [
            ("floyd-steinberg", 16),
            ("jarvis-judice-ninke", 48),
            ("stucki", 42),
            ("burkes", 32),
            ("sierra", 32),
            ("sierra-2", 16),
            ("sierra-lite", 4),
            ("atkinson", 8),
            ("shiau-fan", 8),
            ("shiau-fan-2", 16),
            ("fan", 16),
        ];
        for (n, d) in want {
            assert_eq!(Kernel::builtin(n).unwrap().divisor, d, "{n}");
        }
        assert_eq!(Kernel::builtin_names().count(), want.len());
    }

    #[test]
    fn text_round_trip() {
        for n in Kernel::builtin_names() {
            let k = Kernel::builtin(n).unwrap();
            let back = Kernel::parse(&k.to_text(), n).unwrap();
            assert_eq!(k, back, "{n}");
        }
    }

    #[test]
    fn bad_files_name_file_and_line() {
        let cases = [
            ("- X 7\n3 5\n/ 16", ":2:"),
            ("- 7 7\n3 5 1", ":1:"),
            ("- X 7\n3 q 1", ":2:"),
            ("- X 7\n3 5 1\n/ 3", ":3:"),
            ("2 X 7\n3 5 1", ":1:"),
            ("", ":0:"),
        ];
        for (text, at) in cases {
            let e = Kernel::parse(text, "k.txt").unwrap_err().to_string();
            assert!(e.starts_with("k.txt") && e.contains(at), "{text:?}: {e}");
        }
    }

    #[test]
    fn divisor_defaults_to_sum() {
        let k = Kernel::parse("# mine\nX 2 # right\n1 1", "mine").unwrap();
        assert_eq!(k.divisor, 4);
        assert_eq!(k.rows_below(), 1);
    }
}
