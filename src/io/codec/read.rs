//! Decoding: the pixel limit from the header before any pixel is allocated, alpha
//! composited over paper white in linear light, EXIF orientation applied, resolution kept.

use std::fs::File;
use std::io::{Cursor, Read};
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};

use super::pnm::{self, HeaderParse};
use crate::error::{Error, Result};
use crate::io::ReadOptions;
use crate::io::{check_pixels, decode_err, max_input_bytes};
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::{linear_to_srgb, srgb_to_linear, Encoding};

/// How many bytes of a file are read first to recognise a P4/P5 header.
const HEAD_BYTES: usize = 4096;

/// Decodes the image at `path` (a regular file, or a pipe, FIFO or device read once).
///
/// Nothing is read whole before its format is known: the first bytes are sniffed (a P4/P5
/// header, or another format's signature), and the rest is read only up to what the pixel
/// limit allows ([`max_input_bytes`]), so `/dev/zero`, a stream from it or a huge file that
/// is not an image fail after a few kilobytes.
pub fn read_image(path: &Path, opts: &ReadOptions) -> Result<Image> {
    let io_err = |e| Error::io(path, e);
    let mut file = File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_dir() {
        return Err(decode_err(path, "is a folder, not an image".into()));
    }
    if !meta.is_file() {
        // A pipe, FIFO or device: read once, under the bound its header sets.
        let bytes = crate::io::read_stream(&mut file, path, opts)?;
        return read_image_bytes(&bytes, path, opts);
    }
    // Devices and pipes report length 0: their length is what is read, bounded below.
    let len = meta.is_file().then_some(meta.len());
    let head = read_head(&mut file).map_err(io_err)?;
    // The head first: a P4/P5 file is then read straight into its plane.
    if let HeaderParse::Ok(h) = pnm::parse_header(&head) {
        check_pixels(path, h.width, h.height, opts)?;
        let needed = (h.data_offset as u64).saturating_add(pnm_data_bytes(&h));
        if len.is_some_and(|len| len < needed) {
            let msg = pnm::truncated_message(&h, pnm_data_bytes(&h) as usize);
            return Err(decode_err(path, msg));
        }
        #[cfg(unix)]
        if let Some(samples) = read_greymap8_parallel(&file, &h) {
            let samples = samples.map_err(|msg| decode_err(path, msg))?;
            return Ok(gray_image(h.width, h.height, samples));
        }
        let mut data = (&head[h.data_offset.min(head.len())..]).chain(&mut file);
        let samples = pnm::read_data(&h, &mut data).map_err(|msg| decode_err(path, msg))?;
        return Ok(gray_image(h.width, h.height, samples));
    }
    // A large 8-bit P6 file: read in bands straight into its planes (pixmap.rs).
    #[cfg(unix)]
    if let Some(h) = super::pixmap::header(&head).filter(|_| len.is_some()) {
        check_pixels(path, h.width, h.height, opts)?;
        return super::pixmap::read(&file, &h).map_err(|msg| decode_err(path, msg));
    }
    sniff(&head, path)?;
    let cap = max_input_bytes(opts);
    if len.is_some_and(|len| len > cap) {
        return Err(too_many_bytes(path, len, opts));
    }
    // Everything else: the whole file in one buffer (of exact size for a regular file).
    let mut bytes = Vec::with_capacity(len.map_or(1 << 16, |l| l as usize + 1));
    bytes.extend_from_slice(&head);
    drop(head);
    (&mut file)
        .take(cap.saturating_add(1).saturating_sub(bytes.len() as u64))
        .read_to_end(&mut bytes)
        .map_err(io_err)?;
    if bytes.len() as u64 > cap {
        return Err(too_many_bytes(path, None, opts));
    }
    read_image_bytes(&bytes, path, opts)
}

