//! The print server's IPP requests: any bytes as the body of an HTTP POST to
//! `halftone serve`, answered by the library's printer (`Printer::handle_bytes`), and any job
//! they made processed to a folder under a 64-kilopixel limit. Every request gets an IPP
//! response that parses, with a status code; nothing panics, and a job ends completed or
//! aborted with a message.
#![no_main]

use std::sync::OnceLock;

use halftone::serve::{Config, Limits, Printer};
use libfuzzer_sys::fuzz_target;

/// The folder jobs are written to, shared by every run.
fn spool() -> &'static std::path::Path {
    static DIR: OnceLock<std::path::PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("halftone-fuzz-ipp-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a folder for the jobs");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let toml = format!(
        "[queue.q]\npreset = \"thermal-203\"\nmax_pixels = 65536\nbackend = \"file://{}\"\n\
         [queue.l]\npreset = \"label-203\"\nmax_pixels = 65536\nbackend = \"file://{}\"\n",
        spool().display(),
        spool().display()
    );
    let config = Config::parse(&toml).expect("the queue file parses");
    let printer = Printer::new(
        config,
        "127.0.0.1:8631",
        Limits {
            max_request: 1 << 18,
            max_jobs: 4,
            max_pages: 8,
            max_job_seconds: 5,
        },
    );
    // The request, and the same bytes told to be cut short (the HTTP layer's view of a body
    // over the limit).
    for too_long in [false, true] {
        let resp = printer.handle_bytes(data.to_vec(), too_long);
        let parsed = ipp::parser::IppParser::new(ipp::reader::IppReader::new(
            std::io::Cursor::new(resp),
        ))
        .parse()
        .expect("every response is IPP");
        let _ = parsed.header().status_code();
    }
    while let Some(id) = printer.wait_for_job(std::time::Duration::ZERO) {
        let _ = printer.process(id);
        let (state, message) = printer.job_state(id).expect("the job is kept");
        assert!(state.is_finished(), "job {id} left {state:?}");
        if state != halftone::serve::JobState::Completed {
            assert!(!message.is_empty());
        }
    }
});
