//! Fixed threshold (and, with more than two levels, plain quantisation to the nearest level),
//! in the same tone domain as every other method.

use super::{each_plane, Method};
use crate::error::{Error, Result};
use crate::raster::{Halftone, Planes, SamplesRef};

/// One threshold for every pixel.
#[derive(Clone, Debug)]
pub struct Threshold {
    /// Reflectance (0..1, after the tone curve) at or above which a bilevel pixel is paper.
    pub threshold: f32,
    /// Output levels per channel (2..=256). Above 2 each pixel takes the nearest level.
    pub levels: u16,
}

impl Threshold {
    /// A threshold method; `threshold` must lie in 0..=1 and `levels` in 2..=256.
    pub fn new(threshold: f32, levels: u16) -> Result<Threshold> {
        if !(0.0..=1.0).contains(&threshold) {
            return Err(Error::Option {
                field: "threshold",
                value: threshold.to_string(),
                msg: "must be between 0 and 1".into(),
            });
        }
        check_levels(levels)?;
        Ok(Threshold { threshold, levels })
    }

    fn level_of(&self, v: f32) -> u8 {
        if self.levels == 2 {
            (v >= self.threshold) as u8
        } else {
            let top = (self.levels - 1) as f32;
            (v * top).round().clamp(0.0, top) as u8
        }
    }
}

/// Checks a `--levels` value.
pub fn check_levels(levels: u16) -> Result<()> {
    if (2..=256).contains(&levels) {
        Ok(())
    } else {
        Err(Error::Option {
            field: "levels",
            value: levels.to_string(),
            msg: "must be between 2 and 256".into(),
        })
    }
}

impl Method for Threshold {
    fn name(&self) -> String {
        if self.levels == 2 {
            format!("threshold({})", self.threshold)
        } else {
            format!("threshold(levels {})", self.levels)
        }
    }

    fn rows(&self) -> Option<Box<dyn super::rows::RowMethod + '_>> {
        // Per pixel: any band will do.
        Some(Box::new(super::rows::BandLocal::new(self, 1, 0)))
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        Ok(each_plane(
            input,
            input.width,
            input.height,
            self.levels,
            |_, plane, out| {
                // One level per code, built once: no tone conversion per pixel.
                let lut: Vec<u8> = plane.tone.iter().map(|&v| self.level_of(v)).collect();
                let w = plane.width;
                match plane.samples {
                    SamplesRef::U8(s) => out.par_rows(|y, row| {
                        for (o, &c) in row.iter_mut().zip(&s[y * w..(y + 1) * w]) {
                            *o = lut[c as usize];
                        }
                    }),
                    SamplesRef::U16(s) => out.par_rows(|y, row| {
                        for (o, &c) in row.iter_mut().zip(&s[y * w..(y + 1) * w]) {
                            *o = lut[c as usize];
                        }
                    }),
                }
            },
        ))
    }
}
