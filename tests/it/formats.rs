//! Every output format read back bit-exact by real decoders (image, png, tiff, fax, and
//! libtiff's tiffcp when installed), resolution carried, and the reader's promises: depth
//! kept, alpha composited in linear light, EXIF orientation, the P5/P4 fast path equal to
//! image's own PNM decoder.

use std::io::Cursor;
use std::path::Path;

use halftone::io::{
    encode, read_image, read_image_bytes, Compression, Format, ReadOptions, WriteOptions,
};
use halftone::raster::{ColorKind, Halftone, Samples};
use halftone::tone::{linear_to_srgb, Encoding};

/// Widths and heights that exercise row padding at every bit depth.
const SIZES: [(usize, usize); 5] = [(1, 1), (7, 3), (9, 2), (33, 5), (64, 4)];

/// A deterministic pseudo-random halftone (xorshift), every level present in big ones.
fn random_halftone(w: usize, h: usize, channels: usize, levels: u16, seed: u64) -> Halftone {
    let mut ht = Halftone::new(w, h, channels, levels);
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    for c in 0..channels {
        for y in 0..h {
            for x in 0..w {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                ht.set(c, x, y, (s % levels as u64) as u8);
            }
        }
    }
    ht
}

/// A palette halftone of `n` colours.
fn palette_halftone(w: usize, h: usize, n: u16, seed: u64) -> Halftone {
    let mut ht = random_halftone(w, h, 1, n, seed);
    ht.palette = Some(
        (0..n as usize)
            .map(|i| [(i * 37) as u8, (255 - i * 5) as u8, (i * 91 % 256) as u8])
            .collect(),
    );
    ht
}

fn encode_to_vec(h: &Halftone, opts: &WriteOptions) -> Vec<u8> {
    let mut out = Vec::new();
    encode(h, opts, Path::new("test.out"), &mut out).expect("encode");
    out
}

fn opts(format: Format) -> WriteOptions {
    WriteOptions::new(format)
}

/// The 8-bit sRGB code of level k of L (what grey/RGB 8-bit outputs hold).
fn srgb_code(k: u8, levels: u16) -> u8 {
    (linear_to_srgb(k as f64 / (levels - 1) as f64) * 255.0).round() as u8
}

/// Maps decoded 8-bit codes back to levels through the code table; fails on a code that is
/// no level's.
fn codes_to_levels(codes: &[u8], levels: u16) -> Vec<u8> {
    let table: Vec<u8> = (0..levels).map(|k| srgb_code(k as u8, levels)).collect();
    codes
        .iter()
        .map(|c| {
            table
                .iter()
                .position(|t| t == c)
                .unwrap_or_else(|| panic!("code {c} is no level of {levels}")) as u8
        })
        .collect()
}

/// Every level of plane c of h, row-major.
fn levels(h: &Halftone, c: usize) -> Vec<u8> {
    h.levels_of(c)
}

/// Interleaved levels of an RGB halftone.
fn interleaved(h: &Halftone) -> Vec<u8> {
    let planes: Vec<Vec<u8>> = (0..h.channels()).map(|c| levels(h, c)).collect();
    (0..h.width * h.height)
        .flat_map(|i| planes.iter().map(move |p| p[i]))
        .collect()
}

#[test]
fn pbm_round_trip_through_image() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        let h = random_halftone(w, hh, 1, 2, i as u64);
        let bytes = encode_to_vec(&h, &opts(Format::Pbm));
        assert!(bytes.starts_with(format!("P4\n{w} {hh}\n").as_bytes()));
        let img = image::load_from_memory(&bytes).unwrap().to_luma8();
        // PBM 1 = black: image shows black as 0, i.e. level 0.
        let back: Vec<u8> = img.as_raw().iter().map(|&v| (v == 255) as u8).collect();
        assert_eq!(back, levels(&h, 0), "{w}x{hh}");
        // Our own fast reader agrees.
        let ours = read_image_bytes(&bytes, Path::new("t.pbm"), &ReadOptions::default()).unwrap();
        assert_eq!(ours.planes[0], Samples::U8(img.into_raw()));
    }
}

