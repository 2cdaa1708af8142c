//! Planning a batch: which files, where their outputs go, which shard runs which.
//!
//! Inputs are files, folders (with `recursive`, their whole tree) and glob patterns. The list
//! is sorted and de-duplicated, so `--shard K/N` is deterministic: every machine of an array
//! job computes the same list and takes every N-th file starting at the K-th.
//!
//! For array jobs, [`ShardSpec::resolve`] turns a scheduler's task variables (Slurm's array
//! index and range, a Kubernetes indexed Job's completion index) into a [`Shard`];
//! [`scan_temp_files`] finds the temp files that killed writers left; [`ReportLine`] is a
//! line of the JSON-lines report and [`merge_reports`] checks a whole array's reports.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

pub use crate::io::codec::IMAGE_EXTENSIONS;

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
        } else if path.is_file() || crate::io::is_stream(path) {
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
                "`shard` {s}: expected K/N with 1 <= K <= N, e.g. 2/8"
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

/// What `--shard` asks for: a fixed slice, or one read from the scheduler's environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardSpec {
    /// `K/N`: the K-th of N slices, counting from 1.
    Fixed(Shard),
    /// `auto`, `auto/N` or `auto/LO-HI`: from the array task's index.
    Auto(ArraySize),
}

/// How big the array of an `auto` shard is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArraySize {
    /// `auto`: Slurm's own range (`SLURM_ARRAY_TASK_MIN`..`MAX`, with its step).
    FromScheduler,
    /// `auto/N`: N tasks, Slurm's indices 1..=N or Kubernetes' 0..N.
    Count(usize),
    /// `auto/LO-HI`: the indices LO..=HI (`sbatch --array=LO-HI`), whichever the scheduler.
    Range(u64, u64),
}

impl std::str::FromStr for ShardSpec {
    type Err = Error;
    fn from_str(s: &str) -> Result<ShardSpec> {
        let Some(rest) = s.strip_prefix("auto") else {
            return s.parse().map(ShardSpec::Fixed);
        };
        let bad = || {
            Error::Invalid(format!(
                "`shard` {s}: expected auto, auto/N (N tasks) or auto/LO-HI (the array's index range, as given to sbatch --array)"
            ))
        };
        let size = match rest.strip_prefix('/') {
            None if rest.is_empty() => ArraySize::FromScheduler,
            None => return Err(bad()),
            Some(r) => match r.split_once('-') {
                Some((lo, hi)) => {
                    let lo: u64 = lo.trim().parse().map_err(|_| bad())?;
                    let hi: u64 = hi.trim().parse().map_err(|_| bad())?;
                    if hi < lo {
                        return Err(bad());
                    }
                    ArraySize::Range(lo, hi)
                }
                None => match r.trim().parse() {
                    Ok(n) if n > 0 => ArraySize::Count(n),
                    _ => return Err(bad()),
                },
            },
        };
        Ok(ShardSpec::Auto(size))
    }
}

/// The scheduler's variables that place an array task, as read from the environment (the
/// command line reads them; this module only does the arithmetic).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ArrayTask {
    /// `SLURM_ARRAY_TASK_ID`.
    pub slurm_id: Option<String>,
    /// `SLURM_ARRAY_TASK_MIN`.
    pub slurm_min: Option<String>,
    /// `SLURM_ARRAY_TASK_MAX`.
    pub slurm_max: Option<String>,
    /// `SLURM_ARRAY_TASK_STEP`.
    pub slurm_step: Option<String>,
    /// `JOB_COMPLETION_INDEX` (Kubernetes indexed Job; counts from 0).
    pub k8s_index: Option<String>,
}

impl ArrayTask {
    /// The variables, looked up by name through `var` (e.g. `|k| std::env::var(k).ok()`).
    pub fn from_vars(var: impl Fn(&str) -> Option<String>) -> ArrayTask {
        ArrayTask {
            slurm_id: var("SLURM_ARRAY_TASK_ID"),
            slurm_min: var("SLURM_ARRAY_TASK_MIN"),
            slurm_max: var("SLURM_ARRAY_TASK_MAX"),
            slurm_step: var("SLURM_ARRAY_TASK_STEP"),
            k8s_index: var("JOB_COMPLETION_INDEX"),
        }
    }
}

