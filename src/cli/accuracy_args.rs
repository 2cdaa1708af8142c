//! Flags of the accuracy methods: direct binary search, printer models, green noise.

use std::path::PathBuf;

use anyhow::bail;
use clap::{Args, ValueEnum};

use halftone::method::dbs::{Dbs, DbsOptions};
use halftone::method::diffusion::hysteresis::Hysteresis;
use halftone::method::diffusion::tded::Tded;
use halftone::method::diffusion::DiffuseOptions;
use halftone::printer_model::PrinterModel;
use halftone::quality::Viewing;
use halftone::Method;

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
    /// The model asked for, or None for an ideal printer.
    pub fn model(&self) -> anyhow::Result<Option<PrinterModel>> {
        Ok(match self.printer_model {
            PrinterModelArg::Ideal => None,
            PrinterModelArg::DotOverlap => Some(PrinterModel::dot_overlap(self.dot_ratio)?),
            PrinterModelArg::Table => match &self.printer_table {
                Some(p) => Some(PrinterModel::load_table(p)?),
                None => bail!("--printer-model table needs --printer-table FILE"),
            },
        })
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

impl AccuracyArgs {
    /// Viewing conditions for DBS's eye model.
    pub fn view(&self, dpi: Option<f64>) -> anyhow::Result<Viewing> {
        Ok(Viewing::new(dpi.unwrap_or(300.0), self.distance)?)
    }
}

impl AccuracyArgs {
    /// `--method dbs` with these flags.
    pub fn dbs(&self, levels: u16, dpi: Option<f64>) -> anyhow::Result<Box<dyn Method>> {
        let printer = self.printer.model()?;
        let base = match printer {
            Some(p) => DbsOptions::for_printer(p),
            None => DbsOptions::default(),
        };
        let options = DbsOptions {
            levels,
            view: self.view(dpi)?,
            passes: self.passes,
            tone_correct: !self.no_tone_correction,
            ..base
        };
        Ok(Box::new(Dbs::new(options)?))
    }

    /// Error diffusion with hysteresis (`--hysteresis`) or the trained `--kernel tded`.
    pub fn diffusion(
        &self,
        kernel: &str,
        options: DiffuseOptions,
        palette: bool,
    ) -> anyhow::Result<Box<dyn Method>> {
        if palette {
            bail!("--hysteresis and --kernel tded do not work with --palette");
        }
        if kernel == "tded" {
            if self.hysteresis != 0.0 {
                bail!("--hysteresis works with fixed kernels, not tded");
            }
            return Ok(Box::new(Tded::new(options)?));
        }
        Ok(Box::new(Hysteresis::new(kernel, options, self.hysteresis)?))
    }
}
