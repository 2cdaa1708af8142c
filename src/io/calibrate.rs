//! Calibrating a panel from a photograph: a patch chart to show on the panel, and the
//! measurement of its inks from a photo of the panel beside a sheet of white paper.
//!
//! **The chart** ([`chart`], [`Layout`]) is drawn in the frame the viewer sees (the panel's
//! `width × height`, swapped for a `rotation` of 90 or 270) and turned into the panel's
//! scan order as pictures are. In the viewer's frame, with `s` the shorter side:
//!
//! - a white border of `margin` = max(3, 0.035 s) pixels, in the lightest ink;
//! - four corner **markers**, squares of side `marker` = max(12, 0.2 s) in the darkest ink,
//!   inset by the margin, each with a white square at its centre: 0.3 of the side for
//!   the top-right, bottom-right and bottom-left markers, 0.56 of it for the **top-left**
//!   one, which tells the chart's orientation in a photo;
//! - between the two marker columns (a `gap` = max(2, 0.025 s) from them) a grid of
//!   `cols × rows` patches with white gutters of `gap`: cell `i` (row-major, row `r`) holds
//!   ink `i mod n` (`(i + r) mod n` when `cols` is a multiple of `n`, so that an ink's
//!   patches do not stack in a column), so every ink has 4 patches (3, 2 or 1 on small panels), spread
//!   over the chart. The grid is the one of the most patches per ink (4 down to 1) whose
//!   patches are at least max(8, 0.1 s) pixels on their shorter side.
//!
//! **The measurement** ([`calibrate`]) works in linear light (the photo's tone table):
//!
//! 1. *Markers*: on a grid of at most 1000 pixels a side (box-averaged), a pixel is dark
//!    below 0.45 × the mean luminance around it (a window of a sixth of the grid's larger
//!    side). Dark regions (8-connected) that enclose exactly one light region (4-connected)
//!    are marker candidates when squarish; of every four candidates of similar size (within
//!    3×) with exactly one large centre, in convex order, whose sizes the homography through
//!    them predicts within 2.5×, the widest quadrilateral is the chart.
//! 2. *Homography*: the four marker centres (centroids of the filled squares) against their
//!    places on the chart give the chart-to-photo mapping (perspective).
//! 3. *Paper*: given as a rectangle (`paper`), or found as the brightest large, even region
//!    outside the chart: blocks of 1/48 of the grid's larger side, even where the luminance
//!    varies by less than 8% (standard deviation over mean) and nothing is clipped, outside
//!    the chart widened by 12%; grown from the brightest block through neighbours within 12%
//!    of each other; the first such region, in order of brightness, of at least 1% of the
//!    blocks (and 8) is the paper.
//! 4. *Vignetting*: the logarithm of luminance on the chart's white (border, gutters, white
//!    patches, away from any edge) and on the paper is fitted by one smooth field, a
//!    quadratic in x and y, with one offset for the panel's white and one for the paper
//!    (least squares, samples off by more than 4 MADs dropped once); every sample is divided
//!    by the field before it is used.
//! 5. *Patches*: the middle half (each way) of every patch is sampled on a grid of up to
//!    24 × 24 points (bilinear), each channel averaged with the highest and lowest 20%
//!    dropped; an ink is the mean of its patches. A patch whose middle varies too much, or
//!    patches of one ink that disagree, are an error (blur, glare, a misread chart).
//! 6. *Normalising*: each channel of each ink is divided by the paper's (the same
//!    trimmed mean over the paper), times `paper_reflectance`: the paper is the viewer's
//!    white, sRGB white by default (the method of the epaper-dithering package's
//!    measurements). The camera's white balance and exposure cancel; its primaries are
//!    taken to be sRGB's.
//!
//! [`synthetic_photo`] renders the chart into a photograph with a known colour cast,
//! exposure, vignetting, noise, tilt and blur, for tests and demonstrations.

use super::device::{Device, Ink, Measured, Measurement};
use crate::error::{Error, Result};
use crate::raster::{Halftone, Image, Samples};
use crate::tone::{linear_to_srgb8, ToneOptions};

/// One patch of the chart, in the viewer's frame (pixels, `x` right, `y` down).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Patch {
    /// The ink's index in the device.
    pub ink: usize,
    /// Left column.
    pub x: usize,
    /// Top row.
    pub y: usize,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

/// Where everything is on a device's chart, in the viewer's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// Width of the viewer's frame (the panel's width, or its height when turned 90 or 270).
    pub width: usize,
    /// Height of the viewer's frame.
    pub height: usize,
    /// The white border, in pixels.
    pub margin: usize,
    /// The side of a corner marker.
    pub marker: usize,
    /// The white gap between the markers and the patches, and between patches.
    pub gap: usize,
    /// Columns of the patch grid.
    pub cols: usize,
    /// Rows of the patch grid.
    pub rows: usize,
    /// The index of the lightest ink (the border and gutters).
    pub white: usize,
    /// The index of the darkest ink (the markers).
    pub black: usize,
    /// The quarter turns clockwise from the viewer's frame to the panel's scan order.
    pub turns: u8,
    /// The patches, row-major.
    pub patches: Vec<Patch>,
}

/// Side of a marker's white centre: a third of the marker, 0.56 of it for the top-left one
/// (`big`), with the parity of the marker so that it sits in the middle.
fn hole_side(marker: usize, big: bool) -> usize {
    let h = (marker as f64 * if big { 0.56 } else { 0.3 }).round() as usize;
    if (marker - h) % 2 == 1 {
        h + 1
    } else {
        h
    }
}

/// Relative luminance of an 8-bit sRGB colour (linear light).
fn luminance8(c: [u8; 3]) -> f64 {
    let l = c.map(|v| crate::tone::srgb_to_linear(v as f64 / 255.0));
    0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2]
}

