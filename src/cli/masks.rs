//! `halftone masks`: list, show, check and generate threshold masks.

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
  halftone masks show bayer-16.mask                # a file you wrote or generated
  halftone masks check bayer-16.mask";

/// `halftone masks` subcommands.
#[derive(Subcommand, Debug)]
pub enum MasksCommand {
    /// List the built-in masks with their sizes and descriptions.
    #[command(
        after_long_help = "Examples:\n  halftone masks list\n  halftone masks list | grep blue"
    )]
    List,
    /// Print a mask, its level count, and the lecture's warnings (streaks, isolated pixels),
    /// summarised a line for each kind.
    #[command(
        after_long_help = "Examples:\n  halftone masks show seed-3x3\n  halftone masks generate bayer --size 16 -o bayer-16.mask && halftone masks show bayer-16.mask"
    )]
    Show {
        /// A built-in name or a mask file.
        mask: String,
    },
    /// Validate a mask file (or a built-in): whether it is a permutation of position
    /// numbers (usable by `pattern` and `ordered`) or only ranks (`ordered`), its levels, and
    /// its warnings summarised. Exits 1 when the file is not a mask.
    #[command(
        after_long_help = "Examples:\n  halftone masks check seed-3x3\n  halftone masks generate bayer --size 16 -o bayer-16.mask && halftone masks check bayer-16.mask"
    )]
    Check {
        /// A mask file or a built-in name.
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
                write_warnings(&mut out, &m)?;
            }
            print(&out)?;
        }
        MasksCommand::Check { mask } => print(&check(&mask)?)?,
    }
    Ok(ExitCode::SUCCESS)
}

/// The warnings of `m`, a line for each kind, or the line that says there are none.
fn write_warnings(out: &mut String, m: &Mask) -> anyhow::Result<()> {
    let ws = warnings::check(m);
    if ws.is_empty() {
        writeln!(out, "no streaking or isolated-pixel patterns")?;
    }
    for line in warnings::summarise(&ws) {
        writeln!(out, "warning: {line}")?;
    }
    Ok(())
}

/// `masks check`: what the mask is, what it can be used for, its levels and warnings.
fn check(name: &str) -> anyhow::Result<String> {
    let mut out = String::new();
    let builtin = Mask::builtin(name).is_some();
    let (m, kind) = match Mask::load(name, true) {
        Ok(m) => {
            let base = if builtin { "a built-in" } else { "a" };
            let what = format!(
                "{base} {}x{} position mask: the numbers 1..{} once each; usable by --method pattern and ordered",
                m.width,
                m.height,
                m.len()
            );
            (m, what)
        }
        Err(strict) => {
            // Not a permutation: as ranks it still serves ordered dithering.
            let m = Mask::load(name, false)?;
            let why = strict.to_string();
            let why = why.rsplit(": ").next().unwrap_or(&why).to_string();
            let what = format!(
                "a {}x{} rank mask, not a permutation ({why}); usable by --method ordered only (ties lit in reading order), not by pattern",
                m.width, m.height
            );
            (m, what)
        }
    };
    writeln!(out, "{name}: {kind}")?;
    writeln!(
        out,
        "levels: {} on a bilevel device; {}(L-1)+1 on an L-level device",
        m.len() + 1,
        m.len()
    )?;
    if m.len() > MAX_CHECKED_CELLS {
        writeln!(
            out,
            "streaks and isolated pixels not checked: over {MAX_CHECKED_CELLS} cells"
        )?;
    } else {
        write_warnings(&mut out, &m)?;
    }
    Ok(out)
}

/// Writes `text` to standard output in one write (a closed or broken stdout is an error).
fn print(text: &str) -> anyhow::Result<()> {
    super::stdio::check_stdout()?;
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(text.as_bytes())?;
    stdout.flush()?;
    Ok(())
}
