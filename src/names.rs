//! Errors that teach: when a name is neither a built-in nor a file, say which names exist
//! and which one was probably meant, instead of "No such file or directory".

use std::path::Path;

use crate::error::Error;

/// Levenshtein distance between `a` and `b` (insertions, deletions and substitutions of
/// characters, each costing 1), computed one row at a time.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitute = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitute.min(row[j] + 1).min(diagonal + 1);
        }
    }
    row[b.len()]
}

/// The candidate closest to `name`, if it is close enough to be a likely typo or
/// abbreviation: a candidate that starts with `name` (`floyd` → `floyd-steinberg`), or one
/// within a third of its length in edits.
pub fn closest<'a>(name: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let lower = name.to_ascii_lowercase();
    if lower.len() >= 2 {
        if let Some(c) = candidates.iter().find(|c| c.starts_with(&lower)) {
            return Some(c);
        }
    }
    candidates
        .iter()
        .map(|c| (edit_distance(&lower, c), *c))
        .filter(|&(d, c)| d <= c.chars().count().div_ceil(3).max(1))
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// The error for a `what` (kernel, palette, mask…) named `name` that is neither a built-in
/// nor an existing file: lists the built-in names and the closest one.
pub fn unknown(what: &str, name: &str, candidates: &[&str]) -> Error {
    let mut msg = format!("{name}: no built-in {what} of that name and no such file");
    if let Some(c) = closest(name, candidates) {
        msg.push_str(&format!("; did you mean '{c}'?"));
    }
    msg.push_str(&format!(" (built-in {what}s: {})", candidates.join(", ")));
    Error::Invalid(msg)
}

/// [`unknown`] when `name` is not an existing path, so that a file that exists but cannot be
/// read still reports its own I/O error.
pub fn check_file_or_builtin(what: &str, name: &str, candidates: &[&str]) -> Result<(), Error> {
    if Path::new(name).exists() {
        Ok(())
    } else {
        Err(unknown(what, name, candidates))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("", ""), 0);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("stucki", "stuki"), 1);
        assert_eq!(edit_distance("abc", ""), 3);
    }

    #[test]
    fn closest_names() {
        let k = [
            "floyd-steinberg",
            "stucki",
            "sierra",
            "sierra-lite",
            "atkinson",
        ];
        assert_eq!(closest("floyd", &k), Some("floyd-steinberg"));
        assert_eq!(closest("stuki", &k), Some("stucki"));
        assert_eq!(closest("atkinsn", &k), Some("atkinson"));
        assert_eq!(closest("zzzzzz", &k), None);
        let p = ["epaper-7", "eink-4", "bw"];
        assert_eq!(closest("epaper-8", &p), Some("epaper-7"));
    }

    #[test]
    fn unknown_lists_every_name() {
        let e = unknown("kernel", "floyd", &["floyd-steinberg", "stucki"]).to_string();
        assert!(e.contains("did you mean 'floyd-steinberg'"), "{e}");
        assert!(e.contains("floyd-steinberg, stucki"), "{e}");
        assert!(!e.contains("No such file"), "{e}");
    }
}
