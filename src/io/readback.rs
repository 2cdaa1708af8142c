//! Reading back what `convert` prints: the printer-language files (PDF, PostScript, PCL,
//! ESC/POS, ZPL) decoded into images, so that `compare` measures exactly the bits a printer
//! receives.
//!
//! PCL, ESC/POS and ZPL go through the reference decoders of [`super::decode`]. PDF and
//! PostScript are decoded here, for the forms halftone writes (not for PDF and PostScript in
//! general): a PDF page's image XObject with `/FlateDecode` or `/CCITTFaxDecode` (Group 4)
//! data (PDF 1.7 §7.4.4, §7.4.6, §8.9.5), and a PostScript `image` whose samples follow
//! inline through `/ASCII85Decode` and `/RunLengthDecode` (PLRM 2nd ed. §3.13.3).
//!
//! Every page comes back as 8-bit codes in the convention of the image files `convert`
//! writes: paper 255, ink 0, and a level between them as the sRGB code of its reflectance, so
//! a PDF and the PGM of the same halftone give the same figures.

use std::io::Read;
use std::path::Path;

use super::decode::{self, Bitmap, DecodeError};
use super::print::Language;
use super::ReadOptions;
use crate::error::{Error, Result};
use crate::raster::Image;
use crate::tone::linear_to_srgb;

type DResult<T> = std::result::Result<T, DecodeError>;

fn fail<T>(msg: impl Into<String>) -> DResult<T> {
    Err(DecodeError::new(msg))
}

/// The printer language a file is written in, from its first bytes: `%PDF-`, `%!PS`,
/// PCL's reset (`ESC E`) or a PJL job header, ESC/POS's initialise (`ESC @`), ZPL's `^XA`.
pub fn sniff(head: &[u8]) -> Option<Language> {
    let text = head.trim_ascii_start();
    if head.starts_with(b"%PDF-") {
        Some(Language::Pdf)
    } else if head.starts_with(b"%!PS") {
        Some(Language::Ps)
    } else if head.starts_with(b"\x1bE") || head.starts_with(b"\x1b%-12345X") {
        Some(Language::Pcl)
    } else if head.starts_with(b"\x1b@") {
        Some(Language::EscPos)
    } else if text.starts_with(b"^XA") {
        Some(Language::Zpl)
    } else {
        None
    }
}

/// The pages of a printer-language file as images (see the module's notes on codes).
pub fn pages(data: &[u8], lang: Language) -> DResult<Vec<Image>> {
    match lang {
        Language::Pdf => pdf(data),
        Language::Ps => postscript(data),
        Language::Pcl => Ok(decode::pcl(data)?
            .iter()
            .map(|r| {
                let width = r.rows.iter().map(Vec::len).max().unwrap_or(0) * 8;
                bitmap_image(&r.bitmap(width), Some(r.dpi as f64))
            })
            .collect()),
        Language::EscPos => Ok(vec![bitmap_image(&decode::escpos(data)?.bitmap, None)]),
        Language::Zpl => Ok(decode::zpl(data)?
            .iter()
            .map(|b| bitmap_image(b, None))
            .collect()),
    }
}

/// Reads the printer-language file at `path` and returns its first page, or `None` when the
/// file is not in a printer language (then it is an ordinary image). A file of several
/// pages is refused: say which page by writing it alone.
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Option<Image>> {
    let io_err = |e| Error::io(path, e);
    let mut file = std::fs::File::open(path).map_err(io_err)?;
    let mut head = [0u8; 16];
    let n = read_up_to(&mut file, &mut head).map_err(io_err)?;
    let Some(lang) = sniff(&head[..n]) else {
        return Ok(None);
    };
    let mut data = head[..n].to_vec();
    let cap = super::max_input_bytes(opts);
    file.take(cap.saturating_add(1))
        .read_to_end(&mut data)
        .map_err(io_err)?;
    if data.len() as u64 > cap {
        return Err(Error::Decode {
            path: path.to_path_buf(),
            msg: format!(
                "more than {cap} bytes, more than a page within `max_pixels` {} can need",
                opts.max_pixels
            ),
        });
    }
    let err = |msg: String| Error::Decode {
        path: path.to_path_buf(),
        msg,
    };
    let mut pages = pages(&data, lang).map_err(|e| err(format!("{}: {e}", name(lang))))?;
    for p in &pages {
        super::limits::check_pixels(path, p.width as u32, p.height as u32, opts)?;
    }
    match pages.len() {
        0 => Err(err(format!("{} file with no page", name(lang)))),
        1 => Ok(pages.pop()),
        n => Err(err(format!(
            "{} file of {n} pages; compare reads one page (write that page alone)",
            name(lang)
        ))),
    }
}

fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

fn name(lang: Language) -> &'static str {
    match lang {
        Language::Pdf => "PDF",
        Language::Ps => "PostScript",
        Language::Pcl => "PCL",
        Language::EscPos => "ESC/POS",
        Language::Zpl => "ZPL",
    }
}

/// Fits a printed page to `width` columns when it differs only by the padding of a whole
/// last byte (ESC/POS and PCL send whole bytes a row): blank columns past `width` are cut,
/// missing ones added as paper. Returns false (and leaves the image) otherwise.
pub fn fit_width(img: &mut Image, width: usize) -> bool {
    if img.width == width || img.width.abs_diff(width) >= 8 || img.planes.len() != 1 {
        return img.width == width;
    }
    let crate::raster::Samples::U8(codes) = &img.planes[0] else {
        return false;
    };
    let (w, h) = (img.width, img.height);
    if w > width && (0..h).any(|y| codes[y * w + width..(y + 1) * w].iter().any(|&c| c != 255)) {
        return false;
    }
    let mut out = vec![255u8; width * h];
    let n = w.min(width);
    for y in 0..h {
        out[y * width..y * width + n].copy_from_slice(&codes[y * w..y * w + n]);
    }
    img.planes[0] = crate::raster::Samples::U8(out);
    img.width = width;
    true
}

/// A bilevel bitmap (1 = ink) as grey codes: ink 0, paper 255.
fn bitmap_image(b: &Bitmap, dpi: Option<f64>) -> Image {
    let mut codes = Vec::with_capacity(b.width * b.height);
    for y in 0..b.height {
        codes.extend((0..b.width).map(|x| if b.get(x, y) { 0 } else { 255 }));
    }
    let mut img = Image::gray8(b.width, b.height, codes);
    img.dpi = dpi;
    img
}

/// Largest image a page may declare here, in samples: beyond any page halftone writes
/// within its own pixel limit, so a corrupt header cannot ask for unbounded memory.
const MAX_SAMPLES: u64 = 3 << 30;

/// What an image's samples mean.
#[derive(Clone, Debug, PartialEq)]
enum Space {
    Gray,
    Rgb,
    /// Palette entries, sRGB `r g b`.
    Indexed(Vec<[u8; 3]>),
}

/// One decoded image's header.
#[derive(Clone, Debug)]
struct ImageHead {
    width: usize,
    height: usize,
    bits: u32,
    space: Space,
    /// `/Decode`: the low and high value of each component (ignored for a palette).
    decode: Vec<f64>,
}

impl ImageHead {
    fn components(&self) -> usize {
        if self.space == Space::Rgb {
            3
        } else {
            1
        }
    }

    fn stride(&self) -> usize {
        (self.width * self.components() * self.bits as usize).div_ceil(8)
    }

    fn check(&self) -> DResult<()> {
        if !matches!(self.bits, 1 | 2 | 4 | 8) {
            return fail(format!("{} bits a sample", self.bits));
        }
        let samples = self.width as u64 * self.height as u64 * self.components() as u64;
        if self.width == 0 || self.height == 0 || samples > MAX_SAMPLES {
            return fail(format!("an image of {}x{}", self.width, self.height));
        }
        Ok(())
    }

