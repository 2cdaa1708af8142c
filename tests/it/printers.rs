//! Printer formats carry exactly the bits `--format pbm` writes, read back by decoders
//! nobody here wrote: Ghostscript renders the PDF and PostScript (`gs -sDEVICE=pbmraw`),
//! qpdf checks the PDF's structure, pdfimages lists its image, zebrafy (PyPI) decodes ZPL.
//! PCL and ESC/POS have no such decoder, so the library holds one of each
//! (`halftone::io::lang`, written from the manuals: PCL 5 Technical Reference ch. 15;
//! Epson ESC/POS Command Reference), checked here against netpbm's `pbmtolj`,
//! Ghostscript's `ljet4` device and python-escpos's `Dummy`; its ZPL decoder is checked
//! against zebrafy.
//!
//! Tools come from `.ci/run` (apt: ghostscript, qpdf, poppler-utils, netpbm; a venv with
//! zebrafy and python-escpos named by `HALFTONE_PRINTER_PYTHON`). Outside CI a missing tool
//! skips its test with a note; with `CI=true` it fails.

use std::path::{Path, PathBuf};
use std::process::Command as Process;

use assert_cmd::Command;

use halftone::io::lang::{
    self, escpos,
    pcl::{self, PclRaster},
    zpl,
};
use halftone::io::lang::{PrintOptions, ZplEncoding};
use halftone::io::{encode, Format, WriteOptions};
use halftone::raster::Halftone;

fn halftone() -> Command {
    Command::cargo_bin("halftone").unwrap()
}

/// True when `tool` is installed; otherwise the calling check is skipped (a failure in CI).
#[track_caller]
fn have(tool: &str) -> bool {
    let package = match tool {
        "gs" => "ghostscript",
        "pdfimages" => "poppler-utils",
        "pamtopnm" | "pbmtolj" => "netpbm",
        other => other,
    };
    let at = std::panic::Location::caller();
    crate::common::have_tool(tool, package, &format!("printers.rs:{}", at.line()))
}

/// The venv's Python with zebrafy and python-escpos, if there is one.
fn python() -> Option<PathBuf> {
    let found = std::env::var_os("HALFTONE_PRINTER_PYTHON")
        .map(PathBuf::from)
        .filter(|p| p.exists());
    if found.is_none() {
        crate::common::skip(
            "printers (the zebrafy and python-escpos checks)",
            "HALFTONE_PRINTER_PYTHON does not name a venv's python with them (see .ci/run)",
        );
    }
    found
}

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/printers")
        .join(name)
}

