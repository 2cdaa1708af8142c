//! A fast reader for 8-bit binary pixmaps (P6, maxval 255): the interleaved file is read by
//! every thread at once, in bands of rows, straight into the three planes a method reads.
//!
//! Why: through the `image` crate a 24 MP pixmap is read whole (72 MB), decoded into a second
//! interleaved buffer and then split into planes (a third copy); here each band is read into a
//! small buffer and split as it arrives, so the planes are the only full-size allocation.
//! Other pixmaps (maxval other than 255, pipes, P3) keep the `image` path.

use std::fs::File;

use super::pnm::{self, HeaderParse, PnmHeader};
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::Encoding;

/// Pixmaps with at least this many pixels take this path (smaller ones gain nothing).
const MIN_PIXELS: usize = 1 << 20;
/// Bytes read at a time by one thread.
const PIECE: usize = 1 << 20;

/// The header of an 8-bit P6 file at the start of `head`, if it is one (the P6 header has
/// the P5 layout: width, height, maxval, one whitespace byte).
pub fn header(head: &[u8]) -> Option<PnmHeader> {
    if !head.starts_with(b"P6") {
        return None;
    }
    let mut as_p5 = head.to_vec();
    as_p5[1] = b'5';
    match pnm::parse_header(&as_p5) {
        HeaderParse::Ok(h)
            if h.maxval == 255 && h.width as usize * h.height as usize >= MIN_PIXELS =>
        {
            Some(h)
        }
        _ => None,
    }
}

/// Reads the pixels of `file` (a regular file whose header is `h`) into three planes.
/// Errors are one-line messages (a short file is "truncated").
#[cfg(unix)]
pub fn read(file: &File, h: &PnmHeader) -> Result<Image, String> {
    use rayon::prelude::*;
    use std::os::unix::fs::FileExt;
    let (w, ht) = (h.width as usize, h.height as usize);
    let n = w * ht;
    let mut planes = [vec![0u8; n], vec![0u8; n], vec![0u8; n]];
    // Whole rows a piece, so that a piece maps onto whole rows of every plane.
    let rows = (PIECE / (3 * w)).max(1);
    let [r, g, b] = &mut planes;
    r.par_chunks_mut(rows * w)
        .zip(g.par_chunks_mut(rows * w))
        .zip(b.par_chunks_mut(rows * w))
        .enumerate()
        .try_for_each_init(Vec::new, |buf, (i, ((r, g), b))| {
            buf.resize(3 * r.len(), 0);
            let at = h.data_offset + i * rows * w * 3;
            file.read_exact_at(buf, at as u64)?;
            for (((px, r), g), b) in buf.chunks_exact(3).zip(r).zip(g.iter_mut()).zip(b) {
                *r = px[0];
                *g = px[1];
                *b = px[2];
            }
            Ok(())
        })
        .map_err(|e: std::io::Error| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                format!("truncated: {w}x{ht} needs {} bytes of pixel data", 3 * n)
            } else {
                e.to_string()
            }
        })?;
    Ok(Image {
        width: w,
        height: ht,
        color: ColorKind::Rgb,
        planes: planes.into_iter().map(Samples::U8).collect(),
        encoding: Encoding::Srgb,
        dpi: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_like_the_image_crate() {
        let (w, h) = (1031usize, 1100usize); // over MIN_PIXELS, rows not a power of two
        let mut bytes = format!("P6\n# comment\n{w} {h}\n255\n").into_bytes();
        let px: Vec<u8> = (0..3 * w * h).map(|i| (i * 31 % 251) as u8).collect();
        bytes.extend_from_slice(&px);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.ppm");
        std::fs::write(&path, &bytes).unwrap();
        let hd = header(&bytes[..64]).unwrap();
        let img = read(&File::open(&path).unwrap(), &hd).unwrap();
        let want = Image::rgb8(w, h, &px);
        assert_eq!(img.planes, want.planes);
        assert_eq!((img.width, img.height, img.color), (w, h, ColorKind::Rgb));
        // One byte short: the one-line "truncated" message.
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        let e = read(&File::open(&path).unwrap(), &hd).unwrap_err();
        assert!(e.starts_with("truncated"), "{e}");
        // Small files and other maxvals are left to the image crate.
        assert!(header(b"P6 10 10 255\n").is_none());
        assert!(header(format!("P6 {w} {h} 65535\n").as_bytes()).is_none());
        assert!(header(b"P5 2000 2000 255\n").is_none());
    }
}