    /// The image from its rows of packed samples (`stride` bytes each; shorter data is an
    /// error).
    fn image(&self, data: &[u8]) -> DResult<Image> {
        let stride = self.stride();
        if data.len() < stride * self.height {
            return fail(format!(
                "image data cut short: {} bytes of {}",
                data.len(),
                stride * self.height
            ));
        }
        let max = ((1u32 << self.bits) - 1) as f64;
        let sample = |row: &[u8], i: usize| -> u32 {
            let bit = i * self.bits as usize;
            let byte = row[bit / 8] as u32;
            (byte >> (8 - self.bits as usize - bit % 8)) & ((1 << self.bits) - 1)
        };
        // Each component's code for each sample value: the value through /Decode is linear
        // reflectance, stored as its sRGB code like the image files convert writes.
        let tables: Vec<Vec<u8>> = (0..self.components())
            .map(|c| {
                let (lo, hi) = (
                    self.decode.get(2 * c).copied().unwrap_or(0.0),
                    self.decode.get(2 * c + 1).copied().unwrap_or(1.0),
                );
                (0..=max as u32)
                    .map(|v| {
                        let r = (lo + v as f64 * (hi - lo) / max).clamp(0.0, 1.0);
                        (linear_to_srgb(r) * 255.0).round() as u8
                    })
                    .collect()
            })
            .collect();
        let (w, h) = (self.width, self.height);
        let rows = data.chunks_exact(stride).take(h);
        match &self.space {
            Space::Gray => {
                let mut codes = Vec::with_capacity(w * h);
                for row in rows {
                    codes.extend((0..w).map(|x| tables[0][sample(row, x) as usize]));
                }
                Ok(Image::gray8(w, h, codes))
            }
            Space::Rgb => {
                let mut rgb = Vec::with_capacity(w * h * 3);
                for row in rows {
                    rgb.extend((0..w * 3).map(|i| tables[i % 3][sample(row, i) as usize]));
                }
                Ok(Image::rgb8(w, h, &rgb))
            }
            Space::Indexed(pal) => {
                let mut rgb = Vec::with_capacity(w * h * 3);
                for row in rows {
                    for x in 0..w {
                        let i = sample(row, x) as usize;
                        let Some(c) = pal.get(i) else {
                            return fail(format!("palette index {i} of {} colours", pal.len()));
                        };
                        rgb.extend_from_slice(c);
                    }
                }
                Ok(Image::rgb8(w, h, &rgb))
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// PDF

/// Finds `needle` in `hay` from `from`.
fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

/// The byte offset of every object's body (`N 0 obj` at the start of a line), by number.
fn pdf_objects(data: &[u8]) -> std::collections::HashMap<usize, usize> {
    let mut objs = std::collections::HashMap::new();
    let mut at = 0;
    while let Some(p) = find(data, b" 0 obj\n", at) {
        let start = data[..p]
            .iter()
            .rposition(|b| !b.is_ascii_digit())
            .map_or(0, |i| i + 1);
        if (start == 0 || data[start - 1] == b'\n') && start < p {
            if let Some(n) = std::str::from_utf8(&data[start..p])
                .ok()
                .and_then(|s| s.parse().ok())
            {
                objs.insert(n, p + 7);
            }
        }
        at = p + 7;
    }
    objs
}

/// The text of a dictionary value after `key` (up to the next `/` or `>>`, or the whole
/// bracketed array), within `dict`.
fn value<'a>(dict: &'a str, key: &str) -> Option<&'a str> {
    let mut at = 0;
    // A key is followed by a space or a delimiter, so /Width does not match /WidthX.
    loop {
        let p = dict[at..].find(key)? + at;
        let rest = &dict[p + key.len()..];
        if rest.starts_with([' ', '[', '/', '<', '\n']) {
            let rest = rest.trim_start();
            if rest.starts_with('[') {
                return rest.find(']').map(|e| &rest[..=e]);
            }
            let end = rest[1..]
                .find(['/', '>', '['])
                .map_or(rest.len(), |e| e + 1);
            return Some(rest[..end].trim());
        }
        at = p + key.len();
    }
}

fn number(dict: &str, key: &str) -> DResult<usize> {
    value(dict, key)
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .map_or_else(|| fail(format!("no {key} number")), Ok)
}

fn numbers(array: &str) -> Vec<f64> {
    array
        .trim_matches(['[', ']'])
        .split_whitespace()
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// The colour space of an image from its `/ColorSpace` text and (for `/Indexed`) the hex
/// palette that follows it.
fn space(cs: &str, after: &str) -> DResult<Space> {
    if cs.starts_with("/DeviceGray") {
        return Ok(Space::Gray);
    }
    if cs.starts_with("/DeviceRGB") {
        return Ok(Space::Rgb);
    }
    if cs.starts_with("[/Indexed") || cs.starts_with("[ /Indexed") {
        let open = after.find('<').map(|i| i + 1);
        let hex = open
            .and_then(|o| after[o..].find('>').map(|e| &after[o..o + e]))
            .unwrap_or("");
        let bytes: Option<Vec<u8>> = hex
            .as_bytes()
            .chunks(2)
            .map(|p| {
                std::str::from_utf8(p)
                    .ok()
                    .and_then(|s| u8::from_str_radix(s, 16).ok())
            })
            .collect();
        let Some(bytes) = bytes.filter(|b| !b.is_empty() && b.len() % 3 == 0) else {
            return fail("an /Indexed colour space without an RGB palette");
        };
        return Ok(Space::Indexed(
            bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        ));
    }
    if cs.contains("/Separation") {
        return fail("CMYK separations; compare reads grey, RGB and palette pages");
    }
    fail(format!("colour space {cs}"))
}

/// Decodes the pages of a PDF that halftone wrote: each page's image (one a page), as
/// 8-bit codes. A page of four `/Separation` plates (CMYK) is refused.
pub fn pdf(data: &[u8]) -> DResult<Vec<Image>> {
    let objs = pdf_objects(data);
    let text = |n: usize| -> DResult<&str> {
        let Some(&at) = objs.get(&n) else {
            return fail(format!("object {n} is missing"));
        };
        let end = find(data, b"endobj", at).unwrap_or(data.len());
        let end = find(&data[..end], b"stream\n", at).unwrap_or(end);
        std::str::from_utf8(&data[at..end])
            .map_or_else(|_| fail(format!("object {n} is not text")), Ok)
    };
    let refs = |s: &str| -> Vec<usize> {
        let t: Vec<&str> = s.split_whitespace().collect();
        t.windows(3)
            .filter(|w| w[1] == "0" && w[2].starts_with('R'))
            .filter_map(|w| w[0].trim_start_matches('[').parse().ok())
            .collect()
    };
    // Catalog → page tree → kids, in order.
    let catalog = text(1)?;
    let tree = value(catalog, "/Pages")
        .map(refs)
        .and_then(|r| r.first().copied());
    let Some(tree) = tree else {
        return fail("no page tree");
    };
    let kids = value(text(tree)?, "/Kids").map(refs).unwrap_or_default();
    let mut pages = Vec::new();
    for page in kids {
        let page_text = text(page)?;
        let Some(xo) = page_text.find("/XObject") else {
            return fail(format!("page object {page} has no image"));
        };
        let images = refs(&page_text[xo..]);
        // The contents stream is listed after the resources; the images are in /XObject.
        let images: Vec<usize> = images
            .into_iter()
            .take_while(|&n| text(n).is_ok_and(|t| t.contains("/Subtype /Image")))
            .collect();
        match images.len() {
            0 => return fail(format!("page object {page} has no image")),
            1 => {}
            n => {
                return fail(format!(
                    "a page of {n} images (CMYK separations); compare reads grey, RGB and palette pages"
                ))
            }
        }
        pages.push(pdf_image(data, &objs, images[0], &text)?);
    }
    if pages.is_empty() {
        return fail("no pages");
    }
    Ok(pages)
}

fn pdf_image<'a>(
    data: &'a [u8],
    objs: &std::collections::HashMap<usize, usize>,
    n: usize,
    text: &dyn Fn(usize) -> DResult<&'a str>,
) -> DResult<Image> {
    let dict = text(n)?;
    let cs_at = dict.find("/ColorSpace").map_or("", |i| &dict[i + 11..]);
    let cs = cs_at.trim_start();
    let head = ImageHead {
        width: number(dict, "/Width")?,
        height: number(dict, "/Height")?,
        bits: number(dict, "/BitsPerComponent")? as u32,
        space: space(cs, cs)?,
        decode: value(dict, "/Decode").map(numbers).unwrap_or_default(),
    };
    head.check()?;
    // The stream: its length direct, or an indirect object written after it.
    let len_text = value(dict, "/Length").unwrap_or("");
    let len_words: Vec<&str> = len_text.split_whitespace().collect();
    let length: usize = match len_words.as_slice() {
        [v] => v.parse().ok(),
        [r, "0", "R", ..] => r
            .parse()
            .ok()
            .and_then(|r: usize| text(r).ok())
            .and_then(|t| t.trim().parse().ok()),
        _ => None,
    }
    .map_or_else(|| fail(format!("image object {n} without a /Length")), Ok)?;
    let at = objs[&n];
    let Some(s) = find(data, b"stream\n", at) else {
        return fail(format!("image object {n} without a stream"));
    };
    let Some(stream) = data.get(s + 7..s + 7 + length) else {
        return fail(format!("image object {n}: stream cut short"));
    };
    let expected = head.stride() * head.height;
    let raw = if dict.contains("/FlateDecode") {
        inflate(stream, expected)?
    } else if dict.contains("/CCITTFaxDecode") {
        if head.bits != 1 || head.space != Space::Gray {
            return fail("Group 4 data for an image that is not black and white");
        }
        g4(stream, head.width, head.height)?
    } else {
        return fail(format!(
            "image object {n}: a filter halftone does not write"
        ));
    };
    head.image(&raw)
}

/// Inflates zlib data, up to `expected` bytes.
fn inflate(z: &[u8], expected: usize) -> DResult<Vec<u8>> {
    let mut out = Vec::with_capacity(expected);
    flate2::read::ZlibDecoder::new(z)
        .take(expected as u64)
        .read_to_end(&mut out)
        .map_or_else(|e| fail(format!("Flate data: {e}")), |_| Ok(out))
}

/// Decodes Group 4 (K −1) data of `width` × `height` into packed rows, bit 1 = white.
fn g4(data: &[u8], width: usize, height: usize) -> DResult<Vec<u8>> {
    let stride = width.div_ceil(8);
    let mut out = vec![0u8; stride * height];
    let mut y = 0;
    let (w32, h32) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => return fail("Group 4 image too large"),
    };
    let done = fax::decoder::decode_g4(data.iter().copied(), w32, Some(h32), |line| {
        if y < height {
            let row = &mut out[y * stride..(y + 1) * stride];
            for (x, c) in fax::decoder::pels(line, w32).enumerate() {
                if c == fax::Color::White {
                    row[x / 8] |= 0x80 >> (x % 8);
                }
            }
        }
        y += 1;
    });
    if done.is_none() || y < height {
        return fail("Group 4 data could not be decoded");
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------
// PostScript

/// Decodes the pages of a PostScript file that halftone wrote: each `image` with its
/// samples inline as ASCII85 of run-length data, as 8-bit codes.
pub fn postscript(data: &[u8]) -> DResult<Vec<Image>> {
    const TAIL: &[u8] =
        b"/DataSource currentfile /ASCII85Decode filter /RunLengthDecode filter >> image\n";
    let mut pages = Vec::new();
    let mut at = 0;
    while let Some(p) = find(data, TAIL, at) {
        let Some(open) = data[..p].windows(2).rposition(|w| w == b"<<") else {
            return fail("an image without its dictionary");
        };
        let dict = std::str::from_utf8(&data[open..p]).unwrap_or("");
        let line_start = data[..open]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        // The colour space is set two lines before the image: `… setcolorspace`.
        let before = std::str::from_utf8(&data[..line_start]).unwrap_or("");
        let cs_line = before
            .lines()
            .rev()
            .find(|l| l.ends_with("setcolorspace"))
            .unwrap_or("");
        let head = ImageHead {
            width: number(dict, "/Width")?,
            height: number(dict, "/Height")?,
            bits: number(dict, "/BitsPerComponent")? as u32,
            space: space(cs_line.trim(), cs_line)?,
            decode: value(dict, "/Decode").map(numbers).unwrap_or_default(),
        };
        head.check()?;
        let start = p + TAIL.len();
        let (packed, end) = ascii85(data, start)?;
        let expected = head.stride() * head.height;
        let raw = run_length(&packed, expected)?;
        pages.push(head.image(&raw)?);
        at = end;
    }
    if pages.is_empty() {
        return fail("no image");
    }
    Ok(pages)
}

/// Decodes ASCII85 text from `start` to its `~>`; returns the bytes and the offset after it.
pub fn ascii85(data: &[u8], start: usize) -> DResult<(Vec<u8>, usize)> {
    let mut out = Vec::new();
    let mut group = [0u8; 5];
    let mut n = 0;
    let mut i = start;
    loop {
        let Some(&c) = data.get(i) else {
            return fail("ASCII85 data without its end (~>)");
        };
        i += 1;
        match c {
            b'~' => {
                if data.get(i) != Some(&b'>') {
                    return fail(format!("ASCII85: '~' without '>' at byte {}", i - 1));
                }
                i += 1;
                break;
            }
            b'z' if n == 0 => out.extend_from_slice(&[0; 4]),
            b'!'..=b'u' => {
                group[n] = c - b'!';
                n += 1;
                if n == 5 {
                    out.extend_from_slice(&a85_group(&group, i - 1)?);
                    n = 0;
                }
            }
            c if c.is_ascii_whitespace() => {}
            c => return fail(format!("ASCII85: byte {c:#04x} at {}", i - 1)),
        }
    }
    match n {
        0 => {}
        1 => return fail("ASCII85: a final group of one character"),
        _ => {
            // A final group of n characters stands for n − 1 bytes, padded with 'u'.
            group[n..].fill(b'u' - b'!');
            let bytes = a85_group(&group, i)?;
            out.extend_from_slice(&bytes[..n - 1]);
        }
    }
    Ok((out, i))
}

fn a85_group(g: &[u8; 5], at: usize) -> DResult<[u8; 4]> {
    let v = g.iter().fold(0u64, |v, &d| v * 85 + d as u64);
    match u32::try_from(v) {
        Ok(v) => Ok(v.to_be_bytes()),
        Err(_) => fail(format!("ASCII85: a group over 2^32 before byte {at}")),
    }
}

/// Decodes RunLengthDecode data (PLRM §3.13.3) up to its end-of-data byte (128) or
/// `limit` bytes.
pub fn run_length(data: &[u8], limit: usize) -> DResult<Vec<u8>> {
    let mut out = Vec::with_capacity(limit);
    let mut i = 0;
    while out.len() < limit {
        let Some(&n) = data.get(i) else {
            return fail("run-length data without its end");
        };
        match n {
            128 => break,
            0..=127 => {
                let k = n as usize + 1;
                let Some(s) = data.get(i + 1..i + 1 + k) else {
                    return fail("run-length data cut short");
                };
                out.extend_from_slice(s);
                i += 1 + k;
            }
            _ => {
                let Some(&b) = data.get(i + 1) else {
                    return fail("run-length data cut short");
                };
                out.extend(std::iter::repeat_n(b, 257 - n as usize));
                i += 2;
            }
        }
    }
    out.truncate(limit);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{self, Format, WriteOptions};
    use crate::raster::{Halftone, Samples};

    /// A bilevel halftone of `w` × `h` with a varied pattern.
    fn pattern(w: usize, h: usize) -> Halftone {
        let levels: Vec<u8> = (0..w * h)
            .map(|i| u8::from((i * 7 + i / w * 3) % 5 < 2))
            .collect();
        from_levels(w, h, 2, &levels)
    }

    fn from_levels(w: usize, h: usize, levels: u16, l: &[u8]) -> Halftone {
        let mut ht = Halftone::new(w, h, 1, levels);
        for y in 0..h {
            for x in 0..w {
                ht.set(0, x, y, l[y * w + x]);
            }
        }
        ht
    }

    fn encode(h: &Halftone, format: Format, dpi: Option<f64>) -> Vec<u8> {
        let mut opts = WriteOptions::new(format);
        opts.dpi = dpi;
        let mut out = Vec::new();
        io::encode(h, &opts, Path::new("t"), &mut out).unwrap();
        out
    }

    fn codes(img: &Image) -> Vec<u8> {
        match &img.planes[0] {
            Samples::U8(v) => v.clone(),
            Samples::U16(_) => panic!("16-bit"),
        }
    }

    /// Every printer language gives back exactly the bits of the halftone.
    #[test]
    fn every_language_reads_back_the_bits() {
        for (w, h) in [(37, 11), (320, 3), (8, 1)] {
            let ht = pattern(w, h);
            let want: Vec<u8> = ht.levels_of(0).iter().map(|&l| l * 255).collect();
            for (format, dpi) in [
                (Format::Pdf, None),
                (Format::Ps, None),
                (Format::Pcl, Some(300.0)),
                (Format::EscPos, None),
                (Format::Zpl, None),
            ] {
                let data = encode(&ht, format, dpi);
                let lang = sniff(&data).unwrap_or_else(|| panic!("{format:?} not sniffed"));
                let mut pages = pages(&data, lang).unwrap();
                assert_eq!(pages.len(), 1, "{format:?}");
                let mut img = pages.pop().unwrap();
                assert!(fit_width(&mut img, w), "{format:?} {}", img.width);
                assert_eq!((img.width, img.height), (w, h), "{format:?}");
                assert_eq!(codes(&img), want, "{format:?} {w}x{h}");
            }
        }
    }

    #[test]
    fn group4_pdf_reads_back_the_bits() {
        let ht = pattern(45, 17);
        let mut opts = WriteOptions::new(Format::Pdf);
        opts.compression = Some(io::Compression::G4);
        let mut data = Vec::new();
        io::encode(&ht, &opts, Path::new("t"), &mut data).unwrap();
        assert!(find(&data, b"/CCITTFaxDecode", 0).is_some());
        let img = pdf(&data).unwrap().pop().unwrap();
        let want: Vec<u8> = ht.levels_of(0).iter().map(|&l| l * 255).collect();
        assert_eq!(codes(&img), want);
    }

    /// Four grey levels come back as the codes the PGM of the same halftone holds.
    #[test]
    fn grey_levels_read_back_as_display_codes() {
        let levels: Vec<u8> = (0..60).map(|i| (i % 4) as u8).collect();
        let ht = from_levels(12, 5, 4, &levels);
        let want: Vec<u8> = levels
            .iter()
            .map(|&k| io::level_code(k, 4, 255, crate::tone::Encoding::Srgb) as u8)
            .collect();
        for format in [Format::Pdf, Format::Ps] {
            let data = encode(&ht, format, Some(300.0));
            let img = pages(&data, sniff(&data).unwrap()).unwrap().pop().unwrap();
            assert_eq!(codes(&img), want, "{format:?}");
        }
    }

    #[test]
    fn ascii85_and_run_length() {
        // "Man " is "9jqo^" (the classic example); a final group of two characters is one
        // byte.
        let (b, end) = ascii85(b"9jqo^z6W~>rest", 0).unwrap();
        assert_eq!(&b[..4], b"Man ");
        assert_eq!(&b[4..8], &[0; 4]);
        assert_eq!(b.len(), 8 + 1);
        assert_eq!(end, 10);
        assert!(ascii85(b"9jqo^", 0).is_err());
        assert_eq!(
            run_length(&[2, 1, 2, 3, 254, 9, 128], 100).unwrap(),
            vec![1, 2, 3, 9, 9, 9]
        );
        assert!(run_length(&[5, 1], 100).is_err());
    }

    #[test]
    fn broken_files_are_errors_not_panics() {
        let ht = pattern(30, 9);
        for format in [Format::Pdf, Format::Ps] {
            let data = encode(&ht, format, None);
            for cut in [10, data.len() / 3, data.len() / 2, data.len() - 20] {
                let _ = pages(&data[..cut], sniff(&data).unwrap());
            }
            let mut flipped = data.clone();
            for i in (0..flipped.len()).step_by(7) {
                flipped[i] ^= 0x55;
                let _ = pages(&flipped, sniff(&data).unwrap());
            }
        }
        assert!(pdf(b"%PDF-1.4\n").is_err());
        assert!(postscript(b"%!PS\n").is_err());
    }
}
