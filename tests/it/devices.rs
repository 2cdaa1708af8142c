//! E-paper devices: `--device` is `--palette` with the panel's colours plus its size and
//! ppi; every panel encoding decodes back (by a decoder written here from the documented
//! layout) to exactly the palette indices of the PNG of the same job; profile errors are
//! one line naming the file, line and field; the listing.

use std::io::Cursor;
use std::path::Path;

use halftone::panel::Device;
use halftone::{Format, Image, InkColours, Input, Options};

use crate::common::halftone as bin;

/// A photo-like colour image: smooth hue and lightness ramps, a dark and a light patch,
/// and deterministic grain (no flat areas, every ink gets used).
fn photo(w: usize, h: usize) -> Image {
    Image::rgb8(w, h, &photo_rgb(w, h))
}

/// [`photo`]'s interleaved RGB codes.
fn photo_rgb(w: usize, h: usize) -> Vec<u8> {
    let mut px = Vec::with_capacity(w * h * 3);
    let mut state = 0x2545_f491_u32;
    for y in 0..h {
        for x in 0..w {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = (state % 41) as f64 - 20.0;
            let hue = x as f64 / w as f64 * 6.0;
            let light = y as f64 / (h.max(2) - 1) as f64;
            let f = |k: f64| (((hue + k) % 6.0 - 3.0).abs() - 1.0).clamp(0.0, 1.0);
            let c = [f(0.0), f(4.0), f(2.0)].map(|c| {
                let v = if light < 0.5 {
                    c * light * 2.0
                } else {
                    c + (1.0 - c) * (light - 0.5) * 2.0
                };
                (v * 255.0 + noise).round().clamp(0.0, 255.0) as u8
            });
            px.extend(c);
        }
    }
    px
}

/// [`photo`] saved as `name` (PNG or JPEG by its extension) in `dir`.
fn photo_file(dir: &Path, name: &str, w: usize, h: usize) -> std::path::PathBuf {
    let path = dir.join(name);
    image::save_buffer(
        &path,
        &photo_rgb(w, h),
        w as u32,
        h as u32,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    path
}

fn device_opts(device: &str, w: usize, h: usize) -> Options {
    Options {
        device: Some(device.into()),
        width: Some(w),
        height: Some(h),
        ..Default::default()
    }
}

/// The palette indices and the PLTE colours of an indexed PNG.
fn png_indices(bytes: &[u8]) -> (usize, usize, Vec<u8>, Vec<[u8; 3]>) {
    let mut dec = png::Decoder::new(Cursor::new(bytes));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut r = dec.read_info().unwrap();
    let info = r.info();
    assert_eq!(info.color_type, png::ColorType::Indexed);
    let (w, h, bits) = (
        info.width as usize,
        info.height as usize,
        info.bit_depth as usize,
    );
    let plte: Vec<[u8; 3]> = info
        .palette
        .as_deref()
        .unwrap()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
    r.next_frame(&mut buf).unwrap();
    let stride = (w * bits).div_ceil(8);
    let mut idx = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let bit = x * bits;
            let byte = buf[y * stride + bit / 8];
            idx.push((byte >> (8 - bits - bit % 8)) & ((1u16 << bits) - 1) as u8);
        }
    }
    (w, h, idx, plte)
}

/// The index of each code of a device.
fn index_of_code(d: &Device, code: u8) -> u8 {
    d.inks
        .iter()
        .position(|i| i.code == code)
        .unwrap_or_else(|| panic!("code {code} is no ink of {}", d.name)) as u8
}

