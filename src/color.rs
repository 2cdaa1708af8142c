//! Palettes: a fixed set of output colours (e-paper pigments, a display's colours, a classic
//! computer's palette), and the nearest colour chosen in Oklab.
//!
//! # Palette files
//!
//! Two formats are read:
//! - a hex list: one colour per line, `#rrggbb` or `rrggbb`; a line whose first token is not a
//!   colour and starts with `#` is a comment (but `#` and hex digits only is a mistyped
//!   colour), and `# …` after a colour is a comment too;
//! - a GIMP palette (`.gpl`): the `GIMP Palette` header, optional `Name:`/`Columns:` lines,
//!   `#` comments, then `R G B [name]` per line in decimal.
//!
//! A palette holds 2 to 256 colours. Errors name the file and the line.
//!
//! # Nearest colour
//!
//! Distances are Euclidean in Oklab (Björn Ottosson, 2020), computed with the `palette` crate
//! from linear RGB; the palette is converted once. Ties are broken by the colour value, not by
//! the entry's position, so the result never depends on the order of the palette's entries.

use std::path::Path;

use crate::fmath as fm;

use crate::error::{Error, Result};
use crate::tone::srgb_to_linear;

/// Built-in palettes: name and file text (the files in `palettes/`).
const BUILTIN: &[(&str, &str)] = &[
    ("bw", include_str!("../palettes/bw.txt")),
    ("eink-4", include_str!("../palettes/eink-4.txt")),
    ("epaper-7", include_str!("../palettes/epaper-7.txt")),
    ("rgb-8", include_str!("../palettes/rgb-8.txt")),
    ("cga-16", include_str!("../palettes/cga-16.txt")),
    ("gameboy", include_str!("../palettes/gameboy.gpl")),
    ("pico-8", include_str!("../palettes/pico-8.txt")),
];

/// A list of output colours (sRGB, 8 bits per channel).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Palette {
    /// The built-in's name or the file it came from.
    pub name: String,
    /// The colours, in the file's order; output indices refer to this order.
    pub colours: Vec<[u8; 3]>,
}

impl Palette {
    /// A palette from colours; 2..=256 of them.
    pub fn new(name: &str, colours: Vec<[u8; 3]>) -> Result<Palette> {
        if !(2..=256).contains(&colours.len()) {
            return Err(Error::Invalid(format!(
                "palette {name}: {} colours, must be 2 to 256",
                colours.len()
            )));
        }
        Ok(Palette {
            name: name.to_string(),
            colours,
        })
    }

    /// Names of the built-in palettes.
    pub fn builtin_names() -> impl Iterator<Item = &'static str> {
        BUILTIN.iter().map(|(n, _)| *n)
    }

    /// A built-in palette by name.
    pub fn builtin(name: &str) -> Option<Palette> {
        BUILTIN
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(n, text)| Palette::parse(text, n).expect("built-in palettes parse"))
    }

    /// A built-in palette by name, else a palette file at that path. `auto:N` is refused
    /// with an error naming `palette`: that palette is made from the image
    /// ([`crate::quantize::auto_palette`]), so there is nothing to load.
    pub fn load(name_or_path: &str) -> Result<Palette> {
        if let Some(p) = Palette::builtin(name_or_path) {
            return Ok(p);
        }
        if let Some(n) = auto_palette_size(name_or_path) {
            let n = n?;
            return Err(Error::Option {
                field: "palette",
                value: name_or_path.to_string(),
                msg: format!(
                    "is made from the image ({n} colours): the method computes it, there is \
                     no file to load"
                ),
            });
        }
        let names: Vec<&str> = Palette::builtin_names().collect();
        crate::names::check_file_or_builtin("palette", name_or_path, &names)?;
        let path = Path::new(name_or_path);
        let text = crate::io::read_text(path, 1 << 20)?;
        Palette::parse(&text, name_or_path)
    }

    /// Parses a hex list or a GIMP palette; `origin` names the file in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Palette> {
        let first = text.lines().next().unwrap_or("").trim();
        let colours = if first.starts_with("GIMP Palette") {
            parse_gpl(text, origin)?
        } else {
            parse_hex(text, origin)?
        };
        if !(2..=256).contains(&colours.len()) {
            let n = colours.len();
            let found = match n {
                0 => "no colour".to_string(),
                1 => "only 1 colour".to_string(),
                n => format!("{n} colours"),
            };
            return Err(Error::parse(
                origin,
                0,
                format!("{found} in the file; a palette needs 2 to 256, one a line"),
            ));
        }
        Ok(Palette {
            name: origin.to_string(),
            colours,
        })
    }

    /// Number of colours.
    pub fn len(&self) -> usize {
        self.colours.len()
    }

    /// True when there are no colours (never, for a parsed palette).
    pub fn is_empty(&self) -> bool {
        self.colours.is_empty()
    }
}