/// Runs a command, panics with its stderr on failure, returns stdout.
fn run(cmd: &mut Process) -> Vec<u8> {
    let out = cmd.output().expect("spawn");
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// A bilevel bitmap: width, height, rows of `(width + 7) / 8` bytes, 1 = ink.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Bits {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl Bits {
    fn stride(&self) -> usize {
        self.width.div_ceil(8)
    }

    fn get(&self, x: usize, y: usize) -> bool {
        self.data[y * self.stride() + x / 8] & (0x80 >> (x % 8)) != 0
    }

    /// Parses a binary PBM (P4) with no comments.
    fn from_pbm(bytes: &[u8]) -> Bits {
        let mut fields: Vec<usize> = Vec::new();
        let mut i = 2;
        assert_eq!(&bytes[..2], b"P4", "not a P4 PBM");
        while fields.len() < 2 {
            while bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            let start = i;
            while bytes[i].is_ascii_digit() {
                i += 1;
            }
            fields.push(
                std::str::from_utf8(&bytes[start..i])
                    .unwrap()
                    .parse()
                    .unwrap(),
            );
        }
        i += 1;
        let (width, height) = (fields[0], fields[1]);
        let mut data = bytes[i..i + width.div_ceil(8) * height].to_vec();
        // Padding bits mean nothing; clear them so that bitmaps compare by their pixels.
        if width % 8 != 0 {
            for row in data.chunks_exact_mut(width.div_ceil(8)) {
                *row.last_mut().unwrap() &= 0xFFu8 << (8 - width % 8);
            }
        }
        Bits {
            width,
            height,
            data,
        }
    }

    /// The sub-bitmap at (x0, y0) of size w × h.
    fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> Bits {
        let mut out = Bits {
            width: w,
            height: h,
            data: vec![0; w.div_ceil(8) * h],
        };
        for y in 0..h {
            for x in 0..w {
                if self.get(x0 + x, y0 + y) {
                    out.data[y * w.div_ceil(8) + x / 8] |= 0x80 >> (x % 8);
                }
            }
        }
        out
    }

    /// The smallest rectangle holding all ink: (x0, y0, w, h).
    fn ink_box(&self) -> Option<(usize, usize, usize, usize)> {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if self.get(x, y) {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        (x0 != usize::MAX).then(|| (x0, y0, x1 + 1 - x0, y1 + 1 - y0))
    }

    fn ink_crop(&self) -> Bits {
        let (x, y, w, h) = self.ink_box().expect("some ink");
        self.crop(x, y, w, h)
    }
}

/// A test picture: smooth shading, a dark disc, black bars (line art) and a blank stretch,
/// `w × h`, as a PNG in `dir`.
fn picture(dir: &Path, name: &str, w: u32, h: u32, seed: u32) -> PathBuf {
    let img = image::GrayImage::from_fn(w, h, |x, y| {
        let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
        let blank = (0.55..0.7).contains(&fy);
        let bars = fx < 0.2 && (x / 3 + seed).is_multiple_of(3) && fy < 0.5;
        let disc = (fx - 0.6).powi(2) + (fy - 0.3).powi(2) < 0.02;
        let v = if blank {
            255.0
        } else if bars {
            0.0
        } else if disc {
            40.0
        } else {
            255.0 * (0.5 + 0.5 * (fx * 7.0 + fy * 3.0 + seed as f32).sin() * (1.0 - fy * 0.5))
        };
        image::Luma([v.clamp(0.0, 255.0) as u8])
    });
    let path = dir.join(name);
    img.save(&path).unwrap();
    path
}

/// `halftone convert input -o output` with the options every test shares (explicit method,
/// levels and dpi: none of the defaults matter).
fn convert(input: &Path, output: &Path, extra: &[&str]) {
    halftone()
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(output)
        .args([
            "--method",
            "diffuse",
            "--kernel",
            "floyd-steinberg",
            "--levels",
            "2",
        ])
        .args(extra)
        .assert()
        .success();
}

/// Renders a PDF or PostScript file with Ghostscript at `dpi` and returns each page.
fn ghostscript_pages(file: &Path, dpi: u32) -> Vec<Bits> {
    let dir = tempfile::tempdir().unwrap();
    let pattern = dir.path().join("page-%d.pbm");
    run(Process::new("gs")
        .args(["-q", "-dSAFER", "-dBATCH", "-dNOPAUSE", "-sDEVICE=pbmraw"])
        .arg(format!("-r{dpi}"))
        .arg("-o")
        .arg(&pattern)
        .arg(file));
    (1..)
        .map(|i| dir.path().join(format!("page-{i}.pbm")))
        .take_while(|p| p.exists())
        .map(|p| {
            // gs writes a comment line; pamtopnm rewrites the header without it.
            let bytes = run(Process::new("pamtopnm").stdin(std::fs::File::open(&p).unwrap()));
            Bits::from_pbm(&bytes)
        })
        .collect()
}

fn read_pbm(path: &Path) -> Bits {
    Bits::from_pbm(&std::fs::read(path).unwrap())
}

#[test]
fn pdf_and_postscript_render_exactly_in_ghostscript() {
    if !(have("gs") && have("pamtopnm") && have("qpdf") && have("pdfimages")) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 301, 203, 1);
    for dpi in [72u32, 203, 300, 600] {
        let dpi_s = dpi.to_string();
        let pbm = d.join("ref.pbm");
        convert(&input, &pbm, &["--dpi", &dpi_s]);
        let want = read_pbm(&pbm);
        for (ext, extra) in [
            ("pdf", &[][..]),
            ("pdf", &["--compression", "g4"][..]),
            ("ps", &[][..]),
        ] {
            let out = d.join(format!("out.{ext}"));
            let mut args = vec!["--dpi", &dpi_s];
            args.extend_from_slice(extra);
            convert(&input, &out, &args);
            let pages = ghostscript_pages(&out, dpi);
            assert_eq!(pages.len(), 1);
            assert_eq!(pages[0], want, "{ext} {extra:?} at {dpi} dpi");
        }
    }
    // Structure and image listing of the last Flate PDF (300 dpi).
    let pdf = d.join("flate.pdf");
    convert(&input, &pdf, &["--dpi", "300"]);
    let check = run(Process::new("qpdf").arg("--check").arg(&pdf));
    let check = String::from_utf8_lossy(&check);
    assert!(
        check.contains("No syntax or stream encoding errors"),
        "{check}"
    );
    let list = String::from_utf8(run(Process::new("pdfimages").arg("-list").arg(&pdf))).unwrap();
    let rows: Vec<Vec<&str>> = list
        .lines()
        .skip(2)
        .map(|l| l.split_whitespace().collect())
        .collect();
    assert_eq!(rows.len(), 1, "{list}");
    // page num type width height color comp bpc enc interp object ID x-ppi y-ppi size ratio
    let r = &rows[0];
    assert_eq!(
        (r[3], r[4], r[5], r[7]),
        ("301", "203", "gray", "1"),
        "{list}"
    );
    assert_eq!((r[12], r[13]), ("300", "300"), "{list}");
    let ratio: f64 = r[15].trim_end_matches('%').parse().unwrap();
    assert!(ratio < 100.0, "{list}");
}

