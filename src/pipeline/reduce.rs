//! A photo read smaller than it is, for work that needs its content, not its every pixel
//! (finding and measuring a calibration chart): decoded band by band and averaged down in
//! linear light on the way, so a 324-megapixel photo never lies in memory whole.

use std::path::Path;

use super::source::{self, Opened};
use crate::error::Result;
use crate::io::ReadOptions;
use crate::raster::{Image, Samples};
use crate::tone::{Encoding, ToneOptions};

/// Reads the image at `path` with at most about `max_pixels` pixels: a larger one is
/// shrunk as it is decoded (JPEG's DCT scaling where it can, then boxes of `g × g` pixels
/// averaged in linear light into 16-bit linear codes, [`Encoding::Linear`]). Returns the
/// image and how many of the file's pixels one of its pixels spans each way (1: read as
/// it is). A format that does not decode band by band (GIF, BMP, WebP, interlaced PNG) is
/// read whole, under the reader's own limits.
pub fn read_reduced(path: &Path, opts: &ReadOptions, max_pixels: usize) -> Result<(Image, usize)> {
    let input = source::open_input(path, opts)?;
    let name = input.name.clone();
    let mut src = match source::open(&name, input.file.as_deref(), input.reader, opts)? {
        Opened::Rows(src) => src,
        Opened::Whole(rest) => {
            let img = match &input.file {
                Some(file) => {
                    drop(rest);
                    crate::io::read_image(file, opts)?
                }
                None => {
                    let bytes = crate::io::read_stream(&mut { rest }, &name, opts)?;
                    crate::io::read_image_bytes(&bytes, &name, opts)?
                }
            };
            return Ok((img, 1));
        }
    };
    let factor = |w: usize, h: usize| {
        let over = (w as f64 * h as f64) / max_pixels.max(1) as f64;
        if over <= 1.0 {
            1
        } else {
            over.sqrt().ceil() as usize
        }
    };
    let (w, h) = (src.info().width, src.info().height);
    let f = factor(w, h);
    if f == 1 {
        // Small enough: read as the whole-image reader reads it (the same pixels as ever).
        return match &input.file {
            Some(file) => {
                drop(src);
                Ok((crate::io::read_image(file, opts)?, 1))
            }
            None => {
                let mut band = source::empty_band(src.info());
                src.read_rows(h, &mut band)?;
                Ok((band, 1))
            }
        };
    }
    let d = src.shrink_to(w.div_ceil(f), h.div_ceil(f)).max(1);
    let info = src.info().clone();
    let (iw, ih) = (info.width, info.height);
    let g = factor(iw, ih);
    let mut band = source::empty_band(&info);
    if g == 1 {
        src.read_rows(ih, &mut band)?;
        return Ok((band, d));
    }
    let (ow, oh) = (iw.div_ceil(g), ih.div_ceil(g));
    let channels = info.channels();
    let mut planes: Vec<Vec<u16>> = (0..channels).map(|_| Vec::with_capacity(ow * oh)).collect();
    let mut acc = vec![0f32; ow];
    let mut lut: Option<Vec<f32>> = None;
    for oy in 0..oh {
        let rows = g.min(ih - oy * g);
        src.read_rows(rows, &mut band)?;
        let lut =
            lut.get_or_insert_with(|| band.tone_table(&ToneOptions::default()).as_slice().to_vec());
        for (plane, out) in band.planes.iter().zip(planes.iter_mut()) {
            acc.fill(0.0);
            match plane {
                Samples::U8(v) => {
                    for row in v.chunks_exact(iw) {
                        for (x, &s) in row.iter().enumerate() {
                            acc[x / g] += lut[s as usize];
                        }
                    }
                }
                Samples::U16(v) => {
                    for row in v.chunks_exact(iw) {
                        for (x, &s) in row.iter().enumerate() {
                            acc[x / g] += lut[s as usize];
                        }
                    }
                }
            }
            for (ox, sum) in acc.iter().enumerate() {
                let n = (rows * g.min(iw - ox * g)) as f32;
                out.push(((sum / n).clamp(0.0, 1.0) * 65535.0).round() as u16);
            }
        }
    }
    Ok((
        Image {
            width: ow,
            height: oh,
            color: info.color,
            planes: planes.into_iter().map(Samples::U16).collect(),
            encoding: Encoding::Linear,
            dpi: info.dpi,
        },
        d * g,
    ))
}
