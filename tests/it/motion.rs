//! Clips: what each method does over time, and the clip formats on the real binary.
//!
//! - A still clip gives identical frames for every method family (threshold, ordered
//!   masks, blue noise, screens, DBS, error diffusion both stable and frame by frame).
//! - Where one region of a clip changes, the masks keep every dot outside it (they stay
//!   put: a dot depends on its pixel alone), stable diffusion keeps every dot outside the
//!   region and its reach, and frame-by-frame diffusion does not (the failure stable
//!   diffusion is there to fix, measured so the test can tell them apart).
//! - Frame delays and loop counts survive a GIF round trip and a YUV4MPEG2 rate survives
//!   a stream round trip.
//! - A truncated GIF or YUV4MPEG2 stream is a one-line error naming the input, after the
//!   complete frames were written to an output that decodes.

use std::borrow::Cow;
use std::path::Path;

use halftone::motion::{ClipMethod, Temporal};
use halftone::{Halftone, Image, Options};

use crate::common::halftone;

/// A photo-like grey picture: a gradient, a ring and a fixed fine grain.
fn picture(w: usize, h: usize) -> Vec<u8> {
    let mut s = 0x2545_f491_u32;
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let (dx, dy) = (x - w as f64 * 0.6, y - h as f64 * 0.45);
            let ring = if (dx * dx + dy * dy).sqrt() % 14.0 < 5.0 {
                40.0
            } else {
                0.0
            };
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            let grain = (s % 9) as f64 - 4.0;
            (20.0 + 180.0 * x / w as f64 + ring + grain).clamp(0.0, 255.0) as u8
        })
        .collect()
}

fn options(pairs: &[(&str, &str)]) -> Options {
    let mut o = Options::default();
    for (k, v) in pairs {
        o.set(k, *v).unwrap();
    }
    o
}

/// A method family: its name and its options (among them its handling in time).
type Family = (&'static str, Vec<(&'static str, &'static str)>);

/// The method families, by their options.
fn families() -> Vec<Family> {
    vec![
        ("threshold", vec![("method", "threshold")]),
        (
            "threshold, 4 levels",
            vec![("method", "threshold"), ("levels", "4")],
        ),
        (
            "ordered bayer-8",
            vec![("method", "ordered"), ("mask", "bayer-8")],
        ),
        (
            "ordered blue-noise-64",
            vec![("method", "ordered"), ("mask", "blue-noise-64")],
        ),
        ("pattern", vec![("method", "pattern")]),
        ("screen", vec![("method", "screen")]),
        ("dbs", vec![("method", "dbs")]),
        ("diffuse stable", vec![("method", "diffuse")]),
        (
            "diffuse stable, 3 levels",
            vec![("method", "diffuse"), ("levels", "3")],
        ),
        (
            "diffuse stable, jarvis",
            vec![("method", "diffuse"), ("kernel", "jarvis-judice-ninke")],
        ),
        (
            "diffuse frame by frame",
            vec![("method", "diffuse"), ("temporal", "frame")],
        ),
    ]
}

/// Every method family gives the same halftone for every frame of a still clip.
#[test]
fn still_clip_gives_identical_frames_for_every_method() {
    let (w, h) = (72, 48);
    let pic = picture(w, h);
    for (name, pairs) in families() {
        let opts = options(&pairs);
        let mut m = ClipMethod::new(&opts).unwrap();
        let first = m.next(&Image::gray8(w, h, pic.clone())).unwrap();
        assert!(dots(&first) > 0, "{name}: an empty halftone proves nothing");
        for f in 1..5 {
            let next = m.next(&Image::gray8(w, h, pic.clone())).unwrap();
            assert_eq!(
                halftone::motion::changed_dots(&first, &next),
                0,
                "{name}: frame {f} differs from frame 0 of a still clip"
            );
        }
    }
}

/// Dots not at level 0.
fn dots(h: &Halftone) -> usize {
    (0..h.height)
        .flat_map(|y| (0..h.width).map(move |x| (x, y)))
        .filter(|&(x, y)| h.get(0, x, y) != 0)
        .count()
}

/// The dots that differ between two halftones, as (x, y).
fn moved(a: &Halftone, b: &Halftone) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for y in 0..a.height {
        for x in 0..a.width {
            if a.get(0, x, y) != b.get(0, x, y) {
                out.push((x, y));
            }
        }
    }
    out
}

