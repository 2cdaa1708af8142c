//! `halftone masks`: list, show and check threshold masks.

use std::fmt::Write as _;
use std::io::Write as _;
use std::process::ExitCode;

/// The largest mask whose levels `masks show` checks for streaks and isolated pixels.
const MAX_CHECKED_CELLS: usize = 4096;

use clap::Subcommand;

use halftone::mask::warnings;
use halftone::Mask;

/// Examples shown by `halftone masks --help`.
pub const EXAMPLES: &str = "Examples:
  halftone masks list
  halftone masks show seed-3x3
  halftone masks generate bayer --size 16 -o bayer-16.mask
  halftone masks show bayer-16.mask                # a file you wrote or generated";

/// `halftone masks` subcommands.
#[derive(Subcommand, Debug)]
pub enum MasksCommand {
    /// List the built-in masks with their sizes and descriptions.
    #[command(after_long_help = "Example:\n  halftone masks list")]
    List,
    /// Print a mask, its level count, and the lecture's warnings (streaks, isolated pixels).
    #[command(
        after_long_help = "Examples:\n  halftone masks show seed-3x3\n  halftone masks generate bayer --size 16 -o bayer-16.mask && halftone masks show bayer-16.mask"
    )]
    Show {
        /// A built-in name or a mask file.
        mask: String,
    },
    /// Generate a mask: Bayer, clustered dot from a spot function, or blue noise.
    #[command(subcommand, after_long_help = super::generate::EXAMPLES)]
    Generate(super::generate::GenerateCommand),
}

pub fn run(c: MasksCommand) -> anyhow::Result<ExitCode> {
    match c {
        MasksCommand::Generate(g) => return super::generate::run(g),
        MasksCommand::List => {
            let names: Vec<&str> = Mask::builtin_names().collect();
            let width = names.iter().map(|n| n.len()).max().unwrap_or(4);
            for n in names {
                let m = Mask::builtin(n).expect("built-in");
                let size = format!("{}x{}", m.width, m.height);
                // The description's first clause; `masks show` prints the whole comment.
                let desc = Mask::builtin_description(n).unwrap_or_default();
                let desc = desc.trim_start_matches(&format!("{n}: ")).to_string();
                let short = desc.split(" (").next().unwrap_or("");
                let short = short.split(": ").next().unwrap_or("").trim_end_matches('.');
                println!("{n:<width$}  {size:>7}  {short}");
            }
        }
        MasksCommand::Show { mask } => {
            let m = Mask::load(&mask, false)?;
            // Built whole, then written once: a closed or broken stdout is an error.
            let mut out = m.to_text(&format!("{} ({}x{})", m.name, m.width, m.height));
            writeln!(
                out,
                "{} cells: {} levels on a bilevel device; N(L-1)+1 on an L-level device",
                m.len(),
                m.len() + 1
            )?;
            // The check takes time in the square of the cells: 4096 (64x64) takes well under
            // a second; a 1024x1024 mask would take hours.
            if m.len() > MAX_CHECKED_CELLS {
                writeln!(
                    out,
                    "streaks and isolated pixels not checked: over {MAX_CHECKED_CELLS} cells"
                )?;
            } else {
                let ws = warnings::check(&m);
                if ws.is_empty() {
                    writeln!(out, "no streaking or isolated-pixel patterns")?;
                }
                for w in &ws {
                    writeln!(out, "warning: level {}: {}", w.level, w.what)?;
                }
            }
            halftone::io::check_stdout()?;
            let mut stdout = std::io::stdout().lock();
            stdout.write_all(out.as_bytes())?;
            stdout.flush()?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
