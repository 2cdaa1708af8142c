//! Resizing to a device's size, in linear light, before halftoning.
//!
//! Averaging sRGB-encoded codes darkens fine detail (a black-and-white checkerboard shrinks
//! to code 128, 22% light, instead of 50%), so codes are decoded to 16-bit linear first and
//! the result keeps 16-bit linear codes ([`Encoding::Linear`]): no precision is lost before
//! the method. Lanczos-3 (fast_image_resize) for quality.

use fast_image_resize::images::{Image as FrImage, ImageRef as FrImageRef};
use fast_image_resize::{FilterType, PixelType, ResizeAlg, ResizeOptions, Resizer};

use crate::error::{Error, Result};
use crate::raster::{Image, Samples};
use crate::tone::{Encoding, ToneOptions, ToneTable};

/// Parses a physical length such as `4in`, `100mm`, `10cm` or `72pt` into inches.
pub fn parse_length(s: &str) -> Result<f64> {
    let s = s.trim();
    // The unit is the trailing run of letters (or `"`), so a number in scientific
    // notation (`1e2in`) keeps its exponent.
    let split = s
        .trim_end_matches(|c: char| c.is_ascii_alphabetic() || c == '"')
        .len();
    let (num, unit) = s.split_at(split);
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| Error::Invalid(format!("'{s}': not a length (try 4in, 100mm, 10cm)")))?;
    let inches = match unit.trim().to_ascii_lowercase().as_str() {
        "in" | "inch" | "\"" => v,
        "mm" => v / 25.4,
        "cm" => v / 2.54,
        "pt" => v / 72.0,
        "" => {
            return Err(Error::Invalid(format!(
                "'{s}': a length needs a unit (in, mm, cm, pt)"
            )))
        }
        u => return Err(Error::Invalid(format!("'{s}': unknown unit '{u}'"))),
    };
    if !(inches > 0.0 && inches.is_finite()) {
        return Err(Error::Invalid(format!(
            "'{s}': a length must be a positive, finite number"
        )));
    }
    Ok(inches)
}

/// The width in pixels of `--size s` at `dpi`, or an error when it is too large for a
/// number (`1e308in`).
fn size_pixels(s: &str, dpi: f64) -> Result<f64> {
    let px = (parse_length(s)? * dpi).round();
    if !px.is_finite() {
        return Err(Error::Invalid(format!(
            "`size` {s} at {dpi} dpi: the width in pixels is too large to compute (choose a \
             smaller size)"
        )));
    }
    Ok(px)
}

/// Target width in pixels from a pixel width, or a physical width at a resolution.
pub fn target_width(
    width: Option<usize>,
    size: Option<&str>,
    dpi: Option<f64>,
) -> Result<Option<usize>> {
    match (width, size) {
        (Some(_), Some(_)) => Err(Error::Invalid(
            "`width` and `size` both given: choose one".into(),
        )),
        (Some(0), None) => Err(Error::Invalid("`width` must be at least 1".into())),
        (Some(w), None) => Ok(Some(w)),
        (None, Some(s)) => {
            let dpi = dpi.ok_or_else(|| {
                Error::Invalid(format!("`size` {s} needs `dpi` to turn inches into pixels"))
            })?;
            let px = size_pixels(s, dpi)?;
            // Far beyond any pixel limit; `as usize` would saturate silently.
            if px >= 1e15 {
                return Err(Error::Invalid(format!(
                    "`size` {s} at {dpi} dpi makes a width of {px:.3e} pixels: far too large"
                )));
            }
            Ok(Some((px as usize).max(1)))
        }
        (None, None) => Ok(None),
    }
}

/// Quarter turns before resizing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Rotate {
    /// Keep the image as it is.
    #[default]
    None,
    /// Turn a portrait image a quarter clockwise for a landscape box (`--fit`), and the other
    /// way round; nothing when the shapes already agree.
    Auto,
    /// This many quarter turns clockwise (1, 2 or 3).
    Clockwise(u8),
}

/// How a picture goes into a box (`fit`, or a device's panel).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FitMode {
    /// The largest size inside the box, aspect kept: one side may be shorter than the box's.
    #[default]
    Inside,
    /// As `Inside`, then centred on a canvas of exactly the box (at `⌊(W − w)/2⌋`,
    /// `⌊(H − h)/2⌋`), the rest filled with the input's white (its largest code): paper, or a
    /// device's white ink.
    Pad,
    /// Scaled to cover the box, aspect kept, and cropped about the centre to exactly the box.
    Cover,
}

impl FitMode {
    /// Every name, in the order of the variants.
    pub const NAMES: &'static [&'static str] = &["inside", "pad", "cover"];

    /// The name, as the command line spells it.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
}

impl std::str::FromStr for FitMode {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "inside" => Ok(FitMode::Inside),
            "pad" => Ok(FitMode::Pad),
            "cover" => Ok(FitMode::Cover),
            _ => Err(crate::names::unknown("fit mode", s, Self::NAMES)),
        }
    }
}