#[test]
fn pdf_page_centres_the_image_and_refuses_a_small_page() {
    if !(have("gs") && have("pamtopnm")) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 600 × 400 at 300 dpi on a 4×6 in page (1200 × 1800 dots): offset (300, 700).
    let input = picture(d, "in.png", 600, 400, 2);
    let pbm = d.join("ref.pbm");
    convert(&input, &pbm, &["--dpi", "300"]);
    let want = read_pbm(&pbm);
    for ext in ["pdf", "ps"] {
        let out = d.join(format!("page.{ext}"));
        convert(&input, &out, &["--dpi", "300", "--page", "4x6in"]);
        let pages = ghostscript_pages(&out, 300);
        assert_eq!((pages[0].width, pages[0].height), (1200, 1800), "{ext}");
        assert_eq!(pages[0].crop(300, 700, 600, 400), want, "{ext}");
        assert_eq!(
            pages[0].ink_crop(),
            want.ink_crop(),
            "{ext}: ink outside the image"
        );
    }
}

#[test]
fn pdf_refuses_a_page_smaller_than_the_image() {
    // A page smaller than the image: one line, no file (no decoder needed).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 600, 400, 2);
    let out = d.join("small.pdf");
    let assert = halftone()
        .args(["convert"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "threshold", "--dpi", "300", "--page", "1x1in"])
        .assert()
        .code(1);
    let err = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("larger than the 1.00 x 1.00 in page"), "{err}");
    assert!(!out.exists());
}

#[test]
fn pdf_grey_levels_render_to_their_reflectance() {
    if !(have("gs") && have("pamtopnm")) {
        return;
    }
    // 3, 4 and 16 levels (2 and 4 bits a sample): gs renders DeviceGray through the
    // /Decode to k/(L-1) of white.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (levels, seed) in [(3u16, 1u64), (4, 2), (16, 3)] {
        let (w, h) = (37usize, 11usize);
        let mut ht = Halftone::new(w, h, 1, levels);
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        for y in 0..h {
            for x in 0..w {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                ht.set(0, x, y, (s % levels as u64) as u8);
            }
        }
        let mut opts = WriteOptions::new(Format::Pdf);
        opts.dpi = Some(72.0);
        let mut pdf = Vec::new();
        encode(&ht, &opts, Path::new("grey.pdf"), &mut pdf).unwrap();
        let path = d.join("grey.pdf");
        std::fs::write(&path, &pdf).unwrap();
        let out = d.join("g.pgm");
        run(Process::new("gs")
            .args([
                "-q",
                "-dSAFER",
                "-dBATCH",
                "-dNOPAUSE",
                "-sDEVICE=pgmraw",
                "-r72",
            ])
            .arg("-o")
            .arg(&out)
            .arg(&path));
        let got = image::load_from_memory(&run(
            Process::new("pamtopnm").stdin(std::fs::File::open(&out).unwrap())
        ))
        .unwrap()
        .to_luma8();
        assert_eq!(got.dimensions(), (w as u32, h as u32));
        for y in 0..h {
            for x in 0..w {
                let k = ht.get(0, x, y) as f64;
                let want = (k / (levels - 1) as f64 * 255.0).round() as i32;
                let g = got.get_pixel(x as u32, y as u32)[0] as i32;
                assert!(
                    (g - want).abs() <= 1,
                    "{levels} levels: level {k} rendered as {g}"
                );
            }
        }
    }
}

