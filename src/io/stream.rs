//! Inputs that cannot seek (standard input, a pipe, a FIFO, a character device, a process
//! substitution's `/dev/fd/N`): read once, front to back, never reopened.
//!
//! Their length is unknown until they end, and some never end (`/dev/zero`, a signature
//! followed by it, an image followed by endless data). So the header is parsed first, from
//! bytes that stay in front of the rest, and the format's header bounds what the rest can
//! be: a PNM or a WebP says its exact length (what follows is not read); a compressed
//! format cannot need more than twice its uncompressed size plus [`MARGIN`] for metadata.
//! A stream longer than that is refused when the bound is reached, with a message naming
//! it, after at most a few hundred megabytes for any image within the pixel limit that
//! fits in memory at all.

use std::io::Read;
use std::path::Path;

use super::codec::pnm::{self, HeaderParse};
use super::limits::{check_pixels, decode_err, max_input_bytes};
use super::ReadOptions;
use crate::error::{Error, Result};

/// Room for what a compressed file holds besides its pixel data (ICC profiles, EXIF and
/// XMP blocks, text chunks, palettes), and for the metadata read before a JPEG's frame
/// header.
pub const MARGIN: u64 = 32 << 20;

/// True for an input read as a stream: a path that exists and is neither a regular file
/// nor a folder (a FIFO, a device, `/dev/stdin`, `/proc/self/fd/N`).
pub fn is_stream(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// What the bytes read so far say about the input's length.
#[derive(Debug, PartialEq)]
enum Need {
    /// The image takes exactly this many bytes; what follows is not read.
    Exactly(u64),
    /// The image can take at most this many bytes (`what` says whose bound it is).
    AtMost(u64, String),
    /// The header goes on past the bytes read: read at least this many and look again.
    More(u64),
    /// Not a readable header, and why.
    Bad(String),
}

/// Reads a whole stream (its head included: `reader` starts at its first byte) under the
/// bound its header sets; `name` names it in messages. An image followed by endless data
/// stops at the bound with an error, as does a header followed by garbage.
pub fn read_stream(reader: &mut dyn Read, name: &Path, opts: &ReadOptions) -> Result<Vec<u8>> {
    let io_err = |e| Error::io(name, e);
    let mut bytes = Vec::with_capacity(1 << 16);
    let mut ended = fill(reader, &mut bytes, 4096).map_err(io_err)?;
    if bytes.is_empty() {
        return Err(decode_err(name, "empty file".into()));
    }
    loop {
        match need(&bytes, name, opts)? {
            Need::Bad(msg) => return Err(decode_err(name, msg)),
            Need::More(_) if ended => return Ok(bytes),
            Need::More(n) => {
                // Only a TIFF's directory may lie past its pixel data.
                let tiff = bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*");
                let limit = if tiff { max_input_bytes(opts) } else { MARGIN };
                if n > limit {
                    let why = format!("and its header is not complete yet ({limit} bytes allowed)");
                    return Err(over_limit(name, limit, &why, opts));
                }
                // Grow geometrically: a header that ends far in is found in few rounds.
                let target = n.max(bytes.len() as u64 * 2).min(limit) as usize;
                ended = fill(reader, &mut bytes, target).map_err(io_err)?;
            }
            Need::Exactly(n) => {
                if (bytes.len() as u64) < n {
                    let more = n - bytes.len() as u64;
                    reader.take(more).read_to_end(&mut bytes).map_err(io_err)?;
                }
                bytes.truncate(n.min(bytes.len() as u64) as usize);
                return Ok(bytes);
            }
            Need::AtMost(n, what) => {
                let n = n.min(max_input_bytes(opts));
                if !ended {
                    let have = bytes.len() as u64;
                    reader
                        .take(n.saturating_add(1).saturating_sub(have))
                        .read_to_end(&mut bytes)
                        .map_err(io_err)?;
                }
                if bytes.len() as u64 > n {
                    return Err(over_limit(
                        name,
                        n,
                        &format!("the most {what} can take"),
                        opts,
                    ));
                }
                return Ok(bytes);
            }
        }
    }
}

/// Reads until `bytes` holds `target` bytes or the stream ends; true when it ended.
fn fill(reader: &mut dyn Read, bytes: &mut Vec<u8>, target: usize) -> std::io::Result<bool> {
    let want = target.saturating_sub(bytes.len()) as u64;
    let got = reader.take(want).read_to_end(bytes)? as u64;
    Ok(got < want)
}

/// The error for a stream that goes on past its bound; `why` says whose bound it is.
fn over_limit(name: &Path, limit: u64, why: &str, opts: &ReadOptions) -> Error {
    let msg = if limit >= max_input_bytes(opts) {
        format!(
            "input limit hit: reading stopped at {limit} bytes, the most any image of at most \
             `max_pixels` {} pixels can take; raise `max_pixels` if it is one",
            opts.max_pixels
        )
    } else {
        format!(
            "input limit hit: reading stopped at {limit} bytes, {why}: data follows the \
             image, or it is corrupt. If it is one genuine image, save it to a file and pass \
             the file's path (a file is read at its own length)"
        )
    };
    decode_err(name, msg)
}

/// Bytes `raw` uncompressed bytes can take compressed, with metadata.
fn compressed(raw: u64) -> u64 {
    raw.saturating_mul(2).saturating_add(MARGIN)
}

fn be16(b: &[u8], at: usize) -> u64 {
    u16::from_be_bytes([b[at], b[at + 1]]) as u64
}

fn be32(b: &[u8], at: usize) -> u64 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as u64
}

