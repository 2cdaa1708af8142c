//! Measuring a halftone against its original as an eye sees the print.
//!
//! Both images are taken as reflectance in linear light (the original through its sRGB table,
//! the halftone's level k as k/(L−1)). The error is filtered by Näsänen's contrast
//! sensitivity function, the model used for halftone quality since Näsänen (1984), "Visibility
//! of halftone dot textures", IEEE Trans. SMC 14(6):
//!
//! ```text
//! H(f) = a · L^b · exp(−f / (c·ln L + d)),  L = 11 cd/m², a = 131.6, b = 0.3188, c = 0.525, d = 3.91
//! ```
//!
//! with `f` the radial frequency in cycles per degree. Normalised to 1 at f = 0 the factor
//! `a·L^b` cancels and H(f) = exp(−f / 5.169). The filter is applied exactly, in the frequency
//! domain, with a radix-2 FFT over the image mirrored out to a power-of-two size (mirroring
//! keeps the image's edges from becoming false high-frequency error).
//!
//! From pixels to degrees: one degree of visual angle centred on the line of sight spans
//! `2·D·tan(0.5°)` inches at a viewing distance of `D` inches, that is
//! `ppd = 2·D·tan(0.5°)·dpi` pixels (within 0.01% of `D·tan(1°)·dpi`). A frequency of
//! `f` cycles per pixel is then `f · ppd` cycles per degree. At 300 dpi and 12 inches,
//! ppd ≈ 62.8: a checkerboard (0.5 cycles per pixel diagonally 0.707) sits near 44 cpd where
//! H ≈ 2·10⁻⁴, invisible, as a print at that distance is.

use crate::fmath as fm;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::raster::{ColorKind, Halftone, Image};
use crate::tone::{srgb_to_linear, Encoding, ToneOptions, ToneTable};

/// Näsänen's adaptation luminance L, cd/m² (a page under office light).
pub const NASANEN_L: f64 = 11.0;
/// Näsänen's constant a.
pub const NASANEN_A: f64 = 131.6;
/// Näsänen's exponent b.
pub const NASANEN_B: f64 = 0.3188;
/// Näsänen's constant c.
pub const NASANEN_C: f64 = 0.525;
/// Näsänen's constant d.
pub const NASANEN_D: f64 = 3.91;

/// Rec. 709 / sRGB luminance weights of linear red, green and blue.
pub const LUMA_709: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Näsänen's contrast sensitivity at `f` cycles per degree, unnormalised: a·L^b·exp(−f/(c·ln L + d)).
pub fn nasanen_absolute(f_cpd: f64) -> f64 {
    NASANEN_A * fm::powf(NASANEN_L, NASANEN_B) * nasanen(f_cpd)
}

/// Näsänen's contrast sensitivity at `f` cycles per degree, normalised to 1 at f = 0.
pub fn nasanen(f_cpd: f64) -> f64 {
    fm::exp(-f_cpd / (NASANEN_C * fm::ln(NASANEN_L) + NASANEN_D))
}

/// How a print is viewed: its resolution and the distance to the eye.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Viewing {
    /// Printed pixels per inch (of the halftone).
    pub dpi: f64,
    /// Viewing distance, inches.
    pub distance_in: f64,
}

impl Default for Viewing {
    /// 300 dpi read at 12 inches: a laser print in the hand.
    fn default() -> Self {
        Viewing {
            dpi: 300.0,
            distance_in: 12.0,
        }
    }
}

impl Viewing {
    /// Viewing conditions; both numbers must be positive and finite.
    pub fn new(dpi: f64, distance_in: f64) -> Result<Viewing> {
        if !(dpi > 0.0 && dpi.is_finite()) {
            return Err(Error::Option {
                field: "dpi",
                value: dpi.to_string(),
                msg: "must be a positive number".into(),
            });
        }
        if !(distance_in > 0.0 && distance_in.is_finite()) {
            return Err(Error::Option {
                field: "distance",
                value: distance_in.to_string(),
                msg: "must be a positive number of inches".into(),
            });
        }
        Ok(Viewing { dpi, distance_in })
    }

