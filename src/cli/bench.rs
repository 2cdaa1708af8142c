//! `halftone bench`: every method's speed and visual accuracy, a chart of the two, and
//! (with --stability) where each method fails.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use halftone::bench::{self, BenchOptions};
use halftone::io::ReadOptions;
use halftone::quality::Viewing;
use halftone::stability::{self, StabilityOptions};

/// Examples shown by `halftone bench --help`.
pub const EXAMPLES: &str = "Examples:
  halftone bench -o bench-results
  halftone bench --images photos/ --methods threshold,pattern --runs 9
  halftone bench --stability -o bench-results
  halftone bench --motion clip.gif -o motion-results   # methods over time, not stills";

/// `halftone bench` arguments.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Folder of test images (searched recursively); default: ./samples if present (else the
    /// same pictures built into the binary), and a grey ramp.
    #[arg(long)]
    pub images: Option<PathBuf>,

    /// Methods to run, by registry key or its prefix, comma-separated (e.g.
    /// `threshold,pattern-3x3`); default: all.
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,

    /// Folder for results.csv, results.json, chart.svg and chart.png (created if missing).
    #[arg(long, short = 'o', default_value = "bench-results")]
    pub output: PathBuf,

    /// Timed runs per method and image; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub runs: usize,

    /// Resolution of the printed halftone for the quality figures, pixels per inch.
    #[arg(long, default_value_t = 300.0)]
    pub dpi: f64,

    /// Viewing distance for the quality figures, inches.
    #[arg(long, default_value_t = 12.0)]
    pub distance: f64,

    /// Also measure where methods fail (tone curve, start-up, texture, moiré, flicker, edge
    /// cases; saturated colours on every e-paper panel): writes stability.csv, stability.json,
    /// stability.md, panels.csv, heatmap.svg, heatmap.png.
    #[arg(long)]
    pub stability: bool,

    /// Measure the methods over time on this clip instead of the still images (animated GIF, APNG or WebP, a
    /// YUV4MPEG2 stream, a numbered series): HVS-PSNR, flicker in still areas and time a
    /// frame, each as `convert` halftones a clip; writes motion.csv, motion.json,
    /// motion.md, motion-chart.svg and motion-chart.png.
    #[arg(long, value_name = "CLIP")]
    pub motion: Option<PathBuf>,

    /// With --motion: the input "stayed" where its grey code moved by at most this much.
    #[arg(long, default_value_t = 2, requires = "motion")]
    pub noise: u8,

    /// With --motion: HVS-PSNR on every N-th frame.
    #[arg(long, default_value_t = 1, requires = "motion")]
    pub every: usize,

    /// Only the stability report, no timing.
    #[arg(long, requires = "stability")]
    pub no_timing: bool,

    /// Side of the stability test patches, pixels (48: whole 2×2, 3×3 and 4×4 cells).
    #[arg(long, default_value_t = 48)]
    pub patch: usize,

    /// Refuse images larger than this many pixels (checked from the header, before decoding).
    #[arg(long, default_value_t = 1_000_000_000)]
    pub max_pixels: u64,

    /// Also score every bilevel method as this printer would print it ("as printed" beside
    /// "ideal"), e.g. `--printer-model dot-overlap --dot-ratio 1.25`.
    #[command(flatten)]
    pub printer: super::option_args::PrinterArgs,
}

fn progress(len: usize, what: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len as u64);
    pb.set_style(
        ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    pb.set_prefix(what.to_string());
    pb
}

fn write(path: &Path, text: &str) -> anyhow::Result<()> {
    // Atomic, like every output: a failed or interrupted run leaves no half file.
    halftone::io::write_atomic(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| "cannot write the results".to_string())
}

