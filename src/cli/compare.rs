//! `halftone compare`: how close a halftone looks to its original at a viewing distance.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, ValueEnum};

use halftone::io::{self, ReadOptions};
use halftone::quality::{self, Viewing};
use halftone::raster::ColorKind;
use halftone::tone::Encoding;

/// Examples shown by `halftone compare --help`.
pub const EXAMPLES: &str = "Examples:
  halftone compare photo.png photo.pbm
  halftone compare photo.png photo-expand.png --dpi 600 --distance 18
  halftone compare photo.png photo-4.pgm --halftone-codes linear --json
  halftone compare photo.png photo.pbm --printer-model dot-overlap --dot-ratio 1.25
  halftone compare photo.png page.pdf                # what the printer receives
  halftone compare photo.png frame.png --device spectra6-7in3-v2   # frame.png: convert --device
  halftone compare --clip photo.png photo.pbm   # clips (GIF, APNG, y4m): flicker, HVS-PSNR";

/// How the halftone file's codes relate to light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CodesArg {
    /// Codes are sRGB (what `convert` writes for display; bilevel files are the same either way).
    Srgb,
    /// Codes are evenly spaced in light (a PGM whose maxval is levels − 1, or --no-linearize).
    Linear,
}

/// `halftone compare` arguments.
#[derive(Args, Debug)]
pub struct CompareArgs {
    /// The continuous-tone original.
    pub original: PathBuf,

    /// The halftone: any file `convert` writes (an image, or PDF, PostScript, PCL, ESC/POS
    /// or ZPL read back as the printer would), the same size as the original or a whole
    /// multiple of it (pattern `--cell expand`), compared then with the original enlarged by
    /// box.
    pub halftone: PathBuf,

    /// Resolution of the printed halftone, pixels per inch.
    #[arg(long, default_value_t = 300.0)]
    pub dpi: f64,

    /// Viewing distance, inches.
    #[arg(long, default_value_t = 12.0)]
    pub distance: f64,

    /// How the halftone file's codes relate to light.
    #[arg(long, value_enum, default_value = "srgb")]
    pub halftone_codes: CodesArg,

    /// Print the figures as JSON (an exact match, i.e. infinite PSNR, is written as null).
    #[arg(long)]
    pub json: bool,

    /// Refuse images larger than this many pixels (checked from the header, before decoding).
    #[arg(long, default_value_t = 1_000_000_000)]
    pub max_pixels: u64,

    /// Score a halftone made for an e-paper panel (built-in name or profile file) as a
    /// viewer adapted to the panel's white and black sees it: S-CIELAB at the panel's pixels
    /// a degree, mean CIEDE2000 and ΔE*ab, and the lightness ratio. The halftone file holds
    /// the inks' measured colours (what `convert --device` writes by default).
    #[arg(long, value_name = "NAME|FILE")]
    pub device: Option<String>,

    /// Compare two clips (GIF, APNG, WebP, YUV4MPEG2, a series): the original clip, then its
    /// halftone; per-frame HVS-PSNR, the flicker rate and the sizes.
    #[arg(long)]
    pub clip: bool,

    /// With --clip: the original's noise, grey codes; a pixel that moves no more than this
    /// between frames is still, and a dot that changes there is flicker.
    #[arg(long, default_value_t = 2, requires = "clip")]
    pub noise: u8,

    /// With --clip: HVS-PSNR of every N-th frame (1: all; 0: none).
    #[arg(long, default_value_t = 1, requires = "clip", value_name = "N")]
    pub every: usize,

    #[command(flatten)]
    pub printer: super::option_args::PrinterArgs,
}

