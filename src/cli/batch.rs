//! `halftone batch`: many files on all cores, nothing lost; shards of an array job on a
//! cluster, resumable after a kill, and their reports merged.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use halftone::batch::{plan, ArrayTask, Job, ReportLine, Shard, ShardSpec, Status};
use halftone::io::{Format, OutputFile};
use halftone::{Converter, Options};

use super::convert::{CommonArgs, FormatArg};

/// Every input done (or its output already there, with `--skip-existing`).
pub const EXIT_DONE: u8 = 0;
/// Something other than an input went wrong (options, the output or report folder, a full
/// disk): run again, with `--skip-existing`.
pub const EXIT_FAILED: u8 = 1;
/// The batch is done but some inputs were rejected (not images, broken, too large); they
/// are in the report and the summary, and running again rejects them again.
pub const EXIT_REJECTED: u8 = 3;

pub const EXAMPLES: &str =
    "Shards: --shard K/N counts K from 1 (1/8 .. 8/8); every task plans the same sorted list and
takes every N-th file from the K-th. --shard auto reads the array task from the environment:
  Slurm        SLURM_ARRAY_TASK_ID within SLURM_ARRAY_TASK_MIN..MAX (and _STEP): the first
               index is shard 1. A task resubmitted alone (sbatch --array=2) is an array of
               one, so state the size: auto/N for --array=1-N, auto/LO-HI for --array=LO-HI.
  Kubernetes   JOB_COMPLETION_INDEX counts from 0: auto/N with N the Job's completions.
--jobs defaults to SLURM_CPUS_PER_TASK when it is set, else to the number of cores.

Resuming: with --skip-existing a run does only what is missing (outputs appear whole or not at
all). Temp files of killed runs on this host (.NAME.HOST.PID.N.tmp) are removed at the start,
and the report keeps the lines of the run that made each output.

Exit status:
  0    every input done (or already there)
  1    failed: an error other than a bad input (options, output folder, disk, report); run
       it again with --skip-existing
  2    the command line is wrong
  3    done, but some inputs were rejected (listed in the summary and the report as
       \"rejected\"); running again rejects them again
  130, 143, 129   interrupted by SIGINT, SIGTERM, SIGHUP (no partial output left)

Examples:
  halftone batch photos/ -o out/ --recursive --format pbm --method pattern
  halftone batch 'scans/*.png' -o out/ --preset laser-600 --report report.jsonl
  halftone batch in/ -o out/ --preset thermal-203 --jobs 2 --skip-existing
  halftone batch in/ -o out/ --recursive --shard 3/8     # one task of an array job
  SLURM_ARRAY_TASK_ID=3 halftone batch in/ -o out/ --shard auto/16 --report r3.jsonl
  halftone batch report merge report.jsonl r3.jsonl -o all.jsonl   # missing, twice, failed
  halftone batch scans/ -o book.pdf --dpi 300 --method ordered  # every input a page";

/// `halftone batch` arguments.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct BatchArgs {
    #[command(subcommand)]
    pub command: Option<BatchCommand>,

    /// Input files, folders and glob patterns (quote patterns to keep the shell out).
    #[arg(required = true)]
    pub inputs: Vec<String>,

    /// Output folder; outputs mirror the input tree with the format's extension. A file
    /// of a multi-page format (book.pdf, all.ps, labels.zpl, ...) or - gets every input as
    /// a page, in sorted order.
    #[arg(long, short = 'o', required = true)]
    pub output: Option<PathBuf>,

    /// Output format (default: the preset's, else png).
    #[arg(long, short = 'f', value_enum)]
    pub format: Option<FormatArg>,

    /// Descend into subfolders of folder inputs.
    #[arg(long, short = 'r')]
    pub recursive: bool,

    /// Files in flight and threads in all (default: SLURM_CPUS_PER_TASK when set, else the
    /// number of cores). Each image's own parallelism shares these threads, so the cores are
    /// never oversubscribed and peak memory grows with --jobs, not with the number of files.
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,

    /// Skip inputs whose output already exists (resume an interrupted run).
    #[arg(long)]
    pub skip_existing: bool,

    /// Take the K-th of N slices of the sorted input list, K counting from 1 (for array
    /// jobs on a cluster). `auto` reads the task from Slurm's or a Kubernetes indexed Job's
    /// environment; `auto/N` or `auto/LO-HI` states the array's size (see the notes below).
    #[arg(long, value_name = "K/N|auto[/N]", value_parser = parse_shard)]
    pub shard: Option<ShardSpec>,

    /// Write a JSON line per file (input, output, method, pixels, seconds, status, error,
    /// shard, planned); its folder is created if needed.
    #[arg(long, value_name = "FILE.jsonl")]
    pub report: Option<PathBuf>,

    /// No progress and no per-file lines; failures and the summary only.
    #[arg(long, short = 'q')]
    pub quiet: bool,

    #[command(flatten)]
    pub common: CommonArgs,
}

