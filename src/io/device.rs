//! Output devices as data: e-paper panels with their size, resolution, viewing distance,
//! inks and the encodings their firmware takes (`devices/*.toml`, built into the binary).
//!
//! An ink has a **nominal** colour (the pure sRGB value drivers and palettes name it by), a
//! **measured** colour where one exists (what the panel really shows, relative to a viewer
//! adapted to daylight: sRGB, or CIE Lab under D50 as ICC profiles and colorimeters give
//! it), and the **code** the firmware expects in its buffer. The order of the `[[ink]]`
//! tables is the device's index order: palette indices, PNG indices and the raw buffers'
//! order all follow it.
//!
//! A profile says how far its colours can be trusted (`colours`): `measured` (a cited
//! measurement), `estimated` (values the source gives without a measurement) or `nominal`
//! (no measurement exists: the nominal colours stand in). Every profile cites its
//! `source`. Errors name the file, the line and the field.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::Format;
use crate::error::{Error, Result};
use crate::tone::{linear_to_srgb, srgb_to_linear};

/// The built-in profiles: name and file text (the files in `devices/`).
const BUILTIN: &[(&str, &str)] = &[
    (
        "spectra6-7in3-v2",
        include_str!("../../devices/spectra6-7in3-v2.toml"),
    ),
    (
        "spectra6-7in3",
        include_str!("../../devices/spectra6-7in3.toml"),
    ),
    ("bwry-3in97", include_str!("../../devices/bwry-3in97.toml")),
    ("bwry-4in2", include_str!("../../devices/bwry-4in2.toml")),
    ("mono-4in26", include_str!("../../devices/mono-4in26.toml")),
    ("solum-bwr", include_str!("../../devices/solum-bwr.toml")),
    (
        "hanshow-bwr",
        include_str!("../../devices/hanshow-bwr.toml"),
    ),
    (
        "hanshow-bwy",
        include_str!("../../devices/hanshow-bwy.toml"),
    ),
    (
        "acep7-5in65",
        include_str!("../../devices/acep7-5in65.toml"),
    ),
    ("grey4-4in2", include_str!("../../devices/grey4-4in2.toml")),
    ("grey16-6in", include_str!("../../devices/grey16-6in.toml")),
];

/// How far a profile's ink colours can be trusted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Measurement {
    /// Measured on a panel; the `source` cites the measurement.
    Measured,
    /// Given by the source without a measurement (placeholder values).
    Estimated,
    /// No measurement exists: the nominal colours stand in for what the panel shows.
    Nominal,
}

impl Measurement {
    /// The word used in profiles and listings.
    pub fn name(self) -> &'static str {
        match self {
            Measurement::Measured => "measured",
            Measurement::Estimated => "estimated",
            Measurement::Nominal => "nominal",
        }
    }
}

/// What an ink looks like on the panel, as measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measured {
    /// sRGB (IEC 61966-2-1: D65 white, the sRGB transfer curve), 8 bits a channel.
    Srgb([u8; 3]),
    /// CIE L*a*b* relative to D50 (the ICC profile connection space), converted to sRGB
    /// with the Bradford transform.
    LabD50([f64; 3]),
}

/// One ink of a panel.
#[derive(Clone, Debug, PartialEq)]
pub struct Ink {
    /// The ink's name (`black`, `white`, `red`, …).
    pub name: String,
    /// The value the firmware expects for this ink in its buffer.
    pub code: u8,
    /// The nominal sRGB colour: what drivers and palettes call this ink.
    pub nominal: [u8; 3],
    /// The measured colour, when there is one.
    pub measured: Option<Measured>,
}

impl Ink {
    /// The colour the panel shows, in linear-light sRGB (may fall outside 0..1 for a Lab
    /// measurement outside the sRGB gamut): the measurement, else the nominal colour.
    pub fn shown_linear(&self) -> [f64; 3] {
        match self.measured {
            Some(Measured::Srgb(c)) => c.map(|v| srgb_to_linear(v as f64 / 255.0)),
            Some(Measured::LabD50(lab)) => lab_d50_to_linear_srgb(lab),
            None => self.nominal.map(|v| srgb_to_linear(v as f64 / 255.0)),
        }
    }

