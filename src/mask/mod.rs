//! Threshold masks: n×m grids of pixel position numbers (the lecture's "mask of pixel
//! position numbers"), parsed from plain-text files, built in from masks/, or generated.
//!
//! File format: `#` starts a comment; each other non-blank line is one row of numbers
//! separated by white space or commas. A *position mask* holds 1..N (or 0..N−1) exactly
//! once each; [`Mask::parse_ranks`] also accepts any numbers (a threshold array from another
//! tool), ranking them with ties broken by position (row-major).

use std::path::Path;

use crate::error::{Error, Result};

pub mod generate;
pub mod warnings;

include!(concat!(env!("OUT_DIR"), "/builtin_masks.rs"));

/// A threshold mask: every cell's rank 0..N−1 (position number − 1), row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    /// Name: the built-in's name or the file's stem.
    pub name: String,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Rank of each cell, 0..width·height−1, each exactly once, row-major.
    pub ranks: Vec<u32>,
}

/// The most cells a mask may have (1024×1024; the largest generated mask, Bayer 256, has
/// 65536). Larger grids are refused while parsing, before the rank tables are built.
pub const MAX_CELLS: usize = 1 << 20;

struct Grid {
    rows: Vec<(usize, Vec<f64>)>, // (line number, values)
}

fn read_grid(text: &str, source: &Path) -> Result<Grid> {
    let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let content = line.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        let mut vals = Vec::new();
        for tok in content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let v: f64 = tok
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| Error::parse(source, line_no, format!("'{tok}' is not a number")))?;
            vals.push(v);
        }
        // Separators alone (`,`) hold no numbers: a blank line, not a row of width 0 (found
        // by fuzzing: a first row of width 0 gave an empty mask and a division by zero).
        if vals.is_empty() {
            continue;
        }
        if let Some((first_line, first)) = rows.first() {
            if vals.len() != first.len() {
                return Err(Error::parse(
                    source,
                    line_no,
                    format!(
                        "mask is not rectangular: this row has {} numbers, line {first_line} has {}",
                        vals.len(),
                        first.len()
                    ),
                ));
            }
        }
        if (rows.len() + 1).saturating_mul(vals.len()) > MAX_CELLS {
            return Err(Error::parse(
                source,
                line_no,
                format!("the mask has more than {MAX_CELLS} cells (1024x1024): too large"),
            ));
        }
        rows.push((line_no, vals));
    }
    if rows.is_empty() {
        return Err(Error::parse(source, 0, "mask file holds no numbers"));
    }
    Ok(Grid { rows })
}

impl Mask {
    /// Parses a position mask: the numbers 1..N (or 0..N−1), each exactly once.
    /// Errors name `source` and the line of the first missing, repeated or stray number.
    pub fn parse(text: &str, source: &Path) -> Result<Mask> {
        let grid = read_grid(text, source)?;
        let height = grid.rows.len();
        let width = grid.rows[0].1.len();
        let n = width * height;
        let mut all: Vec<(usize, f64)> = Vec::with_capacity(n);
        for (line, vals) in &grid.rows {
            all.extend(vals.iter().map(|&v| (*line, v)));
        }
        let base = if all.iter().any(|&(_, v)| v == 0.0) {
            0
        } else {
            1
        };
        let mut seen: Vec<Option<usize>> = vec![None; n];
        let mut ranks = Vec::with_capacity(n);
        for &(line, v) in &all {
            if v.fract() != 0.0 || v < base as f64 || v >= (n + base) as f64 {
                return Err(Error::parse(
                    source,
                    line,
                    format!(
                        "{v} is not a position number: a {width}x{height} mask holds {base}..{} once each",
                        n + base - 1
                    ),
                ));
            }
            let r = v as usize - base;
            if let Some(first) = seen[r] {
                return Err(Error::parse(
                    source,
                    line,
                    format!("number {v} is repeated (first on line {first})"),
                ));
            }
            seen[r] = Some(line);
            ranks.push(r as u32);
        }
        // Every slot filled: n distinct values in a range of n cannot miss one.
        Ok(Mask {
            name: stem(source),
            width,
            height,
            ranks,
        })
    }

    /// Parses any rectangular grid of numbers as ranks: smaller numbers light first, ties
    /// broken by position (row-major).
    pub fn parse_ranks(text: &str, source: &Path) -> Result<Mask> {
        let grid = read_grid(text, source)?;
        let height = grid.rows.len();
        let width = grid.rows[0].1.len();
        let vals: Vec<f64> = grid.rows.into_iter().flat_map(|(_, v)| v).collect();
        Ok(Mask::from_values(&stem(source), width, height, &vals))
    }

