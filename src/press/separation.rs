//! sRGB → CMYK: the press model inverted at the nodes of a 3-D lookup table, with a
//! black-generation rule (grey component replacement) and a total ink limit; or the naive
//! complement.
//!
//! At each node the target is the sRGB colour's CIELAB (D50, media-relative). Black is
//! `k = gcr · k_max`, where `k_max` is the most black with which C, M and Y can still reach
//! the target (as closely as they can with no black, + 0.5 ΔE): so `--gcr 100` prints a
//! neutral grey with black alone and `--gcr 0` with C, M and Y alone. C, M and Y then
//! minimise `ΔE² + μ·(c + m + y)` (μ small: of two near-equal matches, less ink) by
//! projected Gauss–Newton steps inside `0 ≤ c, m, y ≤ 1`, `c + m + y ≤ tac − k`.

use rayon::prelude::*;

use super::{delta_e76, srgb8_to_lab, Press};

/// Nodes a side of the lookup table (17³ = 4913 nodes, 16 code steps apart).
pub const GRID: usize = 17;

/// Weight of the ink-saving term (ΔE² per unit of summed C+M+Y coverage).
const INK_WEIGHT: f64 = 10.0;

/// How sRGB becomes ink.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeparationOptions {
    /// Grey component replacement, 0..1.
    pub gcr: f64,
    /// Total area coverage limit, 1..4 (3 = 300%).
    pub tac: f64,
}

impl Default for SeparationOptions {
    fn default() -> Self {
        SeparationOptions { gcr: 0.5, tac: 3.0 }
    }
}

/// The naive complement with grey component replacement: `c = 1 − r` (on sRGB codes, as
/// the usual tools do), `k = gcr · min(c, m, y)`, `c −= k` …, then scaled to the ink limit.
pub fn naive(rgb: [u8; 3], opts: &SeparationOptions) -> [f64; 4] {
    let c = rgb.map(|v| 1.0 - v as f64 / 255.0);
    let k = opts.gcr * c[0].min(c[1]).min(c[2]);
    let mut out = [c[0] - k, c[1] - k, c[2] - k, k];
    limit(&mut out, opts.tac);
    out
}

/// Scales C, M, Y down so the total stays within `tac`.
fn limit(cmyk: &mut [f64; 4], tac: f64) {
    let cmy = cmyk[0] + cmyk[1] + cmyk[2];
    let room = (tac - cmyk[3]).max(0.0);
    if cmy > room && cmy > 0.0 {
        for v in cmyk.iter_mut().take(3) {
            *v *= room / cmy;
        }
    }
}