/// `compare --device`: the viewing-adapted colour error ([`halftone::compare_device`]).
fn run_device(a: &CompareArgs, device: &str, opts: &ReadOptions) -> anyhow::Result<ExitCode> {
    // The profile first, so a bad one is named before any image is read.
    halftone::panel::Device::load(device)?;
    let original = super::stdio::read_image(&a.original, opts)?;
    let displayed = super::stdio::read_image(&a.halftone, opts)?;
    let c = halftone::compare_device(original, &displayed, device, opts.max_pixels)
        .with_context(|| format!("{} against {}", a.halftone.display(), a.original.display()))?;
    if let Some(w) = c.warning(&a.halftone.display().to_string()) {
        eprintln!("halftone: warning: {w}");
    }
    let (e, ppd) = (c.error, c.pixels_per_degree);
    let mut text = String::new();
    if a.json {
        let out = serde_json::json!({
            "original": a.original,
            "halftone": a.halftone,
            "device": c.device,
            "pixels_per_degree": ppd,
            "de2000": e.de2000,
            "de76": e.de76,
            "lightness_ratio": e.lightness_ratio,
        });
        writeln!(text, "{}", serde_json::to_string_pretty(&out)?)?;
    } else {
        writeln!(
            text,
            "CIEDE2000  {:>8.3}      (S-CIELAB mean, viewer adapted to {}; {:.1} pixels a degree)",
            e.de2000, c.device, ppd
        )?;
        writeln!(text, "ΔE*ab      {:>8.3}", e.de76)?;
        writeln!(
            text,
            "lightness  {:>8.3}      (mean L*, displayed / original)",
            e.lightness_ratio
        )?;
    }
    super::stdio::check_stdout()?;
    std::io::stdout().lock().write_all(text.as_bytes())?;
    Ok(ExitCode::SUCCESS)
}

/// Refuses a comparison whose working memory ([`quality::compare_bytes`]) is more than the
/// memory available (Linux's MemAvailable), instead of failing an allocation half way.
fn check_memory(
    a: &CompareArgs,
    original: (u32, u32),
    halftone: (usize, usize),
    view: &Viewing,
) -> anyhow::Result<()> {
    let need = quality::compare_bytes(halftone.0, halftone.1, 3, view);
    let Some(available) = available_memory() else {
        return Ok(());
    };
    if need > available {
        anyhow::bail!(
            "{} against {}: comparing {}x{} (original {}x{}) needs about {} MB, more than the \
             {} MB of memory available; compare a crop or a smaller copy",
            a.halftone.display(),
            a.original.display(),
            halftone.0,
            halftone.1,
            original.0,
            original.1,
            need / 1_000_000,
            available / 1_000_000
        );
    }
    Ok(())
}

/// Memory available to new allocations (MemAvailable in /proc/meminfo), in bytes.
fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// `halftone compare --clip ORIGINAL HALFTONE`: per-frame HVS-PSNR, the flicker rate in
/// the original's still areas, and the sizes of both files.
fn run_clip(a: &CompareArgs) -> anyhow::Result<ExitCode> {
    use std::io::Write as _;
    let view = halftone::quality::Viewing::new(a.dpi, a.distance)?;
    let read = halftone::io::ReadOptions {
        max_pixels: a.max_pixels,
    };
    let mut original = halftone::motion::open_source(&a.original, &read, true)?;
    let mut halftoned = halftone::motion::open_source(&a.halftone, &read, true)?;
    let c = halftone::motion::measure::compare_clips(
        original.as_mut(),
        halftoned.as_mut(),
        a.noise,
        a.every,
        &view,
    )?;
    let size = |p: &std::path::Path| std::fs::metadata(p).ok().map(|m| m.len());
    let psnr = &c.hvs_psnr_db;
    let finite: Vec<f64> = psnr.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = (!finite.is_empty()).then(|| finite.iter().sum::<f64>() / finite.len() as f64);
    let min = finite.iter().copied().reduce(f64::min);
    let text = if a.json {
        let out = serde_json::json!({
            "original": a.original,
            "halftone": a.halftone,
            "frames": c.frames,
            "hvs_psnr_db_mean": mean,
            "hvs_psnr_db_min": min,
            "hvs_psnr_db": finite,
            "flicker": c.flicker,
            "still_pixels": c.still_pixels,
            "noise": a.noise,
            "original_bytes": size(&a.original),
            "halftone_bytes": size(&a.halftone),
        });
        format!("{}\n", serde_json::to_string_pretty(&out)?)
    } else {
        let bytes = |v: Option<u64>| v.map_or("-".to_string(), |b| b.to_string());
        format!(
            "frames     {:>10}\n\
             HVS-PSNR   {:>10} dB  (mean over {} frames; lowest {} dB)\n\
             flicker    {:>10.6}     (dots changed where the original moved at most {} codes, \
             over {} such pixels)\n\
             size       {:>10} bytes (original {} bytes)\n",
            c.frames,
            mean.map_or("-".into(), |m| format!("{m:.2}")),
            finite.len(),
            min.map_or("-".into(), |m| format!("{m:.2}")),
            c.flicker,
            a.noise,
            c.still_pixels,
            bytes(size(&a.halftone)),
            bytes(size(&a.original)),
        )
    };
    super::stdio::check_stdout()?;
    std::io::stdout().lock().write_all(text.as_bytes())?;
    Ok(ExitCode::SUCCESS)
}