#[test]
fn pbm_refuses_grey_levels_and_colour() {
    let h = random_halftone(4, 4, 1, 4, 1);
    let e = encode(&h, &opts(Format::Pbm), Path::new("x.pbm"), &mut Vec::new())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("x.pbm: ") && e.contains("PGM"), "{e}");
    let rgb = random_halftone(4, 4, 3, 2, 1);
    assert!(encode(
        &rgb,
        &opts(Format::Pbm),
        Path::new("x.pbm"),
        &mut Vec::new()
    )
    .is_err());
    assert!(encode(
        &rgb,
        &opts(Format::Pgm),
        Path::new("x.pgm"),
        &mut Vec::new()
    )
    .is_err());
}

#[test]
fn pgm_holds_levels_or_encoded_maxval() {
    for &(w, hh) in &SIZES {
        let h = random_halftone(w, hh, 1, 5, 7);
        // Device levels: maxval = L − 1, value = level.
        let device = WriteOptions {
            device_levels: true,
            ..opts(Format::Pgm)
        };
        let bytes = encode_to_vec(&h, &device);
        assert!(bytes.starts_with(format!("P5\n{w} {hh}\n4\n").as_bytes()));
        let data = &bytes[bytes.len() - w * hh..];
        assert_eq!(data, levels(&h, 0).as_slice());
        // Default: display codes, the same as maxval 255 (sRGB codes of the reflectance).
        let bytes = encode_to_vec(&h, &opts(Format::Pgm));
        assert!(bytes.starts_with(format!("P5\n{w} {hh}\n255\n").as_bytes()));
        let want: Vec<u8> = levels(&h, 0).iter().map(|&k| srgb_code(k, 5)).collect();
        assert_eq!(&bytes[bytes.len() - w * hh..], want.as_slice());
        // maxval 255 with sRGB display: sRGB codes of the reflectance.
        let o = WriteOptions {
            maxval: Some(255),
            ..opts(Format::Pgm)
        };
        let bytes = encode_to_vec(&h, &o);
        let img = image::load_from_memory(&bytes).unwrap().to_luma8();
        assert_eq!(codes_to_levels(img.as_raw(), 5), levels(&h, 0));
        // maxval 1000, linear display: evenly spaced 16-bit big-endian values.
        let o = WriteOptions {
            maxval: Some(1000),
            display: Encoding::Linear,
            ..opts(Format::Pgm)
        };
        let bytes = encode_to_vec(&h, &o);
        let data = &bytes[bytes.len() - 2 * w * hh..];
        let vals: Vec<u16> = data
            .chunks_exact(2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
            .collect();
        let want: Vec<u16> = levels(&h, 0).iter().map(|&k| k as u16 * 250).collect();
        assert_eq!(vals, want);
    }
    // A maxval below the levels would merge levels.
    let h = random_halftone(3, 3, 1, 16, 1);
    let o = WriteOptions {
        maxval: Some(7),
        ..opts(Format::Pgm)
    };
    assert!(encode(&h, &o, Path::new("x.pgm"), &mut Vec::new()).is_err());
}

#[test]
fn ppm_replicates_grey_and_carries_rgb_and_palette() {
    for &(w, hh) in &SIZES {
        let g = random_halftone(w, hh, 1, 2, 3);
        let img = image::load_from_memory(&encode_to_vec(&g, &opts(Format::Ppm)))
            .unwrap()
            .to_rgb8();
        let want: Vec<u8> = levels(&g, 0).iter().flat_map(|&k| [k * 255; 3]).collect();
        assert_eq!(img.as_raw(), &want);

        let rgb = random_halftone(w, hh, 3, 4, 5);
        let device = WriteOptions {
            device_levels: true,
            ..opts(Format::Ppm)
        };
        let bytes = encode_to_vec(&rgb, &device);
        assert!(bytes.starts_with(format!("P6\n{w} {hh}\n3\n").as_bytes()));
        assert_eq!(
            &bytes[bytes.len() - 3 * w * hh..],
            interleaved(&rgb).as_slice()
        );

        let p = palette_halftone(w, hh, 6, 9);
        let img = image::load_from_memory(&encode_to_vec(&p, &opts(Format::Ppm)))
            .unwrap()
            .to_rgb8();
        let pal = p.palette.clone().unwrap();
        let want: Vec<u8> = levels(&p, 0)
            .iter()
            .flat_map(|&k| pal[k as usize])
            .collect();
        assert_eq!(img.as_raw(), &want);
    }
}

#[test]
fn png_grey_depths_round_trip() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        for &(levels_n, depth, scale) in &[(2u16, 1u8, 255u8), (4, 2, 85), (16, 4, 17)] {
            let h = random_halftone(w, hh, 1, levels_n, i as u64 + levels_n as u64);
            let device = WriteOptions {
                device_levels: true,
                ..opts(Format::Png)
            };
            let bytes = encode_to_vec(&h, &device);
            // The png crate sees the packed depth and the levels themselves.
            let mut dec = png::Decoder::new(Cursor::new(&bytes));
            dec.set_transformations(png::Transformations::IDENTITY);
            let mut r = dec.read_info().unwrap();
            let info = r.info();
            assert_eq!(info.bit_depth as u8, depth);
            assert_eq!(info.color_type, png::ColorType::Grayscale);
            if depth > 1 {
                // Levels are evenly spaced in light: gamma 1.
                assert_eq!(info.gamma(), Some(png::ScaledFloat::new(1.0)));
            }
            let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
            r.next_frame(&mut buf).unwrap();
            assert_eq!(buf, h.planes[0], "{w}x{hh} L{levels_n}");
            // image expands to 8 bits: level × scale.
            let img = image::load_from_memory(&bytes).unwrap().to_luma8();
            let back: Vec<u8> = img.as_raw().iter().map(|&v| v / scale).collect();
            assert_eq!(back, levels(&h, 0));
            if depth > 1 {
                // Default: the same packed samples as palette indices, each entry the
                // level's sRGB grey, so plain viewers show the right tone.
                let bytes = encode_to_vec(&h, &opts(Format::Png));
                let mut dec = png::Decoder::new(Cursor::new(&bytes));
                dec.set_transformations(png::Transformations::IDENTITY);
                let mut r = dec.read_info().unwrap();
                assert_eq!(r.info().color_type, png::ColorType::Indexed);
                assert_eq!(r.info().bit_depth as u8, depth);
                let pal: Vec<u8> = (0..levels_n as u8)
                    .flat_map(|k| [srgb_code(k, levels_n); 3])
                    .collect();
                assert_eq!(r.info().palette.as_deref(), Some(pal.as_slice()));
                let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
                r.next_frame(&mut buf).unwrap();
                assert_eq!(buf, h.planes[0], "{w}x{hh} L{levels_n}");
                let img = image::load_from_memory(&bytes).unwrap().to_luma8();
                let want: Vec<u8> = levels(&h, 0)
                    .iter()
                    .map(|&k| srgb_code(k, levels_n))
                    .collect();
                assert_eq!(img.as_raw(), &want);
            }
        }
        // 17 levels: 8-bit sRGB codes.
        let h = random_halftone(w, hh, 1, 17, i as u64);
        let img = image::load_from_memory(&encode_to_vec(&h, &opts(Format::Png))).unwrap();
        assert!(matches!(img, image::DynamicImage::ImageLuma8(_)));
        assert_eq!(codes_to_levels(img.to_luma8().as_raw(), 17), levels(&h, 0));
    }
}

