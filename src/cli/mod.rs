//! Command-line definitions: one file per subcommand, each with its arguments documented
//! where they are defined.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod convert;
mod masks;
mod patterns;

/// Turn continuous-tone images into halftones: pattern cells, ordered and error-diffusion
/// dithering in linear light, written as printer-ready bitmaps (PBM, PNG, TIFF G4, BMP).
#[derive(Parser, Debug)]
#[command(name = "halftone", version, about, long_about = None, max_term_width = 100)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Halftone one image.
    #[command(after_long_help = convert::EXAMPLES)]
    Convert(convert::ConvertArgs),
    /// Print a mask's pattern table: every level's cell, as text, JSON or an image sheet.
    #[command(after_long_help = patterns::EXAMPLES)]
    Patterns(patterns::PatternsArgs),
    /// List, show or check threshold masks.
    #[command(subcommand)]
    Masks(masks::MasksCommand),
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Convert(a) => convert::run(a),
        Command::Patterns(a) => patterns::run(a),
        Command::Masks(a) => masks::run(a),
    }
}
