//! `--color cmyk`: separation into four plates, each halftoned with its own screen, written
//! as `NAME-cyan.EXT`, `NAME-magenta.EXT`, `NAME-yellow.EXT`, `NAME-black.EXT`.

use std::path::Path;

use anyhow::{bail, Context};

use halftone::io::{self, Format};
use halftone::method::screen::ScreenMethod;
use halftone::press::icc::IccProfile;
use halftone::press::plates::{plate, plate_path, plate_tiff, preview, preview_coverages, INKS};
use halftone::press::separation::{Separation, SeparationOptions};
use halftone::press::transfer::Transfer;
use halftone::press::Press;
use halftone::raster::{ColorKind, PlaneRef, Planes, Samples, SamplesRef};
use halftone::tone::{linear_to_srgb, Encoding, ToneTable};
use halftone::{Image, Method, ToneOptions};

use super::convert::{CommonArgs, MethodName};
use super::screen_args::SeparationArg;

/// What prints the preview: the press model, or the ICC profile that made the plates.
pub enum Printed {
    /// The press model of `--press`.
    Press(Box<Press>),
    /// The profile of `--icc`.
    Icc(IccProfile),
}

/// The separation the arguments ask for (the press model's table takes about a second),
/// and what prints the preview (when one is asked for, or the separation needs it).
pub fn separation(a: &CommonArgs) -> anyhow::Result<(Separation, Option<Printed>)> {
    let s = &a.screen;
    if let Some(path) = &s.icc {
        let icc = IccProfile::load(path)?;
        let sep = icc.separation(s.intent.intent())?;
        return Ok((sep, Some(Printed::Icc(icc))));
    }
    if !(0.0..=100.0).contains(&s.gcr) {
        bail!("--gcr {}: must be a percentage from 0 to 100", s.gcr);
    }
    if !(100.0..=400.0).contains(&s.tac) {
        bail!("--tac {}: must be a percentage from 100 to 400", s.tac);
    }
    let opts = SeparationOptions {
        gcr: s.gcr / 100.0,
        tac: s.tac / 100.0,
    };
    let needs_press = s.separation == SeparationArg::Model || s.preview.is_some();
    let press = if needs_press {
        Some(Press::load(&s.press)?)
    } else {
        None
    };
    let sep = match (s.separation, &press) {
        (SeparationArg::Model, Some(p)) => Separation::model(p, opts),
        _ => Separation::naive(opts),
    };
    Ok((sep, press.map(|p| Printed::Press(Box::new(p)))))
}

/// Ink coverages (0..1) of every pixel, one plane per ink, as 16-bit codes of reflectance
/// `1 − coverage` (a linear plane), after the transfer curves.
pub fn ink_planes(img: &Image, sep: &Separation, transfer: Option<&Transfer>) -> Vec<Vec<u16>> {
    let n = img.width * img.height;
    let mut out = vec![vec![0u16; n]; 4];
    // 8-bit sRGB codes of each pixel (16-bit inputs are rounded: the table is 17³).
    let code = |p: &Samples, i: usize| -> u8 {
        let v = match p {
            Samples::U8(v) => v[i] as f64 / 255.0,
            Samples::U16(v) => v[i] as f64 / 65535.0,
        };
        let v = if img.encoding == Encoding::Linear {
            linear_to_srgb(v)
        } else {
            v
        };
        (v * 255.0).round() as u8
    };
    let mut cache: Option<([u8; 3], [u16; 4])> = None;
    for i in 0..n {
        let rgb = match img.color {
            ColorKind::Gray => {
                let g = code(&img.planes[0], i);
                [g, g, g]
            }
            ColorKind::Rgb => [
                code(&img.planes[0], i),
                code(&img.planes[1], i),
                code(&img.planes[2], i),
            ],
        };
        let v = match cache {
            Some((c, v)) if c == rgb => v,
            _ => {
                let cmyk = sep.cmyk(rgb);
                let v = [0, 1, 2, 3].map(|k| {
                    let a = cmyk[k].clamp(0.0, 1.0);
                    let a = transfer.map_or(a, |t| t.compensate(k, a));
                    ((1.0 - a) * 65535.0).round() as u16
                });
                cache = Some((rgb, v));
                v
            }
        };
        for (plane, &vk) in out.iter_mut().zip(&v) {
            plane[i] = vk;
        }
    }
    out
}

/// Separates `img`, halftones each plate, writes the four plates (and the preview).
pub fn write_plates(
    a: &CommonArgs,
    img: &Image,
    output: &Path,
    format: Format,
    method: &dyn Method,
    tone: &ToneOptions,
) -> anyhow::Result<()> {
    if output.as_os_str() == "-" {
        bail!("--color cmyk writes four plate files: give -o NAME.EXT, not stdout");
    }
    if a.palette.is_some() {
        bail!("--palette and --color cmyk do not go together");
    }
    // A preset's curve is for grey work: in CMYK the press model (or ICC profile) already
    // carries the press's dot gain, so only an explicit --transfer wedge applies.
    let transfer = a
        .screen
        .transfer
        .as_deref()
        .map(Transfer::load)
        .transpose()?;
    let (sep, press) = separation(a)?;
    let inks = ink_planes(img, &sep, transfer.as_ref());
    // The plates are linear planes; --dot-gain, --gamma and --invert still apply to them.
    let table = ToneTable::new(16, Encoding::Linear, tone);
    let planes = Planes {
        width: img.width,
        height: img.height,
        planes: inks
            .iter()
            .map(|p| PlaneRef {
                width: img.width,
                height: img.height,
                samples: SamplesRef::U16(p),
                tone: table.as_slice(),
            })
            .collect(),
    };
    let screened;
    let method: &dyn Method = if a.method == MethodName::Screen {
        screened = ScreenMethod::per_plane(a.screen.plate_screens(a.dpi)?.to_vec(), a.levels)?;
        &screened
    } else {
        method
    };
    let h = method.halftone(&planes)?;
    drop(planes);
    drop(inks);
    if format == Format::Pdf {
        // One PDF, one /Separation image a plate (a RIP or tiffsep1 gets the plates back).
        io::write_halftone(&h, output, &a.write_options(format))?;
    }
    for (c, ink) in INKS.iter().enumerate().filter(|_| format != Format::Pdf) {
        let path = plate_path(output, ink);
        if format == Format::Tiff {
            let bytes = plate_tiff(&h, c, ink, a.dpi)?;
            io::write_atomic(&path, |w| w.write_all(&bytes))?;
        } else {
            io::write_halftone(&plate(&h, c), &path, &a.write_options(format))?;
        }
    }
    if let (Some(path), Some(press)) = (&a.screen.preview, &press) {
        // One preview pixel for about two screen periods: averages the dots away.
        let dpi = a.dpi.unwrap_or(super::screen_args::DEFAULT_SCREEN_DPI);
        let lpi: f64 = a.screen.lpi.trim().parse().unwrap_or(106.0);
        let block = if let Some(b) = a.screen.preview_block {
            b.max(1)
        } else if a.method == MethodName::Screen {
            (2.0 * dpi / lpi).round() as usize
        } else {
            4
        };
        let (w, ht, rgb) = match press {
            Printed::Press(press) => preview(&h, press, block),
            Printed::Icc(icc) => {
                let (w, ht, cov) = preview_coverages(&h, block);
                (w, ht, icc.preview_srgb8(&cov)?.concat())
            }
        };
        let mut buf = Vec::new();
        image::RgbImage::from_raw(w as u32, ht as u32, rgb)
            .context("preview size")?
            .write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
            .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
        io::write_atomic(path, |w| w.write_all(&buf))?;
    }
    Ok(())
}
