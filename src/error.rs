//! The library's one error type. Every message that concerns a file names it.

use std::path::PathBuf;

/// Everything that can go wrong in the library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An I/O failure on a named file. The cause is part of the message, not a separate
    /// error source, so a one-line report does not repeat it.
    #[error("{}: {cause}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying failure.
        cause: std::io::Error,
    },
    /// A file that could not be decoded as an image.
    #[error("{}: {msg}", path.display())]
    Decode {
        /// The file concerned.
        path: PathBuf,
        /// Why it could not be decoded.
        msg: String,
    },
    /// An image whose header claims more pixels than the limit allows.
    #[error("{}: image is {width}x{height} = {pixels} pixels, over the limit of {limit} (raise it with `max_pixels`)", path.display())]
    TooLarge {
        /// The file concerned.
        path: PathBuf,
        /// Width from the header.
        width: u64,
        /// Height from the header.
        height: u64,
        /// width × height.
        pixels: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A text file (mask, kernel, palette, preset, scene) with an error on a given line.
    #[error("{}:{line}: {msg}", path.display())]
    Parse {
        /// The file concerned (or a built-in's name).
        path: PathBuf,
        /// 1-based line number; 0 when the problem is the file as a whole.
        line: usize,
        /// What is wrong.
        msg: String,
    },
    /// An encoding failure while writing a named file.
    #[error("{}: cannot encode: {msg}", path.display())]
    Encode {
        /// The file concerned.
        path: PathBuf,
        /// Why.
        msg: String,
    },
    /// An option with a value out of range or one that does not fit the others, named by
    /// its field in [`crate::Options`]; front doors show it in their own spelling (the
    /// command line as `--dot-gain 60: …`, Python as `dot_gain=60: …`).
    #[error("{field} {value}: {msg}")]
    Option {
        /// The field of [`crate::Options`].
        field: &'static str,
        /// The value given, as text.
        value: String,
        /// What is wrong with it.
        msg: String,
    },
    /// Options that do not fit together or a value out of range.
    #[error("{0}")]
    Invalid(String),
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Wraps an I/O error with the file it concerns.
    pub fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            cause,
        }
    }

    /// A parse error at `line` of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: usize, msg: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            msg: msg.into(),
        }
    }
}