/// `halftone batch report ...`.
#[derive(Subcommand, Debug)]
pub enum BatchCommand {
    /// Work on batch reports.
    #[command(subcommand, after_long_help = REPORT_EXAMPLES)]
    Report(ReportCommand),
}

/// Examples shown by `halftone batch report --help` and `… merge --help`.
pub const REPORT_EXAMPLES: &str = "Examples:
  halftone batch in/ -o out/ --report r1.jsonl
  halftone batch report merge r1.jsonl -o all.jsonl   # what is missing, twice, failed";

/// `halftone batch report merge`.
#[derive(Subcommand, Debug)]
pub enum ReportCommand {
    /// Join the reports of an array's shards: print what is missing, written twice, failed
    /// or rejected across the whole array. Exit status as for a batch: 0 all done, 3 only
    /// rejected inputs, 1 anything missing, duplicated or failed.
    #[command(after_long_help = REPORT_EXAMPLES)]
    Merge(MergeArgs),
}

/// `halftone batch report merge` arguments.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// The shards' reports (JSON lines, as --report writes them).
    #[arg(required = true)]
    pub reports: Vec<PathBuf>,

    /// Write the merged report here: one line per input, the best outcome of its lines.
    #[arg(long, short = 'o', value_name = "FILE.jsonl")]
    pub output: Option<PathBuf>,
}

/// File extension for a format.
fn extension(f: Format) -> &'static str {
    f.extension()
}

