//! `--content`: keep line art crisp. Receipts and labels mix text, rules, barcodes and QR
//! codes (already black and white, give or take their anti-aliased edges) with
//! photographs; halftoning the whole page dithers the text's edges and blurs the bars.
//!
//! [`ContentAware`] wraps any method. `LineArt` thresholds everything at 50% reflectance.
//! `Auto` finds the continuous-tone regions: a pixel is a photo core when it is a middle
//! tone and at least [`MID_SHARE`] of the pixels in the window around it are too (text has
//! middle tones only along its edges); the cores are then grown by the window's radius, so
//! a photograph's rim belongs to it. Everything else is line art. The method then runs on
//! the whole page with the line-art pixels snapped to black or white first, so error
//! diffusion carries no error out of text into a photo's edge or back (no seam), and the
//! line-art pixels of its output are replaced by the threshold's.

use crate::error::{Error, Result};
use crate::raster::{Halftone, PlaneRef, Planes, Samples, SamplesRef};

use super::Method;

/// Below this linear reflectance a pixel is black ink (sRGB code ≈ 40).
pub const BLACK_BELOW: f32 = 0.02;
/// Above this linear reflectance a pixel is paper (sRGB code ≈ 235).
pub const WHITE_ABOVE: f32 = 0.83;
/// Window radius in pixels for the middle-tone share and for growing the photo regions.
pub const RADIUS: usize = 6;
/// Share of middle tones in the window that makes a middle-tone pixel part of a photo.
pub const MID_SHARE: f32 = 0.45;

/// What the page holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Content {
    /// Everything is line art: threshold at 50%.
    LineArt,
    /// Find the continuous-tone regions; threshold the rest.
    Auto,
}

/// A method that thresholds line art and halftones the rest with `inner`.
pub struct ContentAware {
    inner: Box<dyn Method>,
    content: Content,
}

impl ContentAware {
    /// Wraps `inner`.
    pub fn new(inner: Box<dyn Method>, content: Content) -> ContentAware {
        ContentAware { inner, content }
    }
}

/// Summed-area table of `mark` (w × h), (w + 1) × (h + 1) entries.
fn integral(mark: &[bool], w: usize, h: usize) -> Vec<u32> {
    let mut s = vec![0u32; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0u32;
        for x in 0..w {
            row += mark[y * w + x] as u32;
            s[(y + 1) * (w + 1) + x + 1] = s[y * (w + 1) + x + 1] + row;
        }
    }
    s
}

/// Count of marks in the window of radius `r` around (x, y), and the window's area.
fn window(s: &[u32], w: usize, h: usize, x: usize, y: usize, r: usize) -> (u32, u32) {
    let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
    let (x1, y1) = ((x + r + 1).min(w), (y + r + 1).min(h));
    let at = |x: usize, y: usize| s[y * (w + 1) + x];
    (
        at(x1, y1) + at(x0, y0) - at(x0, y1) - at(x1, y0),
        ((x1 - x0) * (y1 - y0)) as u32,
    )
}

/// The line-art mask of a plane: true where the pixel is to be thresholded.
pub fn line_art_mask(plane: &PlaneRef<'_>) -> Vec<bool> {
    let (w, h) = (plane.width, plane.height);
    let mut v = vec![0f32; w];
    let mut mid = vec![false; w * h];
    for y in 0..h {
        plane.row_linear(y, &mut v);
        for (m, &x) in mid[y * w..(y + 1) * w].iter_mut().zip(&v) {
            *m = x > BLACK_BELOW && x < WHITE_ABOVE;
        }
    }
    let s = integral(&mid, w, h);
    let mut core = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if mid[y * w + x] {
                let (n, area) = window(&s, w, h, x, y, RADIUS);
                core[y * w + x] = n as f32 >= MID_SHARE * area as f32;
            }
        }
    }
    let s = integral(&core, w, h);
    let mut line = vec![true; w * h];
    for y in 0..h {
        for x in 0..w {
            line[y * w + x] = window(&s, w, h, x, y, RADIUS).0 == 0;
        }
    }
    line
}

/// The codes of the darkest and the lightest entries of a tone table.
fn extreme_codes(tone: &[f32]) -> (usize, usize) {
    let mut lo = 0;
    let mut hi = 0;
    for (i, &t) in tone.iter().enumerate() {
        if t < tone[lo] {
            lo = i;
        }
        if t > tone[hi] {
            hi = i;
        }
    }
    (lo, hi)
}