fn le16(b: &[u8], at: usize) -> u64 {
    u16::from_le_bytes([b[at], b[at + 1]]) as u64
}

fn le32(b: &[u8], at: usize) -> u64 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as u64
}

/// The pixel limit on header dimensions (an error), then the bound for a compressed format.
fn sized(
    name: &Path,
    w: u64,
    h: u64,
    bytes_px: u64,
    fmt: &str,
    opts: &ReadOptions,
) -> Result<Need> {
    check_pixels(
        name,
        w.min(u32::MAX as u64) as u32,
        h.min(u32::MAX as u64) as u32,
        opts,
    )?;
    Ok(Need::AtMost(
        compressed(w * h * bytes_px),
        format!(
            "a {w}x{h} {fmt} (twice its uncompressed size plus {} MiB of metadata)",
            MARGIN >> 20
        ),
    ))
}

/// What the first bytes of a stream say about its length.
fn need(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    if b.starts_with(b"\x89PNG\r\n\x1a\n") {
        return png(b, name, opts);
    }
    if b.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return jpeg(b, name, opts);
    }
    if b.starts_with(b"GIF87a") || b.starts_with(b"GIF89a") {
        if b.len() < 10 {
            return Ok(Need::More(10));
        }
        // Up to 12 bits of LZW code a pixel of the logical screen.
        return sized(name, le16(b, 6), le16(b, 8), 1, "GIF", opts);
    }
    if b.starts_with(b"II*\0") || b.starts_with(b"MM\0*") {
        return tiff(b, name, opts);
    }
    if b.starts_with(b"BM") {
        return bmp(b, name, opts);
    }
    if b.starts_with(b"RIFF") && b.get(8..12) == Some(b"WEBP") {
        return webp(b, name, opts);
    }
    if b.len() >= 2 && b[0] == b'P' && (b'1'..=b'7').contains(&b[1]) {
        return pnm_need(b, name, opts);
    }
    if b.len() < 12 && image::guess_format(b).is_err() {
        // Too short to tell yet (a RIFF header, say).
        return Ok(Need::More(12));
    }
    Ok(match image::guess_format(b) {
        // Another format the `image` crate knows by its signature: its decoder says
        // whether it reads it.
        Ok(_) => Need::AtMost(
            MARGIN,
            format!("a file of this format ({} MiB)", MARGIN >> 20),
        ),
        Err(_) => Need::Bad(
            "not an image format halftone reads (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM)".into(),
        ),
    })
}