impl std::fmt::Display for FitMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The size a user asked for, in any of the ways the command line allows.
#[derive(Clone, Debug, Default)]
pub struct SizeRequest<'a> {
    /// `--width`: pixels.
    pub width: Option<usize>,
    /// `--height`: pixels.
    pub height: Option<usize>,
    /// `--fit WxH`: a box; the picture goes into it as `fit_mode` says.
    pub fit: Option<(usize, usize)>,
    /// `--fit-mode`: how the picture goes into the `fit` box (`None`: [`FitMode::Inside`]);
    /// an error without a box.
    pub fit_mode: Option<FitMode>,
    /// `--size`: a physical width such as `4in`, with `dpi`.
    pub size: Option<&'a str>,
    /// Resolution for `size`.
    pub dpi: Option<f64>,
    /// `--rotate`.
    pub rotate: Rotate,
    /// `--max-pixels`: the output may not be larger either.
    pub max_pixels: u64,
    /// The `device` (a built-in's name or a profile's path) whose panel gave `fit`, when no
    /// size was given: messages about the box name it.
    pub device: Option<&'a str>,
}

/// What to do to an image before halftoning: quarter turns, then a resize, then (`pad`) a
/// white canvas around it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizePlan {
    /// Quarter turns clockwise (0–3).
    pub turns: u8,
    /// Width of the output (with `pad`, the canvas's).
    pub width: usize,
    /// Height of the output.
    pub height: usize,
    /// The size the whole turned image is scaled to: the output's, the picture's on the
    /// canvas with `pad`, larger than the output with `cover`.
    pub scaled: (usize, usize),
    /// `pad`: the picture's left and top on the canvas; `None`: the picture is the output.
    pub place: Option<(usize, usize)>,
    /// `cover`: the part of the turned image resized to the output (left, top, width,
    /// height, as fractions of its width and height); `None`: all of it.
    pub crop: Option<(f64, f64, f64, f64)>,
}

/// Parses a box such as `800x480` (also `800X480`, `800×480`).
pub fn parse_box(s: &str) -> Result<(usize, usize)> {
    let bad = || {
        Error::Invalid(format!(
            "`fit` '{s}': expected WIDTHxHEIGHT in pixels, e.g. 800x480"
        ))
    };
    let (w, h) = s.trim().split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    if w == 0 || h == 0 {
        return Err(Error::Invalid(format!(
            "`fit` '{s}': both sides must be at least 1"
        )));
    }
    Ok((w, h))
}

