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

/// One kind of warning: its text, the levels it occurs at, and the smallest and largest
/// count of pixels it names.
type Group = (String, Vec<usize>, Option<(usize, usize)>);

/// The warnings in a few lines, one for each kind of problem: the level, or the levels as
/// ranges with their count (a 16x16 Bayer mask has isolated pixels at dozens of levels; one
/// line says so). Isolated-pixel counts are given as their range over those levels.
pub fn summarise(ws: &[Warning]) -> Vec<String> {
    let mut groups: Vec<Group> = Vec::new();
    for w in ws {
        let (kind, count) = match w.what.split_once(' ') {
            Some((n, rest)) if n.bytes().all(|b| b.is_ascii_digit()) => {
                (rest.to_string(), n.parse::<usize>().ok())
            }
            _ => (w.what.clone(), None),
        };
        let g = match groups.iter_mut().position(|g| g.0 == kind) {
            Some(i) => &mut groups[i],
            None => {
                groups.push((kind, Vec::new(), None));
                groups.last_mut().expect("just pushed")
            }
        };
        g.1.push(w.level);
        if let Some(c) = count {
            g.2 = Some(g.2.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
        }
    }
    groups
        .into_iter()
        .map(|(kind, levels, count)| {
            let what = match count {
                Some((lo, hi)) if lo == hi => format!("{lo} {kind}"),
                Some((lo, hi)) => format!("{lo} to {hi} {kind}"),
                None => kind,
            };
            if levels.len() == 1 {
                format!("level {}: {what}", levels[0])
            } else {
                format!(
                    "levels {} ({} levels): {what}",
                    ranges(&levels),
                    levels.len()
                )
            }
        })
        .collect()
}

/// Sorted numbers as ranges, `2-9, 12, 14-15`; past six ranges the rest are elided.
fn ranges(v: &[usize]) -> String {
    let mut v = v.to_vec();
    v.sort_unstable();
    v.dedup();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    if out.len() > 6 {
        let last = out.pop().expect("more than six");
        out.truncate(5);
        out.push(format!("… {last}"));
    }
    out.join(", ")
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

    #[test]
    fn summaries_are_one_line_a_kind() {
        let m = crate::mask::generate::bayer(16).unwrap();
        let ws = check(&m);
        assert!(ws.len() > 20, "{}", ws.len());
        let lines = summarise(&ws);
        assert!(lines.len() <= 4, "{lines:#?}");
        let iso = lines.iter().find(|l| l.contains("isolated")).unwrap();
        let n = ws.iter().filter(|w| w.what.contains("isolated")).count();
        assert!(iso.contains(&format!("({n} levels)")), "{iso}");
        // One warning keeps its level.
        let one = [Warning {
            level: 3,
            what: "2 isolated lit pixel(s)".into(),
        }];
        assert_eq!(summarise(&one), ["level 3: 2 isolated lit pixel(s)"]);
        assert_eq!(ranges(&[2, 3, 4, 9, 11, 12]), "2-4, 9, 11-12");
    }
}
