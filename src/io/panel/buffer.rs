//! Panel-native encodings: the buffers e-paper firmware reads, from a palette (or grey)
//! halftone and the device's ink codes.
//!
//! - `raw`: every pixel's ink code packed at the device's bits a pixel (1, 2, 4 or 8), the
//!   first pixel in the most significant bits of its byte, each row padded to a whole byte
//!   (the zero bits of the padding), rows top to bottom, no header.
//! - `h`: the same bytes as a C header: `#define NAME_WIDTH`, `NAME_HEIGHT`, `NAME_BITS`
//!   and `const uint8_t NAME[]`.
//! - `planes`: for black-and-white and three-colour panels, one bit a pixel, MSB first,
//!   rows padded to a byte: the black plane (the black pixels hold the profile's
//!   `planes.black` bit, 0 by default; every other pixel the other bit), then, for three
//!   inks, the colour plane (the colour ink's pixels hold `planes.colour`, 1 by default).
//! - `nibbles`: 16-grey panels as epdiy's framebuffer holds them: two pixels a byte, the
//!   even pixel in the low nibble, the odd one in the high nibble, rows padded to a byte.
//!
//! Without a device the code of a pixel is its index (palette) or level (grey).

use std::io::Write;
use std::sync::Arc;

use super::{bits_for, Device};
use crate::io::sink::{Band, PageEncoder, PageHeader, WholePage};
use crate::io::{EncodeError, EncodeResult, Format, WriteOptions};
use crate::raster::Halftone;

/// The code written for each index (palette index or grey level).
fn codes(levels: u16, device: Option<&Device>) -> Vec<u8> {
    match device {
        Some(d) => d.codes(),
        None => (0..levels).map(|l| l as u8).collect(),
    }
}

/// Bits a pixel of `raw` and `h`.
fn packed_bits(levels: u16, device: Option<&Device>) -> u8 {
    match device {
        Some(d) => d.packed_bits(),
        None => bits_for((levels.max(1) - 1) as u8),
    }
}

/// Why a page of this shape cannot be written as a panel format; `None` when it can.
pub fn check(page: &PageHeader, opts: &WriteOptions) -> Option<String> {
    if !opts.format.is_panel_buffer() {
        return None;
    }
    let device = opts.device.as_deref();
    let name = opts.format.name();
    if page.channels != 1 {
        return Some(format!(
            "{name} holds one plane of ink codes; this halftone has {} planes (RGB): use a \
             `device` or a `palette`",
            page.channels
        ));
    }
    if let Some(d) = device {
        if page.levels as usize > d.inks.len() {
            return Some(format!(
                "the halftone has {} levels, the device {} has {} inks",
                page.levels,
                d.name,
                d.inks.len()
            ));
        }
    }
    let codes = codes(page.levels, device);
    let max = codes.iter().copied().max().unwrap_or(0);
    match opts.format {
        Format::Raw | Format::CHeader => {
            let bits = packed_bits(page.levels, device);
            (bits < 8 && max >> bits != 0)
                .then(|| format!("ink code {max} does not fit in {bits} bits a pixel"))
        }
        Format::Nibbles => (max > 15)
            .then(|| format!("nibbles hold 4-bit codes (0 to 15); this halftone needs code {max}")),
        Format::Planes => match device {
            Some(d) => plane_inks(d).err(),
            None if page.palette.is_none() && page.levels == 2 => None,
            None => Some(
                "planes need a `device` with black and white inks (or a bilevel grey halftone)"
                    .into(),
            ),
        },
        _ => None,
    }
}

