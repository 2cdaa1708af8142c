//! PWG raster (PWG 5102.4, `image/pwg-raster`): what IPP Everywhere clients and CUPS send a
//! raster printer. Reading only: a file is the sync word `RaS2`, then for each page a
//! 1796-byte header (the CUPS version-2 page header, big-endian) and the page's lines in the
//! PackBits-like line compression that Apple raster ([`super::urf`]) shares.
//!
//! Memory stays bounded whatever a header claims: the pixel limit is checked from the header,
//! a line is at most [`MAX_WIDTH`] pixels, and the page's planes grow only as lines are
//! actually decoded, so a short file claiming a huge page fails at its end having allocated
//! what it held.

use std::path::Path;

use crate::error::Result;
use crate::io::{check_pixels, decode_err, ReadOptions};
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::Encoding;

/// The file's first bytes.
pub const SYNC: &[u8; 4] = b"RaS2";
/// Bytes in a page header.
pub const HEADER_BYTES: usize = 1796;
/// The widest line taken, in pixels (about 4.4 m at 600 dpi): a header claiming more is
/// refused before its line buffer is allocated.
pub const MAX_WIDTH: u32 = 1 << 16;

/// True when `data` starts like a PWG raster file.
pub fn is_pwg(data: &[u8]) -> bool {
    data.starts_with(SYNC)
}

/// How a page's samples relate to light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Space {
    /// One additive channel (0 = black): sgray, W.
    Gray,
    /// One subtractive channel (0 = white): black, K.
    Black,
    /// Red, green, blue (sRGB codes; Adobe RGB is read as sRGB).
    Rgb,
    /// Cyan, magenta, yellow, black, turned into RGB naively (no profile).
    Cmyk,
}

impl Space {
    fn channels(self) -> u32 {
        match self {
            Space::Gray | Space::Black => 1,
            Space::Rgb => 3,
            Space::Cmyk => 4,
        }
    }

    /// The byte that "fill the rest of the line" repeats (white).
    fn white(self) -> u8 {
        match self {
            Space::Gray | Space::Rgb => 0xff,
            Space::Black | Space::Cmyk => 0,
        }
    }
}

/// What a page header says, as far as decoding needs it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PageHeader {
    pub width: u32,
    pub height: u32,
    pub bits_per_color: u32,
    pub space: Space,
    pub dpi: (u32, u32),
}

impl PageHeader {
    fn bytes_per_pixel(&self) -> usize {
        (self.bits_per_pixel() as usize).div_ceil(8)
    }

    fn bits_per_pixel(&self) -> u32 {
        self.bits_per_color * self.space.channels()
    }

    fn bytes_per_line(&self) -> usize {
        (self.width as usize * self.bits_per_pixel() as usize).div_ceil(8)
    }

    /// Refuses what is not a decodable page: one line naming the cause.
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("a page of {}x{} pixels", self.width, self.height));
        }
        if self.width > MAX_WIDTH {
            return Err(format!(
                "a page {} pixels wide (the most is {MAX_WIDTH})",
                self.width
            ));
        }
        let ok = match self.space {
            Space::Gray | Space::Black => matches!(self.bits_per_color, 1 | 8 | 16),
            Space::Rgb | Space::Cmyk => matches!(self.bits_per_color, 8 | 16),
        };
        if !ok {
            return Err(format!(
                "{} bits per colour in {:?} pages are not supported",
                self.bits_per_color, self.space
            ));
        }
        if self.dpi.0 == 0 || self.dpi.1 == 0 || self.dpi.0 > 10_000 || self.dpi.1 > 10_000 {
            return Err(format!("a resolution of {}x{} dpi", self.dpi.0, self.dpi.1));
        }
        Ok(())
    }
}

/// The pages of a PWG raster file, decoded one at a time.
///
/// ```no_run
/// # use std::path::Path;
/// let data = std::fs::read("page.pwg")?;
/// let name = Path::new("page.pwg");
/// for page in halftone::io::lang::pwg::pages(&data, name, &Default::default())? {
///     let image = page?;
///     println!("{}x{} at {:?} dpi", image.width, image.height, image.dpi);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Pages<'a> {
    data: &'a [u8],
    pos: usize,
    name: &'a Path,
    opts: ReadOptions,
    page: usize,
    done: bool,
}