/// PNG: IHDR is the first chunk (PNG specification, 5.2 and 11.2.2).
fn png(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    if b.len() < 29 {
        return Ok(Need::More(29));
    }
    if &b[8..16] != b"\0\0\0\x0dIHDR" {
        return Ok(Need::Bad(
            "bad PNG file: the first chunk is not the image header (IHDR)".into(),
        ));
    }
    let (w, h, depth) = (be32(b, 16), be32(b, 20), b[24] as u64);
    let channels = match b[25] {
        0 | 3 => 1,
        2 => 3,
        4 => 2,
        6 => 4,
        t => return Ok(Need::Bad(format!("bad PNG file: colour type {t}"))),
    };
    check_pixels(name, w as u32, h as u32, opts)?;
    // Each row: a filter byte and its packed samples.
    let row = 1 + (w * channels * depth.max(1)).div_ceil(8);
    Ok(Need::AtMost(
        compressed(h * row),
        format!(
            "a {w}x{h} PNG (twice its uncompressed size plus {} MiB of metadata)",
            MARGIN >> 20
        ),
    ))
}

/// JPEG: markers and their segments up to the frame header (ITU T.81, B.1.1).
fn jpeg(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    let mut pos = 2;
    loop {
        while b.get(pos) == Some(&0xFF) && b.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        if pos + 4 > b.len() {
            return Ok(Need::More(pos as u64 + 4));
        }
        if b[pos] != 0xFF {
            return Ok(Need::Bad(format!(
                "bad JPEG file: expected a marker at byte {pos}, found 0x{:02x}",
                b[pos]
            )));
        }
        let marker = b[pos + 1];
        match marker {
            0xD0..=0xD7 | 0xD8 | 0x01 => {
                pos += 2;
                continue;
            }
            0x00 | 0xD9 | 0xDA => {
                return Ok(Need::Bad(format!(
                    "bad JPEG file: marker 0xFF{marker:02X} at byte {pos}, before the frame \
                     header"
                )))
            }
            _ => {}
        }
        let len = be16(b, pos + 2) as usize;
        if len < 2 {
            return Ok(Need::Bad(format!(
                "bad JPEG file: a segment of length {len} at byte {pos}"
            )));
        }
        if (0xC0..=0xCF).contains(&marker) && !matches!(marker, 0xC4 | 0xC8 | 0xCC) {
            if pos + 10 > b.len() {
                return Ok(Need::More(pos as u64 + 10));
            }
            let (h, w, nc) = (be16(b, pos + 5), be16(b, pos + 7), b[pos + 9] as u64);
            let bytes = if b[pos + 4] > 8 { 2 } else { 1 };
            // A height of 0 is set later by a DNL marker: bound it by the format's largest.
            return sized(
                name,
                w,
                if h == 0 { 65535 } else { h },
                nc * bytes,
                "JPEG",
                opts,
            );
        }
        pos += 2 + len;
    }
}

/// TIFF: the first directory, wherever the header says it is (TIFF 6.0, section 2).
fn tiff(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    if b.len() < 8 {
        return Ok(Need::More(8));
    }
    let le = b[0] == b'I';
    let u16at = |at: usize| if le { le16(b, at) } else { be16(b, at) };
    let u32at = |at: usize| if le { le32(b, at) } else { be32(b, at) };
    let ifd = u32at(4) as usize;
    if ifd < 8 {
        return Ok(Need::Bad(format!(
            "bad TIFF file: its first directory (IFD) is at offset {ifd}, inside the header"
        )));
    }
    if ifd + 2 > b.len() {
        return Ok(Need::More(ifd as u64 + 2));
    }
    let n = u16at(ifd) as usize;
    let end = ifd + 2 + 12 * n + 4;
    if end > b.len() {
        return Ok(Need::More(end as u64));
    }
    let (mut w, mut h, mut spp, mut bps) = (0, 0, 1, 16);
    for e in (0..n).map(|i| ifd + 2 + 12 * i) {
        // SHORT (3) values sit in the first two bytes of the value field.
        let value = if u16at(e + 2) == 3 {
            u16at(e + 8)
        } else {
            u32at(e + 8)
        };
        match u16at(e) {
            256 => w = value,
            257 => h = value,
            258 if u32at(e + 4) == 1 => bps = value.clamp(1, 64),
            277 => spp = value.clamp(1, 64),
            _ => {}
        }
    }
    let need = sized(name, w, h, (spp * bps).div_ceil(8), "TIFF", opts)?;
    Ok(match need {
        // The directory may follow the pixel data.
        Need::AtMost(n, what) => Need::AtMost(n.saturating_add(end as u64), what),
        other => other,
    })
}