impl Layout {
    /// The chart's layout for `device` (see the module's documentation for the rules).
    pub fn new(device: &Device) -> Result<Layout> {
        let turns = device.quarter_turns();
        let (width, height) = if turns % 2 == 1 {
            (device.height, device.width)
        } else {
            (device.width, device.height)
        };
        let n = device.inks.len();
        let lum: Vec<f64> = device.inks.iter().map(|i| luminance8(i.nominal)).collect();
        let by = |better: fn(f64, f64) -> bool| {
            (0..n).fold(0, |b, i| if better(lum[i], lum[b]) { i } else { b })
        };
        let white = by(|a, b| a > b);
        let black = by(|a, b| a < b);
        let s = width.min(height) as f64;
        let margin = (0.035 * s).round().max(3.0) as usize;
        let marker = (0.2 * s).round().max(12.0) as usize;
        let gap = (0.025 * s).round().max(2.0) as usize;
        let side = margin + marker + gap;
        let too_small = || {
            Error::Invalid(format!(
                "device '{}': a panel of {width}x{height} is too small for a calibration chart of {n} inks",
                device.name
            ))
        };
        if width < 2 * side + 8 || height < 2 * marker + 2 * margin + gap {
            return Err(too_small());
        }
        let (x0, x1) = (side, width - side);
        let (y0, y1) = (margin, height - margin);
        let (rw, rh) = (x1 - x0, y1 - y0);
        let min_side = (0.1 * s).round().max(8.0) as usize;
        let mut best = None;
        for k in [4usize, 3, 2, 1] {
            let cells = n * k;
            let mut pick: Option<(usize, usize, usize)> = None;
            for cols in 1..=cells {
                let rows = cells.div_ceil(cols);
                let cw = ((rw + gap) / cols).saturating_sub(gap);
                let ch = ((rh + gap) / rows).saturating_sub(gap);
                let m = cw.min(ch);
                if pick.is_none_or(|(pm, ..)| m > pm) {
                    pick = Some((m, cols, rows));
                }
            }
            let (m, cols, rows) = pick.expect("at least one column");
            if m >= min_side || (k == 1 && m >= 6) {
                best = Some((cols, rows));
                break;
            }
        }
        let (cols, rows) = best.ok_or_else(too_small)?;
        let mut patches = Vec::with_capacity(cols * rows);
        for r in 0..rows {
            let top = y0 + r * (rh + gap) / rows;
            let bottom = y0 + (r + 1) * (rh + gap) / rows - gap;
            for c in 0..cols {
                let left = x0 + c * (rw + gap) / cols;
                let right = x0 + (c + 1) * (rw + gap) / cols - gap;
                patches.push(Patch {
                    ink: if cols % n == 0 {
                        (r * cols + c + r) % n
                    } else {
                        (r * cols + c) % n
                    },
                    x: left,
                    y: top,
                    width: right - left,
                    height: bottom - top,
                });
            }
        }
        Ok(Layout {
            width,
            height,
            margin,
            marker,
            gap,
            cols,
            rows,
            white,
            black,
            turns,
            patches,
        })
    }

    /// The top-left corners of the four markers: top-left, top-right, bottom-right,
    /// bottom-left.
    pub fn marker_corners(&self) -> [[usize; 2]; 4] {
        let (m, f) = (self.margin, self.marker);
        let (r, b) = (self.width - m - f, self.height - m - f);
        [[m, m], [r, m], [r, b], [m, b]]
    }

    /// The centres of the four markers (top-left, top-right, bottom-right, bottom-left), in
    /// continuous coordinates (a pixel `x` spans `x..x + 1`).
    pub fn marker_centres(&self) -> [[f64; 2]; 4] {
        let h = self.marker as f64 / 2.0;
        self.marker_corners()
            .map(|[x, y]| [x as f64 + h, y as f64 + h])
    }

    /// The ink index of every pixel of the viewer's frame, row-major.
    pub fn indices(&self) -> Vec<u8> {
        let (w, h) = (self.width, self.height);
        let mut out = vec![self.white as u8; w * h];
        let mut fill = |x0: usize, y0: usize, fw: usize, fh: usize, ink: usize| {
            for y in y0..y0 + fh {
                out[y * w + x0..y * w + x0 + fw].fill(ink as u8);
            }
        };
        for (i, [x, y]) in self.marker_corners().into_iter().enumerate() {
            fill(x, y, self.marker, self.marker, self.black);
            let hs = hole_side(self.marker, i == 0);
            let o = (self.marker - hs) / 2;
            fill(x + o, y + o, hs, hs, self.white);
        }
        for p in &self.patches {
            fill(p.x, p.y, p.width, p.height, p.ink);
        }
        out
    }
}

/// The calibration chart of `device`: a palette halftone of the panel's size in its scan
/// order (the chart turned by the device's `rotation`), one index an ink in the device's
/// order, with the inks' nominal colours as its palette (what the driver expects).
pub fn chart(device: &Device) -> Result<Halftone> {
    let layout = Layout::new(device)?;
    let idx = layout.indices();
    let (vw, vh) = (layout.width, layout.height);
    let (pw, ph) = (device.width, device.height);
    let mut h = Halftone::new(pw, ph, 1, device.inks.len() as u16);
    for y in 0..ph {
        for x in 0..pw {
            // The viewer's pixel that a clockwise turn brings to (x, y).
            let (sx, sy) = match layout.turns {
                1 => (y, vh - 1 - x),
                2 => (vw - 1 - x, vh - 1 - y),
                3 => (vw - 1 - y, x),
                _ => (x, y),
            };
            h.set(0, x, y, idx[sy * vw + sx]);
        }
    }
    h.palette = Some(device.nominal_colours());
    Ok(h)
}