/// Threads for the run: `--jobs`, else Slurm's CPUs for this task, else the cores.
fn jobs(given: Option<usize>) -> anyhow::Result<usize> {
    if let Some(j) = given {
        return Ok(j.max(1));
    }
    if let Ok(v) = std::env::var("SLURM_CPUS_PER_TASK") {
        let n: usize = v
            .trim()
            .parse()
            .ok()
            .filter(|&n| n > 0)
            .with_context(|| format!("SLURM_CPUS_PER_TASK={v:?} is not a count of CPUs"))?;
        return Ok(n);
    }
    Ok(std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// `--shard`, the library's message with its flag named.
fn parse_shard(s: &str) -> Result<ShardSpec, String> {
    s.parse()
        .map_err(|e: halftone::Error| super::flags_for_options(&e.to_string()))
}

/// The shard asked for, with `auto` read from the scheduler's environment.
fn shard(spec: Option<ShardSpec>) -> anyhow::Result<Option<Shard>> {
    spec.map(|s| s.resolve(&ArrayTask::from_vars(|k| std::env::var(k).ok())))
        .transpose()
        .map_err(Into::into)
}

/// An input's fault (the same on every run) or the run's (worth running again): an I/O
/// error on anything but the input (the output, its folder, the disk) is the run's.
fn classify(err: &anyhow::Error, job: &Job) -> Status {
    match err.downcast_ref::<halftone::Error>() {
        Some(halftone::Error::Io { path, .. }) if path != &job.input => Status::Failed,
        _ => Status::Rejected,
    }
}

/// Removes the temp files that killed runs on this host left beside this run's outputs and
/// report; returns the report lines found in a killed run's report, and how many temp files
/// of other hosts were left alone.
fn clean_up_after_killed_runs(
    jobs: &[Job],
    report: Option<&Path>,
) -> (Vec<ReportLine>, Vec<PathBuf>) {
    let folder = |p: &Path| -> PathBuf {
        match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        }
    };
    let mut dirs: BTreeSet<PathBuf> = jobs.iter().map(|j| folder(&j.output)).collect();
    dirs.extend(report.map(folder));
    // Nothing of this process is written yet, so a temp file under its own host and PID is
    // a namesake's from an earlier container or boot.
    let me = std::process::id();
    let scan = halftone::batch::scan_temp_files(
        dirs.iter().map(PathBuf::as_path),
        &halftone::io::this_host(),
        |pid| pid != me && halftone::batch::process_alive(pid),
    );
    // A killed run's report is its temp file `.REPORT.HOST.PID.N.tmp` beside the report.
    let report_temp = report.and_then(|r| {
        let name = r.file_name()?.to_string_lossy().into_owned();
        Some((folder(r), format!(".{name}.")))
    });
    let mut salvaged = Vec::new();
    for t in &scan.stale {
        if let Some((dir, prefix)) = &report_temp {
            let name = t.file_name().map(|n| n.to_string_lossy().into_owned());
            if folder(t) == *dir && name.is_some_and(|n| n.starts_with(prefix.as_str())) {
                if let Ok((lines, _)) = halftone::batch::read_report_file(t, false) {
                    salvaged.extend(lines);
                }
            }
        }
        let _ = std::fs::remove_file(t);
    }
    (salvaged, scan.foreign)
}

pub fn run(mut a: BatchArgs) -> anyhow::Result<ExitCode> {
    if let Some(BatchCommand::Report(ReportCommand::Merge(m))) = a.command.take() {
        return run_merge(&m);
    }
    let output = a.output.clone().context("give the output: -o FOLDER")?;
    let mut opts = a.common.options()?;
    let preset_format = opts.format;
    let flag_format = a.format.map(Format::from);
    // Standard output takes the preset's format, as in `convert`; a file its extension's.
    let book = if output.as_os_str() == "-" {
        flag_format.or(preset_format)
    } else {
        flag_format
    };
    if let Some(format) = book_format(&output, book) {
        a.common.check_used(&opts, Some(format))?;
        opts.format = Some(format);
        return run_book(&a, &output, &opts, format);
    }
    let format: Format = flag_format.or(preset_format).unwrap_or(Format::Png);
    opts.format = Some(format);
    a.common.check_used(&opts, Some(format))?;
    let conv = Converter::new(&opts)?;
    let method_name = conv.method().name();
    let shard = shard(a.shard)?;
    let jobs = jobs(a.jobs)?;

    let mut p = plan(&a.inputs, a.recursive, &output, extension(format));
    if let Some(shard) = shard {
        p.jobs = shard.select(p.jobs);
        p.failed = shard.select(p.failed);
    }
    let shard_name = shard.map_or("1/1".to_string(), |s| format!("{}/{}", s.k, s.n));
    let planned = p.jobs.len() + p.failed.len();

    // A run killed by SIGKILL (the out-of-memory killer, a node lost) leaves its temp files;
    // they go now. Its report's whole lines, and an earlier run's report, tell which
    // outputs on disk they made, so a resumed report keeps those lines.
    let (salvaged, foreign) = clean_up_after_killed_runs(&p.jobs, a.report.as_deref());
    let mut earlier: BTreeMap<PathBuf, ReportLine> = BTreeMap::new();
    if a.skip_existing {
        let mut lines = salvaged;
        if let Some(path) = &a.report {
            if let Ok((read, _)) = halftone::batch::read_report_file(path, false) {
                lines.extend(read);
            }
        }
        for l in lines {
            if l.status == Status::Done {
                earlier.insert(l.input.clone(), l);
            }
        }
    }
    // Shown with --quiet too: files left in the outputs' folders deserve a word.
    if let Some(first) = foreign.first() {
        eprintln!(
            "halftone: note: {} temp file(s) of other hosts left alone (e.g. {}); remove them once those runs are over",
            foreign.len(),
            first.display()
        );
    }

    // Written as files finish, into a temp file put in place at the end: a report that
    // cannot be written fails the run, and an interrupted run leaves no half report. Each
    // line is flushed, so a killed run's lines can be read back by the next.
    let mut report = match &a.report {
        Some(path) => {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).with_context(|| {
                    format!("{}: cannot create the report's folder", dir.display())
                })?;
            }
            Some(OutputFile::create(path).context("cannot create the report")?)
        }
        None => None,
    };
    let report_error: Mutex<Option<std::io::Error>> = Mutex::new(None);

    let total = p.jobs.len();
    let terminal = std::io::stderr().is_terminal() && !a.quiet;
    let bar = if terminal {
        let b = ProgressBar::new(total as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} files  {per_sec}  {elapsed} elapsed, {eta} left  {msg}",
            )
            .expect("template"),
        );
        Some(b)
    } else {
        None
    };
    let log = |line: String| match &bar {
        Some(b) => b.println(line),
        None => eprintln!("{line}"),
    };
    let line = |input: &Path, output: &Path, status, pixels, seconds: f64, error| ReportLine {
        input: input.to_path_buf(),
        output: output.to_path_buf(),
        method: method_name.clone(),
        pixels,
        seconds: (seconds * 1e4).round() / 1e4,
        status,
        error,
        shard: Some(shard_name.clone()),
        planned: Some(planned),
    };

    let mut outcomes: Vec<ReportLine> = p
        .failed
        .iter()
        .map(|(input, why)| {
            line(
                input,
                Path::new(""),
                Status::Rejected,
                0,
                0.0,
                Some(format!("{}: {why}", input.display())),
            )
        })
        .collect();
    for o in &outcomes {
        log(format!(
            "halftone: {}",
            o.error.as_deref().unwrap_or_default()
        ));
    }

    // `jobs` workers take files in order; each file runs inside one shared pool of `jobs`
    // threads, so nested image parallelism never adds threads.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start worker threads")?;
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    // Outputs made by an earlier run whose report line is kept: skipped by this one.
    let kept = AtomicUsize::new(0);
    let kept_pixels = std::sync::atomic::AtomicU64::new(0);
    let results: Mutex<Vec<ReportLine>> = Mutex::new(Vec::with_capacity(total));
    let report_lock = Mutex::new(report.as_mut());
    let write_line = |o: &ReportLine| {
        if let Some(f) = report_lock.lock().expect("report").as_mut() {
            let json = serde_json::to_string(o).expect("a report line serialises");
            if let Err(e) = writeln!(f, "{json}").and_then(|()| f.flush()) {
                report_error.lock().expect("report").get_or_insert(e);
            }
        }
    };
    std::thread::scope(|s| {
        for _ in 0..jobs.min(total.max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(job) = p.jobs.get(i) else { break };
                let start = Instant::now();
                let existed = a.skip_existing && job.output.exists();
                let o = if existed {
                    // The line of the run that made it, when a report tells.
                    match earlier.get(&job.input).filter(|l| l.output == job.output) {
                        Some(l) => {
                            kept.fetch_add(1, Ordering::SeqCst);
                            kept_pixels.fetch_add(l.pixels, Ordering::SeqCst);
                            ReportLine {
                                shard: Some(shard_name.clone()),
                                planned: Some(planned),
                                ..l.clone()
                            }
                        }
                        None => line(&job.input, &job.output, Status::Skipped, 0, 0.0, None),
                    }
                } else {
                    let (status, pixels, error) =
                        match job.output.parent().map(std::fs::create_dir_all) {
                            Some(Err(e)) => (
                                Status::Failed,
                                0,
                                Some(format!(
                                    "{}: cannot create folder: {e}",
                                    job.output.display()
                                )),
                            ),
                            _ => match pool
                                .install(|| a.common.convert_file(&conv, &job.input, &job.output))
                            {
                                Ok(px) => (Status::Done, px, None),
                                Err(e) => (classify(&e, job), 0, Some(format!("{e:#}"))),
                            },
                        };
                    let secs = start.elapsed().as_secs_f64();
                    line(&job.input, &job.output, status, pixels, secs, error)
                };
                let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                if let Some(e) = &o.error {
                    log(format!("halftone: {e}"));
                } else if bar.is_none() && !a.quiet {
                    let what = if !existed { "done" } else { "skipped (exists)" };
                    log(format!(
                        "[{n}/{total}] {} -> {} {what} ({:.2} s)",
                        job.input.display(),
                        job.output.display(),
                        o.seconds
                    ));
                }
                if let Some(b) = &bar {
                    b.inc(1);
                }
                write_line(&o);
                results.lock().expect("results").push(o);
            });
        }
    });
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    if let (Some(mut f), Some(path)) = (report, &a.report) {
        let written = match report_error.into_inner().expect("report") {
            Some(e) => Err(e),
            None => outcomes.iter().try_for_each(|o| {
                writeln!(
                    f,
                    "{}",
                    serde_json::to_string(o).expect("a report line serialises")
                )
            }),
        };
        written
            .map_err(|e| halftone::Error::io(path, e))
            .and_then(|()| f.commit())
            .context("cannot write the report")?;
    }
    outcomes.extend(results.into_inner().expect("results"));
    outcomes.sort_by(|x, y| x.input.cmp(&y.input));

    let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
    let kept = kept.into_inner();
    let (ok, skipped, rejected, failed) = (
        count(Status::Done) - kept,
        count(Status::Skipped) + kept,
        count(Status::Rejected),
        count(Status::Failed),
    );
    let pixels: u64 = outcomes
        .iter()
        .filter(|o| o.status == Status::Done)
        .map(|o| o.pixels)
        .sum::<u64>()
        - kept_pixels.into_inner();
    let detail = if rejected + failed > 0 {
        format!(" ({rejected} inputs rejected, {failed} errors)")
    } else {
        String::new()
    };
    let shard_note = shard.map_or(String::new(), |s| format!(", shard {}/{}", s.k, s.n));
    eprintln!(
        "halftone batch: {ok} done, {skipped} skipped, {} failed{detail} ({:.1} megapixels{shard_note})",
        rejected + failed,
        pixels as f64 / 1e6
    );
    for o in outcomes
        .iter()
        .filter(|o| matches!(o.status, Status::Rejected | Status::Failed))
    {
        eprintln!(
            "  failed: {}",
            o.error.as_deref().unwrap_or("unknown error")
        );
    }
    Ok(ExitCode::from(if failed > 0 {
        EXIT_FAILED
    } else if rejected > 0 {
        EXIT_REJECTED
    } else {
        EXIT_DONE
    }))
}