/// Starts reading the PWG raster file in `data` (`name` is for error messages).
pub fn pages<'a>(data: &'a [u8], name: &'a Path, opts: &ReadOptions) -> Result<Pages<'a>> {
    if !is_pwg(data) {
        return Err(decode_err(
            name,
            "not a PWG raster file (no RaS2 sync word)".into(),
        ));
    }
    Ok(Pages {
        data,
        pos: SYNC.len(),
        name,
        opts: opts.clone(),
        page: 0,
        done: false,
    })
}

impl Iterator for Pages<'_> {
    type Item = Result<Image>;

    fn next(&mut self) -> Option<Result<Image>> {
        if self.done || (self.pos >= self.data.len() && self.page > 0) {
            return None;
        }
        self.page += 1;
        let r = self.next_page();
        if r.is_err() {
            self.done = true;
        }
        Some(r)
    }
}

impl Pages<'_> {
    fn next_page(&mut self) -> Result<Image> {
        let page = self.page;
        let err = |msg: String| decode_err(self.name, format!("page {page}: {msg}"));
        let rest = &self.data[self.pos..];
        if rest.len() < HEADER_BYTES {
            return Err(err(format!(
                "truncated: the page header needs {HEADER_BYTES} bytes, {} remain",
                rest.len()
            )));
        }
        let h = parse_header(&rest[..HEADER_BYTES]).map_err(err)?;
        check_pixels(self.name, h.width, h.height, &self.opts)?;
        self.pos += HEADER_BYTES;
        decode_lines(self.data, &mut self.pos, &h, true).map_err(err)
    }
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Reads the fields a decoder needs from a 1796-byte page header.
pub(crate) fn parse_header(b: &[u8]) -> std::result::Result<PageHeader, String> {
    let bits_per_color = be32(b, 384);
    let bits_per_pixel = be32(b, 388);
    let bytes_per_line = be32(b, 392);
    let color_order = be32(b, 396);
    let space = match be32(b, 400) {
        0 | 18 => Space::Gray,
        3 => Space::Black,
        1 | 19 | 20 => Space::Rgb,
        6 => Space::Cmyk,
        s => return Err(format!("colour space {s} is not supported")),
    };
    let compression = be32(b, 404);
    let h = PageHeader {
        width: be32(b, 372),
        height: be32(b, 376),
        bits_per_color,
        space,
        dpi: (be32(b, 276), be32(b, 280)),
    };
    if color_order != 0 {
        return Err(format!(
            "colour order {color_order} (PWG raster is chunked, 0)"
        ));
    }
    if compression > 1 {
        return Err(format!("compression {compression} is not PWG's"));
    }
    h.check()?;
    if bits_per_pixel != h.bits_per_pixel() {
        return Err(format!(
            "{bits_per_pixel} bits per pixel for {} channels of {bits_per_color} bits",
            h.space.channels()
        ));
    }
    if bytes_per_line as usize != h.bytes_per_line() {
        return Err(format!(
            "{bytes_per_line} bytes per line for {} pixels of {bits_per_pixel} bits",
            h.width
        ));
    }
    Ok(h)
}