/// The dimensions of the image at `path` from its header alone (no pixel is decoded), for
/// checking sizes before any work. `None` for standard input and other streams, which
/// cannot be read twice.
pub fn read_dimensions(path: &Path, opts: &ReadOptions) -> Result<Option<(u32, u32)>> {
    if crate::io::is_stream(path) {
        return Ok(None);
    }
    let io_err = |e| Error::io(path, e);
    let mut file = File::open(path).map_err(io_err)?;
    let head = read_head(&mut file).map_err(io_err)?;
    let (w, h) = match pnm::parse_header(&head) {
        HeaderParse::Ok(h) => (h.width, h.height),
        HeaderParse::Bad(msg) => return Err(decode_err(path, msg)),
        _ => {
            let format = sniff(&head, path)?;
            drop(head);
            let file = std::io::BufReader::new(File::open(path).map_err(io_err)?);
            let mut reader = ImageReader::with_format(file, format);
            reader.limits(decoder_limits(opts));
            reader
                .into_dimensions()
                .map_err(|e| image_error(path, format, e, opts))?
        }
    };
    check_pixels(path, w, h, opts)?;
    Ok(Some((w, h)))
}

/// Reads up to [`HEAD_BYTES`] from `r` (fewer only at its end), whatever its length says.
fn read_head(r: &mut dyn Read) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(HEAD_BYTES);
    r.take(HEAD_BYTES as u64).read_to_end(&mut head)?;
    Ok(head)
}

/// The format of a file from its first bytes, or the error for a file that is no image.
fn sniff(head: &[u8], name: &Path) -> Result<ImageFormat> {
    if head.is_empty() {
        return Err(decode_err(name, "empty file".into()));
    }
    image::guess_format(head).map_err(|_| {
        decode_err(
            name,
            "not an image format halftone reads (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM)".into(),
        )
    })
}

/// The most bytes a decoder may allocate for the decoded image: one byte a pixel of the
/// pixel limit (at least 64 MiB). This bounds memory for every format, including a GIF's
/// logical screen and a PNG that inflates far beyond its file size.
pub fn decode_budget(opts: &ReadOptions) -> u64 {
    opts.max_pixels.max(64 << 20)
}

/// The `image` crate's limits for every decoder: dimensions and allocation.
fn decoder_limits(opts: &ReadOptions) -> Limits {
    let mut limits = Limits::no_limits();
    let side = u32::try_from(opts.max_pixels).unwrap_or(u32::MAX).max(1);
    limits.max_image_width = Some(side);
    limits.max_image_height = Some(side);
    limits.max_alloc = Some(decode_budget(opts));
    limits
}

/// The error for an input with more bytes than the pixel limit allows.
fn too_many_bytes(name: &Path, len: Option<u64>, opts: &ReadOptions) -> Error {
    let cap = max_input_bytes(opts);
    let size = len.map_or_else(|| format!("over {cap} bytes"), |l| format!("{l} bytes"));
    decode_err(
        name,
        format!(
            "{size}: more than any image of at most {} pixels can take ({cap} bytes); \
             raise `max_pixels` if it is one",
            opts.max_pixels
        ),
    )
}

/// Bytes of pixel data after a P4/P5 header.
fn pnm_data_bytes(h: &pnm::PnmHeader) -> u64 {
    let (w, ht) = (h.width as u64, h.height as u64);
    match h.kind {
        pnm::PnmKind::Bitmap => w.div_ceil(8) * ht,
        pnm::PnmKind::Greymap if h.maxval <= 255 => w * ht,
        pnm::PnmKind::Greymap => w * ht * 2,
    }
}

/// The error for an `image` crate failure; a refused allocation says which limit to raise.
fn image_error(
    name: &Path,
    format: ImageFormat,
    e: image::ImageError,
    opts: &ReadOptions,
) -> Error {
    let fmt_name = format!("{format:?}").to_uppercase();
    match e {
        image::ImageError::Limits(_) => decode_err(
            name,
            format!(
                "decoding this {fmt_name} needs more than the {} MB that `max_pixels` {} allows \
                 (one byte a pixel); raise `max_pixels` if the image is genuine",
                decode_budget(opts) / 1_000_000,
                opts.max_pixels
            ),
        ),
        e => decode_err(name, format!("bad {fmt_name} file: {e}")),
    }
}

