//! Decoding: the pixel limit from the header before any pixel is allocated, alpha
//! composited over paper white in linear light, EXIF orientation applied, resolution kept.

use std::fs::File;
use std::io::{Cursor, Read};
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};

use super::pnm::{self, HeaderParse};
use super::ReadOptions;
use crate::error::{Error, Result};
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::{linear_to_srgb, srgb_to_linear, Encoding};

/// How many bytes of a file are read first to recognise a P4/P5 header.
const HEAD_BYTES: usize = 4096;

/// The name standard input goes by in messages.
const STDIN_NAME: &str = "<stdin>";

/// Decodes the image at `path` (`-` reads standard input).
pub fn read_image(path: &Path, opts: &ReadOptions) -> Result<Image> {
    if path.as_os_str() == "-" {
        let mut bytes = Vec::new();
        std::io::stdin()
            .lock()
            .read_to_end(&mut bytes)
            .map_err(|e| Error::io(STDIN_NAME, e))?;
        return read_image_bytes(&bytes, Path::new(STDIN_NAME), opts);
    }
    let io_err = |e| Error::io(path, e);
    let mut file = File::open(path).map_err(io_err)?;
    let len = file.metadata().map_err(io_err)?.len() as usize;
    // The head first: a P4/P5 file is then read straight into its plane.
    let mut head = vec![0u8; len.min(HEAD_BYTES)];
    file.read_exact(&mut head).map_err(io_err)?;
    if let HeaderParse::Ok(h) = pnm::parse_header(&head) {
        check_pixels(path, h.width, h.height, opts)?;
        #[cfg(unix)]
        if let Some(samples) = read_greymap8_parallel(&file, &h) {
            let samples = samples.map_err(|msg| decode_err(path, msg))?;
            return Ok(gray_image(h.width, h.height, samples));
        }
        let mut data = (&head[h.data_offset..]).chain(&mut file);
        let samples = pnm::read_data(&h, &mut data).map_err(|msg| decode_err(path, msg))?;
        return Ok(gray_image(h.width, h.height, samples));
    }
    // A large 8-bit P6 file: read in bands straight into its planes (pixmap.rs).
    #[cfg(unix)]
    if let Some(h) =
        super::pixmap::header(&head).filter(|_| file.metadata().is_ok_and(|m| m.is_file()))
    {
        check_pixels(path, h.width, h.height, opts)?;
        return super::pixmap::read(&file, &h).map_err(|msg| decode_err(path, msg));
    }
    // Everything else: the whole file in one buffer of exact size.
    let mut bytes = Vec::with_capacity(len + 1);
    bytes.extend_from_slice(&head);
    drop(head);
    file.read_to_end(&mut bytes).map_err(io_err)?;
    read_image_bytes(&bytes, path, opts)
}

/// 8-bit greymaps with at least this many pixels are read by several threads at once.
const PARALLEL_READ_BYTES: usize = 4 << 20;

/// Reads the pixels of a large 8-bit P5 file by positional reads into disjoint parts of the
/// plane, one part per thread: copying from the page cache is a fair share of a fast job's
/// time (about 16 ms of a 24 MP file on one core here). `None` when the file is not such a
/// greymap.
#[cfg(unix)]
fn read_greymap8_parallel(
    file: &File,
    h: &pnm::PnmHeader,
) -> Option<std::result::Result<Samples, String>> {
    use rayon::prelude::*;
    use std::os::unix::fs::FileExt;
    let n = h.width as usize * h.height as usize;
    if h.kind != pnm::PnmKind::Greymap
        || h.maxval > 255
        || n < PARALLEL_READ_BYTES
        || !file.metadata().is_ok_and(|m| m.is_file())
    {
        return None;
    }
    let part = n.div_ceil(rayon::current_num_threads().max(1)).max(1 << 20);
    let mut out = vec![0u8; n];
    huge_pages(&mut out);
    let read = out
        .par_chunks_mut(part)
        .enumerate()
        .try_for_each(|(i, chunk)| file.read_exact_at(chunk, (h.data_offset + i * part) as u64));
    Some(match read {
        Ok(()) => {
            pnm::rescale8(&mut out, h.maxval);
            Ok(Samples::U8(out))
        }
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            Err(pnm::truncated_message(h, n))
        }
        Err(e) => Err(e.to_string()),
    })
}