/// Decodes one page's lines from `data[*pos..]`, leaving `*pos` after them: compressed as
/// below, or as they are (CUPS raster v3) when `compressed` is false.
///
/// Each compressed line group is a repeat byte (the line is used that many times plus one), then runs
/// of whole pixels: a control byte below 128 repeats the next pixel (control + 1) times, 128
/// fills the rest of the line with white, and above 128 (257 − control) pixels follow as is.
pub(crate) fn decode_lines(
    data: &[u8],
    pos: &mut usize,
    h: &PageHeader,
    compressed: bool,
) -> std::result::Result<Image, String> {
    let (width, height) = (h.width as usize, h.height as usize);
    let bpp = h.bytes_per_pixel();
    let bpl = h.bytes_per_line();
    let wide = h.bits_per_color == 16;
    let planes_n = match h.space {
        Space::Gray | Space::Black => 1,
        Space::Rgb | Space::Cmyk => 3,
    };
    // Grown as lines are decoded: at most what the data really holds.
    let first = (width * height).min(1 << 20);
    let mut p8: Vec<Vec<u8>> = Vec::new();
    let mut p16: Vec<Vec<u16>> = Vec::new();
    for _ in 0..planes_n {
        if wide {
            p16.push(Vec::with_capacity(first));
        } else {
            p8.push(Vec::with_capacity(first));
        }
    }
    let mut line = vec![0u8; bpl];
    let truncated = |y: usize| format!("truncated in line {} of {height}", y + 1);
    let mut y = 0;
    while y < height {
        if !compressed {
            let Some(raw) = data.get(*pos..*pos + bpl) else {
                return Err(truncated(y));
            };
            *pos += bpl;
            if wide {
                push16(&mut p16, raw, width, h.space);
            } else {
                push8(&mut p8, raw, width, h);
            }
            y += 1;
            continue;
        }
        let Some(&rep) = data.get(*pos) else {
            return Err(truncated(y));
        };
        *pos += 1;
        let mut x = 0; // bytes of the line filled
        while x < bpl {
            let Some(&c) = data.get(*pos) else {
                return Err(truncated(y));
            };
            *pos += 1;
            match c {
                0..=127 => {
                    let Some(px) = data.get(*pos..*pos + bpp) else {
                        return Err(truncated(y));
                    };
                    *pos += bpp;
                    for _ in 0..=c {
                        let n = bpp.min(bpl - x);
                        line[x..x + n].copy_from_slice(&px[..n]);
                        x += n;
                        if x == bpl {
                            break;
                        }
                    }
                }
                128 => {
                    line[x..].fill(h.space.white());
                    x = bpl;
                }
                _ => {
                    let n = (257 - c as usize) * bpp;
                    let Some(px) = data.get(*pos..*pos + n) else {
                        return Err(truncated(y));
                    };
                    *pos += n;
                    let n = n.min(bpl - x);
                    line[x..x + n].copy_from_slice(&px[..n]);
                    x += n;
                }
            }
        }
        let times = (rep as usize + 1).min(height - y);
        for _ in 0..times {
            if wide {
                push16(&mut p16, &line, width, h.space);
            } else {
                push8(&mut p8, &line, width, h);
            }
        }
        y += times;
    }
    let planes: Vec<Samples> = if wide {
        p16.into_iter().map(Samples::U16).collect()
    } else {
        p8.into_iter().map(Samples::U8).collect()
    };
    Ok(Image {
        width,
        height,
        color: if planes.len() == 1 {
            ColorKind::Gray
        } else {
            ColorKind::Rgb
        },
        planes,
        encoding: Encoding::Srgb,
        dpi: Some(h.dpi.0 as f64),
    })
}

fn cmyk_to_rgb(c: u32, m: u32, y: u32, k: u32, max: u32) -> [u32; 3] {
    [c, m, y].map(|v| (max - v) * (max - k) / max)
}

fn push8(planes: &mut [Vec<u8>], line: &[u8], width: usize, h: &PageHeader) {
    match (h.space, h.bits_per_color) {
        (Space::Gray | Space::Black, 1) => {
            let black_bit = h.space == Space::Black;
            planes[0].extend((0..width).map(|x| {
                let bit = line[x / 8] >> (7 - x % 8) & 1 == 1;
                if bit == black_bit {
                    0
                } else {
                    255
                }
            }));
        }
        (Space::Gray, _) => planes[0].extend_from_slice(&line[..width]),
        (Space::Black, _) => planes[0].extend(line[..width].iter().map(|v| 255 - v)),
        (Space::Rgb, _) => {
            for (c, plane) in planes.iter_mut().enumerate() {
                plane.extend(line.chunks_exact(3).map(|p| p[c]));
            }
        }
        (Space::Cmyk, _) => {
            let px: Vec<[u32; 3]> = line
                .chunks_exact(4)
                .map(|p| {
                    let [c, m, y, k] = [p[0], p[1], p[2], p[3]].map(u32::from);
                    cmyk_to_rgb(c, m, y, k, 255)
                })
                .collect();
            for (c, plane) in planes.iter_mut().enumerate() {
                plane.extend(px.iter().map(|p| p[c] as u8));
            }
        }
    }
}