/// Reads a text file (mask, kernel, palette, preset, scene) of at most `limit` bytes: a
/// device or a huge file given by mistake is refused after `limit` bytes, not read until
/// memory runs out.
pub fn read_text(path: &Path, limit: u64) -> Result<String> {
    let io_err = |e| Error::io(path, e);
    let file = File::open(path).map_err(io_err)?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(Error::parse(path, 0, "is a folder, not a file"));
    }
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io_err)?;
    if bytes.len() as u64 > limit {
        return Err(Error::parse(
            path,
            0,
            format!("over {limit} bytes: too large for this kind of file"),
        ));
    }
    String::from_utf8(bytes).map_err(|_| Error::parse(path, 0, "not UTF-8 text"))
}

/// 8-bit greymaps with at least this many pixels are read by several threads at once.
#[cfg(unix)]
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
    if bytes.starts_with(b"P7") {
        if let Ok(Some(p)) = pnm::parse_pam(bytes) {
            if p.depth == 0 {
                return Err(decode_err(name, pnm::PAM_DEPTH_0.into()));
            }
        }
    }
    let format = sniff(bytes, name)?;
    match format {
        ImageFormat::Jpeg => check_jpeg_data(bytes, name)?,
        ImageFormat::Png => check_png_chunks(bytes, name)?,
        _ => {}
    }
    guarded(name, || decode_with_image(bytes, name, format, opts))
}

