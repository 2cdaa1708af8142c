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
//! The feedback weights lean on the row above (0.5 above, 0.1 above-behind, 0.1 above-ahead,
//! 0.3 the pixel behind in the scan). Floyd–Steinberg's weights mirrored (7/16 behind), the
//! first choice, let clusters grow along the row faster than across it: at `H = 1.5` a flat
//! grey turned into horizontal stripes one pixel high. To break the stripes that error
//! diffusion with strong feedback still draws, each pixel's error weights are perturbed
//! (each scaled by `1 + u`, `u` uniform in [−1, 1), then rescaled to their sum, so the tone
//! is kept), as Ulichney perturbed Floyd–Steinberg's weights against worms ("Digital
//! Halftoning", 1987, ch. 8) and Lau, Arce and Gallagher did for green noise ("Green-noise
//! digital halftoning", Proc. IEEE 86(12), 1998). `u` is a hash of the pixel's position and
//! the tap, not a random generator, so the output is the same on every run. With `H = 0`
//! nothing is perturbed: plain error diffusion.

use super::kernels::{self, Kernel};
use super::DiffuseOptions;
use crate::error::{Error, Result};
use crate::method::{each_plane, Method, PlaneOut};
use crate::raster::{pack_row, Halftone, PlaneRef, Planes};

/// Feedback weights: behind in the row, above-behind, above, above-ahead (module docs).
const FEEDBACK: [f32; 4] = [0.3, 0.1, 0.5, 0.1];

/// Amplitude of the perturbation of the error weights (module docs).
const PERTURB: f32 = 1.0;

/// A hash of a pixel position and a tap number, uniform in [0, 1): the perturbation's
/// deterministic stand-in for a random number.
fn jitter(x: usize, y: usize, k: usize) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (k as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

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
            return Err(Error::Option {
                field: "hysteresis",
                value: gain.to_string(),
                msg: "must be between 0 and 8".into(),
            });
        }
        if options.levels != 2 {
            return Err(Error::Invalid(
                "`hysteresis` works with bilevel output (`levels` 2)".into(),
            ));
        }
        if !(0.0..=1.0).contains(&options.strength) {
            return Err(Error::Option {
                field: "strength",
                value: options.strength.to_string(),
                msg: "must be between 0 and 1".into(),
            });
        }
        if ["ostromoukhov", "zhou-fang", "riemersma"].contains(&kernel) {
            return Err(Error::Invalid(format!(
                "`hysteresis` works with fixed kernels ({}), not {kernel}",
                super::kernels::BUILTIN
                    .iter()
                    .map(|k| k.0)
                    .collect::<Vec<_>>()
                    .join(", ")
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
        let total: f32 = taps.iter().map(|t| t.2).sum();
        let mut perturbed = vec![0f32; taps.len()];
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
                if g > 0.0 {
                    let mut sum = 0.0;
                    for (k, (p, &(_, _, wt))) in perturbed.iter_mut().zip(&taps).enumerate() {
                        *p = wt * (1.0 + PERTURB * (2.0 * jitter(x, y, k) - 1.0));
                        sum += *p;
                    }
                    let scale = if sum > 1e-6 { total / sum } else { 0.0 };
                    for (&p, &(dx, dy, wt)) in perturbed.iter().zip(&taps) {
                        let tx = (x as isize + pad as isize + dir * dx) as usize;
                        err[dy][tx] += e * if scale > 0.0 { p * scale } else { wt };
                    }
                } else {
                    for &(dx, dy, wt) in &taps {
                        let tx = (x as isize + pad as isize + dir * dx) as usize;
                        err[dy][tx] += e * wt;
                    }
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