    /// Printed pixels spanned by one degree of visual angle: 2·D·tan(0.5°)·dpi.
    pub fn pixels_per_degree(&self) -> f64 {
        2.0 * self.distance_in * fm::tan(0.5f64.to_radians()) * self.dpi
    }

    /// Cycles per degree of a frequency given in cycles per pixel.
    pub fn cycles_per_degree(&self, f_cycles_per_pixel: f64) -> f64 {
        f_cycles_per_pixel * self.pixels_per_degree()
    }

    /// The normalised Näsänen filter's gain at `f` cycles per pixel.
    pub fn hvs_gain(&self, f_cycles_per_pixel: f64) -> f64 {
        nasanen(self.cycles_per_degree(f_cycles_per_pixel))
    }

    /// Mirror margin (pixels) wide enough for the filter's spatial spread. The kernel of
    /// exp(−f/f₀) is a Poisson kernel of scale 1/(2π·f₀) pixels; eight scales keep the
    /// seam of the padding far from the image.
    pub fn margin(&self) -> usize {
        let f0 = (NASANEN_C * fm::ln(NASANEN_L) + NASANEN_D) / self.pixels_per_degree();
        let scale = 1.0 / (2.0 * std::f64::consts::PI * f0);
        ((8.0 * scale).ceil() as usize).clamp(8, 4096)
    }
}

/// An image as linear reflectance (0 = solid ink, 1 = paper), one `f32` per sample, planar.
#[derive(Clone, Debug, PartialEq)]
pub struct Reflectance {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// One plane (grey) or three (linear red, green, blue), row-major.
    pub planes: Vec<Vec<f32>>,
}

impl Reflectance {
    /// A grey image of one reflectance everywhere.
    pub fn constant(width: usize, height: usize, value: f32) -> Reflectance {
        Reflectance {
            width,
            height,
            planes: vec![vec![value; width * height]],
        }
    }

    /// Mean reflectance over every sample of every plane.
    pub fn mean(&self) -> f64 {
        let n: usize = self.planes.iter().map(Vec::len).sum();
        if n == 0 {
            return 0.0;
        }
        let s: f64 = self
            .planes
            .iter()
            .map(|p| p.iter().map(|&v| v as f64).sum::<f64>())
            .sum();
        s / n as f64
    }

    /// Luminance in linear light (Rec. 709 weights) of an RGB image; a grey one unchanged.
    pub fn luminance(&self) -> Reflectance {
        if self.planes.len() != 3 {
            return self.clone();
        }
        let (r, g, b) = (&self.planes[0], &self.planes[1], &self.planes[2]);
        let y = r
            .iter()
            .zip(g)
            .zip(b)
            .map(|((&r, &g), &b)| {
                (LUMA_709[0] * r as f64 + LUMA_709[1] * g as f64 + LUMA_709[2] * b as f64) as f32
            })
            .collect();
        Reflectance {
            width: self.width,
            height: self.height,
            planes: vec![y],
        }
    }

    /// Enlarged `kx × ky` by box (each pixel repeated): the original a pattern `expand`
    /// halftone stands for.
    pub fn enlarge(&self, kx: usize, ky: usize) -> Reflectance {
        let (w, h) = (self.width * kx, self.height * ky);
        let planes = self
            .planes
            .iter()
            .map(|p| {
                let mut out = Vec::with_capacity(w * h);
                for y in 0..h {
                    let src = &p[(y / ky) * self.width..(y / ky + 1) * self.width];
                    for &v in src {
                        out.extend(std::iter::repeat_n(v, kx));
                    }
                }
                out
            })
            .collect();
        Reflectance {
            width: w,
            height: h,
            planes,
        }
    }
}

/// The original's reflectance: codes decoded through the sRGB table (or taken as linear
/// when the image says so), without the user's tone curves.
pub fn image_reflectance(img: &Image) -> Reflectance {
    let table = ToneTable::new(img.bits(), img.encoding, &ToneOptions::default());
    codes_reflectance(img, &table)
}