#[test]
fn pdf_and_postscript_colour_render_to_their_levels_and_palette() {
    if !(have("gs") && have("pamtopnm")) {
        return;
    }
    // RGB at 2 and 4 levels a channel (interleaved samples of 1 and 2 bits) and a
    // 5-colour palette (/Indexed): gs's ppmraw shows each level k as k/(L-1) of full.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (29usize, 13usize);
    let fill = |ht: &mut Halftone, levels: u16| {
        let mut s = 0x1234_5678_9abc_def1u64;
        for c in 0..ht.channels() {
            for y in 0..h {
                for x in 0..w {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    ht.set(c, x, y, (s % levels as u64) as u8);
                }
            }
        }
    };
    let mut cases = Vec::new();
    for levels in [2u16, 4] {
        let mut ht = Halftone::new(w, h, 3, levels);
        fill(&mut ht, levels);
        cases.push(ht);
    }
    let mut pal = Halftone::new(w, h, 1, 5);
    fill(&mut pal, 5);
    pal.palette = Some(vec![
        [0, 0, 0],
        [255, 0, 0],
        [0, 128, 255],
        [255, 255, 0],
        [255, 255, 255],
    ]);
    cases.push(pal);
    for ht in &cases {
        for format in [Format::Pdf, Format::Ps] {
            let mut opts = WriteOptions::new(format);
            opts.dpi = Some(72.0);
            let mut bytes = Vec::new();
            encode(ht, &opts, Path::new("colour"), &mut bytes).unwrap();
            let path = d.join("colour.doc");
            std::fs::write(&path, &bytes).unwrap();
            let out = d.join("c.ppm");
            run(Process::new("gs")
                .args([
                    "-q",
                    "-dSAFER",
                    "-dBATCH",
                    "-dNOPAUSE",
                    "-sDEVICE=ppmraw",
                    "-r72",
                ])
                .arg("-o")
                .arg(&out)
                .arg(&path));
            let got = image::load_from_memory(&run(
                Process::new("pamtopnm").stdin(std::fs::File::open(&out).unwrap())
            ))
            .unwrap()
            .to_rgb8();
            assert_eq!(got.dimensions(), (w as u32, h as u32));
            for y in 0..h {
                for x in 0..w {
                    let want: [i32; 3] = match &ht.palette {
                        Some(p) => p[ht.get(0, x, y) as usize].map(i32::from),
                        None => [0, 1, 2].map(|c| {
                            (ht.get(c, x, y) as f64 / (ht.levels - 1) as f64 * 255.0).round() as i32
                        }),
                    };
                    let g = got.get_pixel(x as u32, y as u32).0.map(i32::from);
                    assert!(
                        (0..3).all(|c| (g[c] - want[c]).abs() <= 1),
                        "{format:?} {} levels{}: ({x},{y}) is {g:?}, want {want:?}",
                        ht.levels,
                        if ht.palette.is_some() {
                            " (palette)"
                        } else {
                            ""
                        }
                    );
                }
            }
        }
    }
}

/// A 4-plane (cyan, magenta, yellow, black) halftone with a different pattern on each plate.
fn cmyk_halftone(w: usize, h: usize) -> Halftone {
    let mut ht = Halftone::new(w, h, 4, 2);
    for c in 0..4 {
        for y in 0..h {
            for x in 0..w {
                let ink = match c {
                    0 => (x / 4 + y / 4) % 2 == 0,
                    1 => x < w / 2 && (x * y) % 3 == 0,
                    2 => y % 5 < 2,
                    _ => (x + 2 * y) % 7 == 0,
                };
                ht.set(c, x, y, if ink { 0 } else { 1 });
            }
        }
    }
    ht
}

#[test]
fn cmyk_plates_come_back_from_tiffsep1() {
    if !have("gs") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ht = cmyk_halftone(64, 40);
    let mut opts = WriteOptions::new(Format::Pdf);
    opts.dpi = Some(72.0);
    let mut pdf = Vec::new();
    encode(&ht, &opts, Path::new("plates.pdf"), &mut pdf).unwrap();
    let path = d.join("plates.pdf");
    std::fs::write(&path, &pdf).unwrap();
    run(Process::new("gs")
        .args([
            "-q",
            "-dSAFER",
            "-dBATCH",
            "-dNOPAUSE",
            "-sDEVICE=tiffsep1",
            "-r72",
        ])
        .arg("-o")
        .arg(d.join("sep.tif"))
        .arg(&path));
    for (c, ink) in ["Cyan", "Magenta", "Yellow", "Black"].iter().enumerate() {
        let plate = d.join(format!("sep({ink}).tif"));
        let img = image::open(&plate)
            .unwrap_or_else(|e| panic!("{}: {e}", plate.display()))
            .to_luma8();
        assert_eq!(img.dimensions(), (64, 40));
        for y in 0..40 {
            for x in 0..64 {
                // tiffsep1 plates are WhiteIsZero-style greys: ink is dark.
                let inked = img.get_pixel(x as u32, y as u32)[0] < 128;
                assert_eq!(inked, ht.get(c, x, y) == 0, "{ink} plate at ({x},{y})");
            }
        }
    }
}

