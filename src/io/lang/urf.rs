//! Apple raster (`image/urf`, "UNIRAST"): what AirPrint clients send. Reading only: the
//! file is `UNIRAST\0` and a big-endian page count (0 when the writer did not know it), then
//! for each page a 32-byte header and its lines in the same compression as PWG raster
//! ([`super::pwg`]). Memory is bounded as there.
//!
//! Page header bytes: 0 bits per pixel (8, 16, 24, 32, 48, 64), 1 colour space (0 sGray,
//! 1 sRGB, 2 CIE Lab, 3 Adobe RGB, 4 grey, 5 RGB, 6 CMYK), 2 duplex, 3 quality, 12–15 width,
//! 16–19 height, 20–23 resolution (dpi, both ways).

use std::path::Path;

use super::pwg::{decode_lines, PageHeader, Space};
use crate::error::Result;
use crate::io::{check_pixels, decode_err, ReadOptions};
use crate::raster::Image;

/// The file's first bytes.
pub const SYNC: &[u8; 8] = b"UNIRAST\0";
/// Bytes in a page header.
pub const HEADER_BYTES: usize = 32;

/// True when `data` starts like an Apple raster file.
pub fn is_urf(data: &[u8]) -> bool {
    data.starts_with(SYNC)
}

/// The pages of an Apple raster file, decoded one at a time (as [`super::pwg::Pages`]).
pub struct Pages<'a> {
    data: &'a [u8],
    pos: usize,
    name: &'a Path,
    opts: ReadOptions,
    /// Pages the file header announces (0: read to the end).
    count: u32,
    page: u32,
    done: bool,
}

/// Starts reading the Apple raster file in `data` (`name` is for error messages).
pub fn pages<'a>(data: &'a [u8], name: &'a Path, opts: &ReadOptions) -> Result<Pages<'a>> {
    if !is_urf(data) {
        return Err(decode_err(
            name,
            "not an Apple raster file (no UNIRAST signature)".into(),
        ));
    }
    let Some(count) = data.get(8..12) else {
        return Err(decode_err(
            name,
            "truncated: no page count after UNIRAST".into(),
        ));
    };
    Ok(Pages {
        data,
        pos: 12,
        name,
        opts: opts.clone(),
        count: u32::from_be_bytes([count[0], count[1], count[2], count[3]]),
        page: 0,
        done: false,
    })
}

impl Pages<'_> {
    /// Pages the file header announces (0 when the writer did not say).
    pub fn announced(&self) -> u32 {
        self.count
    }

    fn next_page(&mut self) -> Result<Image> {
        let page = self.page;
        let err = |msg: String| decode_err(self.name, format!("page {page}: {msg}"));
        let Some(b) = self.data.get(self.pos..self.pos + HEADER_BYTES) else {
            return Err(err(format!(
                "truncated: the page header needs {HEADER_BYTES} bytes, {} remain",
                self.data.len() - self.pos.min(self.data.len())
            )));
        };
        let be = |at: usize| u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let (space, channels) = match b[1] {
            0 | 4 => (Space::Gray, 1),
            1 | 3 | 5 => (Space::Rgb, 3),
            6 => (Space::Cmyk, 4),
            s => return Err(err(format!("colour space {s} is not supported"))),
        };
        let bits = u32::from(b[0]);
        if bits % (8 * channels) != 0 || !matches!(bits / channels, 8 | 16) {
            return Err(err(format!(
                "{bits} bits per pixel for {channels} channels (8 or 16 bits each)"
            )));
        }
        let dpi = be(20);
        let h = PageHeader {
            width: be(12),
            height: be(16),
            bits_per_color: bits / channels,
            space,
            dpi: (dpi, dpi),
        };
        h.check().map_err(err)?;
        check_pixels(self.name, h.width, h.height, &self.opts)?;
        self.pos += HEADER_BYTES;
        decode_lines(self.data, &mut self.pos, &h, true).map_err(err)
    }
}

impl Iterator for Pages<'_> {
    type Item = Result<Image>;

    fn next(&mut self) -> Option<Result<Image>> {
        let finished = if self.count > 0 {
            self.page >= self.count
        } else {
            self.page > 0 && self.pos >= self.data.len()
        };
        if self.done || finished {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Samples;

    fn file(count: u32, pages: &[(u8, u8, u32, u32, &[u8])]) -> Vec<u8> {
        let mut f = SYNC.to_vec();
        f.extend(count.to_be_bytes());
        for &(bits, space, w, h, lines) in pages {
            let mut hd = [0u8; HEADER_BYTES];
            hd[0] = bits;
            hd[1] = space;
            hd[12..16].copy_from_slice(&w.to_be_bytes());
            hd[16..20].copy_from_slice(&h.to_be_bytes());
            hd[20..24].copy_from_slice(&203u32.to_be_bytes());
            f.extend(hd);
            f.extend_from_slice(lines);
        }
        f
    }

    fn read(f: &[u8]) -> Result<Vec<Image>> {
        pages(f, Path::new("t.urf"), &ReadOptions::default())?.collect()
    }

    #[test]
    fn pages_counts_and_errors() {
        // sRGB 2x1: a literal pair of pixels; then a grey page: a run.
        let rgb: &[u8] = &[0, 0xff, 1, 2, 3, 4, 5, 6];
        let grey: &[u8] = &[0, 1, 200];
        let f = file(2, &[(24, 1, 2, 1, rgb), (8, 0, 2, 1, grey)]);
        let p = read(&f).unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].planes.len(), 3);
        assert!(matches!(&p[0].planes[1], Samples::U8(v) if v == &[2, 5]));
        assert!(matches!(&p[1].planes[0], Samples::U8(v) if v == &[200, 200]));
        assert_eq!(p[1].dpi, Some(203.0));
        // Count 0: read to the end.
        assert_eq!(read(&file(0, &[(8, 0, 2, 1, grey)])).unwrap().len(), 1);
        // A count larger than the pages held: a truncation error.
        let e = read(&file(3, &[(8, 0, 2, 1, grey)]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.urf") && e.contains("page 2: truncated"),
            "{e}"
        );
        // 1-bit and odd depths are not Apple raster.
        let e = read(&file(1, &[(1, 0, 8, 1, &[0, 0, 0])]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 bits per pixel"), "{e}");
        let e = read(&file(1, &[(8, 9, 8, 1, &[])]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("colour space 9"), "{e}");
        // No panics on any truncation or on random bytes.
        for n in 0..f.len() {
            let _ = read(&f[..n]);
            assert!(n >= 12 || read(&f[..n]).is_err());
        }
        let mut seed = 3u64;
        for _ in 0..3000 {
            let mut g = f.clone();
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let at = (seed >> 33) as usize % g.len();
            g[at] = (seed >> 20) as u8;
            let _ = read(&g);
        }
    }
}