/// One region changes (a patch brightens by 50 codes, the rest keeps its pixels, grain
/// and all): the masks keep every dot outside the patch, stable diffusion every dot outside
/// the patch and its reach, and frame-by-frame diffusion moves dots far from it.
#[test]
fn a_changed_region_leaves_the_rest_in_place() {
    let (w, h) = (160, 120);
    let pic = picture(w, h);
    let (x0, y0, x1, y1) = (70, 50, 90, 66);
    let mut changed = pic.clone();
    for y in y0..y1 {
        for x in x0..x1 {
            changed[y * w + x] = changed[y * w + x].saturating_add(50);
        }
    }
    let inside = |x: usize, y: usize, reach: usize| {
        x + reach >= x0 && x < x1 + reach && y + reach >= y0 && y < y1 + reach
    };
    for (name, pairs) in families() {
        if name == "dbs" || name == "screen" || name == "pattern" {
            continue; // whole-picture optimisation (DBS) and cells: below.
        }
        let opts = options(&pairs);
        let mut m = ClipMethod::new(&opts).unwrap();
        let a = m.next(&Image::gray8(w, h, pic.clone())).unwrap();
        let b = m.next(&Image::gray8(w, h, changed.clone())).unwrap();
        let moved = moved(&a, &b);
        assert!(!moved.is_empty(), "{name}: the change moved no dot");
        let far: Vec<_> = match (name.starts_with("diffuse"), opts.temporal) {
            // Masks: a dot depends on its pixel alone.
            (false, _) => moved.iter().filter(|&&(x, y)| !inside(x, y, 0)).collect(),
            // Stable diffusion: the eye box's radius (4 px at the default viewing) and
            // the kernel's reach (2 px for Jarvis).
            (true, Temporal::Stable) => moved.iter().filter(|&&(x, y)| !inside(x, y, 6)).collect(),
            (true, Temporal::Frame) => {
                let far = moved.iter().filter(|&&(x, y)| !inside(x, y, 6)).count();
                assert!(
                    far > 100,
                    "{name}: only {far} dots moved outside the patch (frame-by-frame diffusion \
                     should reroute the error downstream)"
                );
                continue;
            }
        };
        assert!(
            far.is_empty(),
            "{name}: {} dots outside the patch moved, the first {:?}",
            far.len(),
            &far[..far.len().min(5)]
        );
    }
    // Cells (pattern, screen): a dot depends on its cell, so the reach is a cell.
    for pairs in [vec![("method", "pattern")], vec![("method", "screen")]] {
        let opts = options(&pairs);
        let mut m = ClipMethod::new(&opts).unwrap();
        let a = m.next(&Image::gray8(w, h, pic.clone())).unwrap();
        let b = m.next(&Image::gray8(w, h, changed.clone())).unwrap();
        let mv = moved(&a, &b);
        assert!(!mv.is_empty(), "{pairs:?}: the change moved no dot");
        let far: Vec<_> = mv.iter().filter(|&&(x, y)| !inside(x, y, 16)).collect();
        assert!(
            far.is_empty(),
            "{pairs:?}: {} dots far from the patch moved",
            far.len()
        );
    }
}