#[test]
fn png_rgb_and_palette_round_trip() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        let h = random_halftone(w, hh, 3, 2, i as u64);
        let img = image::load_from_memory(&encode_to_vec(&h, &opts(Format::Png))).unwrap();
        assert!(matches!(img, image::DynamicImage::ImageRgb8(_)));
        assert_eq!(
            codes_to_levels(img.to_rgb8().as_raw(), 2),
            interleaved(&h),
            "{w}x{hh}"
        );

        for n in [2u16, 4, 16, 40] {
            let p = palette_halftone(w, hh, n, i as u64);
            let bytes = encode_to_vec(&p, &opts(Format::Png));
            let mut dec = png::Decoder::new(Cursor::new(&bytes));
            dec.set_transformations(png::Transformations::IDENTITY);
            let mut r = dec.read_info().unwrap();
            assert_eq!(r.info().color_type, png::ColorType::Indexed);
            assert_eq!(r.info().bit_depth as u8, p.bits);
            let pal = p.palette.clone().unwrap();
            let flat: Vec<u8> = pal.iter().flatten().copied().collect();
            assert_eq!(r.info().palette.as_deref(), Some(flat.as_slice()));
            let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
            r.next_frame(&mut buf).unwrap();
            assert_eq!(buf, p.planes[0]);
            let img = image::load_from_memory(&bytes).unwrap().to_rgb8();
            let want: Vec<u8> = levels(&p, 0)
                .iter()
                .flat_map(|&k| pal[k as usize])
                .collect();
            assert_eq!(img.as_raw(), &want);
        }
    }
}