/// The indices of the black ink and of the colour ink (if any) of a two- or three-ink
/// device with inks named `black` and `white`.
fn plane_inks(d: &Device) -> Result<(usize, Option<usize>), String> {
    let find = |n: &str| d.inks.iter().position(|i| i.name == n);
    let (Some(black), Some(white)) = (find("black"), find("white")) else {
        return Err(format!(
            "planes are for panels with inks named black and white; {} has {}",
            d.name,
            d.inks
                .iter()
                .map(|i| i.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    };
    match d.inks.len() {
        2 => Ok((black, None)),
        3 => Ok((black, (0..3).find(|&i| i != black && i != white))),
        n => Err(format!(
            "planes are for two- and three-ink panels; {} has {n} inks (use raw)",
            d.name
        )),
    }
}

/// Packs `values` (each below 2^bits) MSB first into `out` (zeroed, a whole row).
fn pack(values: &[u8], bits: u8, out: &mut [u8]) {
    out.fill(0);
    let per = (8 / bits) as usize;
    for (x, &v) in values.iter().enumerate() {
        let shift = 8 - bits as usize * (x % per + 1);
        out[x / per] |= v << shift;
    }
}

/// The packed `raw` bytes of a whole halftone.
pub fn raw_bytes(h: &Halftone, device: Option<&Device>) -> Vec<u8> {
    let bits = packed_bits(h.levels, device);
    let codes = codes(h.levels, device);
    let stride = (h.width * bits as usize).div_ceil(8);
    let mut out = vec![0u8; stride * h.height];
    let mut idx = vec![0u8; h.width];
    for (y, row) in out.chunks_exact_mut(stride).enumerate() {
        h.unpack_row(0, y, &mut idx);
        for v in idx.iter_mut() {
            *v = codes[*v as usize];
        }
        pack(&idx, bits, row);
    }
    out
}

fn write_raw(h: &Halftone, device: Option<&Device>, out: &mut dyn Write) -> EncodeResult {
    out.write_all(&raw_bytes(h, device))?;
    Ok(())
}

fn write_nibbles(h: &Halftone, device: Option<&Device>, out: &mut dyn Write) -> EncodeResult {
    let codes = codes(h.levels, device);
    let stride = h.width.div_ceil(2);
    let mut row = vec![0u8; stride];
    let mut idx = vec![0u8; h.width];
    for y in 0..h.height {
        h.unpack_row(0, y, &mut idx);
        row.fill(0);
        for (x, &i) in idx.iter().enumerate() {
            // epdiy: the even pixel in the low nibble, the odd one in the high nibble.
            row[x / 2] |= codes[i as usize] << (4 * (x % 2));
        }
        out.write_all(&row)?;
    }
    Ok(())
}

fn write_planes(h: &Halftone, device: Option<&Device>, out: &mut dyn Write) -> EncodeResult {
    let (black, colour, bits) = match device {
        Some(d) => {
            let (b, c) = plane_inks(d).map_err(EncodeError::Other)?;
            (b as u8, c.map(|c| c as u8), d.planes)
        }
        // A bilevel grey halftone: level 0 is black.
        None => (0, None, Default::default()),
    };
    let stride = h.width.div_ceil(8);
    let mut idx = vec![0u8; h.width];
    let mut bit_row = vec![0u8; h.width];
    let mut packed = vec![0u8; stride];
    let mut plane = |target: u8, on: u8, out: &mut dyn Write| -> EncodeResult {
        for y in 0..h.height {
            h.unpack_row(0, y, &mut idx);
            for (b, &i) in bit_row.iter_mut().zip(&idx) {
                *b = if i == target { on } else { 1 - on };
            }
            pack(&bit_row, 1, &mut packed);
            out.write_all(&packed)?;
        }
        Ok(())
    };
    plane(black, bits.black, out)?;
    if let Some(c) = colour {
        plane(c, bits.colour, out)?;
    }
    Ok(())
}

/// A C identifier from a device name (`spectra6-7in3` → `spectra6_7in3`).
fn c_name(device: Option<&Device>) -> String {
    let base = device.map_or("halftone", |d| d.name.as_str());
    let mut s: String = base
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

fn write_c_header(h: &Halftone, device: Option<&Device>, out: &mut dyn Write) -> EncodeResult {
    let bytes = raw_bytes(h, device);
    let name = c_name(device);
    let upper = name.to_ascii_uppercase();
    let bits = packed_bits(h.levels, device);
    let mut s = String::with_capacity(bytes.len() * 6 + 512);
    s.push_str(&format!(
        "/* {name}: {}x{} pixels, {bits} bits a pixel (ink codes), first pixel in the most \
         significant bits, rows padded to a byte. Written by halftone. */\n",
        h.width, h.height
    ));
    s.push_str(&format!(
        "#include <stdint.h>\n\n#define {upper}_WIDTH {}\n#define {upper}_HEIGHT {}\n\
         #define {upper}_BITS {bits}\n\nconst uint8_t {name}[{}] = {{\n",
        h.width,
        h.height,
        bytes.len()
    ));
    for chunk in bytes.chunks(16) {
        s.push_str("   ");
        for b in chunk {
            s.push_str(&format!(" 0x{b:02x},"));
        }
        s.push('\n');
    }
    s.push_str("};\n");
    out.write_all(s.as_bytes())?;
    Ok(())
}

/// The encoder of a panel format.
pub fn encoder(opts: &WriteOptions) -> Box<dyn PageEncoder> {
    let device = opts.device.clone();
    let format = opts.format;
    Box::new(WholePage::new(
        move |h: &Halftone, _dpi, out: &mut dyn Write| {
            let d = device.as_deref();
            match format {
                Format::Raw => write_raw(h, d, out),
                Format::CHeader => write_c_header(h, d, out),
                Format::Planes => write_planes(h, d, out),
                Format::Nibbles => write_nibbles(h, d, out),
                other => Err(EncodeError::Other(format!(
                    "{} is not a panel format",
                    other.name()
                ))),
            }
        },
    ))
}

/// Wraps an encoder so that a page of the device's palette is written in the inks'
/// nominal colours (what the driver expects) instead of the colours the panel shows.
pub struct NominalColours {
    inner: Box<dyn PageEncoder>,
    device: Arc<Device>,
}

impl NominalColours {
    /// `inner` with the device's nominal colours.
    pub fn new(inner: Box<dyn PageEncoder>, device: Arc<Device>) -> NominalColours {
        NominalColours { inner, device }
    }
}

impl PageEncoder for NominalColours {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        let mut page = page.clone();
        if let Some(p) = &mut page.palette {
            if p.len() == self.device.inks.len() {
                *p = self.device.nominal_colours();
            }
        }
        self.inner.begin_page(&page, out)
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        self.inner.write_rows(band, out)
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        self.inner.end_page(out)
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        self.inner.finish(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packs_msb_first_with_padding() {
        let mut out = [0u8; 2];
        pack(&[1, 0, 1, 1, 0, 0, 0, 1, 1], 1, &mut out);
        assert_eq!(out, [0b1011_0001, 0b1000_0000]);
        let mut out = [0u8; 2];
        pack(&[3, 0, 2, 1, 1], 2, &mut out);
        assert_eq!(out, [0b1100_1001, 0b0100_0000]);
        let mut out = [0u8; 2];
        pack(&[5, 6, 1], 4, &mut out);
        assert_eq!(out, [0x56, 0x10]);
    }

    #[test]
    fn c_names_are_identifiers() {
        let d = Device::builtin("spectra6-7in3-v2").unwrap();
        assert_eq!(c_name(Some(&d)), "spectra6_7in3_v2");
        assert_eq!(c_name(None), "halftone");
    }
}