/// An image file that holds a halftone, read back: codes decoded through the sRGB table
/// (`Encoding::Srgb`: a level written as the sRGB code of its reflectance decodes to it) or
/// taken as linear (`Encoding::Linear`: codes evenly spaced in light, e.g. a PGM whose
/// maxval is levels − 1).
pub fn decoded_halftone_reflectance(img: &Image, codes: Encoding) -> Reflectance {
    let opts = ToneOptions {
        linearize: codes == Encoding::Srgb,
        ..ToneOptions::default()
    };
    let table = ToneTable::new(img.bits(), Encoding::Srgb, &opts);
    codes_reflectance(img, &table)
}

fn codes_reflectance(img: &Image, table: &ToneTable) -> Reflectance {
    let t = table.as_slice();
    let planes = img
        .planes
        .iter()
        .map(|s| match s {
            crate::raster::Samples::U8(v) => v.iter().map(|&c| t[c as usize]).collect(),
            crate::raster::Samples::U16(v) => v.iter().map(|&c| t[c as usize]).collect(),
        })
        .collect();
    Reflectance {
        width: img.width,
        height: img.height,
        planes,
    }
}

/// A halftone's reflectance: level k of L is k/(L−1) (levels are evenly spaced in light);
/// a palette halftone gives the linear red, green and blue of each index's colour.
pub fn halftone_reflectance(h: &Halftone) -> Reflectance {
    let n = h.width * h.height;
    let planes = match &h.palette {
        Some(pal) => {
            let idx = h.levels_of(0);
            (0..3)
                .map(|c| {
                    let lin: Vec<f32> = pal
                        .iter()
                        .map(|rgb| srgb_to_linear(rgb[c] as f64 / 255.0) as f32)
                        .collect();
                    idx.iter()
                        .map(|&i| lin.get(i as usize).copied().unwrap_or(0.0))
                        .collect()
                })
                .collect()
        }
        None => {
            let top = (h.levels.max(2) - 1) as f32;
            let lut: Vec<f32> = (0..=255u16).map(|k| (k as f32 / top).min(1.0)).collect();
            (0..h.channels())
                .map(|c| {
                    let mut out = vec![0f32; n];
                    let mut row = vec![0u8; h.width];
                    for (y, o) in out.chunks_exact_mut(h.width.max(1)).enumerate() {
                        h.unpack_row(c, y, &mut row);
                        for (o, &l) in o.iter_mut().zip(&row) {
                            *o = lut[l as usize];
                        }
                    }
                    out
                })
                .collect()
        }
    };
    Reflectance {
        width: h.width,
        height: h.height,
        planes,
    }
}

/// The figures `compare` reports.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    /// PSNR with peak 1 over the mean square of the HVS-filtered error, dB (infinite when the
    /// filtered error is zero; JSON writes that as null).
    pub hvs_psnr_db: f64,
    /// Mean square of the HVS-filtered error (colour: the mean of the channels').
    pub hvs_mse: f64,
    /// Mean reflectance of the halftone minus that of the original.
    pub tone_bias: f64,
    /// RMS difference in CIE L* between the two images' filtered luminance.
    pub lstar_rms: f64,
    /// PSNR of the unfiltered error, dB: what a pixel-by-pixel metric would say.
    pub plain_psnr_db: f64,
    /// The box enlargement applied to the original to match the halftone's size (1 × 1
    /// unless the halftone was expanded).
    pub scale: [usize; 2],
}

/// PSNR with peak 1 for a mean square error.
pub fn psnr_db(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        -10.0 * fm::log10(mse)
    }
}

/// CIE L* of a luminance relative to paper white (CIE 1976; L* = 116·f(Y) − 16).
pub fn lstar(y: f64) -> f64 {
    const EPS: f64 = 216.0 / 24389.0; // (6/29)³
    const KAPPA: f64 = 24389.0 / 27.0; // (29/3)³
    let y = y.clamp(0.0, 1.0);
    if y > EPS {
        116.0 * fm::cbrt(y) - 16.0
    } else {
        KAPPA * y
    }
}

