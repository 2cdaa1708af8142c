//! Standard input and output for the command line: `-` as a file name, and a closed
//! standard output detected before Rust's runtime hides it. Process state such as this
//! belongs to the binary; the library takes readers and writers.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use halftone::io::ReadOptions;
use halftone::{Error, Image};

/// Set by [`note_stdout_closed`] (the binary's start-up hook).
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Records that the process started with standard output closed (`>&-`). Rust's runtime
/// opens `/dev/null` on a closed descriptor 0–2 before `main` runs, so writes would vanish
/// and succeed; `main.rs` looks at descriptor 1 earlier (an `.init_array` constructor) and
/// calls this, and [`check_stdout`] then fails.
pub fn note_stdout_closed() {
    STDOUT_CLOSED.store(true, Ordering::Relaxed);
}

/// Fails when standard output is closed (`>&-`): Rust's `stdout` then discards every write
/// and reports success, so a run would print nothing and exit 0.
pub fn check_stdout() -> halftone::Result<()> {
    #[cfg(unix)]
    {
        // SAFETY: F_GETFD only queries the descriptor's flags; it touches no memory.
        let closed = unsafe { libc::fcntl(1, libc::F_GETFD) } == -1;
        if closed || STDOUT_CLOSED.load(Ordering::Relaxed) {
            return Err(Error::io(
                "<stdout>",
                std::io::Error::other("standard output is closed"),
            ));
        }
    }
    Ok(())
}

/// True for the file name `-`: standard input or output.
pub fn is_dash(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Decodes the image at `path`, `-` being standard input (read once, under the same bound
/// as any other stream).
pub fn read_image(path: &Path, opts: &ReadOptions) -> halftone::Result<Image> {
    if is_dash(path) {
        let name = Path::new("<stdin>");
        let bytes = halftone::io::read_stream(&mut std::io::stdin().lock(), name, opts)?;
        return halftone::io::read_image_bytes(&bytes, name, opts);
    }
    halftone::io::read_image(path, opts)
}

/// The size from the header of the image at `path`; `None` for standard input (`-`), which
/// can be read only once, and for other streams.
pub fn read_dimensions(path: &Path, opts: &ReadOptions) -> halftone::Result<Option<(u32, u32)>> {
    if is_dash(path) {
        return Ok(None);
    }
    halftone::io::read_dimensions(path, opts)
}
