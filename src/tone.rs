//! Transfer tables: sRGB-encoded codes to linear-light reflectance, and the optional
//! curves after it (user gamma, dot-gain compensation, inversion).
//!
//! A table has one `f32` per possible code (256 for 8-bit, 65536 for 16-bit), built once
//! per image, so no method ever calls `powf` per pixel.

use crate::fmath as fm;

/// How a plane's codes relate to light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// sRGB-encoded (IEC 61966-2-1): what cameras, scanners and the web produce.
    Srgb,
    /// Codes proportional to linear reflectance (e.g. a luminance plane computed in linear light).
    Linear,
}

/// The user's tone options, applied after decoding to linear light.
#[derive(Clone, Debug, PartialEq)]
pub struct ToneOptions {
    /// Decode sRGB to linear light (true) or treat codes as if they were linear (the naive
    /// behaviour of most tools; `--no-linearize`).
    pub linearize: bool,
    /// Extra gamma applied to linear reflectance: `r' = r^gamma` (1 = none).
    pub gamma: f32,
    /// Dot gain at 50% coverage to pre-compensate, as a fraction (0.15 = 15%); 0 = none.
    pub dot_gain: f32,
    /// Negative media: reflectance becomes `1 - r`.
    pub invert: bool,
}

impl Default for ToneOptions {
    fn default() -> Self {
        ToneOptions {
            linearize: true,
            gamma: 1.0,
            dot_gain: 0.0,
            invert: false,
        }
    }
}

/// sRGB decoding of a normalised code `v` in 0..=1 (IEC 61966-2-1).
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        fm::powf((v + 0.055) / 1.055, 2.4)
    }
}

/// sRGB encoding of a linear value `l` in 0..=1 (IEC 61966-2-1).
pub fn linear_to_srgb(l: f64) -> f64 {
    let l = l.clamp(0.0, 1.0);
    if l <= 0.0031308 {
        l * 12.92
    } else {
        1.055 * fm::powf(l, 1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB code nearest to linear value `l`.
pub fn linear_to_srgb8(l: f64) -> u8 {
    (linear_to_srgb(l) * 255.0).round() as u8
}

/// Ink coverage that, after a dot gain of `gain` at 50% (modelled as
/// `printed = a + 4·gain·a·(1−a)`, a parabola through 0 and 1), prints as `target`.
fn compensate_dot_gain(target: f64, gain: f64) -> f64 {
    if gain <= 0.0 {
        return target;
    }
    // Solve 4g·a² − (1+4g)·a + target = 0 for the root in 0..=1.
    let g4 = 4.0 * gain;
    let b = 1.0 + g4;
    let disc = (b * b - 4.0 * g4 * target).max(0.0);
    ((b - disc.sqrt()) / (2.0 * g4)).clamp(0.0, 1.0)
}

/// Maps every code of a plane to linear reflectance in 0..=1 (0 = solid ink, 1 = paper).
#[derive(Clone, Debug)]
pub struct ToneTable {
    values: Vec<f32>,
}

impl ToneTable {
    /// Builds the table for codes of `bits` (8 or 16) in `encoding`, with the user's options.
    pub fn new(bits: u32, encoding: Encoding, opts: &ToneOptions) -> ToneTable {
        assert!(
            bits == 8 || bits == 16,
            "tone tables are for 8- or 16-bit codes"
        );
        let max = ((1u32 << bits) - 1) as f64;
        let values = (0..=max as u32)
            .map(|c| {
                let v = c as f64 / max;
                let mut r = if opts.linearize && encoding == Encoding::Srgb {
                    srgb_to_linear(v)
                } else {
                    v
                };
                if opts.gamma != 1.0 {
                    r = fm::powf(r, opts.gamma as f64);
                }
                if opts.dot_gain > 0.0 {
                    // Coverage is 1 − reflectance; print less ink where it will spread.
                    r = 1.0 - compensate_dot_gain(1.0 - r, opts.dot_gain as f64);
                }
                if opts.invert {
                    r = 1.0 - r;
                }
                r.clamp(0.0, 1.0) as f32
            })
            .collect();
        ToneTable { values }
    }

    /// The table as a slice indexed by code.
    pub fn as_slice(&self) -> &[f32] {
        &self.values
    }

    /// True when reflectance never decreases as the code increases.
    pub fn is_increasing(&self) -> bool {
        self.values.windows(2).all(|w| w[0] <= w[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_all_codes() {
        for c in 0..=255u8 {
            let l = srgb_to_linear(c as f64 / 255.0);
            assert_eq!(linear_to_srgb8(l), c);
        }
    }

    #[test]
    fn code_128_is_about_22_percent() {
        let t = ToneTable::new(8, Encoding::Srgb, &ToneOptions::default());
        assert!((t.as_slice()[128] - 0.2158).abs() < 1e-3);
        assert_eq!(t.as_slice()[0], 0.0);
        assert_eq!(t.as_slice()[255], 1.0);
        assert!(t.is_increasing());
    }

    #[test]
    fn no_linearize_is_proportional() {
        let opts = ToneOptions {
            linearize: false,
            ..Default::default()
        };
        let t = ToneTable::new(8, Encoding::Srgb, &opts);
        assert!((t.as_slice()[51] - 0.2).abs() < 1e-6);
    }

    #[test]
    fn invert_and_dot_gain() {
        let inv = ToneTable::new(
            8,
            Encoding::Linear,
            &ToneOptions {
                invert: true,
                ..Default::default()
            },
        );
        assert_eq!(inv.as_slice()[0], 1.0);
        assert!(!inv.is_increasing());
        // With 15% gain, 50% coverage must be printed as less ink whose gained result is 50%.
        let a = compensate_dot_gain(0.5, 0.15);
        assert!(a < 0.5);
        let printed = a + 4.0 * 0.15 * a * (1.0 - a);
        assert!((printed - 0.5).abs() < 1e-12);
        assert_eq!(compensate_dot_gain(0.0, 0.2), 0.0);
        assert!((compensate_dot_gain(1.0, 0.2) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sixteen_bit_table() {
        let t = ToneTable::new(16, Encoding::Srgb, &ToneOptions::default());
        assert_eq!(t.as_slice().len(), 65536);
        assert!((t.as_slice()[32896] - 0.2158).abs() < 1e-3);
    }
}
