//! The colours a set of inks can show by dithering, and how a picture is mapped into them.
//!
//! Dithering mixes inks in linear light, so what a panel can show is the convex hull of its
//! inks in linear RGB. [`Hull`] holds that hull (a solid, a flat polygon when the inks lie in
//! one plane, a segment for black, white and greys) and clips a colour into it without
//! changing its luminance: along the line from the neutral of the same luminance (the
//! *anchor*, on the segment from the darkest to the lightest ink) towards the colour, then,
//! when the colour leaves the hull through a face, sliding along that face at the same
//! luminance towards the nearest hue the inks have. A hue the inks lack altogether (blue on a
//! black, white, red and yellow panel) becomes the neutral of its luminance.

use crate::color::{OKLAB_M1_F64, OKLAB_M1_INV_F64, OKLAB_M2_F64, OKLAB_M2_INV_F64};
use crate::fmath as fm;

/// Luminance of linear sRGB (the Y row of the sRGB → XYZ matrix).
pub const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add_scaled(a: [f64; 3], s: f64, b: [f64; 3]) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// A bounding plane: `n · x ≤ d` inside.
#[derive(Clone, Copy, Debug)]
struct Face {
    n: [f64; 3],
    d: f64,
}

/// The convex hull of the inks in linear RGB.
#[derive(Clone, Debug)]
pub struct Hull {
    /// The darkest and the lightest ink: the neutral axis runs between them.
    dark: [f64; 3],
    light: [f64; 3],
    /// 0 (one colour), 1 (a segment), 2 (a polygon) or 3 (a solid).
    dim: u8,
    /// A flat hull's unit normal.
    normal: [f64; 3],
    /// For a flat hull: its direction of zero luminance (unit), the one way colour can go.
    chroma_dir: [f64; 3],
    faces: Vec<Face>,
}

/// What [`Hull::clip`] found for one colour.
#[derive(Clone, Copy, Debug)]
pub struct Clipped {
    /// The colour in the hull.
    pub colour: [f64; 3],
    /// The neutral of the same luminance.
    pub anchor: [f64; 3],
    /// How far out the colour was: its distance from the anchor over the hull's along the
    /// same line (≤ 1 inside; `f64::INFINITY` where the hull has no room in that direction).
    pub reach: f64,
}

impl Hull {
    /// The hull of `inks` (linear RGB, at least one).
    pub fn new(inks: &[[f64; 3]]) -> Hull {
        let y = |c: &[f64; 3]| dot(LUMA, *c);
        let dark = *inks
            .iter()
            .min_by(|a, b| y(a).total_cmp(&y(b)))
            .expect("at least one ink");
        let light = *inks
            .iter()
            .max_by(|a, b| y(a).total_cmp(&y(b)))
            .expect("at least one ink");
        // Dimension by Gram–Schmidt on the differences from the first ink.
        let scale = inks
            .iter()
            .map(|c| norm(sub(*c, inks[0])))
            .fold(0.0, f64::max)
            .max(1e-12);
        let mut basis: Vec<[f64; 3]> = Vec::new();
        for c in inks {
            let mut v = sub(*c, inks[0]);
            for b in &basis {
                v = add_scaled(v, -dot(v, *b), *b);
            }
            let n = norm(v);
            if n > 1e-4 * scale && basis.len() < 3 {
                basis.push(v.map(|x| x / n));
            }
        }
        let dim = basis.len() as u8;
        let centroid = {
            let mut c = [0.0; 3];
            for i in inks {
                c = add_scaled(c, 1.0 / inks.len() as f64, *i);
            }
            c
        };
        let mut hull = Hull {
            dark,
            light,
            dim,
            normal: [0.0; 3],
            chroma_dir: [0.0; 3],
            faces: Vec::new(),
        };
        let eps = 1e-9 * scale * scale;
        match dim {
            3 => {
                for i in 0..inks.len() {
                    for j in i + 1..inks.len() {
                        for k in j + 1..inks.len() {
                            let n = cross(sub(inks[j], inks[i]), sub(inks[k], inks[i]));
                            if norm(n) < 1e-6 * scale * scale {
                                continue;
                            }
                            hull.push_face(n, inks[i], inks, centroid, eps);
                        }
                    }
                }
            }
            2 => {
                let normal = cross(basis[0], basis[1]);
                let normal = normal.map(|x| x / norm(normal));
                hull.normal = normal;
                // The in-plane direction of zero luminance.
                let c = add_scaled(
                    basis[0].map(|x| x * dot(LUMA, basis[1])),
                    -dot(LUMA, basis[0]),
                    basis[1],
                );
                let cn = norm(c);
                if cn > 1e-12 {
                    hull.chroma_dir = c.map(|x| x / cn);
                }
                for i in 0..inks.len() {
                    for j in i + 1..inks.len() {
                        let n = cross(sub(inks[j], inks[i]), normal);
                        if norm(n) < 1e-6 * scale {
                            continue;
                        }
                        hull.push_face(n, inks[i], inks, centroid, eps);
                    }
                }
            }
            _ => {}
        }
        hull
    }