/// How [`calibrate`] reads a photo.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrateOptions {
    /// The paper as a rectangle of the photo: left, top, width, height in pixels; `None`:
    /// found (the brightest large even region outside the chart).
    pub paper: Option<[f64; 4]>,
    /// What the paper is taken to be, as a fraction of sRGB white (1: the paper is the
    /// viewer's white, as the epaper-dithering measurements take it).
    pub paper_reflectance: f64,
    /// Correct vignetting and uneven light with a smooth field fitted to the chart's white
    /// and the paper.
    pub vignetting: bool,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            paper: None,
            paper_reflectance: 1.0,
            vignetting: true,
        }
    }
}

/// One ink as measured.
#[derive(Clone, Debug, PartialEq)]
pub struct InkReading {
    /// The ink's name.
    pub name: String,
    /// Linear-light sRGB relative to the viewer's white (the paper times its reflectance).
    pub linear: [f64; 3],
    /// The same as 8-bit sRGB (clipped to the gamut): what the profile's `measured` gets.
    pub srgb: [u8; 3],
    /// How many patches were averaged.
    pub patches: usize,
    /// The largest difference of one patch's luminance from the ink's median, as a
    /// fraction of the paper's.
    pub spread: f64,
}

/// What [`calibrate`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Every ink, in the device's order.
    pub inks: Vec<InkReading>,
    /// The marker centres in the photo (pixels): top-left, top-right, bottom-right,
    /// bottom-left of the chart.
    pub markers: [[f64; 2]; 4],
    /// The paper's rectangle in the photo: left, top, width, height (its bounding box when
    /// found).
    pub paper: [f64; 4],
    /// The lowest and highest of the fitted brightness field over the chart, relative to its
    /// highest there (1, 1 without vignetting correction).
    pub field: [f64; 2],
}

/// A photo's pixels in linear light.
struct Photo<'a> {
    img: &'a Image,
    lut: Vec<f32>,
    w: usize,
    h: usize,
}