/// Asks the kernel to back `buf` with 2 MiB pages where it can, before the first write: a
/// 24 MP plane then takes a dozen page faults instead of six thousand. Only advice: nothing
/// changes if the kernel does not follow it.
#[cfg(target_os = "linux")]
fn huge_pages(buf: &mut [u8]) {
    let start = buf.as_mut_ptr() as usize & !4095;
    let len = buf.as_ptr() as usize + buf.len() - start;
    // SAFETY: the range is `buf` widened to the start of its first page, all of it mapped by
    // this process (that page holds `buf`'s first byte). MADV_HUGEPAGE is advice on how pages
    // are backed: it changes no contents, here or in whatever else shares that first page.
    unsafe {
        libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
    }
}

#[cfg(all(unix, not(target_os = "linux")))]
fn huge_pages(_: &mut [u8]) {}

/// Decodes an image held in memory; `name` is used in error messages.
pub fn read_image_bytes(bytes: &[u8], name: &Path, opts: &ReadOptions) -> Result<Image> {
    if bytes.is_empty() {
        return Err(decode_err(name, "empty file".into()));
    }
    match pnm::parse_header(bytes) {
        HeaderParse::Ok(h) => {
            check_pixels(name, h.width, h.height, opts)?;
            let samples = pnm::read_data(&h, &mut &bytes[h.data_offset..])
                .map_err(|msg| decode_err(name, msg))?;
            return Ok(gray_image(h.width, h.height, samples));
        }
        HeaderParse::Incomplete => {
            return Err(decode_err(
                name,
                "truncated: the header is incomplete".into(),
            ))
        }
        HeaderParse::Bad(msg) => return Err(decode_err(name, msg)),
        HeaderParse::NotFastPath => {}
    }
    let format = image::guess_format(bytes).map_err(|_| {
        decode_err(
            name,
            "not an image format halftone reads (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM)".into(),
        )
    })?;
    let fmt_name = format!("{format:?}").to_uppercase();
    let image_err = |e: image::ImageError| decode_err(name, format!("bad {fmt_name} file: {e}"));
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    // image refuses decodes over 512 MiB by default; our limit is in pixels, checked below
    // from the header, so allow what that many pixels of RGBA at 16 bits need.
    let mut limits = Limits::no_limits();
    limits.max_alloc = Some(
        opts.max_pixels
            .saturating_mul(8)
            .saturating_add(64 << 20)
            .max(512 << 20),
    );
    reader.limits(limits);
    let mut decoder = reader.into_decoder().map_err(image_err)?;
    let (w, h) = decoder.dimensions();
    check_pixels(name, w, h, opts)?;
    if w == 0 || h == 0 {
        return Err(decode_err(name, format!("image is {w}x{h}: no pixels")));
    }
    // A broken EXIF block should not stop a readable image.
    let orientation = decoder
        .orientation()
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut img = DynamicImage::from_decoder(decoder).map_err(image_err)?;
    img.apply_orientation(orientation);
    let mut out = from_dynamic(img);
    out.dpi = resolution(bytes, format);
    Ok(out)
}

/// A one-line decode error naming the file.
fn decode_err(name: &Path, msg: String) -> Error {
    Error::Decode {
        path: name.to_path_buf(),
        msg: msg.replace(['\n', '\r'], " "),
    }
}

/// Refuses images over the pixel limit, from header dimensions.
fn check_pixels(name: &Path, width: u32, height: u32, opts: &ReadOptions) -> Result<()> {
    let pixels = width as u64 * height as u64;
    if pixels > opts.max_pixels {
        return Err(Error::TooLarge {
            path: name.to_path_buf(),
            width: width as u64,
            height: height as u64,
            pixels,
            limit: opts.max_pixels,
        });
    }
    Ok(())
}

/// A grey sRGB image from one plane.
fn gray_image(width: u32, height: u32, samples: Samples) -> Image {
    Image {
        width: width as usize,
        height: height as usize,
        color: ColorKind::Gray,
        planes: vec![samples],
        encoding: Encoding::Srgb,
        dpi: None,
    }
}