/// Decodes `raw`: codes at `bits` a pixel, MSB first, rows padded to a byte.
fn decode_raw(d: &Device, bytes: &[u8], w: usize, h: usize) -> Vec<u8> {
    let bits = d.packed_bits() as usize;
    let stride = (w * bits).div_ceil(8);
    assert_eq!(bytes.len(), stride * h, "{}: raw size", d.name);
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        let row = &bytes[y * stride..(y + 1) * stride];
        for x in 0..w {
            let bit = x * bits;
            let code = (row[bit / 8] >> (8 - bits - bit % 8)) & ((1u16 << bits) - 1) as u8;
            out.push(index_of_code(d, code));
        }
        // The padding bits are zero.
        let used = w * bits;
        if !used.is_multiple_of(8) {
            assert_eq!(
                row[stride - 1] & (0xFF >> (used % 8)),
                0,
                "{}: padding",
                d.name
            );
        }
    }
    out
}

/// Decodes a C header: the defines, then the bytes of the array, as `raw`.
fn decode_header(d: &Device, text: &str) -> (usize, usize, Vec<u8>) {
    let define = |suffix: &str| -> usize {
        let line = text
            .lines()
            .find(|l| {
                l.starts_with("#define ") && l.split_whitespace().nth(1).unwrap().ends_with(suffix)
            })
            .unwrap_or_else(|| panic!("no {suffix} define"));
        line.split_whitespace().nth(2).unwrap().parse().unwrap()
    };
    let (w, h, bits) = (define("_WIDTH"), define("_HEIGHT"), define("_BITS"));
    assert_eq!(bits, d.packed_bits() as usize);
    let decl = text.find("const uint8_t ").expect("an array");
    let body = &text[decl..];
    let open = body.find('{').unwrap();
    let close = body.find("};").unwrap();
    let bytes: Vec<u8> = body[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| u8::from_str_radix(t.trim_start_matches("0x"), 16).unwrap())
        .collect();
    let declared: usize = body[..open]
        .split('[')
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(declared, bytes.len());
    (w, h, decode_raw(d, &bytes, w, h))
}

/// Decodes `planes`: the black plane, then (three inks) the colour plane, one bit a pixel,
/// MSB first, rows padded to a byte; the black ink's bit is `planes.black`, the colour
/// ink's `planes.colour`.
fn decode_planes(d: &Device, bytes: &[u8], w: usize, h: usize) -> Vec<u8> {
    let stride = w.div_ceil(8);
    let plane_len = stride * h;
    let black = d.inks.iter().position(|i| i.name == "black").unwrap() as u8;
    let white = d.inks.iter().position(|i| i.name == "white").unwrap() as u8;
    let colour = (0..d.inks.len() as u8).find(|&i| i != black && i != white);
    assert_eq!(
        bytes.len(),
        plane_len * if colour.is_some() { 2 } else { 1 },
        "{}: planes size",
        d.name
    );
    let bit = |plane: usize, x: usize, y: usize| {
        (bytes[plane * plane_len + y * stride + x / 8] >> (7 - x % 8)) & 1
    };
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let is_black = bit(0, x, y) == d.planes.black;
            let is_colour = colour.is_some() && bit(1, x, y) == d.planes.colour;
            assert!(
                !(is_black && is_colour),
                "{}: both planes at {x},{y}",
                d.name
            );
            out.push(match (is_black, is_colour) {
                (true, _) => black,
                (_, true) => colour.unwrap(),
                _ => white,
            });
        }
    }
    out
}

/// Decodes `nibbles`: two pixels a byte, the even pixel in the low nibble.
fn decode_nibbles(d: &Device, bytes: &[u8], w: usize, h: usize) -> Vec<u8> {
    let stride = w.div_ceil(2);
    assert_eq!(bytes.len(), stride * h);
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let b = bytes[y * stride + x / 2];
            let code = if x % 2 == 0 { b & 0x0F } else { b >> 4 };
            out.push(index_of_code(d, code));
        }
        if w % 2 == 1 {
            assert_eq!(bytes[y * stride + stride - 1] >> 4, 0, "padding nibble");
        }
    }
    out
}

