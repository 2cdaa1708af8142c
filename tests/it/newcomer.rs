//! The first five minutes, on the real binary: defaults that give a good picture, files that
//! show the right tone in any viewer, sizes that fit, errors that teach, and the helpers
//! (completions, man page, contact sheet).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use assert_cmd::Command;

/// A real photograph from Debian's python-matplotlib-data (Grace Hopper, public domain;
/// 512×600 JPEG). `.ci/run` installs the package.
const PHOTO: &str = "/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg";

fn photo() -> Option<PathBuf> {
    let p = PathBuf::from(PHOTO);
    if p.exists() {
        return Some(p);
    }
    crate::common::skip(
        "newcomer (the photo checks)",
        &format!("{PHOTO} is missing (apt-get install python-matplotlib-data)"),
    );
    None
}

fn halftone() -> Command {
    Command::cargo_bin("halftone").unwrap()
}

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("samples")
        .join(name)
}

/// Runs `args`, expecting success; returns stdout.
fn ok(args: &[&std::ffi::OsStr]) -> String {
    let out = halftone().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "halftone {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Runs `args`, expecting exit status 1 and nothing on stdout; returns stderr.
fn fails(args: &[&str]) -> String {
    let out = halftone().args(args).output().unwrap();
    assert_eq!(out.status.code(), Some(1), "halftone {args:?} should fail");
    let e = String::from_utf8(out.stderr).unwrap();
    assert!(!e.contains("panicked"), "{e}");
    e
}

macro_rules! os {
    ($($a:expr),* $(,)?) => { &[$(std::ffi::OsStr::new($a)),*] };
}

/// `compare ORIGINAL HALFTONE --json`: (HVS-PSNR dB, tone bias).
fn compare(original: &Path, halftone: &Path) -> (f64, f64) {
    let json = ok(os![
        "compare",
        original.as_os_str(),
        halftone.as_os_str(),
        "--json"
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    (
        v["quality"]["hvs_psnr_db"].as_f64().unwrap(),
        v["quality"]["tone_bias"].as_f64().unwrap(),
    )
}

fn srgb_to_linear(c: u8) -> f64 {
    let v = c as f64 / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Mean linear luminance of a file decoded as plain sRGB by the `image` crate (no gAMA, no
/// metadata: what an ordinary viewer does).
fn mean_linear(path: &Path) -> f64 {
    let img = image::open(path).unwrap().to_rgb8();
    let n = (img.width() * img.height()) as f64;
    img.pixels()
        .map(|p| {
            0.2126 * srgb_to_linear(p[0])
                + 0.7152 * srgb_to_linear(p[1])
                + 0.0722 * srgb_to_linear(p[2])
        })
        .sum::<f64>()
        / n
}

#[test]
fn first_command_on_a_photograph_is_floyd_steinberg_quality() {
    let Some(photo) = photo() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("photo.pbm");
    // The README's first command, with a photograph in place of the shipped sample.
    ok(os!["convert", photo.as_os_str(), "-o", out.as_os_str()]);
    let (db, bias) = compare(&photo, &out);
    assert!(db >= 40.0, "default method: {db:.2} dB");
    assert!(bias.abs() < 0.01, "tone bias {bias}");
    // The old default, threshold, is far worse: the default really changed.
    let thr = dir.path().join("threshold.pbm");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        thr.as_os_str(),
        "--method",
        "threshold"
    ]);
    let (db_threshold, _) = compare(&photo, &thr);
    assert!(db_threshold < 30.0, "threshold: {db_threshold:.2} dB");
}

#[test]
fn four_level_defaults_show_the_right_tone_and_compare_reads_them() {
    let Some(photo) = photo() else { return };
    let want = mean_linear(&photo);
    let dir = tempfile::tempdir().unwrap();
    for name in ["four.png", "four.pgm"] {
        let out = dir.path().join(name);
        ok(os![
            "convert",
            photo.as_os_str(),
            "-o",
            out.as_os_str(),
            "--levels",
            "4"
        ]);
        let got = mean_linear(&out);
        assert!(
            (got - want).abs() < 0.01,
            "{name}: mean linear reflectance {got:.4} against the original's {want:.4}"
        );
        let (db, bias) = compare(&photo, &out);
        assert!(db >= 45.0, "{name}: compare reads {db:.2} dB");
        assert!(bias.abs() < 0.01, "{name}: tone bias {bias}");
    }
    // The PNG keeps its 2-bit size: indexed colour (type 3) at depth 2.
    let png = std::fs::read(dir.path().join("four.png")).unwrap();
    assert_eq!(&png[24..26], &[2, 3], "bit depth and colour type");
    // The PGM holds display codes at maxval 255.
    let pgm = std::fs::read(dir.path().join("four.pgm")).unwrap();
    assert!(pgm.starts_with(b"P5\n512 600\n255\n"), "{:?}", &pgm[..16]);

    // --device-levels keeps the level numbers for a device that wants them.
    let dev = dir.path().join("device.pgm");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        dev.as_os_str(),
        "--levels",
        "4",
        "--device-levels"
    ]);
    let pgm = std::fs::read(&dev).unwrap();
    assert!(pgm.starts_with(b"P5\n512 600\n3\n"), "{:?}", &pgm[..16]);
    assert!(pgm[14..].iter().all(|&v| v <= 3));
}

fn dimensions(path: &Path) -> (u32, u32) {
    image::image_dimensions(path).unwrap()
}

#[test]
fn fit_keeps_the_aspect_inside_the_box() {
    let Some(photo) = photo() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (sw, sh) = dimensions(&photo);
    assert!(sh > sw, "a portrait photo");
    let check = |(w, h): (u32, u32), (bw, bh): (u32, u32), (sw, sh): (u32, u32)| {
        assert!(w <= bw && h <= bh, "{w}x{h} outside {bw}x{bh}");
        assert!(
            w == bw || h == bh,
            "{w}x{h} does not touch the box {bw}x{bh}"
        );
        let exact_w = h as f64 * sw as f64 / sh as f64;
        assert!(
            (w as f64 - exact_w).abs() <= 1.0,
            "{w}x{h}: aspect of {sw}x{sh} lost"
        );
    };
    let out = dir.path().join("fit.png");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        out.as_os_str(),
        "--fit",
        "800x480"
    ]);
    check(dimensions(&out), (800, 480), (sw, sh));
    // Turned for the landscape panel: now as wide as the turned photo allows.
    let turned = dir.path().join("turned.png");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        turned.as_os_str(),
        "--fit",
        "800x480",
        "--rotate",
        "auto"
    ]);
    let (tw, th) = dimensions(&turned);
    assert!(tw > th, "turned to landscape: {tw}x{th}");
    check((tw, th), (800, 480), (sh, sw));
    // The e-ink preset fits its panel instead of growing a portrait photo to 800 wide.
    let eink = dir.path().join("eink.png");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        eink.as_os_str(),
        "--preset",
        "eink-4grey"
    ]);
    check(dimensions(&eink), (800, 480), (sw, sh));
    // --height alone keeps the aspect too.
    let tall = dir.path().join("tall.png");
    ok(os![
        "convert",
        photo.as_os_str(),
        "-o",
        tall.as_os_str(),
        "--height",
        "300"
    ]);
    check(dimensions(&tall), (10_000, 300), (sw, sh));
}

