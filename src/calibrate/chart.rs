//! The chart shown on the panel: its layout and the palette halftone drawn from it.

use super::*;

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
pub(super) fn hole_side(marker: usize, big: bool) -> usize {
    let h = (marker as f64 * if big { 0.56 } else { 0.3 }).round() as usize;
    if (marker - h) % 2 == 1 {
        h + 1
    } else {
        h
    }
}

/// Relative luminance of an 8-bit sRGB colour (linear light).
pub(super) fn luminance8(c: [u8; 3]) -> f64 {
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