/// `halftone batch report merge`: the shards' reports joined, with what is missing, written
/// twice, failed or rejected.
fn run_merge(m: &MergeArgs) -> anyhow::Result<ExitCode> {
    let mut all = Vec::new();
    for path in &m.reports {
        // Line by line, each line bounded: a file that is not a report (a disk image,
        // `/dev/zero`) is refused at its first line, not read whole.
        let (lines, _) = halftone::batch::read_report_file(path, true)?;
        all.extend(lines);
    }
    let merged = halftone::batch::merge_reports(all);
    let count = |s: Status| merged.with_status(s).count();
    let mut problems = 0;
    println!(
        "{} reports, {} files: {} done, {} skipped, {} rejected, {} failed",
        m.reports.len(),
        merged.lines.len(),
        count(Status::Done),
        count(Status::Skipped),
        count(Status::Rejected),
        count(Status::Failed)
    );
    if merged.shard_counts.len() > 1 {
        problems += 1;
        println!(
            "mixed arrays: shards of {} tasks",
            merged
                .shard_counts
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    for k in &merged.absent {
        problems += 1;
        println!("missing: shard {k} has no report line (run that task again)");
    }
    for (k, n) in &merged.short {
        problems += 1;
        println!("missing: shard {k} reports {n} file(s) fewer than it planned (run it again with --skip-existing)");
    }
    for (input, n) in &merged.duplicated {
        problems += 1;
        println!("duplicated: {} written {n} times", input.display());
    }
    for l in merged.with_status(Status::Failed) {
        problems += 1;
        println!("failed: {}", l.error.as_deref().unwrap_or("unknown error"));
    }
    for l in merged.with_status(Status::Rejected) {
        println!(
            "rejected: {}",
            l.error.as_deref().unwrap_or("unknown error")
        );
    }
    if let Some(out) = &m.output {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
        }
        halftone::io::write_atomic(out, |w| {
            for l in &merged.lines {
                writeln!(
                    w,
                    "{}",
                    serde_json::to_string(l).map_err(std::io::Error::other)?
                )?;
            }
            Ok(())
        })?;
    }
    let code = if problems > 0 {
        println!("incomplete: {problems} problem(s)");
        EXIT_FAILED
    } else if count(Status::Rejected) > 0 {
        println!(
            "complete but for {} rejected input(s)",
            count(Status::Rejected)
        );
        EXIT_REJECTED
    } else {
        println!("complete");
        EXIT_DONE
    };
    Ok(ExitCode::from(code))
}

/// `halftone batch ... -o book.pdf`: every input a page of one file, in sorted order
/// (the order `--shard` slices), each through the pipeline's per-page entry point in
/// turn (the image's own work uses the `--jobs` threads); any failure leaves no file.
fn run_book(
    a: &BatchArgs,
    output: &Path,
    opts: &Options,
    format: Format,
) -> anyhow::Result<ExitCode> {
    if a.skip_existing || a.report.is_some() {
        anyhow::bail!(
            "{}: --skip-existing and --report apply to a folder of outputs, not to one {} file",
            output.display(),
            extension(format)
        );
    }
    let conv = Converter::new(opts)?;
    let (mut files, failed) = halftone::batch::inputs(&a.inputs, a.recursive);
    if let Some((input, why)) = failed.first() {
        anyhow::bail!("{}: {why}", input.display());
    }
    if let Some(shard) = shard(a.shard)? {
        files = shard.select(files);
    }
    if files.is_empty() {
        anyhow::bail!("{}: no input images", output.display());
    }
    if files.iter().any(|f| super::convert::same_file(f, output)) {
        anyhow::bail!("{}: refusing to write over an input", output.display());
    }
    let jobs = jobs(a.jobs)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start worker threads")?;
    let start = Instant::now();
    let write = opts.write_options(format);
    let mut next = files.iter();
    let page = |enc: &mut dyn halftone::io::sink::PageEncoder, out: &mut dyn std::io::Write| {
        let Some(input) = next.next() else {
            return Ok(false);
        };
        conv.add_page(input.as_path(), format, enc, out, output)?;
        Ok(true)
    };
    let n = pool.install(|| {
        if super::stdio::is_dash(output) {
            super::stdio::check_stdout()?;
            let mut stdout = std::io::stdout().lock();
            halftone::io::write_pages_to(&mut stdout, output, &write, page)
        } else {
            halftone::io::write_pages(output, &write, page)
        }
    })?;
    if !a.quiet {
        eprintln!(
            "halftone batch: {n} pages -> {} ({:.2} s)",
            output.display(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The multi-page format of a batch writing into one file (`-o book.pdf`, or `-o -` with
/// a multi-page `--format`), `None` for a folder of outputs.
pub fn book_format(output: &Path, format: Option<Format>) -> Option<Format> {
    if output.as_os_str() == "-" {
        return format.filter(|f| f.is_multi_page());
    }
    if output.is_dir() {
        return None;
    }
    let by_name = Format::from_path(output).filter(|f| f.is_multi_page())?;
    Some(format.unwrap_or(by_name)).filter(|f| f.is_multi_page())
}