/// A still clip through the binary: every frame of the y4m output is the same, for a mask
/// method and both kinds of diffusion.
#[test]
fn still_y4m_clip_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (64, 40);
    let pic = picture(w, h);
    let input = dir.path().join("still.y4m");
    std::fs::write(&input, y4m(w, h, &vec![pic; 6], (30, 1))).unwrap();
    for args in [
        &["-m", "ordered", "--mask", "blue-noise-64"][..],
        &["-m", "diffuse"][..],
        &["-m", "diffuse", "--temporal", "frame"][..],
    ] {
        let out = dir.path().join("out.y4m");
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(args)
            .assert()
            .success();
        let (frames, rate) = read_y4m(&std::fs::read(&out).unwrap());
        assert_eq!(rate, (30, 1), "{args:?}");
        assert_eq!(frames.len(), 6, "{args:?}");
        assert!(
            frames.iter().all(|f| f == &frames[0]),
            "{args:?}: frames differ"
        );
        assert!(frames[0].contains(&0) && frames[0].contains(&255));
    }
}

/// `bench --motion`: the clip methods' figures, a table and a chart; masks do not flicker
/// where the input holds still, stable diffusion flickers less than diffusion frame by frame.
#[test]
fn bench_motion_charts_flicker_against_accuracy() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (96, 64);
    let frames: Vec<Vec<u8>> = (0..6)
        .map(|i| {
            let mut f = picture(w, h);
            for y in 20..36 {
                for x in 10 + 5 * i..30 + 5 * i {
                    f[y * w + x] = 240;
                }
            }
            f
        })
        .collect();
    let input = dir.path().join("moving.y4m");
    std::fs::write(&input, y4m(w, h, &frames, (25, 1))).unwrap();
    let out = dir.path().join("results");
    let o = halftone()
        .args(["bench", "--motion"])
        .arg(&input)
        .args(["--methods", "ordered,diffuse", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| diffuse-stable |"));
    let csv = std::fs::read_to_string(out.join("motion.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let keys: Vec<&str> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(
        keys,
        [
            "ordered-bayer-8",
            "ordered-blue-noise-64",
            "diffuse-stable",
            "diffuse-frame",
            "diffuse-jarvis-stable"
        ]
    );
    let flicker = |k: &str| -> f64 {
        let r = rows.iter().find(|r| r[0] == k).unwrap();
        r[r.len() - 1].parse().unwrap()
    };
    assert_eq!(flicker("ordered-bayer-8"), 0.0);
    assert!(flicker("diffuse-stable") < flicker("diffuse-frame") / 2.0);
    let png = image::open(out.join("motion-chart.png")).unwrap();
    assert_eq!((png.width(), png.height()), (900, 600));
    assert!(std::fs::read_to_string(out.join("motion-chart.svg"))
        .unwrap()
        .contains("diffuse-stable"));
    // A method that is not a clip method is refused in one line.
    let o = halftone()
        .args(["bench", "--motion"])
        .arg(&input)
        .args(["--methods", "dbs", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("none of the clip methods") && err.lines().count() == 1,
        "{err}"
    );
}

/// A grey YUV4MPEG2 stream (mono, full range).
fn y4m(w: usize, h: usize, frames: &[Vec<u8>], rate: (u32, u32)) -> Vec<u8> {
    let mut out =
        format!("YUV4MPEG2 W{w} H{h} F{}:{} Ip A1:1 Cmono\n", rate.0, rate.1).into_bytes();
    for f in frames {
        out.extend_from_slice(b"FRAME\n");
        out.extend_from_slice(f);
    }
    out
}

/// The frames and rate of a mono YUV4MPEG2 stream (a reader of its own, independent of
/// the library's).
fn read_y4m(bytes: &[u8]) -> (Vec<Vec<u8>>, (u32, u32)) {
    let nl = bytes.iter().position(|&b| b == b'\n').unwrap();
    let header = std::str::from_utf8(&bytes[..nl]).unwrap();
    assert!(header.contains("Cmono"), "{header}");
    let field = |k: char| {
        header
            .split(' ')
            .find_map(|t| t.strip_prefix(k))
            .unwrap()
            .to_string()
    };
    let (w, h): (usize, usize) = (field('W').parse().unwrap(), field('H').parse().unwrap());
    let f = field('F');
    let (n, d) = f.split_once(':').unwrap();
    let mut at = nl + 1;
    let mut frames = Vec::new();
    while at < bytes.len() {
        assert_eq!(&bytes[at..at + 6], b"FRAME\n");
        at += 6;
        frames.push(bytes[at..at + w * h].to_vec());
        at += w * h;
    }
    (frames, (n.parse().unwrap(), d.parse().unwrap()))
}

/// An animated GIF of grey frames (a 256-grey palette), each with its delay in hundredths.
fn gif(w: usize, h: usize, frames: &[(Vec<u8>, u16)], repeat: gif::Repeat) -> Vec<u8> {
    let pal: Vec<u8> = (0..=255u8).flat_map(|g| [g, g, g]).collect();
    let mut out = Vec::new();
    {
        let mut enc = gif::Encoder::new(&mut out, w as u16, h as u16, &pal).unwrap();
        enc.set_repeat(repeat).unwrap();
        for (px, delay) in frames {
            let frame = gif::Frame {
                width: w as u16,
                height: h as u16,
                delay: *delay,
                buffer: Cow::Borrowed(px),
                ..gif::Frame::default()
            };
            enc.write_frame(&frame).unwrap();
        }
    }
    out
}

/// A GIF's frames composited (index 0/1 of a two-colour palette as 0/255), their
/// delays, and the repeat, through the `gif` crate alone.
fn read_gif(path: &Path) -> (Vec<Vec<u8>>, Vec<u16>, gif::Repeat) {
    let mut o = gif::DecodeOptions::new();
    o.set_color_output(gif::ColorOutput::RGBA);
    let mut d = o.read_info(std::fs::File::open(path).unwrap()).unwrap();
    let (w, h) = (d.width() as usize, d.height() as usize);
    let mut canvas = vec![255u8; w * h];
    let (mut frames, mut delays) = (Vec::new(), Vec::new());
    while let Some(f) = d.read_next_frame().unwrap() {
        let (l, t, fw) = (f.left as usize, f.top as usize, f.width as usize);
        for (i, p) in f.buffer.chunks_exact(4).enumerate() {
            if p[3] != 0 {
                canvas[(t + i / fw) * w + l + i % fw] = p[0];
            }
        }
        frames.push(canvas.clone());
        delays.push(f.delay);
    }
    (frames, delays, d.repeat())
}

/// Each frame `k` of a [`moving_bar`] clip, decoded, has its bar white at column `6k + 1`.
fn assert_bars(frames: &[Vec<u8>], w: usize, h: usize) {
    for (k, f) in frames.iter().enumerate() {
        assert!(
            (0..h).all(|y| f[y * w + k * 6 + 1] == 255),
            "frame {k}: no bar"
        );
    }
}

/// Distinct frames with distinct delays: a bar that moves.
fn moving_bar(w: usize, h: usize, n: usize) -> Vec<Vec<u8>> {
    (0..n)
        .map(|k| {
            let mut p = picture(w, h);
            for y in 0..h {
                for x in k * 6..k * 6 + 4 {
                    p[y * w + x] = 255;
                }
            }
            p
        })
        .collect()
}

/// Delays and loop counts survive a GIF to GIF conversion.
#[test]
fn gif_delays_and_loops_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (48, 32);
    let delays = [7u16, 20, 35, 3, 100];
    for repeat in [
        gif::Repeat::Infinite,
        gif::Repeat::Finite(2),
        gif::Repeat::Finite(0),
    ] {
        let frames: Vec<_> = moving_bar(w, h, 5).into_iter().zip(delays).collect();
        let input = dir.path().join("in.gif");
        std::fs::write(&input, gif(w, h, &frames, repeat)).unwrap();
        let out = dir.path().join("out.gif");
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["-m", "diffuse"])
            .assert()
            .success();
        let (got, got_delays, got_repeat) = read_gif(&out);
        assert_eq!(got.len(), 5, "{repeat:?}");
        assert_eq!(got_delays, delays, "{repeat:?}");
        assert_eq!(got_repeat, repeat);
        // The bar is white in the output where it is in the input.
        assert_bars(&got, w, h);
    }
}

/// Identical frames in a row are stored once with their delays summed.
#[test]
fn repeated_frames_become_delay() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (48, 32);
    let bars = moving_bar(w, h, 2);
    let frames = vec![
        (bars[0].clone(), 10),
        (bars[0].clone(), 15),
        (bars[1].clone(), 20),
        (bars[1].clone(), 5),
    ];
    let input = dir.path().join("in.gif");
    std::fs::write(&input, gif(w, h, &frames, gif::Repeat::Infinite)).unwrap();
    let out = dir.path().join("out.gif");
    halftone()
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["-m", "ordered"])
        .assert()
        .success();
    let (got, delays, _) = read_gif(&out);
    assert_eq!(got.len(), 2);
    assert_eq!(delays, [25, 25]);
}