#[test]
fn absurd_sizes_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("raytrace.png");
    let out = dir.path().join("huge.pbm");
    for args in [
        &["--width", "1000000"][..],
        &["--height", "1000000"],
        &["--fit", "1000000x1000000"],
        &["--size", "1000in", "--dpi", "100000"],
        &["--width", "18446744073709551615"],
    ] {
        let start = Instant::now();
        let mut all = vec![
            "convert",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        all.extend_from_slice(args);
        // A value outside the flag's range is a usage error (2, from the option
        // table's parser); a size over the pixel limit is refused at run time (1).
        let run = halftone().args(&all).output().unwrap();
        let usage = args[1] == "18446744073709551615";
        assert_eq!(
            run.status.code(),
            Some(if usage { 2 } else { 1 }),
            "{args:?}"
        );
        let e = String::from_utf8(run.stderr).unwrap();
        assert!(!e.contains("panicked"), "{e}");
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "{args:?} took too long"
        );
        assert!(
            e.contains(args[0]) && (e.contains("max-pixels") || e.contains("too large")),
            "{args:?}: {e}"
        );
        assert!(!out.exists(), "nothing written");
    }
}

#[test]
fn unknown_names_list_the_valid_ones() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("raytrace.png");
    let input = input.to_str().unwrap();
    let out = dir.path().join("o.pbm");
    let out = out.to_str().unwrap();

    let e = fails(&["convert", input, "-o", out, "--kernel", "floyd"]);
    assert!(e.contains("did you mean 'floyd-steinberg'"), "{e}");
    assert!(e.contains("stucki") && e.contains("atkinson"), "{e}");
    assert!(!e.contains("No such file"), "{e}");

    let e = fails(&["convert", input, "-o", out, "--palette", "epaper-8"]);
    assert!(e.contains("epaper-7") && !e.contains("No such file"), "{e}");

    let e = fails(&[
        "convert", input, "-o", out, "--method", "ordered", "--mask", "bayer8",
    ]);
    assert!(e.contains("did you mean 'bayer-8'"), "{e}");

    let e = fails(&["convert", input, "-o", out, "--preset", "thermal"]);
    assert!(e.contains("thermal-203"), "{e}");

    let jpg = dir.path().join("o.jpg");
    let e = fails(&["convert", input, "-o", jpg.to_str().unwrap()]);
    assert!(
        e.contains(".jpg") && e.contains("pbm") && e.contains("png") && e.contains("tif"),
        "{e}"
    );
    assert!(!jpg.exists());

    // --format jpg lists the formats too (clap's own list).
    let out_png = dir.path().join("o.png");
    let run = halftone()
        .args([
            "convert",
            input,
            "-o",
            out_png.to_str().unwrap(),
            "--format",
            "jpg",
        ])
        .output()
        .unwrap();
    let e = String::from_utf8(run.stderr).unwrap();
    assert!(!run.status.success());
    assert!(e.contains("pbm") && e.contains("tiff"), "{e}");
}

