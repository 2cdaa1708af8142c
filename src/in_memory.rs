//! Entry points for callers that hold pixels in their own memory (a numpy array, a frame
//! buffer): interleaved samples made into an [`Image`] the way the decoder makes one from a
//! file, and a grey 8-bit buffer halftoned in place, without copying it, when the options
//! ask for no resizing or turning.

use crate::error::{Error, Result};
use crate::options::Color;
use crate::raster::{ColorKind, Halftone, Image, PlaneRef, Planes, Samples, SamplesRef};
use crate::tone::{Encoding, ToneTable};
use crate::{ColorMode, Converter};

/// Checks that `len` samples make `width × height` pixels of `channels` each.
fn check_len(width: usize, height: usize, channels: usize, len: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Invalid(format!(
            "the image is empty ({width}x{height} pixels)"
        )));
    }
    if !(1..=4).contains(&channels) {
        return Err(Error::Invalid(format!(
            "{channels} channels a pixel: expected 1 (grey), 2 (grey and alpha), 3 (RGB) or 4 (RGBA)"
        )));
    }
    let want = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels));
    if want != Some(len) {
        return Err(Error::Invalid(format!(
            "{len} samples do not make {width}x{height} pixels of {channels} channels"
        )));
    }
    Ok(())
}

/// Checks an array of `height × width` pixels of `channels` samples of `sample_bytes` each
/// against the limits a file meets, before anything is allocated or copied: at most
/// `max_pixels` pixels, and samples within the decode budget of that limit (1 byte a
/// pixel of it, at least 64 MiB), which bounds a file's decoded samples too. A shape
/// whose sizes overflow is over the limit.
pub fn check_array(
    width: usize,
    height: usize,
    channels: usize,
    sample_bytes: usize,
    max_pixels: u64,
) -> Result<()> {
    let pixels = (width as u64).checked_mul(height as u64);
    if pixels.is_none_or(|p| p > max_pixels) {
        let shown = pixels.map_or_else(|| "more than 2^64".to_string(), |p| p.to_string());
        return Err(Error::Invalid(format!(
            "the image array is {width}x{height} = {shown} pixels, over the limit of \
             {max_pixels} (raise it with `max_pixels`)"
        )));
    }
    let budget = crate::io::decode_budget(&crate::io::ReadOptions { max_pixels });
    let bytes = pixels
        .and_then(|p| p.checked_mul(channels as u64))
        .and_then(|n| n.checked_mul(sample_bytes as u64));
    if bytes.is_none_or(|b| b > budget) {
        return Err(Error::Invalid(format!(
            "the image array is {width}x{height} pixels of {channels} samples of {sample_bytes} \
             byte(s): over the limit of {budget} bytes of samples that `max_pixels` \
             {max_pixels} sets (1 byte a pixel of it, as for a decoded file; raise \
             `max_pixels`)"
        )));
    }
    Ok(())
}

/// A vector of `n` default values, or an error when the memory cannot be had (never an
/// abort).
fn try_vec<T: Copy + Default>(n: usize) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        Error::Invalid(format!(
            "cannot allocate {} bytes for the image's samples",
            n.saturating_mul(std::mem::size_of::<T>())
        ))
    })?;
    v.resize(n, T::default());
    Ok(v)
}

/// Splits interleaved samples into planes; with alpha (2 or 4 channels), composites over
/// paper white in linear light as the decoder does for a file (`composite`). Memory that
/// cannot be had is an error, not an abort.
fn planes_of<T: Copy + Default + Send + Sync>(
    data: &[T],
    channels: usize,
    composite: impl Fn(&[T], usize) -> Vec<Vec<T>>,
) -> Result<Vec<Vec<T>>> {
    if channels == 2 || channels == 4 {
        // Room for the planes made, tried first (reserved, not touched, then given back):
        // the compositing allocates them itself.
        let n = data.len() / channels * (channels - 1);
        Vec::<T>::new()
            .try_reserve_exact(n)
            .map_err(|_| Error::Invalid(format!("cannot allocate {n} samples")))?;
        return Ok(composite(data, channels - 1));
    }
    if channels == 1 {
        let mut v = Vec::new();
        v.try_reserve_exact(data.len())
            .map_err(|_| Error::Invalid(format!("cannot allocate {} samples", data.len())))?;
        v.extend_from_slice(data);
        return Ok(vec![v]);
    }
    deinterleave3(data)
}