/// The concatenated `IDAT` data of a PNG.
fn idat(png: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut i = 8;
    while i + 8 <= png.len() {
        let n = u32::from_be_bytes(png[i..i + 4].try_into().unwrap()) as usize;
        if &png[i + 4..i + 8] == b"IDAT" {
            out.extend_from_slice(&png[i + 8..i + 8 + n]);
        }
        i += 12 + n;
    }
    out
}

/// The filter type of each row of a PNG (no interlace).
fn row_filters(png: &[u8]) -> Vec<u8> {
    let mut dec = png::Decoder::new(Cursor::new(png));
    dec.set_transformations(png::Transformations::IDENTITY);
    let r = dec.read_info().unwrap();
    let (stride, rows) = (r.info().raw_row_length(), r.info().height as usize);
    let mut raw = Vec::new();
    std::io::Read::read_to_end(
        &mut flate2::read::ZlibDecoder::new(&idat(png)[..]),
        &mut raw,
    )
    .unwrap();
    assert_eq!(raw.len(), stride * rows);
    raw.chunks(stride).map(|row| row[0]).collect()
}

/// Filter None for indexed colour and samples below 8 bits (the PNG spec's advice), the png
/// crate's adaptive choice for 8-bit grey and RGB and for 256 grey levels as indices; either
/// way the compressed stream is the png crate's own for the same rows and filter.
#[test]
fn png_filters_none_below_8_bits_and_for_palettes_adaptive_otherwise() {
    let (w, hh) = (67, 23);
    use png::{BitDepth::*, ColorType::*};
    // Name, channels, levels (or palette colours with `P`), --device-levels, PNG kind,
    // adaptive filtering.
    const P: bool = true;
    let cases = [
        ("grey 1", 1, 2, !P, false, (Grayscale, One), false),
        ("grey 2", 1, 4, !P, true, (Grayscale, Two), false),
        ("indexed grey 2", 1, 4, !P, false, (Indexed, Two), false),
        ("palette 4", 1, 8, P, false, (Indexed, Four), false),
        ("palette 8", 1, 40, P, false, (Indexed, Eight), false),
        ("indexed grey 8", 1, 256, !P, false, (Indexed, Eight), true),
        ("grey 8", 1, 256, !P, true, (Grayscale, Eight), true),
        ("grey codes 8", 1, 3, !P, false, (Grayscale, Eight), true),
        ("RGB 8", 3, 2, !P, false, (Rgb, Eight), true),
    ];
    for (seed, (what, channels, n, pal, device_levels, kind, adaptive)) in
        cases.into_iter().enumerate()
    {
        let h = if pal {
            palette_halftone(w, hh, n, seed as u64)
        } else {
            random_halftone(w, hh, channels, n, seed as u64)
        };
        let o = WriteOptions {
            device_levels,
            ..opts(Format::Png)
        };
        let bytes = encode_to_vec(&h, &o);
        let filters = row_filters(&bytes);
        if adaptive {
            assert!(filters.iter().any(|&f| f != 0), "{what}: {filters:?}");
        } else {
            assert!(filters.iter().all(|&f| f == 0), "{what}: {filters:?}");
        }
        // The same rows through the png crate with that filter give the same IDAT data.
        let mut dec = png::Decoder::new(Cursor::new(&bytes));
        dec.set_transformations(png::Transformations::IDENTITY);
        let mut r = dec.read_info().unwrap();
        let mut rows = vec![0u8; r.output_buffer_size().unwrap()];
        r.next_frame(&mut rows).unwrap();
        let info = r.info();
        assert_eq!((info.color_type, info.bit_depth), kind, "{what}");
        let mut again = Vec::new();
        let mut e = png::Encoder::new(&mut again, info.width, info.height);
        e.set_color(info.color_type);
        e.set_depth(info.bit_depth);
        if let Some(pal) = &info.palette {
            e.set_palette(pal.to_vec());
        }
        e.set_filter(if adaptive {
            png::Filter::Adaptive
        } else {
            png::Filter::NoFilter
        });
        let mut wr = e.write_header().unwrap();
        wr.write_image_data(&rows).unwrap();
        wr.finish().unwrap();
        assert!(
            idat(&bytes) == idat(&again),
            "{what}: not the png crate's stream"
        );
    }
}

