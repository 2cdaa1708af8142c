//! The `halftone` command: parse, call the library, map errors to exit codes.

use std::process::ExitCode;

use clap::Parser;

mod cli;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            // One line, naming the file and the cause; no backtrace.
            eprintln!("halftone: {err:#}");
            ExitCode::FAILURE
        }
    }
}