#[test]
fn batch_into_one_pdf_has_a_page_per_input_in_sorted_order() {
    if !(have("gs") && have("pamtopnm")) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("in")).unwrap();
    // Written out of order and with different sizes, so a wrong order shows.
    let inputs = [
        picture(&d.join("in"), "c.png", 40, 30, 3),
        picture(&d.join("in"), "a.png", 64, 20, 1),
        picture(&d.join("in"), "b.png", 33, 47, 2),
    ];
    for ext in ["pdf", "ps"] {
        let book = d.join(format!("book.{ext}"));
        halftone()
            .args(["batch"])
            .arg(d.join("in"))
            .arg("-o")
            .arg(&book)
            .args(["--method", "diffuse", "--levels", "2", "--dpi", "144", "-q"])
            .assert()
            .success();
        if ext == "pdf" && have("qpdf") {
            run(Process::new("qpdf").arg("--check").arg(&book));
        }
        let pages = ghostscript_pages(&book, 144);
        assert_eq!(pages.len(), 3, "{ext}");
        for (page, name) in pages.iter().zip(["a", "b", "c"]) {
            let input = inputs
                .iter()
                .find(|p| p.ends_with(format!("{name}.png")))
                .unwrap();
            let pbm = d.join(format!("{name}.pbm"));
            convert(input, &pbm, &["--dpi", "144"]);
            assert_eq!(page, &read_pbm(&pbm), "{ext} page {name}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// PCL 5: the reference decoder (PCL 5 Technical Reference Manual, ch. 15).

/// Every raster graphic of a PCL stream, by the library's reference decoder.
fn decode_pcl(data: &[u8]) -> Vec<PclRaster> {
    pcl::decode(data).expect("PCL decodes")
}

/// A decoded raster as a bitmap of `width` columns.
fn raster_bits(r: &PclRaster, width: usize) -> Bits {
    let b = r.bitmap(width);
    Bits {
        width: b.width,
        height: b.height,
        data: b.data,
    }
}

#[test]
fn pcl_decodes_exactly_and_the_decoder_agrees_with_pbmtolj_and_ghostscript() {
    if !(have("pbmtolj") && have("gs") && have("pamtopnm")) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 509, 301, 4);
    for dpi in ["300", "600", "75"] {
        let pbm = d.join("ref.pbm");
        convert(&input, &pbm, &["--dpi", dpi]);
        let want = read_pbm(&pbm);
        // The decoder against netpbm's encoder (both of its compressions).
        for flags in [&[][..], &["-packbits", "-delta"][..]] {
            let lj = run(Process::new("pbmtolj")
                .args(flags)
                .args(["-resolution", dpi])
                .arg(&pbm));
            let r = decode_pcl(&lj);
            assert_eq!(r.len(), 1);
            assert_eq!(
                raster_bits(&r[0], want.width).ink_crop(),
                want.ink_crop(),
                "pbmtolj {flags:?}"
            );
        }
    }
    // The decoder against Ghostscript's LaserJet 4 driver: a PDF printed through gs.
    let pdf = d.join("g.pdf");
    convert(&input, &pdf, &["--dpi", "300", "--page", "letter"]);
    let lj4 = d.join("g.pcl");
    run(Process::new("gs")
        .args([
            "-q",
            "-dSAFER",
            "-dBATCH",
            "-dNOPAUSE",
            "-sDEVICE=ljet4",
            "-r300",
        ])
        .arg("-o")
        .arg(&lj4)
        .arg(&pdf));
    let r = decode_pcl(&std::fs::read(&lj4).unwrap());
    assert_eq!(r.len(), 1);
    let page = &ghostscript_pages(&pdf, 300)[0];
    let width = r[0].rows.iter().map(Vec::len).max().unwrap() * 8;
    assert_eq!(
        raster_bits(&r[0], width).ink_crop(),
        page.ink_crop(),
        "gs ljet4"
    );
}

/// Our PCL through the library's decoder (checked against netpbm and Ghostscript above):
/// the bits of `--format pbm` at every resolution, with no tool needed.
#[test]
fn pcl_decodes_to_the_pbm_bits_at_every_resolution() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 509, 301, 4);
    for dpi in ["300", "600", "75"] {
        let pbm = d.join("ref.pbm");
        convert(&input, &pbm, &["--dpi", dpi]);
        let want = read_pbm(&pbm);
        let pcl = d.join("out.pcl");
        convert(&input, &pcl, &["--dpi", dpi]);
        let r = decode_pcl(&std::fs::read(&pcl).unwrap());
        assert_eq!(r.len(), 1);
        assert_eq!(
            (r[0].x, r[0].y, r[0].dpi.to_string()),
            (0, 0, dpi.to_string())
        );
        assert_eq!(raster_bits(&r[0], want.width), want, "pcl at {dpi} dpi");
    }
}

#[test]
fn pcl_refuses_other_resolutions() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 40, 30, 1);
    let out = d.join("x.pcl");
    let assert = halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "threshold", "--dpi", "203"])
        .assert()
        .code(1);
    let err = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("75, 100, 150, 200, 300, 600") && err.contains("not 203"),
        "{err}"
    );
    assert!(!out.exists());
}

// ---------------------------------------------------------------------------------------
// ESC/POS: the reference decoder (ESC/POS Command Reference: the commands halftone and
// python-escpos send).

/// The receipt an ESC/POS stream prints (by the library's reference decoder): raster rows
/// (1 = dot) in order, feeds as blank rows, and the heights of the `GS v 0` bands.
fn decode_escpos(data: &[u8]) -> (Bits, Vec<usize>, bool) {
    let r = escpos::decode(data).expect("ESC/POS decodes");
    let bits = Bits {
        width: r.bitmap.width,
        height: r.bitmap.height,
        data: r.bitmap.data,
    };
    (bits, r.bands, r.cut)
}