thread_local! {
    /// True while this thread runs a decoder under [`guarded`].
    static DECODING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// True while the current thread runs a third-party decoder whose panics become errors:
/// a panic hook stays quiet then, as the panic is reported as one line.
pub fn decoding_on_this_thread() -> bool {
    DECODING.with(|d| d.get())
}

/// Runs a decoder, turning a panic inside it (a bug in a decoder crate, on a corrupt file)
/// into a decode error naming the file rather than a crash.
fn guarded<T>(name: &Path, decode: impl FnOnce() -> Result<T>) -> Result<T> {
    let was = DECODING.with(|d| d.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(decode));
    DECODING.with(|d| d.set(was));
    r.unwrap_or_else(|panic| {
        let why = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(decode_err(
            name,
            format!("corrupt file: the decoder failed ({why})"),
        ))
    })
}

/// Refuses PNG chunks before the image data that the `png` crate (0.18.1) mishandles: a
/// PLTE whose length is not a multiple of three (or over 256 entries) panics in its palette
/// expansion (found by fuzzing).
fn check_png_chunks(bytes: &[u8], name: &Path) -> Result<()> {
    let mut pos = 8;
    while let Some(head) = bytes.get(pos..pos + 8) {
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        match &head[4..8] {
            b"PLTE" if !len.is_multiple_of(3) || len > 768 => {
                return Err(decode_err(
                    name,
                    format!(
                        "bad PNG file: a palette (PLTE) of {len} bytes; it must be 3 bytes an \
                         entry, at most 256 entries"
                    ),
                ))
            }
            b"IDAT" | b"IEND" => break,
            _ => pos = pos.saturating_add(12).saturating_add(len),
        }
    }
    Ok(())
}

/// Decodes through the `image` crate, under the limits.
fn decode_with_image(
    bytes: &[u8],
    name: &Path,
    format: ImageFormat,
    opts: &ReadOptions,
) -> Result<Image> {
    let image_err = |e: image::ImageError| image_error(name, format, e, opts);
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    reader.limits(decoder_limits(opts));
    let mut decoder = reader.into_decoder().map_err(image_err)?;
    let (w, h) = decoder.dimensions();
    check_pixels(name, w, h, opts)?;
    if w == 0 || h == 0 {
        if let Some((cw, ch)) = (format == ImageFormat::WebP)
            .then(|| crate::io::stream::webp_size(bytes))
            .flatten()
            .filter(|&(cw, ch)| cw > 0 && ch > 0)
        {
            // The decoder reads a lossless side of 16384 (the format's largest) as 0.
            return Err(decode_err(
                name,
                format!(
                    "bad WEBP file: its header says {cw}x{ch}, which the WebP decoder in use \
                     cannot read (it takes a side of 16384 as 0); at most 16383 pixels a side \
                     work"
                ),
            ));
        }
        return Err(decode_err(name, format!("image is {w}x{h}: no pixels")));
    }
    if decoder.total_bytes() > decode_budget(opts) {
        return Err(image_err(image::ImageError::Limits(
            image::error::LimitError::from_kind(image::error::LimitErrorKind::InsufficientMemory),
        )));
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

/// Refuses a JPEG whose entropy-coded data is missing or ends early: the decoder would
/// fill the missing blocks with made-up grey and report success. Two checks from the
/// structure alone (ITU T.81): an end-of-image marker (FFD9) after the first scan (inside
/// scan data a 0xFF byte is always followed by 0x00 or a restart marker, so FFD9 is only
/// ever the real marker), and at least one bit per 8×8 block of the first component (every
/// block codes its DC coefficient with a Huffman code of at least one bit, in baseline and
/// progressive scans alike). A 334-byte file claiming 30000×30000 fails the second.
pub(crate) fn check_jpeg_data(bytes: &[u8], name: &Path) -> Result<()> {
    let mut pos = 2;
    let mut size: Option<(u64, u64)> = None;
    let sos = loop {
        // Markers may be preceded by fill bytes 0xFF.
        while bytes.get(pos) == Some(&0xFF) && bytes.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        let (Some(&0xFF), Some(&marker)) = (bytes.get(pos), bytes.get(pos + 1)) else {
            // Not the structure expected: the decoder's own errors say what is wrong.
            return Ok(());
        };
        // Markers without a length: SOI, RSTn, TEM.
        if matches!(marker, 0xD0..=0xD8 | 0x01) {
            pos += 2;
            continue;
        }
        let Some(len) = bytes.get(pos + 2..pos + 4) else {
            return Err(decode_err(
                name,
                "truncated: the JPEG header is incomplete".into(),
            ));
        };
        let len = u16::from_be_bytes([len[0], len[1]]) as usize;
        let segment = pos + 4;
        if matches!(marker, 0xC0..=0xCF) && !matches!(marker, 0xC4 | 0xC8 | 0xCC) {
            if let Some(f) = bytes.get(segment..segment + 5) {
                let h = u16::from_be_bytes([f[1], f[2]]) as u64;
                let w = u16::from_be_bytes([f[3], f[4]]) as u64;
                size = Some((w, h));
            }
        }
        if marker == 0xDA {
            break pos + 2 + len;
        }
        pos += 2 + len;
        if pos >= bytes.len() {
            return Err(decode_err(
                name,
                "truncated: the JPEG ends before its image data".into(),
            ));
        }
    };
    let data = bytes.get(sos..).unwrap_or_default();
    // From the end, where the marker is (the answer is the same either way).
    if !data.windows(2).rev().any(|w| w == [0xFF, 0xD9]) {
        return Err(decode_err(
            name,
            "truncated: the JPEG has no end-of-image marker (image data is missing)".into(),
        ));
    }
    if let Some((w, h)) = size {
        let blocks = w.div_ceil(8) * h.div_ceil(8);
        if (data.len() as u64) < blocks / 8 {
            return Err(decode_err(
                name,
                format!(
                    "truncated or corrupt: {} bytes of JPEG data cannot hold {w}x{h} pixels \
                     (at least {} bytes)",
                    data.len(),
                    blocks / 8
                ),
            ));
        }
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
pub(crate) fn composite8(src: &[u8], channels: usize) -> Vec<Vec<u8>> {
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
pub(crate) fn composite16(src: &[u16], channels: usize) -> Vec<Vec<u16>> {
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
pub(crate) fn jfif_density(bytes: &[u8]) -> Option<f64> {
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
