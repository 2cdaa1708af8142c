//! `halftone compare`: how close a halftone looks to its original at a viewing distance.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, ValueEnum};

use halftone::io::{self, ReadOptions};
use halftone::quality::{self, Viewing};
use halftone::tone::Encoding;

/// Examples shown by `halftone compare --help`.
pub const EXAMPLES: &str = "Examples:
  halftone compare photo.png photo.pbm
  halftone compare photo.png photo-expand.png --dpi 600 --distance 18
  halftone compare photo.png photo-4.pgm --halftone-codes linear --json
  halftone compare photo.png photo.pbm --printer-model dot-overlap --dot-ratio 1.25";

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

    /// The halftone: the same size as the original, or a whole multiple of it (pattern
    /// `--cell expand`), compared then with the original enlarged by box.
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

    #[command(flatten)]
    pub printer: super::accuracy_args::PrinterArgs,
}

/// Runs `halftone compare`.
pub fn run(a: CompareArgs) -> anyhow::Result<ExitCode> {
    let view = Viewing::new(a.dpi, a.distance)?;
    let opts = ReadOptions {
        max_pixels: a.max_pixels,
    };
    let original = io::read_image(&a.original, &opts)?;
    let halftone = io::read_image(&a.halftone, &opts)?;
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
    if a.json {
        let out = serde_json::json!({
            "original": a.original,
            "halftone": a.halftone,
            "viewing": view,
            "quality": q,
            "printer_model": model.as_ref().map(|m| m.name.clone()),
            "printed_mean_reflectance": ht.mean(),
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!(
            "HVS-PSNR   {:>8.2} dB   ({} dpi at {} in; {:.1} pixels a degree)",
            q.hvs_psnr_db,
            view.dpi,
            view.distance_in,
            view.pixels_per_degree()
        );
        println!(
            "tone bias  {:>+8.4}      (mean reflectance, halftone − original)",
            q.tone_bias
        );
        println!("L* RMS     {:>8.3}", q.lstar_rms);
        if let Some(m) = &model {
            println!(
                "printed    {:>8.4}      (mean ink share as printed, model {})",
                1.0 - ht.mean(),
                m.name
            );
        }
        println!("plain PSNR {:>8.2} dB   (unfiltered)", q.plain_psnr_db);
        if q.scale != [1, 1] {
            println!(
                "original enlarged {}x{} by box to the halftone's size",
                q.scale[0], q.scale[1]
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