/// Planar grey or RGB at the decoded depth, alpha composited over white.
fn from_dynamic(img: DynamicImage) -> Image {
    let (w, h) = (img.width(), img.height());
    let (color, planes) = match img {
        DynamicImage::ImageLuma8(b) => (ColorKind::Gray, vec![Samples::U8(b.into_raw())]),
        DynamicImage::ImageLuma16(b) => (ColorKind::Gray, vec![Samples::U16(b.into_raw())]),
        DynamicImage::ImageLumaA8(b) => (
            ColorKind::Gray,
            composite8(&b.into_raw(), 1)
                .into_iter()
                .map(Samples::U8)
                .collect(),
        ),
        DynamicImage::ImageLumaA16(b) => (
            ColorKind::Gray,
            composite16(&b.into_raw(), 1)
                .into_iter()
                .map(Samples::U16)
                .collect(),
        ),
        DynamicImage::ImageRgb8(b) => (
            ColorKind::Rgb,
            deinterleave(&b.into_raw())
                .into_iter()
                .map(Samples::U8)
                .collect(),
        ),
        DynamicImage::ImageRgb16(b) => (
            ColorKind::Rgb,
            deinterleave(&b.into_raw())
                .into_iter()
                .map(Samples::U16)
                .collect(),
        ),
        DynamicImage::ImageRgba8(b) => (
            ColorKind::Rgb,
            composite8(&b.into_raw(), 3)
                .into_iter()
                .map(Samples::U8)
                .collect(),
        ),
        DynamicImage::ImageRgba16(b) => (
            ColorKind::Rgb,
            composite16(&b.into_raw(), 3)
                .into_iter()
                .map(Samples::U16)
                .collect(),
        ),
        // Float images (and any later variant): through 16-bit RGBA.
        other => (
            ColorKind::Rgb,
            composite16(&other.to_rgba16().into_raw(), 3)
                .into_iter()
                .map(Samples::U16)
                .collect(),
        ),
    };
    Image {
        width: w as usize,
        height: h as usize,
        color,
        planes,
        encoding: Encoding::Srgb,
        dpi: None,
    }
}

/// Three planes from interleaved RGB.
fn deinterleave<T: Copy + Default>(src: &[T]) -> Vec<Vec<T>> {
    let n = src.len() / 3;
    let mut planes = vec![vec![T::default(); n]; 3];
    let [r, g, b] = &mut planes[..] else {
        unreachable!()
    };
    for (i, px) in src.chunks_exact(3).enumerate() {
        r[i] = px[0];
        g[i] = px[1];
        b[i] = px[2];
    }
    planes
}

/// `channels` planes from interleaved colour + alpha (8-bit), each composited over paper
/// white in linear light: `c' = enc(a·lin(c) + (1 − a))`.
fn composite8(src: &[u8], channels: usize) -> Vec<Vec<u8>> {
    let n = src.len() / (channels + 1);
    let mut planes = vec![vec![0u8; n]; channels];
    let translucent = src.chunks_exact(channels + 1).any(|px| px[channels] != 255);
    // One table over (alpha, code), built only when some pixel is not opaque.
    let table: Vec<u8> = if translucent {
        let lin: Vec<f64> = (0..256).map(|c| srgb_to_linear(c as f64 / 255.0)).collect();
        let mut t = vec![0u8; 256 * 256];
        for a in 0..256 {
            let af = a as f64 / 255.0;
            for c in 0..256 {
                t[a * 256 + c] = (linear_to_srgb(af * lin[c] + (1.0 - af)) * 255.0).round() as u8;
            }
        }
        t
    } else {
        Vec::new()
    };
    for (i, px) in src.chunks_exact(channels + 1).enumerate() {
        let a = px[channels] as usize;
        for (c, plane) in planes.iter_mut().enumerate() {
            plane[i] = if a == 255 {
                px[c]
            } else {
                table[a * 256 + px[c] as usize]
            };
        }
    }
    planes
}

