//! `halftone batch`: many files on all cores, nothing lost.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::Context;
use clap::{ArgMatches, Args};
use indicatif::{ProgressBar, ProgressStyle};

use halftone::batch::{plan, Job, Shard};
use halftone::io::{Format, OutputFile};
use halftone::{Converter, Options};

use super::convert::{CommonArgs, FormatArg};

pub const EXAMPLES: &str = "Examples:
  halftone batch photos/ -o out/ --recursive --format pbm --method pattern
  halftone batch 'scans/*.png' -o out/ --preset laser-600 --report report.jsonl
  halftone batch in/ -o out/ --preset thermal-203 --jobs 2 --skip-existing
  halftone batch in/ -o out/ --recursive --shard 3/8     # one task of an array job
  halftone batch scans/ -o book.pdf --dpi 300 --method ordered  # every input a page";

/// `halftone batch` arguments.
#[derive(Args, Debug)]
pub struct BatchArgs {
    /// Input files, folders and glob patterns (quote patterns to keep the shell out).
    #[arg(required = true)]
    pub inputs: Vec<String>,

    /// Output folder; outputs mirror the input tree with the format's extension. A file
    /// of a multi-page format (book.pdf, all.ps, labels.zpl, ...) or - gets every input as
    /// a page, in sorted order.
    #[arg(long, short = 'o')]
    pub output: PathBuf,

    /// Output format (default: the preset's, else png).
    #[arg(long, short = 'f', value_enum)]
    pub format: Option<FormatArg>,

    /// Descend into subfolders of folder inputs.
    #[arg(long, short = 'r')]
    pub recursive: bool,

    /// Files in flight and threads in all (default: the number of cores). Each image's own
    /// parallelism shares these threads, so the cores are never oversubscribed and peak
    /// memory grows with --jobs, not with the number of files.
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,

    /// Skip inputs whose output already exists (resume an interrupted run).
    #[arg(long)]
    pub skip_existing: bool,

    /// Take the K-th of N slices of the sorted input list (for array jobs on a cluster).
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,

    /// Write a JSON line per file (input, output, method, pixels, seconds, status, error).
    #[arg(long, value_name = "FILE.jsonl")]
    pub report: Option<PathBuf>,

    /// No progress and no per-file lines; failures and the summary only.
    #[arg(long, short = 'q')]
    pub quiet: bool,

    #[command(flatten)]
    pub common: CommonArgs,
}

/// File extension for a format.
fn extension(f: Format) -> &'static str {
    f.extension()
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Status {
    Done,
    Skipped,
    Failed,
}

struct Outcome {
    job: Job,
    status: Status,
    pixels: u64,
    seconds: f64,
    error: Option<String>,
}

fn report_line(o: &Outcome, method: &str) -> String {
    let v = serde_json::json!({
        "input": o.job.input.display().to_string(),
        "output": o.job.output.display().to_string(),
        "method": method,
        "pixels": o.pixels,
        "seconds": (o.seconds * 1e4).round() / 1e4,
        "status": match o.status { Status::Done => "done", Status::Skipped => "skipped", Status::Failed => "failed" },
        "error": o.error,
    });
    v.to_string()
}