/// Projects `x` onto `{0 ≤ xᵢ ≤ 1, Σ xᵢ ≤ cap}`.
fn project(x: [f64; 3], cap: f64) -> [f64; 3] {
    let clamp = |l: f64| x.map(|v| (v - l).clamp(0.0, 1.0));
    let s = |l: f64| clamp(l).iter().sum::<f64>();
    if s(0.0) <= cap {
        return clamp(0.0);
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if s(mid) > cap {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    clamp(hi)
}

fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if d.abs() < 1e-18 {
        return None;
    }
    let mut x = [0.0; 3];
    for (i, xi) in x.iter_mut().enumerate() {
        let mut m = a;
        for r in 0..3 {
            m[r][i] = b[r];
        }
        *xi = det(m) / d;
    }
    Some(x)
}

/// Best C, M, Y for `target` with black fixed at `k`: `(cmy, ΔE)`.
fn solve_cmy(
    press: &Press,
    target: [f64; 3],
    k: f64,
    cap: f64,
    start: [f64; 3],
) -> ([f64; 3], f64) {
    let cost = |x: [f64; 3]| {
        let l = press.lab([x[0], x[1], x[2], k]);
        let de = delta_e76(l, target);
        (de * de + INK_WEIGHT * (x[0] + x[1] + x[2]), l)
    };
    let mut x = project(start, cap);
    let (mut fx, mut lx) = cost(x);
    let mut lambda = 1e-3;
    for _ in 0..40 {
        // Jacobian of Lab by forward differences (stepping inward at the upper bound).
        let mut jac = [[0.0; 3]; 3];
        for i in 0..3 {
            let h = if x[i] > 0.5 { -1e-4 } else { 1e-4 };
            let mut xh = x;
            xh[i] += h;
            let lh = press.lab([xh[0], xh[1], xh[2], k]);
            for r in 0..3 {
                jac[r][i] = (lh[r] - lx[r]) / h;
            }
        }
        let res = [lx[0] - target[0], lx[1] - target[1], lx[2] - target[2]];
        // Normal equations with the ink term's gradient (μ on each of c, m, y).
        let mut jtj = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        for i in 0..3 {
            for j in 0..3 {
                jtj[i][j] = (0..3).map(|r| jac[r][i] * jac[r][j]).sum();
            }
            g[i] = (0..3).map(|r| jac[r][i] * res[r]).sum::<f64>() + INK_WEIGHT / 2.0;
        }
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj;
            for (i, row) in a.iter_mut().enumerate() {
                row[i] += lambda * (1.0 + jtj[i][i]);
            }
            let Some(step) = solve3(a, g.map(|v| -v)) else {
                lambda *= 10.0;
                continue;
            };
            let xn = project([x[0] + step[0], x[1] + step[1], x[2] + step[2]], cap);
            let (fn_, ln) = cost(xn);
            if fn_ < fx {
                let moved = (0..3).map(|i| (xn[i] - x[i]).abs()).fold(0.0, f64::max);
                x = xn;
                fx = fn_;
                lx = ln;
                lambda = (lambda * 0.3).max(1e-7);
                improved = moved > 1e-7;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (x, delta_e76(lx, target))
}

/// The ink amounts (0..1) that print `target` (CIELAB D50, media-relative) on `press`.
pub fn separate_lab(press: &Press, target: [f64; 3], opts: &SeparationOptions) -> [f64; 4] {
    let tac = opts.tac.clamp(1.0, 4.0);
    let start = [0.3, 0.3, 0.3];
    let (cmy0, de0) = solve_cmy(press, target, 0.0, tac, start);
    let mut k = 0.0;
    if opts.gcr > 0.0 {
        // Largest k that still reaches the target about as well as no black does.
        let reach = |k: f64| solve_cmy(press, target, k, tac - k, cmy0).1 <= de0 + 0.5;
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        if reach(1.0) {
            lo = 1.0;
        } else {
            for _ in 0..12 {
                let mid = 0.5 * (lo + hi);
                if reach(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        }
        k = opts.gcr.clamp(0.0, 1.0) * lo;
    }
    let (cmy, _) = if k == 0.0 {
        (cmy0, de0)
    } else {
        solve_cmy(press, target, k, tac - k, cmy0)
    };
    [cmy[0], cmy[1], cmy[2], k]
}

/// A separation: sRGB codes to ink amounts.
#[derive(Clone, Debug)]
pub struct Separation {
    /// `GRID³` nodes of C, M, Y, K, red fastest; `None` for the naive complement.
    lut: Option<Vec<[f32; 4]>>,
    opts: SeparationOptions,
}

impl Separation {
    /// The press model inverted at every node of a `GRID³` table (in parallel).
    pub fn model(press: &Press, opts: SeparationOptions) -> Separation {
        let nodes: Vec<[u8; 3]> = (0..GRID * GRID * GRID)
            .map(|i| {
                let code = |k: usize| ((k * 255) as f64 / (GRID - 1) as f64).round() as u8;
                [
                    code(i % GRID),
                    code((i / GRID) % GRID),
                    code(i / (GRID * GRID)),
                ]
            })
            .collect();
        let lut = nodes
            .par_iter()
            .map(|&rgb| separate_lab(press, srgb8_to_lab(rgb), &opts).map(|v| v as f32))
            .collect();
        Separation {
            lut: Some(lut),
            opts,
        }
    }

    /// A table filled elsewhere (e.g. from an ICC profile, [`super::icc`]): `GRID³` nodes of
    /// C, M, Y, K at sRGB `(r, g, b) = (i, j, k)/(GRID − 1)`, red fastest.
    pub fn from_table(lut: Vec<[f32; 4]>, opts: SeparationOptions) -> Separation {
        assert_eq!(
            lut.len(),
            GRID * GRID * GRID,
            "a separation table has GRID³ nodes"
        );
        Separation {
            lut: Some(lut),
            opts,
        }
    }

    /// The naive complement.
    pub fn naive(opts: SeparationOptions) -> Separation {
        Separation { lut: None, opts }
    }

    /// Ink amounts (0..1) for an 8-bit sRGB colour: trilinear interpolation in the table.
    pub fn cmyk(&self, rgb: [u8; 3]) -> [f64; 4] {
        let Some(lut) = &self.lut else {
            return naive(rgb, &self.opts);
        };
        let step = 255.0 / (GRID - 1) as f64;
        let pos = rgb.map(|c| {
            let t = c as f64 / step;
            let i = (t as usize).min(GRID - 2);
            (i, t - i as f64)
        });
        let mut out = [0.0; 4];
        for corner in 0..8 {
            let mut w = 1.0;
            let mut idx = 0;
            let mut mul = 1;
            for (a, &(i, f)) in pos.iter().enumerate() {
                let hi = corner & (1 << a) != 0;
                w *= if hi { f } else { 1.0 - f };
                idx += (i + hi as usize) * mul;
                mul *= GRID;
            }
            if w > 0.0 {
                for (o, v) in out.iter_mut().zip(lut[idx]) {
                    *o += w * v as f64;
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_respects_box_and_cap() {
        let p = project([0.9, 0.8, 1.4], 2.0);
        assert!(p.iter().all(|v| (0.0..=1.0).contains(v)));
        assert!((p.iter().sum::<f64>() - 2.0).abs() < 1e-9);
        assert_eq!(project([0.2, -0.1, 0.3], 2.0), [0.2, 0.0, 0.3]);
    }

    #[test]
    fn naive_grey_goes_to_black_at_full_gcr() {
        let o = SeparationOptions { gcr: 1.0, tac: 3.0 };
        let c = naive([128, 128, 128], &o);
        assert_eq!(&c[..3], &[0.0, 0.0, 0.0]);
        assert!((c[3] - (1.0 - 128.0 / 255.0)).abs() < 1e-12);
    }
}
