//! `halftone train`: remakes the trained tables the library ships (they live in kernels/).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Subcommand;

use halftone::method::dbs;
use halftone::method::diffusion::tded;

/// Examples shown by `halftone train --help`.
pub const EXAMPLES: &str = "Examples:
  halftone train tded -o my-tded.txt --iterations 40     # minutes; the shipped table took more
  halftone train dbs-tone -o - | head";

/// What to train.
#[derive(Subcommand, Debug)]
pub enum TrainCommand {
    /// Tone-dependent error diffusion's weights and thresholds (kernels/tded.txt), trained on
    /// synthetic flats of 33 greys against the eye-filtered error `compare` scores (one run
    /// for each of eight start-up margins, the best on synthetic validation images kept).
    #[command(
        after_long_help = "Examples:\n  halftone train tded -o my-tded.txt --iterations 40\n  halftone convert photo.png -o out.pbm --kernel tded   # uses the shipped table"
    )]
    Tded {
        /// Output file (- for stdout).
        #[arg(long, short = 'o', default_value = "kernels/tded.txt")]
        output: PathBuf,
        /// Search iterations per grey.
        #[arg(long, default_value_t = halftone::lab::train::TRAIN_ITERATIONS)]
        iterations: usize,
    },
    /// DBS's tone correction (kernels/dbs-tone.txt): DBS's response on flats, inverted.
    #[command(
        after_long_help = "Examples:\n  halftone train dbs-tone -o my-dbs-tone.txt\n  halftone train dbs-tone -o - | head"
    )]
    DbsTone {
        /// Output file (- for stdout).
        #[arg(long, short = 'o', default_value = "kernels/dbs-tone.txt")]
        output: PathBuf,
    },
}

fn write(output: &PathBuf, text: &str) -> anyhow::Result<ExitCode> {
    if output.as_os_str() == "-" {
        print!("{text}");
    } else {
        std::fs::write(output, text).with_context(|| format!("{}", output.display()))?;
        eprintln!("wrote {}", output.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Runs `halftone train`.
pub fn run(c: TrainCommand) -> anyhow::Result<ExitCode> {
    match c {
        TrainCommand::Tded { output, iterations } => {
            let runs = halftone::lab::train::train(iterations);
            for r in &runs {
                eprintln!(
                    "margin {:2}: {:.3} dB on the validation images",
                    r.margin, r.validation_db
                );
            }
            write(&output, &tded::table_text(&runs[0].rows, runs[0].margin))
        }
        TrainCommand::DbsTone { output } => {
            write(&output, &dbs::tone_table_text(&dbs::train_tone()))
        }
    }
}
