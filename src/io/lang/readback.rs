//! Reading back what `convert` prints: the printer-language files (PDF, PostScript, PCL,
//! ESC/POS, ZPL) decoded into images, so that `compare` measures exactly the bits a printer
//! receives.
//!
//! Each language's reference decoder is in its own file beside its encoder (`decode` in
//! [`super::pcl`], [`super::escpos`], [`super::zpl`], [`super::pdf`], [`super::ps`]); this file
//! finds the language of a file from its first bytes and turns its pages into images.
//!
//! Every page comes back as 8-bit codes in the convention of the image files `convert`
//! writes: paper 255, ink 0, and a level between them as the sRGB code of its reflectance, so
//! a PDF and the PGM of the same halftone give the same figures.

use std::io::Read;
use std::path::Path;

use super::Language;
use crate::error::{Error, Result};
use crate::io::ReadOptions;
use crate::raster::Image;

/// Reads the printer-language file at `path` and returns its first page, or `None` when the
/// file is not in a printer language (then it is an ordinary image). A file of several
/// pages is refused: say which page by writing it alone.
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Option<Image>> {
    let io_err = |e| Error::io(path, e);
    let mut file = std::fs::File::open(path).map_err(io_err)?;
    let mut head = [0u8; 16];
    let n = read_up_to(&mut file, &mut head).map_err(io_err)?;
    let Some(lang) = Language::sniff(&head[..n]) else {
        return Ok(None);
    };
    let mut data = head[..n].to_vec();
    let cap = crate::io::max_input_bytes(opts);
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
    let mut pages = lang
        .pages(&data)
        .map_err(|e| err(format!("{}: {e}", lang.name())))?;
    for p in &pages {
        crate::io::check_pixels(path, p.width as u32, p.height as u32, opts)?;
    }
    match pages.len() {
        0 => Err(err(format!("{} file with no page", lang.name()))),
        1 => Ok(pages.pop()),
        n => Err(err(format!(
            "{} file of {n} pages; compare reads one page (write that page alone)",
            lang.name()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::lang::{escpos, pcl, pdf, ps, zpl};
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
                let lang =
                    Language::sniff(&data).unwrap_or_else(|| panic!("{format:?} not sniffed"));
                let mut pages = lang.pages(&data).unwrap();
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
        assert!(super::super::find(&data, b"/CCITTFaxDecode", 0).is_some());
        let img = pdf::decode(&data).unwrap().pop().unwrap();
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
            let img = Language::sniff(&data)
                .unwrap()
                .pages(&data)
                .unwrap()
                .pop()
                .unwrap();
            assert_eq!(codes(&img), want, "{format:?}");
        }
    }

    #[test]
    fn truncated_streams_are_errors_not_panics() {
        let pcl_stream = b"\x1b*r8S\x1b*r1A\x1b*b2m9W\x05ab";
        for n in 0..pcl_stream.len() {
            let _ = pcl::decode(&pcl_stream[..n]);
        }
        assert!(pcl::decode(pcl_stream).is_err());
        assert!(escpos::decode(b"\x1dv0\x00\x02\x00\x02\x00\xff").is_err());
        assert!(zpl::decode(b"^XA^PW8^LL1^GFA,1,1,1,FF^FS").is_err());
    }

    #[test]
    fn ascii85_and_run_length() {
        // "Man " is "9jqo^" (the classic example); a final group of two characters is one
        // byte.
        let (b, end) = ps::decode_ascii85(b"9jqo^z6W~>rest", 0).unwrap();
        assert_eq!(&b[..4], b"Man ");
        assert_eq!(&b[4..8], &[0; 4]);
        assert_eq!(b.len(), 8 + 1);
        assert_eq!(end, 10);
        assert!(ps::decode_ascii85(b"9jqo^", 0).is_err());
        assert_eq!(
            ps::decode_run_length(&[2, 1, 2, 3, 254, 9, 128], 100).unwrap(),
            vec![1, 2, 3, 9, 9, 9]
        );
        assert!(ps::decode_run_length(&[5, 1], 100).is_err());
    }

    #[test]
    fn broken_files_are_errors_not_panics() {
        let ht = pattern(30, 9);
        for format in [Format::Pdf, Format::Ps] {
            let data = encode(&ht, format, None);
            for cut in [10, data.len() / 3, data.len() / 2, data.len() - 20] {
                let _ = Language::sniff(&data).unwrap().pages(&data[..cut]);
            }
            let mut flipped = data.clone();
            for i in (0..flipped.len()).step_by(7) {
                flipped[i] ^= 0x55;
                let _ = Language::sniff(&data).unwrap().pages(&flipped);
            }
        }
        assert!(pdf::decode(b"%PDF-1.4\n").is_err());
        assert!(ps::decode(b"%!PS\n").is_err());
    }
}