    /// The colour the panel shows as 8-bit sRGB (clipped to the sRGB gamut).
    pub fn shown(&self) -> [u8; 3] {
        match self.measured {
            Some(Measured::Srgb(c)) => c,
            None => self.nominal,
            Some(Measured::LabD50(_)) => self
                .shown_linear()
                .map(|v| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8),
        }
    }
}

/// Polarity of the black and colour planes (`planes` encoding): the bit written where the
/// pixel is that ink; the other value everywhere else.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneBits {
    /// The bit of a black pixel in the black plane (0 in Waveshare's and Pimoroni's
    /// drivers: the black/white RAM holds 1 for white).
    #[serde(default)]
    pub black: u8,
    /// The bit of a colour pixel in the colour plane (1 in Pimoroni's Inky and SSD1680-class
    /// controllers' red RAM).
    #[serde(default = "one")]
    pub colour: u8,
}

fn one() -> u8 {
    1
}

impl Default for PlaneBits {
    fn default() -> Self {
        PlaneBits {
            black: 0,
            colour: 1,
        }
    }
}

/// A panel: everything the colour code and the encoders need to know about it.
#[derive(Clone, Debug, PartialEq)]
pub struct Device {
    /// Short name (`spectra6-7in3-v2`): what `--device` takes for a built-in.
    pub name: String,
    /// A line on what the panel is.
    pub description: String,
    /// Width in pixels, in the panel's own scan order (what its buffer holds).
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels per inch.
    pub ppi: f64,
    /// The distance it is usually viewed from, in centimetres.
    pub viewing_distance_cm: f64,
    /// Degrees clockwise (0, 90, 180, 270) the picture is turned before it is fitted to the
    /// panel: a landscape panel mounted upright takes 90. Output stays in the panel's scan
    /// order, `width × height`.
    pub rotation: u16,
    /// How far the ink colours can be trusted.
    pub colours: Measurement,
    /// Where the colours (and codes) come from.
    pub source: String,
    /// The encodings its firmware takes, in order of preference.
    pub encodings: Vec<Format>,
    /// Bits a pixel of the packed buffer (`raw`, `c`); `None`: the fewest of 1, 2, 4, 8 that
    /// hold the largest code.
    pub bits: Option<u8>,
    /// Polarity of the `planes` encoding.
    pub planes: PlaneBits,
    /// The inks, in the device's index order.
    pub inks: Vec<Ink>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDevice {
    name: Spanned<String>,
    description: String,
    width: Spanned<i64>,
    height: Spanned<i64>,
    ppi: Spanned<f64>,
    viewing_distance_cm: Spanned<f64>,
    rotation: Option<Spanned<i64>>,
    colours: Measurement,
    source: Spanned<String>,
    encodings: Vec<Format>,
    bits: Option<Spanned<i64>>,
    #[serde(default)]
    planes: Option<Spanned<PlaneBits>>,
    ink: Vec<Spanned<RawInk>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInk {
    name: String,
    code: Spanned<i64>,
    nominal: Spanned<String>,
    measured: Option<Spanned<String>>,
    measured_lab: Option<Spanned<[f64; 3]>>,
}

/// The 1-based line of byte offset `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text[..at.min(text.len())].matches('\n').count() + 1
}

/// `#rrggbb` (or `rrggbb`) as three bytes.
fn hex(s: &str) -> Option<[u8; 3]> {
    let h = s.trim().strip_prefix('#').unwrap_or(s.trim());
    if h.len() != 6 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let v = u32::from_str_radix(h, 16).ok()?;
    Some([(v >> 16) as u8, (v >> 8) as u8, v as u8])
}

/// CIE Lab (D50) to linear sRGB: Lab → XYZ (D50), Bradford D50 → D65, XYZ → linear sRGB
/// (the matrices of IEC 61966-2-1 and the ICC's Bradford adaptation, as Lindbloom tabulates
/// them).
pub fn lab_d50_to_linear_srgb(lab: [f64; 3]) -> [f64; 3] {
    const WHITE_D50: [f64; 3] = [0.96422, 1.0, 0.82521];
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = fy + lab[1] / 500.0;
    let fz = fy - lab[2] / 200.0;
    let inv = |t: f64| {
        const EPS: f64 = 6.0 / 29.0;
        if t > EPS {
            t * t * t
        } else {
            3.0 * EPS * EPS * (t - 4.0 / 29.0)
        }
    };
    let xyz50 = [
        WHITE_D50[0] * inv(fx),
        WHITE_D50[1] * inv(fy),
        WHITE_D50[2] * inv(fz),
    ];
    const BRADFORD_D50_D65: [[f64; 3]; 3] = [
        [0.9555766, -0.0230393, 0.0631636],
        [-0.0282895, 1.0099416, 0.0210077],
        [0.0122982, -0.0204830, 1.3299098],
    ];
    const XYZ_TO_SRGB: [[f64; 3]; 3] = [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ];
    let mul = |m: &[[f64; 3]; 3], v: [f64; 3]| {
        [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
    };
    mul(&XYZ_TO_SRGB, mul(&BRADFORD_D50_D65, xyz50))
}

impl Device {
    /// Names of the built-in profiles.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(n, _)| *n)
    }

    /// The TOML text of a built-in profile.
    pub fn builtin_text(name: &str) -> Option<&'static str> {
        BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
    }