fn env_number(name: &str, value: &Option<String>) -> Result<Option<u64>> {
    match value {
        None => Ok(None),
        Some(v) => v.trim().parse().map(Some).map_err(|_| {
            let t = v.trim();
            let negative = t.strip_prefix('-').is_some_and(|d| {
                !d.is_empty()
                    && d.bytes().all(|b| b.is_ascii_digit())
                    && d.bytes().any(|b| b != b'0')
            });
            if negative {
                Error::Invalid(format!(
                    "`shard` auto: {name}={v:?} is below 0: array task indices are whole \
                     numbers from 0 up (as sbatch --array=LO-HI numbers them)"
                ))
            } else if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) {
                Error::Invalid(format!(
                    "`shard` auto: {name}={v:?} is too large for an array task index (at \
                     most {})",
                    u64::MAX
                ))
            } else {
                Error::Invalid(format!("`shard` auto: {name}={v:?} is not a whole number"))
            }
        }),
    }
}

impl ShardSpec {
    /// The shard this task runs: a fixed one as given; `auto` from the array task's index.
    ///
    /// Slurm (`SLURM_ARRAY_TASK_ID`): with `auto`, the K-th of the array's indices
    /// `MIN, MIN+STEP, ..., MAX`; with `auto/N`, index K of 1..=N (`--array=1-N`); with
    /// `auto/LO-HI`, index LO is shard 1. A task resubmitted alone (`sbatch --array=2`) sees
    /// a one-task array, so plain `auto` refuses it and asks for the size. Kubernetes
    /// (`JOB_COMPLETION_INDEX`, from 0) needs the size stated (`auto/N` with N the Job's
    /// completions): its pods are not told it.
    pub fn resolve(&self, task: &ArrayTask) -> Result<Shard> {
        let size = match self {
            ShardSpec::Fixed(s) => return Ok(*s),
            ShardSpec::Auto(size) => *size,
        };
        let err = |msg: String| Err(Error::Invalid(format!("`shard` auto: {msg}")));
        let range = |index: u64, lo: u64, hi: u64, step: u64, var: &str| {
            if index < lo || index > hi || !(index - lo).is_multiple_of(step) {
                let step_note = if step > 1 {
                    format!(" in steps of {step}")
                } else {
                    String::new()
                };
                return err(format!(
                    "{var}={index} is not among the array's indices {lo}..={hi}{step_note}"
                ));
            }
            Ok(Shard {
                k: ((index - lo) / step + 1) as usize,
                n: ((hi - lo) / step + 1) as usize,
            })
        };
        if let Some(id) = env_number("SLURM_ARRAY_TASK_ID", &task.slurm_id)? {
            let var = "SLURM_ARRAY_TASK_ID";
            return match size {
                ArraySize::Count(n) => {
                    if id == 0 || id > n as u64 {
                        return err(format!(
                            "{var}={id} is outside 1..={n}; `auto/{n}` counts Slurm's array from 1 (--array=1-{n}); for --array=0-{} give `shard` auto/0-{}",
                            n - 1,
                            n - 1
                        ));
                    }
                    range(id, 1, n as u64, 1, var)
                }
                ArraySize::Range(lo, hi) => range(id, lo, hi, 1, var),
                ArraySize::FromScheduler => {
                    let min = env_number("SLURM_ARRAY_TASK_MIN", &task.slurm_min)?;
                    let max = env_number("SLURM_ARRAY_TASK_MAX", &task.slurm_max)?;
                    let step = env_number("SLURM_ARRAY_TASK_STEP", &task.slurm_step)?
                        .unwrap_or(1)
                        .max(1);
                    let (Some(min), Some(max)) = (min, max) else {
                        return err(
                            "SLURM_ARRAY_TASK_ID is set without SLURM_ARRAY_TASK_MIN and _MAX; give the size: `shard` auto/N"
                                .into(),
                        );
                    };
                    if min == max {
                        return err(format!(
                            "this array has the one task {id} (a task resubmitted alone?), so its size is unknown; give it: `shard` auto/N (indices 1..=N) or auto/LO-HI"
                        ));
                    }
                    range(id, min, max, step, var)
                }
            };
        }
        if let Some(index) = env_number("JOB_COMPLETION_INDEX", &task.k8s_index)? {
            let var = "JOB_COMPLETION_INDEX";
            return match size {
                ArraySize::Count(n) => range(index, 0, n as u64 - 1, 1, var),
                ArraySize::Range(lo, hi) => range(index, lo, hi, 1, var),
                ArraySize::FromScheduler => err(format!(
                    "{var}={index}: a Kubernetes pod is not told its Job's completions; give them: `shard` auto/N"
                )),
            };
        }
        err("no array task in the environment (SLURM_ARRAY_TASK_ID for a Slurm array job, JOB_COMPLETION_INDEX for a Kubernetes indexed Job); outside one, give `shard` K/N (K counts from 1)".into())
    }
}