/// A truncated clip: exit status 1, one line naming the input and the frames written, and
/// an output with those frames that decodes; no file left beside it.
fn truncated(input: &Path, out: &Path, frames: usize) {
    let run = halftone()
        .arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(["-m", "diffuse"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "a truncated clip succeeded");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(
        err.contains(&*input.display().to_string()),
        "no input named: {err}"
    );
    assert!(
        err.contains(&format!(
            "the {frames} complete frames before it were written"
        )),
        "{err}"
    );
    let left: Vec<_> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') || n.contains("tmp"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn truncated_gif_writes_the_complete_frames() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (48, 32);
    let frames: Vec<_> = moving_bar(w, h, 5).into_iter().map(|f| (f, 4)).collect();
    let bytes = gif(w, h, &frames, gif::Repeat::Infinite);
    // Cut in the middle of the fourth frame's data: find the fourth image descriptor.
    let starts: Vec<usize> = (0..bytes.len() - 10)
        .filter(|&i| bytes[i] == 0x2c && bytes[i + 5..i + 9] == [w as u8, 0, h as u8, 0])
        .collect();
    assert_eq!(starts.len(), 5, "image descriptors");
    let cut = starts[3] + (starts[4] - starts[3]) / 2;
    let input = dir.path().join("cut.gif");
    std::fs::write(&input, &bytes[..cut]).unwrap();
    let outdir = dir.path().join("out");
    std::fs::create_dir(&outdir).unwrap();
    let out = outdir.join("out.gif");
    truncated(&input, &out, 3);
    let (got, _, _) = read_gif(&out);
    assert_eq!(got.len(), 3);
    assert_bars(&got, w, h);
}

#[test]
fn truncated_y4m_writes_the_complete_frames() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (48, 32);
    let bytes = y4m(w, h, &moving_bar(w, h, 5), (25, 1));
    let input = dir.path().join("cut.y4m");
    std::fs::write(&input, &bytes[..bytes.len() - w * h / 2]).unwrap();
    let outdir = dir.path().join("out");
    std::fs::create_dir(&outdir).unwrap();
    for name in ["out.y4m", "out.gif"] {
        let out = outdir.join(name);
        truncated(&input, &out, 4);
        let frames = if name.ends_with("y4m") {
            read_y4m(&std::fs::read(&out).unwrap()).0
        } else {
            read_gif(&out).0
        };
        assert_eq!(frames.len(), 4, "{name}");
    }
    // From a pipe to a pipe: the complete frames on standard output, the error after.
    let run = halftone()
        .args(["convert", "-", "-o", "-", "-f", "y4m"])
        .write_stdin(bytes[..bytes.len() - 10].to_vec())
        .output()
        .unwrap();
    assert!(!run.status.success());
    assert_eq!(read_y4m(&run.stdout).0.len(), 4);
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("<stdin>") && err.contains("truncated in frame 5"),
        "{err}"
    );
}

