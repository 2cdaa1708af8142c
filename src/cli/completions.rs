//! `halftone completions SHELL` and `halftone man`: shell completion scripts and a man
//! page, both generated from the command-line definitions themselves.

use std::io::Write;
use std::process::ExitCode;

use clap::{Args, CommandFactory, ValueEnum};
use clap_complete::Shell;

use super::Cli;

/// Examples shown by `halftone completions --help`.
pub const COMPLETIONS_EXAMPLES: &str = "Examples:
  halftone completions bash > ~/.local/share/bash-completion/completions/halftone
  halftone completions zsh > ~/.zfunc/_halftone      # with fpath+=(~/.zfunc) in ~/.zshrc
  halftone completions fish > ~/.config/fish/completions/halftone.fish
  halftone completions powershell >> $PROFILE";

/// Examples shown by `halftone man --help`.
pub const MAN_EXAMPLES: &str = "Examples:
  halftone man > halftone.1 && man ./halftone.1
  halftone man | gzip > ~/.local/share/man/man1/halftone.1.gz";

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
    let mut cmd = Cli::command();
    let mut out = Vec::new();
    clap_complete::generate(shell, &mut cmd, "halftone", &mut out);
    std::io::stdout().write_all(&out)?;
    Ok(ExitCode::SUCCESS)
}

/// Prints the man page (roff) on standard output.
pub fn run_man() -> anyhow::Result<ExitCode> {
    let man = clap_mangen::Man::new(Cli::command());
    let mut out = Vec::new();
    man.render(&mut out)?;
    std::io::stdout().write_all(&out)?;
    Ok(ExitCode::SUCCESS)
}