/// `want` widened to whole bytes (the width ESC/POS rasters carry).
fn byte_wide(want: &Bits) -> Bits {
    Bits {
        width: want.stride() * 8,
        ..want.clone()
    }
}

#[test]
fn escpos_tall_receipt_bands_exactly_and_matches_python_escpos() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 3,000 rows: more than three bands; the blank stretch becomes feeds.
    let input = picture(d, "receipt.png", 380, 3000, 5);
    let pbm = d.join("ref.pbm");
    convert(&input, &pbm, &["--dpi", "203"]);
    let want = byte_wide(&read_pbm(&pbm));
    let file = d.join("r.escpos");
    convert(
        &input,
        &file,
        &["--dpi", "203", "--paper-width", "384", "--cut"],
    );
    let ours = std::fs::read(&file).unwrap();
    let (got, bands, cut) = decode_escpos(&ours);
    assert_eq!(got, want);
    assert!(cut);
    assert!(
        bands.len() >= 3 && bands.iter().all(|&b| b <= 960),
        "{bands:?}"
    );
    assert!(
        ours.windows(2).any(|w| w == b"\x1bJ"),
        "blank rows are fed, not sent"
    );
    // Smaller bands on request.
    let small = d.join("s.escpos");
    convert(&input, &small, &["--dpi", "203", "--band-rows", "100"]);
    let (got, bands, _) = decode_escpos(&std::fs::read(&small).unwrap());
    assert_eq!(got, want);
    assert!(bands.iter().all(|&b| b <= 100));
    // Standard output carries the same bytes as the file.
    let piped = halftone()
        .arg("convert")
        .arg(&input)
        .args(["-o", "-", "--format", "escpos"])
        .args([
            "--method",
            "diffuse",
            "--kernel",
            "floyd-steinberg",
            "--levels",
            "2",
        ])
        .args(["--dpi", "203", "--paper-width", "384", "--cut"])
        .assert()
        .success();
    assert_eq!(piped.get_output().stdout, ours);
    // python-escpos's Dummy printer sends the same dots (in its own 960-row fragments).
    if let Some(py) = python() {
        let dummy = d.join("dummy.escpos");
        run(Process::new(py)
            .arg(script("escpos_dummy.py"))
            .arg(&pbm)
            .arg(&dummy));
        let theirs = std::fs::read(&dummy).unwrap();
        let (got, bands, _) = decode_escpos(&theirs);
        assert_eq!(got, want, "python-escpos");
        assert_eq!(bands, vec![960, 960, 960, 120]);
    }
}

#[test]
fn escpos_refuses_an_image_wider_than_the_head() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "wide.png", 600, 20, 1);
    let out = d.join("x.escpos");
    let assert = halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args([
            "--method",
            "threshold",
            "--preset",
            "thermal-203",
            "--width",
            "600",
        ])
        .assert()
        .code(1);
    let err = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("wider than the 384-dot print head") && err.contains("--width"),
        "{err}"
    );
    assert!(!out.exists());
    // The preset alone fits the head.
    halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--preset", "thermal-203"])
        .assert()
        .success();
    let (got, _, _) = decode_escpos(&std::fs::read(&out).unwrap());
    assert_eq!(got.width, 384);
    // `-o -` takes the preset's format: ESC/POS bytes on standard output.
    let piped = halftone()
        .arg("convert")
        .arg(&input)
        .args(["-o", "-", "--preset", "thermal-203"])
        .assert()
        .success();
    assert_eq!(piped.get_output().stdout, std::fs::read(&out).unwrap());
}

// ---------------------------------------------------------------------------------------
// ZPL through zebrafy.

/// A label decoded by the library's ZPL decoder, as a test bitmap.
fn zpl_bits(b: &lang::Bitmap) -> Bits {
    Bits {
        width: b.width,
        height: b.height,
        data: b.data.clone(),
    }
}

