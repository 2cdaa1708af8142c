//! The `halftone` command: parse, call the library, map errors to exit codes.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches};

mod cli;

fn main() -> ExitCode {
    let matches = cli::Cli::command().get_matches();
    let args = match cli::Cli::from_arg_matches(&matches) {
        Ok(a) => a,
        Err(e) => e.exit(),
    };
    cli::install_interrupt_handler();
    match cli::run(args, &matches) {
        Ok(code) => code,
        Err(err) => {
            // One line, naming the file and the cause; no backtrace.
            eprintln!("halftone: {err:#}");
            ExitCode::FAILURE
        }
    }
}