    /// Ranks arbitrary values (ties broken by position) into a mask.
    pub fn from_values(name: &str, width: usize, height: usize, values: &[f64]) -> Mask {
        assert_eq!(values.len(), width * height);
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));
        let mut ranks = vec![0u32; values.len()];
        for (r, &i) in order.iter().enumerate() {
            ranks[i] = r as u32;
        }
        Mask {
            name: name.to_string(),
            width,
            height,
            ranks,
        }
    }

    /// A built-in mask by name (the file stem in masks/).
    pub fn builtin(name: &str) -> Option<Mask> {
        BUILTIN_MASKS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(n, text)| {
                Mask::parse_ranks(text, Path::new(n)).expect("built-in masks are valid")
            })
    }

    /// Names and comment headers of the built-in masks.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN_MASKS.iter().map(|(n, _)| *n)
    }

    /// The comment lines at the top of a built-in mask's file (its description).
    pub fn builtin_description(name: &str) -> Option<String> {
        BUILTIN_MASKS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, t)| {
                t.lines()
                    .take_while(|l| l.starts_with('#'))
                    .map(|l| l.trim_start_matches('#').trim())
                    .collect::<Vec<_>>()
                    .join(" ")
            })
    }

    /// A built-in name or a path to a mask file. Position masks are required when `strict`
    /// (pattern halftoning); otherwise any numbers are taken as ranks.
    pub fn load(name_or_path: &str, strict: bool) -> Result<Mask> {
        if let Some(m) = Mask::builtin(name_or_path) {
            return Ok(m);
        }
        let path = Path::new(name_or_path);
        let names: Vec<&str> = Mask::builtin_names().collect();
        crate::names::check_file_or_builtin("mask", name_or_path, &names)?;
        // A mask of MAX_CELLS numbers of up to 8 digits, with separators and comments.
        let text = crate::io::read_text(path, (MAX_CELLS as u64) * 16 + (1 << 20))?;
        if strict {
            Mask::parse(&text, path)
        } else {
            Mask::parse_ranks(&text, path)
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.ranks.len()
    }

    /// True for an empty mask (never produced by the parsers).
    pub fn is_empty(&self) -> bool {
        self.ranks.is_empty()
    }

    /// Rank of the cell at (x, y), coordinates taken modulo the mask size.
    #[inline]
    pub fn rank(&self, x: usize, y: usize) -> u32 {
        self.ranks[(y % self.height) * self.width + (x % self.width)]
    }

    /// The mask as text in the masks/ file format (position numbers 1..N).
    pub fn to_text(&self, comment: &str) -> String {
        let digits = self.len().to_string().len();
        let mut s = String::new();
        for line in comment.lines() {
            s.push_str("# ");
            s.push_str(line);
            s.push('\n');
        }
        for row in self.ranks.chunks(self.width) {
            let cells: Vec<String> = row.iter().map(|r| format!("{:>digits$}", r + 1)).collect();
            s.push_str(&cells.join(" "));
            s.push('\n');
        }
        s
    }
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_3x3_is_the_lecture_mask() {
        let m = Mask::builtin("seed-3x3").unwrap();
        let numbers: Vec<u32> = m.ranks.iter().map(|r| r + 1).collect();
        assert_eq!(numbers, vec![8, 3, 7, 5, 1, 2, 4, 9, 6]);
        assert_eq!((m.width, m.height), (3, 3));
    }

    #[test]
    fn every_builtin_parses_strictly() {
        for name in Mask::builtin_names() {
            let text = BUILTIN_MASKS.iter().find(|(n, _)| *n == name).unwrap().1;
            Mask::parse(text, Path::new(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                Mask::builtin_description(name).unwrap().len() > 10,
                "{name} needs a comment"
            );
        }
    }

    #[test]
    fn errors_name_file_and_line() {
        let p = Path::new("bad.mask");
        let e = Mask::parse("1 2\n3\n", p).unwrap_err().to_string();
        assert_eq!(
            e,
            "bad.mask:2: mask is not rectangular: this row has 1 numbers, line 1 has 2"
        );
        let e = Mask::parse("# c\n1 2\n2 4\n", p).unwrap_err().to_string();
        assert_eq!(e, "bad.mask:3: number 2 is repeated (first on line 2)");
        let e = Mask::parse("1 2\n3 5\n", p).unwrap_err().to_string();
        assert!(
            e.starts_with("bad.mask:2: 5 is not a position number"),
            "{e}"
        );
        let e = Mask::parse("1 x\n", p).unwrap_err().to_string();
        assert_eq!(e, "bad.mask:1: 'x' is not a number");
        let e = Mask::parse("# only a comment\n", p)
            .unwrap_err()
            .to_string();
        assert_eq!(e, "bad.mask:0: mask file holds no numbers");
    }

    #[test]
    fn ranks_break_ties_by_position() {
        let m = Mask::parse_ranks("5 5\n0 9\n", Path::new("t")).unwrap();
        assert_eq!(m.ranks, vec![1, 2, 0, 3]);
    }

    #[test]
    fn text_round_trip() {
        let m = Mask::builtin("seed-3x3").unwrap();
        let back = Mask::parse(&m.to_text("x"), Path::new("seed-3x3")).unwrap();
        assert_eq!(m, back);
    }
}