/// Temp files of atomic writes found in output folders, sorted by who left them.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TempScan {
    /// Left by processes of this host that no longer run: safe to remove.
    pub stale: Vec<PathBuf>,
    /// Written by processes of other hosts, whose state cannot be seen from here: left alone
    /// (their names never collide with ours).
    pub foreign: Vec<PathBuf>,
}

/// Finds the temp files (`.NAME.HOST.PID.N.tmp`) in `dirs`: those of `host` whose process
/// `alive` says is gone are stale, those of other hosts foreign, those of live processes
/// omitted. A folder that cannot be read is passed over (there is nothing to clean).
pub fn scan_temp_files<'a>(
    dirs: impl IntoIterator<Item = &'a Path>,
    host: &str,
    alive: impl Fn(u32) -> bool,
) -> TempScan {
    let mut scan = TempScan::default();
    let dirs: BTreeSet<&Path> = dirs.into_iter().collect();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name();
            let Some(writer) = crate::io::parse_temp_name(&name) else {
                continue;
            };
            if !e.file_type().is_ok_and(|t| t.is_file()) {
                continue;
            }
            if writer.host != host {
                scan.foreign.push(e.path());
            } else if !alive(writer.pid) {
                scan.stale.push(e.path());
            }
        }
    }
    scan.stale.sort();
    scan.foreign.sort();
    scan
}

/// Whether process `pid` of this host runs (a signal 0 probe: nothing is sent). A process
/// that exists but belongs to another user counts as running.
pub fn process_alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return false;
        };
        if pid <= 0 {
            return false;
        }
        // SAFETY: kill with signal 0 only checks that the process exists.
        if unsafe { libc::kill(pid, 0) } == 0 {
            return true;
        }
        std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// What became of one file of a batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Written by this run.
    Done,
    /// Its output existed already (`--skip-existing`).
    Skipped,
    /// The input cannot be halftoned (not an image, broken, too large, missing): running
    /// again gives the same answer; the rest of the batch is done.
    Rejected,
    /// Something other than the input went wrong (the output folder, a full disk): worth
    /// running again.
    Failed,
}

impl Status {
    /// Whether the file's output is in place.
    pub fn complete(self) -> bool {
        matches!(self, Status::Done | Status::Skipped)
    }
}

/// One line of a batch report (JSON lines): a file and what became of it.
///
/// Paths are JSON strings. A path that is not UTF-8 (a name such as `caf\xe9.png` from a
/// Latin-1 file system) is written with each byte that is not UTF-8 as `\xNN` in `input`
/// (or `output`), and its exact bytes in hex in `input_bytes` (or `output_bytes`), which a
/// reader takes in preference; UTF-8 paths are written as they are, with no such field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "WireLine", try_from = "WireLine")]
pub struct ReportLine {
    /// The input file.
    pub input: PathBuf,
    /// Its output (empty when the input was refused before planning an output).
    pub output: PathBuf,
    /// The method's name.
    #[serde(default)]
    pub method: String,
    /// Pixels of the input.
    #[serde(default)]
    pub pixels: u64,
    /// Seconds it took.
    #[serde(default)]
    pub seconds: f64,
    /// What became of it.
    pub status: Status,
    /// Why it was rejected or failed.
    #[serde(default)]
    pub error: Option<String>,
    /// The run's shard, `K/N` (`1/1` for a whole batch).
    #[serde(default)]
    pub shard: Option<String>,
    /// How many files the run's shard holds, so a merge can tell a report cut short.
    #[serde(default)]
    pub planned: Option<usize>,
}