/// Runs `halftone compare`.
pub fn run(a: CompareArgs) -> anyhow::Result<ExitCode> {
    let view = Viewing::new(a.dpi, a.distance)?;
    let opts = ReadOptions {
        max_pixels: a.max_pixels,
    };
    if a.clip {
        return run_clip(&a);
    }
    if let Some(device) = &a.device {
        return run_device(&a, device, &opts);
    }
    let activity = super::progress::Activity::start(format!(
        "comparing {} with {}",
        a.halftone.display(),
        a.original.display()
    ));
    // Sizes from the headers first: a comparison too large for this machine's memory is
    // refused before anything is decoded.
    // A printer-language file (PDF, PostScript, PCL, ESC/POS, ZPL) is decoded as the
    // printer would read it; its page is small next to the comparison's working memory.
    let printed = io::lang::readback::read(&a.halftone, &opts)?;
    let dims = (
        super::stdio::read_dimensions(&a.original, &opts)?,
        match &printed {
            Some(p) => Some((p.width as u32, p.height as u32)),
            None => super::stdio::read_dimensions(&a.halftone, &opts)?,
        },
    );
    if let (Some(o), Some((hw, hh))) = dims {
        check_memory(&a, o, (hw as usize, hh as usize), &view)?;
    }
    let original = super::stdio::read_image(&a.original, &opts)?;
    let mut halftone = match printed {
        Some(mut p) => {
            // ESC/POS and PCL rows are whole bytes: blank padding columns are not the
            // picture's.
            io::lang::readback::fit_width(&mut p, original.width);
            p
        }
        None => super::stdio::read_image(&a.halftone, &opts)?,
    };
    // A grey halftone stored as colour (convert's 2/4-bit PNG is indexed, with grey palette
    // entries) is grey: compared as luminance, not channel by channel with a colour original.
    if halftone.planes.len() == 3
        && halftone.planes[0] == halftone.planes[1]
        && halftone.planes[1] == halftone.planes[2]
    {
        halftone.planes.truncate(1);
        halftone.color = ColorKind::Gray;
    }
    let codes = match a.halftone_codes {
        CodesArg::Srgb => Encoding::Srgb,
        CodesArg::Linear => Encoding::Linear,
    };
    let mut ht = quality::decoded_halftone_reflectance(&halftone, codes);
    let model = a.printer.model()?;
    if let Some(m) = &model {
        // Score what the printer would print, not the bitmap.
        ht = m
            .print_reflectance(&ht)
            .with_context(|| format!("{}", a.halftone.display()))?;
    }
    let q = quality::compare(&quality::image_reflectance(&original), &ht, &view)
        .with_context(|| format!("{} against {}", a.halftone.display(), a.original.display()))?;
    drop(activity);
    // Printed in one write that can fail (a closed or broken stdout is an error, not a
    // silent success or a panic).
    let mut text = String::new();
    if a.json {
        let out = serde_json::json!({
            "original": a.original,
            "halftone": a.halftone,
            "viewing": view,
            "quality": q,
            "printer_model": model.as_ref().map(|m| m.name.clone()),
            "printed_mean_reflectance": ht.mean(),
        });
        writeln!(text, "{}", serde_json::to_string_pretty(&out)?)?;
    } else {
        writeln!(
            text,
            "HVS-PSNR   {:>8.2} dB   ({} dpi at {} in; {:.1} pixels a degree)",
            q.hvs_psnr_db,
            view.dpi,
            view.distance_in,
            view.pixels_per_degree()
        )?;
        writeln!(
            text,
            "tone bias  {:>+8.4}      (mean reflectance, halftone − original)",
            q.tone_bias
        )?;
        writeln!(text, "L* RMS     {:>8.3}", q.lstar_rms)?;
        if let Some(m) = &model {
            writeln!(
                text,
                "printed    {:>8.4}      (mean ink share as printed, model {})",
                1.0 - ht.mean(),
                m.name
            )?;
        }
        writeln!(
            text,
            "plain PSNR {:>8.2} dB   (unfiltered)",
            q.plain_psnr_db
        )?;
        if q.scale != [1, 1] {
            writeln!(
                text,
                "original enlarged {}x{} by box to the halftone's size",
                q.scale[0], q.scale[1]
            )?;
        }
    }
    super::stdio::check_stdout()?;
    std::io::stdout().lock().write_all(text.as_bytes())?;
    Ok(ExitCode::SUCCESS)
}
