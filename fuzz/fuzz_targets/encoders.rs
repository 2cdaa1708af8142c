//! Every output format: a small halftone built from the input (size, channels, levels,
//! palette, options and pixels), encoded whole and in bands of a second size. The bytes
//! must not depend on the banding; a bilevel grey page must come back bit for bit through
//! the read path (PBM, PNG, TIFF in every compression, BMP) or the reference decoders
//! (PCL, ESC/POS, ZPL in both encodings); anything refused must be refused by `check`
//! before a byte is written, never by a panic.
#![no_main]

use halftone::io::lang::{self, escpos, pcl, zpl};
use halftone::io::lang::{PrintOptions, ZplEncoding};
use halftone::io::sink::{encode_halftone, Band, PageHeader};
use halftone::io::{encode, page_encoder, Compression, Format, ReadOptions, WriteOptions};
use halftone::raster::Halftone;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

const FORMATS: [Format; 11] = [
    Format::Pbm,
    Format::Pgm,
    Format::Ppm,
    Format::Png,
    Format::Tiff,
    Format::Bmp,
    Format::Pdf,
    Format::Ps,
    Format::Pcl,
    Format::EscPos,
    Format::Zpl,
];

fuzz_target!(|data: &[u8]| {
    if data.len() < 8 {
        return;
    }
    let (head, pixels) = data.split_at(8);
    let format = FORMATS[head[0] as usize % FORMATS.len()];
    let width = 1 + head[1] as usize % 80;
    let height = 1 + head[2] as usize % 80;
    let channels = [1, 1, 3, 4][head[3] as usize % 4];
    let levels = [2u16, 2, 3, 4, 16, 256][head[4] as usize % 6];
    let band = 1 + head[5] as usize % height;
    let flags = head[6];
    let mut h = Halftone::new(width, height, channels, levels);
    if flags & 1 != 0 && channels == 1 && levels <= 16 {
        // An indexed palette of as many colours as levels.
        h.palette = Some(
            (0..levels as usize)
                .map(|i| [(i * 37) as u8, (i * 91) as u8, (i * 13) as u8])
                .collect(),
        );
    }
    let mut k = 0;
    for c in 0..channels {
        for y in 0..height {
            for x in 0..width {
                let v = pixels.get(k).copied().unwrap_or((x ^ y) as u8);
                k += 1;
                h.set(c, x, y, (v as u16 % levels) as u8);
            }
        }
    }
    let mut opts = WriteOptions::new(format);
    opts.dpi = [None, Some(300.0), Some(203.0), Some(600.0)][(flags >> 1) as usize % 4];
    opts.compression = [
        None,
        Some(Compression::G4),
        Some(Compression::Deflate),
        Some(Compression::Lzw),
        Some(Compression::PackBits),
        Some(Compression::None),
    ][head[7] as usize % 6];
    opts.device_levels = flags & 8 != 0;
    opts.print = PrintOptions {
        band_rows: 1 + head[5] as usize % 960,
        cut: flags & 16 != 0,
        zpl_encoding: if flags & 32 != 0 {
            ZplEncoding::Z64
        } else {
            ZplEncoding::Hex
        },
        ..PrintOptions::default()
    };
    let name = Path::new("fuzz.out");
    let mut whole = Vec::new();
    if encode(&h, &opts, name, &mut whole).is_err() {
        // Refused up front: nothing written.
        assert!(whole.is_empty(), "{format:?} wrote bytes before refusing");
        return;
    }
    // The same page in bands of `band` rows.
    let mut enc = page_encoder(&opts);
    let mut banded = Vec::new();
    enc.begin_page(&PageHeader::of(&h, opts.dpi), &mut banded)
        .unwrap();
    let mut y = 0;
    while y < height {
        let rows = band.min(height - y);
        let planes: Vec<&[u8]> = h
            .planes
            .iter()
            .map(|p| &p[y * h.stride..(y + rows) * h.stride])
            .collect();
        enc.write_rows(&Band { y, rows, planes: &planes }, &mut banded)
            .unwrap();
        y += rows;
    }
    enc.end_page(&mut banded).unwrap();
    enc.finish(&mut banded).unwrap();
    assert!(banded == whole, "{format:?} differs in bands of {band}");
    // A second whole encode through the same helper as the CLI's gives the same bytes.
    let mut again = Vec::new();
    let mut enc = page_encoder(&opts);
    encode_halftone(enc.as_mut(), &h, opts.dpi, &mut again).unwrap();
    enc.finish(&mut again).unwrap();
    assert!(again == whole);

    if channels != 1 || levels != 2 || h.palette.is_some() {
        return;
    }
    // Bilevel grey: the page comes back bit for bit.
    let ink = |x: usize, y: usize| h.get(0, x, y) == 0;
    // Decoded dots (outside the decoded bitmap, none: a blank receipt is only feeds).
    let same = |b: &lang::Bitmap, what: &str| {
        assert!(b.height >= height, "{what}: {}x{}", b.width, b.height);
        for y in 0..height {
            for x in 0..width {
                let dot = x < b.width && b.get(x, y);
                assert_eq!(dot, ink(x, y), "{what} at ({x}, {y})");
            }
        }
    };
    match format {
        Format::Pcl => {
            let r = pcl::decode(&whole).expect("PCL decodes");
            assert_eq!(r.len(), 1);
            same(&r[0].bitmap(width), "PCL");
        }
        Format::EscPos => {
            let r = escpos::decode(&whole).expect("ESC/POS decodes");
            assert_eq!(r.bitmap.height, height);
            assert_eq!(r.cut, opts.print.cut);
            same(&r.bitmap, "ESC/POS");
        }
        Format::Zpl => {
            let labels = zpl::decode(&whole).expect("ZPL decodes");
            assert_eq!(labels.len(), 1);
            assert_eq!((labels[0].width, labels[0].height), (width, height));
            same(&labels[0], "ZPL");
        }
        Format::Pbm | Format::Png | Format::Tiff | Format::Bmp | Format::Pgm | Format::Ppm => {
            let img = halftone::io::read_image_bytes(
                &whole,
                Path::new("fuzz.out"),
                &ReadOptions::default(),
            )
            .expect("our own output reads back");
            assert_eq!((img.width, img.height), (width, height));
            // Grey or (BMP's palette) RGB: black and white have equal channels.
            let plane = match &img.planes[0] {
                halftone::raster::Samples::U8(v) => v.clone(),
                halftone::raster::Samples::U16(v) => v.iter().map(|&s| (s >> 8) as u8).collect(),
            };
            for y in 0..height {
                for x in 0..width {
                    let v = plane[y * width + x];
                    assert!(v == 0 || v == 255, "{format:?}: sample {v}");
                    assert_eq!(v == 0, ink(x, y), "{format:?} at ({x}, {y})");
                }
            }
        }
        Format::Pdf | Format::Ps => {}
    }
});