/// Delays and loop counts survive GIF to APNG, read back by the `image` crate's decoder;
/// each frame after the first is stored as the rectangle that changed.
#[test]
fn apng_delays_and_loops_round_trip() {
    use image::AnimationDecoder;
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (48, 32);
    let delays = [7u16, 20, 35, 3, 100];
    for (repeat, loops) in [
        (gif::Repeat::Infinite, None),
        (gif::Repeat::Finite(2), Some(3)),
    ] {
        let frames: Vec<_> = moving_bar(w, h, 5).into_iter().zip(delays).collect();
        let input = dir.path().join("in.gif");
        std::fs::write(&input, gif(w, h, &frames, repeat)).unwrap();
        let out = dir.path().join("out.apng");
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["-m", "diffuse"])
            .assert()
            .success();
        let bytes = std::fs::read(&out).unwrap();
        let dec = image::codecs::png::PngDecoder::new(std::io::Cursor::new(&bytes)).unwrap();
        assert!(dec.is_apng().unwrap());
        let apng = dec.apng().unwrap();
        let plays = match apng.loop_count() {
            image::metadata::LoopCount::Infinite => None,
            image::metadata::LoopCount::Finite(n) => Some(n.get()),
        };
        assert_eq!(plays, loops);
        let got: Vec<image::Frame> = apng.into_frames().collect_frames().unwrap();
        assert_eq!(got.len(), 5);
        for (k, f) in got.iter().enumerate() {
            let (n, d) = f.delay().numer_denom_ms();
            assert_eq!(n as f64 / d as f64, delays[k] as f64 * 10.0, "frame {k}");
            let buf = f.buffer();
            assert!((0..h).all(|y| buf.get_pixel((k * 6 + 1) as u32, y as u32).0 == [255; 4]));
            assert!(buf
                .pixels()
                .all(|p| p.0[3] == 255 && (p.0[0] == 0 || p.0[0] == 255)));
        }
        // The frames after the first are stored cropped: fewer bytes than five whole frames.
        let fctl = bytes.windows(4).filter(|c| c == b"fcTL").count();
        assert_eq!(fctl, 5);
    }
}

