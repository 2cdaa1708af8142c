//! CMYK plates on the road: separation (press model or ICC profile), the four ink planes
//! halftoned, each with its own screen, the preview, and the plate files.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::{self, Format};
use crate::method::screen::ScreenMethod;
use crate::options::{MethodKind, Options, SeparationKind, DEFAULT_SCREEN_DPI};
#[cfg(feature = "icc")]
use crate::press::icc::IccProfile;
use crate::press::plates::{plate, plate_path, plate_tiff, preview, INKS};
use crate::press::separation::{Separation, SeparationOptions};
use crate::press::transfer::Transfer;
use crate::press::Press;
use crate::raster::{ColorKind, Halftone, Image, PlaneRef, Planes, Samples, SamplesRef};
use crate::tone::{linear_to_srgb, Encoding, ToneOptions, ToneTable};
use crate::Method;

/// What prints the preview: the press model, or the ICC profile that made the plates.
pub enum Printed {
    /// The press model of `press`.
    Press(Box<Press>),
    /// The profile of `icc`.
    #[cfg(feature = "icc")]
    Icc(IccProfile),
}

/// The separation the options ask for (the press model's table takes about a second), and
/// what prints the preview (when one is asked for, or the separation needs it).
pub fn separation(o: &Options) -> Result<(Separation, Option<Printed>)> {
    if let Some(path) = &o.icc {
        #[cfg(feature = "icc")]
        {
            let icc = IccProfile::load(path)?;
            let sep = icc.separation(o.intent.unwrap_or_default())?;
            return Ok((sep, Some(Printed::Icc(icc))));
        }
        #[cfg(not(feature = "icc"))]
        return Err(Error::Option {
            field: "icc",
            value: path.display().to_string(),
            msg: "ICC profiles need the library's `icc` feature (Little CMS)".into(),
        });
    }
    if !(0.0..=100.0).contains(&o.gcr) {
        return Err(Error::Option {
            field: "gcr",
            value: o.gcr.to_string(),
            msg: "must be a percentage from 0 to 100".into(),
        });
    }
    if !(100.0..=400.0).contains(&o.tac) {
        return Err(Error::Option {
            field: "tac",
            value: o.tac.to_string(),
            msg: "must be a percentage from 100 to 400".into(),
        });
    }
    let opts = SeparationOptions {
        gcr: o.gcr / 100.0,
        tac: o.tac / 100.0,
    };
    let needs_press = o.separation == SeparationKind::Model || o.preview;
    let press = if needs_press {
        Some(Press::load(&o.press)?)
    } else {
        None
    };
    let sep = match (o.separation, &press) {
        (SeparationKind::Model, Some(p)) => Separation::model(p, opts),
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

/// The four plates of an image and, when asked for, how they print.
pub struct Separated {
    /// Cyan, magenta, yellow and black planes.
    pub halftone: Halftone,
    /// The preview: width, height, interleaved sRGB bytes.
    pub preview: Option<(usize, usize, Vec<u8>)>,
}

/// Separates `img` (already resized) and halftones each plate with `method`, or with one
/// screen a plate for [`MethodKind::Screen`].
pub fn separate(
    img: &Image,
    o: &Options,
    method: &dyn Method,
    tone: &ToneOptions,
) -> Result<Separated> {
    if o.palette.is_some() {
        return Err(Error::Invalid(
            "a palette and CMYK plates do not go together".into(),
        ));
    }
    // A preset's curve is for grey work: in CMYK the press model (or ICC profile) already
    // carries the press's dot gain, so only an explicit transfer wedge applies.
    let transfer = o.transfer.as_deref().map(Transfer::load).transpose()?;
    let (sep, press) = separation(o)?;
    let inks = ink_planes(img, &sep, transfer.as_ref());
    // The plates are linear planes; dot gain, gamma and invert still apply to them.
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
    let method: &dyn Method = if o.method == MethodKind::Screen {
        screened = ScreenMethod::per_plane(o.plate_screens()?.to_vec(), o.levels)?;
        &screened
    } else {
        method
    };
    let h = method.halftone(&planes)?;
    drop(planes);
    drop(inks);
    let preview = match (o.preview, &press) {
        (true, Some(press)) => {
            // One preview pixel for about two screen periods: averages the dots away.
            let dpi = o.dpi.unwrap_or(DEFAULT_SCREEN_DPI);
            let lpi: f64 = o.lpi.trim().parse().unwrap_or(106.0);
            let block = if let Some(b) = o.preview_block {
                b.max(1)
            } else if o.method == MethodKind::Screen {
                (2.0 * dpi / lpi).round() as usize
            } else {
                4
            };
            Some(match press {
                Printed::Press(press) => preview(&h, press, block),
                #[cfg(feature = "icc")]
                Printed::Icc(icc) => {
                    let (w, ht, cov) = crate::press::plates::preview_coverages(&h, block);
                    (w, ht, icc.preview_srgb8(&cov)?.concat())
                }
            })
        }
        _ => None,
    };
    Ok(Separated {
        halftone: h,
        preview,
    })
}

/// Writes the plates of `h`: one PDF with a separation image a plate, or one file a plate
/// named after `output` (`poster-cyan.tif`, …; TIFF plates carry their ink's name).
pub fn write(h: &Halftone, output: &Path, format: Format, o: &Options) -> Result<()> {
    if format == Format::Pdf {
        // One PDF, one /Separation image a plate (a RIP or tiffsep1 gets the plates back).
        return io::write_halftone(h, output, &o.write_options(format));
    }
    for (c, ink) in INKS.iter().enumerate() {
        let path = plate_path(output, ink);
        if format == Format::Tiff {
            let bytes = plate_tiff(h, c, ink, o.dpi)?;
            io::write_atomic(&path, |w| w.write_all(&bytes))?;
        } else {
            io::write_halftone(&plate(h, c), &path, &o.write_options(format))?;
        }
    }
    Ok(())
}
