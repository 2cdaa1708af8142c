//! BMP writer (Windows BITMAPINFOHEADER, uncompressed): 1-bit with a black/white palette
//! for bilevel, 8-bit indexed for more grey levels (a ramp of their display codes) or a
//! palette, 24-bit otherwise. Rows bottom-up, each padded to 4 bytes.

use std::io::Write;

use crate::io::{dots_per_metre, level_codes8, row8, EncodeResult, WriteOptions};
use crate::raster::Halftone;

/// Writes `h` as BMP.
pub(in crate::io) fn write(h: &Halftone, opts: &WriteOptions, out: &mut dyn Write) -> EncodeResult {
    let table = level_codes8(h.levels, opts.display);
    // Colour table (RGB) and bits a pixel.
    let (palette, bpp): (Vec<[u8; 3]>, u16) = match (&h.palette, h.channels()) {
        (Some(p), _) => (
            p[..h.levels as usize].to_vec(),
            if h.bits == 1 { 1 } else { 8 },
        ),
        (None, 1) => (
            (0..h.levels as usize).map(|k| [table[k]; 3]).collect(),
            if h.bits == 1 { 1 } else { 8 },
        ),
        _ => (Vec::new(), 24),
    };
    let row_bytes = (h.width * bpp as usize).div_ceil(8);
    let padded = row_bytes.div_ceil(4) * 4;
    let data_offset = 14 + 40 + 4 * palette.len();
    let image_size = padded * h.height;
    let file_size = data_offset + image_size;
    let ppm = opts.dpi.map_or(0, dots_per_metre);

    let mut head = Vec::with_capacity(data_offset);
    head.extend_from_slice(b"BM");
    head.extend_from_slice(&(file_size.min(u32::MAX as usize) as u32).to_le_bytes());
    head.extend_from_slice(&[0; 4]);
    head.extend_from_slice(&(data_offset as u32).to_le_bytes());
    head.extend_from_slice(&40u32.to_le_bytes());
    head.extend_from_slice(&(h.width as i32).to_le_bytes());
    // Positive height: rows stored bottom-up.
    head.extend_from_slice(&(h.height as i32).to_le_bytes());
    head.extend_from_slice(&1u16.to_le_bytes());
    head.extend_from_slice(&bpp.to_le_bytes());
    head.extend_from_slice(&0u32.to_le_bytes()); // BI_RGB
    head.extend_from_slice(&(image_size.min(u32::MAX as usize) as u32).to_le_bytes());
    head.extend_from_slice(&ppm.to_le_bytes());
    head.extend_from_slice(&ppm.to_le_bytes());
    head.extend_from_slice(&(palette.len() as u32).to_le_bytes());
    head.extend_from_slice(&0u32.to_le_bytes());
    for c in &palette {
        head.extend_from_slice(&[c[2], c[1], c[0], 0]);
    }
    out.write_all(&head)?;

    let mut row = vec![0u8; padded];
    let mut levels = vec![0u8; h.width];
    for y in (0..h.height).rev() {
        match bpp {
            // Level bits are palette indices: rows map directly.
            1 => {
                row[..h.stride].copy_from_slice(h.row(0, y));
                let tail = h.width % 8;
                if tail != 0 {
                    row[h.stride - 1] &= 0xFFu8 << (8 - tail);
                }
            }
            8 => h.unpack_row(0, y, &mut row[..h.width]),
            _ => {
                row8(h, y, &table, &mut levels, &mut row[..h.width * 3]);
                for px in row[..h.width * 3].chunks_exact_mut(3) {
                    px.swap(0, 2);
                }
            }
        }
        out.write_all(&row)?;
    }
    Ok(())
}