fn tiff_opts(c: Compression) -> WriteOptions {
    WriteOptions {
        compression: Some(c),
        ..opts(Format::Tiff)
    }
}

#[test]
fn tiff_bilevel_round_trips_every_compression() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        let h = random_halftone(w, hh, 1, 2, i as u64 + 100);
        for c in [
            Compression::None,
            Compression::PackBits,
            Compression::Lzw,
            Compression::Deflate,
        ] {
            let bytes = encode_to_vec(&h, &tiff_opts(c));
            let img = image::load_from_memory(&bytes)
                .unwrap_or_else(|e| panic!("{c:?} {w}x{hh}: {e}"))
                .to_luma8();
            let back: Vec<u8> = img.as_raw().iter().map(|&v| (v > 127) as u8).collect();
            assert_eq!(back, levels(&h, 0), "{c:?} {w}x{hh}");
        }
    }
}

#[test]
fn tiff_grey_and_rgb_round_trip() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        let g = random_halftone(w, hh, 1, 4, i as u64);
        for c in [
            Compression::Deflate,
            Compression::Lzw,
            Compression::PackBits,
        ] {
            let img = image::load_from_memory(&encode_to_vec(&g, &tiff_opts(c))).unwrap();
            assert_eq!(codes_to_levels(img.to_luma8().as_raw(), 4), levels(&g, 0));
        }
        let rgb = random_halftone(w, hh, 3, 2, i as u64);
        let img = image::load_from_memory(&encode_to_vec(&rgb, &opts(Format::Tiff))).unwrap();
        assert_eq!(
            codes_to_levels(img.to_rgb8().as_raw(), 2),
            interleaved(&rgb)
        );
    }
}

/// The strip of a single-strip TIFF, with its width and height, via the tiff crate.
fn tiff_strip(bytes: &[u8]) -> (Vec<u8>, u32, u32, u16) {
    use tiff::tags::Tag;
    let mut d = tiff::decoder::Decoder::new(Cursor::new(bytes)).unwrap();
    let (w, h) = d.dimensions().unwrap();
    let off = d.get_tag_u32_vec(Tag::StripOffsets).unwrap();
    let len = d.get_tag_u32_vec(Tag::StripByteCounts).unwrap();
    assert_eq!(off.len(), 1, "Group 4 is written as one strip");
    let photometric = d.get_tag_u32(Tag::PhotometricInterpretation).unwrap() as u16;
    let s = off[0] as usize;
    (bytes[s..s + len[0] as usize].to_vec(), w, h, photometric)
}

#[test]
fn tiff_g4_decodes_with_fax() {
    for (i, &(w, hh)) in SIZES.iter().chain(&[(1728, 40), (100, 1)]).enumerate() {
        let h = random_halftone(w, hh, 1, 2, i as u64 + 7);
        let bytes = encode_to_vec(&h, &tiff_opts(Compression::G4));
        let (strip, tw, th, photometric) = tiff_strip(&bytes);
        assert_eq!((tw as usize, th as usize), (w, hh));
        assert_eq!(photometric, 0, "WhiteIsZero");
        let mut rows = Vec::new();
        fax::decoder::decode_g4(strip.iter().copied(), tw, Some(th), |line| {
            rows.extend(fax::decoder::pels(line, tw).map(|c| (c == fax::Color::White) as u8));
        })
        .expect("fax decodes our Group 4");
        assert_eq!(rows, levels(&h, 0), "{w}x{hh}");
    }
}

#[test]
fn tiff_g4_through_libtiff() {
    let check = "formats::tiff_g4_through_libtiff";
    let tiffcp = crate::common::have_tool("tiffcp", "libtiff-tools", check);
    if !(tiffcp & crate::common::have_tool("tiffinfo", "libtiff-tools", check)) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (i, &(w, hh)) in SIZES.iter().chain(&[(1728, 40)]).enumerate() {
        let h = random_halftone(w, hh, 1, 2, i as u64 + 11);
        let o = WriteOptions {
            dpi: Some(204.0),
            ..tiff_opts(Compression::G4)
        };
        let g4 = dir.path().join("g4.tif");
        let raw = dir.path().join("raw.tif");
        std::fs::write(&g4, encode_to_vec(&h, &o)).unwrap();
        let st = std::process::Command::new("tiffcp")
            .args(["-c", "none"])
            .arg(&g4)
            .arg(&raw)
            .output()
            .unwrap();
        assert!(
            st.status.success() && st.stderr.is_empty(),
            "tiffcp: {}",
            String::from_utf8_lossy(&st.stderr)
        );
        let img = image::open(&raw).unwrap().to_luma8();
        let back: Vec<u8> = img.as_raw().iter().map(|&v| (v > 127) as u8).collect();
        assert_eq!(back, levels(&h, 0), "{w}x{hh}");
        let info = std::process::Command::new("tiffinfo")
            .arg(&g4)
            .output()
            .unwrap();
        assert!(info.status.success(), "tiffinfo {w}x{hh}");
        let text = String::from_utf8_lossy(&info.stdout);
        assert!(text.contains("CCITT Group 4"), "{text}");
        assert!(text.contains("Resolution: 204, 204 pixels/inch"), "{text}");
        assert!(text.contains("min-is-white"), "{text}");
    }
}