/// Works out the turns and the output size for an image of `src_w × src_h`; `None` when
/// nothing is asked, or the size asked for is the image's own. Every size is computed with
/// checked arithmetic and held to `req.max_pixels` before anything is allocated, so
/// `--width 1000000` is a one-line error, not an out-of-memory kill.
pub fn plan(req: &SizeRequest<'_>, src_w: usize, src_h: usize) -> Result<Option<SizePlan>> {
    let given = [
        req.width.map(|_| "`width`"),
        req.height.map(|_| "`height`"),
        req.fit.map(|_| "`fit`"),
        req.size.map(|_| "`size`"),
    ];
    let given: Vec<&str> = given.into_iter().flatten().collect();
    if let (Some(mode), None) = (req.fit_mode, req.fit) {
        return Err(Error::Invalid(format!(
            "`fit_mode` {mode} needs a box: give `fit` WxH, or a `device` without `width`, \
             `height` or `size`"
        )));
    }
    let mode = req.fit_mode.unwrap_or_default();
    let allowed = matches!(given.as_slice(), [] | [_] | ["`width`", "`height`"]);
    if !allowed {
        return Err(Error::Invalid(format!(
            "{} given together: choose one (`width` and `height` together set an exact size; \
             `fit` keeps the aspect ratio inside a box)",
            given.join(" and ")
        )));
    }
    for (flag, v) in [("`width`", req.width), ("`height`", req.height)] {
        if v == Some(0) {
            return Err(Error::Invalid(format!("{flag} must be at least 1")));
        }
    }
    let bounding = req.fit.or(match (req.width, req.height) {
        (Some(w), Some(h)) => Some((w, h)),
        _ => None,
    });
    let turns = match req.rotate {
        Rotate::None => 0,
        Rotate::Clockwise(n) => n % 4,
        Rotate::Auto => {
            let Some((bw, bh)) = bounding else {
                return Err(Error::Invalid(
                    "`rotate` auto turns the image to the shape of a box: give `fit` WxH".into(),
                ));
            };
            let box_landscape = bw > bh;
            let image_landscape = src_w > src_h;
            u8::from(bw != bh && src_w != src_h && box_landscape != image_landscape)
        }
    };
    let (sw, sh) = if turns % 2 == 1 {
        (src_h, src_w)
    } else {
        (src_w, src_h)
    };
    // Sizes in f64 first: a product of two usizes can overflow, a ratio cannot.
    let mut crop = None;
    let mut scaled = None;
    let (w, h): (f64, f64) = if let Some((bw, bh)) = req.fit {
        let (bwf, bhf, swf, shf) = (bw as f64, bh as f64, sw as f64, sh as f64);
        let inside = || {
            let scale = (bwf / swf).min(bhf / shf);
            (
                (swf * scale).round().clamp(1.0, bwf),
                (shf * scale).round().clamp(1.0, bhf),
            )
        };
        match mode {
            FitMode::Inside => inside(),
            FitMode::Pad => {
                scaled = Some(inside());
                (bwf, bhf)
            }
            FitMode::Cover => {
                // The box's shape cut from the middle of the image: its full width when
                // the box is wider for its height than the image, else its full height.
                // Compared as exact integer products, so the same shapes crop nothing.
                let (wide, tall) = (bw as u128 * sh as u128, bh as u128 * sw as u128);
                if wide > tall {
                    let r = tall as f64 / wide as f64;
                    crop = Some((0.0, (1.0 - r) / 2.0, 1.0, r));
                    scaled = Some((bwf, (bhf / r).ceil()));
                } else if wide < tall {
                    let r = wide as f64 / tall as f64;
                    crop = Some(((1.0 - r) / 2.0, 0.0, r, 1.0));
                    scaled = Some(((bwf / r).ceil(), bhf));
                }
                (bwf, bhf)
            }
        }
    } else {
        let width = match (req.width, req.size) {
            (Some(w), _) => Some(w as f64),
            (None, Some(s)) => {
                let dpi = req.dpi.ok_or_else(|| {
                    Error::Invalid(format!("`size` {s} needs `dpi` to turn inches into pixels"))
                })?;
                Some(size_pixels(s, dpi)?.max(1.0))
            }
            (None, None) => None,
        };
        match (width, req.height) {
            (Some(w), Some(h)) => (w, h as f64),
            (Some(w), None) => (w, (sh as f64 * w / sw as f64).round().max(1.0)),
            (None, Some(h)) => (
                (sw as f64 * h as f64 / sh as f64).round().max(1.0),
                h as f64,
            ),
            (None, None) if turns == 0 => return Ok(None),
            (None, None) => (sw as f64, sh as f64),
        }
    };
    let asked = given.first().copied().unwrap_or("`rotate`");
    let too_large = || match req.device {
        // The box is the panel's: the profile is what asked for it.
        Some(device) if asked == "`fit`" => Error::Invalid(format!(
            "`device` {device}: its panel makes the output {w:.0}x{h:.0} pixels, over the \
             limit of {} (check the profile's width and height, give a smaller `fit`, or \
             raise `max_pixels`)",
            req.max_pixels
        )),
        _ => Error::Invalid(format!(
            "{asked}: the output would be {w:.0}x{h:.0} pixels, over the limit of {} \
             (choose a smaller size, or raise `max_pixels`)",
            req.max_pixels
        )),
    };
    if !(w.is_finite() && h.is_finite()) || w > u32::MAX as f64 || h > u32::MAX as f64 {
        return Err(too_large());
    }
    let (w, h) = (w as usize, h as usize);
    match (w as u64).checked_mul(h as u64) {
        Some(n) if n <= req.max_pixels => {}
        _ => return Err(too_large()),
    }
    // The picture on the canvas (`pad`), or the whole image at the crop's scale (`cover`,
    // never allocated: it sizes shrink-on-load).
    let scaled = scaled.map_or((w, h), |(a, b)| (a as usize, b as usize));
    let place = (mode == FitMode::Pad && scaled != (w, h))
        .then(|| ((w - scaled.0) / 2, (h - scaled.1) / 2));
    if turns == 0 && (w, h) == (src_w, src_h) && place.is_none() && crop.is_none() {
        // The size asked for is the picture's own: nothing to do (and nothing to copy).
        return Ok(None);
    }
    Ok(Some(SizePlan {
        turns,
        width: w,
        height: h,
        scaled,
        place,
        crop,
    }))
}

/// Applies a [`SizePlan`]: turns, then resizes (in linear light when `tone.linearize`),
/// cropped (`cover`) or padded (`pad`) to the output's size.
pub fn apply(img: &Image, plan: &SizePlan, tone: &ToneOptions) -> Result<Image> {
    if plan.turns.is_multiple_of(4) {
        return fill(img, plan, tone, None);
    }
    let turned = rotate(img, plan.turns);
    fill(&turned, plan, tone, None)
}

/// The output of `plan` from `img`, already turned, of its part `extent` (left, top, width,
/// height: the full image's extent when `img` was shrunk on load; `None`: all of it): the
/// plan's crop of it resized to the output, or all of it resized and padded.
fn fill(
    img: &Image,
    plan: &SizePlan,
    tone: &ToneOptions,
    extent: Option<(f64, f64, f64, f64)>,
) -> Result<Image> {
    if let Some((x, y, w, h)) = plan.crop {
        let (ex, ey, ew, eh) = extent.unwrap_or((0.0, 0.0, img.width as f64, img.height as f64));
        let region = (ex + x * ew, ey + y * eh, w * ew, h * eh);
        return resize_region(img, plan.width, plan.height, tone, Some(region));
    }
    let (w, h) = plan.scaled;
    let picture = match extent {
        None => resize(img, w, h, tone)?,
        Some(e) => resize_region(img, w, h, tone, Some(e))?,
    };
    Ok(match plan.place {
        Some(at) => pad(&picture, plan.width, plan.height, at),
        None => picture,
    })
}