    /// Keeps the plane through `p` with normal `n` if every ink lies on one side of it,
    /// turned to face away from the centroid.
    fn push_face(
        &mut self,
        n: [f64; 3],
        p: [f64; 3],
        inks: &[[f64; 3]],
        centroid: [f64; 3],
        eps: f64,
    ) {
        let side: Vec<f64> = inks.iter().map(|q| dot(n, sub(*q, p))).collect();
        let (n, d) = if side.iter().all(|&s| s <= eps) {
            (n, dot(n, p))
        } else if side.iter().all(|&s| s >= -eps) {
            let n = n.map(|x| -x);
            (n, dot(n, p))
        } else {
            return;
        };
        debug_assert!(dot(n, centroid) <= d + eps);
        let len = norm(n);
        self.faces.push(Face {
            n: n.map(|x| x / len),
            d: d / len,
        });
    }

    /// The neutral of luminance `y`: on the segment from the darkest to the lightest ink
    /// (clamped to it).
    pub fn anchor(&self, y: f64) -> [f64; 3] {
        let (yd, yl) = (dot(LUMA, self.dark), dot(LUMA, self.light));
        let u = if yl - yd > 1e-12 {
            ((y - yd) / (yl - yd)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        add_scaled(self.dark, u, sub(self.light, self.dark))
    }

    /// How far along `dir` from `from` (a point in the hull) the hull goes, in units of
    /// `dir`, and the face it leaves through.
    fn exit(&self, from: [f64; 3], dir: [f64; 3]) -> (f64, Option<usize>) {
        let mut best = (f64::INFINITY, None);
        for (i, f) in self.faces.iter().enumerate() {
            let along = dot(f.n, dir);
            if along > 1e-12 {
                let t = ((f.d - dot(f.n, from)) / along).max(0.0);
                if t < best.0 {
                    best = (t, Some(i));
                }
            }
        }
        best
    }

    /// The part of `r` (a change of colour at constant luminance) that a flat hull can
    /// follow: its projection on the hull's zero-luminance direction.
    fn in_plane(&self, r: [f64; 3]) -> [f64; 3] {
        if self.dim == 2 {
            self.chroma_dir.map(|c| c * dot(r, self.chroma_dir))
        } else {
            r
        }
    }

    /// How far out `colour` is (see [`Clipped::reach`]) and the line it is measured on: the
    /// anchor and the (possibly flattened) direction from it.
    pub fn reach(&self, colour: [f64; 3]) -> ([f64; 3], [f64; 3], f64) {
        let l = self.line(colour);
        (l.anchor, l.dir, l.reach)
    }

    /// Whether the hull is a solid (the inks span all three dimensions of colour).
    pub fn is_solid(&self) -> bool {
        self.dim == 3
    }

    /// 0 (one colour), 1 (a segment: black, white and greys), 2 (a polygon) or 3 (a solid).
    pub fn dimension(&self) -> u8 {
        self.dim
    }

    /// The line from the neutral of `colour`'s luminance towards it, and where it leaves
    /// the hull.
    pub fn line(&self, colour: [f64; 3]) -> Line {
        self.line_towards(colour, dot(LUMA, colour), false)
    }

    /// The line from the neutral of luminance `y` towards `colour`, and where it leaves the
    /// hull: [`Self::line`] aimed from another lightness.
    ///
    /// A flat hull's line goes towards the colour's projection on its plane (not only the
    /// part of the way at constant luminance, which from a lighter anchor to a darker colour
    /// points away from every hue the plane has: a violet on black, white and red inks went
    /// to a light grey).
    pub fn line_from(&self, colour: [f64; 3], y: f64) -> Line {
        self.line_towards(colour, y, true)
    }

    /// [`Self::line_from`], a flat hull's line projected on its plane (`project`) or kept
    /// at constant luminance.
    fn line_towards(&self, colour: [f64; 3], y: f64, project: bool) -> Line {
        let anchor = self.anchor(y);
        let line = |dir, exit, reach| Line {
            anchor,
            dir,
            exit,
            reach,
        };
        if self.dim <= 1 {
            return line([0.0; 3], (f64::INFINITY, None), 0.0);
        }
        let d = sub(colour, anchor);
        let r = if project && self.dim == 2 {
            add_scaled(d, -dot(d, self.normal), self.normal)
        } else {
            self.in_plane(d)
        };
        if norm(r) < 1e-9 {
            return line(r, (f64::INFINITY, None), 0.0);
        }
        let exit = self.exit(anchor, r);
        let reach = if exit.0 > 0.0 {
            1.0 / exit.0
        } else {
            f64::INFINITY
        };
        line(r, exit, reach)
    }

    /// `colour` moved into the hull at its own luminance (where the hull reaches that
    /// luminance): see the module docs.
    pub fn clip(&self, colour: [f64; 3]) -> Clipped {
        self.clip_line(&self.line(colour))
    }

    /// [`Self::clip`] of the colour whose [`Self::line`] is `l`.
    pub fn clip_line(&self, l: &Line) -> Clipped {
        let (anchor, r, reach) = (l.anchor, l.dir, l.reach);
        if self.dim <= 1 || reach <= 1.0 {
            return Clipped {
                colour: if self.dim <= 1 {
                    anchor
                } else {
                    add_scaled(anchor, 1.0, r)
                },
                anchor,
                reach,
            };
        }
        let (t, face) = l.exit;
        let t = t.min(1.0);
        let mut at = add_scaled(anchor, t, r);
        if let (3, Some(f)) = (self.dim, face) {
            // Slide along the face it left by, at the same luminance.
            let rest = r.map(|x| x * (1.0 - t));
            let along = cross(self.faces[f].n, LUMA);
            let len2 = dot(along, along);
            if len2 > 1e-18 {
                let q = along.map(|a| a * dot(rest, along) / len2);
                if norm(q) > 1e-9 {
                    let (s, _) = self.exit(at, q);
                    at = add_scaled(at, s.min(1.0), q);
                }
            }
        }
        Clipped {
            colour: at,
            anchor,
            reach,
        }
    }
}

/// Oklab of a linear sRGB colour (Ottosson's matrices; negative light clamped to 0). Of
/// the adapted inks' linear RGB (the panel's white `[1, 1, 1]`, its black near 0), this is
/// Oklab relative to the panel's white and black.
pub fn oklab(c: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = c.map(|v| v.max(0.0));
    let [l, m, s] = OKLAB_M1_F64.map(|w| fm::cbrt(w[0] * r + w[1] * g + w[2] * b));
    OKLAB_M2_F64.map(|w| w[0] * l + w[1] * m + w[2] * s)
}

/// Linear sRGB of an Oklab colour (the inverse of [`oklab`]; may leave `[0, 1]`).
pub fn linear_of_oklab(lab: [f64; 3]) -> [f64; 3] {
    let [l, a, b] = lab;
    let [l_, m_, s_] = OKLAB_M2_INV_F64.map(|w| (w[0] * l + w[1] * a + w[2] * b).powi(3));
    OKLAB_M1_INV_F64.map(|w| w[0] * l_ + w[1] * m_ + w[2] * s_)
}

/// The mix of `inks` (linear sRGB, as measured: white `[1, 1, 1]` is D65 at `Y = 1`) whose
/// colour is nearest `target` by CIEDE2000: what the absolute intent aims at for a colour
/// outside the inks' hull, as an absolute colorimetric rendering clips.
///
/// Neither a line from the neutral axis nor a clip at the colour's own luminance finds it on
/// real inks: their black and white are an edge of the hull, so every line from a neutral
/// leaves the hull at once, and at constant luminance a saturated red far lighter than the
/// red ink clips to a pale pink that renders as black and white (a flat red on bwry-3in97
/// with DBS: 0% red ink, 63% black). Here the mix's shares are found by projected gradient
/// descent on the simplex (the gradient by finite differences, steps grown after a success
/// and halved after a failure), from the nearest single ink: a fixed sequence of `f64`
/// operations, so the same result on every machine.
pub fn nearest_mix(inks: &[[f64; 3]], target: [f64; 3]) -> [f64; 3] {
    use crate::scielab::{ciede2000, lab_of_xyz, RGB_TO_XYZ};
    let lab = |c: [f64; 3]| lab_of_xyz(RGB_TO_XYZ.map(|row| dot(row, c.map(|v| v.max(0.0)))));
    let aim = lab(target);
    let cost = |c: [f64; 3]| {
        let d = ciede2000(lab(c), aim);
        d * d
    };
    let mix = |w: &[f64]| -> [f64; 3] {
        let mut c = [0.0; 3];
        for (k, &s) in w.iter().enumerate() {
            c = add_scaled(c, s, inks[k]);
        }
        c
    };
    let n = inks.len();
    if n == 0 {
        return target;
    }
    let first = (0..n)
        .min_by(|&a, &b| cost(inks[a]).total_cmp(&cost(inks[b])))
        .expect("an ink");
    let mut w = vec![0.0; n];
    w[first] = 1.0;
    let mut at = inks[first];
    let mut f = cost(at);
    let mut step = 0.25;
    const H: f64 = 1e-5;
    for _ in 0..60 {
        // The gradient in colour by central differences, then in the shares.
        let g: [f64; 3] = std::array::from_fn(|c| {
            let (mut hi, mut lo) = (at, at);
            hi[c] += H;
            lo[c] -= H;
            (cost(hi) - cost(lo)) / (2.0 * H)
        });
        let gw: Vec<f64> = inks.iter().map(|ink| dot(g, *ink)).collect();
        let mean = gw.iter().sum::<f64>() / n as f64;
        let len = gw
            .iter()
            .map(|v| (v - mean) * (v - mean))
            .sum::<f64>()
            .sqrt();
        if len < 1e-12 {
            break;
        }
        loop {
            let moved: Vec<f64> = w
                .iter()
                .zip(&gw)
                .map(|(s, v)| s - step * (v - mean) / len)
                .collect();
            let next = project_simplex(&moved);
            let c = mix(&next);
            let fc = cost(c);
            if fc < f - 1e-12 {
                (w, at, f) = (next, c, fc);
                step = (step * 1.5).min(1.0);
                break;
            }
            step *= 0.5;
            if step < 1e-5 {
                break;
            }
        }
        if step < 1e-5 {
            break;
        }
    }
    at
}

/// The point of the probability simplex nearest `v` (Euclidean): Duchi et al.'s sort.
fn project_simplex(v: &[f64]) -> Vec<f64> {
    let mut u = v.to_vec();
    u.sort_by(|a, b| b.total_cmp(a));
    let (mut sum, mut theta) = (0.0, 0.0);
    for (j, &x) in u.iter().enumerate() {
        sum += x;
        let t = (sum - 1.0) / (j + 1) as f64;
        if x - t > 0.0 {
            theta = t;
        }
    }
    v.iter().map(|x| (x - theta).max(0.0)).collect()
}

/// Hue bins of [`Cusps`] (2° each).
const HUE_BINS: usize = 180;

/// The inks' most chromatic colour at each hue, in Oklab relative to the panel (the *cusp*
/// of their gamut at that hue: its lightness and chroma), and the rule for the hues they
/// cannot make.
///
/// Found by sampling the hull's surface: every mix of two inks and of three (a grid of
/// 1/24 steps), whose convex combinations hold every face; each bin keeps its most
/// chromatic sample.
#[derive(Clone, Debug)]
pub struct Cusps {
    /// Per bin: lightness and chroma of the cusp (chroma 0: no sample of that hue).
    bins: Vec<(f64, f64)>,
    /// Chroma below which the inks are taken not to make a hue.
    floor: f64,
    /// Per bin: how many bins down and up the nearest bin of a hue the inks make is (0 for
    /// a made bin; `HUE_BINS` when they make none).
    made_down: Vec<usize>,
    made_up: Vec<usize>,
}

/// How far [`Cusps::nearest_hue`] may turn a hue the inks make (radians: 16°).
pub const SNAP: f64 = 16.0 * std::f64::consts::PI / 180.0;
/// What a radian of turn costs in [`Cusps::nearest_hue`], in Oklab chroma (0.004 a degree).
pub const SNAP_COST: f64 = 0.004 * 180.0 / std::f64::consts::PI;

/// Oklab chroma below which a colour counts as having no hue for [`Cusps`] and the hue rule.
pub const HUE_CHROMA: f64 = 0.04;

impl Cusps {
    /// The cusps of `inks` (linear RGB, adapted: see [`oklab`]).
    pub fn new(inks: &[[f64; 3]]) -> Cusps {
        let mut bins = vec![(0.0, 0.0); HUE_BINS];
        let mut put = |c: [f64; 3]| {
            let [l, a, b] = oklab(c);
            let ch = fm::hypot(a, b);
            if ch < 1e-6 {
                return;
            }
            let k = bin_of(fm::atan2(b, a));
            if ch > bins[k].1 {
                bins[k] = (l, ch);
            }
        };
        let n = inks.len();
        const STEPS: usize = 24;
        for i in 0..n {
            for j in i + 1..n {
                for t in 0..=4 * STEPS {
                    let u = t as f64 / (4 * STEPS) as f64;
                    put(std::array::from_fn(|c| {
                        inks[i][c] * (1.0 - u) + inks[j][c] * u
                    }));
                }
                for k in j + 1..n {
                    for p in 1..STEPS {
                        for q in 1..STEPS - p {
                            let (u, v) = (p as f64 / STEPS as f64, q as f64 / STEPS as f64);
                            put(std::array::from_fn(|c| {
                                inks[i][c] * (1.0 - u - v) + inks[j][c] * u + inks[k][c] * v
                            }));
                        }
                    }
                }
            }
        }
        let top = bins.iter().map(|b| b.1).fold(0.0, f64::max);
        // A hue the inks make at under a quarter of their best chroma (and under the
        // colourless floor) is one they lack.
        let floor = (0.25 * top).max(HUE_CHROMA);
        let nearest = |k: usize, s: isize| {
            (0..HUE_BINS)
                .find(|&d| {
                    bins[(k as isize + s * d as isize).rem_euclid(HUE_BINS as isize) as usize].1
                        >= floor
                })
                .unwrap_or(HUE_BINS)
        };
        let made_down = (0..HUE_BINS).map(|k| nearest(k, -1)).collect();
        let made_up = (0..HUE_BINS).map(|k| nearest(k, 1)).collect();
        Cusps {
            bins,
            floor,
            made_down,
            made_up,
        }
    }

    /// The cusp (lightness, chroma) at hue `h` (radians).
    pub fn at(&self, h: f64) -> (f64, f64) {
        self.bins[bin_of(h)]
    }

    /// The hue a colour of hue `h` (radians) and chroma `c` is rendered at, how far it is
    /// turned (radians) and the share of its chroma kept (1 when it is not turned); `None`
    /// when the inks make no hue at all (the colour then becomes a neutral).
    ///
    /// The rule: a hue the inks make is kept, unless a hue within [`SNAP`] of it holds
    /// more of the colour's chroma: each hue scores the chroma it can give (the smaller of
    /// the colour's and its cusp's) less [`SNAP_COST`] a radian of turn, and the best is
    /// taken (its chroma kept as the cosine of the turn). So a yellow a few degrees greener
    /// than the yellow ink is the yellow ink, not a dull mix of yellow and green; a colour
    /// the inks reach at its own hue stays there.
    ///
    /// A hue the inks lack (cusp chroma under a quarter of their best) goes to the nearest
    /// edge of the hues they make, its chroma faded as it goes: the share kept is
    /// `cos(π/2 · turn / reach)`, with `reach` the smaller of [`FADE`] and half the gap of
    /// lacked hues it lies in, and none beyond. The share falls continuously from 1 at the
    /// edge to 0 in the middle of the gap (where the nearest edge changes sides), so no hue
    /// of a smooth gradient is switched at a step: a purple on black, white, red and yellow
    /// inks fades through a dull red-purple to grey instead of turning grey at a contour.
    pub fn nearest_hue(&self, h: f64, c: f64) -> Option<(f64, f64, f64)> {
        let k = bin_of(h);
        let step = std::f64::consts::TAU / HUE_BINS as f64;
        let made = |j: usize| self.bins[j].1 >= self.floor;
        if made(k) {
            if c <= self.bins[k].1 {
                // No other hue can give more of the colour's chroma than its own.
                return Some((h, 0.0, 1.0));
            }
            let reach = (SNAP / step).round() as isize;
            let mut best = (c.min(self.bins[k].1), k, 0.0);
            for d in -reach..=reach {
                let j = (k as isize + d).rem_euclid(HUE_BINS as isize) as usize;
                let turn = d.unsigned_abs() as f64 * step;
                let score = c.min(self.bins[j].1) - SNAP_COST * turn;
                if score > best.0 + 1e-9 {
                    best = (score, j, turn);
                }
            }
            if best.1 == k {
                return Some((h, 0.0, 1.0));
            }
            let to = (best.1 as f64 + 0.5) * step - std::f64::consts::PI;
            return Some((to, best.2, fm::cos(best.2)));
        }
        // The nearest made bin each way, and the edge of the made hues it holds.
        let (down, up) = (self.made_down[k], self.made_up[k]);
        if down >= HUE_BINS || up >= HUE_BINS {
            return None;
        }
        let wrap = |a: f64| a.rem_euclid(std::f64::consts::TAU);
        let lo = |j: usize| j as f64 * step - std::f64::consts::PI;
        let jd = (k + HUE_BINS - down) % HUE_BINS;
        let ju = (k + up) % HUE_BINS;
        // Turns to the edges: down to the top of bin `jd`, up to the bottom of bin `ju`.
        let (td, tu) = (wrap(h - lo(jd + 1)), wrap(lo(ju) - h));
        let reach = FADE.min(0.5 * (td + tu));
        let (to, turn) = if td <= tu {
            (lo(jd + 1) - 1e-9, td)
        } else {
            (lo(ju) + 1e-9, tu)
        };
        let keep = fm::cos(std::f64::consts::FRAC_PI_2 * (turn / reach).min(1.0)).max(0.0);
        Some((to, turn, keep))
    }
}

/// How far (radians: 120°) a hue the inks lack may be turned towards one they make before
/// its chroma has faded to nothing (see [`Cusps::nearest_hue`]).
pub const FADE: f64 = 120.0 * std::f64::consts::PI / 180.0;

/// The bin of hue `h` (radians, any turn).
fn bin_of(h: f64) -> usize {
    let t = (h + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
    ((t * HUE_BINS as f64) as usize).min(HUE_BINS - 1)
}

/// What [`Hull::line`] found for one colour.
#[derive(Clone, Copy, Debug)]
pub struct Line {
    /// The neutral of the colour's luminance.
    pub anchor: [f64; 3],
    /// From the anchor to the colour (flattened onto a flat hull's plane).
    pub dir: [f64; 3],
    /// How far along `dir` the hull goes, and the face it leaves through.
    exit: (f64, Option<usize>),
    /// See [`Clipped::reach`].
    pub reach: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    const BWRY: [[f64; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 1.0],
        [0.45, 0.01, 0.0],
        [0.6, 0.5, 0.0],
    ];

    fn inside(h: &Hull, c: [f64; 3]) -> bool {
        h.faces.iter().all(|f| dot(f.n, c) <= f.d + 1e-9)
    }

    #[test]
    fn a_tetrahedron_has_four_faces_and_keeps_what_is_inside() {
        let h = Hull::new(&BWRY);
        assert_eq!(h.dim, 3);
        assert_eq!(h.faces.len(), 4);
        let c = [0.3, 0.2, 0.1];
        assert!(inside(&h, c));
        let k = h.clip(c);
        assert!(k.reach <= 1.0);
        assert!(sub(k.colour, c).iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn clipping_keeps_luminance_and_lands_in_the_hull() {
        let h = Hull::new(&BWRY);
        for c in [
            [0.05, 0.1, 0.6],
            [0.0, 0.8, 0.0],
            [0.9, 0.2, 0.6],
            [0.2, 0.2, 0.2],
        ] {
            let k = h.clip(c);
            assert!(inside(&h, k.colour), "{c:?} → {:?}", k.colour);
            assert!((dot(LUMA, k.colour) - dot(LUMA, c)).abs() < 1e-9);
        }
        // Blue on BWRY: no blue in the inks, so the neutral of its luminance.
        let blue = [0.02, 0.05, 0.7];
        let k = h.clip(blue);
        assert!(sub(k.colour, k.anchor).iter().all(|v| v.abs() < 1e-6));
        assert!(k.reach.is_infinite());
    }

    #[test]
    fn a_flat_hull_keeps_the_hue_it_has() {
        // Black, white and red lie in one plane: orange goes towards red, cyan to grey.
        let inks = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.45, 0.01, 0.0]];
        let h = Hull::new(&inks);
        assert_eq!(h.dim, 2);
        let orange = h.clip([0.6, 0.2, 0.0]);
        assert!(orange.colour[0] > orange.colour[1] + 0.05, "{orange:?}");
        let cyan = h.clip([0.0, 0.3, 0.3]);
        assert!(cyan.colour[1] >= cyan.colour[0] - 1e-9, "{cyan:?}");
    }

    #[test]
    fn greys_are_a_segment() {
        let h = Hull::new(&[[0.0; 3], [0.2; 3], [1.0; 3]]);
        assert_eq!(h.dim, 1);
        let k = h.clip([0.5, 0.1, 0.1]);
        let y = dot(LUMA, [0.5, 0.1, 0.1]);
        assert!(k.colour.iter().all(|v| (v - y).abs() < 1e-12));
    }
}
