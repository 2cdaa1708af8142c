//! `halftone print`: halftone files and send them to an IPP printer in a format it lists
//! (PWG raster, Apple raster or PDF), at a resolution it lists, then follow the job.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail};
use clap::Args;

use halftone::io::Format;
use halftone::serve::client::Target;
use halftone::{Book, Color};

use super::convert::FormatArg;
use super::option_args::CommonArgs;

pub const EXAMPLES: &str = "Examples:
  halftone print ipp://printer.local/ipp/print photo.jpg   # fitted to its default paper
  halftone print ipp://printer.local/ipp/print scan.png --method ordered --mask blue-noise-64
  halftone print ipp://10.0.0.7/ipp/print a.png b.png --format urf --dpi 600   # one job, 2 pages
  halftone print ipp://127.0.0.1:8631/ipp/print/receipt photo.jpg --no-wait  # a queue";

/// How long `print` follows a job before giving up.
const JOB_TIMEOUT: Duration = Duration::from_secs(600);

/// `halftone print` arguments.
#[derive(Args, Debug)]
pub struct PrintArgs {
    /// The printer: ipp://HOST[:PORT]/PATH (port 631 when not given).
    pub uri: String,

    /// Images to print, one page each, in one job.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,

    /// The format to send when the printer lists it (pwg, urf, pdf); default: PWG raster,
    /// then Apple raster, then PDF, the first the printer lists.
    #[arg(long, short = 'f', value_enum)]
    pub format: Option<FormatArg>,

    /// Send the job and return; do not wait for the printer to finish it.
    #[arg(long)]
    pub no_wait: bool,

    /// The job's name (default: the first file's name).
    #[arg(long, value_name = "NAME")]
    pub job_name: Option<String>,

    #[command(flatten)]
    pub common: CommonArgs,
}

pub fn run(a: PrintArgs) -> anyhow::Result<ExitCode> {
    let target = Target::parse(&a.uri).map_err(|e| anyhow!(e))?;
    let started = Instant::now();
    let info = target.printer_info()?;
    let mut opts = a.common.options()?;
    let colour = opts.color != Color::Gray || opts.palette.is_some();
    let wanted = a.format.map(Format::from);
    if let Some(w) = wanted {
        if halftone::serve::client::mime_type(w).is_none() {
            bail!(
                "--format {}: not a format printers take; use pwg, urf or pdf",
                w.name()
            );
        }
    }
    let Some(format) = info.choose_format(wanted, colour) else {
        bail!(
            "{}: the printer takes {}, none of PWG raster, Apple raster or PDF{}",
            target.uri,
            info.formats.join(", "),
            if colour { " in colour" } else { "" }
        );
    };
    let dpi_given = a.common.given_entries().iter().any(|(k, _)| k == "dpi");
    let wanted_dpi = opts.dpi.map(|d| d.round() as u32);
    let dpi = info
        .choose_resolution(format, wanted_dpi, dpi_given)
        .map_err(|e| anyhow!("{}: {e}", target.uri))?;
    if let Some(d) = dpi {
        opts.dpi = Some(d as f64);
    }
    // No size asked for: the printer's default media is the page and the picture is fitted
    // to it at the resolution chosen.
    let media = info
        .media_default
        .as_deref()
        .and_then(|m| Some((m, halftone::serve::client::media_size(m)?)))
        .filter(|_| {
            opts.width.is_none()
                && opts.height.is_none()
                && opts.fit.is_none()
                && opts.size.is_none()
                && opts.print.page.is_none()
                && opts.device.is_none()
        });
    if let (Some((_, page)), Some(d)) = (media, opts.dpi) {
        let px = |pt: f64| (pt * d / 72.0).floor().max(1.0) as usize;
        opts.print.page = Some(page);
        opts.fit = Some((px(page.width), px(page.height)));
    }
    opts.format = Some(format);
    a.common.check_used(&opts, Some(format))?;
    let mut book = Book::new(Vec::new(), &opts)?;
    for f in &a.files {
        book.add_page(f.as_path())?;
    }
    let pages = book.pages();
    let data = book.finish()?;
    let name = a.job_name.clone().unwrap_or_else(|| {
        a.files[0]
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "halftone".into())
    });
    let id = target.print_job(&data, format, &name)?;
    let what = format!(
        "{pages} page{} of {} at {} dpi{}, {} bytes",
        if pages == 1 { "" } else { "s" },
        format.name(),
        opts.dpi.map_or("its own".into(), |d| d.to_string()),
        media.map(|(m, _)| format!(" on {m}")).unwrap_or_default(),
        data.len()
    );
    if a.no_wait {
        println!("{}: job {id} sent: {what}", target.uri);
        return Ok(ExitCode::SUCCESS);
    }
    let st = target.wait_for_job(id, JOB_TIMEOUT)?;
    println!(
        "{}: job {id} {}: {what} in {:.1} s",
        target.uri,
        st.state_name(),
        started.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
