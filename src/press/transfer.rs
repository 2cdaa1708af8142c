//! Calibration: a measured step wedge becomes a compensation (transfer) curve.
//!
//! The wedge file is CSV: each line `nominal %, measured %` (one measured column per ink
//! for CMYK: `nominal, c, m, y, k`), `#` starting a comment. The measured response is
//! interpolated with a monotone cubic (PCHIP, Fritsch & Carlson 1980, with the end
//! derivatives of Moler's `pchip`) and inverted: to print coverage `a` the plate gets the
//! nominal coverage whose measured response is `a`.

use std::path::Path;

use crate::error::{Error, Result};

/// A monotone piecewise-cubic Hermite interpolant through rising `x`.
#[derive(Clone, Debug, PartialEq)]
pub struct Pchip {
    x: Vec<f64>,
    y: Vec<f64>,
    d: Vec<f64>,
}

impl Pchip {
    /// Through the points `(x, y)`, `x` strictly rising, at least 2 points.
    pub fn new(x: Vec<f64>, y: Vec<f64>) -> Pchip {
        let n = x.len();
        assert!(n >= 2 && y.len() == n);
        let h: Vec<f64> = x.windows(2).map(|w| w[1] - w[0]).collect();
        let del: Vec<f64> = (0..n - 1).map(|k| (y[k + 1] - y[k]) / h[k]).collect();
        let mut d = vec![0.0; n];
        if n == 2 {
            d[0] = del[0];
            d[1] = del[0];
        } else {
            for k in 1..n - 1 {
                if del[k - 1] * del[k] > 0.0 {
                    let (w1, w2) = (2.0 * h[k] + h[k - 1], h[k] + 2.0 * h[k - 1]);
                    d[k] = (w1 + w2) / (w1 / del[k - 1] + w2 / del[k]);
                }
            }
            let end = |h0: f64, h1: f64, d0: f64, d1: f64| {
                let mut e = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
                if e * d0 <= 0.0 {
                    e = 0.0;
                } else if d0 * d1 <= 0.0 && e.abs() > (3.0 * d0).abs() {
                    e = 3.0 * d0;
                }
                e
            };
            d[0] = end(h[0], h[1], del[0], del[1]);
            d[n - 1] = end(h[n - 2], h[n - 3], del[n - 2], del[n - 3]);
        }
        Pchip { x, y, d }
    }

    /// The interpolant at `t` (held flat outside the points).
    pub fn eval(&self, t: f64) -> f64 {
        let n = self.x.len();
        if t <= self.x[0] {
            return self.y[0];
        }
        if t >= self.x[n - 1] {
            return self.y[n - 1];
        }
        let k = self.x.partition_point(|&v| v <= t) - 1;
        self.eval_in(k, t)
    }

    /// The interpolant at `t` on segment `k` (`x[k] ≤ t ≤ x[k + 1]`).
    fn eval_in(&self, k: usize, t: f64) -> f64 {
        let h = self.x[k + 1] - self.x[k];
        let s = (t - self.x[k]) / h;
        let (h00, h10, h01, h11) = hermite(s);
        h00 * self.y[k] + h10 * h * self.d[k] + h01 * self.y[k + 1] + h11 * h * self.d[k + 1]
    }

    /// The `t` in the points' range where the interpolant reaches `v` (the interpolant is
    /// monotone when the points are): the segment whose ends bracket `v`, then the Illinois
    /// variant of regula falsi on its cubic, to 1e-13 (far below an `f32` tone's step).
    /// A 16-bit tone table asks this 65,536 times, so it must be quick.
    pub fn inverse(&self, v: f64) -> f64 {
        let n = self.x.len();
        if v <= self.y[0] {
            return self.x[0];
        }
        if v >= self.y[n - 1] {
            return self.x[n - 1];
        }
        // The first point at or above v; the one before it is below (y[0] < v).
        let k = self.y.partition_point(|&y| y < v) - 1;
        let (mut a, mut b) = (self.x[k], self.x[k + 1]);
        let (mut fa, mut fb) = (self.y[k] - v, self.y[k + 1] - v);
        let mut side = 0i8;
        for _ in 0..200 {
            if b - a <= 1e-13 {
                break;
            }
            let mut c = (a * fb - b * fa) / (fb - fa);
            if !(c > a && c < b) {
                c = 0.5 * (a + b);
            }
            let fc = self.eval_in(k, c) - v;
            // Below v: the root is to the right. At or above: to the left (the lowest t
            // that reaches v, as on a flat stretch).
            if fc < 0.0 {
                (a, fa) = (c, fc);
                if side == -1 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                (b, fb) = (c, fc);
                if side == 1 {
                    fa *= 0.5;
                }
                side = 1;
            }
        }
        0.5 * (a + b)
    }
}

