//! The `halftone` command: parse, call the library, map errors to exit codes.

use std::process::ExitCode;

use clap::FromArgMatches;

mod cli;

/// Runs before Rust's runtime replaces a closed standard output with `/dev/null` (see
/// [`cli::stdio::note_stdout_closed`]): only a flag is stored, nothing allocated.
#[cfg(target_os = "linux")]
#[used]
#[link_section = ".init_array"]
static NOTE_CLOSED_STDOUT: extern "C" fn() = {
    extern "C" fn note() {
        // SAFETY: F_GETFD only queries descriptor 1's flags.
        if unsafe { libc::fcntl(1, libc::F_GETFD) } == -1 {
            cli::stdio::note_stdout_closed();
        }
    }
    note
};

fn main() -> ExitCode {
    let matches = cli::command().get_matches();
    let args = match cli::Cli::from_arg_matches(&matches) {
        Ok(a) => a,
        Err(e) => e.exit(),
    };
    cli::install_interrupt_handler();
    // A panic inside an image decoder is reported as one line naming the file; the default
    // report (message and backtrace) stays for every other panic.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !halftone::io::decoding_on_this_thread() {
            default_hook(info);
        }
    }));
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            // One line, naming the file and the cause; no backtrace.
            eprintln!("halftone: {}", cli::message(&err));
            ExitCode::FAILURE
        }
    }
}
