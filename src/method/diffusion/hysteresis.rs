//! Green-noise error diffusion: error diffusion with output-dependent feedback (Levien,
//! "Output dependent feedback in error diffusion halftoning", IS&T Imaging Science and
//! Technology 1(1), 1993).
//!
//! The quantiser sees the diffused value plus `H` times a weighted sum of the outputs already
//! placed next to the pixel (each as −½ for ink, +½ for paper): a pixel next to ink leans to
//! ink, so dots gather into small aperiodic clusters whose size grows with `H`. The error
//! carried on is still `value − output`, without the feedback term, so the tone is kept.
//! Clusters have less edge per dot than dispersed dots, so they spread less on a laser or
//! an inkjet (see [`crate::printer_model`]). `H = 0` is plain error diffusion.
//!
//! The feedback weights are Floyd–Steinberg's mirrored onto the pixels already done (7/16 the
//! pixel behind in the scan, 5/16 above, 3/16 above-ahead, 1/16 above-behind), Levien's choice
//! of a feedback filter shaped like the error filter.

use super::kernels::{self, Kernel};
use super::{DiffuseOptions, NAMES};
use crate::error::{Error, Result};
use crate::method::{each_plane, Method, PlaneOut};
use crate::raster::{pack_row, Halftone, PlaneRef, Planes};

/// Feedback weights: behind in the row, above-behind, above, above-ahead.
const FEEDBACK: [f32; 4] = [7.0 / 16.0, 1.0 / 16.0, 5.0 / 16.0, 3.0 / 16.0];

/// Error diffusion with hysteresis (bilevel).
#[derive(Clone, Debug)]
pub struct Hysteresis {
    /// The error filter.
    pub kernel: Kernel,
    /// Scan and strength (levels must be 2).
    pub options: DiffuseOptions,
    /// The feedback gain `H` (0 = plain error diffusion).
    pub gain: f32,
}

impl Hysteresis {
    /// Hysteresis `gain` on a fixed kernel (a built-in name or a kernel file).
    pub fn new(kernel: &str, options: DiffuseOptions, gain: f32) -> Result<Hysteresis> {
        if !(0.0..=8.0).contains(&gain) {
            return Err(Error::Invalid(format!(
                "--hysteresis {gain}: must be between 0 and 8"
            )));
        }
        if options.levels != 2 {
            return Err(Error::Invalid(
                "--hysteresis works with bilevel output (--levels 2)".into(),
            ));
        }
        if !(0.0..=1.0).contains(&options.strength) {
            return Err(Error::Invalid(format!(
                "--strength {}: must be between 0 and 1",
                options.strength
            )));
        }
        if ["ostromoukhov", "zhou-fang", "riemersma"].contains(&kernel) {
            return Err(Error::Invalid(format!(
                "--hysteresis works with fixed kernels ({}), not {kernel}",
                NAMES[..11].join(", ")
            )));
        }
        Ok(Hysteresis {
            kernel: Kernel::load(kernel)?,
            options,
            gain,
        })
    }

    /// One plane, one row at a time.
    fn plane(&self, plane: &PlaneRef<'_>, out: &mut PlaneOut<'_>) {
        let (w, h) = (plane.width, plane.height);
        if w == 0 {
            return;
        }
        let pad = kernels::MAX_REACH;
        let div = self.kernel.divisor as f32;
        let taps: Vec<(isize, usize, f32)> = self
            .kernel
            .taps
            .iter()
            .map(|t| {
                (
                    t.dx as isize,
                    t.dy as usize,
                    t.weight as f32 / div * self.options.strength,
                )
            })
            .collect();
        let mut err = vec![vec![0f32; w + 2 * pad]; self.kernel.rows_below() + 1];
        // Outputs (−½ ink, +½ paper) of the row above and this row, at x + 1 (0 outside).
        let mut above = vec![0f32; w + 2];
        let mut here = vec![0f32; w + 2];
        let mut vals = vec![0f32; w];
        let mut levels = vec![0u8; w];
        let g = self.gain;
        let fbw = FEEDBACK;
        for y in 0..h {
            plane.row_linear(y, &mut vals);
            let rtl = self.options.serpentine && y % 2 == 1;
            let dir: isize = if rtl { -1 } else { 1 };
            here.fill(0.0);
            for i in 0..w {
                let x = if rtl { w - 1 - i } else { i };
                let xi = x as isize + 1;
                let u = vals[x] + err[0][x + pad];
                let fb = fbw[0] * here[(xi - dir) as usize]
                    + fbw[1] * above[(xi - dir) as usize]
                    + fbw[2] * above[xi as usize]
                    + fbw[3] * above[(xi + dir) as usize];
                let paper = u + g * fb >= 0.5;
                let b = if paper { 1.0 } else { 0.0 };
                let e = u - b;
                for &(dx, dy, wt) in &taps {
                    let tx = (x as isize + pad as isize + dir * dx) as usize;
                    err[dy][tx] += e * wt;
                }
                here[xi as usize] = b - 0.5;
                levels[x] = paper as u8;
            }
            err.rotate_left(1);
            if let Some(last) = err.last_mut() {
                last.fill(0.0);
            }
            std::mem::swap(&mut above, &mut here);
            pack_row(
                &levels,
                out.bits,
                &mut out.data[y * out.stride..(y + 1) * out.stride],
            );
        }
    }
}

impl Method for Hysteresis {
    fn name(&self) -> String {
        format!("diffuse({}, hysteresis {})", self.kernel.name, self.gain)
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        Ok(each_plane(
            input,
            input.width,
            input.height,
            2,
            |_, plane, out| self.plane(plane, out),
        ))
    }
}
