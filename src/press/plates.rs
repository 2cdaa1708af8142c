//! CMYK plates: the four ink planes of a separation, their file names, a 1-bit TIFF per
//! plate with the InkNames tag, and the press preview.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use tiff::encoder::compression::{CompressionAlgorithm, Deflate};
use tiff::encoder::TiffEncoder;
use tiff::tags::{CompressionMethod, PhotometricInterpretation, Tag};

use super::Press;
use crate::error::{Error, Result};
use crate::raster::Halftone;

/// Ink names in plate order, as they go into file names.
pub const INKS: [&str; 4] = ["cyan", "magenta", "yellow", "black"];

/// `poster.tif` → `poster-cyan.tif` (and `-magenta`, `-yellow`, `-black`).
pub fn plate_path(output: &Path, ink: &str) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match output.extension() {
        Some(ext) => format!("{stem}-{ink}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{ink}"),
    };
    output.with_file_name(name)
}

/// One plane of `h` as a one-plane halftone (a plate).
pub fn plate(h: &Halftone, c: usize) -> Halftone {
    Halftone {
        width: h.width,
        height: h.height,
        levels: h.levels,
        bits: h.bits,
        stride: h.stride,
        planes: vec![h.planes[c].clone()],
        palette: None,
    }
}

/// A bilevel plate as a TIFF: 1 bit a pixel, WhiteIsZero (bit 1 = ink), Deflate, the
/// resolution and the InkNames tag (TIFF 6.0 §16: tag 333, with NumberOfInks 334).
pub fn plate_tiff(h: &Halftone, plane: usize, ink: &str, dpi: Option<f64>) -> Result<Vec<u8>> {
    if h.levels != 2 {
        return Err(Error::Invalid(
            "CMYK TIFF plates are bilevel: use `levels` 2".into(),
        ));
    }
    let mut raw = vec![0u8; h.stride * h.height];
    let tail = h.width % 8;
    for y in 0..h.height {
        let src = h.row(plane, y);
        let dst = &mut raw[y * h.stride..(y + 1) * h.stride];
        for (o, &b) in dst.iter_mut().zip(src) {
            *o = !b;
        }
        if tail != 0 {
            if let Some(last) = dst.last_mut() {
                *last &= 0xFFu8 << (8 - tail);
            }
        }
    }
    let mut strip = Vec::new();
    Deflate::default()
        .write_to(&mut strip, &raw)
        .map_err(|e| Error::Invalid(format!("deflate: {e}")))?;
    let err = |e: tiff::TiffError| Error::Invalid(format!("TIFF: {e}"));
    let mut file = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut file).map_err(err)?;
        let mut dir = enc.image_directory().map_err(err)?;
        let offset = dir.write_data(strip.as_slice()).map_err(err)? as u32;
        dir.write_tag(Tag::ImageWidth, h.width as u32)
            .map_err(err)?;
        dir.write_tag(Tag::ImageLength, h.height as u32)
            .map_err(err)?;
        dir.write_tag(Tag::BitsPerSample, 1u16).map_err(err)?;
        dir.write_tag(Tag::Compression, CompressionMethod::Deflate)
            .map_err(err)?;
        dir.write_tag(
            Tag::PhotometricInterpretation,
            PhotometricInterpretation::WhiteIsZero,
        )
        .map_err(err)?;
        dir.write_tag(Tag::StripOffsets, offset).map_err(err)?;
        dir.write_tag(Tag::SamplesPerPixel, 1u16).map_err(err)?;
        dir.write_tag(Tag::RowsPerStrip, h.height.max(1) as u32)
            .map_err(err)?;
        dir.write_tag(Tag::StripByteCounts, strip.len() as u32)
            .map_err(err)?;
        if let Some(dpi) = dpi {
            crate::io::codec::tiff::write_resolution(&mut dir, dpi).map_err(err)?;
        }
        // InkNames: NUL-terminated ASCII, capitalised as RIPs list them.
        let mut name = ink.to_string();
        if let Some(f) = name.get_mut(0..1) {
            f.make_ascii_uppercase();
        }
        dir.write_tag(Tag::Unknown(333), name.as_str())
            .map_err(err)?;
        dir.write_tag(Tag::Unknown(334), 1u16).map_err(err)?;
        dir.finish().map_err(err)?;
    }
    Ok(file.into_inner())
}

/// What the press would print, for the screen: each `block × block` area's ink coverages
/// (the share of pixels at level 0, or the mean ink of multi-level plates) printed through
/// the press model, paper shown as white. Returns `(width, height, interleaved sRGB)`.
pub fn preview(h: &Halftone, press: &Press, block: usize) -> (usize, usize, Vec<u8>) {
    let (w, ht, cov) = preview_coverages(h, block);
    let mut out = Vec::with_capacity(w * ht * 3);
    for c in &cov {
        out.extend_from_slice(&press.preview_srgb8(*c));
    }
    (w, ht, out)
}

/// Mean ink coverages (0..1, C, M, Y, K) of each `block × block` area of the plates, the
/// preview's input: `(width, height, coverages)`.
pub fn preview_coverages(h: &Halftone, block: usize) -> (usize, usize, Vec<[f64; 4]>) {
    let block = block.max(1);
    let (w, ht) = (h.width.div_ceil(block), h.height.div_ceil(block));
    let mut sums = vec![[0f64; 4]; w * ht];
    let mut counts = vec![0u32; w * ht];
    let mut levels = vec![0u8; h.width];
    let top = (h.levels - 1) as f64;
    #[allow(clippy::needless_range_loop)] // c indexes the plate and the sums' inner arrays
    for c in 0..4.min(h.channels()) {
        for y in 0..h.height {
            h.unpack_row(c, y, &mut levels);
            let by = y / block;
            for (x, &l) in levels.iter().enumerate() {
                let i = by * w + x / block;
                sums[i][c] += 1.0 - l as f64 / top;
                if c == 0 {
                    counts[i] += 1;
                }
            }
        }
    }
    let cov = sums
        .iter()
        .zip(&counts)
        .map(|(s, &n)| s.map(|v| v / n.max(1) as f64))
        .collect();
    (w, ht, cov)
}