    /// A built-in profile by name.
    pub fn builtin(name: &str) -> Option<Device> {
        Device::builtin_text(name).map(|text| {
            Device::parse(text, &format!("devices/{name}.toml")).expect("built-in devices parse")
        })
    }

    /// A built-in profile by name, else a profile file at that path.
    pub fn load(name_or_path: &str) -> Result<Device> {
        if let Some(d) = Device::builtin(name_or_path) {
            return Ok(d);
        }
        let names: Vec<&str> = Device::builtin_names().collect();
        crate::names::check_file_or_builtin("device", name_or_path, &names)?;
        let text = super::read_text(Path::new(name_or_path), 1 << 20)?;
        Device::parse(&text, name_or_path)
    }

    /// Parses a profile; `origin` names the file in errors, each with the line and the field.
    pub fn parse(text: &str, origin: &str) -> Result<Device> {
        let raw: RawDevice = toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| line_of(text, s.start)).unwrap_or(0);
            Error::parse(origin, line, e.message().trim().replace('\n', " "))
        })?;
        let fail = |at: usize, field: &str, msg: String| {
            Err(Error::parse(
                origin,
                line_of(text, at),
                format!("{field}: {msg}"),
            ))
        };
        let name = raw.name.get_ref().trim().to_string();
        if name.is_empty() || name.chars().any(char::is_whitespace) {
            return fail(
                raw.name.span().start,
                "name",
                "a short name without spaces".into(),
            );
        }
        let mut size = [0usize; 2];
        for (i, (field, v)) in [("width", &raw.width), ("height", &raw.height)]
            .into_iter()
            .enumerate()
        {
            if !(1..=1 << 20).contains(v.get_ref()) {
                return fail(
                    v.span().start,
                    field,
                    format!("{} pixels: must be 1 to 1048576", v.get_ref()),
                );
            }
            size[i] = *v.get_ref() as usize;
        }
        for (field, v, max) in [
            ("ppi", &raw.ppi, 10_000.0),
            ("viewing_distance_cm", &raw.viewing_distance_cm, 10_000.0),
        ] {
            let x = *v.get_ref();
            if !(x.is_finite() && x > 0.0 && x <= max) {
                return fail(
                    v.span().start,
                    field,
                    format!("{x}: must be a positive number up to {max}"),
                );
            }
        }
        let rotation = raw.rotation.as_ref().map_or(0, |r| *r.get_ref());
        if ![0, 90, 180, 270].contains(&rotation) {
            return fail(
                raw.rotation.as_ref().map_or(0, |r| r.span().start),
                "rotation",
                format!("{rotation}: must be 0, 90, 180 or 270 degrees"),
            );
        }
        if raw.colours != Measurement::Nominal && raw.source.get_ref().trim().is_empty() {
            return fail(
                raw.source.span().start,
                "source",
                "cite where the measured colours come from".into(),
            );
        }
        let bits = match &raw.bits {
            Some(b) if ![1, 2, 4, 8].contains(b.get_ref()) => {
                return fail(
                    b.span().start,
                    "bits",
                    format!("{}: must be 1, 2, 4 or 8", b.get_ref()),
                )
            }
            Some(b) => Some(*b.get_ref() as u8),
            None => None,
        };
        let planes = match &raw.planes {
            Some(p) if p.get_ref().black > 1 || p.get_ref().colour > 1 => {
                return fail(p.span().start, "planes", "bits are 0 or 1".into())
            }
            Some(p) => *p.get_ref(),
            None => PlaneBits::default(),
        };
        if !(2..=256).contains(&raw.ink.len()) {
            return Err(Error::parse(
                origin,
                0,
                format!(
                    "ink: {} [[ink]] tables; a device needs 2 to 256",
                    raw.ink.len()
                ),
            ));
        }
        let mut inks: Vec<Ink> = Vec::with_capacity(raw.ink.len());
        for spanned in &raw.ink {
            let at = spanned.span().start;
            let r = spanned.get_ref();
            let code = *r.code.get_ref();
            if !(0..=255).contains(&code) {
                return fail(
                    r.code.span().start,
                    "code",
                    format!("{code}: must be 0 to 255"),
                );
            }
            let colour = |s: &Spanned<String>, field: &str| -> Result<[u8; 3]> {
                hex(s.get_ref()).ok_or_else(|| {
                    Error::parse(
                        origin,
                        line_of(text, s.span().start),
                        format!(
                            "{field}: `{}` is not a colour: write \"#rrggbb\"",
                            s.get_ref()
                        ),
                    )
                })
            };
            let nominal = colour(&r.nominal, "nominal")?;
            let measured = match (&r.measured, &r.measured_lab) {
                (Some(_), Some(l)) => {
                    return fail(
                        l.span().start,
                        "measured_lab",
                        "give measured (sRGB) or measured_lab, not both".into(),
                    )
                }
                (Some(m), None) => Some(Measured::Srgb(colour(m, "measured")?)),
                (None, Some(l)) => {
                    let [lightness, a, b] = *l.get_ref();
                    if !((0.0..=100.0).contains(&lightness)
                        && a.is_finite()
                        && b.is_finite()
                        && a.abs() <= 200.0
                        && b.abs() <= 200.0)
                    {
                        return fail(
                            l.span().start,
                            "measured_lab",
                            "L* must be 0 to 100, a* and b* within ±200".into(),
                        );
                    }
                    Some(Measured::LabD50([lightness, a, b]))
                }
                (None, None) => None,
            };
            if measured.is_none() && raw.colours != Measurement::Nominal {
                return fail(
                    at,
                    "measured",
                    format!(
                        "ink '{}' has no measured colour, but colours = \"{}\" (say \"nominal\", or give one)",
                        r.name,
                        raw.colours.name()
                    ),
                );
            }
            if measured.is_some() && raw.colours == Measurement::Nominal {
                return fail(
                    at,
                    "colours",
                    format!(
                        "ink '{}' has a measured colour, but colours = \"nominal\"",
                        r.name
                    ),
                );
            }
            let ink = Ink {
                name: r.name.trim().to_string(),
                code: code as u8,
                nominal,
                measured,
            };
            if let Some(b) = bits {
                if b < 8 && ink.code >> b != 0 {
                    return fail(
                        r.code.span().start,
                        "code",
                        format!("{}: does not fit in bits = {b}", ink.code),
                    );
                }
            }
            for other in &inks {
                let clash = if other.name == ink.name {
                    Some("name")
                } else if other.code == ink.code {
                    Some("code")
                } else if other.shown() == ink.shown() {
                    Some(if ink.measured.is_some() {
                        "measured"
                    } else {
                        "nominal"
                    })
                } else if other.nominal == ink.nominal {
                    Some("nominal")
                } else {
                    None
                };
                if let Some(field) = clash {
                    let at = match field {
                        "code" => r.code.span().start,
                        "nominal" => r.nominal.span().start,
                        "measured" => r.measured.as_ref().map_or(at, |m| m.span().start),
                        _ => at,
                    };
                    return fail(
                        at,
                        field,
                        format!(
                            "ink '{}' repeats the {field} of ink '{}'",
                            ink.name, other.name
                        ),
                    );
                }
            }
            inks.push(ink);
        }
        Ok(Device {
            name,
            description: raw.description.trim().to_string(),
            width: size[0],
            height: size[1],
            ppi: *raw.ppi.get_ref(),
            viewing_distance_cm: *raw.viewing_distance_cm.get_ref(),
            rotation: rotation as u16,
            colours: raw.colours,
            source: raw.source.get_ref().trim().to_string(),
            encodings: raw.encodings,
            bits,
            planes,
            inks,
        })
    }

    /// The colours the panel shows, in ink order: the palette a halftone is made with.
    pub fn shown_colours(&self) -> Vec<[u8; 3]> {
        self.inks.iter().map(Ink::shown).collect()
    }

    /// The nominal colours, in ink order.
    pub fn nominal_colours(&self) -> Vec<[u8; 3]> {
        self.inks.iter().map(|i| i.nominal).collect()
    }

    /// The firmware's code of every ink, in ink order.
    pub fn codes(&self) -> Vec<u8> {
        self.inks.iter().map(|i| i.code).collect()
    }

    /// Bits a pixel of the packed buffer: the profile's `bits`, else the fewest of 1, 2, 4
    /// and 8 that hold the largest code.
    pub fn packed_bits(&self) -> u8 {
        self.bits
            .unwrap_or_else(|| bits_for(self.inks.iter().map(|i| i.code).max().unwrap_or(0)))
    }

    /// The quarter turns clockwise of [`Device::rotation`].
    pub fn quarter_turns(&self) -> u8 {
        (self.rotation / 90) as u8
    }

    /// Pixels per degree of visual angle at the viewing distance.
    pub fn pixels_per_degree(&self) -> f64 {
        let inches = self.viewing_distance_cm / 2.54;
        2.0 * inches * 0.5f64.to_radians().tan() * self.ppi
    }
}

