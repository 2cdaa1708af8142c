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
// Not in the Python or WebAssembly builds: the standard library's transcendental functions
// are allowed here (clippy.toml; the rest of the library calls `crate::fmath`).
#![allow(clippy::disallowed_methods)]

use crate::error::{Error, Result};
use crate::io::panel::{Device, Ink, Measured, Measurement};
use crate::raster::{Halftone, Image, Samples};
use crate::tone::{linear_to_srgb8, ToneOptions};

mod chart;
mod detect;
mod measure;
mod synthetic;

pub use chart::{chart, Layout, Patch};
pub use detect::Homography;
pub use measure::{
    calibrate, measured_device, profile, CalibrateOptions, Calibration, InkReading,
    CALIBRATION_PIXELS,
};
pub use synthetic::{synthetic_photo, Scene};

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