impl Pchip {
    /// `1 − inverse(v)` as `f32` for every `v` of `vs`: exactly the bits of
    /// [`Pchip::inverse`], about three times faster for a tone table's 65,536 values.
    ///
    /// Each root is found by Newton's method on its segment (started from the previous
    /// root moved along its tangent, so about two steps), to the last bits. `inverse` ends within 1e-13 of the
    /// root; where the curve is steep enough that its computed values change sign only
    /// within that distance of the root (slope at least 1e-2), and every point within
    /// 2e-13 of it gives the same `f32`, that is the `f32` `inverse` gives too. Elsewhere
    /// (near a flat stretch, on an `f32` rounding boundary, at the ends) `inverse` itself
    /// answers.
    pub fn complement_of_inverses(&self, vs: impl Iterator<Item = f64>) -> Vec<f32> {
        let n = self.x.len();
        // The previous value's segment, value, root and slope there.
        let mut prev: Option<(usize, f64, f64, f64)> = None;
        vs.map(|v| {
            let exact = || (1.0 - self.inverse(v)) as f32;
            if v <= self.y[0] || v >= self.y[n - 1] {
                return exact();
            }
            let k = self.y.partition_point(|&y| y < v) - 1;
            let start = match prev {
                Some((pk, pv, r, slope)) if pk == k && slope.abs() >= 1e-2 => r + (v - pv) / slope,
                _ => {
                    let (x0, x1, y0, y1) = (self.x[k], self.x[k + 1], self.y[k], self.y[k + 1]);
                    x0 + (v - y0) / (y1 - y0) * (x1 - x0)
                }
            };
            let Some((r, slope)) = self.newton(k, v, start) else {
                return exact();
            };
            prev = Some((k, v, r, slope));
            let (lo, hi) = ((1.0 - (r - 2e-13)) as f32, (1.0 - (r + 2e-13)) as f32);
            if slope.abs() >= 1e-2 && lo == hi {
                lo
            } else {
                exact()
            }
        })
        .collect()
    }

    /// The root of the interpolant minus `v` on segment `k` by Newton's method from `t`,
    /// kept inside a bracket (bisection when a step leaves it), and the slope there;
    /// `None` when it does not settle.
    fn newton(&self, k: usize, v: f64, mut t: f64) -> Option<(f64, f64)> {
        let (mut a, mut b) = (self.x[k], self.x[k + 1]);
        if !(t > a && t < b) {
            t = 0.5 * (a + b);
        }
        for _ in 0..60 {
            let (e, slope) = self.eval_slope(k, t);
            let f = e - v;
            if f == 0.0 {
                return Some((t, slope));
            }
            if f < 0.0 {
                a = t;
            } else {
                b = t;
            }
            let mut next = t - f / slope;
            if !(next > a && next < b) {
                next = 0.5 * (a + b);
            }
            if (next - t).abs() <= 1e-15 {
                return Some((next, slope));
            }
            t = next;
        }
        None
    }

