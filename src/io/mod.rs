//! Reading images (with a pixel limit checked before allocation) and writing halftones in
//! printer-ready formats, atomically.
//!
//! STUB: the signatures below are the contract; bodies are being written.

use std::io::Write;
use std::path::Path;

use crate::error::Result;
use crate::raster::{Halftone, Image};
use crate::tone::Encoding;

/// Limits and choices for decoding.
#[derive(Clone, Debug)]
pub struct ReadOptions {
    /// Refuse images whose header claims more pixels than this.
    pub max_pixels: u64,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            max_pixels: 1_000_000_000,
        }
    }
}

/// Output file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// Netpbm bitmap, P4 (bilevel grey only; 1 = black ink).
    Pbm,
    /// Netpbm greymap, P5.
    Pgm,
    /// Netpbm pixmap, P6.
    Ppm,
    /// PNG: 1-bit grey for bilevel, 2/4/8-bit grey, 8-bit RGB or indexed colour.
    Png,
    /// TIFF: bilevel with G4/Deflate/LZW/PackBits/none; 8-bit grey or RGB otherwise.
    Tiff,
    /// BMP: 1-bit for bilevel, 8-bit indexed or 24-bit otherwise.
    Bmp,
}

/// TIFF compression.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// CCITT Group 4 (bilevel only).
    G4,
    /// Deflate (zlib).
    Deflate,
    /// LZW.
    Lzw,
    /// PackBits run lengths.
    PackBits,
    /// Uncompressed.
    None,
}

/// How a halftone is encoded.
#[derive(Clone, Debug)]
pub struct WriteOptions {
    /// The format.
    pub format: Format,
    /// Resolution to record, in dots per inch.
    pub dpi: Option<f64>,
    /// PGM/PPM maxval; `None` = levels − 1 (the device's own levels).
    pub maxval: Option<u16>,
    /// TIFF compression; `None` = the format's default.
    pub compression: Option<Compression>,
    /// How level reflectance maps to codes when a format needs more codes than levels:
    /// `Srgb` encodes reflectance k/(L−1) to sRGB (correct tone on screen), `Linear` spaces
    /// codes evenly (for `--no-linearize`).
    pub display: Encoding,
}

impl Format {
    /// The format named by a path's extension.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Format::from_name(&ext)
    }

    /// The format of a name such as `pbm`, `png`, `tif`.
    pub fn from_name(name: &str) -> Option<Format> {
        Some(match name.to_ascii_lowercase().as_str() {
            "pbm" => Format::Pbm,
            "pgm" => Format::Pgm,
            "ppm" | "pnm" => Format::Ppm,
            "png" => Format::Png,
            "tif" | "tiff" => Format::Tiff,
            "bmp" => Format::Bmp,
            _ => return None,
        })
    }
}

/// Decodes the image at `path` (`-` reads standard input).
pub fn read_image(path: &Path, opts: &ReadOptions) -> Result<Image> {
    let _ = (path, opts);
    todo!()
}

/// Decodes an image held in memory; `name` is used in error messages.
pub fn read_image_bytes(bytes: &[u8], name: &Path, opts: &ReadOptions) -> Result<Image> {
    let _ = (bytes, name, opts);
    todo!()
}

/// Encodes `h` into `out`; `name` is used in error messages.
pub fn encode(h: &Halftone, opts: &WriteOptions, name: &Path, out: &mut dyn Write) -> Result<()> {
    let _ = (h, opts, name, out);
    todo!()
}

/// Writes `h` to `path` atomically (temp file in the same folder, then rename); `-` writes
/// standard output.
pub fn write_halftone(h: &Halftone, path: &Path, opts: &WriteOptions) -> Result<()> {
    let _ = (h, path, opts);
    todo!()
}

/// Writes a file atomically: `fill` writes into a temp file in the same folder, which is
/// renamed over `path` only on success; on failure no file is left behind.
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let _ = (path, fill);
    todo!()
}

/// Removes the temp files of atomic writes still in progress (for an interrupt handler).
pub fn remove_temp_files() {}
