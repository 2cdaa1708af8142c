//! Planning a batch: which files, where their outputs go, which shard runs which.
//!
//! Inputs are files, folders (with `recursive`, their whole tree) and glob patterns. The list
//! is sorted and de-duplicated, so `--shard K/N` is deterministic: every machine of an array
//! job computes the same list and takes every N-th file starting at the K-th.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use crate::error::{Error, Result};

/// File extensions a folder walk picks up (files named explicitly are taken whatever
/// their extension).
pub const IMAGE_EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "tif", "tiff", "bmp", "gif", "webp", "pbm", "pgm", "ppm", "pnm",
];

/// One file of a batch.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Job {
    /// The input file.
    pub input: PathBuf,
    /// Where its halftone goes.
    pub output: PathBuf,
}

/// A batch plan: the jobs, and inputs that could not be planned (with the reason).
#[derive(Clone, Debug, Default)]
pub struct Plan {
    /// Files to halftone, sorted by input path.
    pub jobs: Vec<Job>,
    /// Inputs that fail before starting: (input as given, reason).
    pub failed: Vec<(PathBuf, String)>,
}

fn is_image(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

fn has_glob_chars(s: &str) -> bool {
    s.contains(['*', '?', '['])
}

/// The leading components of a glob pattern that hold no wildcard: outputs mirror the tree
/// below it.
fn glob_base(pattern: &str) -> PathBuf {
    let mut base = PathBuf::new();
    for c in Path::new(pattern).components() {
        if has_glob_chars(&c.as_os_str().to_string_lossy()) {
            break;
        }
        base.push(c);
    }
    base
}

/// Expands input specs into (file, path relative to the output folder) pairs.
fn expand(
    specs: &[String],
    recursive: bool,
    outdir: &Path,
    failed: &mut Vec<(PathBuf, String)>,
) -> Vec<(PathBuf, PathBuf)> {
    let mut out = Vec::new();
    // An output folder inside an input folder is not descended into: a second run would
    // otherwise halftone the first run's outputs (and a third theirs).
    let outdir = outdir.canonicalize().ok();
    let is_outdir = |e: &walkdir::DirEntry| {
        e.depth() > 0
            && e.file_type().is_dir()
            && outdir.is_some()
            && e.path().canonicalize().ok() == outdir
    };
    for spec in specs {
        let path = Path::new(spec);
        if path.is_dir() {
            let walker = walkdir::WalkDir::new(path)
                .follow_links(true)
                .max_depth(if recursive { usize::MAX } else { 1 })
                .sort_by_file_name()
                .into_iter()
                .filter_entry(|e| !is_outdir(e));
            for entry in walker {
                match entry {
                    Ok(e) if e.file_type().is_file() && is_image(e.path()) => {
                        let rel = e
                            .path()
                            .strip_prefix(path)
                            .unwrap_or(e.path())
                            .to_path_buf();
                        out.push((e.path().to_path_buf(), rel));
                    }
                    Ok(_) => {}
                    Err(err) => {
                        let p = err.path().unwrap_or(path).to_path_buf();
                        failed.push((p, format!("cannot read folder: {err}")));
                    }
                }
            }
        } else if path.is_file() || (spec != "-" && crate::io::is_stream(path)) {
            // A regular file, or a pipe, FIFO or `/dev/fd/N` given by name: one input.
            let name = path.file_name().map(PathBuf::from).unwrap_or_default();
            out.push((path.to_path_buf(), name));
        } else if has_glob_chars(spec) {
            let base = glob_base(spec);
            match glob::glob(spec) {
                Ok(paths) => {
                    let mut n = 0;
                    for p in paths.flatten() {
                        if p.is_file() {
                            let rel = p.strip_prefix(&base).unwrap_or(&p).to_path_buf();
                            out.push((p, rel));
                            n += 1;
                        }
                    }
                    if n == 0 {
                        failed.push((path.to_path_buf(), "no file matches this pattern".into()));
                    }
                }
                Err(e) => failed.push((path.to_path_buf(), format!("bad pattern: {e}"))),
            }
        } else {
            failed.push((path.to_path_buf(), "no such file or folder".into()));
        }
    }
    out
}

/// Plans a batch: inputs expanded and sorted, outputs under `outdir` mirroring the input
/// tree with extension `ext`, an output claimed by two inputs reported for the later ones,
/// an output that would overwrite an input refused.
pub fn plan(specs: &[String], recursive: bool, outdir: &Path, ext: &str) -> Plan {
    let mut failed = Vec::new();
    let mut pairs = expand(specs, recursive, outdir, &mut failed);
    pairs.sort();
    pairs.dedup_by(|a, b| a.0 == b.0);
    let mut claimed: BTreeMap<PathBuf, PathBuf> = BTreeMap::new();
    let mut jobs = Vec::new();
    for (input, rel) in pairs {
        // Never let `..` or an absolute part lead outside the output folder.
        let rel: PathBuf = rel
            .components()
            .filter(|c| matches!(c, Component::Normal(_)))
            .collect();
        let output = outdir.join(rel).with_extension(ext);
        if let Some(first) = claimed.get(&output) {
            failed.push((
                input,
                format!(
                    "its output {} is already the output of {}",
                    output.display(),
                    first.display()
                ),
            ));
            continue;
        }
        if same_path(&input, &output) {
            failed.push((input, "refusing to write over the input".into()));
            continue;
        }
        claimed.insert(output.clone(), input.clone());
        jobs.push(Job { input, output });
    }
    Plan { jobs, failed }
}

/// The inputs of a batch alone, sorted and de-duplicated in the order [`plan`] gives its
/// jobs (for outputs that gather every input into one file, such as a PDF book).
pub fn inputs(specs: &[String], recursive: bool) -> (Vec<PathBuf>, Vec<(PathBuf, String)>) {
    let mut failed = Vec::new();
    let mut files: Vec<PathBuf> = expand(specs, recursive, Path::new(""), &mut failed)
        .into_iter()
        .map(|(input, _)| input)
        .collect();
    files.sort();
    files.dedup();
    (files, failed)
}

fn same_path(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// A shard `K/N`: the K-th (1-based) of N slices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which slice, 1..=n.
    pub k: usize,
    /// How many slices.
    pub n: usize,
}

impl std::str::FromStr for Shard {
    type Err = Error;
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || {
            Error::Invalid(format!(
                "--shard {s}: expected K/N with 1 <= K <= N, e.g. 2/8"
            ))
        };
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (usize, usize) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if n == 0 || k == 0 || k > n {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }
}

impl Shard {
    /// Keeps this shard's jobs: every N-th, starting at the K-th, of the sorted list.
    pub fn select<T>(&self, items: Vec<T>) -> Vec<T> {
        items
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % self.n == self.k - 1)
            .map(|(_, t)| t)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_everything_once() {
        let items: Vec<usize> = (0..200).collect();
        let mut all: Vec<usize> = (1..=3)
            .flat_map(|k| Shard { k, n: 3 }.select(items.clone()))
            .collect();
        all.sort();
        assert_eq!(all, items);
        assert!("0/3".parse::<Shard>().is_err());
        assert!("4/3".parse::<Shard>().is_err());
        assert!("x".parse::<Shard>().is_err());
        assert_eq!("2/3".parse::<Shard>().unwrap(), Shard { k: 2, n: 3 });
    }

    #[test]
    fn mirrors_tree_and_reports_collisions() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("in/sub dir")).unwrap();
        for f in ["in/a.png", "in/a.jpg", "in/sub dir/ü b.png", "in/notes.txt"] {
            std::fs::write(d.join(f), b"x").unwrap();
        }
        let out = d.join("out");
        let specs = vec![d.join("in").display().to_string()];
        let p = plan(&specs, true, &out, "pbm");
        let outs: Vec<PathBuf> = p.jobs.iter().map(|j| j.output.clone()).collect();
        assert_eq!(outs, vec![out.join("a.pbm"), out.join("sub dir/ü b.pbm")]);
        assert_eq!(p.failed.len(), 1, "a.jpg and a.png both want a.pbm");
        assert!(p.failed[0].1.contains("already the output of"));
        // Not recursive: the subfolder is left out.
        assert_eq!(plan(&specs, false, &out, "pbm").jobs.len(), 1);
        // Globs mirror below their fixed prefix; a pattern that matches nothing fails.
        let g = vec![
            format!("{}/in/**/*.png", d.display()),
            format!("{}/none/*.png", d.display()),
        ];
        let p = plan(&g, false, &out, "png");
        assert_eq!(p.jobs.len(), 2);
        assert!(p
            .jobs
            .iter()
            .any(|j| j.output == out.join("sub dir/ü b.png")));
        assert_eq!(p.failed.len(), 1);
        // Writing into the input folder with the same extension is refused.
        let p = plan(
            &[d.join("in/a.png").display().to_string()],
            false,
            &d.join("in"),
            "png",
        );
        assert!(p.jobs.is_empty());
        assert_eq!(p.failed[0].1, "refusing to write over the input");
    }

    #[test]
    fn output_folder_inside_the_input_tree_is_not_read() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("in/out/deeper")).unwrap();
        for f in ["in/a.png", "in/out/a.pbm", "in/out/deeper/b.pbm"] {
            std::fs::write(d.join(f), b"x").unwrap();
        }
        let specs = vec![d.join("in").display().to_string()];
        let p = plan(&specs, true, &d.join("in/out"), "pbm");
        let ins: Vec<PathBuf> = p.jobs.iter().map(|j| j.input.clone()).collect();
        assert_eq!(ins, vec![d.join("in/a.png")]);
        assert!(p.failed.is_empty(), "{:?}", p.failed);
    }
}