#[test]
fn flags_the_method_or_format_ignores_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("raytrace.png");
    let input = input.to_str().unwrap();
    let pbm = dir.path().join("o.pbm");
    let pbm = pbm.to_str().unwrap();
    let png = dir.path().join("o.png");
    let png = png.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["-o", pbm, "--method", "diffuse", "--mask", "bayer-8"],
            "--mask",
        ),
        (&["-o", pbm, "--mask", "bayer-8"], "--mask"),
        (
            &["-o", pbm, "--method", "ordered", "--kernel", "stucki"],
            "--kernel",
        ),
        (
            &["-o", pbm, "--method", "ordered", "--strength", "0.8"],
            "--strength",
        ),
        (&["-o", pbm, "--maxval", "255"], "--maxval"),
        (&["-o", png, "--compression", "g4"], "--compression"),
        (&["-o", pbm, "--preset", "eink-4grey"], "preset"),
    ];
    for (args, flag) in cases {
        let mut all = vec!["convert", input];
        all.extend_from_slice(args);
        let e = fails(&all);
        assert!(e.contains(flag), "{args:?}: {e}");
    }
    assert!(!Path::new(pbm).exists() && !Path::new(png).exists());
    // The same flags with a method or format that uses them are fine.
    ok(os![
        "convert", input, "-o", pbm, "--method", "ordered", "--mask", "bayer-8"
    ]);
    ok(os![
        "convert",
        input,
        "-o",
        png,
        "--kernel",
        "stucki",
        "--strength",
        "0.9"
    ]);
}

#[test]
fn threshold_takes_a_fraction_a_percentage_or_a_code() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("raytrace.png");
    let run = |value: &str| {
        let out = dir
            .path()
            .join(format!("t-{}.pbm", value.replace('%', "pc")));
        ok(os![
            "convert",
            input.as_os_str(),
            "-o",
            out.as_os_str(),
            "--method",
            "threshold",
            "--threshold",
            value
        ]);
        std::fs::read(out).unwrap()
    };
    assert_eq!(run("0.5"), run("50%"));
    // Code 128 is sRGB 128, 21.6% of the light: the same cut as that fraction, darker
    // than half the light.
    let code = run("128");
    assert_eq!(code, run("0.2158605"));
    assert_ne!(code, run("0.5"));
    // A value out of range is a usage error (clap's exit status 2) that says the range.
    let run = halftone()
        .args(["convert", input.to_str().unwrap(), "-o"])
        .arg(dir.path().join("x.pbm"))
        .args(["--method", "threshold", "--threshold", "300"])
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    let e = String::from_utf8(run.stderr).unwrap();
    assert!(e.contains("0 to 255"), "{e}");
}

#[test]
fn completions_and_man_page() {
    let bash = ok(os!["completions", "bash"]);
    assert!(
        bash.contains("complete -F") && bash.contains("halftone"),
        "{bash}"
    );
    assert!(bash.contains("--fit") && bash.contains("sheet"));
    for shell in ["zsh", "fish", "powershell"] {
        assert!(
            ok(os!["completions", shell]).contains("halftone"),
            "{shell}"
        );
    }
    let man = ok(os!["man"]);
    assert!(
        man.contains(".TH halftone"),
        "{}",
        &man[..200.min(man.len())]
    );
    // Every subcommand's --help has examples.
    for sub in [
        "convert",
        "patterns",
        "batch",
        "masks",
        "compare",
        "bench",
        "render",
        "sheet",
        "completions",
        "man",
    ] {
        let help = ok(os![sub, "--help"]);
        assert!(help.contains("Example"), "{sub} --help has no examples");
    }
}

#[test]
fn sheet_writes_a_labelled_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sheet.png");
    let stdout = ok(os![
        "sheet",
        sample("raytrace.png").as_os_str(),
        "-o",
        out.as_os_str(),
        "--tile",
        "160"
    ]);
    assert!(
        stdout.contains("floyd") || stdout.contains("diffuse (default)"),
        "{stdout}"
    );
    let img = image::open(&out).unwrap().to_rgb8();
    // Ten crops (the original and nine methods) of 160 pixels, five a row.
    assert!(
        img.width() >= 5 * 200 && img.height() >= 2 * 160,
        "{}x{}",
        img.width(),
        img.height()
    );
    // The first crop of a halftone is pure black and white; the original's is not.
    let crop_colours = |x0: u32, y0: u32| {
        let mut seen = std::collections::BTreeSet::new();
        for y in y0..y0 + 150 {
            for x in x0..x0 + 150 {
                seen.insert(img.get_pixel(x, y)[0]);
            }
        }
        seen
    };
    assert!(crop_colours(12, 12).len() > 10, "original crop");
    let fs = crop_colours(12 + 210, 12);
    assert_eq!(fs, [0u8, 255].into_iter().collect(), "Floyd–Steinberg crop");
}