#[test]
fn every_encoding_of_every_device_decodes_to_the_png_indices() {
    let (mut checked, mut expected) = (0, 0);
    for name in Device::builtin_names() {
        let d = Device::builtin(name).unwrap();
        // Every panel takes its raw buffer and the C header of it.
        for f in [Format::Raw, Format::CHeader] {
            assert!(d.encodings.contains(&f), "{name}: no {}", f.name());
        }
        expected += 4 * d.encodings.iter().filter(|&&f| f != Format::Png).count();
        for (w, h) in [(37, 11), (8, 3), (1, 5), (64, 9)] {
            let img = photo(w, h);
            let opts = device_opts(name, w, h);
            let png =
                halftone::convert_to_bytes(Input::Image(img.clone()), Format::Png, &opts).unwrap();
            let (pw, ph, want, plte) = png_indices(&png);
            assert_eq!((pw, ph), (w, h));
            assert_eq!(
                plte,
                d.shown_colours(),
                "{name}: the PNG shows the measured inks"
            );
            if (w, h) == (64, 9) && d.inks.len() <= 7 {
                // The photo uses every ink, so a wrong code table shows.
                for i in 0..d.inks.len() as u8 {
                    assert!(want.contains(&i), "{name}: ink {i} unused");
                }
            }
            for &format in &d.encodings {
                let bytes =
                    halftone::convert_to_bytes(Input::Image(img.clone()), format, &opts).unwrap();
                let got = match format {
                    Format::Raw => decode_raw(&d, &bytes, w, h),
                    Format::CHeader => {
                        let (hw, hh, got) = decode_header(&d, std::str::from_utf8(&bytes).unwrap());
                        assert_eq!((hw, hh), (w, h));
                        got
                    }
                    Format::Planes => decode_planes(&d, &bytes, w, h),
                    Format::Nibbles => decode_nibbles(&d, &bytes, w, h),
                    Format::Png => continue,
                    other => panic!("{name}: unexpected encoding {other:?}"),
                };
                assert_eq!(got, want, "{name} {w}x{h} {}", format.name());
                checked += 1;
            }
        }
    }
    // 4 sizes of every encoding of every panel (the 11 built-in ones: raw and h for all,
    // planes for the four two- and three-ink ones, nibbles for the 16-grey one).
    assert!(Device::builtin_names().count() >= 11);
    assert_eq!(checked, expected);
}

#[test]
fn raw_holds_the_firmware_codes_not_the_indices() {
    // Spectra 6: blue and green are codes 5 and 6 at indices 4 and 5.
    let d = Device::builtin("spectra6-7in3-v2").unwrap();
    let blue = d.inks[4].shown();
    let green = d.inks[5].shown();
    let px: Vec<u8> = [blue, green, blue, green].concat();
    let opts = device_opts("spectra6-7in3-v2", 4, 1);
    let raw = halftone::convert_to_bytes(Input::Image(Image::rgb8(4, 1, &px)), Format::Raw, &opts)
        .unwrap();
    assert_eq!(raw, [0x56, 0x56]);
    // The PNG holds the indices.
    let png = halftone::convert_to_bytes(Input::Image(Image::rgb8(4, 1, &px)), Format::Png, &opts)
        .unwrap();
    assert_eq!(png_indices(&png).2, [4, 5, 4, 5]);
}

#[test]
fn nominal_png_has_the_same_indices_in_the_nominal_colours() {
    for name in ["spectra6-7in3-v2", "hanshow-bwr", "bwry-3in97"] {
        let d = Device::builtin(name).unwrap();
        let img = photo(33, 7);
        let measured = device_opts(name, 33, 7);
        let nominal = Options {
            ink_colours: InkColours::Nominal,
            ..measured.clone()
        };
        let a =
            halftone::convert_to_bytes(Input::Image(img.clone()), Format::Png, &measured).unwrap();
        let b = halftone::convert_to_bytes(Input::Image(img), Format::Png, &nominal).unwrap();
        let (_, _, ia, pa) = png_indices(&a);
        let (_, _, ib, pb) = png_indices(&b);
        assert_eq!(ia, ib, "{name}");
        assert_eq!(pa, d.shown_colours(), "{name}");
        assert_eq!(pb, d.nominal_colours(), "{name}");
        assert_ne!(pa, pb, "{name}");
    }
}