/// [`composite8`] at 16 bits: exact per pixel (translucent 16-bit pixels are rare).
fn composite16(src: &[u16], channels: usize) -> Vec<Vec<u16>> {
    let n = src.len() / (channels + 1);
    let mut planes = vec![vec![0u16; n]; channels];
    for (i, px) in src.chunks_exact(channels + 1).enumerate() {
        let a = px[channels];
        for (c, plane) in planes.iter_mut().enumerate() {
            plane[i] = match a {
                65535 => px[c],
                0 => 65535,
                _ => {
                    let af = a as f64 / 65535.0;
                    let l = af * srgb_to_linear(px[c] as f64 / 65535.0) + (1.0 - af);
                    (linear_to_srgb(l) * 65535.0).round() as u16
                }
            };
        }
    }
    planes
}

/// Resolution recorded in the file, dots per inch, where it is cheap to find: PNG pHYs,
/// JPEG JFIF density, TIFF X resolution, BMP pixels per metre.
fn resolution(bytes: &[u8], format: ImageFormat) -> Option<f64> {
    let dpi = match format {
        ImageFormat::Png => png_phys(bytes),
        ImageFormat::Jpeg => jfif_density(bytes),
        ImageFormat::Tiff => tiff_resolution(bytes),
        ImageFormat::Bmp => {
            let ppm = i32::from_le_bytes(bytes.get(38..42)?.try_into().ok()?);
            (ppm > 0).then_some(ppm as f64 * 0.0254)
        }
        _ => None,
    }?;
    (dpi.is_finite() && dpi > 0.0).then_some(dpi)
}

/// PNG pHYs, when its unit is the metre.
fn png_phys(bytes: &[u8]) -> Option<f64> {
    let mut pos = 8;
    while pos + 8 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[pos..pos + 4].try_into().ok()?) as usize;
        let kind = &bytes[pos + 4..pos + 8];
        let data = bytes.get(pos + 8..pos + 8 + len)?;
        match kind {
            b"pHYs" if len == 9 && data[8] == 1 => {
                let x = u32::from_be_bytes(data[0..4].try_into().ok()?);
                return Some(x as f64 * 0.0254);
            }
            b"IDAT" | b"IEND" => return None,
            _ => pos += 12 + len,
        }
    }
    None
}

/// JPEG JFIF APP0 density, when its unit is the inch (1) or the centimetre (2).
fn jfif_density(bytes: &[u8]) -> Option<f64> {
    let app0 = bytes.get(2..20)?;
    if app0[0..2] != [0xFF, 0xE0] || &app0[4..9] != b"JFIF\0" {
        return None;
    }
    let x = u16::from_be_bytes([app0[12], app0[13]]) as f64;
    match app0[11] {
        1 => Some(x),
        2 => Some(x * 2.54),
        _ => None,
    }
}

/// TIFF XResolution with ResolutionUnit inch (2, the default) or centimetre (3).
fn tiff_resolution(bytes: &[u8]) -> Option<f64> {
    use tiff::tags::Tag;
    let mut d = tiff::decoder::Decoder::new(Cursor::new(bytes)).ok()?;
    let x = match d.find_tag(Tag::XResolution).ok()?? {
        tiff::decoder::ifd::Value::Rational(n, den) if den != 0 => n as f64 / den as f64,
        other => other.into_f64().ok()?,
    };
    let unit = d
        .find_tag(Tag::ResolutionUnit)
        .ok()
        .flatten()
        .and_then(|v| v.into_u16().ok())
        .unwrap_or(2);
    match unit {
        2 => Some(x),
        3 => Some(x * 2.54),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_alpha_black_over_white_is_half_light() {
        // Alpha 50% (32768/65535 ≈ 0.5): linear 0.5 → sRGB 0.7354.
        let p = composite16(&[0, 32768], 1);
        let v = p[0][0] as f64 / 65535.0;
        assert!(
            (v - linear_to_srgb(1.0 - 32768.0 / 65535.0)).abs() < 1e-4,
            "{v}"
        );
        let p8 = composite8(&[0, 128, 255, 0, 200, 255], 1);
        // 128/255 coverage of black: reflectance 0.498 → code 187.
        assert_eq!(p8[0], vec![187, 255, 200]);
    }

    #[test]
    fn text_is_not_an_image() {
        let e = read_image_bytes(
            b"hello, world\n",
            Path::new("notes.txt"),
            &ReadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("notes.txt: not an image format"), "{e}");
    }
}
