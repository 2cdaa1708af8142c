//! Measuring the inks: options, readings, the brightness field, [`calibrate`] itself, and
//! the profile written from the measurement.

use super::detect::{
    find_chart, lum, paper_found, paper_given, rect_text, rings, solve, Grid, Photo,
};
use super::*;

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

/// The mean of the middle 60% of `v` (sorted in place).
pub(super) fn trimmed_mean(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let cut = v.len() / 5;
    let mid = &v[cut..v.len() - cut];
    mid.iter().sum::<f64>() / mid.len() as f64
}

pub(super) fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The brightness field: `exp` of a quadratic in the photo's normalised coordinates.
pub(super) struct Field {
    pub(super) coef: [f64; 5],
    pub(super) centre: [f64; 2],
    pub(super) scale: f64,
}

impl Field {
    pub(super) fn flat() -> Field {
        Field {
            coef: [0.0; 5],
            centre: [0.0; 2],
            scale: 1.0,
        }
    }

    pub(super) fn terms(&self, [u, v]: [f64; 2]) -> [f64; 5] {
        let x = (u - self.centre[0]) / self.scale;
        let y = (v - self.centre[1]) / self.scale;
        [x, y, x * x, x * y, y * y]
    }

    pub(super) fn at(&self, p: [f64; 2]) -> f64 {
        let t = self.terms(p);
        (0..5).map(|i| self.coef[i] * t[i]).sum::<f64>().exp()
    }

    /// Fits log luminance of `white` (the panel's) and `paper` samples: one offset each, a
    /// shared quadratic; samples off by more than 4 MADs dropped once.
    pub(super) fn fit(
        white: &[([f64; 2], f64)],
        paper: &[([f64; 2], f64)],
        w: usize,
        h: usize,
    ) -> Field {
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
    if device.planes != crate::io::panel::PlaneBits::default() {
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
