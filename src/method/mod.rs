//! Halftoning methods. Every method is one type behind the [`Method`] trait, so the CLI,
//! the batch runner, the benchmark and the stability tests see them all the same way.
//! A method knows nothing of files or flags.

pub mod auto_palette;
pub mod content;
pub mod dbs;
pub mod device;
pub mod diffusion;
pub mod gamut;
pub mod ordered;
pub mod ordered_palette;
pub mod pattern;
pub mod rows;
pub mod screen;
pub mod threshold;
pub mod transfer;

use rayon::prelude::*;

use crate::error::Result;
use crate::raster::{Halftone, PlaneRef, Planes};

/// A halftoning method.
pub trait Method: Send + Sync {
    /// A short name for reports, e.g. `pattern(seed-3x3, expand)`.
    fn name(&self) -> String;

    /// Output size for an input of `width × height` (most methods keep the size).
    fn output_size(&self, width: usize, height: usize) -> (usize, usize) {
        (width, height)
    }

    /// Halftones the planes (one for grey, three for RGB).
    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone>;

    /// Row streaming, when the method can halftone an image band by band with the same bytes
    /// (see [`rows`]): a fresh [`rows::RowMethod`] for one page. `None` (the default): the
    /// method needs the whole image.
    fn rows(&self) -> Option<Box<dyn rows::RowMethod + '_>> {
        None
    }
}

/// Refuses a halftone of more than `max_pixels` pixels before it is allocated: a method
/// may enlarge its input (pattern `--cell expand` makes it n× wider and higher).
pub fn check_output_size(
    method: &dyn Method,
    width: usize,
    height: usize,
    max_pixels: u64,
) -> Result<()> {
    let (w, h) = method.output_size(width, height);
    let pixels = (w as u64).saturating_mul(h as u64);
    if pixels > max_pixels {
        return Err(crate::Error::Invalid(format!(
            "{} would make a {w}x{h} halftone ({pixels} pixels) of a {width}x{height} image, \
             over the limit of {max_pixels} (raise it with `max_pixels`, or use a smaller \
             mask or `cell` fit)",
            method.name()
        )));
    }
    Ok(())
}

/// Runs `per_plane` on every plane in parallel and gathers the planes into one halftone of
/// `out_w × out_h` at `levels` levels. `per_plane(index, plane, out)` fills one packed plane.
pub fn each_plane<F>(
    input: &Planes<'_>,
    out_w: usize,
    out_h: usize,
    levels: u16,
    per_plane: F,
) -> Halftone
where
    F: Fn(usize, &PlaneRef<'_>, &mut PlaneOut<'_>) + Sync,
{
    let mut h = Halftone::new(out_w, out_h, input.planes.len(), levels);
    let (bits, stride) = (h.bits, h.stride);
    h.planes.par_iter_mut().enumerate().for_each(|(c, data)| {
        let mut out = PlaneOut {
            width: out_w,
            height: out_h,
            bits,
            stride,
            data,
        };
        per_plane(c, &input.planes[c], &mut out);
    });
    h
}

/// One packed output plane being written.
pub struct PlaneOut<'a> {
    /// Width in samples.
    pub width: usize,
    /// Height in rows.
    pub height: usize,
    /// Bits per sample (1, 2, 4, 8).
    pub bits: u8,
    /// Bytes per row.
    pub stride: usize,
    /// `stride × height` bytes.
    pub data: &'a mut [u8],
}

impl PlaneOut<'_> {
    /// Fills rows in parallel bands: `fill(y, levels_row)` writes one level per byte for row
    /// `y`; packing happens here, in one place. Output is identical for any thread count.
    pub fn par_rows<F>(&mut self, fill: F)
    where
        F: Fn(usize, &mut [u8]) + Sync,
    {
        let (w, bits) = (self.width, self.bits);
        self.data
            .par_chunks_mut(self.stride.max(1))
            .enumerate()
            .for_each_init(
                || vec![0u8; w],
                |scratch, (y, row)| {
                    if bits == 8 {
                        fill(y, &mut row[..w]);
                    } else {
                        fill(y, scratch);
                        crate::raster::pack_row(scratch, bits, row);
                    }
                },
            );
    }
}