fn write_palette_file(dir: &Path, d: &Device) -> std::path::PathBuf {
    let text: String = d
        .shown_colours()
        .iter()
        .map(|c| format!("#{:02x}{:02x}{:02x}\n", c[0], c[1], c[2]))
        .collect();
    let p = dir.join(format!("{}.txt", d.name));
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn at_the_absolute_intent_a_device_is_the_palette_plus_size_and_ppi() {
    let dir = tempfile::tempdir().unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/color-balls.png");
    for name in [
        "spectra6-7in3-v2",
        "bwry-3in97",
        "hanshow-bwy",
        "grey4-4in2",
    ] {
        let d = Device::builtin(name).unwrap();
        let pal = write_palette_file(dir.path(), &d);
        let a = dir.path().join(format!("{name}-device.png"));
        let b = dir.path().join(format!("{name}-palette.png"));
        bin()
            .args(["convert"])
            .arg(&input)
            .arg("-o")
            .arg(&a)
            .args(["--device", name, "--intent", "absolute"])
            .assert()
            .success();
        bin()
            .args(["convert"])
            .arg(&input)
            .arg("-o")
            .arg(&b)
            .arg("--palette")
            .arg(&pal)
            .args([
                "--fit",
                &format!("{}x{}", d.width, d.height),
                "--fit-mode",
                "pad",
            ])
            .args(["--dpi", &d.ppi.to_string()])
            .assert()
            .success();
        let (a, b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
        assert_eq!(a, b, "{name}");
        // Fitted into the panel and padded to its size.
        let (w, h, _, _) = png_indices(&a);
        assert_eq!((w, h), (d.width, d.height), "{name}");
        // And a size the user gives wins over the panel's.
        let (w, _, _, _) = png_indices(
            &halftone::convert_to_bytes(
                Input::Path(input.clone()),
                Format::Png,
                &Options {
                    device: Some(name.into()),
                    width: Some(41),
                    ..Default::default()
                },
            )
            .unwrap(),
        );
        assert_eq!(w, 41, "{name}");
    }
}

/// The index of the ink named white.
fn white_of(d: &Device) -> u8 {
    d.inks.iter().position(|i| i.name == "white").unwrap() as u8
}

/// The columns of a `w`-wide index image that hold only `ink`.
fn columns_all(idx: &[u8], w: usize, ink: u8) -> Vec<usize> {
    (0..w)
        .filter(|&x| idx.iter().skip(x).step_by(w).all(|&i| i == ink))
        .collect()
}

#[test]
fn a_panel_buffer_is_the_panels_size_padded_with_its_white() {
    let dir = tempfile::tempdir().unwrap();
    let name = "spectra6-7in3-v2";
    let d = Device::builtin(name).unwrap();
    let white = white_of(&d);
    // A 3:2 photo into the 5:3 panel: 720x480, 40 columns of white either side.
    let input = photo_file(dir.path(), "p.png", 360, 240);
    let run = |out: &str, mode: &[&str]| {
        let path = dir.path().join(out);
        bin()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&path)
            .args(["--device", name])
            .args(mode)
            .assert()
            .success();
        std::fs::read(path).unwrap()
    };
    let png = run("pad.png", &[]);
    let (w, h, idx, _) = png_indices(&png);
    assert_eq!((w, h), (800, 480));
    let white_columns = columns_all(&idx, w, white);
    let want: Vec<usize> = (0..40).chain(760..800).collect();
    assert_eq!(white_columns, want);
    // The firmware's buffer: the panel's size, the same pixels.
    let bin_bytes = run("pad.bin", &[]);
    assert_eq!(bin_bytes.len(), 800 * 480 / 2);
    assert_eq!(decode_raw(&d, &bin_bytes, 800, 480), idx);
    // pad is the default; the library and an explicit --fit-mode make the same bytes.
    assert_eq!(run("pad2.png", &["--fit-mode", "pad"]), png);
    let opts = Options {
        device: Some(name.into()),
        ..Default::default()
    };
    let lib = halftone::convert_to_bytes(Input::Path(input.clone()), Format::Png, &opts).unwrap();
    assert_eq!(lib, png);
    // cover: the panel's size, cropped, no white border.
    let (w, h, idx, _) = png_indices(&run("cover.png", &["--fit-mode", "cover"]));
    assert_eq!((w, h), (800, 480));
    assert_eq!(columns_all(&idx, w, white), Vec::<usize>::new());
    assert_eq!(
        run("cover.bin", &["--fit-mode", "cover"]).len(),
        800 * 480 / 2
    );
    // inside: today's fit, 720x480.
    let (w, h, _, _) = png_indices(&run("inside.png", &["--fit-mode", "inside"]));
    assert_eq!((w, h), (720, 480));
    // The border does not sway the rendering: the tone and gamut statistics are taken inside
    // it. A dim, low-contrast photo (which the perceptual intent stretches to the panel's
    // range; a white border taken into the statistics stops the stretch): each ink covers the
    // same share of the picture padded or not, to the diffusion's noise.
    let dim: Vec<u8> = photo_rgb(360, 240).iter().map(|&v| 40 + v / 3).collect();
    let dim_path = dir.path().join("dim.png");
    image::save_buffer(&dim_path, &dim, 360, 240, image::ExtendedColorType::Rgb8).unwrap();
    let shares = |mode: &str| {
        let path = dir.path().join(format!("dim-{mode}.png"));
        bin()
            .arg("convert")
            .arg(&dim_path)
            .arg("-o")
            .arg(&path)
            .args(["--device", name, "--fit-mode", mode])
            .assert()
            .success();
        let (w, _, idx, _) = png_indices(&std::fs::read(path).unwrap());
        let x0 = (w - 720) / 2;
        let picture: Vec<u8> = idx
            .chunks(w)
            .flat_map(|row| row[x0..x0 + 720].iter().copied())
            .collect();
        (0..d.inks.len() as u8)
            .map(|k| picture.iter().filter(|&&i| i == k).count() as f64 / picture.len() as f64)
            .collect::<Vec<f64>>()
    };
    let (padded, alone) = (shares("pad"), shares("inside"));
    for (k, (a, b)) in padded.iter().zip(&alone).enumerate() {
        assert!(
            (a - b).abs() < 0.003,
            "ink {k}: {a:.4} of the padded picture, {b:.4} of the picture alone"
        );
    }
    // A plain --fit box stays inside by default.
    let out = dir.path().join("fit.png");
    bin()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--palette", "epaper-7", "--fit", "800x480"])
        .assert()
        .success();
    assert_eq!(png_indices(&std::fs::read(out).unwrap()).0, 720);
}

#[test]
fn pad_and_cover_from_a_large_photo_shrunk_on_load_and_in_a_batch() {
    // 3600x2400 is shrunk by 2 on load (8.6 megapixels, twice the 720x480 or 800x534 asked
    // for) before the resize: the padded picture sits where it does from a small photo.
    let dir = tempfile::tempdir().unwrap();
    let name = "spectra6-7in3-v2";
    let d = Device::builtin(name).unwrap();
    let white = white_of(&d);
    let input = photo_file(dir.path(), "big.jpg", 3600, 2400);
    for (mode, want) in [
        ("pad", (0..40).chain(760..800).collect::<Vec<usize>>()),
        ("cover", vec![]),
    ] {
        let opts = Options {
            device: Some(name.into()),
            fit_mode: Some(mode.parse().unwrap()),
            ..Default::default()
        };
        let png =
            halftone::convert_to_bytes(Input::Path(input.clone()), Format::Png, &opts).unwrap();
        let (w, h, idx, _) = png_indices(&png);
        assert_eq!((w, h), (800, 480), "{mode}");
        assert_eq!(columns_all(&idx, w, white), want, "{mode}");
    }
    // A batch takes the same road: every buffer the panel's size.
    let out = dir.path().join("out");
    bin()
        .args(["batch", "-q", "--format", "raw", "--device", name])
        .arg(&input)
        .arg(photo_file(dir.path(), "small.png", 90, 60))
        .arg("-o")
        .arg(&out)
        .assert()
        .success();
    for f in ["big.raw", "small.raw"] {
        assert_eq!(
            std::fs::read(out.join(f)).unwrap().len(),
            800 * 480 / 2,
            "{f}"
        );
    }
}

#[test]
fn a_profile_file_with_a_rotation_turns_the_picture_into_the_panel() {
    let dir = tempfile::tempdir().unwrap();
    let text = Device::builtin_text("hanshow-bwr")
        .unwrap()
        .replace("rotation = 0", "rotation = 90")
        .replace("name = \"hanshow-bwr\"", "name = \"upright-tag\"");
    let profile = dir.path().join("upright.toml");
    std::fs::write(&profile, text).unwrap();
    // A landscape picture, 3:1, for a 296x128 panel mounted upright: turned a quarter, it is
    // 1:3 and fills the panel's 128-pixel side... as its width 296 → height 128 after turning.
    let img = photo(90, 30);
    let inside = Some(halftone::FitMode::Inside);
    let opts = Options {
        device: Some(profile.to_str().unwrap().into()),
        fit_mode: inside,
        ..Default::default()
    };
    let (w, h, _, _) = png_indices(
        &halftone::convert_to_bytes(Input::Image(img.clone()), Format::Png, &opts).unwrap(),
    );
    assert_eq!((w, h), (43, 128));
    let plain = Options {
        device: Some("hanshow-bwr".into()),
        fit_mode: inside,
        ..Default::default()
    };
    let (w, h, _, _) = png_indices(
        &halftone::convert_to_bytes(Input::Image(img.clone()), Format::Png, &plain).unwrap(),
    );
    assert_eq!((w, h), (296, 99));
    // Padded by default to the panel's own size, turned or not: the turned picture's 43
    // columns centred at 126, the plain one's 99 rows at 14. The photo's top row is dark:
    // turned clockwise, it is the picture's last column.
    let d = Device::builtin("hanshow-bwr").unwrap();
    let white = white_of(&d);
    for (o, columns) in [(opts, true), (plain, false)] {
        let o = Options {
            fit_mode: None,
            ..o
        };
        let (w, h, idx, _) = png_indices(
            &halftone::convert_to_bytes(Input::Image(img.clone()), Format::Png, &o).unwrap(),
        );
        assert_eq!((w, h), (296, 128));
        let (white_lines, picture, dark) = if columns {
            (columns_all(&idx, w, white), 126..169, 168)
        } else {
            let rows: Vec<usize> = (0..h)
                .filter(|&y| idx[y * w..(y + 1) * w].iter().all(|&i| i == white))
                .collect();
            (rows, 14..113, 14)
        };
        let n = if columns { w } else { h };
        for i in (0..n).filter(|i| !picture.contains(i)) {
            assert!(white_lines.contains(&i), "columns {columns}: {i} not white");
        }
        assert!(
            !white_lines.contains(&dark),
            "columns {columns}: {dark} white"
        );
        assert!(
            white_lines.len() < n - picture.len() / 2,
            "columns {columns}"
        );
    }
}

#[test]
fn bad_profiles_and_misuse_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/color-balls.png");
    let good = Device::builtin_text("bwry-3in97").unwrap();
    let cases = [
        ("width = 800", "width = -3", "bad.toml:7: width: -3 pixels"),
        (
            "measured = \"#55180e\"",
            "measured = \"#55180\"",
            "bad.toml:38: measured: `#55180` is not a colour",
        ),
        (
            "code = 3",
            "code = 2",
            "bad.toml:36: code: ink 'red' repeats the code of ink 'yellow'",
        ),
        ("ppi = 235", "ppi = \"many\"", "bad.toml:9:"),
    ];
    for (from, to, want) in cases {
        let text = good.replacen(from, to, 1);
        assert_ne!(text, good, "{from}");
        let p = dir.path().join("bad.toml");
        std::fs::write(&p, &text).unwrap();
        let out = bin()
            .args(["convert"])
            .arg(&input)
            .args(["-o", "-", "--format", "raw", "--device"])
            .arg(&p)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{to}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(want), "{to}: {err}");
        assert!(out.stdout.is_empty());
    }
    for (args, want) in [
        (vec!["--device", "spectra6-7in3-v3"], "spectra6-7in3-v2"),
        (
            vec!["--device", "bwry-3in97", "--palette", "bw"],
            "--device bwry-3in97: sets the palette",
        ),
        (vec!["--ink-colours", "nominal"], "--ink-colours nominal"),
        (
            vec!["--device", "spectra6-7in3-v2", "--format", "planes"],
            "planes are for two- and three-ink panels",
        ),
        (
            vec!["--device", "bwry-3in97", "--method", "screen"],
            "--device",
        ),
        (
            vec![
                "--device",
                "bwry-3in97",
                "--intent",
                "relative",
                "--tone",
                "0.5",
            ],
            "--tone and --gamut steer the perceptual intent",
        ),
        (
            vec!["--exposure", "1"],
            "--exposure, --saturation, --tone and --gamut work with a --device or --palette",
        ),
        (
            vec!["--format", "raw", "--color", "rgb"],
            "one plane of ink codes",
        ),
        (
            vec!["--fit-mode", "pad"],
            "--fit-mode pad needs a box: give --fit WxH, or a --device without --width",
        ),
        (
            vec![
                "--device",
                "bwry-3in97",
                "--width",
                "100",
                "--fit-mode",
                "cover",
            ],
            "--fit-mode cover needs a box",
        ),
        (
            vec!["--device", "bwry-3in97", "--kernel", "riemersma"],
            "--kernel riemersma: a device works with the fixed kernels (floyd-steinberg,",
        ),
        (
            vec!["--device", "bwry-3in97", "--kernel", "zhou-fang"],
            "--kernel zhou-fang: a device works with the fixed kernels",
        ),
    ] {
        let out = bin()
            .args(["convert"])
            .arg(&input)
            .args(["-o", "-"])
            .args(if args.contains(&"--format") {
                vec![]
            } else {
                vec!["--format", "raw"]
            })
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn listing_and_showing() {
    let out = bin().args(["devices", "list"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let names: Vec<&str> = Device::builtin_names().collect();
    assert_eq!(text.lines().count(), names.len());
    for (line, name) in text.lines().zip(&names) {
        let d = Device::builtin(name).unwrap();
        assert!(line.starts_with(name), "{line}");
        assert!(
            line.contains(&format!("{}x{}", d.width, d.height)),
            "{line}"
        );
        assert!(line.contains(d.colours.name()), "{line}");
    }
    assert!(text.contains("spectra6-7in3-v2") && text.contains("measured"));
    assert!(text.contains("acep7-5in65") && text.contains("nominal"));
    let out = bin()
        .args(["devices", "show", "bwry-3in97"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        Device::builtin_text("bwry-3in97").unwrap()
    );
    // A file is checked, then printed; a bad one is a one-line error.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mine.toml");
    std::fs::write(&p, Device::builtin_text("grey4-4in2").unwrap()).unwrap();
    let out = bin().args(["devices", "show"]).arg(&p).output().unwrap();
    assert!(out.status.success());
    std::fs::write(&p, "name = \"x\"\n").unwrap();
    let out = bin().args(["devices", "show"]).arg(&p).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("mine.toml"), "{err}");
}
