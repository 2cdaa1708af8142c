//! The limits every reader keeps: the pixel limit checked from a header before anything is
//! allocated, the most bytes an input may have, and the one-line error naming the file.

use std::path::Path;

use super::ReadOptions;
use crate::error::{Error, Result};

/// The most bytes an input may have: 16 bytes a pixel (RGBA at 32-bit float, the widest
/// samples any reader here takes) for the pixel limit, and 16 MiB for headers and metadata.
/// A larger file cannot be an image within the limit, so it is refused before it is read.
pub fn max_input_bytes(opts: &ReadOptions) -> u64 {
    opts.max_pixels.saturating_mul(16).saturating_add(16 << 20)
}

/// A one-line decode error naming the file.
pub fn decode_err(name: &Path, msg: String) -> Error {
    Error::Decode {
        path: name.to_path_buf(),
        msg: msg.replace(['\n', '\r'], " "),
    }
}

/// Refuses images over the pixel limit, from header dimensions.
pub fn check_pixels(name: &Path, width: u32, height: u32, opts: &ReadOptions) -> Result<()> {
    let pixels = width as u64 * height as u64;
    if pixels > opts.max_pixels {
        return Err(Error::TooLarge {
            path: name.to_path_buf(),
            width: width as u64,
            height: height as u64,
            pixels,
            limit: opts.max_pixels,
        });
    }
    Ok(())
}