/// `img` on a `width × height` canvas of its white (the largest code: white in every
/// encoding) with its top left corner at `at`.
fn pad(img: &Image, width: usize, height: usize, at: (usize, usize)) -> Image {
    fn place<T: Copy>(
        src: &[T],
        white: T,
        w: usize,
        width: usize,
        height: usize,
        at: (usize, usize),
    ) -> Vec<T> {
        let mut out = vec![white; width * height];
        for (y, row) in src.chunks_exact(w).enumerate() {
            let start = (at.1 + y) * width + at.0;
            out[start..start + w].copy_from_slice(row);
        }
        out
    }
    let planes = img
        .planes
        .iter()
        .map(|p| match p {
            Samples::U8(v) => Samples::U8(place(v, u8::MAX, img.width, width, height, at)),
            Samples::U16(v) => Samples::U16(place(v, u16::MAX, img.width, width, height, at)),
        })
        .collect();
    Image {
        width,
        height,
        color: img.color,
        planes,
        encoding: img.encoding,
        dpi: img.dpi,
    }
}

/// What a decoded image stands for: the full image's size, the factor it was shrunk by on
/// load (1: not shrunk), and where the partial column and row lie (at the right, at the
/// bottom; a decoder that turns the image by its EXIF orientation moves them).
#[derive(Clone, Copy, Debug)]
pub struct Shrunk {
    /// The full image's size.
    pub full: (usize, usize),
    /// Each pixel stands for `factor × factor` of the full image's.
    pub factor: usize,
    /// The partial column is at the right (else the left), the partial row at the bottom
    /// (else the top).
    pub remainder_at: (bool, bool),
}

/// Applies a [`SizePlan`] made for an image of `s.full` size to `img`, that image shrunk on
/// load by `s.factor`: `⌈w/f⌉ × ⌈h/f⌉` pixels, each for `f × f` of the full image's, the
/// partial row and column where `s.remainder_at` says.
///
/// The resize reads `img` over the full image's extent exactly (`w/f × h/f` of its pixels,
/// a fractional crop), so every output pixel samples the same place as from the full
/// image. Resizing the whole of `img` instead stretches the image by up to `(f − 1)/w`:
/// on photos whose sides are no multiple of 3, shrunk by 3, that shift alone cost up to
/// 0.9 dB HVS-PSNR (tests/it/shrink.rs).
pub fn apply_shrunk(img: &Image, plan: &SizePlan, tone: &ToneOptions, s: Shrunk) -> Result<Image> {
    let f = s.factor as f64;
    let (ew, eh) = (s.full.0 as f64 / f, s.full.1 as f64 / f);
    let (sw, sh) = (img.width as f64, img.height as f64);
    // The full image's extent before turning: the partial column and row outside it.
    let x0 = if s.remainder_at.0 { 0.0 } else { sw - ew };
    let y0 = if s.remainder_at.1 { 0.0 } else { sh - eh };
    let crop = match plan.turns % 4 {
        0 => (x0, y0, ew, eh),
        // Clockwise: (x, y) goes to (sh − y, x).
        1 => (sh - (y0 + eh), x0, eh, ew),
        2 => (sw - (x0 + ew), sh - (y0 + eh), ew, eh),
        // Counter-clockwise: (x, y) goes to (y, sw − x).
        _ => (y0, sw - (x0 + ew), eh, ew),
    };
    if plan.turns.is_multiple_of(4) {
        return fill(img, plan, tone, Some(crop));
    }
    let turned = rotate(img, plan.turns);
    fill(&turned, plan, tone, Some(crop))
}

/// `img` turned `turns` quarter turns clockwise.
pub fn rotate(img: &Image, turns: u8) -> Image {
    let turns = turns % 4;
    let (w, h) = (img.width, img.height);
    let (ow, oh) = if turns % 2 == 1 { (h, w) } else { (w, h) };
    fn turn<T: Copy>(src: &[T], w: usize, h: usize, turns: u8) -> Vec<T> {
        match turns {
            0 => src.to_vec(),
            2 => src.iter().rev().copied().collect(),
            // Clockwise: output (x, y) of an h-wide image comes from input (y, h − 1 − x).
            1 => (0..w)
                .flat_map(|y| (0..h).map(move |x| src[(h - 1 - x) * w + y]))
                .collect(),
            // Counter-clockwise: output (x, y) comes from input (w − 1 − y, x).
            _ => (0..w)
                .flat_map(|y| (0..h).map(move |x| src[x * w + (w - 1 - y)]))
                .collect(),
        }
    }
    let planes = img
        .planes
        .iter()
        .map(|p| match p {
            Samples::U8(v) => Samples::U8(turn(v, w, h, turns)),
            Samples::U16(v) => Samples::U16(turn(v, w, h, turns)),
        })
        .collect();
    Image {
        width: ow,
        height: oh,
        color: img.color,
        planes,
        encoding: img.encoding,
        dpi: img.dpi,
    }
}

