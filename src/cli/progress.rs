//! A progress line for single commands that take a while: shown on stderr only when it is
//! a terminal, and only once the work has run for a second, so quick commands and pipes
//! print nothing extra.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How long work runs before its progress line appears.
const DELAY: Duration = Duration::from_secs(1);

/// A spinner with a message and the elapsed time; cleared when dropped.
pub struct Activity {
    pb: ProgressBar,
}

impl Activity {
    /// Starts timing `message`; the line appears after [`DELAY`] on a terminal.
    pub fn start(message: impl Into<String>) -> Activity {
        let pb = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        pb.set_style(
            ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("valid template"),
        );
        pb.set_message(message.into());
        if std::io::stderr().is_terminal() {
            let later = pb.clone();
            std::thread::spawn(move || {
                std::thread::sleep(DELAY);
                if !later.is_finished() {
                    later.set_draw_target(ProgressDrawTarget::stderr());
                    later.enable_steady_tick(Duration::from_millis(120));
                }
            });
        }
        Activity { pb }
    }

    /// Changes the message (the stage of the work).
    pub fn set(&self, message: impl Into<String>) {
        self.pb.set_message(message.into());
    }

    /// A bar of `len` steps instead of a spinner, for work that counts its steps.
    pub fn steps(&self, len: u64) {
        self.pb.set_length(len);
        self.pb.set_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} ({elapsed})")
                .expect("valid template")
                .progress_chars("=> "),
        );
    }

    /// One step done.
    pub fn inc(&self) {
        self.pb.inc(1);
    }
}

impl Drop for Activity {
    fn drop(&mut self) {
        self.pb.finish_and_clear();
    }
}