/// The size of an automatic palette, `auto:N` with N in 2..=256: `None` when `spec` is not
/// of that form (a built-in name or a file), `Some(Err)` naming `palette` when N is not a
/// number of colours from 2 to 256.
pub fn auto_palette_size(spec: &str) -> Option<Result<usize>> {
    let rest = spec.trim().strip_prefix("auto:")?;
    let bad = |msg: String| {
        Err(Error::Option {
            field: "palette",
            value: spec.to_string(),
            msg,
        })
    };
    Some(match rest.trim().parse::<usize>() {
        Ok(n) if (2..=256).contains(&n) => Ok(n),
        Ok(n) => bad(format!(
            "an automatic palette has 2 to 256 colours, not {n} (write auto:16)"
        )),
        Err(_) => bad(format!(
            "`{rest}` is not a number of colours: write auto:N with N from 2 to 256"
        )),
    })
}

fn hex_colour(token: &str) -> Option<[u8; 3]> {
    let h = token.strip_prefix('#').unwrap_or(token);
    if h.len() != 6 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let v = u32::from_str_radix(h, 16).ok()?;
    Some([(v >> 16) as u8, (v >> 8) as u8, v as u8])
}

fn parse_hex(text: &str, origin: &str) -> Result<Vec<[u8; 3]>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut tokens = line.split_whitespace();
        let Some(first) = tokens.next() else { continue };
        match hex_colour(first) {
            Some(c) => {
                if let Some(rest) = tokens.next() {
                    if !rest.starts_with('#') {
                        return Err(Error::parse(
                            origin,
                            i + 1,
                            format!("unexpected `{rest}` after the colour (comments start with #)"),
                        ));
                    }
                }
                out.push(c);
            }
            // `#` and hex digits only, but not six of them: a mistyped colour, not a comment.
            // By bytes: a first character of several bytes must not be sliced (found by
            // fuzzing: `ݜaaaa` panicked here).
            None if first.len() > 1 && first.bytes().skip(1).all(|b| b.is_ascii_hexdigit()) => {
                return Err(Error::parse(
                    origin,
                    i + 1,
                    format!("`{first}` is not a colour: write #rrggbb with six hex digits"),
                ))
            }
            // `#` and six letters or digits, some not hex (`#gg0000`): a colour mistyped,
            // not a comment, which would be a word after `#` and a space.
            None if first.len() == 7
                && first.starts_with('#')
                && first.bytes().skip(1).all(|b| b.is_ascii_alphanumeric()) =>
            {
                return Err(Error::parse(
                    origin,
                    i + 1,
                    format!("`{first}` is not a colour: a hex digit is 0-9 or a-f (write #rrggbb)"),
                ))
            }
            None if first.starts_with('#') => {}
            None => {
                return Err(Error::parse(
                    origin,
                    i + 1,
                    format!("`{first}` is not a colour: write #rrggbb or rrggbb"),
                ))
            }
        }
    }
    Ok(out)
}

fn parse_gpl(text: &str, origin: &str) -> Result<Vec<[u8; 3]>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("Name:") || t.starts_with("Columns:")
        {
            continue;
        }
        let mut c = [0u8; 3];
        let mut tokens = t.split_whitespace();
        for (k, v) in c.iter_mut().enumerate() {
            let tok = tokens.next().ok_or_else(|| {
                Error::parse(origin, i + 1, "expected three numbers: R G B [name]")
            })?;
            *v = tok.parse().map_err(|_| {
                Error::parse(
                    origin,
                    i + 1,
                    format!(
                        "`{tok}` is not a {} value 0..255",
                        ["red", "green", "blue"][k]
                    ),
                )
            })?;
        }
        out.push(c);
    }
    Ok(out)
}