/// Resizes `img` to `width` pixels wide, keeping the aspect ratio, in linear light when
/// `tone.linearize` (otherwise in code space, the naive way). Returns 16-bit planes.
pub fn resize_to_width(img: &Image, width: usize, tone: &ToneOptions) -> Result<Image> {
    let height = ((img.height as f64 * width as f64 / img.width as f64).round() as usize).max(1);
    resize(img, width, height, tone)
}

/// Resizes `img` to `width × height` (Lanczos-3), in linear light when `tone.linearize`.
pub fn resize(img: &Image, width: usize, height: usize, tone: &ToneOptions) -> Result<Image> {
    if width == img.width && height == img.height {
        return Ok(img.clone());
    }
    resize_region(img, width, height, tone, None)
}

/// [`resize`] of the part of `img` in `crop` (left, top, width, height, in pixels, which
/// may be fractional), or of all of it.
fn resize_region(
    img: &Image,
    width: usize,
    height: usize,
    tone: &ToneOptions,
    crop: Option<(f64, f64, f64, f64)>,
) -> Result<Image> {
    let plain = ToneOptions {
        linearize: tone.linearize,
        ..ToneOptions::default()
    };
    let table = ToneTable::new(img.bits(), img.encoding, &plain);
    let t = table.as_slice();
    let encoding = if tone.linearize {
        Encoding::Linear
    } else {
        img.encoding
    };
    let mut opts = ResizeOptions::new().resize_alg(ResizeAlg::Convolution(FilterType::Lanczos3));
    if let Some((left, top, w, h)) = crop {
        opts = opts.crop(left, top, w, h);
    }
    let bad = |e: &dyn std::fmt::Display| Error::Invalid(format!("resize failed: {e}"));
    // Every code as the 16-bit code the filter reads (linear light, or the original codes
    // when not linearising), from a table: one rounding per code, not per sample.
    let lut: Vec<u16> = t.iter().map(|&v| (v * 65535.0).round() as u16).collect();
    // 16-bit codes that are already what the filter reads (linear light from a shrink, or
    // luminance) are filtered where they are.
    let identity = img.bits() == 16 && lut.iter().enumerate().all(|(c, &v)| v as usize == c);
    let one = |p: &Samples| -> Result<Samples> {
        let owned: Vec<u8>;
        let bytes: &[u8] = match p {
            Samples::U16(v) if identity => {
                // SAFETY: any u16 is two valid u8s, and u8 has no alignment to meet, so
                // the middle part is the whole slice.
                let (head, mid, tail) = unsafe { v.align_to::<u8>() };
                debug_assert!(head.is_empty() && tail.is_empty());
                mid
            }
            Samples::U8(v) => {
                owned = codes_to_bytes(v, &lut);
                &owned
            }
            Samples::U16(v) => {
                owned = codes_to_bytes(v, &lut);
                &owned
            }
        };
        let src = FrImageRef::new(img.width as u32, img.height as u32, bytes, PixelType::U16)
            .map_err(|e| bad(&e))?;
        let mut dst = FrImage::new(width as u32, height as u32, PixelType::U16);
        Resizer::new()
            .resize(&src, &mut dst, &opts)
            .map_err(|e| bad(&e))?;
        let out: Vec<u16> = dst
            .buffer()
            .chunks_exact(2)
            .map(|b| u16::from_ne_bytes([b[0], b[1]]))
            .collect();
        Ok(Samples::U16(out))
    };
    // Colour planes are independent: with a megapixel or more, the first is filtered on a
    // second thread while this one does the rest (the same bytes either way).
    let planes: Vec<Samples> = match &img.planes[..] {
        [first, rest @ ..] if !rest.is_empty() && img.width * img.height >= 1 << 20 => {
            std::thread::scope(|s| -> Result<Vec<Samples>> {
                let first = s.spawn(|| one(first));
                let rest: Vec<Samples> = rest.iter().map(one).collect::<Result<_>>()?;
                let mut all = vec![first.join().expect("resize thread")?];
                all.extend(rest);
                Ok(all)
            })?
        }
        planes => planes.iter().map(one).collect::<Result<_>>()?,
    };
    // Codes are now linear 16-bit (or the original scale, widened).
    let encoding = if tone.linearize {
        encoding
    } else {
        img.encoding
    };
    Ok(Image {
        width,
        height,
        color: img.color,
        planes,
        encoding,
        dpi: img.dpi,
    })
}

