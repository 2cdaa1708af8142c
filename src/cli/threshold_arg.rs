//! `--threshold`: a fraction of reflectance, a percentage, or an 8-bit code.

use std::str::FromStr;

use halftone::tone::srgb_to_linear;

/// A `--threshold` value as the user wrote it. A pixel at or above it becomes paper.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThresholdArg {
    /// `0.5`: a fraction of reflectance, 0..1, in the tone domain (linear light unless
    /// `--no-linearize`).
    Fraction(f32),
    /// `50%`: the same as a fraction, written as a percentage.
    Percent(f32),
    /// `128`: an 8-bit code of the input file (sRGB), as a paint program's threshold
    /// means it; turned into that code's linear reflectance (0.216 for 128).
    Code(u8),
}

impl Default for ThresholdArg {
    fn default() -> Self {
        ThresholdArg::Fraction(0.5)
    }
}

impl FromStr for ThresholdArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        let bad = || {
            format!(
                "'{s}': expected a fraction of reflectance (0.5), a percentage (50%) or an \
                 8-bit code (128)"
            )
        };
        if let Some(p) = t.strip_suffix('%') {
            let v: f32 = p.trim().parse().map_err(|_| bad())?;
            if !(0.0..=100.0).contains(&v) {
                return Err(format!("'{s}': a percentage must be from 0% to 100%"));
            }
            return Ok(ThresholdArg::Percent(v));
        }
        // A whole number above 1 is a code; 0 and 1 (and anything with a point) are
        // fractions, so `--threshold 1` keeps meaning "only white is paper".
        if t.bytes().all(|b| b.is_ascii_digit()) && !t.is_empty() {
            let v: u32 = t.parse().map_err(|_| bad())?;
            if v > 1 {
                return u8::try_from(v).map(ThresholdArg::Code).map_err(|_| {
                    format!(
                        "'{s}': an 8-bit code is a whole number from 2 to 255 (0 and 1 are \
                             fractions); or write a fraction (0.5) or a percentage (50%)"
                    )
                });
            }
        }
        let v: f32 = t.parse().map_err(|_| bad())?;
        if !(0.0..=1.0).contains(&v) {
            return Err(format!(
                "'{s}': a fraction must be from 0 to 1 (or write 50% or an 8-bit code)"
            ));
        }
        Ok(ThresholdArg::Fraction(v))
    }
}

impl ThresholdArg {
    /// The threshold as reflectance in the method's tone domain: linear light when
    /// `linearize`, the code scale otherwise.
    pub fn reflectance(self, linearize: bool) -> f32 {
        match self {
            ThresholdArg::Fraction(v) => v,
            ThresholdArg::Percent(p) => p / 100.0,
            ThresholdArg::Code(c) if linearize => srgb_to_linear(c as f64 / 255.0) as f32,
            ThresholdArg::Code(c) => c as f32 / 255.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_ways_to_say_it() {
        let p = |s: &str| s.parse::<ThresholdArg>();
        assert_eq!(p("0.5").unwrap().reflectance(true), 0.5);
        assert_eq!(p("50%").unwrap().reflectance(true), 0.5);
        assert_eq!(p("1").unwrap().reflectance(true), 1.0);
        assert_eq!(p("0").unwrap().reflectance(true), 0.0);
        let c = p("128").unwrap();
        assert!((c.reflectance(true) - 0.2158).abs() < 1e-3);
        assert!((c.reflectance(false) - 128.0 / 255.0).abs() < 1e-6);
        for bad in ["256", "1.5", "101%", "-0.1", "half", ""] {
            assert!(p(bad).is_err(), "{bad}");
        }
        // The message states the forms that are accepted.
        let e = p("300").unwrap_err();
        assert!(
            e.contains("from 2 to 255") && e.contains("0.5") && e.contains("50%"),
            "{e}"
        );
    }
}
