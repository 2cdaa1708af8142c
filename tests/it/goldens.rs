//! The golden outputs (`tests/golden/out`, which `streaming` holds every budget and thread
//! count to) read back by two decoders nobody here wrote: netpbm and Pillow. Both must read
//! every file and agree on its size and every sample; and the threshold cases must be the
//! threshold of their input, computed here from netpbm's reading of the input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::common::{have_tool, skip};

/// An image as plain numbers: `channels` samples a pixel, 0 = black, `maxval` = white.
#[derive(Debug)]
struct Plain {
    width: usize,
    height: usize,
    channels: usize,
    maxval: u32,
    samples: Vec<u32>,
}

fn golden(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(dir)
}

/// Runs `cmd` with `input` on its standard input; its standard output, which must be a
/// success.
fn pipe(cmd: &mut Command, input: &[u8]) -> Vec<u8> {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let input = input.to_vec();
    let feeder = std::thread::spawn(move || stdin.write_all(&input));
    let out = child.wait_with_output().unwrap();
    feeder.join().unwrap().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// netpbm's reading of `path` (by its extension), written out as plain PNM by
/// `pnmtoplainpnm` and parsed here.
fn netpbm(path: &Path) -> Plain {
    let ext = path.extension().unwrap().to_str().unwrap();
    let bytes = std::fs::read(path).unwrap();
    let pnm = match ext {
        "png" => pipe(&mut Command::new("pngtopnm"), &bytes),
        "tif" => pipe(&mut Command::new("tifftopnm"), &bytes),
        "bmp" => pipe(&mut Command::new("bmptopnm"), &bytes),
        "pbm" | "pgm" | "ppm" => bytes,
        other => panic!("{other}: no netpbm reader named"),
    };
    let text =
        String::from_utf8_lossy(&pipe(&mut Command::new("pnmtoplainpnm"), &pnm)).into_owned();
    let mut words = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .flat_map(str::split_whitespace);
    let magic = words.next().unwrap();
    let mut num = || -> u32 { words.next().unwrap().parse().unwrap() };
    let (width, height) = (num() as usize, num() as usize);
    let (channels, maxval) = match magic {
        "P1" => (1, 1),
        "P2" => (1, num()),
        "P3" => (3, num()),
        m => panic!("{}: pnmtoplainpnm wrote {m}", path.display()),
    };
    let samples: Vec<u32> = if magic == "P1" {
        // Bits may run together without spaces; in a bitmap 1 is ink.
        words
            .flat_map(str::chars)
            .take(width * height)
            .map(|c| 1 - c.to_digit(2).unwrap())
            .collect()
    } else {
        (0..width * height * channels).map(|_| num()).collect()
    };
    Plain {
        width,
        height,
        channels,
        maxval,
        samples,
    }
}

/// Pillow's reading of `path`: bitmaps as 8-bit grey, palettes as RGB.
const PILLOW: &str = r#"
import sys
from PIL import Image
im = Image.open(sys.argv[1])
im.load()
if im.mode == "1":
    im = im.convert("L")
if im.mode == "P":
    im = im.convert("RGB")
if im.mode in ("I;16", "I;16B", "I;16L", "I"):
    ch, maxval, data = 1, 65535, list(im.getdata())
elif im.mode == "L":
    ch, maxval, data = 1, 255, list(im.getdata())
elif im.mode == "RGB":
    ch, maxval, data = 3, 255, [v for px in im.getdata() for v in px]
else:
    sys.exit("mode " + im.mode)
print(im.width, im.height, ch, maxval)
print(" ".join(map(str, data)))
"#;

fn pillow(python: &Path, path: &Path) -> Plain {
    let out = Command::new(python)
        .args(["-c", PILLOW])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "Pillow on {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut words = text.split_whitespace().map(|w| w.parse::<u32>().unwrap());
    let mut num = || words.next().unwrap();
    let (width, height, channels, maxval) = (num() as usize, num() as usize, num() as usize, num());
    let samples = (0..width * height * channels).map(|_| num()).collect();
    Plain {
        width,
        height,
        channels,
        maxval,
        samples,
    }
}

/// The Python with Pillow: `HALFTONE_PILLOW_PYTHON`, or Debian's (python3-pil).
fn pillow_python(check: &str) -> Option<PathBuf> {
    let p = std::env::var_os("HALFTONE_PILLOW_PYTHON")
        .map_or_else(|| PathBuf::from("/usr/bin/python3"), PathBuf::from);
    let ok = Command::new(&p)
        .args(["-c", "import PIL"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        skip(
            check,
            &format!(
                "{} has no Pillow (apt-get install python3-pil)",
                p.display()
            ),
        );
        return None;
    }
    Some(p)
}

/// Whether `a` and `b` hold the same samples: equal as fractions of white, to within half
/// a step of the finer of the two scales (a reader may rescale 3 levels to 0..255).
fn same(a: &Plain, b: &Plain) -> Result<(), String> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(format!(
            "{}x{} against {}x{}",
            a.width, a.height, b.width, b.height
        ));
    }
    // A grey image read as RGB by one of them: compare each pixel's three samples.
    let grey = |p: &Plain, i: usize, c: usize| p.samples[i * p.channels + c.min(p.channels - 1)];
    let channels = a.channels.max(b.channels);
    let tol = 0.5 / a.maxval.max(b.maxval) as f64 + 1e-9;
    for i in 0..a.width * a.height {
        for c in 0..channels {
            let (x, y) = (
                grey(a, i, c) as f64 / a.maxval as f64,
                grey(b, i, c) as f64 / b.maxval as f64,
            );
            if (x - y).abs() > tol {
                return Err(format!(
                    "pixel {i} channel {c}: {}/{} against {}/{}",
                    grey(a, i, c),
                    a.maxval,
                    grey(b, i, c),
                    b.maxval
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn goldens_read_the_same_in_netpbm_and_pillow() {
    let check = "goldens::goldens_read_the_same_in_netpbm_and_pillow";
    let tools = ["pngtopnm", "tifftopnm", "bmptopnm", "pnmtoplainpnm"];
    if !tools.iter().all(|t| have_tool(t, "netpbm", check)) {
        return;
    }
    let Some(python) = pillow_python(check) else {
        return;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(golden("out"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 50, "{} golden files", files.len());
    let mut differ = Vec::new();
    for f in &files {
        let (a, b) = (netpbm(f), pillow(&python, f));
        if let Err(e) = same(&a, &b) {
            differ.push(format!("{}: {e}", f.display()));
        }
    }
    assert!(differ.is_empty(), "{differ:#?}");
}

/// sRGB code to linear light (IEC 61966-2-1).
fn linear(code: u32, maxval: u32) -> f64 {
    let v = code as f64 / maxval as f64;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

#[test]
fn threshold_goldens_are_the_threshold_of_their_input() {
    let check = "goldens::threshold_goldens_are_the_threshold_of_their_input";
    if !have_tool("pnmtoplainpnm", "netpbm", check) {
        return;
    }
    // `--method threshold` (0.5 of linear light): paper where the input is at least half
    // as light as paper.
    for (out, input) in [
        ("thr-pbm.pbm", "grey8.pgm"),
        ("thr-200.pbm", "grey200.pgm"),
        ("thr-bitmap.pbm", "bitmap.pbm"),
    ] {
        let (got, src) = (
            netpbm(&golden("out").join(out)),
            netpbm(&golden("inputs").join(input)),
        );
        assert_eq!((got.width, got.height), (src.width, src.height), "{out}");
        let want: Vec<u32> = src
            .samples
            .iter()
            .map(|&v| (linear(v, src.maxval) >= 0.5) as u32)
            .collect();
        assert_eq!(got.maxval, 1, "{out}");
        let wrong = want
            .iter()
            .zip(&got.samples)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(wrong, 0, "{out}: {wrong} pixels differ from the threshold");
        assert!(want.contains(&0) && want.contains(&1), "{out}: flat");
    }
}