    /// The interpolant at `t` on segment `k`, the same bits as [`Pchip::eval_in`], and its
    /// slope there.
    fn eval_slope(&self, k: usize, t: f64) -> (f64, f64) {
        let h = self.x[k + 1] - self.x[k];
        let s = (t - self.x[k]) / h;
        let (h00, h10, h01, h11) = hermite(s);
        let e =
            h00 * self.y[k] + h10 * h * self.d[k] + h01 * self.y[k + 1] + h11 * h * self.d[k + 1];
        let (g00, g10, g01, g11) = (
            6.0 * s * s - 6.0 * s,
            3.0 * s * s - 4.0 * s + 1.0,
            6.0 * s - 6.0 * s * s,
            3.0 * s * s - 2.0 * s,
        );
        let hd =
            g00 * self.y[k] + g10 * h * self.d[k] + g01 * self.y[k + 1] + g11 * h * self.d[k + 1];
        (e, hd / h)
    }
}

/// Compensation curves read from a measured wedge: one per measured column.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    curves: Vec<Pchip>,
}

impl Transfer {
    /// Parses a wedge file (see the module's description). Errors name the file and line.
    pub fn parse(text: &str, source: &Path) -> Result<Transfer> {
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let content = line.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let vals: Vec<f64> = content
                .split([',', ';', '\t', ' '])
                .map(str::trim)
                .filter(|t| !t.is_empty())
                .map(|t| {
                    t.trim_end_matches('%')
                        .parse::<f64>()
                        .ok()
                        .filter(|v| (0.0..=100.0).contains(v))
                        .ok_or_else(|| {
                            Error::parse(
                                source,
                                i + 1,
                                format!("'{t}' is not a percentage from 0 to 100"),
                            )
                        })
                })
                .collect::<Result<_>>()?;
            if vals.len() < 2 {
                return Err(Error::parse(
                    source,
                    i + 1,
                    "expected 'nominal %, measured %' (one measured column per ink)",
                ));
            }
            if let Some(first) = rows.first() {
                if first.len() != vals.len() {
                    return Err(Error::parse(
                        source,
                        i + 1,
                        format!("{} columns, the first row has {}", vals.len(), first.len()),
                    ));
                }
            }
            if let Some(prev) = rows.last() {
                if vals[0] <= prev[0] {
                    return Err(Error::parse(source, i + 1, "nominal values must rise"));
                }
            }
            rows.push(vals);
        }
        if rows.len() < 2 {
            return Err(Error::parse(source, 0, "a wedge needs at least 2 steps"));
        }
        let cols = rows[0].len() - 1;
        let mut curves = Vec::with_capacity(cols);
        for c in 1..=cols {
            let mut x: Vec<f64> = rows.iter().map(|r| r[0] / 100.0).collect();
            let mut y: Vec<f64> = rows.iter().map(|r| r[c] / 100.0).collect();
            if y.windows(2).any(|w| w[1] < w[0]) {
                return Err(Error::parse(
                    source,
                    0,
                    format!(
                        "measured column {c} falls somewhere: a wedge's response must not decrease"
                    ),
                ));
            }
            // Paper is paper and solid is solid.
            if x[0] > 0.0 {
                x.insert(0, 0.0);
                y.insert(0, 0.0);
            }
            if *x.last().unwrap() < 1.0 {
                x.push(1.0);
                y.push(1.0);
            }
            curves.push(Pchip::new(x, y));
        }
        Ok(Transfer { curves })
    }

    /// Reads and parses a wedge file.
    pub fn load(path: &Path) -> Result<Transfer> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Transfer::parse(&text, path)
    }

    /// Number of measured columns.
    pub fn columns(&self) -> usize {
        self.curves.len()
    }

    /// The plate coverage that prints coverage `a`, for ink/column `c` (the last column
    /// serves any further ink).
    pub fn compensate(&self, c: usize, a: f64) -> f64 {
        self.curves[c.min(self.curves.len() - 1)].inverse(a.clamp(0.0, 1.0))
    }

    /// A plane's tone table (reflectance of each code) passed through the compensation
    /// curve of ink/column `c`: `1 − compensate(c, 1 − v)` for every v, as one pass over
    /// the curve.
    pub fn compensated_table(&self, c: usize, tone: &[f32]) -> Vec<f32> {
        let curve = &self.curves[c.min(self.curves.len() - 1)];
        curve.complement_of_inverses(tone.iter().map(|&v| (1.0 - v as f64).clamp(0.0, 1.0)))
    }

    /// The measured response at nominal coverage `a`, for ink/column `c`.
    pub fn response(&self, c: usize, a: f64) -> f64 {
        self.curves[c.min(self.curves.len() - 1)].eval(a)
    }
}