pub fn run(a: BatchArgs, matches: &ArgMatches) -> anyhow::Result<ExitCode> {
    let mut opts = a.common.options(matches)?;
    let preset_format = opts.format;
    let flag_format = a.format.map(Format::from);
    // Standard output takes the preset's format, as in `convert`; a file its extension's.
    let book = if a.output.as_os_str() == "-" {
        flag_format.or(preset_format)
    } else {
        flag_format
    };
    if let Some(format) = super::print_args::book_format(&a.output, book) {
        super::flag_check::check_used(matches, opts.method, Some(format))?;
        opts.format = Some(format);
        return run_book(&a, &opts, format);
    }
    let format: Format = flag_format.or(preset_format).unwrap_or(Format::Png);
    opts.format = Some(format);
    super::flag_check::check_used(matches, opts.method, Some(format))?;
    let conv = Converter::new(&opts)?;
    let method_name = conv.method().name();
    let jobs = a
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);

    let mut p = plan(&a.inputs, a.recursive, &a.output, extension(format));
    if let Some(shard) = a.shard {
        p.jobs = shard.select(p.jobs);
        p.failed = shard.select(p.failed);
    }
    // Written as files finish, into a temp file put in place at the end: a report that
    // cannot be written fails the run, and an interrupted run leaves no half report.
    let mut report = match &a.report {
        Some(path) => Some(OutputFile::create(path).context("cannot create the report")?),
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

    let mut outcomes: Vec<Outcome> = p
        .failed
        .iter()
        .map(|(input, why)| Outcome {
            job: Job {
                input: input.clone(),
                output: PathBuf::new(),
            },
            status: Status::Failed,
            pixels: 0,
            seconds: 0.0,
            error: Some(format!("{}: {why}", input.display())),
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
    let results: Mutex<Vec<Outcome>> = Mutex::new(Vec::with_capacity(total));
    let report_lock = Mutex::new(report.as_mut());
    std::thread::scope(|s| {
        for _ in 0..jobs.min(total.max(1)) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(job) = p.jobs.get(i) else { break };
                let start = Instant::now();
                let (status, pixels, error) = if a.skip_existing && job.output.exists() {
                    (Status::Skipped, 0, None)
                } else {
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
                            Err(e) => (Status::Failed, 0, Some(format!("{e:#}"))),
                        },
                    }
                };
                let o = Outcome {
                    job: job.clone(),
                    status,
                    pixels,
                    seconds: start.elapsed().as_secs_f64(),
                    error,
                };
                let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                if let Some(e) = &o.error {
                    log(format!("halftone: {e}"));
                } else if bar.is_none() && !a.quiet {
                    let what = if o.status == Status::Skipped {
                        "skipped (exists)"
                    } else {
                        "done"
                    };
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
                if let Some(f) = report_lock.lock().expect("report").as_mut() {
                    if let Err(e) = writeln!(f, "{}", report_line(&o, &method_name)) {
                        report_error.lock().expect("report").get_or_insert(e);
                    }
                }
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
            None => outcomes
                .iter()
                .try_for_each(|o| writeln!(f, "{}", report_line(o, &method_name))),
        };
        written
            .map_err(|e| halftone::Error::io(path, e))
            .and_then(|()| f.commit())
            .context("cannot write the report")?;
    }
    outcomes.extend(results.into_inner().expect("results"));
    outcomes.sort_by(|x, y| x.job.input.cmp(&y.job.input));

    let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
    let (ok, skipped, failed) = (
        count(Status::Done),
        count(Status::Skipped),
        count(Status::Failed),
    );
    let pixels: u64 = outcomes.iter().map(|o| o.pixels).sum();
    eprintln!(
        "halftone batch: {ok} done, {skipped} skipped, {failed} failed ({:.1} megapixels)",
        pixels as f64 / 1e6
    );
    for o in outcomes.iter().filter(|o| o.status == Status::Failed) {
        eprintln!(
            "  failed: {}",
            o.error.as_deref().unwrap_or("unknown error")
        );
    }
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `halftone batch ... -o book.pdf`: every input a page of one file, in sorted order
/// (the order `--shard` slices), each through the pipeline's per-page entry point in
/// turn (the image's own work uses the `--jobs` threads); any failure leaves no file.
fn run_book(a: &BatchArgs, opts: &Options, format: Format) -> anyhow::Result<ExitCode> {
    if a.skip_existing || a.report.is_some() {
        anyhow::bail!(
            "{}: --skip-existing and --report apply to a folder of outputs, not to one {} file",
            a.output.display(),
            extension(format)
        );
    }
    let conv = Converter::new(opts)?;
    let (mut files, failed) = halftone::batch::inputs(&a.inputs, a.recursive);
    if let Some((input, why)) = failed.first() {
        anyhow::bail!("{}: {why}", input.display());
    }
    if let Some(shard) = a.shard {
        files = shard.select(files);
    }
    if files.is_empty() {
        anyhow::bail!("{}: no input images", a.output.display());
    }
    if files
        .iter()
        .any(|f| super::convert::same_file(f, &a.output))
    {
        anyhow::bail!("{}: refusing to write over an input", a.output.display());
    }
    let jobs = a
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .context("cannot start worker threads")?;
    let start = Instant::now();
    let write = opts.write_options(format);
    let mut next = files.iter();
    let n = pool.install(|| {
        halftone::io::write_pages(&a.output, &write, |enc, out| {
            let Some(input) = next.next() else {
                return Ok(false);
            };
            conv.add_page(input.as_path(), format, enc, out, &a.output)?;
            Ok(true)
        })
    })?;
    if !a.quiet {
        eprintln!(
            "halftone batch: {n} pages -> {} ({:.2} s)",
            a.output.display(),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(ExitCode::SUCCESS)
}