/// Runs `halftone bench`.
pub fn run(a: BenchArgs) -> anyhow::Result<ExitCode> {
    let view = Viewing::new(a.dpi, a.distance)?;
    if a.runs == 0 {
        anyhow::bail!("--runs 0: at least one run is needed");
    }
    if a.patch < 8 {
        anyhow::bail!("--patch {}: at least 8 pixels", a.patch);
    }
    // With --motion alone, --methods picks among the clip methods (below).
    let methods = if a.motion.is_some() && !a.stability {
        Vec::new()
    } else {
        bench::select(bench::registry(), &a.methods)?
    };
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("{}: cannot create the folder", a.output.display()))?;

    if !a.no_timing && a.motion.is_none() {
        let read = ReadOptions {
            max_pixels: a.max_pixels,
        };
        let images = match &a.images {
            Some(dir) => bench::images_in(dir, &read, usize::MAX)?,
            None => bench::default_images(Path::new("samples"), &read)?,
        };
        if images.is_empty() {
            anyhow::bail!("no images to measure");
        }
        // Say what is measured: a folder, the repository's samples/, or the same samples
        // built into the binary (outside the repository).
        let source = match &a.images {
            Some(dir) => format!("{}", dir.display()),
            None if Path::new("samples").is_dir() => "./samples".to_string(),
            None => "the sample pictures built into halftone (no ./samples here)".to_string(),
        };
        eprintln!(
            "bench: {} method(s) on {} image(s) from {source}: {}",
            methods.len(),
            images.len(),
            images
                .iter()
                .map(|i| i.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let pb = progress(methods.len() * images.len(), "bench");
        let opts = BenchOptions { runs: a.runs, view };
        let printer = a.printer.model()?;
        let ms = bench::run_printed(&methods, &images, &opts, printer.as_ref(), &|msg| {
            pb.set_message(msg.to_string());
            pb.inc(1);
        })?;
        pb.finish_and_clear();
        let sums = bench::summarise(&ms);
        write(&a.output.join("results.csv"), &bench::to_csv(&ms))?;
        let json = serde_json::json!({
            "viewing": view,
            "runs": a.runs,
            "threads": rayon::current_num_threads(),
            "images": images.iter().map(|i| serde_json::json!({
                "name": i.name, "width": i.image.width, "height": i.image.height,
            })).collect::<Vec<_>>(),
            "summary": sums,
            "measurements": ms,
        });
        write(
            &a.output.join("results.json"),
            &serde_json::to_string_pretty(&json)?,
        )?;
        bench::write_chart(
            &sums,
            &view,
            &a.output.join("chart.svg"),
            &a.output.join("chart.png"),
        )?;
        print!("{}", bench::to_markdown(&sums));
        if let Some(p) = &printer {
            print!("{}", bench::to_markdown_printed(&sums, &p.name));
        }
    }

    if a.stability {
        let opts = StabilityOptions {
            size: a.patch,
            view,
        };
        let pb = progress(methods.len(), "stability");
        let mut results = Vec::new();
        for (key, m) in &methods {
            pb.set_message(key.clone());
            results.push(stability::measure(key, m.as_ref(), &opts)?);
            pb.inc(1);
        }
        pb.finish_and_clear();
        write(
            &a.output.join("stability.csv"),
            &stability::to_csv(&results),
        )?;
        write(
            &a.output.join("stability.json"),
            &serde_json::to_string_pretty(&results)?,
        )?;
        // Real inks: every built-in panel given saturated colours it mostly lacks.
        let panels = halftone::panel_stability::panels(96)?;
        write(
            &a.output.join("panels.csv"),
            &halftone::panel_stability::to_csv(&panels),
        )?;
        let md = format!(
            "{}\n{}",
            stability::to_markdown(&results),
            halftone::panel_stability::to_markdown(&panels)
        );
        write(&a.output.join("stability.md"), &md)?;
        stability::write_heatmap(
            &results,
            &a.output.join("heatmap.svg"),
            &a.output.join("heatmap.png"),
        )?;
        println!();
        print!("{md}");
        for r in &results {
            for e in r.edge_cases.iter().filter(|e| !e.ok) {
                eprintln!("halftone: {}: edge case {}: {}", r.key, e.case, e.detail);
            }
        }
    }
    if let Some(clip) = &a.motion {
        motion(clip, &a, &view)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `--motion CLIP`: the methods of [`motion_bench::methods`] (those `--methods` selects)
/// over the clip.
fn motion(clip: &Path, a: &BenchArgs, view: &Viewing) -> anyhow::Result<()> {
    use halftone::lab::motion_bench;
    let read = ReadOptions {
        max_pixels: a.max_pixels,
    };
    let open = || halftone::motion::open_source(clip, &read, true);
    // The clip opens (and is a clip) before any method runs.
    open()?;
    let chosen: Vec<_> = motion_bench::methods()
        .into_iter()
        .filter(|(k, _)| {
            a.methods.is_empty() || a.methods.iter().any(|m| k.starts_with(m.as_str()))
        })
        .collect();
    if chosen.is_empty() {
        anyhow::bail!(
            "--methods {}: none of the clip methods ({})",
            a.methods.join(","),
            motion_bench::methods()
                .iter()
                .map(|(k, _)| *k)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let pb = progress(chosen.len(), "motion");
    let mut rows = Vec::new();
    for (key, pairs) in &chosen {
        pb.set_message(key.to_string());
        let opts = motion_bench::options_of(pairs, view)?;
        rows.push(motion_bench::measure(
            &open,
            key,
            &opts,
            a.noise,
            a.every.max(1),
            view,
        )?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    write(&a.output.join("motion.csv"), &motion_bench::to_csv(&rows))?;
    write(
        &a.output.join("motion.json"),
        &serde_json::to_string_pretty(&serde_json::json!({
            "clip": clip.display().to_string(),
            "viewing": view,
            "noise": a.noise,
            "every": a.every.max(1),
            "threads": rayon::current_num_threads(),
            "methods": rows,
        }))?,
    )?;
    let md = motion_bench::to_markdown(&clip.display().to_string(), &rows);
    write(&a.output.join("motion.md"), &md)?;
    motion_bench::write_chart(
        &rows,
        view,
        &a.output.join("motion-chart.svg"),
        &a.output.join("motion-chart.png"),
    )?;
    println!();
    print!("{md}");
    Ok(())
}
