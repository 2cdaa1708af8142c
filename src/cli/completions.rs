//! `halftone completions SHELL` and `halftone man`: shell completion scripts and man pages,
//! generated from the command-line definitions themselves.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, ValueEnum};
use clap_complete::Shell;

/// Examples shown by `halftone completions --help`. Each makes its folder first, so it
/// works in a fresh home.
pub const COMPLETIONS_EXAMPLES: &str = "Examples:
  mkdir -p ~/.local/share/bash-completion/completions
  halftone completions bash > ~/.local/share/bash-completion/completions/halftone
  mkdir -p ~/.zfunc && halftone completions zsh > ~/.zfunc/_halftone   # fpath+=(~/.zfunc)
  mkdir -p ~/.config/fish/completions
  halftone completions fish > ~/.config/fish/completions/halftone.fish";

/// Examples shown by `halftone man --help`.
pub const MAN_EXAMPLES: &str = "Examples:
  halftone man > halftone.1 && man ./halftone.1
  halftone man --dir man/                 # halftone.1, halftone-convert.1, … one a subcommand
  mkdir -p ~/.local/share/man/man1 && halftone man --dir ~/.local/share/man/man1";

/// `halftone man` arguments.
#[derive(Args, Debug)]
pub struct ManArgs {
    /// Write a page for the command and one for every subcommand (halftone.1,
    /// halftone-convert.1, halftone-masks-show.1, …) into this folder, made if missing,
    /// instead of printing the top page.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

/// Shells with completion scripts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ShellArg {
    /// Bash.
    Bash,
    /// Zsh.
    Zsh,
    /// Fish.
    Fish,
    /// PowerShell.
    Powershell,
    /// Elvish.
    Elvish,
}

/// `halftone completions` arguments.
#[derive(Args, Debug)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: ShellArg,
}

/// Prints the completion script for a shell on standard output.
pub fn run_completions(a: CompletionsArgs) -> anyhow::Result<ExitCode> {
    let shell = match a.shell {
        ShellArg::Bash => Shell::Bash,
        ShellArg::Zsh => Shell::Zsh,
        ShellArg::Fish => Shell::Fish,
        ShellArg::Powershell => Shell::PowerShell,
        ShellArg::Elvish => Shell::Elvish,
    };
    let mut cmd = super::command();
    let mut out = Vec::new();
    clap_complete::generate(shell, &mut cmd, "halftone", &mut out);
    std::io::stdout().write_all(&out)?;
    Ok(ExitCode::SUCCESS)
}

/// Prints the top man page (roff) on standard output, or writes every page into `--dir`.
pub fn run_man(a: ManArgs) -> anyhow::Result<ExitCode> {
    let mut cmd = super::command();
    // Built so that every subcommand knows its full name (`halftone masks show`).
    cmd.build();
    match a.dir {
        None => {
            let mut out = Vec::new();
            clap_mangen::Man::new(cmd).render(&mut out)?;
            super::stdio::check_stdout()?;
            std::io::stdout().write_all(&out)?;
        }
        Some(dir) => {
            std::fs::create_dir_all(&dir).map_err(|e| halftone::Error::io(&dir, e))?;
            let mut written = Vec::new();
            write_pages(&cmd, "halftone", &dir, &mut written)?;
            eprintln!(
                "wrote {} man pages in {} ({}, …)",
                written.len(),
                dir.display(),
                written
                    .iter()
                    .take(3)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes the page of `cmd` as `NAME.1` and then its subcommands' pages as `NAME-SUB.1`,
/// each listing every flag with its long help.
fn write_pages(
    cmd: &clap::Command,
    name: &str,
    dir: &Path,
    written: &mut Vec<String>,
) -> anyhow::Result<()> {
    let page = cmd.clone();
    let mut out = Vec::new();
    clap_mangen::Man::new(page).render(&mut out)?;
    let file = format!("{name}.1");
    let path = dir.join(&file);
    halftone::io::write_atomic(&path, |w| w.write_all(&out))?;
    written.push(file);
    for sub in cmd.get_subcommands() {
        if sub.get_name() == "help" {
            continue;
        }
        write_pages(sub, &format!("{name}-{}", sub.get_name()), dir, written)?;
    }
    Ok(())
}