/// Three planes from interleaved RGB, in one pass over the samples, blocks of pixels on
/// every worker thread (a strided copy a plane at a time read the input three times).
fn deinterleave3<T: Copy + Default + Send + Sync>(data: &[T]) -> Result<Vec<Vec<T>>> {
    use rayon::prelude::*;
    const BLOCK: usize = 1 << 16;
    let n = data.len() / 3;
    let mut planes = [try_vec(n)?, try_vec(n)?, try_vec(n)?];
    let [r, g, b] = &mut planes;
    r.par_chunks_mut(BLOCK)
        .zip(g.par_chunks_mut(BLOCK))
        .zip(b.par_chunks_mut(BLOCK))
        .zip(data.par_chunks(3 * BLOCK))
        .for_each(|(((r, g), b), src)| {
            for (i, px) in src.chunks_exact(3).enumerate() {
                r[i] = px[0];
                g[i] = px[1];
                b[i] = px[2];
            }
        });
    Ok(planes.into())
}

/// Linear-light codes over white: `c' = a·c + (1 − a)·max`, exact per pixel.
fn composite_linear<T: Copy + Into<f64>>(
    src: &[T],
    channels: usize,
    max: f64,
    make: impl Fn(f64) -> T,
) -> Vec<Vec<T>> {
    let n = src.len() / (channels + 1);
    let mut planes: Vec<Vec<T>> = (0..channels).map(|_| Vec::with_capacity(n)).collect();
    for px in src.chunks_exact(channels + 1) {
        let a = px[channels].into() / max;
        for (c, plane) in planes.iter_mut().enumerate() {
            plane.push(make((a * px[c].into() + (1.0 - a) * max).round()));
        }
    }
    planes
}

/// An image from interleaved 8-bit samples, `channels` a pixel (grey, grey + alpha, RGB,
/// RGBA), row-major, with `encoding` saying what light the codes are.
pub fn image_u8(
    width: usize,
    height: usize,
    channels: usize,
    data: &[u8],
    encoding: Encoding,
) -> Result<Image> {
    check_len(width, height, channels, data.len())?;
    let planes = planes_of(data, channels, |d, c| match encoding {
        Encoding::Srgb => crate::io::composite8(d, c),
        Encoding::Linear => composite_linear(d, c, 255.0, |v| v as u8),
    })?;
    Ok(image_of(
        width,
        height,
        planes.into_iter().map(Samples::U8).collect(),
        encoding,
    ))
}

/// [`image_u8`] for 16-bit samples.
pub fn image_u16(
    width: usize,
    height: usize,
    channels: usize,
    data: &[u16],
    encoding: Encoding,
) -> Result<Image> {
    check_len(width, height, channels, data.len())?;
    let planes = planes_of(data, channels, |d, c| match encoding {
        Encoding::Srgb => crate::io::composite16(d, c),
        Encoding::Linear => composite_linear(d, c, 65535.0, |v| v as u16),
    })?;
    Ok(image_of(
        width,
        height,
        planes.into_iter().map(Samples::U16).collect(),
        encoding,
    ))
}

fn image_of(width: usize, height: usize, planes: Vec<Samples>, encoding: Encoding) -> Image {
    Image {
        width,
        height,
        color: if planes.len() == 3 {
            ColorKind::Rgb
        } else {
            ColorKind::Gray
        },
        planes,
        encoding,
        dpi: None,
    }
}