/// A [`ReportLine`] as written: paths as text, with their bytes when they are not UTF-8.
#[derive(Serialize, Deserialize)]
struct WireLine {
    input: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    input_bytes: Option<String>,
    output: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    output_bytes: Option<String>,
    #[serde(default)]
    method: String,
    #[serde(default)]
    pixels: u64,
    #[serde(default)]
    seconds: f64,
    status: Status,
    #[serde(default)]
    error: Option<String>,
    #[serde(default)]
    shard: Option<String>,
    #[serde(default)]
    planned: Option<usize>,
}

/// A path as report text, and its bytes in hex when it is not UTF-8 (each byte that is not
/// UTF-8 shown as `\xNN` in the text).
fn path_text(p: &Path) -> (String, Option<String>) {
    if let Some(s) = p.to_str() {
        return (s.to_string(), None);
    }
    #[cfg(unix)]
    {
        use std::fmt::Write;
        use std::os::unix::ffi::OsStrExt;
        let bytes = p.as_os_str().as_bytes();
        let mut text = String::new();
        for chunk in bytes.utf8_chunks() {
            text.push_str(chunk.valid());
            for b in chunk.invalid() {
                let _ = write!(text, "\\x{b:02x}");
            }
        }
        let hex = bytes.iter().fold(String::new(), |mut h, b| {
            let _ = write!(h, "{b:02x}");
            h
        });
        (text, Some(hex))
    }
    #[cfg(not(unix))]
    {
        (p.to_string_lossy().into_owned(), None)
    }
}

/// The path a report line names: its bytes when given, else its text.
fn path_of(
    text: String,
    bytes: Option<String>,
    field: &str,
) -> std::result::Result<PathBuf, String> {
    let Some(hex) = bytes else {
        return Ok(PathBuf::from(text));
    };
    let bad = || format!("`{field}_bytes` is not an even number of hex digits");
    if hex.len() % 2 != 0 || !hex.is_ascii() {
        return Err(bad());
    }
    let raw = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad()))
        .collect::<std::result::Result<Vec<u8>, String>>()?;
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStringExt;
        Ok(PathBuf::from(std::ffi::OsString::from_vec(raw)))
    }
    #[cfg(not(unix))]
    {
        Ok(PathBuf::from(String::from_utf8_lossy(&raw).into_owned()))
    }
}

impl From<ReportLine> for WireLine {
    fn from(l: ReportLine) -> WireLine {
        let (input, input_bytes) = path_text(&l.input);
        let (output, output_bytes) = path_text(&l.output);
        WireLine {
            input,
            input_bytes,
            output,
            output_bytes,
            method: l.method,
            pixels: l.pixels,
            seconds: l.seconds,
            status: l.status,
            error: l.error,
            shard: l.shard,
            planned: l.planned,
        }
    }
}

impl TryFrom<WireLine> for ReportLine {
    type Error = String;
    fn try_from(w: WireLine) -> std::result::Result<ReportLine, String> {
        Ok(ReportLine {
            input: path_of(w.input, w.input_bytes, "input")?,
            output: path_of(w.output, w.output_bytes, "output")?,
            method: w.method,
            pixels: w.pixels,
            seconds: w.seconds,
            status: w.status,
            error: w.error,
            shard: w.shard,
            planned: w.planned,
        })
    }
}

/// The whole lines of a report that parse (a killed writer may leave its last line cut),
/// and how many lines did not.
pub fn parse_report(text: &str) -> (Vec<ReportLine>, usize) {
    let mut lines = Vec::new();
    let mut bad = 0;
    // Only whole lines: a tail without its newline is what a killed writer left mid-line.
    let whole = match text.rfind('\n') {
        Some(i) => &text[..i],
        None => "",
    };
    for l in whole.lines().filter(|l| !l.trim().is_empty()) {
        match serde_json::from_str(l) {
            Ok(r) => lines.push(r),
            Err(_) => bad += 1,
        }
    }
    (lines, bad)
}

/// The most bytes a report line may have. A line is some hundred bytes (an error message
/// and two paths); a longer one, or a file with no line break in its first MiB, is not a
/// report.
pub const MAX_REPORT_LINE: usize = 1 << 20;