/// About how many bytes [`compare`] needs for a halftone of `width × height` with
/// `channels` planes: the padded FFT buffer and its transpose (16 bytes a complex sample,
/// each side padded by the margin and rounded up to a power of two), and per pixel the two
/// filtered planes and two luminance planes (`f64`) and up to three reflectance copies a
/// channel (`f32`). Saturates instead of overflowing, so a huge size gives a huge figure.
pub fn compare_bytes(width: usize, height: usize, channels: usize, view: &Viewing) -> u64 {
    let margin = view.margin() as u64;
    let pad = |n: usize| {
        (n as u64)
            .saturating_add(2 * margin)
            .checked_next_power_of_two()
            .unwrap_or(u64::MAX)
    };
    let fft = pad(width).saturating_mul(pad(height)).saturating_mul(32);
    let pixels = (width as u64).saturating_mul(height as u64);
    let per_pixel = 32 + 12 * channels as u64;
    fft.saturating_add(pixels.saturating_mul(per_pixel))
}

/// Compares a halftone with its original. Sizes must match, or the halftone must be a whole
/// multiple of the original in each direction (pattern `expand`), in which case the original
/// is enlarged by box. When one is colour and the other grey, both are compared as luminance.
pub fn compare(original: &Reflectance, halftone: &Reflectance, view: &Viewing) -> Result<Quality> {
    let (ow, oh) = (original.width, original.height);
    let (hw, hh) = (halftone.width, halftone.height);
    if ow == 0 || oh == 0 || hw == 0 || hh == 0 {
        return Err(Error::Invalid(format!(
            "cannot compare empty images ({ow}x{oh} and {hw}x{hh})"
        )));
    }
    if hw % ow != 0 || hh % oh != 0 {
        return Err(Error::Invalid(format!(
            "the halftone is {hw}x{hh} and the original {ow}x{oh}: \
             neither the same size nor a whole multiple"
        )));
    }
    let (kx, ky) = (hw / ow, hh / oh);
    let lum;
    let (orig, ht) = if original.planes.len() == halftone.planes.len() {
        (original, halftone)
    } else {
        lum = (original.luminance(), halftone.luminance());
        (&lum.0, &lum.1)
    };
    let enlarged;
    let orig = if (kx, ky) == (1, 1) {
        orig
    } else {
        enlarged = orig.enlarge(kx, ky);
        &enlarged
    };

    let channels = orig.planes.len();
    let n = (hw * hh) as f64;
    let margin = view.margin();
    let mut hvs_mse = 0.0;
    let mut plain_mse = 0.0;
    // Filtered luminance of each image, for L*.
    let mut y_orig = vec![0f64; hw * hh];
    let mut y_ht = vec![0f64; hw * hh];
    for (c, (a, b)) in orig.planes.iter().zip(&ht.planes).enumerate() {
        plain_mse += a
            .iter()
            .zip(b)
            .map(|(&a, &b)| {
                let e = b as f64 - a as f64;
                e * e
            })
            .sum::<f64>()
            / n;
        let (fa, fb) = if a == b {
            // Identical planes: the error is exactly zero, not the FFT's rounding.
            let (fa, _) = filter_pair(a, a, hw, hh, margin, &|f| view.hvs_gain(f));
            (fa.clone(), fa)
        } else {
            filter_pair(a, b, hw, hh, margin, &|f| view.hvs_gain(f))
        };
        hvs_mse += fa
            .iter()
            .zip(&fb)
            .map(|(&a, &b)| (b - a) * (b - a))
            .sum::<f64>()
            / n;
        let w = if channels == 3 { LUMA_709[c] } else { 1.0 };
        for ((yo, yh), (&a, &b)) in y_orig
            .iter_mut()
            .zip(y_ht.iter_mut())
            .zip(fa.iter().zip(&fb))
        {
            *yo += w * a;
            *yh += w * b;
        }
    }
    hvs_mse /= channels as f64;
    plain_mse /= channels as f64;
    let lstar_ms = y_orig
        .iter()
        .zip(&y_ht)
        .map(|(&a, &b)| {
            let d = lstar(b) - lstar(a);
            d * d
        })
        .sum::<f64>()
        / n;
    Ok(Quality {
        hvs_psnr_db: psnr_db(hvs_mse),
        hvs_mse,
        tone_bias: ht.mean() - orig.mean(),
        lstar_rms: lstar_ms.sqrt(),
        plain_psnr_db: psnr_db(plain_mse),
        scale: [kx, ky],
    })
}