fn push16(planes: &mut [Vec<u16>], line: &[u8], width: usize, space: Space) {
    let s: Vec<u16> = line
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    match space {
        Space::Gray => planes[0].extend_from_slice(&s[..width]),
        Space::Black => planes[0].extend(s[..width].iter().map(|v| 65535 - v)),
        Space::Rgb => {
            for (c, plane) in planes.iter_mut().enumerate() {
                plane.extend(s.chunks_exact(3).map(|p| p[c]));
            }
        }
        Space::Cmyk => {
            let px: Vec<[u32; 3]> = s
                .chunks_exact(4)
                .map(|p| {
                    let [c, m, y, k] = [p[0], p[1], p[2], p[3]].map(u32::from);
                    cmyk_to_rgb(c, m, y, k, 65535)
                })
                .collect();
            for (c, plane) in planes.iter_mut().enumerate() {
                plane.extend(px.iter().map(|p| p[c] as u16));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-page PWG file: `lines` already compressed.
    pub(crate) fn file(w: u32, h: u32, space: u32, bits: u32, chans: u32, lines: &[u8]) -> Vec<u8> {
        let mut hd = vec![0u8; HEADER_BYTES];
        hd[..9].copy_from_slice(b"PwgRaster");
        let mut put = |at: usize, v: u32| hd[at..at + 4].copy_from_slice(&v.to_be_bytes());
        put(276, 300);
        put(280, 300);
        put(372, w);
        put(376, h);
        put(384, bits);
        put(388, bits * chans);
        put(392, (w * bits * chans).div_ceil(8));
        put(400, space);
        let mut f = SYNC.to_vec();
        f.extend(hd);
        f.extend_from_slice(lines);
        f
    }

    fn read(f: &[u8]) -> Result<Vec<Image>> {
        pages(f, Path::new("t.pwg"), &ReadOptions::default())?.collect()
    }

    fn gray(img: &Image) -> &[u8] {
        match &img.planes[0] {
            Samples::U8(v) => v,
            Samples::U16(_) => panic!("16-bit"),
        }
    }

    #[test]
    fn runs_literals_fill_and_line_repeats() {
        // 4x3 sgray: line 1 = run of 2 × 10 then literal (0xff: two pixels) 20 30; repeated twice; line 3 = fill.
        let f = file(4, 3, 18, 8, 1, &[1, 1, 10, 0xff, 20, 30, 0, 128]);
        let p = read(&f).unwrap();
        assert_eq!(p.len(), 1);
        assert_eq!(
            gray(&p[0]),
            &[10, 10, 20, 30, 10, 10, 20, 30, 255, 255, 255, 255]
        );
        assert_eq!(p[0].dpi, Some(300.0));
        // black_1: bits set are black; the fill is white (0 bits).
        let f = file(10, 1, 3, 1, 1, &[0, 0, 0b1010_0000, 128]);
        let p = read(&f).unwrap();
        assert_eq!(gray(&p[0]), &[0, 255, 0, 255, 255, 255, 255, 255, 255, 255]);
        // Two pages.
        let mut two = file(1, 1, 18, 8, 1, &[0, 0, 7]);
        two.extend_from_slice(&file(1, 1, 18, 8, 1, &[0, 0, 9])[4..]);
        let p = read(&two).unwrap();
        assert_eq!((gray(&p[0]), gray(&p[1])), (&[7u8][..], &[9u8][..]));
    }

    #[test]
    fn bad_files_give_one_line_errors_and_bounded_memory() {
        let e = read(&file(4, 3, 18, 8, 1, &[1, 1, 10]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.pwg") && e.contains("truncated in line 1 of 3"),
            "{e}"
        );
        // A header claiming a page of 65536 x 4e9 pixels, and two bytes of data: refused by
        // the pixel limit before anything is allocated.
        let e = read(&file(65536, u32::MAX, 18, 8, 1, &[0, 128])).unwrap_err();
        assert!(e.to_string().contains("pixel"), "{e}");
        // Under the limit but far more than the data: fails at the data's end, having
        // grown its planes only as far as the lines given.
        let opts = ReadOptions {
            max_pixels: u64::MAX,
        };
        let f = file(65536, 60_000, 18, 8, 1, &[255, 128]);
        let e = pages(&f, Path::new("t.pwg"), &opts)
            .unwrap()
            .next()
            .unwrap();
        assert!(e.unwrap_err().to_string().contains("line 257 of 60000"));
        let e = read(&file(70_000, 1, 18, 8, 1, &[]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("70000 pixels wide"), "{e}");
        let e = read(&file(4, 1, 42, 8, 1, &[])).unwrap_err().to_string();
        assert!(e.contains("colour space 42"), "{e}");
        let e = read(b"RaS2 short").unwrap_err().to_string();
        assert!(e.contains("page 1: truncated: the page header"), "{e}");
        assert!(read(b"RaS3").is_err());
        // Every truncation and many random bytes: errors, never panics.
        let f = file(5, 4, 19, 8, 3, &[3, 0xff, 1, 2, 3, 4, 5, 6, 128]);
        assert_eq!(read(&f).unwrap()[0].planes.len(), 3);
        for n in 0..f.len() {
            assert!(read(&f[..n]).is_err());
        }
        let mut seed = 7u64;
        for _ in 0..3000 {
            let mut g = f.clone();
            for _ in 0..4 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let at = (seed >> 33) as usize % g.len();
                g[at] = (seed >> 20) as u8;
            }
            let _ = read(&g);
        }
    }
}
