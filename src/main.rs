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
    let code = match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            // One line, naming the file and the cause; no backtrace.
            eprintln!("halftone: {}", cli::message(&err));
            ExitCode::FAILURE
        }
    };
    write_peak_memory();
    code
}

/// With `HALFTONE_PEAK_FILE` set, writes this process's peak resident size in KiB (Linux's
/// `VmHWM`) to that file on the way out. A parent's `wait4` cannot tell it: Linux carries the
/// parent's own peak into a child's `ru_maxrss` across `exec`, so a large test harness would
/// seem to be the child's use. The memory-bound tests read this instead.
fn write_peak_memory() {
    let Some(path) = std::env::var_os("HALFTONE_PEAK_FILE") else {
        return;
    };
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    if let Some(kib) = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
    {
        let _ = std::fs::write(path, kib.to_string());
    }
}
