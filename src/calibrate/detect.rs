//! Finding the chart in a photo: the photo in linear light, the markers, the homography,
//! and the paper beside the chart.

use super::*;

/// A photo's pixels in linear light.
pub(super) struct Photo<'a> {
    pub(super) img: &'a Image,
    pub(super) lut: Vec<f32>,
    pub(super) w: usize,
    pub(super) h: usize,
}

impl<'a> Photo<'a> {
    pub(super) fn new(img: &'a Image) -> Photo<'a> {
        Photo {
            img,
            lut: img.tone_table(&ToneOptions::default()).as_slice().to_vec(),
            w: img.width,
            h: img.height,
        }
    }

    #[inline]
    pub(super) fn at(&self, c: usize, i: usize) -> f32 {
        let p = &self.img.planes[c.min(self.img.planes.len() - 1)];
        match p {
            Samples::U8(v) => self.lut[v[i] as usize],
            Samples::U16(v) => self.lut[v[i] as usize],
        }
    }

    /// Bilinear sample at continuous coordinates (pixel `x` spans `x..x + 1`), clamped to
    /// the edges.
    pub(super) fn sample(&self, u: f64, v: f64) -> [f64; 3] {
        let fx = (u - 0.5).clamp(0.0, (self.w - 1) as f64);
        let fy = (v - 0.5).clamp(0.0, (self.h - 1) as f64);
        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.w - 1), (y0 + 1).min(self.h - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        [0, 1, 2].map(|c| {
            let p = |x: usize, y: usize| self.at(c, y * self.w + x) as f64;
            let top = p(x0, y0) * (1.0 - tx) + p(x1, y0) * tx;
            let bottom = p(x0, y1) * (1.0 - tx) + p(x1, y1) * tx;
            top * (1.0 - ty) + bottom * ty
        })
    }
}

pub(super) fn lum(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The photo box-averaged to at most 1000 pixels a side: luminance and the brightest
/// channel of each cell.
pub(super) struct Grid {
    pub(super) w: usize,
    pub(super) h: usize,
    /// Photo pixels a grid cell, each way.
    pub(super) ds: usize,
    pub(super) lum: Vec<f32>,
    pub(super) maxc: Vec<f32>,
}

impl Grid {
    pub(super) fn new(p: &Photo) -> Grid {
        let ds = p.w.max(p.h).div_ceil(1000).max(1);
        let (w, h) = (p.w.div_ceil(ds), p.h.div_ceil(ds));
        let mut lum = vec![0f32; w * h];
        let mut maxc = vec![0f32; w * h];
        for gy in 0..h {
            for gx in 0..w {
                let mut s = [0f64; 3];
                let mut n = 0.0;
                for y in gy * ds..((gy + 1) * ds).min(p.h) {
                    for x in gx * ds..((gx + 1) * ds).min(p.w) {
                        for (c, sc) in s.iter_mut().enumerate() {
                            *sc += p.at(c, y * p.w + x) as f64;
                        }
                        n += 1.0;
                    }
                }
                let m = s.map(|v| v / n);
                lum[gy * w + gx] = self::lum(m) as f32;
                maxc[gy * w + gx] = m[0].max(m[1]).max(m[2]) as f32;
            }
        }
        Grid {
            w,
            h,
            ds,
            lum,
            maxc,
        }
    }
}

/// A 3×3 projective map, row-major, `m[8]` = 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homography(pub [f64; 9]);

impl Homography {
    /// The map taking each `from[i]` to `to[i]`; `None` when three points are in a line.
    pub fn from_points(from: &[[f64; 2]; 4], to: &[[f64; 2]; 4]) -> Option<Homography> {
        let mut a = vec![vec![0.0; 9]; 8];
        for i in 0..4 {
            let ([x, y], [u, v]) = (from[i], to[i]);
            a[2 * i] = vec![x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, u];
            a[2 * i + 1] = vec![0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, v];
        }
        let h = solve(a)?;
        Some(Homography([
            h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0,
        ]))
    }

    /// Maps a point.
    pub fn apply(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        let m = &self.0;
        let w = m[6] * x + m[7] * y + m[8];
        [
            (m[0] * x + m[1] * y + m[2]) / w,
            (m[3] * x + m[4] * y + m[5]) / w,
        ]
    }

    /// The inverse map; `None` when singular.
    pub fn inverse(&self) -> Option<Homography> {
        let m = &self.0;
        let c = [
            m[4] * m[8] - m[5] * m[7],
            m[2] * m[7] - m[1] * m[8],
            m[1] * m[5] - m[2] * m[4],
            m[5] * m[6] - m[3] * m[8],
            m[0] * m[8] - m[2] * m[6],
            m[2] * m[3] - m[0] * m[5],
            m[3] * m[7] - m[4] * m[6],
            m[1] * m[6] - m[0] * m[7],
            m[0] * m[4] - m[1] * m[3],
        ];
        let det = m[0] * c[0] + m[1] * c[3] + m[2] * c[6];
        if det.abs() < 1e-300 || c[8].abs() < 1e-300 {
            return None;
        }
        Some(Homography(c.map(|v| v / c[8])))
    }
}

/// Solves the augmented system `a` (n rows of n + 1) by Gaussian elimination with partial
/// pivoting; `None` when singular.
pub(super) fn solve(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let n = a.len();
    for col in 0..n {
        let p = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[p][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, p);
        let (top, below) = a.split_at_mut(col + 1);
        let pivot = &top[col];
        for row in below {
            let f = row[col] / pivot[col];
            if f != 0.0 {
                for (x, p) in row[col..].iter_mut().zip(&pivot[col..]) {
                    *x -= f * p;
                }
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (a[r][n] - s) / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// A marker candidate: a dark region around one light one.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ring {
    /// Centre of the filled square, photo pixels.
    pub(super) centre: [f64; 2],
    /// Area of the filled square, photo pixels.
    pub(super) area: f64,
    /// The light centre's share of the area.
    pub(super) hole: f64,
}

pub(super) const NONE: u32 = u32::MAX;

/// Connected components of the pixels where `mask == want`; 8- or 4-connected.
pub(super) fn components(
    mask: &[bool],
    w: usize,
    h: usize,
    want: bool,
    eight: bool,
) -> (Vec<u32>, usize) {
    let mut label = vec![NONE; w * h];
    let mut n = 0u32;
    let mut stack = Vec::new();
    for start in 0..w * h {
        if mask[start] != want || label[start] != NONE {
            continue;
        }
        label[start] = n;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    if (dx == 0 && dy == 0) || (!eight && dx != 0 && dy != 0) {
                        continue;
                    }
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if mask[j] == want && label[j] == NONE {
                        label[j] = n;
                        stack.push(j);
                    }
                }
            }
        }
        n += 1;
    }
    (label, n as usize)
}

/// The marker candidates of the grid.
pub(super) fn rings(g: &Grid) -> Vec<Ring> {
    let (w, h) = (g.w, g.h);
    // Local mean through an integral image.
    let r = (w.max(h) / 12).max(4);
    let mut integral = vec![0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += g.lum[y * w + x] as f64;
            integral[(y + 1) * (w + 1) + x + 1] = integral[y * (w + 1) + x + 1] + row;
        }
    }
    let mut dark = vec![false; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let s = integral[y1 * (w + 1) + x1]
                - integral[y0 * (w + 1) + x1]
                - integral[y1 * (w + 1) + x0]
                + integral[y0 * (w + 1) + x0];
            let mean = s / ((x1 - x0) * (y1 - y0)) as f64;
            dark[y * w + x] = (g.lum[y * w + x] as f64) < 0.45 * mean;
        }
    }
    let (dl, nd) = components(&dark, w, h, true, true);
    let (ll, nl) = components(&dark, w, h, false, false);
    const MULTI: u32 = u32::MAX - 1;
    let mut around = vec![NONE; nl];
    let mut touches = vec![false; nl];
    #[derive(Clone, Copy, Default)]
    struct Stat {
        n: f64,
        sx: f64,
        sy: f64,
        x0: usize,
        x1: usize,
        y0: usize,
        y1: usize,
    }
    let mut ds = vec![
        Stat {
            x0: usize::MAX,
            y0: usize::MAX,
            ..Stat::default()
        };
        nd
    ];
    let mut ls = vec![Stat::default(); nl];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if dark[i] {
                let s = &mut ds[dl[i] as usize];
                s.n += 1.0;
                s.sx += x as f64 + 0.5;
                s.sy += y as f64 + 0.5;
                s.x0 = s.x0.min(x);
                s.x1 = s.x1.max(x);
                s.y0 = s.y0.min(y);
                s.y1 = s.y1.max(y);
                continue;
            }
            let l = ll[i] as usize;
            let s = &mut ls[l];
            s.n += 1.0;
            s.sx += x as f64 + 0.5;
            s.sy += y as f64 + 0.5;
            if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
                touches[l] = true;
            }
            for j in [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ]
            .into_iter()
            .flatten()
            {
                if dark[j] {
                    let d = dl[j];
                    around[l] = match around[l] {
                        NONE => d,
                        a if a == d => a,
                        _ => MULTI,
                    };
                }
            }
        }
    }
    let mut holes = vec![(0usize, 0usize); nd];
    for l in 0..nl {
        if !touches[l] && around[l] != NONE && around[l] != MULTI {
            let e = &mut holes[around[l] as usize];
            e.0 += 1;
            e.1 = l;
        }
    }
    let k = g.ds as f64;
    let mut out = Vec::new();
    for (d, s) in ds.iter().enumerate() {
        let (count, l) = holes[d];
        if count != 1 {
            continue;
        }
        let hs = &ls[l];
        let area = s.n + hs.n;
        let (bw, bh) = ((s.x1 - s.x0 + 1) as f64, (s.y1 - s.y0 + 1) as f64);
        if area < 24.0 || bw < 4.0 || bh < 4.0 || bw > 3.0 * bh || bh > 3.0 * bw {
            continue;
        }
        let hole = hs.n / area;
        if area < 0.45 * bw * bh || !(0.03..=0.6).contains(&hole) {
            continue;
        }
        let centre = [(s.sx + hs.sx) / area, (s.sy + hs.sy) / area];
        let hc = [hs.sx / hs.n, hs.sy / hs.n];
        if (hc[0] - centre[0]).hypot(hc[1] - centre[1]) > 0.2 * area.sqrt() {
            continue;
        }
        out.push(Ring {
            centre: centre.map(|v| v * k),
            area: area * k * k,
            hole,
        });
    }
    out.sort_by(|a, b| b.area.total_cmp(&a.area));
    out.truncate(16);
    out
}

