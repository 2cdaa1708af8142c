//! Flags of the accuracy methods: direct binary search, printer models, green noise.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use halftone::printer_model::PrinterModel;
use halftone::PrinterModelKind;

/// Printer models.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrinterModelArg {
    /// Ideal printer: every pixel prints as a square of its level.
    Ideal,
    /// Pappas–Neuhoff circular dots of --dot-ratio that spill onto their neighbours.
    DotOverlap,
    /// A measured 3×3-neighbourhood table (--printer-table FILE).
    Table,
}

/// The printer model flags, shared by `convert`, `batch` and `compare`.
#[derive(Args, Debug, Clone)]
pub struct PrinterArgs {
    /// Printer model: what the bitmap looks like once printed. With --method dbs, DBS
    /// optimises the printed result (model-based DBS); `compare` scores the printed result.
    #[arg(long, value_enum, default_value = "ideal")]
    pub printer_model: PrinterModelArg,

    /// Dot ratio of the dot-overlap model: dot diameter over the pixel's diagonal (1 = the dot
    /// just covers its pixel, 1.414 = it reaches the neighbours' centres). Lasers: about 1.25.
    #[arg(long, default_value_t = 1.25)]
    pub dot_ratio: f64,

    /// Measured printer table for `--printer-model table`: 512 printed reflectances, one for
    /// each 3×3 neighbourhood (see docs/accuracy.md).
    #[arg(long, value_name = "FILE")]
    pub printer_table: Option<PathBuf>,
}

impl PrinterArgs {
    /// The library's name for the model.
    pub fn kind(&self) -> PrinterModelKind {
        match self.printer_model {
            PrinterModelArg::Ideal => PrinterModelKind::Ideal,
            PrinterModelArg::DotOverlap => PrinterModelKind::DotOverlap,
            PrinterModelArg::Table => PrinterModelKind::Table,
        }
    }

    /// The model asked for, or None for an ideal printer.
    pub fn model(&self) -> anyhow::Result<Option<PrinterModel>> {
        let o = halftone::Options {
            printer_model: self.kind(),
            dot_ratio: self.dot_ratio,
            printer_table: self.printer_table.clone(),
            ..Default::default()
        };
        Ok(o.printer()?)
    }
}

/// Flags of `--method dbs` and of green-noise error diffusion.
#[derive(Args, Debug, Clone)]
pub struct AccuracyArgs {
    /// DBS: at most this many passes (it stops earlier when a pass changes nothing).
    #[arg(long, default_value_t = 40)]
    pub passes: u32,

    /// DBS: viewing distance in inches for the eye model (with --dpi, default 300).
    #[arg(long, default_value_t = 12.0)]
    pub distance: f64,

    /// DBS: do not correct DBS's tone response.
    #[arg(long)]
    pub no_tone_correction: bool,

    /// Error diffusion: output-dependent feedback (Levien's hysteresis) that clusters dots
    /// into small aperiodic groups ("green noise") that survive dot gain; 0 = plain.
    #[arg(long, default_value_t = 0.0)]
    pub hysteresis: f32,

    #[command(flatten)]
    pub printer: PrinterArgs,
}