#[test]
fn bmp_round_trips() {
    for (i, &(w, hh)) in SIZES.iter().enumerate() {
        let b = random_halftone(w, hh, 1, 2, i as u64);
        let bytes = encode_to_vec(&b, &opts(Format::Bmp));
        assert_eq!(
            u16::from_le_bytes([bytes[28], bytes[29]]),
            1,
            "1 bit a pixel"
        );
        let img = image::load_from_memory(&bytes).unwrap().to_luma8();
        let back: Vec<u8> = img.as_raw().iter().map(|&v| (v == 255) as u8).collect();
        assert_eq!(back, levels(&b, 0), "{w}x{hh}");

        let g = random_halftone(w, hh, 1, 5, i as u64);
        let bytes = encode_to_vec(&g, &opts(Format::Bmp));
        assert_eq!(u16::from_le_bytes([bytes[28], bytes[29]]), 8);
        let img = image::load_from_memory(&bytes).unwrap().to_luma8();
        assert_eq!(codes_to_levels(img.as_raw(), 5), levels(&g, 0));

        let rgb = random_halftone(w, hh, 3, 2, i as u64);
        let bytes = encode_to_vec(&rgb, &opts(Format::Bmp));
        assert_eq!(u16::from_le_bytes([bytes[28], bytes[29]]), 24);
        let img = image::load_from_memory(&bytes).unwrap().to_rgb8();
        assert_eq!(codes_to_levels(img.as_raw(), 2), interleaved(&rgb));

        let p = palette_halftone(w, hh, 7, i as u64);
        let img = image::load_from_memory(&encode_to_vec(&p, &opts(Format::Bmp)))
            .unwrap()
            .to_rgb8();
        let pal = p.palette.clone().unwrap();
        let want: Vec<u8> = levels(&p, 0)
            .iter()
            .flat_map(|&k| pal[k as usize])
            .collect();
        assert_eq!(img.as_raw(), &want);
    }
}

#[test]
fn dpi_is_recorded_everywhere() {
    let h = random_halftone(9, 3, 1, 2, 1);
    let with = |f| WriteOptions {
        dpi: Some(300.0),
        ..opts(f)
    };
    // PNG pHYs: 300 dpi = 11811 pixels per metre.
    let png = encode_to_vec(&h, &with(Format::Png));
    let r = png::Decoder::new(Cursor::new(&png)).read_info().unwrap();
    let dims = r.info().pixel_dims.unwrap();
    assert_eq!((dims.xppu, dims.yppu), (11811, 11811));
    assert_eq!(dims.unit, png::Unit::Meter);
    // TIFF tags.
    for c in [Compression::G4, Compression::Deflate] {
        let tif = encode_to_vec(
            &h,
            &WriteOptions {
                compression: Some(c),
                ..with(Format::Tiff)
            },
        );
        let mut d = tiff::decoder::Decoder::new(Cursor::new(&tif)).unwrap();
        use tiff::decoder::ifd::Value;
        use tiff::tags::Tag;
        let x = d.find_tag(Tag::XResolution).unwrap().unwrap();
        let y = d.find_tag(Tag::YResolution).unwrap().unwrap();
        assert!(matches!(x, Value::Rational(300, 1)), "{x:?}");
        assert!(matches!(y, Value::Rational(300, 1)), "{y:?}");
        assert_eq!(d.get_tag_u32(Tag::ResolutionUnit).unwrap(), 2, "inch");
    }
    // BMP header: pixels per metre at offsets 38 and 42.
    let bmp = encode_to_vec(&h, &with(Format::Bmp));
    assert_eq!(i32::from_le_bytes(bmp[38..42].try_into().unwrap()), 11811);
    assert_eq!(i32::from_le_bytes(bmp[42..46].try_into().unwrap()), 11811);
    // And the reader brings it back.
    let tif = encode_to_vec(&h, &with(Format::Tiff));
    for bytes in [&png, &bmp, &tif] {
        let img = read_image_bytes(bytes, Path::new("t"), &ReadOptions::default()).unwrap();
        assert!((img.dpi.unwrap() - 300.0).abs() < 0.01, "{:?}", img.dpi);
    }
}

