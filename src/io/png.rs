//! PNG writer (png crate): packed grey for bilevel and power-of-two level counts, indexed
//! colour for palettes, 8-bit grey or RGB otherwise.
//!
//! Grey samples are bit 1 = white, the same sense as the levels, so packed rows map
//! directly. With 2^b levels (4 or 16) the default is an indexed PNG at b bits whose
//! palette holds each level's sRGB grey: the same size, and the right tone in every viewer.
//! With `device_levels` the b-bit grey sample is the level and, because levels are evenly
//! spaced in light, the file says so with gAMA 1.0 (PNG spec §11.3.3.2); sBIT records the
//! depth. Other level counts (3, 5–15, 17+) do not divide the b-bit range
//! evenly, so they are written as 8-bit codes of their reflectance (sRGB-encoded, or evenly
//! spaced for a linear display).

use std::io::Write;

use png::{BitDepth, ColorType, PixelDimensions, ScaledFloat, SrgbRenderingIntent, Unit};

use super::WriteOptions;
use super::{dots_per_metre, level_codes8, row8, samples8, EncodeError, EncodeResult};
use crate::raster::Halftone;
use crate::tone::Encoding;

/// PNG bit depth of a packed sample width.
fn depth(bits: u8) -> BitDepth {
    match bits {
        1 => BitDepth::One,
        2 => BitDepth::Two,
        4 => BitDepth::Four,
        _ => BitDepth::Eight,
    }
}

/// Writes `h` as PNG.
pub(super) fn write(h: &Halftone, opts: &WriteOptions, out: &mut dyn Write) -> EncodeResult {
    let mut enc = png::Encoder::new(out, h.width as u32, h.height as u32);
    if let Some(dpi) = opts.dpi {
        let ppm = dots_per_metre(dpi);
        enc.set_pixel_dims(Some(PixelDimensions {
            xppu: ppm,
            yppu: ppm,
            unit: Unit::Meter,
        }));
    }
    let png_err = |e: png::EncodingError| match e {
        png::EncodingError::IoError(e) => EncodeError::Io(e),
        e => EncodeError::Other(e.to_string()),
    };
    let grey = h.channels() == 1 && h.palette.is_none();
    let packed_grey = grey && h.levels == 1u16 << h.bits;
    if let Some(pal) = &h.palette {
        // Indices at the halftone's own packing: rows map directly.
        enc.set_color(ColorType::Indexed);
        enc.set_depth(depth(h.bits));
        enc.set_palette(pal.iter().flatten().copied().collect::<Vec<u8>>());
        let mut w = enc.write_header().map_err(png_err)?;
        w.write_image_data(&h.planes[0]).map_err(png_err)?;
        return w.finish().map_err(png_err);
    }
    if packed_grey && h.bits > 1 && !opts.device_levels && opts.display == Encoding::Srgb {
        // Display codes at the packed size: an indexed PNG whose palette holds each level's
        // sRGB grey, so viewers that ignore gAMA still show the right tone (a 2-bit grey
        // sample would be read as evenly spaced sRGB codes, far too dark).
        let table = level_codes8(h.levels, opts.display);
        enc.set_color(ColorType::Indexed);
        enc.set_depth(depth(h.bits));
        enc.set_palette(
            table[..h.levels as usize]
                .iter()
                .flat_map(|&c| [c, c, c])
                .collect::<Vec<u8>>(),
        );
        enc.set_source_srgb(SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(png_err)?;
        w.write_image_data(&h.planes[0]).map_err(png_err)?;
        return w.finish().map_err(png_err);
    }
    if packed_grey {
        enc.set_color(ColorType::Grayscale);
        enc.set_depth(depth(h.bits));
        if h.bits > 1 && opts.display == Encoding::Srgb {
            enc.set_source_gamma(ScaledFloat::new(1.0));
        }
        let mut w = enc.write_header().map_err(png_err)?;
        if h.bits > 1 {
            w.write_chunk(png::chunk::sBIT, &[h.bits])
                .map_err(png_err)?;
        }
        w.write_image_data(&h.planes[0]).map_err(png_err)?;
        return w.finish().map_err(png_err);
    }
    let spp = samples8(h);
    enc.set_color(if spp == 1 {
        ColorType::Grayscale
    } else {
        ColorType::Rgb
    });
    enc.set_depth(BitDepth::Eight);
    if opts.display == Encoding::Srgb {
        enc.set_source_srgb(SrgbRenderingIntent::Perceptual);
    }
    let table = level_codes8(h.levels, opts.display);
    let mut w = enc.write_header().map_err(png_err)?;
    let mut data = vec![0u8; h.width * spp * h.height];
    let mut levels = vec![0u8; h.width];
    for (y, row) in data.chunks_exact_mut(h.width * spp).enumerate() {
        row8(h, y, &table, &mut levels, row);
    }
    w.write_image_data(&data).map_err(png_err)?;
    w.finish().map_err(png_err)
}