/// Ottosson's linear sRGB → LMS matrix, the first step of Oklab, as the `palette` crate
/// writes it. The one copy of Oklab's numbers: the `f32` matrices below are these rounded,
/// as the `palette` crate's `T::from_f64` rounds them; [`oklab_of_linear`] (through the
/// `palette` crate), the fast nearest-colour search of palette diffusion, the panels' colour
/// mapping ([`crate::rendering`]) and the inks' hull (`method::gamut`) all evaluate them.
pub const OKLAB_M1_F64: [[f64; 3]; 3] = [
    [0.4122214708, 0.5363325363, 0.0514459929],
    [0.2119034982, 0.6806995451, 0.1073969566],
    [0.0883024619, 0.2817188376, 0.6299787005],
];
/// Cube-root LMS → Oklab `[L, a, b]`, the second step of Oklab (see [`OKLAB_M1_F64`]).
pub const OKLAB_M2_F64: [[f64; 3]; 3] = [
    [0.2104542553, 0.7936177850, -0.0040720468],
    [1.9779984951, -2.4285922050, 0.4505937099],
    [0.0259040371, 0.7827717662, -0.8086757660],
];
/// Oklab `[L, a, b]` → cube-root LMS: the inverse of [`OKLAB_M2_F64`] (Ottosson's).
pub const OKLAB_M2_INV_F64: [[f64; 3]; 3] = [
    [1.0, 0.3963377774, 0.2158037573],
    [1.0, -0.1055613458, -0.0638541728],
    [1.0, -0.0894841775, -1.2914855480],
];
/// LMS → linear sRGB: the inverse of [`OKLAB_M1_F64`] (Ottosson's).
pub const OKLAB_M1_INV_F64: [[f64; 3]; 3] = [
    [4.0767416621, -3.3077115913, 0.2309699292],
    [-1.2684380046, 2.6097574011, -0.3413193965],
    [-0.0041960863, -0.7034186147, 1.7076147010],
];
/// [`OKLAB_M1_F64`] in `f32`.
pub const OKLAB_M1: [[f32; 3]; 3] = f32_matrix(OKLAB_M1_F64);
/// [`OKLAB_M2_F64`] in `f32`.
pub const OKLAB_M2: [[f32; 3]; 3] = f32_matrix(OKLAB_M2_F64);

const fn f32_matrix(m: [[f64; 3]; 3]) -> [[f32; 3]; 3] {
    let mut out = [[0f32; 3]; 3];
    let mut i = 0;
    while i < 9 {
        out[i / 3][i % 3] = m[i / 3][i % 3] as f32;
        i += 1;
    }
    out
}

/// Cube root of `x ≥ 0` to about 1e-6 relative: a first guess from the exponent bits, then
/// three Newton steps (several times faster than `cbrt`).
#[inline(always)]
pub(crate) fn cbrt(x: f32) -> f32 {
    let mut y = f32::from_bits(x.to_bits() / 3 + 709_921_077);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    y = (2.0 * y + x / (y * y)) * (1.0 / 3.0);
    if x <= 1e-30 {
        0.0
    } else {
        y
    }
}

/// Oklab of a linear RGB colour ([`OKLAB_M1`], [`OKLAB_M2`] with a fast cube root; negative
/// light clamped to 0).
#[inline(always)]
pub(crate) fn oklab(c: [f32; 3]) -> [f32; 3] {
    oklab_signed(c.map(|v| v.max(0.0)))
}

/// Oklab of a linear RGB colour whose channels may be negative: the cube roots keep their
/// sign (for colours without negative light, the plain cube roots: [`oklab`]).
#[inline(always)]
pub(crate) fn oklab_signed(c: [f32; 3]) -> [f32; 3] {
    let [r, g, b] = c;
    let root = |x: f32| cbrt(x.abs()).copysign(x);
    let [l, m, s] = OKLAB_M1.map(|w| root(w[0] * r + w[1] * g + w[2] * b));
    OKLAB_M2.map(|w| w[0] * l + w[1] * m + w[2] * s)
}

/// [`oklab_signed`] of eight colours, a channel an array (the same operations, so the same
/// values).
#[inline(always)]
pub(crate) fn oklab8(r: [f32; 8], g: [f32; 8], b: [f32; 8]) -> [[f32; 8]; 3] {
    let mut out = [[0f32; 8]; 3];
    for k in 0..8 {
        let o = oklab_signed([r[k], g[k], b[k]]);
        for (c, v) in o.into_iter().enumerate() {
            out[c][k] = v;
        }
    }
    out
}