/// `compare --clip`: a mask method has no flicker at all where the input stays (noise 0),
/// stable diffusion has less than a tenth of frame-by-frame diffusion's, and the figures
/// come as JSON.
#[test]
fn compare_clip_measures_flicker() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (96, 64);
    let input = dir.path().join("bar.y4m");
    std::fs::write(&input, y4m(w, h, &moving_bar(w, h, 8), (25, 1))).unwrap();
    let mut flicker = Vec::new();
    for (name, args) in [
        ("ordered", &["-m", "ordered", "--mask", "blue-noise-64"][..]),
        ("stable", &["-m", "diffuse"][..]),
        ("frame", &["-m", "diffuse", "--temporal", "frame"][..]),
    ] {
        let out = dir.path().join(format!("{name}.gif"));
        halftone()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(args)
            .assert()
            .success();
        let run = halftone()
            .args(["compare", "--clip", "--noise", "0", "--json"])
            .arg(&input)
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let j: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(j["frames"], 8, "{name}");
        assert_eq!(j["hvs_psnr_db"].as_array().unwrap().len(), 8, "{name}");
        assert!(
            j["hvs_psnr_db_mean"].as_f64().unwrap() > 15.0,
            "{name}: {j}"
        );
        assert!(j["still_pixels"].as_u64().unwrap() > (7 * w * h / 2) as u64);
        flicker.push(j["flicker"].as_f64().unwrap());
    }
    assert_eq!(
        flicker[0], 0.0,
        "a mask's dots moved where the input stayed"
    );
    assert!(
        flicker[2] > 0.01,
        "frame-by-frame diffusion: flicker {}",
        flicker[2]
    );
    assert!(
        flicker[1] <= flicker[2] / 10.0,
        "stable {} against frame {}",
        flicker[1],
        flicker[2]
    );
}