#[test]
fn zpl_decodes_exactly_in_zebrafy_in_both_encodings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 4×6 in label at 300 dpi: 1200 × 1800 dots, 270,000 bytes, so three fields.
    let input = picture(d, "label.png", 1200, 1800, 6);
    let pbm = d.join("ref.pbm");
    let common = ["--dpi", "300", "--method", "ordered", "--mask", "cluster-8"];
    halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&pbm)
        .args(common)
        .args(["--levels", "2"])
        .assert()
        .success();
    let want = read_pbm(&pbm);
    for enc in ["hex", "z64"] {
        let zpl = d.join(format!("label-{enc}.zpl"));
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&zpl)
            .args(common)
            .args(["--levels", "2", "--zpl-encoding", enc])
            .assert()
            .success();
        let text = std::fs::read_to_string(&zpl).unwrap();
        assert!(text.starts_with("^XA\n^PW1200\n^LL1800\n") && text.ends_with("^XZ\n"));
        let fields: Vec<usize> = text
            .match_indices("^GFA,")
            .map(|(i, _)| text[i + 5..].split(',').next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(fields.len(), 3, "{enc}: {fields:?}");
        assert!(fields.iter().all(|&n| n <= 99_999), "{fields:?}");
        assert_eq!(fields.iter().sum::<usize>(), 150 * 1800);
        let ours = zpl::decode(text.as_bytes()).expect("ZPL decodes");
        assert_eq!(ours.len(), 1);
        assert_eq!(zpl_bits(&ours[0]), want, "reference decoder, {enc}");
        if let Some(py) = python() {
            let got = run(Process::new(&py).arg(script("zpl_to_pbm.py")).arg(&zpl));
            assert_eq!(Bits::from_pbm(&got), want, "zebrafy, {enc}");
        }
    }
    // The library's own round trip on odd widths (row padding, `,` `!` `:` runs), and
    // zebrafy's reading of the same files where the venv is there.
    let py = python();
    {
        for (w, h) in [(1usize, 1usize), (13, 7), (203, 40)] {
            let mut ht = Halftone::new(w, h, 1, 2);
            for y in 0..h {
                for x in 0..w {
                    let v = (x * 7 + y * 3) % 11 < 5 || y % 4 == 1 || (y == 2 && x > w / 2);
                    ht.set(0, x, y, v as u8);
                }
            }
            for encoding in [ZplEncoding::Hex, ZplEncoding::Z64] {
                let mut opts = WriteOptions::new(Format::Zpl);
                opts.print = PrintOptions {
                    zpl_encoding: encoding,
                    ..PrintOptions::default()
                };
                let mut zpl = Vec::new();
                encode(&ht, &opts, Path::new("t.zpl"), &mut zpl).unwrap();
                let mut pbm = Vec::new();
                encode(
                    &ht,
                    &WriteOptions::new(Format::Pbm),
                    Path::new("t.pbm"),
                    &mut pbm,
                )
                .unwrap();
                let want = Bits::from_pbm(&pbm);
                let ours = zpl::decode(&zpl).expect("ZPL decodes");
                assert_eq!(
                    zpl_bits(&ours[0]),
                    want,
                    "reference decoder {w}x{h} {encoding:?}"
                );
                if let Some(py) = &py {
                    let path = d.join("t.zpl");
                    std::fs::write(&path, &zpl).unwrap();
                    let got = Bits::from_pbm(&run(Process::new(py)
                        .arg(script("zpl_to_pbm.py"))
                        .arg(&path)));
                    assert_eq!(got, want, "zebrafy {w}x{h} {encoding:?}");
                }
            }
        }
    }
}

#[test]
fn zpl_refuses_a_label_over_the_maximum_length() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // label-203 is 4×6 in: 812 dots wide, at most 1,218 long; this picture is 2,000.
    let input = picture(d, "long.png", 812, 2000, 1);
    let out = d.join("x.zpl");
    let assert = halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--preset", "label-203"])
        .assert()
        .code(1);
    let err = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("2000 dots long, over the printer's maximum of 1218"),
        "{err}"
    );
    assert!(!out.exists());
}

// ---------------------------------------------------------------------------------------
// Streaming: the bytes do not depend on how the rows are cut into bands.

