//! The lecture's two warnings about pattern cells ("Halftone Approximations"): symmetric
//! patterns that tile into vertical, horizontal or diagonal streaks, and isolated "on" pixels.

use super::Mask;

/// A problem found in one level's pattern.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// The level (number of lit pixels) whose pattern has the problem.
    pub level: usize,
    /// What is wrong, in words.
    pub what: String,
}

/// Checks every level 2..N−2 of a bilevel cell (tiled). A level streaks when its lit pixels
/// (or its dark ones) are exactly a union of whole rows, columns or wrapped diagonals: tiled,
/// those draw lines across the page. A lit pixel with no lit 8-neighbour is isolated. Level 1
/// is a single pixel by necessity and is not reported.
pub fn check(mask: &Mask) -> Vec<Warning> {
    let (w, h) = (mask.width, mask.height);
    let n = mask.len();
    // Each family of lines as lists of cell indices.
    let mut families: Vec<(&str, Vec<Vec<usize>>)> = vec![
        (
            "horizontal",
            (0..h)
                .map(|y| (0..w).map(|x| y * w + x).collect())
                .collect(),
        ),
        (
            "vertical",
            (0..w)
                .map(|x| (0..h).map(|y| y * w + x).collect())
                .collect(),
        ),
    ];
    if w == h && w > 1 {
        families.push((
            "diagonal",
            (0..w)
                .map(|d| (0..w).map(|i| i * w + (i + d) % w).collect())
                .collect(),
        ));
        families.push((
            "diagonal",
            (0..w)
                .map(|d| (0..w).map(|i| i * w + (d + w - i) % w).collect())
                .collect(),
        ));
    }
    let mut out = Vec::new();
    for k in 2..n.saturating_sub(1) {
        let lit: Vec<bool> = mask.ranks.iter().map(|&r| (r as usize) < k).collect();
        let mut found: Vec<String> = Vec::new();
        for (dir, lines) in &families {
            for (state, what) in [(true, "lit"), (false, "dark")] {
                // The pixels in `state` are exactly the union of the lines wholly in `state`.
                let mut covered = vec![false; n];
                for line in lines {
                    if line.iter().all(|&i| lit[i] == state) {
                        line.iter().for_each(|&i| covered[i] = true);
                    }
                }
                let exact = (0..n).all(|i| (lit[i] == state) == covered[i]);
                let msg = format!("{what} pixels form {dir} lines: {dir} streaks when tiled");
                if exact && !found.contains(&msg) {
                    found.push(msg);
                }
            }
        }
        out.extend(found.into_iter().map(|what| Warning { level: k, what }));
        let mut isolated = 0;
        for y in 0..h {
            for x in 0..w {
                if !lit[y * w + x] {
                    continue;
                }
                let has_neighbour = (0..3).any(|dy| {
                    (0..3).any(|dx| {
                        (dx != 1 || dy != 1)
                            && lit[((y + h + dy - 1) % h) * w + (x + w + dx - 1) % w]
                    })
                });
                if !has_neighbour {
                    isolated += 1;
                }
            }
        }
        if isolated > 0 {
            out.push(Warning {
                level: k,
                what: format!("{isolated} isolated lit pixel(s)"),
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn lecture_mask_has_no_streaks() {
        let m = Mask::builtin("seed-3x3").unwrap();
        let w = check(&m);
        assert!(w.iter().all(|w| !w.what.contains("streak")), "{w:?}");
    }

    #[test]
    fn row_order_mask_streaks() {
        // Lighting row by row draws horizontal lines at level 3.
        let m = Mask::parse("1 2 3\n4 5 6\n7 8 9\n", Path::new("rows")).unwrap();
        let w = check(&m);
        assert!(w.contains(&Warning {
            level: 3,
            what: "lit pixels form horizontal lines: horizontal streaks when tiled".into()
        }));
    }

    #[test]
    fn scattered_mask_isolates() {
        // Two lit pixels that do not touch even when tiled: 4x4 with 1 and 2 far apart.
        let m = Mask::parse(
            "1 5 6 7\n8 9 10 11\n12 13 2 14\n15 16 3 4\n",
            Path::new("s"),
        )
        .unwrap();
        let w = check(&m);
        assert!(
            w.iter()
                .any(|w| w.level == 2 && w.what.contains("isolated")),
            "{w:?}"
        );
    }
}