/// BMP: the file header and the size fields of the info header (any version).
fn bmp(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    if b.len() < 30 {
        return Ok(Need::More(30));
    }
    let offset = le32(b, 10);
    let info = le32(b, 14);
    let (w, h, bits) = match info {
        12 => (le16(b, 18), le16(b, 20), le16(b, 24)),
        16.. => (
            (le32(b, 18) as u32 as i32).unsigned_abs() as u64,
            (le32(b, 22) as u32 as i32).unsigned_abs() as u64,
            le16(b, 28),
        ),
        _ => {
            return Ok(Need::Bad(format!(
                "bad BMP file: an info header of {info} bytes (at least 12)"
            )))
        }
    };
    let need = sized(name, w, h, bits.clamp(1, 64).div_ceil(8), "BMP", opts)?;
    Ok(match need {
        Need::AtMost(n, what) => Need::AtMost(n.saturating_add(offset), what),
        other => other,
    })
}

/// The size a WebP's first chunk gives (VP8X canvas, VP8L or VP8 frame header), or why
/// there is none. Reading its fields here, not through the decoder: that one reads a
/// lossless side of 16384 as 0.
pub(crate) fn webp_size(b: &[u8]) -> Option<(u64, u64)> {
    match b.get(12..16)? {
        b"VP8X" if b.len() >= 30 => {
            let le24 =
                |at: usize| b[at] as u64 | (b[at + 1] as u64) << 8 | (b[at + 2] as u64) << 16;
            Some((1 + le24(24), 1 + le24(27)))
        }
        b"VP8L" if b.len() >= 25 && b[20] == 0x2F => {
            let bits = le32(b, 21);
            Some((1 + (bits & 0x3FFF), 1 + ((bits >> 14) & 0x3FFF)))
        }
        b"VP8 " if b.len() >= 30 && b[23..26] == [0x9D, 0x01, 0x2A] => {
            Some((le16(b, 26) & 0x3FFF, le16(b, 28) & 0x3FFF))
        }
        _ => None,
    }
}

/// WebP: a RIFF file says its own length (RIFF container, section 2 of RFC 9649).
fn webp(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    if b.len() < 30 {
        return Ok(Need::More(30));
    }
    let Some((w, h)) = webp_size(b) else {
        return Ok(Need::Bad(
            "bad WEBP file: no VP8, VP8L or VP8X image header at its start".into(),
        ));
    };
    let Need::AtMost(bound, what) = sized(name, w, h, 4, "WebP", opts)? else {
        unreachable!("sized gives a bound")
    };
    let len = 8 + le32(b, 4);
    if len > bound {
        return Ok(Need::Bad(format!(
            "bad WEBP file: its RIFF header claims {len} bytes, more than {what} can take \
             ({bound} bytes)"
        )));
    }
    Ok(Need::Exactly(len))
}