pub(super) fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// The four markers of the chart among the candidates, ordered top-left, top-right,
/// bottom-right, bottom-left, with the homography from the chart to the photo.
pub(super) fn find_chart(cands: &[Ring], layout: &Layout) -> Option<([[f64; 2]; 4], Homography)> {
    let targets = layout.marker_centres();
    let f = layout.marker as f64;
    let n = cands.len();
    let mut best: Option<(f64, [[f64; 2]; 4], Homography)> = None;
    for a in 0..n {
        for b in a + 1..n {
            for c in b + 1..n {
                for d in c + 1..n {
                    let q = [cands[a], cands[b], cands[c], cands[d]];
                    let (lo, hi) = q.iter().fold((f64::MAX, 0f64), |(lo, hi), r| {
                        (lo.min(r.area), hi.max(r.area))
                    });
                    if hi > 3.0 * lo {
                        continue;
                    }
                    // Exactly one large centre: the top-left marker.
                    let mut by_hole = q;
                    by_hole.sort_by(|x, y| y.hole.total_cmp(&x.hole));
                    if by_hole[0].hole < 1.5 * by_hole[1].hole {
                        continue;
                    }
                    let tl = by_hole[0].centre;
                    let cx = q.iter().map(|r| r.centre[0]).sum::<f64>() / 4.0;
                    let cy = q.iter().map(|r| r.centre[1]).sum::<f64>() / 4.0;
                    let angle = |r: &Ring| (r.centre[1] - cy).atan2(r.centre[0] - cx);
                    let mut ord = q;
                    ord.sort_by(|x, y| angle(x).total_cmp(&angle(y)));
                    let start = ord.iter().position(|r| r.centre == tl)?;
                    ord.rotate_left(start);
                    let pts = ord.map(|r| r.centre);
                    let convex = (0..4).all(|i| {
                        let (p0, p1, p2) = (pts[i], pts[(i + 1) % 4], pts[(i + 2) % 4]);
                        (p1[0] - p0[0]) * (p2[1] - p1[1]) - (p1[1] - p0[1]) * (p2[0] - p1[0]) > 0.0
                    });
                    if !convex {
                        continue;
                    }
                    let Some(hm) = Homography::from_points(&targets, &pts) else {
                        continue;
                    };
                    let sizes_fit = (0..4).all(|i| {
                        let [x, y] = layout.marker_corners()[i].map(|v| v as f64);
                        let sq =
                            [[x, y], [x + f, y], [x + f, y + f], [x, y + f]].map(|p| hm.apply(p));
                        let r = polygon_area(&sq) / ord[i].area;
                        (0.4..=2.5).contains(&r)
                    });
                    if !sizes_fit {
                        continue;
                    }
                    let area = polygon_area(&pts);
                    if best.as_ref().is_none_or(|(b, ..)| area > *b) {
                        best = Some((area, pts, hm));
                    }
                }
            }
        }
    }
    best.map(|(_, p, h)| (p, h))
}