/// The cubic Hermite basis at `s` in 0..=1: the weights of the two ends' values and
/// slopes (`h00`, `h10`, `h01`, `h11`).
#[inline]
fn hermite(s: f64) -> (f64, f64, f64, f64) {
    (
        (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s),
        s * (1.0 - s) * (1.0 - s),
        s * s * (3.0 - 2.0 * s),
        s * s * (s - 1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pchip_is_monotone_and_interpolates() {
        let p = Pchip::new(
            vec![0.0, 0.1, 0.5, 0.9, 1.0],
            vec![0.0, 0.15, 0.68, 0.95, 1.0],
        );
        let mut last = -1.0;
        for k in 0..=1000 {
            let v = p.eval(k as f64 / 1000.0);
            assert!(v >= last);
            last = v;
        }
        assert!((p.eval(0.5) - 0.68).abs() < 1e-12);
        assert!((p.inverse(0.68) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn inverse_is_the_lowest_point_that_reaches_the_value() {
        // Rising, with a flat stretch (0.5..0.6 held at 0.7), as measured wedges can be.
        let p = Pchip::new(
            vec![0.0, 0.2, 0.5, 0.6, 0.8, 1.0],
            vec![0.0, 0.3, 0.7, 0.7, 0.9, 1.0],
        );
        // The plain bisection over the whole range that this replaces.
        let slow = |v: f64| {
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if p.eval(mid) < v {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        for i in 0..=4000 {
            let v = i as f64 / 4000.0;
            let t = p.inverse(v);
            // Where the curve turns flat (zero slope at 0.5), t is determined only to about
            // the square root of f64's epsilon by either search.
            assert!((t - slow(v)).abs() < 1e-7, "{v}: {t} against {}", slow(v));
            if v > 0.0 && v < 1.0 {
                assert!((p.eval(t) - v).abs() < 1e-9, "{v}");
            }
        }
        assert!((p.inverse(0.7) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn tables_have_the_bits_of_one_inverse_at_a_time() {
        let flat = Transfer::parse(
            "0,0\n20,30\n50,70\n60,70\n80,90\n100,100\n",
            Path::new("flat.csv"),
        )
        .unwrap();
        let mut curves = vec![flat];
        for name in ["thermal-203.csv", "laser-600.csv"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("presets")
                .join(name);
            curves.push(Transfer::load(&path).unwrap());
        }
        let srgb = crate::tone::ToneTable::new(8, crate::tone::Encoding::Srgb, &Default::default());
        let linear16 =
            crate::tone::ToneTable::new(16, crate::tone::Encoding::Linear, &Default::default());
        let srgb16 =
            crate::tone::ToneTable::new(16, crate::tone::Encoding::Srgb, &Default::default());
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let random: Vec<f32> = (0..20000)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s % 1_000_001) as f32 / 1_000_000.0
            })
            .collect();
        for t in &curves {
            for tone in [
                srgb.as_slice(),
                linear16.as_slice(),
                srgb16.as_slice(),
                &random,
            ] {
                let one_at_a_time: Vec<u32> = tone
                    .iter()
                    .map(|&v| ((1.0 - t.compensate(0, 1.0 - v as f64)) as f32).to_bits())
                    .collect();
                let table: Vec<u32> = t
                    .compensated_table(0, tone)
                    .iter()
                    .map(|v| v.to_bits())
                    .collect();
                assert!(table == one_at_a_time, "{} values", tone.len());
            }
        }
    }

    #[test]
    fn parse_wedge_with_comments() {
        let t = Transfer::parse(
            "# wedge\n0, 0\n50, 62 # mid\n100, 100\n",
            Path::new("w.csv"),
        )
        .unwrap();
        assert_eq!(t.columns(), 1);
        assert!((t.compensate(0, 0.62) - 0.5).abs() < 1e-9);
        let e = Transfer::parse("0,0\n50,40\n40,50\n", Path::new("w.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("w.csv:3:"), "{e}");
    }
}