/// PNM: binary kinds say their exact length; plain (text) kinds are bounded by their
/// samples, a few characters each (Netpbm manual: pbm, pgm, ppm, pam).
fn pnm_need(b: &[u8], name: &Path, opts: &ReadOptions) -> Result<Need> {
    let more = || -> Result<Need> { Ok(Need::More(b.len() as u64 + 4096)) };
    if b[1] == b'7' {
        return match pnm::parse_pam(b) {
            Ok(Some(p)) if p.depth == 0 => Ok(Need::Bad(pnm::PAM_DEPTH_0.into())),
            Ok(Some(p)) => {
                check_pixels(name, p.width, p.height, opts)?;
                let bytes = if p.maxval > 255 { 2 } else { 1 };
                let data = p.width as u64 * p.height as u64 * p.depth as u64 * bytes;
                Ok(Need::Exactly(p.data_offset as u64 + data))
            }
            Ok(None) => more(),
            Err(msg) => Ok(Need::Bad(msg)),
        };
    }
    // P6 has the header of P5; P1–P3 have those of P4–P6 with text samples.
    let mut probe = b[..b.len().min(1 << 20)].to_vec();
    let (kind, channels, text) = match b[1] {
        b'1' => (b'4', 1, true),
        b'2' => (b'5', 1, true),
        b'3' => (b'5', 3, true),
        b'4' | b'5' => (b[1], 1, false),
        _ => (b'5', 3, false),
    };
    probe[1] = kind;
    match pnm::parse_header(&probe) {
        HeaderParse::Ok(h) => {
            check_pixels(name, h.width, h.height, opts)?;
            let px = h.width as u64 * h.height as u64;
            if text {
                // At most "65535" and a separator a sample, and comments.
                let bound = (px * channels).saturating_mul(8).saturating_add(MARGIN);
                let what = format!(
                    "a {}x{} plain PNM (8 bytes a sample plus {} MiB of comments)",
                    h.width,
                    h.height,
                    MARGIN >> 20
                );
                return Ok(Need::AtMost(bound, what));
            }
            let data = match (kind, h.maxval > 255) {
                (b'4', _) => (h.width as u64).div_ceil(8) * h.height as u64,
                (_, wide) => px * channels * if wide { 2 } else { 1 },
            };
            Ok(Need::Exactly(h.data_offset as u64 + data))
        }
        HeaderParse::Incomplete => more(),
        HeaderParse::Bad(msg) => Ok(Need::Bad(msg)),
        HeaderParse::NotFastPath => Ok(Need::Bad("bad PNM header".into())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn need_of(b: &[u8]) -> Need {
        need(b, Path::new("x"), &ReadOptions::default()).unwrap()
    }

    #[test]
    fn binary_pnm_is_exact_and_text_pnm_bounded() {
        assert_eq!(need_of(b"P5 3 2 255\nabcdef"), Need::Exactly(17));
        assert_eq!(need_of(b"P6 3 2 65535\n"), Need::Exactly(13 + 36));
        assert_eq!(need_of(b"P4 9 2\n"), Need::Exactly(7 + 4));
        assert!(matches!(need_of(b"P2 3 2 255\n1 2 3"), Need::AtMost(..)));
        assert_eq!(need_of(b"P5 3"), Need::More(4 + 4096));
    }

    #[test]
    fn signatures_followed_by_zeros_are_refused_at_once() {
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.resize(4096, 0);
        assert!(matches!(need_of(&png), Need::Bad(_)));
        let mut jpeg = vec![0xFF, 0xD8, 0xFF];
        jpeg.resize(4096, 0);
        assert!(matches!(need_of(&jpeg), Need::Bad(_)));
        let mut tiff = b"II*\0".to_vec();
        tiff.resize(4096, 0);
        assert!(matches!(need_of(&tiff), Need::Bad(_)));
    }

    #[test]
    fn jpeg_frame_header_after_metadata() {
        let mut j = vec![0xFF, 0xD8, 0xFF, 0xE1, 0x01, 0x02];
        j.resize(2 + 2 + 0x102, 0);
        j.extend_from_slice(&[0xFF, 0xC0, 0, 11, 8, 0, 20, 0, 30, 3, 0, 0, 0, 0, 0]);
        let Need::AtMost(n, what) = need_of(&j) else {
            panic!("{:?}", need_of(&j))
        };
        assert_eq!(n, 2 * 20 * 30 * 3 + MARGIN);
        assert!(what.starts_with("a 30x20 JPEG (twice"), "{what}");
        assert_eq!(need_of(&j[..100]), Need::More(2 + 2 + 0x102 + 4));
    }
}
