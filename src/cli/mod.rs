//! Command-line definitions: one file per subcommand, each with its arguments documented
//! where they are defined.

use std::io::Write;
use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};

mod batch;
mod bench;
mod compare;
mod completions;
mod convert;
mod devices;
mod generate;
mod masks;
mod motion;
mod option_args;
mod options;
mod patterns;
mod patterns_screen;
mod press;
mod print;
mod progress;
mod render;
mod serve;
mod sheet;
pub mod stdio;
mod train;

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
    #[command(subcommand, after_long_help = masks::EXAMPLES)]
    Masks(masks::MasksCommand),
    /// E-paper panels: list the built-in profiles, show one as TOML, write a calibration
    /// chart, measure a panel's inks from a photo of it.
    #[command(subcommand, after_long_help = devices::EXAMPLES)]
    Devices(devices::DevicesCommand),
    /// Measure a halftone against its original: HVS-filtered PSNR, tone bias, L* RMS.
    #[command(after_long_help = compare::EXAMPLES)]
    Compare(compare::CompareArgs),
    /// Speed against accuracy for every method: results.csv/json, chart, stability map.
    #[command(after_long_help = bench::EXAMPLES)]
    Bench(bench::BenchArgs),
    /// Render a sample scene from the lecture's illumination models (or a TOML scene file).
    #[command(after_long_help = render::EXAMPLES)]
    Render(render::RenderArgs),
    /// A contact sheet: your image through the main methods, side by side at 1:1, each
    /// labelled with its HVS-PSNR and time.
    #[command(after_long_help = sheet::EXAMPLES)]
    Sheet(sheet::SheetArgs),
    /// Print a shell completion script (bash, zsh, fish, powershell, elvish).
    #[command(after_long_help = completions::COMPLETIONS_EXAMPLES)]
    Completions(completions::CompletionsArgs),
    /// Print the man page (roff) on standard output, or write one for every subcommand.
    #[command(after_long_help = completions::MAN_EXAMPLES)]
    Man(completions::ManArgs),
    /// Every option `convert` takes (flag, values, default, help) and the lists of names;
    /// `--json` for other programs.
    #[command(after_long_help = options::EXAMPLES)]
    Options(options::OptionsArgs),
    /// An IPP Everywhere printer: print queues that halftone what phones, laptops and CUPS
    /// send them and pass it to a printer in its own language (ESC/POS, ZPL, PCL, PDF…).
    #[command(after_long_help = serve::EXAMPLES)]
    Serve(serve::ServeArgs),
    /// Halftone images and send them to an IPP printer (ipp://…) in a format and at a
    /// resolution it lists (PWG raster, Apple raster or PDF); wait for the job.
    #[command(after_long_help = print::EXAMPLES)]
    Print(print::PrintArgs),
    /// Remake the trained tables shipped in kernels/ (tded weights, DBS tone correction).
    #[command(subcommand, after_long_help = train::EXAMPLES)]
    Train(train::TrainCommand),
}

/// The one-line message for `err` as `{:#}` prints it (each cause after its context), with
/// the library's option names in the command line's spelling: `dot_gain` is `--dot-gain`.
pub fn message(err: &anyhow::Error) -> String {
    err.chain()
        .map(|cause| match cause.downcast_ref::<halftone::Error>() {
            Some(halftone::Error::Option { field, value, msg }) => {
                flags_for_options(&format!("{} {value}: {msg}", flag(field)))
            }
            _ => flags_for_options(&cause.to_string()),
        })
        .collect::<Vec<_>>()
        .join(": ")
}