impl<'a> Photo<'a> {
    fn new(img: &'a Image) -> Photo<'a> {
        Photo {
            img,
            lut: img.tone_table(&ToneOptions::default()).as_slice().to_vec(),
            w: img.width,
            h: img.height,
        }
    }

    #[inline]
    fn at(&self, c: usize, i: usize) -> f32 {
        let p = &self.img.planes[c.min(self.img.planes.len() - 1)];
        match p {
            Samples::U8(v) => self.lut[v[i] as usize],
            Samples::U16(v) => self.lut[v[i] as usize],
        }
    }

    /// Bilinear sample at continuous coordinates (pixel `x` spans `x..x + 1`), clamped to
    /// the edges.
    fn sample(&self, u: f64, v: f64) -> [f64; 3] {
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

fn lum(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The photo box-averaged to at most 1000 pixels a side: luminance and the brightest
/// channel of each cell.
struct Grid {
    w: usize,
    h: usize,
    /// Photo pixels a grid cell, each way.
    ds: usize,
    lum: Vec<f32>,
    maxc: Vec<f32>,
}

impl Grid {
    fn new(p: &Photo) -> Grid {
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
fn solve(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
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
struct Ring {
    /// Centre of the filled square, photo pixels.
    centre: [f64; 2],
    /// Area of the filled square, photo pixels.
    area: f64,
    /// The light centre's share of the area.
    hole: f64,
}

const NONE: u32 = u32::MAX;

/// Connected components of the pixels where `mask == want`; 8- or 4-connected.
fn components(mask: &[bool], w: usize, h: usize, want: bool, eight: bool) -> (Vec<u32>, usize) {
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
fn rings(g: &Grid) -> Vec<Ring> {
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

fn polygon_area(p: &[[f64; 2]]) -> f64 {
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
fn find_chart(cands: &[Ring], layout: &Layout) -> Option<([[f64; 2]; 4], Homography)> {
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

/// The mean of the middle 60% of `v` (sorted in place).
fn trimmed_mean(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let cut = v.len() / 5;
    let mid = &v[cut..v.len() - cut];
    mid.iter().sum::<f64>() / mid.len() as f64
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The brightness field: `exp` of a quadratic in the photo's normalised coordinates.
struct Field {
    coef: [f64; 5],
    centre: [f64; 2],
    scale: f64,
}

impl Field {
    fn flat() -> Field {
        Field {
            coef: [0.0; 5],
            centre: [0.0; 2],
            scale: 1.0,
        }
    }

    fn terms(&self, [u, v]: [f64; 2]) -> [f64; 5] {
        let x = (u - self.centre[0]) / self.scale;
        let y = (v - self.centre[1]) / self.scale;
        [x, y, x * x, x * y, y * y]
    }

    fn at(&self, p: [f64; 2]) -> f64 {
        let t = self.terms(p);
        (0..5).map(|i| self.coef[i] * t[i]).sum::<f64>().exp()
    }

    /// Fits log luminance of `white` (the panel's) and `paper` samples: one offset each, a
    /// shared quadratic; samples off by more than 4 MADs dropped once.
    fn fit(white: &[([f64; 2], f64)], paper: &[([f64; 2], f64)], w: usize, h: usize) -> Field {
        let mut field = Field {
            coef: [0.0; 5],
            centre: [w as f64 / 2.0, h as f64 / 2.0],
            scale: w.max(h) as f64 / 2.0,
        };
        let rows: Vec<([f64; 7], f64)> = white
            .iter()
            .map(|s| (s, 0))
            .chain(paper.iter().map(|s| (s, 1)))
            .filter(|((_, l), _)| *l > 1e-6)
            .map(|((p, l), k)| {
                let t = field.terms(*p);
                let mut r = [0.0; 7];
                r[k] = 1.0;
                r[2..].copy_from_slice(&t);
                (r, l.ln())
            })
            .collect();
        if rows.len() < 20 {
            return Field::flat();
        }
        let fit = |keep: &[bool]| -> Option<[f64; 7]> {
            let mut a = vec![vec![0.0; 8]; 7];
            for ((r, y), _) in rows.iter().zip(keep).filter(|(_, k)| **k) {
                for i in 0..7 {
                    for j in 0..7 {
                        a[i][j] += r[i] * r[j];
                    }
                    a[i][7] += r[i] * y;
                }
            }
            // A touch of ridge on the shape keeps a thin spread of samples well posed.
            for (i, row) in a.iter_mut().enumerate().skip(2) {
                row[i] += 1e-6 * rows.len() as f64;
            }
            let x = solve(a)?;
            Some(std::array::from_fn(|i| x[i]))
        };
        let resid = |c: &[f64; 7]| -> Vec<f64> {
            rows.iter()
                .map(|(r, y)| y - (0..7).map(|i| r[i] * c[i]).sum::<f64>())
                .collect()
        };
        let Some(c) = fit(&vec![true; rows.len()]) else {
            return Field::flat();
        };
        let res = resid(&c);
        let mut abs: Vec<f64> = res.iter().map(|v| v.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let limit = (4.0 * 1.4826 * percentile(&abs, 0.5)).max(0.02);
        let keep: Vec<bool> = res.iter().map(|v| v.abs() <= limit).collect();
        let c = fit(&keep).unwrap_or(c);
        field.coef.copy_from_slice(&c[2..]);
        field
    }
}

/// The most pixels [`crate::pipeline::calibrate::calibrate_file`] measures a photo at: a larger one is averaged down in
/// linear light as it is decoded (4000 × 4000 leaves a chart a tenth of the photo's width
/// some 400 pixels across).
pub const CALIBRATION_PIXELS: usize = 16_000_000;

/// Measures the inks of `device` in a photograph of its chart ([`chart`]) beside a sheet
/// of white paper (the method is in the module's documentation).
pub fn calibrate(device: &Device, photo: &Image, opts: &CalibrateOptions) -> Result<Calibration> {
    let r = opts.paper_reflectance;
    if !(r.is_finite() && r > 0.0 && r <= 1.0) {
        return Err(Error::Invalid(format!(
            "`paper_reflectance` {r}: must be above 0 and at most 1"
        )));
    }
    if photo.width < 16 || photo.height < 16 {
        return Err(Error::Invalid(format!(
            "the photo is {}x{} pixels: too small to find a chart in",
            photo.width, photo.height
        )));
    }
    let layout = Layout::new(device)?;
    let p = Photo::new(photo);
    let grid = Grid::new(&p);
    let cands = rings(&grid);
    let Some((markers, hm)) = find_chart(&cands, &layout) else {
        return Err(Error::Invalid(format!(
            "chart not found: {} of the 4 corner markers (black squares with a white centre, \
             the top-left one's larger) seen; photograph the whole chart of `devices chart`, \
             sharp, evenly lit, without glare",
            cands.len().min(4)
        )));
    };
    let inv = hm.inverse().ok_or_else(|| {
        Error::Invalid("chart not found: its corner markers are in a line".into())
    })?;
    let (cw, ch) = (layout.width as f64, layout.height as f64);
    // Photo pixels a chart pixel, along the top edge.
    let tl = markers[0];
    let tr = markers[1];
    let t = layout.marker_centres();
    let scale = (tr[0] - tl[0]).hypot(tr[1] - tl[1]) / (t[1][0] - t[0][0]);
    let idx = layout.indices();

    // The paper.
    let (paper_pts, paper_rect) = match opts.paper {
        Some(rect) => paper_given(rect, &p)?,
        None => paper_found(&grid, &inv, cw, ch)?,
    };
    let mut clipped = 0;
    let paper: Vec<([f64; 2], [f64; 3])> = paper_pts
        .iter()
        .map(|&q| {
            let s = p.sample(q[0], q[1]);
            if s.iter().any(|&v| v >= 0.99) {
                clipped += 1;
            }
            (q, s)
        })
        .collect();
    if clipped * 20 > paper.len() {
        return Err(Error::Invalid(format!(
            "the paper ({}) is overexposed: {} of {} samples clipped; photograph with less exposure",
            rect_text(paper_rect),
            clipped,
            paper.len()
        )));
    }

    // The panel's white, away from every edge: for the field.
    let safe = (3.0 / scale).max(2.0);
    let step = (cw.min(ch) / 40.0).max(1.0);
    let mut white = Vec::new();
    let mut y = safe;
    while y < ch - safe {
        let mut x = safe;
        while x < cw - safe {
            let (x0, x1) = ((x - safe).floor() as usize, (x + safe).ceil() as usize);
            let (y0, y1) = ((y - safe).floor() as usize, (y + safe).ceil() as usize);
            let all_white = (y0..y1.min(layout.height)).all(|yy| {
                (x0..x1.min(layout.width))
                    .all(|xx| idx[yy * layout.width + xx] as usize == layout.white)
            });
            if all_white {
                let q = hm.apply([x, y]);
                white.push((q, lum(p.sample(q[0], q[1]))));
            }
            x += step;
        }
        y += step;
    }
    let field = if opts.vignetting {
        let paper_lum: Vec<([f64; 2], f64)> = paper.iter().map(|(q, s)| (*q, lum(*s))).collect();
        Field::fit(&white, &paper_lum, p.w, p.h)
    } else {
        Field::flat()
    };
    let corners = [[0.0, 0.0], [cw, 0.0], [cw, ch], [0.0, ch]];
    let mut fmin = f64::MAX;
    let mut fmax = 0f64;
    for i in 0..=8 {
        for j in 0..=8 {
            let (a, b) = (i as f64 / 8.0, j as f64 / 8.0);
            let top = [corners[0][0] * (1.0 - a) + corners[1][0] * a, 0.0];
            let q = hm.apply([top[0], ch * b]);
            let v = field.at(q);
            fmin = fmin.min(v);
            fmax = fmax.max(v);
        }
    }

    let corrected = |q: [f64; 2]| {
        let f = field.at(q);
        p.sample(q[0], q[1]).map(|v| v / f)
    };
    let mut paper_rgb = [0.0; 3];
    for (c, pc) in paper_rgb.iter_mut().enumerate() {
        let mut v: Vec<f64> = paper.iter().map(|(q, s)| s[c] / field.at(*q)).collect();
        *pc = trimmed_mean(&mut v);
    }
    let paper_lum = lum(paper_rgb);
    if paper_lum < 0.01 || paper_rgb.iter().any(|&v| v <= 1e-4) {
        return Err(Error::Invalid(format!(
            "the paper ({}) is almost black: the photo is too dark, or the rectangle is not the paper",
            rect_text(paper_rect)
        )));
    }

    // Every patch.
    let n = device.inks.len();
    let mut per_ink: Vec<Vec<([f64; 3], f64)>> = vec![Vec::new(); n];
    for (k, patch) in layout.patches.iter().enumerate() {
        let (x0, y0) = (
            patch.x as f64 + patch.width as f64 * 0.25,
            patch.y as f64 + patch.height as f64 * 0.25,
        );
        let (iw, ih) = (patch.width as f64 * 0.5, patch.height as f64 * 0.5);
        let nx = ((iw * scale).round() as usize).clamp(4, 24);
        let ny = ((ih * scale).round() as usize).clamp(4, 24);
        let mut rgb = [Vec::new(), Vec::new(), Vec::new()];
        let mut ls = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let q = hm.apply([
                    x0 + iw * (i as f64 + 0.5) / nx as f64,
                    y0 + ih * (j as f64 + 0.5) / ny as f64,
                ]);
                let s = corrected(q);
                for c in 0..3 {
                    rgb[c].push(s[c]);
                }
                ls.push(lum(s) / paper_lum);
            }
        }
        ls.sort_by(f64::total_cmp);
        let (lo, mid, hi) = (
            percentile(&ls, 0.1),
            percentile(&ls, 0.5),
            percentile(&ls, 0.9),
        );
        if hi - lo > 0.08 + 0.3 * mid {
            return Err(Error::Invalid(format!(
                "patch {} (row {}, column {}) of ink '{}' is not uniform: its middle spans \
                 {:.2} to {:.2} of the paper's brightness; the photo is blurred, the chart \
                 misread, or there is glare",
                k + 1,
                k / layout.cols + 1,
                k % layout.cols + 1,
                device.inks[patch.ink].name,
                lo,
                hi
            )));
        }
        let m = rgb.map(|mut v| trimmed_mean(&mut v));
        per_ink[patch.ink].push((m, lum(m) / paper_lum));
    }
    let mut inks = Vec::with_capacity(n);
    for (i, ink) in device.inks.iter().enumerate() {
        let got = &per_ink[i];
        if got.is_empty() {
            return Err(Error::Invalid(format!(
                "device '{}': ink '{}' has no patch on the chart",
                device.name, ink.name
            )));
        }
        let mut ls: Vec<f64> = got.iter().map(|g| g.1).collect();
        ls.sort_by(f64::total_cmp);
        let med = percentile(&ls, 0.5);
        let spread = ls.iter().map(|l| (l - med).abs()).fold(0.0, f64::max);
        if spread > 0.04 + 0.15 * med {
            return Err(Error::Invalid(format!(
                "the {} patches of ink '{}' disagree: their brightness runs from {:.3} to {:.3} \
                 of the paper's; glare, a shadow, or uneven light on the panel",
                got.len(),
                ink.name,
                ls[0],
                ls[ls.len() - 1]
            )));
        }
        let linear = [0, 1, 2]
            .map(|c| got.iter().map(|g| g.0[c]).sum::<f64>() / got.len() as f64 / paper_rgb[c] * r);
        inks.push(InkReading {
            name: ink.name.clone(),
            linear,
            srgb: linear.map(|v| linear_to_srgb8(v.clamp(0.0, 1.0))),
            patches: got.len(),
            spread,
        });
    }
    let wl = lum(inks[layout.white].linear) / r;
    if wl > 1.05 {
        return Err(Error::Invalid(format!(
            "the region taken for the paper ({}) is darker than the panel's white ink ({:.2} of \
             it): put a sheet of white paper beside the panel, or give `paper`",
            rect_text(paper_rect),
            wl
        )));
    }
    if lum(inks[layout.black].linear) >= lum(inks[layout.white].linear) {
        return Err(Error::Invalid(format!(
            "chart misread: ink '{}' measures no darker than ink '{}'",
            device.inks[layout.black].name, device.inks[layout.white].name
        )));
    }
    Ok(Calibration {
        inks,
        markers,
        paper: paper_rect,
        field: [fmin / fmax, 1.0],
    })
}

fn rect_text(r: [f64; 4]) -> String {
    format!("{:.0},{:.0},{:.0},{:.0}", r[0], r[1], r[2], r[3])
}

/// Sample points in a given paper rectangle (its middle 80%).
fn paper_given(rect: [f64; 4], p: &Photo) -> Result<(Vec<[f64; 2]>, [f64; 4])> {
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
fn paper_found(g: &Grid, inv: &Homography, cw: f64, ch: f64) -> Result<(Vec<[f64; 2]>, [f64; 4])> {
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

/// The profile TOML of `device` with the measured inks: the device's fields, `name`,
/// `colours = "measured"` and `source` as given. Checked by parsing it back; an error when
/// two inks measure the same colour.
pub fn profile(device: &Device, cal: &Calibration, name: &str, source: &str) -> Result<String> {
    let q = |s: &str| toml::Value::String(s.to_string()).to_string();
    let hex = |c: [u8; 3]| format!("\"#{:02x}{:02x}{:02x}\"", c[0], c[1], c[2]);
    let description = format!("{}; inks measured from a photograph", device.description);
    let mut t = format!("# {name}: {description}\n# {source}\n\n");
    t += &format!("name = {}\n", q(name));
    t += &format!("description = {}\n", q(&description));
    t += &format!("width = {}\nheight = {}\n", device.width, device.height);
    t += &format!(
        "ppi = {}\nviewing_distance_cm = {}\nrotation = {}\n",
        device.ppi, device.viewing_distance_cm, device.rotation
    );
    t += &format!(
        "colours = {}\nsource = {}\n",
        q(Measurement::Measured.name()),
        q(source)
    );
    let enc: Vec<String> = device.encodings.iter().map(|e| q(e.name())).collect();
    t += &format!("encodings = [{}]\n", enc.join(", "));
    if let Some(b) = device.bits {
        t += &format!("bits = {b}\n");
    }
    if device.planes != super::device::PlaneBits::default() {
        t += &format!(
            "\n[planes]\nblack = {}\ncolour = {}\n",
            device.planes.black, device.planes.colour
        );
    }
    for (ink, m) in device.inks.iter().zip(&cal.inks) {
        t += &format!(
            "\n[[ink]]\nname = {}\ncode = {}\nnominal = {}\nmeasured = {}\n",
            q(&ink.name),
            ink.code,
            hex(ink.nominal),
            hex(m.srgb)
        );
    }
    for (i, a) in cal.inks.iter().enumerate() {
        if let Some(b) = cal.inks[..i].iter().find(|b| b.srgb == a.srgb) {
            return Err(Error::Invalid(format!(
                "inks '{}' and '{}' both measure {}: the photo does not tell them apart",
                b.name,
                a.name,
                hex(a.srgb).trim_matches('"')
            )));
        }
    }
    Device::parse(&t, name)?;
    Ok(t)
}

/// The device with its inks' colours replaced by the measurement (`colours = "measured"`).
pub fn measured_device(device: &Device, cal: &Calibration, source: &str) -> Device {
    let mut d = device.clone();
    d.colours = Measurement::Measured;
    d.source = source.to_string();
    d.inks = device
        .inks
        .iter()
        .zip(&cal.inks)
        .map(|(i, m)| Ink {
            measured: Some(Measured::Srgb(m.srgb)),
            ..i.clone()
        })
        .collect();
    d
}

/// The conditions of a [`synthetic_photo`].
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Photo width in pixels.
    pub width: usize,
    /// Photo height in pixels.
    pub height: usize,
    /// The light's and camera's gain on each channel (a colour cast).
    pub gains: [f64; 3],
    /// The exposure: paper white in the middle of the photo reads `exposure × gains`.
    pub exposure: f64,
    /// Radial falloff: brightness at the photo's corners is `1 − vignetting` of the middle's.
    pub vignetting: f64,
    /// Standard deviation of the noise at paper white, linear (shot noise: it scales with
    /// the square root of the signal, plus a floor of a quarter of it).
    pub noise: f64,
    /// The noise's seed.
    pub seed: u64,
    /// Perspective: the far edge of the chart is shorter by this fraction, and the chart
    /// turned by 10 × this many degrees.
    pub tilt: f64,
    /// Standard deviation of a Gaussian blur, in photo pixels (0: none).
    pub blur: f64,
    /// Put a sheet of white paper (reflectance 1) beside the panel.
    pub paper: bool,
    /// Leave the chart out (the panel shows its white only).
    pub blank: bool,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            width: 640,
            height: 400,
            gains: [1.0, 0.92, 0.75],
            exposure: 0.8,
            vignetting: 0.25,
            noise: 0.006,
            seed: 1,
            tilt: 0.08,
            blur: 0.7,
            paper: true,
            blank: false,
        }
    }
}

/// A photograph of `device`'s chart with the inks showing `inks` (linear-light sRGB, one
/// an ink, relative to paper white = 1), on a dark desk in a dark bezel, beside a sheet of
/// white paper, taken under `scene`'s light (cast, exposure, vignetting), tilted in
/// perspective (sampled bilinearly, 2×2 a pixel), blurred, with deterministic noise: 8-bit
/// sRGB. The chart fills the left 55% of the photo, the paper the right 30%.
pub fn synthetic_photo(device: &Device, inks: &[[f64; 3]], scene: &Scene) -> Result<Image> {
    if inks.len() != device.inks.len() {
        return Err(Error::Invalid(format!(
            "{} ink colours for the {} inks of device '{}'",
            inks.len(),
            device.inks.len(),
            device.name
        )));
    }
    let (pw, ph) = (scene.width, scene.height);
    if pw < 64 || ph < 64 {
        return Err(Error::Invalid(format!(
            "a synthetic photo of {pw}x{ph} is too small: at least 64x64"
        )));
    }
    let layout = Layout::new(device)?;
    let idx = layout.indices();
    let (cw, ch) = (layout.width, layout.height);
    let refl: Vec<[f64; 3]> = idx
        .iter()
        .map(|&i| {
            if scene.blank {
                inks[layout.white]
            } else {
                inks[i as usize]
            }
        })
        .collect();
    // Where the chart goes: a box in the left 55%, keystoned and turned.
    let bezel = 0.06 * cw.max(ch) as f64;
    let (bx0, by0, bx1, by1) = (
        0.05 * pw as f64,
        0.08 * ph as f64,
        0.58 * pw as f64,
        0.92 * ph as f64,
    );
    let s = ((bx1 - bx0) / (cw as f64 + 2.0 * bezel)).min((by1 - by0) / (ch as f64 + 2.0 * bezel));
    let (w2, h2) = (cw as f64 * s / 2.0, ch as f64 * s / 2.0);
    let centre = [(bx0 + bx1) / 2.0, (by0 + by1) / 2.0];
    let k = scene.tilt;
    let rough = [
        [-w2 * (1.0 - k), -h2],
        [w2 * (1.0 - k), -h2],
        [w2, h2],
        [-w2, h2],
    ];
    let a = (10.0 * k).to_radians();
    let to = rough.map(|[x, y]| {
        [
            centre[0] + x * a.cos() - y * a.sin(),
            centre[1] + x * a.sin() + y * a.cos(),
        ]
    });
    let from = [
        [0.0, 0.0],
        [cw as f64, 0.0],
        [cw as f64, ch as f64],
        [0.0, ch as f64],
    ];
    let inv = Homography::from_points(&from, &to)
        .and_then(|h| h.inverse())
        .ok_or_else(|| Error::Invalid(format!("`tilt` {k}: the chart folds")))?;
    // The paper: a slightly turned rectangle in the right 30%.
    let pc = [0.79 * pw as f64, 0.5 * ph as f64];
    let (pw2, ph2) = (0.13 * pw as f64, 0.38 * ph as f64);
    let pa = 2f64.to_radians();
    let in_paper = |x: f64, y: f64| {
        let (dx, dy) = (x - pc[0], y - pc[1]);
        let (u, v) = (
            dx * pa.cos() + dy * pa.sin(),
            -dx * pa.sin() + dy * pa.cos(),
        );
        scene.paper && u.abs() < pw2 && v.abs() < ph2
    };
    let chart_at = |u: f64, v: f64| -> [f64; 3] {
        // Bilinear between chart pixel centres.
        let fx = (u - 0.5).clamp(0.0, (cw - 1) as f64);
        let fy = (v - 0.5).clamp(0.0, (ch - 1) as f64);
        let (x0, y0) = (fx as usize, fy as usize);
        let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
        let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
        [0, 1, 2].map(|c| {
            let p = |x: usize, y: usize| refl[y * cw + x][c];
            (p(x0, y0) * (1.0 - tx) + p(x1, y0) * tx) * (1.0 - ty)
                + (p(x0, y1) * (1.0 - tx) + p(x1, y1) * tx) * ty
        })
    };
    let desk = |x: f64, y: f64| {
        let t = 1.0 + 0.15 * (x * 0.05).sin() * (y * 0.031).cos();
        [0.13 * t, 0.10 * t, 0.075 * t]
    };
    let rmax = (pw as f64).hypot(ph as f64) / 2.0;
    let mut img = vec![[0f64; 3]; pw * ph];
    for y in 0..ph {
        for x in 0..pw {
            let mut acc = [0.0; 3];
            for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                let (u, v) = (x as f64 + sx, y as f64 + sy);
                let r = if in_paper(u, v) {
                    [1.0; 3]
                } else {
                    let [cu, cv] = inv.apply([u, v]);
                    if cu >= 0.0 && cv >= 0.0 && cu < cw as f64 && cv < ch as f64 {
                        chart_at(cu, cv)
                    } else if cu >= -bezel
                        && cv >= -bezel
                        && cu < cw as f64 + bezel
                        && cv < ch as f64 + bezel
                    {
                        [0.03, 0.03, 0.035]
                    } else {
                        desk(u, v)
                    }
                };
                for c in 0..3 {
                    acc[c] += r[c] / 4.0;
                }
            }
            let d =
                (x as f64 + 0.5 - pw as f64 / 2.0).hypot(y as f64 + 0.5 - ph as f64 / 2.0) / rmax;
            let light = scene.exposure * (1.0 - scene.vignetting * d * d);
            img[y * pw + x] = [0, 1, 2].map(|c| acc[c] * light * scene.gains[c]);
        }
    }
    if scene.blur > 0.0 {
        let rad = (3.0 * scene.blur).ceil() as isize;
        let kern: Vec<f64> = (-rad..=rad)
            .map(|i| (-(i * i) as f64 / (2.0 * scene.blur * scene.blur)).exp())
            .collect();
        let sum: f64 = kern.iter().sum();
        let kern: Vec<f64> = kern.iter().map(|v| v / sum).collect();
        for pass in 0..2 {
            let src = img.clone();
            for y in 0..ph as isize {
                for x in 0..pw as isize {
                    let mut acc = [0.0; 3];
                    for (i, kv) in kern.iter().enumerate() {
                        let o = i as isize - rad;
                        let (sx, sy) = if pass == 0 {
                            ((x + o).clamp(0, pw as isize - 1), y)
                        } else {
                            (x, (y + o).clamp(0, ph as isize - 1))
                        };
                        let v = src[sy as usize * pw + sx as usize];
                        for c in 0..3 {
                            acc[c] += kv * v[c];
                        }
                    }
                    img[y as usize * pw + x as usize] = acc;
                }
            }
        }
    }
    let mut state = scene.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(pw * ph * 3);
    for px in &img {
        for &v in px {
            let (u1, u2) = (uniform(), uniform());
            let gauss = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            let sd = scene.noise * (v.max(0.0).sqrt() + 0.25);
            out.push(linear_to_srgb8((v + sd * gauss).clamp(0.0, 1.0)));
        }
    }
    Ok(Image::rgb8(pw, ph, &out))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lab(lin: [f64; 3]) -> [f64; 3] {
        const M: [[f64; 3]; 3] = [
            [0.4124564, 0.3575761, 0.1804375],
            [0.2126729, 0.7151522, 0.0721750],
            [0.0193339, 0.1191920, 0.9503041],
        ];
        let xyz = [0, 1, 2].map(|r| (0..3).map(|c| M[r][c] * lin[c]).sum::<f64>());
        crate::scielab::lab_of_xyz(xyz)
    }

    fn worst_de(device: &Device, scene: &Scene) -> f64 {
        let truth: Vec<[f64; 3]> = device.inks.iter().map(Ink::shown_linear).collect();
        let photo = synthetic_photo(device, &truth, scene).unwrap();
        let cal = calibrate(device, &photo, &CalibrateOptions::default()).unwrap();
        cal.inks
            .iter()
            .zip(&truth)
            .map(|(m, t)| crate::scielab::ciede2000(lab(m.linear), lab(*t)))
            .fold(0.0, f64::max)
    }

    #[test]
    fn layout_fits_and_every_ink_has_patches() {
        for name in [
            "spectra6-7in3-v2",
            "bwry-4in2",
            "mono-4in26",
            "hanshow-bwr",
            "grey16-6in",
        ] {
            let d = Device::builtin(name).unwrap();
            let l = Layout::new(&d).unwrap();
            let per: Vec<usize> = (0..d.inks.len())
                .map(|i| l.patches.iter().filter(|p| p.ink == i).count())
                .collect();
            let least = if name == "grey16-6in" { 2 } else { 4 };
            assert!(per.iter().all(|&c| c >= least), "{name}: {per:?}");
            for p in &l.patches {
                assert!(p.x >= l.margin + l.marker + l.gap, "{name}");
                assert!(
                    p.x + p.width + l.margin + l.marker + l.gap <= l.width,
                    "{name}"
                );
                assert!(
                    p.y >= l.margin && p.y + p.height + l.margin <= l.height,
                    "{name}"
                );
                assert!(p.width.min(p.height) >= 8, "{name}: {p:?}");
            }
            let h = chart(&d).unwrap();
            assert_eq!((h.width, h.height), (d.width, d.height));
            assert_eq!(h.palette.as_deref(), Some(&d.nominal_colours()[..]));
            // The border is white, the top-left marker's corner black.
            assert_eq!(h.get(0, 0, 0) as usize, l.white);
            assert_eq!(h.get(0, l.margin, l.margin) as usize, l.black);
        }
    }

    #[test]
    fn a_turned_panel_gets_a_turned_chart() {
        let text = Device::builtin_text("bwry-4in2")
            .unwrap()
            .replace("rotation = 0", "rotation = 90");
        let d = Device::parse(&text, "t").unwrap();
        let l = Layout::new(&d).unwrap();
        assert_eq!((l.width, l.height), (300, 400));
        let h = chart(&d).unwrap();
        assert_eq!((h.width, h.height), (400, 300));
        let idx = l.indices();
        // Turned clockwise: the viewer's top-left pixel is the panel's top-right.
        for (vx, vy) in [(0, 0), (l.margin + 1, l.margin + 1), (150, 200), (299, 399)] {
            assert_eq!(h.get(0, 399 - vy, vx), idx[vy * 300 + vx]);
        }
    }

    #[test]
    fn homography_maps_and_inverts() {
        let from = [[0.0, 0.0], [10.0, 0.0], [10.0, 5.0], [0.0, 5.0]];
        let to = [[3.0, 4.0], [40.0, 6.0], [38.0, 30.0], [1.0, 25.0]];
        let h = Homography::from_points(&from, &to).unwrap();
        let inv = h.inverse().unwrap();
        for (f, t) in from.iter().zip(&to) {
            let m = h.apply(*f);
            assert!((m[0] - t[0]).abs() < 1e-9 && (m[1] - t[1]).abs() < 1e-9);
            let b = inv.apply(*t);
            assert!((b[0] - f[0]).abs() < 1e-9 && (b[1] - f[1]).abs() < 1e-9);
        }
    }

    #[test]
    fn a_small_three_ink_label_is_recovered() {
        let d = Device::builtin("hanshow-bwr").unwrap();
        let de = worst_de(&d, &Scene::default());
        assert!(de <= 2.0, "worst CIEDE2000 {de:.2}");
    }

    #[test]
    fn a_turned_panel_is_recovered() {
        let text = Device::builtin_text("bwry-4in2")
            .unwrap()
            .replace("rotation = 0", "rotation = 270");
        let d = Device::parse(&text, "t").unwrap();
        let de = worst_de(
            &d,
            &Scene {
                width: 480,
                height: 560,
                ..Scene::default()
            },
        );
        assert!(de <= 2.0, "worst CIEDE2000 {de:.2}");
    }

    #[test]
    fn no_chart_and_no_paper_are_errors() {
        let d = Device::builtin("bwry-4in2").unwrap();
        let truth: Vec<[f64; 3]> = d.inks.iter().map(Ink::shown_linear).collect();
        let blank = synthetic_photo(
            &d,
            &truth,
            &Scene {
                blank: true,
                ..Scene::default()
            },
        )
        .unwrap();
        let e = calibrate(&d, &blank, &CalibrateOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("chart not found"), "{e}");
        let bare = synthetic_photo(
            &d,
            &truth,
            &Scene {
                paper: false,
                ..Scene::default()
            },
        )
        .unwrap();
        let e = calibrate(&d, &bare, &CalibrateOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("paper not found") || e.contains("darker than the panel's white"),
            "{e}"
        );
        assert!(!e.contains('\n'));
    }
}