/// Oklab `[L, a, b]` of a linear-light RGB colour (values may stray outside 0..1 while error
/// is being diffused; the transform is defined there too).
#[inline]
pub fn oklab_of_linear(rgb: [f32; 3]) -> [f32; 3] {
    // Ottosson's two matrices with an exact cube root: the same operations, in the same
    // order, as `palette`'s `Oklab::from_color(LinSrgb)`, but a cube root that gives the
    // same bits natively and in WebAssembly ([`crate::fmath`]). Lightness is clamped to
    // 0..=1, as `into_color` clamps it.
    let [r, g, b] = rgb;
    let [l, m, s] = OKLAB_M1.map(|w| fm::cbrt(w[0] * r + w[1] * g + w[2] * b));
    let [ok_l, a, b] = OKLAB_M2.map(|w| w[0] * l + w[1] * m + w[2] * s);
    [ok_l.clamp(0.0, 1.0), a, b]
}

/// A palette prepared for matching: every entry in linear RGB and in Oklab, converted once.
#[derive(Clone, Debug)]
pub struct PaletteMatcher {
    srgb: Vec<[u8; 3]>,
    linear: Vec<[f32; 3]>,
    oklab: Vec<[f32; 3]>,
}

impl PaletteMatcher {
    /// Converts the palette once.
    pub fn new(palette: &Palette) -> PaletteMatcher {
        let linear: Vec<[f32; 3]> = palette
            .colours
            .iter()
            .map(|c| c.map(|v| srgb_to_linear(v as f64 / 255.0) as f32))
            .collect();
        let oklab = linear.iter().map(|&c| oklab_of_linear(c)).collect();
        PaletteMatcher {
            srgb: palette.colours.clone(),
            linear,
            oklab,
        }
    }

    /// Linear RGB of entry `i`.
    #[inline]
    pub fn linear(&self, i: usize) -> [f32; 3] {
        self.linear[i]
    }

    /// Index of the entry nearest in Oklab to a linear RGB colour. Equal distances go to the
    /// smaller colour value (then the earlier index, which has the same colour).
    pub fn nearest(&self, rgb: [f32; 3]) -> usize {
        let p = oklab_of_linear(rgb);
        let mut best = 0;
        let mut best_d = f32::INFINITY;
        for (i, q) in self.oklab.iter().enumerate() {
            let d = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2);
            if d < best_d || (d == best_d && self.srgb[i] < self.srgb[best]) {
                best = i;
                best_d = d;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_with_their_sizes() {
        let want = [
            ("bw", 2),
            ("eink-4", 4),
            ("epaper-7", 7),
            ("rgb-8", 8),
            ("cga-16", 16),
            ("gameboy", 4),
            ("pico-8", 16),
        ];
        for (n, len) in want {
            assert_eq!(Palette::builtin(n).unwrap().len(), len, "{n}");
        }
        assert_eq!(Palette::builtin_names().count(), want.len());
        assert_eq!(
            Palette::builtin("gameboy").unwrap().colours[0],
            [15, 56, 15]
        );
        assert_eq!(
            Palette::builtin("epaper-7").unwrap().colours[6],
            [255, 128, 0]
        );
    }

    #[test]
    fn hex_and_gpl_agree() {
        let hex = Palette::parse("# two\n#102030\nffeedd # light\n", "a.txt").unwrap();
        let gpl = Palette::parse(
            "GIMP Palette\nName: x\n#\n 16 32 48 dark\n255 238 221\n",
            "b.gpl",
        )
        .unwrap();
        assert_eq!(hex.colours, gpl.colours);
    }

    #[test]
    fn bad_files_name_file_and_line() {
        for (text, at) in [
            ("#000000\n#12345\n", "p.txt:2:"),
            ("#000000\nzzzzzz\n", "p.txt:2:"),
            ("#000000\n#ffffff red\n", "p.txt:2:"),
            ("#000000\n", "p.txt:0:"),
            ("GIMP Palette\n0 0 0\n1 2\n", "p.txt:3:"),
            ("GIMP Palette\n0 0 0\n1 2 300\n", "p.txt:3:"),
        ] {
            let e = Palette::parse(text, "p.txt").unwrap_err().to_string();
            assert!(e.starts_with(at), "{text:?}: {e}");
        }
    }
}