/// Reads a report line by line from `reader` (`name` names it in errors), never holding
/// more than one line of at most [`MAX_REPORT_LINE`] bytes besides the lines read. A last
/// line without its line break that starts as a report line does (`{`) is what a killed
/// writer left mid-line and is passed over; one that parses is taken. A zero byte ends the
/// report (a report being written is made full size ahead, so a killed writer leaves
/// zeros); under `strict`, for a finished report, it is an error.
///
/// `strict`: the first line that is not a report line is an error naming the file and
/// the line; otherwise such lines are counted (the second value) and passed over. A line
/// over the bound, or a read error, is an error either way.
pub fn read_report(
    reader: &mut dyn std::io::BufRead,
    name: &Path,
    strict: bool,
) -> Result<(Vec<ReportLine>, usize)> {
    use std::io::{BufRead, Read};
    let mut lines = Vec::new();
    let mut bad = 0;
    let mut buf = Vec::new();
    for number in 1.. {
        buf.clear();
        let got = (&mut *reader)
            .take(MAX_REPORT_LINE as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(name, e))?;
        if got == 0 {
            break;
        }
        // A report being written is made full size ahead (zeros), so a killed writer's
        // file ends in zeros after its last line: the first zero ends the report.
        let padded = buf.iter().position(|&b| b == 0);
        if let Some(at) = padded {
            if strict {
                return Err(Error::Parse {
                    path: name.to_path_buf(),
                    line: number,
                    msg: "not a batch report: a zero byte (a finished report has none)".into(),
                });
            }
            buf.truncate(at);
        }
        let whole = padded.is_none() && buf.last() == Some(&b'\n');
        if !whole && buf.len() > MAX_REPORT_LINE {
            return Err(Error::Parse {
                path: name.to_path_buf(),
                line: number,
                msg: format!(
                    "not a batch report: no line break in {} MiB (a report line is one JSON \
                     object of some hundred bytes)",
                    MAX_REPORT_LINE >> 20
                ),
            });
        }
        let text = String::from_utf8_lossy(&buf);
        let text = text.trim();
        if text.is_empty() {
            if padded.is_some() {
                break;
            }
            continue;
        }
        match serde_json::from_str::<ReportLine>(text) {
            Ok(l) => lines.push(l),
            // A killed writer's last line, cut short.
            Err(_) if !whole && text.starts_with('{') => {}
            Err(e) => {
                if strict {
                    let shown: String = text.chars().take(40).collect();
                    let more = if shown.len() < text.len() { "..." } else { "" };
                    return Err(Error::Parse {
                        path: name.to_path_buf(),
                        line: number,
                        msg: format!("not a batch report line ({e}): {:?}{more}", shown),
                    });
                }
                bad += 1;
            }
        }
        if padded.is_some() {
            break;
        }
    }
    Ok((lines, bad))
}

/// [`read_report`] of the file at `path`, which may be a pipe or a device.
pub fn read_report_file(path: &Path, strict: bool) -> Result<(Vec<ReportLine>, usize)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            msg: "is a folder, not a batch report".into(),
        });
    }
    read_report(&mut std::io::BufReader::new(file), path, strict)
}

/// The verdict on an array's reports, joined.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Merged {
    /// One line per input: the best of its lines (done, then skipped, failed, rejected).
    pub lines: Vec<ReportLine>,
    /// Inputs written more than once (by two runs or two shards), with how many times.
    pub duplicated: Vec<(PathBuf, usize)>,
    /// Shards whose reports hold fewer files than they planned: (shard `K/N`, how many
    /// files are not reported).
    pub short: Vec<(String, usize)>,
    /// Shards `K/N` with no line at all, while other shards of the N exist.
    pub absent: Vec<String>,
    /// Shard counts found (more than one means reports of different arrays were mixed).
    pub shard_counts: Vec<usize>,
}

impl Merged {
    /// Lines with a given status.
    pub fn with_status(&self, s: Status) -> impl Iterator<Item = &ReportLine> {
        self.lines.iter().filter(move |l| l.status == s)
    }