/// `codes` through `lut`, as the native-endian bytes of 16-bit samples.
fn codes_to_bytes<T: Copy>(codes: &[T], lut: &[u16]) -> Vec<u8>
where
    usize: From<T>,
{
    let mut out = vec![0u8; codes.len() * 2];
    for (o, &c) in out.chunks_exact_mut(2).zip(codes) {
        o.copy_from_slice(&lut[usize::from(c)].to_ne_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmath as fm;

    #[test]
    fn lengths() {
        assert_eq!(parse_length("4in").unwrap(), 4.0);
        assert!((parse_length("25.4mm").unwrap() - 1.0).abs() < 1e-12);
        assert!((parse_length("2.54 cm").unwrap() - 1.0).abs() < 1e-12);
        assert!(parse_length("4").is_err());
        assert!(parse_length("4parsecs").is_err());
        assert!(parse_length("-1in").is_err());
        assert_eq!(
            target_width(None, Some("2in"), Some(300.0)).unwrap(),
            Some(600)
        );
        assert!(target_width(None, Some("2in"), None).is_err());
    }

    #[test]
    fn checkerboard_halves_to_half_light_not_code_128() {
        let px: Vec<u8> = (0..64 * 64)
            .map(|i| if (i % 64 + i / 64) % 2 == 0 { 0 } else { 255 })
            .collect();
        let img = Image::gray8(64, 64, px);
        let small = resize(&img, 16, 16, &ToneOptions::default()).unwrap();
        assert_eq!(small.encoding, Encoding::Linear);
        let Samples::U16(v) = &small.planes[0] else {
            panic!("16-bit expected")
        };
        let mean = v.iter().map(|&c| c as f64 / 65535.0).sum::<f64>() / v.len() as f64;
        assert!((mean - 0.5).abs() < 0.01, "mean linear {mean}");
        // The naive way averages codes: 127.5/255 of code scale, i.e. 21% light.
        let naive = ToneOptions {
            linearize: false,
            ..Default::default()
        };
        let small = resize(&img, 16, 16, &naive).unwrap();
        assert_eq!(small.encoding, Encoding::Srgb);
        let t = small.tone_table(&ToneOptions::default());
        let p = small.planes(&t);
        assert!((p.planes[0].value(8, 8) - 0.214).abs() < 0.01);
    }

    fn req(max_pixels: u64) -> SizeRequest<'static> {
        SizeRequest {
            max_pixels,
            ..Default::default()
        }
    }

    #[test]
    fn fit_keeps_aspect_inside_the_box() {
        let box_ = SizeRequest {
            fit: Some((800, 480)),
            ..req(1 << 40)
        };
        // Portrait 3000x4000 into a landscape box: height-limited.
        let p = plan(&box_, 3000, 4000).unwrap().unwrap();
        assert_eq!((p.turns, p.width, p.height), (0, 360, 480));
        // Turned for the box: now 4000x3000, width... height-limited again at 640x480.
        let turned = SizeRequest {
            rotate: Rotate::Auto,
            ..box_.clone()
        };
        let p = plan(&turned, 3000, 4000).unwrap().unwrap();
        assert_eq!((p.turns, p.width, p.height), (1, 640, 480));
        // Already landscape: no turn.
        let p = plan(&turned, 1600, 900).unwrap().unwrap();
        assert_eq!((p.turns, p.width, p.height), (0, 800, 450));
        assert!(plan(
            &SizeRequest {
                rotate: Rotate::Auto,
                ..req(1 << 40)
            },
            10,
            20
        )
        .is_err());
    }

    #[test]
    fn pad_centres_and_cover_crops_to_exactly_the_box() {
        let mode = |m| SizeRequest {
            fit: Some((800, 480)),
            fit_mode: Some(m),
            ..req(1 << 40)
        };
        // 3:2 into 5:3: 720x480 inside, centred at 40 on the canvas.
        let p = plan(&mode(FitMode::Pad), 600, 400).unwrap().unwrap();
        assert_eq!(
            (p.width, p.height, p.scaled, p.place),
            (800, 480, (720, 480), Some((40, 0)))
        );
        assert_eq!(p.crop, None);
        // Odd margins: the extra pixel goes right (and below).
        let p = plan(&mode(FitMode::Pad), 601, 400).unwrap().unwrap();
        assert_eq!((p.scaled, p.place), ((721, 480), Some((39, 0))));
        // The picture's own size is padded, not resized; the box's shape is left alone.
        let p = plan(&mode(FitMode::Pad), 720, 480).unwrap().unwrap();
        assert_eq!((p.scaled, p.place), ((720, 480), Some((40, 0))));
        assert_eq!(plan(&mode(FitMode::Pad), 800, 480).unwrap(), None);
        assert_eq!(plan(&mode(FitMode::Cover), 800, 480).unwrap(), None);
        // Cover: the full height, the middle 5:3 of the width.
        let p = plan(&mode(FitMode::Cover), 600, 400).unwrap().unwrap();
        assert_eq!(
            (p.width, p.height, p.scaled, p.place),
            (800, 480, (800, 534), None)
        );
        let (x, y, w, h) = p.crop.unwrap();
        assert_eq!((x, w), (0.0, 1.0));
        assert!(
            (h - 0.9).abs() < 1e-12 && (y - 0.05).abs() < 1e-12,
            "{y} {h}"
        );
        // A tall image: the full width, the middle fifth of the height.
        let p = plan(&mode(FitMode::Cover), 300, 900).unwrap().unwrap();
        let (x, y, w, h) = p.crop.unwrap();
        assert_eq!((p.width, p.height, x, w), (800, 480, 0.0, 1.0));
        assert!(
            (h - 0.2).abs() < 1e-12 && (y - 0.4).abs() < 1e-12,
            "{y} {h}"
        );
        // A wide one: the full height, the middle of the width.
        let p = plan(&mode(FitMode::Cover), 1000, 300).unwrap().unwrap();
        let (x, y, w, h) = p.crop.unwrap();
        assert_eq!((p.scaled, y, h), ((1600, 480), 0.0, 1.0));
        assert!(
            (w - 0.5).abs() < 1e-12 && (x - 0.25).abs() < 1e-12,
            "{x} {w}"
        );
        // A mode without a box is an error, naming both.
        let e = plan(
            &SizeRequest {
                fit_mode: Some(FitMode::Pad),
                width: Some(10),
                ..req(1 << 40)
            },
            20,
            20,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("`fit_mode` pad needs a box") && e.contains("`fit`"),
            "{e}"
        );
        assert_eq!("Cover".parse::<FitMode>().unwrap(), FitMode::Cover);
        assert!("fill".parse::<FitMode>().is_err());
    }

    #[test]
    fn padding_is_the_inputs_white_around_the_picture() {
        let req = SizeRequest {
            fit: Some((6, 3)),
            fit_mode: Some(FitMode::Pad),
            ..req(1 << 40)
        };
        let img = Image::gray8(2, 3, vec![0, 10, 20, 30, 40, 50]);
        let p = plan(&req, 2, 3).unwrap().unwrap();
        let out = apply(&img, &p, &ToneOptions::default()).unwrap();
        assert_eq!((out.width, out.height), (6, 3));
        let Samples::U8(v) = &out.planes[0] else {
            panic!("the picture's own size keeps its codes")
        };
        #[rustfmt::skip]
        assert_eq!(v, &[255, 255, 0, 10, 255, 255,
                        255, 255, 20, 30, 255, 255,
                        255, 255, 40, 50, 255, 255]);
        // Resized: 16-bit linear codes, white 65535 in every plane around it.
        let rgb = Image::rgb8(4, 6, &[7; 4 * 6 * 3]);
        let p = plan(&req, 4, 6).unwrap().unwrap();
        assert_eq!((p.scaled, p.place), ((2, 3), Some((2, 0))));
        let out = apply(&rgb, &p, &ToneOptions::default()).unwrap();
        assert_eq!(out.encoding, Encoding::Linear);
        for plane in &out.planes {
            let Samples::U16(v) = plane else { panic!() };
            for (i, &c) in v.iter().enumerate() {
                let inside = (2..4).contains(&(i % 6));
                assert_eq!(c == u16::MAX, !inside, "{i}: {c}");
            }
        }
    }

    #[test]
    fn cover_from_a_shrunk_image_samples_the_same_place() {
        // A horizontal ramp, 3:1, covering a 2:1 box: the middle two thirds of its width.
        let (w, h) = (96, 32);
        let px: Vec<u8> = (0..w * h).map(|i| (i % w * 255 / (w - 1)) as u8).collect();
        let img = Image::gray8(w, h, px);
        let req = SizeRequest {
            fit: Some((16, 8)),
            fit_mode: Some(FitMode::Cover),
            ..req(1 << 40)
        };
        let p = plan(&req, w, h).unwrap().unwrap();
        let full = apply(&img, &p, &ToneOptions::default()).unwrap();
        let shrunk = resize(&img, w / 4, h / 4, &ToneOptions::default()).unwrap();
        let s = Shrunk {
            full: (w, h),
            factor: 4,
            remainder_at: (true, true),
        };
        let from_shrunk = apply_shrunk(&shrunk, &p, &ToneOptions::default(), s).unwrap();
        let (Samples::U16(a), Samples::U16(b)) = (&full.planes[0], &from_shrunk.planes[0]) else {
            panic!()
        };
        assert_eq!((from_shrunk.width, from_shrunk.height), (16, 8));
        // The crop starts a sixth of the way along the ramp (about 1900 in linear 16-bit
        // codes at the first pixel's centre), not at its left end (about 160).
        assert!(a[0] > 1000 && b[0] > 1000, "{} {}", a[0], b[0]);
        for (x, y) in a.iter().zip(b) {
            assert!((*x as i32 - *y as i32).abs() < 1200, "{x} {y}");
        }
    }

    #[test]
    fn the_pictures_own_size_is_no_resize() {
        let same = SizeRequest {
            width: Some(400),
            ..req(1 << 40)
        };
        assert_eq!(plan(&same, 400, 200).unwrap(), None);
        let fit = SizeRequest {
            fit: Some((800, 200)),
            ..req(1 << 40)
        };
        assert_eq!(plan(&fit, 400, 200).unwrap(), None);
        assert!(plan(&same, 401, 200).unwrap().is_some());
    }

    #[test]
    fn height_and_limits() {
        let h = SizeRequest {
            height: Some(100),
            ..req(1 << 40)
        };
        let p = plan(&h, 400, 200).unwrap().unwrap();
        assert_eq!((p.width, p.height), (200, 100));
        let huge = SizeRequest {
            width: Some(1_000_000),
            ..req(1_000_000_000)
        };
        let e = plan(&huge, 4000, 3000).unwrap_err().to_string();
        assert!(
            e.contains("`width`") && !e.contains("--") && e.contains("1000000x750000"),
            "{e}"
        );
        let absurd = SizeRequest {
            width: Some(usize::MAX),
            ..req(u64::MAX)
        };
        assert!(plan(&absurd, 1, 3).is_err());
        let both = SizeRequest {
            width: Some(10),
            fit: Some((10, 10)),
            ..req(1 << 40)
        };
        assert!(plan(&both, 10, 10).is_err());
        assert!(parse_box("800x480").unwrap() == (800, 480));
        assert!(parse_box("800").is_err() && parse_box("0x5").is_err());
    }

    #[test]
    fn rotation_moves_pixels_clockwise() {
        // 3x2:  a b c      turned clockwise (2x3):  d a
        //       d e f                               e b
        //                                           f c
        let img = Image::gray8(3, 2, vec![1, 2, 3, 4, 5, 6]);
        let r = rotate(&img, 1);
        assert_eq!((r.width, r.height), (2, 3));
        assert_eq!(r.planes[0], Samples::U8(vec![4, 1, 5, 2, 6, 3]));
        let back = rotate(&r, 3);
        assert_eq!(back.planes[0], img.planes[0]);
        assert_eq!(
            rotate(&img, 2).planes[0],
            Samples::U8(vec![6, 5, 4, 3, 2, 1])
        );
    }

    #[test]
    fn shrunk_images_are_read_over_the_full_extent_in_every_turn() {
        // A 301 × 203 pattern (no multiple of 3) shrunk by boxes of 3 in linear light, then
        // resized through apply_shrunk, lands where the full image's resize does, in every
        // quarter turn: closer than resizing the whole shrunk image, which stretches it.
        let (w, h, f) = (301usize, 203usize, 3usize);
        let px: Vec<u8> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (127.5 + 120.0 * (fm::sin(x * 0.21) * fm::cos(y * 0.17))) as u8
            })
            .collect();
        let full = Image::gray8(w, h, px);
        let tone = ToneOptions::default();
        let t = ToneTable::new(8, Encoding::Srgb, &tone);
        let lut: Vec<u32> = t
            .as_slice()
            .iter()
            .map(|&v| (v as f64 * 65535.0 * 256.0).round() as u32)
            .collect();
        let (sw, sh) = (w.div_ceil(f), h.div_ceil(f));
        let mut shrunk = vec![0u16; sw * sh];
        let Samples::U8(codes) = &full.planes[0] else {
            unreachable!()
        };
        crate::pipeline::shrink::box_plane(codes, w, f, &lut, &mut vec![0; sw], &mut shrunk);
        let small = Image {
            width: sw,
            height: sh,
            color: full.color,
            planes: vec![Samples::U16(shrunk)],
            encoding: Encoding::Linear,
            dpi: None,
        };
        let diff = |a: &Image, b: &Image| {
            let (Samples::U16(a), Samples::U16(b)) = (&a.planes[0], &b.planes[0]) else {
                panic!("16-bit planes")
            };
            let sum: f64 = a
                .iter()
                .zip(b)
                .map(|(&a, &b)| (a as f64 - b as f64).abs())
                .sum();
            sum / a.len() as f64
        };
        for turns in 0..4 {
            let (width, height) = if turns % 2 == 1 { (41, 60) } else { (60, 41) };
            let plan = SizePlan {
                turns,
                width,
                height,
                scaled: (width, height),
                place: None,
                crop: None,
            };
            let want = apply(&full, &plan, &tone).unwrap();
            let s = Shrunk {
                full: (w, h),
                factor: f,
                remainder_at: (true, true),
            };
            let got = apply_shrunk(&small, &plan, &tone, s).unwrap();
            let stretched = apply(&small, &plan, &tone).unwrap();
            let (d, s) = (diff(&got, &want), diff(&stretched, &want));
            assert!(
                d < 0.5 * s,
                "turns {turns}: {d:.1} against {s:.1} stretched"
            );
            // The crop at the top left whatever the turn: wrong for every turn but none.
            let (ew, eh) = (w as f64 / f as f64, h as f64 / f as f64);
            let (cw, ch) = if turns % 2 == 1 { (eh, ew) } else { (ew, eh) };
            let turned = rotate(&small, turns);
            let corner = resize_region(
                &turned,
                plan.width,
                plan.height,
                &tone,
                Some((0.0, 0.0, cw, ch)),
            )
            .unwrap();
            let c = diff(&corner, &want);
            eprintln!("turns {turns}: {d:.1} (top-left crop {c:.1}, stretched {s:.1})");
            if turns > 0 {
                assert!(
                    d < 0.5 * c,
                    "turns {turns}: {d:.1} against {c:.1} at the corner"
                );
            }
        }
    }

    #[test]
    fn keeps_aspect() {
        let img = Image::gray8(40, 20, vec![100; 800]);
        let r = resize_to_width(&img, 10, &ToneOptions::default()).unwrap();
        assert_eq!((r.width, r.height), (10, 5));
    }
}