/// Compares a method's output with the image it was made from (colour handled as in
/// [`compare`]).
pub fn compare_halftone(original: &Image, halftone: &Halftone, view: &Viewing) -> Result<Quality> {
    let mut orig = image_reflectance(original);
    if original.color == ColorKind::Rgb && halftone.channels() == 1 && halftone.palette.is_none() {
        orig = orig.luminance();
    }
    compare(&orig, &halftone_reflectance(halftone), view)
}

type Cx = [f64; 2];

/// A radix-2 complex FFT of one power-of-two length, twiddles and bit reversal built once.
struct Fft {
    n: usize,
    twiddles: Vec<Cx>,
    reversed: Vec<usize>,
}

impl Fft {
    fn new(n: usize) -> Fft {
        assert!(n.is_power_of_two());
        let bits = n.trailing_zeros();
        let twiddles = (0..n / 2)
            .map(|k| {
                let t = -2.0 * std::f64::consts::PI * k as f64 / n as f64;
                [fm::cos(t), fm::sin(t)]
            })
            .collect();
        let reversed = (0..n)
            .map(|i| {
                if bits == 0 {
                    0
                } else {
                    i.reverse_bits() >> (usize::BITS - bits)
                }
            })
            .collect();
        Fft {
            n,
            twiddles,
            reversed,
        }
    }

    /// In-place transform; `inverse` conjugates the twiddles (no 1/n scaling).
    fn transform(&self, a: &mut [Cx], inverse: bool) {
        let n = self.n;
        for i in 0..n {
            let j = self.reversed[i];
            if j > i {
                a.swap(i, j);
            }
        }
        let sign = if inverse { -1.0 } else { 1.0 };
        let mut len = 2;
        while len <= n {
            let half = len / 2;
            let step = n / len;
            for block in a.chunks_exact_mut(len) {
                let (lo, hi) = block.split_at_mut(half);
                for k in 0..half {
                    let [wr, wi] = self.twiddles[k * step];
                    let wi = wi * sign;
                    let [hr, him] = hi[k];
                    let (vr, vi) = (hr * wr - him * wi, hr * wi + him * wr);
                    let [ur, ui] = lo[k];
                    lo[k] = [ur + vr, ui + vi];
                    hi[k] = [ur - vr, ui - vi];
                }
            }
            len *= 2;
        }
    }
}

/// Index into `0..n` of position `i` of a padded axis of length `p`: the image, then its
/// mirror image continuing the right edge, then (past the middle of the padding) the mirror
/// image continuing the left edge, so that the seam lies as far from the image as it can.
fn mirror_index(i: usize, n: usize, p: usize) -> usize {
    if i < n {
        return i;
    }
    let k = if i < n + (p - n) / 2 {
        i as isize
    } else {
        i as isize - p as isize
    };
    let m = k.rem_euclid(2 * n as isize) as usize;
    if m < n {
        m
    } else {
        2 * n - 1 - m
    }
}

fn transpose(src: &[Cx], rows: usize, cols: usize) -> Vec<Cx> {
    let mut out = vec![[0.0; 2]; src.len()];
    out.par_chunks_mut(rows).enumerate().for_each(|(c, row)| {
        for (r, o) in row.iter_mut().enumerate() {
            *o = src[r * cols + c];
        }
    });
    out
}