pub(super) fn rect_text(r: [f64; 4]) -> String {
    format!("{:.0},{:.0},{:.0},{:.0}", r[0], r[1], r[2], r[3])
}

/// Sample points in a given paper rectangle (its middle 80%).
pub(super) fn paper_given(rect: [f64; 4], p: &Photo) -> Result<(Vec<[f64; 2]>, [f64; 4])> {
    let [x, y, w, h] = rect;
    if !(rect.iter().all(|v| v.is_finite())
        && x >= 0.0
        && y >= 0.0
        && w >= 4.0
        && h >= 4.0
        && x + w <= p.w as f64
        && y + h <= p.h as f64)
    {
        return Err(Error::Invalid(format!(
            "`paper` {}: must be a rectangle of at least 4x4 pixels inside the photo ({}x{})",
            rect_text(rect),
            p.w,
            p.h
        )));
    }
    let mut pts = Vec::with_capacity(32 * 32);
    for j in 0..32 {
        for i in 0..32 {
            pts.push([
                x + w * (0.1 + 0.8 * (i as f64 + 0.5) / 32.0),
                y + h * (0.1 + 0.8 * (j as f64 + 0.5) / 32.0),
            ]);
        }
    }
    Ok((pts, rect))
}

/// The paper: the brightest large even region outside the chart (the module's rule).
pub(super) fn paper_found(
    g: &Grid,
    inv: &Homography,
    cw: f64,
    ch: f64,
) -> Result<(Vec<[f64; 2]>, [f64; 4])> {
    let bs = (g.w.max(g.h) / 48).max(2);
    let (bw, bh) = (g.w / bs, g.h / bs);
    let k = g.ds as f64;
    let pad = 0.12 * cw.max(ch);
    #[derive(Clone, Copy)]
    struct Block {
        mean: f64,
        even: bool,
        clipped: bool,
        outside: bool,
    }
    let mut blocks = Vec::with_capacity(bw * bh);
    for by in 0..bh {
        for bx in 0..bw {
            let (mut s, mut s2, mut clip) = (0.0, 0.0, false);
            for y in by * bs..(by + 1) * bs {
                for x in bx * bs..(bx + 1) * bs {
                    let v = g.lum[y * g.w + x] as f64;
                    s += v;
                    s2 += v * v;
                    clip |= g.maxc[y * g.w + x] >= 0.985;
                }
            }
            let n = (bs * bs) as f64;
            let mean = s / n;
            let sd = (s2 / n - mean * mean).max(0.0).sqrt();
            let centre = [
                (bx as f64 + 0.5) * bs as f64 * k,
                (by as f64 + 0.5) * bs as f64 * k,
            ];
            let c = inv.apply(centre);
            let outside = !(c[0] > -pad && c[0] < cw + pad && c[1] > -pad && c[1] < ch + pad);
            blocks.push(Block {
                mean,
                even: mean > 0.0 && sd < 0.08 * mean,
                clipped: clip,
                outside,
            });
        }
    }
    let min_blocks = (bw * bh / 100).max(8);
    let usable = |b: &Block| b.even && b.outside && !b.clipped;
    let mut order: Vec<usize> = (0..blocks.len()).filter(|&i| usable(&blocks[i])).collect();
    order.sort_by(|&a, &b| blocks[b].mean.total_cmp(&blocks[a].mean).then(a.cmp(&b)));
    let mut seen = vec![false; blocks.len()];
    for &seed in &order {
        if seen[seed] {
            continue;
        }
        let lo = blocks[seed].mean / 1.67;
        let mut region = vec![seed];
        seen[seed] = true;
        let mut i = 0;
        while i < region.len() {
            let b = region[i];
            i += 1;
            let (x, y) = (b % bw, b / bw);
            for (nx, ny) in [
                (x.wrapping_sub(1), y),
                (x + 1, y),
                (x, y.wrapping_sub(1)),
                (x, y + 1),
            ] {
                if nx >= bw || ny >= bh {
                    continue;
                }
                let j = ny * bw + nx;
                let near = (blocks[j].mean / blocks[b].mean - 1.0).abs() < 0.12;
                if !seen[j] && usable(&blocks[j]) && near && blocks[j].mean >= lo {
                    seen[j] = true;
                    region.push(j);
                }
            }
        }
        if region.len() < min_blocks {
            continue;
        }
        // Its inner blocks (all four neighbours in it), when there are enough.
        let inside: std::collections::HashSet<usize> = region.iter().copied().collect();
        let inner: Vec<usize> = region
            .iter()
            .copied()
            .filter(|&b| {
                let (x, y) = (b % bw, b / bw);
                x > 0
                    && y > 0
                    && inside.contains(&(b - 1))
                    && inside.contains(&(b + 1))
                    && inside.contains(&(b - bw))
                    && inside.contains(&(b + bw))
            })
            .collect();
        let use_blocks = if inner.len() >= 4 {
            inner
        } else {
            region.clone()
        };
        let side = bs as f64 * k;
        let mut pts = Vec::new();
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, 0f64, 0f64);
        for &b in &region {
            let (x, y) = ((b % bw) as f64 * side, (b / bw) as f64 * side);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x + side);
            y1 = y1.max(y + side);
        }
        for &b in &use_blocks {
            let (x, y) = ((b % bw) as f64 * side, (b / bw) as f64 * side);
            for j in 0..3 {
                for i in 0..3 {
                    pts.push([
                        x + side * (i as f64 + 0.5) / 3.0,
                        y + side * (j as f64 + 0.5) / 3.0,
                    ]);
                }
            }
        }
        return Ok((pts, [x0, y0, x1 - x0, y1 - y0]));
    }
    let clipped = blocks.iter().filter(|b| b.clipped && b.outside).count();
    let why = if clipped >= min_blocks {
        "the bright regions outside the chart are clipped (overexposed); photograph with less exposure"
    } else {
        "put a sheet of white paper beside the panel (at least 1% of the photo), or give `paper`"
    };
    Err(Error::Invalid(format!(
        "paper not found: no bright, even region outside the chart; {why}"
    )))
}
