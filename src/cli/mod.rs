//! Command-line definitions: one file per subcommand, each with its arguments documented
//! where they are defined.

use std::process::ExitCode;

use clap::{ArgMatches, Parser, Subcommand};

mod batch;
mod bench;
mod compare;
mod convert;
mod generate;
mod masks;
mod patterns;
mod plates;
mod press;
mod render;
mod screen_args;

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
    /// Fit a press model (CMYK separation) to characterisation data, or check one.
    #[command(after_long_help = press::EXAMPLES)]
    Press(press::PressArgs),
    /// Halftone many files on all cores: folders, globs, presets, a report, shards.
    #[command(after_long_help = batch::EXAMPLES)]
    Batch(batch::BatchArgs),
    /// List, show, check or generate threshold masks.
    #[command(subcommand)]
    Masks(masks::MasksCommand),
    /// Measure a halftone against its original: HVS-filtered PSNR, tone bias, L* RMS.
    #[command(after_long_help = compare::EXAMPLES)]
    Compare(compare::CompareArgs),
    /// Speed against accuracy for every method: results.csv/json, chart, stability map.
    #[command(after_long_help = bench::EXAMPLES)]
    Bench(bench::BenchArgs),
    /// Render a sample scene from the lecture's illumination models (or a TOML scene file).
    #[command(after_long_help = render::EXAMPLES)]
    Render(render::RenderArgs),
}

/// Runs the parsed command; `matches` tells which options were given on the command line
/// (a preset fills in only the others).
pub fn run(cli: Cli, matches: &ArgMatches) -> anyhow::Result<ExitCode> {
    let sub = matches.subcommand().map(|(_, m)| m).unwrap_or(matches);
    match cli.command {
        Command::Convert(a) => convert::run(a, sub),
        Command::Batch(a) => batch::run(a, sub),
        Command::Patterns(a) => patterns::run(a),
        Command::Press(a) => press::run(a),
        Command::Masks(a) => masks::run(a),
        Command::Render(a) => render::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Bench(a) => bench::run(a),
    }
}

/// On Ctrl-C: remove the temp files of writes in progress (so no partial file is left) and
/// exit with status 130.
pub fn install_interrupt_handler() {
    let _ = ctrlc::set_handler(|| {
        halftone::io::remove_temp_files();
        eprintln!("halftone: interrupted; no partial output left");
        std::process::exit(130);
    });
}