    /// Whether every planned file is reported once with its output in place.
    pub fn complete(&self) -> bool {
        self.short.is_empty()
            && self.absent.is_empty()
            && self.duplicated.is_empty()
            && self.shard_counts.len() <= 1
            && self.lines.iter().all(|l| l.status.complete())
    }
}

/// Joins the lines of many reports (one or more per shard, in any order): the best status
/// per input, inputs written twice, per shard the files planned but never reported, and the
/// shards without any line (known from the others' `K/N`).
pub fn merge_reports(lines: impl IntoIterator<Item = ReportLine>) -> Merged {
    let rank = |s: Status| match s {
        Status::Done => 0,
        Status::Skipped => 1,
        Status::Failed => 2,
        Status::Rejected => 3,
    };
    let mut best: BTreeMap<PathBuf, ReportLine> = BTreeMap::new();
    let mut done: BTreeMap<PathBuf, usize> = BTreeMap::new();
    // Per shard: the planned count and the inputs seen.
    let mut shards: BTreeMap<String, (usize, BTreeSet<PathBuf>)> = BTreeMap::new();
    for l in lines {
        if l.status == Status::Done {
            *done.entry(l.input.clone()).or_default() += 1;
        }
        if let Some(s) = &l.shard {
            let e = shards.entry(s.clone()).or_default();
            e.0 = e.0.max(l.planned.unwrap_or(0));
            e.1.insert(l.input.clone());
        }
        match best.get(&l.input) {
            Some(b) if rank(b.status) <= rank(l.status) => {}
            _ => {
                best.insert(l.input.clone(), l);
            }
        }
    }
    // An input in two shards (plans that differ) is written twice as surely as one done twice.
    let mut owners: BTreeMap<&PathBuf, usize> = BTreeMap::new();
    for (_, inputs) in shards.values() {
        for i in inputs {
            *owners.entry(i).or_default() += 1;
        }
    }
    let mut duplicated: BTreeMap<PathBuf, usize> =
        done.into_iter().filter(|(_, n)| *n > 1).collect();
    for (i, n) in owners {
        if n > 1 {
            let e = duplicated.entry(i.clone()).or_default();
            *e = (*e).max(n);
        }
    }
    let order = |name: &String| {
        name.parse::<Shard>()
            .map(|s| (s.n, s.k))
            .unwrap_or_default()
    };
    let mut counts = BTreeSet::new();
    let mut short = Vec::new();
    for (name, (planned, inputs)) in &shards {
        if let Ok(s) = name.parse::<Shard>() {
            counts.insert(s.n);
        }
        if *planned > inputs.len() {
            short.push((name.clone(), planned - inputs.len()));
        }
    }
    short.sort_by_key(|(name, _)| order(name));
    let absent = counts
        .iter()
        .flat_map(|&n| (1..=n).map(move |k| format!("{k}/{n}")))
        .filter(|name| !shards.contains_key(name))
        .collect();
    Merged {
        lines: best.into_values().collect(),
        duplicated: duplicated.into_iter().collect(),
        short,
        absent,
        shard_counts: counts.into_iter().collect(),
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

    fn task(pairs: &[(&str, &str)]) -> ArrayTask {
        let map: BTreeMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        ArrayTask::from_vars(|k| map.get(k).cloned())
    }

    fn resolve(spec: &str, pairs: &[(&str, &str)]) -> Result<Shard> {
        spec.parse::<ShardSpec>()?.resolve(&task(pairs))
    }

    #[test]
    fn shard_specs_parse() {
        assert_eq!(
            "3/8".parse::<ShardSpec>().unwrap(),
            ShardSpec::Fixed(Shard { k: 3, n: 8 })
        );
        assert_eq!(
            "auto".parse::<ShardSpec>().unwrap(),
            ShardSpec::Auto(ArraySize::FromScheduler)
        );
        assert_eq!(
            "auto/16".parse::<ShardSpec>().unwrap(),
            ShardSpec::Auto(ArraySize::Count(16))
        );
        assert_eq!(
            "auto/0-15".parse::<ShardSpec>().unwrap(),
            ShardSpec::Auto(ArraySize::Range(0, 15))
        );
        for bad in [
            "auto/0", "auto/x", "auto/5-2", "autox", "auto/", "0/3", "auto/-3",
        ] {
            assert!(bad.parse::<ShardSpec>().is_err(), "{bad}");
        }
    }

    #[test]
    fn slurm_array_from_its_range() {
        let slurm = |id: &str, min: &str, max: &str| {
            resolve(
                "auto",
                &[
                    ("SLURM_ARRAY_TASK_ID", id),
                    ("SLURM_ARRAY_TASK_MIN", min),
                    ("SLURM_ARRAY_TASK_MAX", max),
                ],
            )
        };
        assert_eq!(slurm("1", "1", "3").unwrap(), Shard { k: 1, n: 3 });
        assert_eq!(slurm("3", "1", "3").unwrap(), Shard { k: 3, n: 3 });
        // An array numbered from 0, and one from 5.
        assert_eq!(slurm("0", "0", "15").unwrap(), Shard { k: 1, n: 16 });
        assert_eq!(slurm("7", "5", "8").unwrap(), Shard { k: 3, n: 4 });
        // --array=1-9:2 has the tasks 1, 3, 5, 7, 9.
        let stepped = resolve(
            "auto",
            &[
                ("SLURM_ARRAY_TASK_ID", "5"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "9"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
            ],
        );
        assert_eq!(stepped.unwrap(), Shard { k: 3, n: 5 });
        // A task resubmitted alone (sbatch --array=2) cannot know the array's size.
        let e = slurm("2", "2", "2").unwrap_err().to_string();
        assert!(e.contains("auto/N"), "{e}");
        assert!(slurm("x", "1", "3")
            .unwrap_err()
            .to_string()
            .contains("SLURM_ARRAY_TASK_ID=\"x\""));
    }

    #[test]
    fn slurm_array_with_a_stated_size_survives_resubmission() {
        // The whole array and the same task resubmitted alone map to the same shard.
        for (min, max) in [("1", "3"), ("2", "2")] {
            let vars = [
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", min),
                ("SLURM_ARRAY_TASK_MAX", max),
            ];
            assert_eq!(resolve("auto/3", &vars).unwrap(), Shard { k: 2, n: 3 });
            assert_eq!(resolve("auto/1-3", &vars).unwrap(), Shard { k: 2, n: 3 });
            assert_eq!(resolve("auto/0-2", &vars).unwrap(), Shard { k: 3, n: 3 });
        }
        let zero = resolve("auto/3", &[("SLURM_ARRAY_TASK_ID", "0")]).unwrap_err();
        assert!(zero.to_string().contains("auto/0-2"), "{zero}");
        assert!(resolve("auto/3", &[("SLURM_ARRAY_TASK_ID", "4")]).is_err());
    }

    #[test]
    fn kubernetes_index_counts_from_zero() {
        let k8s = |i: &str| resolve("auto/4", &[("JOB_COMPLETION_INDEX", i)]);
        assert_eq!(k8s("0").unwrap(), Shard { k: 1, n: 4 });
        assert_eq!(k8s("3").unwrap(), Shard { k: 4, n: 4 });
        assert!(k8s("4").is_err());
        let e = resolve("auto", &[("JOB_COMPLETION_INDEX", "1")]).unwrap_err();
        assert!(e.to_string().contains("auto/N"), "{e}");
        // Every index once: the slices cover the list once, as with K/N.
        let items: Vec<usize> = (0..50).collect();
        let mut all: Vec<usize> = (0..4)
            .flat_map(|i| k8s(&i.to_string()).unwrap().select(items.clone()))
            .collect();
        all.sort();
        assert_eq!(all, items);
    }

    #[test]
    fn no_scheduler_no_auto() {
        let e = resolve("auto", &[]).unwrap_err().to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
            "{e}"
        );
        assert_eq!(
            resolve("2/5", &[("SLURM_ARRAY_TASK_ID", "1")]).unwrap(),
            Shard { k: 2, n: 5 }
        );
    }

    #[test]
    fn temp_files_of_dead_writers_on_this_host_are_stale() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for f in [
            ".a.pbm.here.100.0.tmp",
            ".b.pbm.here.200.3.tmp",
            ".c.pbm.there.100.0.tmp",
            "d.pbm",
            ".e.pbm.tmp",
        ] {
            std::fs::write(d.join(f), b"").unwrap();
        }
        let scan = scan_temp_files([d, d], "here", |pid| pid == 200);
        assert_eq!(scan.stale, vec![d.join(".a.pbm.here.100.0.tmp")]);
        assert_eq!(scan.foreign, vec![d.join(".c.pbm.there.100.0.tmp")]);
        assert_eq!(
            scan_temp_files([d.join("none").as_path()], "here", |_| false),
            TempScan::default()
        );
        assert!(process_alive(std::process::id()));
    }

    fn line(input: &str, status: Status, shard: &str, planned: usize) -> ReportLine {
        ReportLine {
            input: input.into(),
            output: format!("out/{input}").into(),
            method: "m".into(),
            pixels: 1,
            seconds: 0.0,
            status,
            error: None,
            shard: Some(shard.into()),
            planned: Some(planned),
        }
    }

    #[test]
    fn merged_reports_show_missing_duplicated_and_failed() {
        use Status::*;
        let good = vec![
            line("a", Done, "1/2", 2),
            line("c", Rejected, "1/2", 2),
            line("b", Done, "2/2", 1),
        ];
        let m = merge_reports(good.clone());
        assert!(!m.complete(), "a rejected input is not complete");
        assert_eq!(m.with_status(Rejected).count(), 1);
        assert!(m.short.is_empty() && m.absent.is_empty() && m.duplicated.is_empty());
        // A shard cut short, a shard absent, a file done twice.
        let m = merge_reports(vec![
            line("a", Done, "1/3", 2),
            line("b", Done, "2/3", 2),
            line("b", Done, "2/3", 2),
        ]);
        assert_eq!(
            m.short,
            vec![("1/3".to_string(), 1), ("2/3".to_string(), 1)]
        );
        assert_eq!(m.absent, vec!["3/3".to_string()]);
        assert_eq!(m.duplicated, vec![(PathBuf::from("b"), 2)]);
        // A failed file that a later run did is complete; a skipped line counts as in place.
        let m = merge_reports(vec![
            line("a", Failed, "1/1", 2),
            line("a", Skipped, "1/1", 2),
            line("b", Done, "1/1", 2),
        ]);
        assert!(m.complete(), "{m:?}");
        assert_eq!(m.lines[0].status, Skipped);
        // The same input in two shards' plans is a duplicate.
        let m = merge_reports(vec![
            line("a", Done, "1/2", 1),
            line("a", Skipped, "2/2", 1),
        ]);
        assert_eq!(m.duplicated, vec![(PathBuf::from("a"), 2)]);
    }

    #[test]
    fn a_report_cut_mid_line_keeps_its_whole_lines() {
        let a = serde_json::to_string(&line("a", Status::Done, "1/1", 2)).unwrap();
        let b = serde_json::to_string(&line("b", Status::Done, "1/1", 2)).unwrap();
        let text = format!("{a}\n{}", &b[..b.len() / 2]);
        let (lines, bad) = parse_report(&text);
        assert_eq!((lines.len(), bad), (1, 0));
        assert_eq!(lines[0].input, PathBuf::from("a"));
        let (lines, bad) = parse_report(&format!("{a}\nnot json\n{b}\n"));
        assert_eq!((lines.len(), bad), (2, 1));
    }

    #[test]
    fn a_killed_writers_zero_padded_report_keeps_its_whole_lines() {
        let a = serde_json::to_string(&line("a", Status::Done, "1/1", 2)).unwrap();
        let b = serde_json::to_string(&line("b", Status::Done, "1/1", 2)).unwrap();
        let name = Path::new("r.jsonl");
        // Two whole lines, then zeros past the line bound; and a line cut by the zeros.
        for (tail, want) in [(String::new(), 2), (b[..b.len() / 2].to_string(), 2)] {
            let mut bytes = format!("{a}\n{b}\n{tail}").into_bytes();
            bytes.resize(bytes.len() + 3 * MAX_REPORT_LINE, 0);
            let (lines, bad) = read_report(&mut &bytes[..], name, false).unwrap();
            assert_eq!((lines.len(), bad), (want, 0));
            let e = read_report(&mut &bytes[..], name, true).unwrap_err();
            assert!(
                e.to_string().contains("r.jsonl:3: not a batch report"),
                "{e}"
            );
        }
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