/// A PNG of 16-bit grey (optionally with alpha) through the png crate.
fn png16(w: u32, h: u32, color: png::ColorType, samples: &[u16]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, w, h);
    e.set_color(color);
    e.set_depth(png::BitDepth::Sixteen);
    let mut wr = e.write_header().unwrap();
    let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_be_bytes()).collect();
    wr.write_image_data(&bytes).unwrap();
    wr.finish().unwrap();
    out
}

#[test]
fn sixteen_bit_png_stays_sixteen_bit() {
    let vals = [0u16, 1, 257, 32768, 65534, 65535];
    let bytes = png16(3, 2, png::ColorType::Grayscale, &vals);
    let img = read_image_bytes(&bytes, Path::new("t.png"), &ReadOptions::default()).unwrap();
    assert_eq!(img.color, ColorKind::Gray);
    assert_eq!(img.planes, vec![Samples::U16(vals.to_vec())]);
}

#[test]
fn alpha_is_composited_over_white_in_linear_light() {
    // Black at 50% alpha over white: linear 0.5, sRGB code 188 (of 255).
    let bytes = png16(2, 1, png::ColorType::GrayscaleAlpha, &[0, 32768, 0, 0]);
    let img = read_image_bytes(&bytes, Path::new("t.png"), &ReadOptions::default()).unwrap();
    let Samples::U16(v) = &img.planes[0] else {
        panic!("16-bit alpha image must stay 16-bit")
    };
    assert_eq!(img.planes.len(), 1, "alpha dropped");
    assert_eq!((v[0] as f64 / 257.0).round(), 188.0);
    assert_eq!(v[1], 65535, "fully transparent is paper");
    // 8-bit RGBA: opaque pixels unchanged, transparent ones white, half-covered red lighter.
    let rgba = image::RgbaImage::from_raw(3, 1, vec![10, 20, 30, 255, 0, 0, 0, 0, 255, 0, 0, 128])
        .unwrap();
    let mut png8 = Vec::new();
    rgba.write_to(&mut Cursor::new(&mut png8), image::ImageFormat::Png)
        .unwrap();
    let img = read_image_bytes(&png8, Path::new("t.png"), &ReadOptions::default()).unwrap();
    assert_eq!(img.color, ColorKind::Rgb);
    let px = |i: usize| -> Vec<u8> {
        img.planes
            .iter()
            .map(|p| match p {
                Samples::U8(v) => v[i],
                _ => panic!("8-bit stays 8-bit"),
            })
            .collect()
    };
    assert_eq!(px(0), [10, 20, 30]);
    assert_eq!(px(1), [255, 255, 255]);
    // Red stays 255; green and blue: 128/255 coverage of 0 → reflectance 0.498 → 187.
    assert_eq!(px(2), [255, 187, 187]);
}

#[test]
fn exif_orientation_is_applied() {
    // 16×8: left half black, right half white; EXIF orientation 6 = rotate 90° clockwise,
    // so the picture becomes 8×16 with the black half on top.
    let (w, h) = (16u32, 8u32);
    let pixels: Vec<u8> = (0..w * h)
        .map(|i| if i % w < 8 { 0 } else { 255 })
        .collect();
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode(&pixels, w, h, image::ExtendedColorType::L8)
        .unwrap();
    let mut exif = b"Exif\0\0MM\0\x2a\0\0\0\x08".to_vec();
    exif.extend_from_slice(&[0, 1]); // one entry
    exif.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0]); // Orientation = 6
    exif.extend_from_slice(&[0, 0, 0, 0]); // no next IFD
    let mut app1 = vec![0xFF, 0xE1];
    app1.extend_from_slice(&((exif.len() + 2) as u16).to_be_bytes());
    app1.extend_from_slice(&exif);
    jpeg.splice(2..2, app1);
    let img = read_image_bytes(&jpeg, Path::new("t.jpg"), &ReadOptions::default()).unwrap();
    assert_eq!((img.width, img.height), (8, 16));
    let Samples::U8(v) = &img.planes[0] else {
        panic!()
    };
    assert!(v[2 * 8 + 4] < 40, "top is black: {}", v[2 * 8 + 4]);
    assert!(v[13 * 8 + 4] > 215, "bottom is white: {}", v[13 * 8 + 4]);
}

