//! `--icc FILE`: CMYK separation through a vendor's ICC output profile (Little CMS).
//!
//! The profile used is Ghostscript's `default_cmyk.icc` (Artifex's SWOP-like coated CMYK
//! output profile, in Debian's `libgs-common`, which `.ci/run` installs with ghostscript).

use std::path::{Path, PathBuf};
use std::process::Command;

use halftone::press::icc::{IccProfile, RenderingIntent};
use halftone::press::{delta_e76, srgb8_to_lab, Press, COLORCHECKER};

/// Ghostscript's CMYK output profile; `None` (with a note) where ghostscript is missing,
/// but CI installs it, so there the test must run.
fn cmyk_profile() -> Option<PathBuf> {
    let mut found: Vec<PathBuf> =
        glob::glob("/usr/share/ghostscript/*/iccprofiles/default_cmyk.icc")
            .unwrap()
            .chain(glob::glob("/usr/share/color/icc/ghostscript/default_cmyk.icc").unwrap())
            .filter_map(Result::ok)
            .collect();
    found.sort();
    let p = found.pop();
    if p.is_none() {
        crate::common::skip(
            "screens_icc (the ICC profile checks)",
            "no default_cmyk.icc (apt-get install ghostscript)",
        );
    }
    p
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_halftone"))
}

#[test]
fn the_profile_table_reproduces_colorchecker_through_the_profile() {
    let Some(path) = cmyk_profile() else { return };
    let icc = IccProfile::load(&path).unwrap();
    let sep = icc.separation(RenderingIntent::Relative).unwrap();
    let cmyk: Vec<[f64; 4]> = COLORCHECKER.iter().map(|&c| sep.cmyk(c)).collect();
    let printed = icc.lab(&cmyk).unwrap();
    let fogra39 = Press::load("fogra39").unwrap();
    let (mut sum, mut sum_fogra, mut n) = (0.0, 0.0, 0);
    for (i, &c) in COLORCHECKER.iter().enumerate() {
        let want = srgb8_to_lab(c);
        let de = delta_e76(printed[i], want);
        // The profile's own round trip (B2A then A2B) is poor out of its gamut: judge the
        // table on the colours the profile reproduces.
        if de < 5.0 {
            sum += de;
            sum_fogra += delta_e76(fogra39.lab(cmyk[i]), want);
            n += 1;
        }
    }
    let mean = sum / n as f64;
    eprintln!(
        "{}: {n} of 24 ColorChecker colours within its gamut; through the profile mean ΔE76 \
         {mean:.2}; the same plates printed through the FOGRA39 model {:.2}",
        icc.description(),
        sum_fogra / n as f64
    );
    assert!(n >= 18, "only {n} colours reproduced");
    // The 17³ table and its trilinear lookup cost little against the profile itself.
    assert!(mean < 2.0, "mean ΔE76 {mean}");
    // Inks are inks: all in 0..1, and black carries the darkest neutral.
    assert!(cmyk.iter().flatten().all(|v| (0.0..=1.0).contains(v)));
    assert!(
        cmyk[23][3] > 0.5,
        "black on the darkest grey: {:?}",
        cmyk[23]
    );
}

#[test]
fn every_intent_builds_a_table() {
    let Some(path) = cmyk_profile() else { return };
    let icc = IccProfile::load(&path).unwrap();
    let rel = icc.separation(RenderingIntent::Relative).unwrap();
    for intent in [
        RenderingIntent::Perceptual,
        RenderingIntent::Saturation,
        RenderingIntent::Absolute,
    ] {
        let sep = icc.separation(intent).unwrap();
        let mut worst = 0.0f64;
        for rgb in COLORCHECKER
            .iter()
            .copied()
            .chain([[0, 0, 255], [255, 255, 255]])
        {
            let (a, b) = (rel.cmyk(rgb), sep.cmyk(rgb));
            assert!(
                b.iter().all(|v| (0.0..=1.0).contains(v)),
                "{intent:?} {rgb:?}"
            );
            worst = worst.max((0..4).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max));
        }
        eprintln!("{intent:?}: largest ink difference from relative {worst:.4}");
        // The profile points all three intents' tags at one table (B2A0 = B2A1 = B2A2):
        // perceptual and saturation give relative's inks; absolute colorimetric keeps the
        // paper's colour (its white point is not D50), so it inks even white (0.141
        // measured). An intent that is dropped or swapped on the way to Little CMS shows
        // here.
        let (low, high) = match intent {
            RenderingIntent::Absolute => (0.11, 0.17),
            _ => (0.0, 1e-3),
        };
        assert!(
            (low..=high).contains(&worst),
            "{intent:?}: largest ink difference from relative {worst}, expected {low} to {high}"
        );
    }
    // Relative colorimetric: paper is paper.
    let white = rel.cmyk([255, 255, 255]);
    assert!(white.iter().all(|&v| v < 0.002), "ink on white: {white:?}");
}

