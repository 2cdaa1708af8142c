//! Measuring a halftoned clip against its original: per-frame HVS-PSNR and the flicker
//! rate, the share of dots that change from one frame to the next where the input did not
//! change by more than its noise.

use super::Frame;
use super::FrameSource;
use crate::error::{Error, Result};
use crate::quality::{compare, image_reflectance, Reflectance, Viewing};
use crate::raster::{Image, Samples};
use crate::tone::ToneOptions;

/// The figures of [`compare_clips`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClipComparison {
    /// Frames compared.
    pub frames: usize,
    /// HVS-PSNR of every `every`-th frame, dB.
    pub hvs_psnr_db: Vec<f64>,
    /// Dots that changed where the input stayed, over the pixels where it stayed.
    pub flicker: f64,
    /// Pixels (summed over frame pairs) where the input stayed within its noise.
    pub still_pixels: u64,
}

/// The grey codes of a frame (luminance of colour frames, through linear light).
fn grey(f: &Frame) -> Vec<u8> {
    let img = f.image.to_luminance(&ToneOptions::default());
    match &img.planes[0] {
        Samples::U8(v) => v.clone(),
        Samples::U16(v) => v
            .iter()
            .map(|&c| (crate::tone::linear_to_srgb(c as f64 / 65535.0) * 255.0).round() as u8)
            .collect(),
    }
}

/// Compares a halftoned clip with its original, frame by frame in time: each frame of the
/// original is set against the halftone's frame on show at the middle of its time (a GIF
/// stores a repeated frame once, with the delays summed). The input "stayed" at a pixel
/// when its grey code moved by at most `noise`; a dot "changed" when the halftone's grey
/// code moved by more than half the range. HVS-PSNR (grey, [`crate::quality`]) on every
/// `every`-th frame (0: none).
pub fn compare_clips(
    original: &mut dyn FrameSource,
    halftone: &mut dyn FrameSource,
    noise: u8,
    every: usize,
    view: &Viewing,
) -> Result<ClipComparison> {
    let mut out = ClipComparison::default();
    let mut prev: Option<(Vec<u8>, Vec<u8>)> = None;
    let mut changed = 0u64;
    // The original's clock, and the halftone frame on show with the time it ends.
    let mut clock = 0.0f64;
    let mut shown: Option<(Vec<u8>, f64)> = None;
    let mut h_clock = 0.0f64;
    while let Some(a) = original.next_frame()? {
        let mid = clock + a.delay.seconds() / 2.0;
        clock += a.delay.seconds();
        // Advance the halftone to the frame on show at `mid`.
        loop {
            match &shown {
                Some((_, end)) if *end > mid => break,
                _ => {}
            }
            let Some(b) = halftone.next_frame()? else {
                break;
            };
            if (a.image.width, a.image.height) != (b.image.width, b.image.height) {
                return Err(Error::Invalid(format!(
                    "{} is {}x{} and {} {}x{}: frames of one size are compared",
                    original.name().display(),
                    a.image.width,
                    a.image.height,
                    halftone.name().display(),
                    b.image.width,
                    b.image.height
                )));
            }
            h_clock += b.delay.seconds();
            // A frame of no time (a zero delay) is on show until the next one.
            let end = if b.delay.num == 0 {
                mid + 1e-9
            } else {
                h_clock
            };
            shown = Some((grey(&b), end.max(h_clock)));
        }
        let Some((gb, _)) = &shown else {
            break;
        };
        let ga = grey(&a);
        if let Some((pa, pb)) = &prev {
            for i in 0..ga.len() {
                if ga[i].abs_diff(pa[i]) <= noise {
                    out.still_pixels += 1;
                    if gb[i].abs_diff(pb[i]) > 127 {
                        changed += 1;
                    }
                }
            }
        }
        if every > 0 && out.frames % every == 0 {
            let (w, h) = (a.image.width, a.image.height);
            let ra: Reflectance = image_reflectance(&Image::gray8(w, h, ga.clone()));
            let rb: Reflectance = image_reflectance(&Image::gray8(w, h, gb.clone()));
            out.hvs_psnr_db.push(compare(&ra, &rb, view)?.hvs_psnr_db);
        }
        out.frames += 1;
        prev = Some((ga, gb.clone()));
    }
    out.flicker = if out.still_pixels == 0 {
        0.0
    } else {
        changed as f64 / out.still_pixels as f64
    };
    Ok(out)
}