/// The fewest of 1, 2, 4 and 8 bits that hold `max_code`.
pub fn bits_for(max_code: u8) -> u8 {
    match max_code {
        0..=1 => 1,
        2..=3 => 2,
        4..=15 => 4,
        _ => 8,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r##"name = "t"
description = "test"
width = 10
height = 4
ppi = 100
viewing_distance_cm = 30
colours = "measured"
source = "here"
encodings = ["raw"]

[[ink]]
name = "black"
code = 0
nominal = "#000000"
measured = "#101010"

[[ink]]
name = "white"
code = 1
nominal = "#ffffff"
measured = "#c0c0c0"
"##;

    #[test]
    fn every_builtin_parses_with_distinct_inks_and_a_source() {
        let mut n = 0;
        for name in Device::builtin_names() {
            let d = Device::builtin(name).unwrap();
            assert_eq!(d.name, name);
            assert!(!d.source.is_empty(), "{name}");
            assert!(!d.encodings.is_empty(), "{name}");
            let shown: std::collections::HashSet<_> = d.inks.iter().map(Ink::shown).collect();
            let codes: std::collections::HashSet<_> = d.codes().into_iter().collect();
            assert_eq!(shown.len(), d.inks.len(), "{name}");
            assert_eq!(codes.len(), d.inks.len(), "{name}");
            for ink in &d.inks {
                assert_eq!(
                    ink.measured.is_none(),
                    d.colours == Measurement::Nominal,
                    "{name}"
                );
                assert!(u32::from(ink.code) < 1 << d.packed_bits(), "{name}");
            }
            n += 1;
        }
        assert_eq!(n, 11);
    }

    #[test]
    fn measured_numbers_are_the_sources() {
        let d = Device::builtin("spectra6-7in3-v2").unwrap();
        assert_eq!(d.inks[1].shown(), [168, 180, 182]);
        assert_eq!(d.inks[3].shown(), [113, 24, 19]);
        assert_eq!(d.codes(), [0, 1, 2, 3, 5, 6]);
        assert_eq!(d.packed_bits(), 4);
        let d = Device::builtin("bwry-3in97").unwrap();
        assert_eq!(d.inks[2].shown(), [172, 128, 0]);
        assert_eq!(d.packed_bits(), 2);
        assert_eq!(Device::builtin("grey16-6in").unwrap().inks.len(), 16);
        // 127 ppi at 40 cm is about 35 pixels a degree.
        let p = Device {
            ppi: 127.0,
            viewing_distance_cm: 40.0,
            ..Device::parse(GOOD, "t").unwrap()
        };
        assert!((p.pixels_per_degree() - 35.0).abs() < 0.1);
    }

    #[test]
    fn lab_white_is_srgb_white() {
        let w = lab_d50_to_linear_srgb([100.0, 0.0, 0.0]);
        for v in w {
            assert!((v - 1.0).abs() < 2e-3, "{w:?}");
        }
        let g = lab_d50_to_linear_srgb([50.0, 0.0, 0.0]);
        assert!(
            (g[0] - g[2]).abs() < 2e-3 && (g[1] - 0.1842).abs() < 1e-3,
            "{g:?}"
        );
    }

    #[test]
    fn bad_profiles_name_file_line_and_field() {
        let cases: &[(&str, &str, &str)] = &[
            ("width = 10", "width = 0", "t.toml:3: width: 0 pixels"),
            ("ppi = 100", "ppi = -1", "t.toml:5: ppi:"),
            (
                "colours = \"measured\"",
                "colours = \"guessed\"",
                "t.toml:7:",
            ),
            (
                "measured = \"#c0c0c0\"",
                "measured = \"#c0c0\"",
                "t.toml:21: measured:",
            ),
            (
                "measured = \"#c0c0c0\"",
                "measured = \"#101010\"",
                "t.toml:21: measured: ink 'white' repeats",
            ),
            (
                "code = 1",
                "code = 0",
                "t.toml:19: code: ink 'white' repeats the code",
            ),
            ("code = 1", "code = 300", "t.toml:19: code: 300"),
            (
                "encodings = [\"raw\"]",
                "encodings = [\"jpeg\"]",
                "t.toml:9:",
            ),
            (
                "height = 4",
                "height = 4\nrotation = 45",
                "t.toml:5: rotation: 45",
            ),
            ("height = 4", "height = 4\nheigth = 4", "t.toml:5:"),
            (
                "measured = \"#c0c0c0\"\n",
                "",
                "t.toml:17: measured: ink 'white' has no measured",
            ),
            ("source = \"here\"", "source = \"\"", "t.toml:8: source:"),
        ];
        for (from, to, want) in cases {
            assert!(GOOD.contains(from), "{from}");
            let text = GOOD.replacen(from, to, 1);
            let e = Device::parse(&text, "t.toml").unwrap_err().to_string();
            assert!(e.starts_with(want), "{to:?}: {e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }

    #[test]
    fn lab_measurements_are_read() {
        let text = GOOD.replace("measured = \"#c0c0c0\"", "measured_lab = [80.0, 0.0, 0.0]");
        let d = Device::parse(&text, "t").unwrap();
        let s = d.inks[1].shown();
        assert!(s[0] == s[2] && (s[1] as i32 - 198).abs() <= 1, "{s:?}");
    }
}