/// Filters two planes of `width × height` with the same zero-phase filter, given by its gain
/// at a radial frequency in cycles per pixel, applied exactly in the frequency domain over
/// the planes mirrored out by at least `margin` pixels to power-of-two sizes. Returns the
/// filtered planes. The two real planes travel as the real and imaginary parts of one
/// complex plane: a real, even gain keeps them apart.
pub fn filter_pair(
    a: &[f32],
    b: &[f32],
    width: usize,
    height: usize,
    margin: usize,
    gain: &(dyn Fn(f64) -> f64 + Sync),
) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(a.len(), width * height);
    assert_eq!(b.len(), width * height);
    let q = (width + 2 * margin).next_power_of_two();
    let p = (height + 2 * margin).next_power_of_two();
    let xs: Vec<usize> = (0..q).map(|i| mirror_index(i, width, q)).collect();
    let mut data = vec![[0.0f64; 2]; p * q];
    data.par_chunks_mut(q).enumerate().for_each(|(py, row)| {
        let sy = mirror_index(py, height, p) * width;
        for (o, &sx) in row.iter_mut().zip(&xs) {
            *o = [a[sy + sx] as f64, b[sy + sx] as f64];
        }
    });
    let (fq, fp) = (Fft::new(q), Fft::new(p));
    data.par_chunks_mut(q).for_each(|r| fq.transform(r, false));
    let mut t = transpose(&data, p, q); // q rows of p
    let freq2 = |k: usize, n: usize| {
        let f = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        } / n as f64;
        f * f
    };
    let fy2: Vec<f64> = (0..p).map(|v| freq2(v, p)).collect();
    let scale = 1.0 / (p * q) as f64;
    t.par_chunks_mut(p).enumerate().for_each(|(u, col)| {
        fp.transform(col, false);
        let fx2 = freq2(u, q);
        for (c, &fy2) in col.iter_mut().zip(&fy2) {
            let g = gain((fx2 + fy2).sqrt()) * scale;
            c[0] *= g;
            c[1] *= g;
        }
        fp.transform(col, true);
    });
    let mut data = transpose(&t, q, p);
    drop(t);
    data.par_chunks_mut(q).for_each(|r| fq.transform(r, true));
    let mut fa = Vec::with_capacity(width * height);
    let mut fb = Vec::with_capacity(width * height);
    for row in data.chunks_exact(q).take(height) {
        for c in &row[..width] {
            fa.push(c[0]);
            fb.push(c[1]);
        }
    }
    (fa, fb)
}

/// Mean square of the difference of two planes after a zero-phase filter (see
/// [`filter_pair`]).
pub fn filtered_mse(
    a: &[f32],
    b: &[f32],
    width: usize,
    height: usize,
    margin: usize,
    gain: &(dyn Fn(f64) -> f64 + Sync),
) -> f64 {
    if width == 0 || height == 0 {
        return 0.0;
    }
    let (fa, fb) = filter_pair(a, b, width, height, margin, gain);
    fa.iter()
        .zip(&fb)
        .map(|(&a, &b)| (b - a) * (b - a))
        .sum::<f64>()
        / (width * height) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_round_trip_and_impulse() {
        let f = Fft::new(8);
        let mut a: Vec<Cx> = (0..8).map(|i| [i as f64, -(i as f64) * 0.5]).collect();
        let orig = a.clone();
        f.transform(&mut a, false);
        // DC bin is the sum.
        assert!((a[0][0] - 28.0).abs() < 1e-12);
        f.transform(&mut a, true);
        for (x, y) in a.iter().zip(&orig) {
            assert!((x[0] / 8.0 - y[0]).abs() < 1e-12 && (x[1] / 8.0 - y[1]).abs() < 1e-12);
        }
    }

    #[test]
    fn mirror_padding_is_continuous() {
        // 5 samples padded to 16: image, right mirror, left mirror.
        let idx: Vec<usize> = (0..16).map(|i| mirror_index(i, 5, 16)).collect();
        assert_eq!(idx, [0, 1, 2, 3, 4, 4, 3, 2, 1, 0, 4, 4, 3, 2, 1, 0]);
    }

    #[test]
    fn pixels_per_degree_at_300_dpi_12_inches() {
        let v = Viewing::default();
        assert!((v.pixels_per_degree() - 62.83).abs() < 0.01);
        assert!(
            (v.pixels_per_degree() / (12.0 * fm::tan(1f64.to_radians()) * 300.0) - 1.0).abs()
                < 1e-4
        );
        assert_eq!(nasanen(0.0), 1.0);
        assert!((nasanen_absolute(0.0) - 131.6 * fm::powf(11f64, 0.3188)).abs() < 1e-9);
    }
}
