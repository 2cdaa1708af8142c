//! Where real inks make diffusion fail: every built-in e-paper panel given flat patches of
//! saturated colours, most of which it lacks (blue on a black, white, red and yellow panel).
//! A stable rendering shows, on average, the colour the gamut map aims at (the nearest the
//! inks can show, at the colour's own lightness) and shows it the same from the first rows to
//! the last; a runaway (error piling up where the inks cannot follow) shows as a mean far from
//! the aim, a hue turned towards another ink, or a drift down the patch.
//!
//! Part of the stability map (`halftone bench --stability`: `panels.csv`, and a section of
//! `stability.md`); `tests/it/stability.rs` holds every panel to bounds.

use serde::Serialize;

use crate::error::Result;
use crate::io::panel::Device;
use crate::method::Method;
use crate::options::{MethodKind, Options};
use crate::press::RenderingIntent;
use crate::raster::Image;
use crate::scielab::{ciede2000, lab_of_xyz};
use crate::tone::ToneOptions;

/// The test colours: full-strength sRGB primaries and secondaries, and a sky blue.
pub const COLOURS: [(&str, [u8; 3]); 7] = [
    ("red", [220, 30, 30]),
    ("green", [30, 180, 40]),
    ("blue", [20, 40, 200]),
    ("cyan", [20, 190, 210]),
    ("magenta", [200, 30, 190]),
    ("yellow", [235, 215, 20]),
    ("sky", [60, 120, 220]),
];

/// One panel and one colour.
#[derive(Clone, Debug, Serialize)]
pub struct PanelCase {
    /// The panel's built-in name.
    pub panel: String,
    /// `diffuse` or `dbs`.
    pub method: String,
    /// The test colour's name (see [`COLOURS`]).
    pub colour: String,
    /// CIELAB of the colour aimed at (the gamut map's mean over the patch), as the viewer
    /// adapted to the panel's white and black sees it.
    pub aim: [f64; 3],
    /// CIELAB of the mean colour shown (the inks the halftone uses, averaged), seen the same way.
    pub seen: [f64; 3],
    /// CIEDE2000 between the two.
    pub de_aim: f64,
    /// Hue angle between the two, degrees (0 when either is near neutral, chroma under 5).
    pub hue_deg: f64,
    /// CIEDE2000 between the mean shown over the patch's top third and over its bottom third.
    pub drift: f64,
    /// Share of pixels printed with a colour (not neutral) ink.
    pub colour_ink_share: f64,
}

/// CIELAB (D65) of a linear sRGB colour.
fn lab(rgb: [f64; 3]) -> [f64; 3] {
    const M: [[f64; 3]; 3] = [
        [0.4124, 0.3576, 0.1805],
        [0.2126, 0.7152, 0.0722],
        [0.0193, 0.1192, 0.9505],
    ];
    lab_of_xyz(M.map(|r| r[0] * rgb[0] + r[1] * rgb[1] + r[2] * rgb[2]))
}

/// The mean of some linear colours.
fn mean<'a>(it: impl Iterator<Item = &'a [f32; 3]>) -> [f64; 3] {
    let (mut sum, mut n) = ([0f64; 3], 0usize);
    for c in it {
        for k in 0..3 {
            sum[k] += c[k] as f64;
        }
        n += 1;
    }
    sum.map(|v| v / n.max(1) as f64)
}

/// The cases of one panel (a built-in name or a profile file) with `method` (diffusion or
/// DBS) on `size`×`size` patches, under its default intent.
pub fn panel(name: &str, method: MethodKind, size: usize) -> Result<Vec<PanelCase>> {
    panel_with(name, method, None, size)
}

