//! Resizing to a device's size, in linear light, before halftoning.
//!
//! Averaging sRGB-encoded codes darkens fine detail (a black-and-white checkerboard shrinks
//! to code 128, 22% light, instead of 50%), so codes are decoded to 16-bit linear first and
//! the result keeps 16-bit linear codes ([`Encoding::Linear`]): no precision is lost before
//! the method. Lanczos-3 (fast_image_resize) for quality.

use fast_image_resize::images::Image as FrImage;
use fast_image_resize::{FilterType, PixelType, ResizeAlg, ResizeOptions, Resizer};

use crate::error::{Error, Result};
use crate::raster::{Image, Samples};
use crate::tone::{Encoding, ToneOptions, ToneTable};

/// Parses a physical length such as `4in`, `100mm`, `10cm` or `72pt` into inches.
pub fn parse_length(s: &str) -> Result<f64> {
    let s = s.trim();
    let split = s.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(s.len());
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
        return Err(Error::Invalid(format!("'{s}': a length must be positive")));
    }
    Ok(inches)
}

/// Target width in pixels from a pixel width, or a physical width at a resolution.
pub fn target_width(
    width: Option<usize>,
    size: Option<&str>,
    dpi: Option<f64>,
) -> Result<Option<usize>> {
    match (width, size) {
        (Some(_), Some(_)) => Err(Error::Invalid(
            "--width and --size both given: choose one".into(),
        )),
        (Some(0), None) => Err(Error::Invalid("--width must be at least 1".into())),
        (Some(w), None) => Ok(Some(w)),
        (None, Some(s)) => {
            let dpi = dpi.ok_or_else(|| {
                Error::Invalid(format!("--size {s} needs --dpi to turn inches into pixels"))
            })?;
            Ok(Some(((parse_length(s)? * dpi).round() as usize).max(1)))
        }
        (None, None) => Ok(None),
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
    let mut resizer = Resizer::new();
    let opts = ResizeOptions::new().resize_alg(ResizeAlg::Convolution(FilterType::Lanczos3));
    let bad = |e: &dyn std::fmt::Display| Error::Invalid(format!("resize failed: {e}"));
    let planes = img
        .planes
        .iter()
        .map(|p| {
            // 16-bit codes (linear light, or the original codes when not linearising).
            let codes: Vec<u16> = match p {
                Samples::U8(v) => v
                    .iter()
                    .map(|&c| (t[c as usize] * 65535.0).round() as u16)
                    .collect(),
                Samples::U16(v) => v
                    .iter()
                    .map(|&c| (t[c as usize] * 65535.0).round() as u16)
                    .collect(),
            };
            let bytes: Vec<u8> = codes.iter().flat_map(|c| c.to_ne_bytes()).collect();
            let src =
                FrImage::from_vec_u8(img.width as u32, img.height as u32, bytes, PixelType::U16)
                    .map_err(|e| bad(&e))?;
            let mut dst = FrImage::new(width as u32, height as u32, PixelType::U16);
            resizer.resize(&src, &mut dst, &opts).map_err(|e| bad(&e))?;
            let out: Vec<u16> = dst
                .buffer()
                .chunks_exact(2)
                .map(|b| u16::from_ne_bytes([b[0], b[1]]))
                .collect();
            Ok(Samples::U16(out))
        })
        .collect::<Result<Vec<_>>>()?;
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

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn keeps_aspect() {
        let img = Image::gray8(40, 20, vec![100; 800]);
        let r = resize_to_width(&img, 10, &ToneOptions::default()).unwrap();
        assert_eq!((r.width, r.height), (10, 5));
    }
}