#[test]
fn every_printer_format_writes_the_same_bytes_for_any_banding() {
    use halftone::io::page_encoder;
    use halftone::io::sink::{encode_halftone, Band, PageHeader};
    let (w, h) = (203usize, 5000usize);
    let mut ht = Halftone::new(w, h, 1, 2);
    for y in 0..h {
        for x in 0..w {
            // Texture, blank stretches (feeds, `,` runs) and repeated rows (`:`, delta rows).
            let blank = (1000..1400).contains(&y);
            let v = blank || (y / 3 % 50 == 7) || (x * 13 + y / 2 * 7) % 11 > 3;
            ht.set(0, x, y, v as u8);
        }
    }
    for format in [
        Format::Pdf,
        Format::Ps,
        Format::Pcl,
        Format::EscPos,
        Format::Zpl,
        Format::Pwg,
        Format::Urf,
        Format::CupsRaster,
    ] {
        let mut opts = WriteOptions::new(format);
        opts.dpi = Some(300.0);
        let whole = {
            let mut enc = page_encoder(&opts);
            let mut out = Vec::new();
            encode_halftone(enc.as_mut(), &ht, opts.dpi, &mut out).unwrap();
            enc.finish(&mut out).unwrap();
            out
        };
        for band_rows in [1usize, 7, 960, 961, 4999] {
            let mut enc = page_encoder(&opts);
            let mut out = Vec::new();
            enc.begin_page(&PageHeader::of(&ht, opts.dpi), &mut out)
                .unwrap();
            let mut y = 0;
            while y < h {
                let rows = band_rows.min(h - y);
                let planes = [&ht.planes[0][y * ht.stride..(y + rows) * ht.stride]];
                enc.write_rows(
                    &Band {
                        y,
                        rows,
                        planes: &planes,
                    },
                    &mut out,
                )
                .unwrap();
                y += rows;
            }
            enc.end_page(&mut out).unwrap();
            enc.finish(&mut out).unwrap();
            assert!(out == whole, "{format:?} in bands of {band_rows}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// --content auto on the sample receipt.

#[test]
fn content_auto_thresholds_the_receipts_text_and_diffuses_its_photo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let receipt = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/receipt/receipt.png");
    let make = |name: &str, args: &[&str]| {
        let out = d.join(name);
        halftone()
            .arg("convert")
            .arg(&receipt)
            .arg("-o")
            .arg(&out)
            .args(["--levels", "2", "--dpi", "203"])
            .args(args)
            .assert()
            .success();
        read_pbm(&out)
    };
    let auto = make(
        "auto.pbm",
        &[
            "--method",
            "diffuse",
            "--kernel",
            "atkinson",
            "--content",
            "auto",
        ],
    );
    let photo = make(
        "photo.pbm",
        &["--method", "diffuse", "--kernel", "atkinson"],
    );
    let line = make("line.pbm", &["--method", "threshold", "--threshold", "0.5"]);
    let art = make(
        "art.pbm",
        &[
            "--method",
            "diffuse",
            "--kernel",
            "atkinson",
            "--content",
            "line-art",
        ],
    );
    assert_eq!(art, line, "line-art is the 50% threshold");
    // The heading and the price list (rows 0..250) and the barcode (rows 560..660) are
    // line art: exactly the threshold. The photograph (rows 260..520) is diffused: far
    // from the threshold, and the same as diffusing everything away from its rim.
    let rows = |b: &Bits, y0: usize, y1: usize| b.crop(0, y0, b.width, y1 - y0);
    assert_eq!(rows(&auto, 0, 250), rows(&line, 0, 250));
    assert_eq!(rows(&auto, 560, 660), rows(&line, 560, 660));
    let differ = |a: &Bits, b: &Bits| {
        a.data
            .iter()
            .zip(&b.data)
            .map(|(x, y)| (x ^ y).count_ones())
            .sum::<u32>()
    };
    let (ap, lp, pp) = (
        rows(&auto, 300, 500),
        rows(&line, 300, 500),
        rows(&photo, 300, 500),
    );
    assert!(differ(&ap, &lp) > 5000, "the photo is halftoned");
    assert!(
        differ(&ap, &pp) < differ(&ap, &lp) / 10,
        "the photo is diffused as with photo content"
    );
}

#[test]
fn printer_flags_for_another_format_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = picture(d, "in.png", 40, 30, 1);
    for (out, flag) in [
        ("x.pdf", &["--cut"][..]),
        ("x.escpos", &["--page", "a4"][..]),
        ("x.pcl", &["--zpl-encoding", "z64"][..]),
    ] {
        let out = d.join(out);
        let assert = halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["--method", "threshold", "--dpi", "300"])
            .args(flag)
            .assert()
            .code(1);
        let err = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(flag[0]), "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn cmyk_screens_into_one_pdf_give_back_the_plate_files_through_tiffsep1() {
    if !have("gs") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/color-balls.png");
    let common = [
        "--method", "screen", "--color", "cmyk", "--dpi", "150", "--lpi", "30", "--width", "160",
    ];
    for out in ["poster.pdf", "poster.pbm"] {
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(d.join(out))
            .args(common)
            .assert()
            .success();
    }
    assert!(
        !d.join("poster-cyan.pdf").exists(),
        "a PDF holds the plates itself"
    );
    run(Process::new("gs")
        .args([
            "-q",
            "-dSAFER",
            "-dBATCH",
            "-dNOPAUSE",
            "-sDEVICE=tiffsep1",
            "-r150",
        ])
        .arg("-o")
        .arg(d.join("sep.tif"))
        .arg(d.join("poster.pdf")));
    let mut inked_total = 0usize;
    for ink in ["Cyan", "Magenta", "Yellow", "Black"] {
        let plate = read_pbm(&d.join(format!("poster-{}.pbm", ink.to_lowercase())));
        let sep = d.join(format!("sep({ink}).tif"));
        let img = image::open(&sep)
            .unwrap_or_else(|e| panic!("{}: {e}", sep.display()))
            .to_luma8();
        assert_eq!(
            (img.width() as usize, img.height() as usize),
            (plate.width, plate.height),
            "{ink}"
        );
        for y in 0..plate.height {
            for x in 0..plate.width {
                let inked = img.get_pixel(x as u32, y as u32)[0] < 128;
                assert_eq!(inked, plate.get(x, y), "{ink} plate at ({x},{y})");
                inked_total += inked as usize;
            }
        }
    }
    assert!(inked_total > 0, "the plates carry ink");
}