/// `text` with each option named as the library names it in a message (`` `max_pixels` ``)
/// written as its flag (`--max-pixels`).
pub fn flags_for_options(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find('`') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        match after.find('`') {
            Some(j) if is_option(&after[..j]) => {
                out.push_str(&flag(&after[..j]));
                rest = &after[j + 1..];
            }
            _ => {
                out.push('`');
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// True for a field of the library's options, or a flag of a command's own.
fn is_option(name: &str) -> bool {
    halftone::options::table::find(name).is_some()
        || ["methods", "shard", "paper", "paper_reflectance"].contains(&name)
}

/// The flag of an option field.
pub fn flag(field: &str) -> String {
    format!("--{}", field.replace('_', "-"))
}

/// The command-line definition, with the lists of built-in names (kernels, palettes,
/// masks, presets) filled in from the library's own lists, so that the help cannot drift
/// from what the library accepts. `main`, the completions and the man pages all use it.
pub fn command() -> clap::Command {
    Cli::command()
        .mut_subcommand("convert", fill_names)
        .mut_subcommand("batch", fill_names)
        .mut_subcommand("serve", fill_names)
        .mut_subcommand("print", fill_names)
}

/// Sets the help of `--kernel`, `--palette`, `--mask` and `--preset` (where `c` has them)
/// to name every built-in.
fn fill_names(c: clap::Command) -> clap::Command {
    use halftone::color::Palette;
    use halftone::Mask;
    let kernels = halftone::method::diffusion::NAMES
        .iter()
        .map(|&k| if k == "tded" { "tded (trained)" } else { k })
        .collect::<Vec<_>>()
        .join(", ");
    let palettes = Palette::builtin_names().collect::<Vec<_>>().join(", ");
    let masks = Mask::builtin_names().collect::<Vec<_>>().join(", ");
    let presets = halftone::preset::Presets::builtin()
        .by_name
        .keys()
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    let texts = [
        (
            "kernel",
            format!("Error-diffusion kernel: {kernels}, or a kernel file (see kernels/README.md)"),
        ),
        (
            "palette",
            format!(
                "Diffuse (or, with --method ordered, pattern-dither) to a palette: a built-in \
                 ({palettes}), a file of hex colours or a GIMP .gpl, or auto:N for N colours \
                 made from the image (2 to 256). Implies --color rgb"
            ),
        ),
        (
            "mask",
            format!(
                "Mask: a built-in ({masks}; see `halftone masks list`) or a mask file \
                 [default: seed-3x3 for pattern, bayer-8 for ordered]"
            ),
        ),
        (
            "preset",
            format!(
                "A printer preset (built-in: {presets}); flags given on the command line win \
                 over it"
            ),
        ),
    ];
    texts.into_iter().fold(c, |c, (id, text)| {
        if c.get_arguments().any(|a| a.get_id() == id) {
            c.mut_arg(id, |a| a.help(text.clone()).long_help(text))
        } else {
            c
        }
    })
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Convert(a) => convert::run(a),
        Command::Batch(a) => batch::run(a),
        Command::Patterns(a) => patterns::run(a),
        Command::Press(a) => press::run(a),
        Command::Masks(a) => masks::run(a),
        Command::Devices(c) => devices::run(c),
        Command::Render(a) => render::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Sheet(a) => sheet::run(a),
        Command::Completions(a) => completions::run_completions(a),
        Command::Man(a) => completions::run_man(a),
        Command::Train(c) => train::run(c),
        Command::Options(a) => options::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Print(a) => print::run(a),
    }
}

/// On SIGINT, SIGTERM or SIGHUP (Ctrl-C, `kill`, `timeout`, systemd, a batch scheduler,
/// a closed terminal): remove the temp files of writes in progress, so no partial file is
/// left, withdraw `serve`'s DNS-SD services, and exit with 128 + the signal's number, as a
/// shell reports a killed command.
#[cfg(unix)]
pub fn install_interrupt_handler() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            let name = match sig {
                SIGINT => "SIGINT",
                SIGTERM => "SIGTERM",
                _ => "SIGHUP",
            };
            let _ = writeln!(
                std::io::stderr(),
                "halftone: interrupted ({name}); no partial output left"
            );
            let _held = halftone::io::remove_temp_files_and_hold();
            serve::withdraw_adverts();
            std::process::exit(128 + sig);
        }
    });
}

/// On Ctrl-C: remove the temp files of writes in progress (so no partial file is left) and
/// exit with status 130.
#[cfg(not(unix))]
pub fn install_interrupt_handler() {
    let _ = ctrlc::set_handler(|| {
        let _ = writeln!(
            std::io::stderr(),
            "halftone: interrupted; no partial output left"
        );
        let _held = halftone::io::remove_temp_files_and_hold();
        serve::withdraw_adverts();
        std::process::exit(130);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn library_option_names_become_flags() {
        let e = anyhow::Error::new(halftone::Error::Option {
            field: "dot_gain",
            value: "60".into(),
            msg: "must be a percentage from 0 to 50".into(),
        });
        assert_eq!(
            message(&e),
            "--dot-gain 60: must be a percentage from 0 to 50"
        );
        let e = anyhow::Error::new(halftone::Error::Invalid(
            "a printer model works with bilevel output only (`levels` 2); `not_an_option` stays"
                .into(),
        ))
        .context("photo.png");
        assert_eq!(
            message(&e),
            "photo.png: a printer model works with bilevel output only (--levels 2); \
             `not_an_option` stays"
        );
    }
}