/// Halftones a grey 8-bit buffer (`width × height` codes, row-major) with `conv`, reading
/// the caller's memory as it is. `None` when the options need the image copied first
/// (resizing, turning, CMYK separation): then convert an [`Image`] instead. The halftone is
/// the one [`Converter::convert`] makes from the same pixels.
pub fn halftone_gray8(
    conv: &Converter,
    width: usize,
    height: usize,
    data: &[u8],
    encoding: Encoding,
) -> Result<Option<Halftone>> {
    check_len(width, height, 1, data.len())?;
    let opts = conv.options();
    if opts.color == Color::Cmyk
        || crate::resize::plan(&opts.size_request(), width, height)?.is_some()
    {
        return Ok(None);
    }
    let method = conv.method();
    crate::method::check_output_size(method, width, height, opts.max_pixels)
        .map_err(|e| Error::Invalid(format!("<image>: {e}")))?;
    let tone = opts.tone()?;
    let table = ToneTable::new(8, encoding, &tone);
    let plane = PlaneRef {
        width,
        height,
        samples: SamplesRef::U8(data),
        tone: table.as_slice(),
    };
    // A grey image under an RGB colour mode (a palette, `color` rgb) is three equal planes,
    // as [`crate::halftone_image`] makes them.
    let planes = match opts.color_mode() {
        ColorMode::Gray => vec![plane],
        ColorMode::Rgb => vec![plane, plane, plane],
    };
    method
        .halftone(&Planes {
            width,
            height,
            planes,
        })
        .map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MethodKind, Options};

    fn ramp(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| ((i % w) * 255 / (w - 1)) as u8)
            .collect()
    }

    #[test]
    fn borrowed_grey_is_the_converted_grey() {
        let (w, h) = (37, 23);
        let data = ramp(w, h);
        for opts in [
            Options::default(),
            Options {
                method: MethodKind::Ordered,
                levels: 4,
                ..Default::default()
            },
            Options {
                palette: Some("epaper-7".into()),
                ..Default::default()
            },
        ] {
            let conv = Converter::new(&opts).unwrap();
            let want = conv.convert(Image::gray8(w, h, data.clone())).unwrap();
            let got = halftone_gray8(&conv, w, h, &data, Encoding::Srgb)
                .unwrap()
                .expect("no resizing asked for");
            assert_eq!((got.width, got.height, got.levels), (w, h, want.levels));
            assert_eq!(got.planes, want.planes);
            assert_eq!(got.palette, want.palette);
        }
        let resize = Converter::new(&Options {
            width: Some(10),
            ..Default::default()
        })
        .unwrap();
        assert!(halftone_gray8(&resize, w, h, &data, Encoding::Srgb)
            .unwrap()
            .is_none());
    }

    #[test]
    fn interleaved_samples_become_planes() {
        let img = image_u8(2, 1, 3, &[1, 2, 3, 4, 5, 6], Encoding::Srgb).unwrap();
        assert_eq!(img.color, ColorKind::Rgb);
        assert!(matches!(&img.planes[1], Samples::U8(v) if v == &[2, 5]));
        // Transparent black over white is white; opaque pixels keep their codes.
        let img = image_u8(2, 1, 2, &[0, 0, 9, 255], Encoding::Srgb).unwrap();
        assert!(matches!(&img.planes[0], Samples::U8(v) if v == &[255, 9]));
        let img = image_u16(1, 1, 2, &[0, 32768], Encoding::Linear).unwrap();
        assert!(matches!(&img.planes[0], Samples::U16(v) if v == &[32767]));
        assert!(image_u8(2, 2, 1, &[0; 3], Encoding::Srgb).is_err());
        assert!(image_u8(0, 2, 1, &[], Encoding::Srgb).is_err());
        assert!(image_u8(1, 1, 5, &[0; 5], Encoding::Srgb).is_err());
    }
}