/// image's own PNM decoder, as planes.
fn image_pnm(bytes: &[u8]) -> Samples {
    match image::load_from_memory_with_format(bytes, image::ImageFormat::Pnm).unwrap() {
        image::DynamicImage::ImageLuma8(b) => Samples::U8(b.into_raw()),
        image::DynamicImage::ImageLuma16(b) => Samples::U16(b.into_raw()),
        other => panic!("unexpected {:?}", other.color()),
    }
}

#[test]
fn pnm_fast_path_equals_image_decoder() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (67usize, 71usize); // > 4096 bytes: the file path reads past its head
    for &maxval in &[255u32, 100, 1, 65535, 1000, 256] {
        let wide = maxval > 255;
        let mut bytes = format!("P5\n# a comment\n{w} {h}\n# another\n{maxval}\n").into_bytes();
        for i in 0..w * h {
            let v = (i as u64 * 7919 % (maxval as u64 + 1)) as u16;
            if wide {
                bytes.extend_from_slice(&v.to_be_bytes());
            } else {
                bytes.push(v as u8);
            }
        }
        let want = image_pnm(&bytes);
        let mem = read_image_bytes(&bytes, Path::new("t.pgm"), &ReadOptions::default()).unwrap();
        assert_eq!(mem.planes[0], want, "maxval {maxval} (memory)");
        let path = dir.path().join("t.pgm");
        std::fs::write(&path, &bytes).unwrap();
        let file = read_image(&path, &ReadOptions::default()).unwrap();
        assert_eq!(file.planes[0], want, "maxval {maxval} (file)");
        assert_eq!((file.width, file.height), (w, h));
        // One byte short: truncated, named.
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        let e = read_image(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.pgm") && e.contains("truncated"), "{e}");
    }
}

#[test]
fn pixel_limit_is_checked_from_the_header() {
    let o = ReadOptions { max_pixels: 100 };
    let pgm = b"P5\n11 10\n255\n";
    let e = read_image_bytes(pgm, Path::new("big.pgm"), &o)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("big.pgm: image is 11x10 = 110 pixels"), "{e}");
    let png = png16(20, 20, png::ColorType::Grayscale, &[0; 400]);
    let e = read_image_bytes(&png, Path::new("big.png"), &o)
        .unwrap_err()
        .to_string();
    assert!(e.contains("over the limit"), "{e}");
}

/// Large 8-bit greymaps are read by several threads at once; the codes are those of the
/// one-buffer decoder, maxval rescaling included, and a short file is still an error.
#[test]
fn large_greymap_reads_like_small() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (2500usize, 1700usize); // 4.25 MB: above the parallel-read size
    for maxval in [255u32, 200] {
        let mut bytes = format!("P5\n# comment\n{w} {h}\n{maxval}\n").into_bytes();
        bytes.extend((0..w * h).map(|i| ((i * 7 + i / w * 13) % (maxval as usize + 1)) as u8));
        let path = dir.path().join(format!("big-{maxval}.pgm"));
        std::fs::write(&path, &bytes).unwrap();
        let opts = ReadOptions::default();
        let from_file = read_image(&path, &opts).unwrap();
        let from_bytes = read_image_bytes(&bytes, &path, &opts).unwrap();
        assert_eq!((from_file.width, from_file.height), (w, h));
        match (&from_file.planes[..], &from_bytes.planes[..]) {
            ([Samples::U8(a)], [Samples::U8(b)]) => assert!(a == b, "maxval {maxval}"),
            _ => panic!("8-bit codes expected"),
        }
        // Cut one byte short: a clear error naming the file, no panic.
        let short = dir.path().join(format!("short-{maxval}.pgm"));
        std::fs::write(&short, &bytes[..bytes.len() - 1]).unwrap();
        let err = read_image(&short, &opts).unwrap_err().to_string();
        assert!(err.contains("short-") && err.contains("truncated"), "{err}");
    }
}