impl Method for ContentAware {
    fn name(&self) -> String {
        match self.content {
            Content::LineArt => "line-art threshold".into(),
            Content::Auto => format!("{} with line art thresholded", self.inner.name()),
        }
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        let (w, h) = (input.width, input.height);
        if self.inner.output_size(w, h) != (w, h) {
            return Err(Error::Invalid(
                "`content` line-art or auto needs a method that keeps the image's size (not `cell` expand)"
                    .into(),
            ));
        }
        let masks: Vec<Vec<bool>> = input
            .planes
            .iter()
            .map(|p| match self.content {
                Content::LineArt => vec![true; w * h],
                Content::Auto => line_art_mask(p),
            })
            .collect();
        // The planes with line art snapped to black or white.
        let snapped: Vec<Samples> = input
            .planes
            .iter()
            .zip(&masks)
            .map(|(p, mask)| {
                let (lo, hi) = extreme_codes(p.tone);
                let pick = |c: usize, on: bool| -> usize {
                    if !on {
                        c
                    } else if p.tone[c] < 0.5 {
                        lo
                    } else {
                        hi
                    }
                };
                match p.samples {
                    SamplesRef::U8(s) => Samples::U8(
                        s.iter()
                            .zip(mask)
                            .map(|(&c, &on)| pick(c as usize, on) as u8)
                            .collect(),
                    ),
                    SamplesRef::U16(s) => Samples::U16(
                        s.iter()
                            .zip(mask)
                            .map(|(&c, &on)| pick(c as usize, on) as u16)
                            .collect(),
                    ),
                }
            })
            .collect();
        let planes = Planes {
            width: w,
            height: h,
            planes: input
                .planes
                .iter()
                .zip(&snapped)
                .map(|(p, s)| PlaneRef {
                    samples: s.as_ref(),
                    ..*p
                })
                .collect(),
        };
        let mut out = self.inner.halftone(&planes)?;
        let top = (out.levels - 1) as u8;
        for (c, (p, mask)) in planes.planes.iter().zip(&masks).enumerate() {
            for y in 0..h {
                for x in 0..w {
                    if mask[y * w + x] {
                        let level = if p.value(x, y) < 0.5 { 0 } else { top };
                        out.set(c, x, y, level);
                    }
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::diffusion::{Diffuse, DiffuseOptions};
    use crate::raster::Image;
    use crate::tone::ToneOptions;

    /// A page: black text-like bars on white at the left, a grey ramp at the right.
    fn page() -> Image {
        let (w, h) = (120, 60);
        let mut d = vec![255u8; w * h];
        for y in 0..h {
            for x in 0..w {
                if x < 50 {
                    // Bars 2 px wide with an anti-aliased grey edge.
                    d[y * w + x] = match x % 6 {
                        0 | 1 => 0,
                        2 => 128,
                        _ => 255,
                    };
                } else if x >= 60 {
                    d[y * w + x] = (40 + (x - 60) * 3) as u8;
                }
            }
        }
        Image::gray8(w, h, d)
    }

    #[test]
    fn auto_thresholds_bars_and_halftones_the_ramp() {
        let img = page();
        let tone = img.tone_table(&ToneOptions::default());
        let planes = img.planes(&tone);
        let mask = line_art_mask(&planes.planes[0]);
        let w = img.width;
        // The bars (with their grey edges) are line art, the ramp is not.
        assert!((0..60).all(|y| (0..40).all(|x| mask[y * w + x])));
        assert!((0..60).all(|y| (70..110).all(|x| !mask[y * w + x])));
        let fs = Diffuse::new("floyd-steinberg", DiffuseOptions::default()).unwrap();
        let m = ContentAware::new(Box::new(fs), Content::Auto);
        let out = m.halftone(&planes).unwrap();
        // Bars: exactly the threshold of the input (the grey edge, 128 = 21% light, is ink).
        for y in 0..60 {
            for x in 0..40 {
                let want = if x % 6 < 3 { 0 } else { 1 };
                assert_eq!(out.get(0, x, y), want, "({x},{y})");
            }
        }
        // The ramp is halftoned: its mean level follows the light.
        let mean: f64 = (0..60)
            .flat_map(|y| (80..90).map(move |x| (x, y)))
            .map(|(x, y)| out.get(0, x, y) as f64)
            .sum::<f64>()
            / 600.0;
        let light = tone.as_slice()[(40 + 25 * 3) as usize] as f64;
        assert!((mean - light).abs() < 0.08, "mean {mean} light {light}");
        assert!(mean > 0.05 && mean < 0.95);
    }
}
