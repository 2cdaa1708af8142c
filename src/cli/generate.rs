//! `halftone masks generate`: write Bayer, clustered-dot and blue-noise masks as mask files.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Subcommand, ValueEnum};

use halftone::mask::generate::{self, Dot};
use halftone::Mask;

/// Examples shown after `halftone masks generate --help`.
pub const EXAMPLES: &str = "Examples:
  halftone masks generate bayer --size 8 -o bayer-8.mask
  halftone masks generate cluster --size 6 --dot ellipse
  halftone masks generate cluster --size 8 --dot round --angle 45 -o dot45-8.mask
  halftone masks generate blue-noise --size 64 --seed 1 -o blue-noise-64.mask";

/// What to generate.
#[derive(Subcommand, Debug)]
pub enum GenerateCommand {
    /// Bayer's dispersed-dot matrix (recursive definition; power-of-two sizes 2..256).
    #[command(
        after_long_help = "Example:\n  halftone masks generate bayer --size 16 -o bayer-16.mask"
    )]
    Bayer {
        /// Side of the square mask: 2, 4, 8, ... 256.
        #[arg(long, default_value_t = 8)]
        size: usize,
        /// Output file (default: standard output).
        #[arg(long, short = 'o')]
        output: Option<PathBuf>,
    },
    /// A clustered dot grown from a spot function: black dots in the highlights that
    /// join at 50% and leave white dots in the shadows, as in print.
    #[command(
        after_long_help = "Example:\n  halftone masks generate cluster --size 8 --dot round --angle 45 -o dot45-8.mask"
    )]
    Cluster {
        /// Side of the square cell, 2..256.
        #[arg(long, default_value_t = 8)]
        size: usize,
        /// Dot shape (spot function).
        #[arg(long, value_enum, default_value = "round")]
        dot: DotArg,
        /// Screen angle: 0 (one dot a cell) or 45 (two dots a cell on a 45° lattice).
        #[arg(long, default_value_t = 0, value_parser = parse_angle)]
        angle: u16,
        /// Output file (default: standard output).
        #[arg(long, short = 'o')]
        output: Option<PathBuf>,
    },
    /// Blue noise by void-and-cluster (Ulichney 1993, Gaussian σ = 1.5, tiles seamlessly).
    #[command(
        after_long_help = "Example:\n  halftone masks generate blue-noise --size 64 --seed 7 -o bn-64.mask"
    )]
    BlueNoise {
        /// Side of the square mask, 8..256 (128 takes about a second).
        #[arg(long, default_value_t = 64)]
        size: usize,
        /// Seed of the initial random pattern; the same seed gives the same mask.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output file (default: standard output).
        #[arg(long, short = 'o')]
        output: Option<PathBuf>,
    },
}

/// Spot functions for `--dot`.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum DotArg {
    /// Round dot, 1 − (x² + y²).
    Round,
    /// Elliptical dot, 1 − (0.6·x² + y²): chains across, then down.
    Ellipse,
    /// Line screen, 1 − |y|.
    Line,
    /// Diamond dot, 1 − (|x| + |y|).
    Diamond,
}

impl From<DotArg> for Dot {
    fn from(d: DotArg) -> Dot {
        match d {
            DotArg::Round => Dot::Round,
            DotArg::Ellipse => Dot::Ellipse,
            DotArg::Line => Dot::Line,
            DotArg::Diamond => Dot::Diamond,
        }
    }
}

fn parse_angle(s: &str) -> Result<u16, String> {
    match s {
        "0" => Ok(0),
        "45" => Ok(45),
        _ => Err(format!("{s}: the angle must be 0 or 45")),
    }
}

/// Generates the mask and writes it as text (position numbers 1..N under a comment that
/// says what it is and the command that made it), atomically when writing a file.
pub fn run(cmd: GenerateCommand) -> anyhow::Result<ExitCode> {
    let (mask, about, command, output): (Mask, String, String, Option<PathBuf>) = match cmd {
        GenerateCommand::Bayer { size, output } => (
            generate::bayer(size)?,
            format!(
                "Bayer dispersed-dot ordered-dither matrix, {size}x{size}\n(B. E. Bayer, \"An optimum \
                 method for two-level rendition of continuous-tone pictures\", ICC 1973; recursive definition)."
            ),
            format!("bayer --size {size}"),
            output,
        ),
        GenerateCommand::Cluster {
            size,
            dot,
            angle,
            output,
        } => {
            let dot = Dot::from(dot);
            let shape = if angle == 45 {
                "two dots on a 45-degree lattice"
            } else {
                "one dot a cell, 0 degrees"
            };
            (
                generate::cluster(size, dot, angle == 45)?,
                format!(
                    "Clustered-dot {} screen, {size}x{size} cell, {shape}:\ncells light in order of \
                     increasing PostScript spot function (PLRM 7.4.3), so the ink dot's core is the \
                     last lit.",
                    dot.name()
                ),
                format!("cluster --size {size} --dot {} --angle {angle}", dot.name()),
                output,
            )
        }
        GenerateCommand::BlueNoise { size, seed, output } => (
            generate::blue_noise(size, seed)?,
            format!(
                "Blue-noise mask, {size}x{size}, by void-and-cluster\n(R. Ulichney, \"The void-and-cluster \
                 method for dither array generation\", SPIE 1913, 1993; Gaussian sigma 1.5, wrap-around)."
            ),
            format!("blue-noise --size {size} --seed {seed}"),
            output,
        ),
    };
    let text = mask.to_text(&format!(
        "{about}\nGenerated by: halftone masks generate {command}"
    ));
    match output {
        Some(path) if path.as_os_str() != "-" => {
            halftone::io::write_atomic(&path, |w| w.write_all(text.as_bytes()))?;
        }
        _ => {
            let mut out = std::io::stdout().lock();
            out.write_all(text.as_bytes())?;
            out.flush()?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
