//! `halftone press`: fit a press model to characterisation data, and check it.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Subcommand};

use halftone::press::{cgats, fit, Press};

pub const EXAMPLES: &str = "Examples:
  halftone press fit FOGRA39L.ti3 --name fogra39 -o my-fogra39.toml   # FOGRA39's measurements
  halftone press check fogra39 FOGRA39L.ti3";

/// `halftone press` arguments.
#[derive(Args, Debug)]
pub struct PressArgs {
    #[command(subcommand)]
    pub command: PressCommand,
}

/// What to do with a press.
#[derive(Subcommand, Debug)]
pub enum PressCommand {
    /// Fit the Yule–Nielsen Neugebauer model to a .ti3 (CGATS) file; print or write its TOML.
    #[command(
        after_long_help = "Examples:\n  halftone press fit FOGRA39L.ti3 --name fogra39 -o my-fogra39.toml\n  halftone press fit measured.ti3 --name my-press --source \"measured 2026-12-01\""
    )]
    Fit {
        /// Characterisation data: CMYK_C..CMYK_K and XYZ_X..XYZ_Z per patch.
        input: PathBuf,
        /// Name to record.
        #[arg(long, default_value = "press")]
        name: String,
        /// Source and licence to record.
        #[arg(long)]
        source: Option<String>,
        /// Output TOML file (default: stdout).
        #[arg(long, short = 'o')]
        output: Option<PathBuf>,
    },
    /// Mean and 95th-percentile ΔE76 of a press model against measured patches.
    #[command(
        after_long_help = "Examples:\n  halftone press check fogra39 FOGRA39L.ti3\n  halftone press check fogra39 measured.ti3"
    )]
    Check {
        /// A built-in press name or a .ti3 file.
        press: String,
        /// Measured patches (.ti3).
        data: PathBuf,
    },
}

pub fn run(a: PressArgs) -> anyhow::Result<ExitCode> {
    match a.command {
        PressCommand::Fit {
            input,
            name,
            source,
            output,
        } => {
            let bytes = std::fs::read(&input).map_err(|e| halftone::Error::io(&input, e))?;
            let text = String::from_utf8_lossy(&bytes);
            let patches = cgats::parse(&text, &input)?;
            let source = source.unwrap_or_else(|| format!("fitted from {}", input.display()));
            let params = fit(&patches, &name, &source)?;
            let body = toml::to_string(&params)?;
            let text = format!(
                "# Press model for halftone (`--press {name}`): Yule–Nielsen modified Neugebauer, XYZ D50.\n\
                 # Made with: halftone press fit {} --name {name}\n\
                 # {} patches; mean ΔE76 of the model over them: {:.2}; n = {:.2}.\n{body}",
                input.display(),
                patches.len(),
                params.fit_mean_de,
                params.n
            );
            match output {
                Some(p) => halftone::io::write_atomic(&p, |w| w.write_all(text.as_bytes()))?,
                None => std::io::stdout().lock().write_all(text.as_bytes())?,
            }
        }
        PressCommand::Check { press, data } => {
            let press = Press::load(&press)?;
            let bytes = std::fs::read(&data).map_err(|e| halftone::Error::io(&data, e))?;
            let text = String::from_utf8_lossy(&bytes);
            let patches = cgats::parse(&text, &data)?;
            let mean = press.mean_delta_e(&patches);
            println!(
                "{}: n = {:.2}, {} patches, mean ΔE76 {:.2}",
                press.params().name,
                press.params().n,
                patches.len(),
                mean
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