/// [`panel`] under `intent` (`None`: the device's default).
pub fn panel_with(
    name: &str,
    method: MethodKind,
    intent: Option<RenderingIntent>,
    size: usize,
) -> Result<Vec<PanelCase>> {
    let opts = Options {
        device: Some(name.into()),
        method,
        intent,
        ..Default::default()
    };
    let ink = opts.inks()?.ok_or_else(|| {
        crate::error::Error::Invalid(format!(
            "{name}: no gamut map under these options (plain palette diffusion)"
        ))
    })?;
    let mut out = Vec::new();
    for (cname, rgb) in COLOURS {
        let img = Image::rgb8(size, size, &rgb.repeat(size * size));
        let tone = img.tone_table(&ToneOptions::default());
        let planes = img.planes(&tone);
        let m = ink.map(&planes)?;
        let h = ink.halftone(&planes)?;
        let idx: Vec<usize> = (0..size * size)
            .map(|i| h.get(0, i % size, i / size) as usize)
            .collect();
        let aim = lab(mean(m.target.iter()));
        let seen = lab(mean(idx.iter().map(|&k| &m.inks[k])));
        let third = size / 3 * size;
        let top = lab(mean(idx[..third].iter().map(|&k| &m.inks[k])));
        let bottom = lab(mean(idx[idx.len() - third..].iter().map(|&k| &m.inks[k])));
        let chroma = |l: [f64; 3]| l[1].hypot(l[2]);
        let hue_deg = if chroma(aim) < 5.0 || chroma(seen) < 5.0 {
            0.0
        } else {
            let d = (seen[2].atan2(seen[1]) - aim[2].atan2(aim[1])).to_degrees();
            (d + 540.0).rem_euclid(360.0) - 180.0
        };
        let colour = idx.iter().filter(|&&k| !m.neutral_inks[k]).count();
        out.push(PanelCase {
            panel: name.to_string(),
            method: if method == MethodKind::Dbs {
                "dbs"
            } else {
                "diffuse"
            }
            .into(),
            colour: cname.into(),
            aim,
            seen,
            de_aim: ciede2000(seen, aim),
            hue_deg,
            drift: ciede2000(top, bottom),
            colour_ink_share: colour as f64 / idx.len() as f64,
        });
    }
    Ok(out)
}

/// Every built-in panel's cases, diffusion and DBS, on `size`×`size` patches.
pub fn panels(size: usize) -> Result<Vec<PanelCase>> {
    let mut out = Vec::new();
    for name in Device::builtin_names() {
        for method in [MethodKind::Diffuse, MethodKind::Dbs] {
            out.extend(panel(name, method, size)?);
        }
    }
    Ok(out)
}

/// The cases as CSV, a row each.
pub fn to_csv(cases: &[PanelCase]) -> String {
    let mut s = String::from(
        "panel,method,colour,aim_l,aim_a,aim_b,seen_l,seen_a,seen_b,de_aim,hue_deg,drift,colour_ink_share\n",
    );
    for c in cases {
        s.push_str(&format!(
            "{},{},{},{:.2},{:.2},{:.2},{:.2},{:.2},{:.2},{:.3},{:.2},{:.3},{:.4}\n",
            c.panel,
            c.method,
            c.colour,
            c.aim[0],
            c.aim[1],
            c.aim[2],
            c.seen[0],
            c.seen[1],
            c.seen[2],
            c.de_aim,
            c.hue_deg,
            c.drift,
            c.colour_ink_share
        ));
    }
    s
}

/// A Markdown section: per panel and method, the worst case of each measure.
pub fn to_markdown(cases: &[PanelCase]) -> String {
    let mut s = String::from(
        "## Panels: saturated colours on real inks\n\n\
         Flat patches of red, green, blue, cyan, magenta, yellow and sky blue on every built-in \
         panel, as the viewer adapted to its white sees them: ΔE aim is CIEDE2000 between the \
         mean shown and the colour the gamut map aims at, hue the angle between them, drift \
         CIEDE2000 between the patch's top and bottom thirds (worst of the seven colours; \
         every case in panels.csv).\n\n\
         | panel | method | worst ΔE aim | worst hue° | worst drift |\n|---|---|---:|---:|---:|\n",
    );
    let mut keys: Vec<(&str, &str)> = Vec::new();
    for c in cases {
        if !keys.contains(&(&c.panel, &c.method)) {
            keys.push((&c.panel, &c.method));
        }
    }
    for (p, m) in keys {
        let of = || cases.iter().filter(|c| c.panel == p && c.method == m);
        let worst = |f: fn(&PanelCase) -> f64| -> (f64, String) {
            of().map(|c| (f(c), c.colour.clone()))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .unwrap_or((0.0, String::new()))
        };
        let (de, dc) = worst(|c| c.de_aim);
        let (hu, hc) = worst(|c| c.hue_deg.abs());
        let (dr, rc) = worst(|c| c.drift);
        s.push_str(&format!(
            "| {p} | {m} | {de:.2} ({dc}) | {hu:.1} ({hc}) | {dr:.2} ({rc}) |\n"
        ));
    }
    s
}