/// Ink coverage of a P4 PBM's `side²` patch at `(x0, y0)`, and the width.
fn pbm_patch(bytes: &[u8], x0: usize, y0: usize, side: usize) -> f64 {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]).to_string();
    let mut it = text.split_ascii_whitespace();
    assert_eq!(it.next(), Some("P4"));
    let w: usize = it.next().unwrap().parse().unwrap();
    let h: usize = it.next().unwrap().parse().unwrap();
    let stride = w.div_ceil(8);
    let data = &bytes[bytes.len() - stride * h..];
    let mut ink = 0usize;
    for y in y0..y0 + side {
        for x in x0..x0 + side {
            ink += ((data[y * stride + x / 8] >> (7 - x % 8)) & 1) as usize;
        }
    }
    ink as f64 / (side * side) as f64
}

#[test]
fn icc_plates_carry_the_profiles_separation() {
    let Some(path) = cmyk_profile() else { return };
    let icc = IccProfile::load(&path).unwrap();
    let sep = icc.separation(RenderingIntent::Relative).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // Three 128-pixel patches: a skin tone, a blue, a mid grey.
    let colours = [COLORCHECKER[1], COLORCHECKER[2], COLORCHECKER[21]];
    let p = 128;
    let mut img = image::RgbImage::new((3 * p) as u32, p as u32);
    for (x, _, px) in img.enumerate_pixels_mut() {
        *px = image::Rgb(colours[x as usize / p]);
    }
    let input = dir.path().join("patches.png");
    img.save(&input).unwrap();
    let out = dir.path().join("sep.pbm");
    let preview = dir.path().join("preview.png");
    let o = bin()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "screen", "--color", "cmyk", "--dpi", "600"])
        .arg("--icc")
        .arg(&path)
        .arg("--preview")
        .arg(&preview)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (k, ink) in ["cyan", "magenta", "yellow", "black"].iter().enumerate() {
        let bytes = std::fs::read(dir.path().join(format!("sep-{ink}.pbm"))).unwrap();
        for (i, &c) in colours.iter().enumerate() {
            let got = pbm_patch(&bytes, i * p + 16, 16, p - 32);
            let want = sep.cmyk(c)[k];
            assert!(
                (got - want).abs() < 0.01,
                "{ink} on colour {i}: plate {got:.4}, profile {want:.4}"
            );
        }
    }
    // The preview prints the plates through the profile: each patch's centre is close to
    // its colour (the screen averaged over two periods a preview pixel).
    let prev = image::open(&preview).unwrap().to_rgb8();
    for (i, &c) in colours.iter().enumerate() {
        let sx = prev.width() as f64 / (3 * p) as f64;
        let px = prev.get_pixel(((i * p + p / 2) as f64 * sx) as u32, prev.height() / 2);
        let de = delta_e76(srgb8_to_lab(px.0), srgb8_to_lab(c));
        assert!(de < 4.0, "preview of colour {i}: ΔE76 {de:.2}");
    }
}

fn fails(args: &[&std::ffi::OsStr]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    image::RgbImage::from_pixel(8, 8, image::Rgb([200, 100, 50]))
        .save(&input)
        .unwrap();
    let out = dir.path().join("o.pbm");
    let o = bin()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "screen", "--color", "cmyk"])
        .args(args)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{args:?}");
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.starts_with("halftone: "), "{e}");
    assert!(
        !dir.path().join("o-cyan.pbm").exists(),
        "{args:?}: plates written"
    );
    e
}

#[test]
fn wrong_profiles_and_flags_are_one_line() {
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    // An RGB display profile: Little CMS's built-in sRGB, saved by Pillow's ImageCms
    // (tests/data/README.md).
    let dir = tempfile::tempdir().unwrap();
    let rgb = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/srgb-lcms2.icc");
    let e = fails(&[os("--icc"), rgb.as_os_str()]);
    assert!(
        e.contains("srgb-lcms2.icc") && e.contains("not a CMYK output profile"),
        "{e}"
    );
    let junk = dir.path().join("junk.icc");
    std::fs::write(&junk, vec![7u8; 500]).unwrap();
    let e = fails(&[os("--icc"), junk.as_os_str()]);
    assert!(
        e.contains("junk.icc") && e.contains("not an ICC profile"),
        "{e}"
    );
    let missing = dir.path().join("missing.icc");
    let e = fails(&[os("--icc"), missing.as_os_str()]);
    assert!(e.contains("missing.icc"), "{e}");
    if let Some(p) = cmyk_profile() {
        for flag in [["--gcr", "80"], ["--tac", "260"], ["--press", "tr002"]] {
            let e = fails(&[os("--icc"), p.as_os_str(), os(flag[0]), os(flag[1])]);
            assert!(e.contains(flag[0]) && e.contains("--icc"), "{e}");
        }
    }
}
