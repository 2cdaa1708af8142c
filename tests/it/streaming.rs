//! The streaming pipeline gives the bytes of the whole-image path for every budget, thread
//! count, method and format.
//!
//! The reference is `tests/golden/out/`: outputs written by the whole-image code before the
//! pipeline existed (`tests/golden/make.sh`, cases in `tests/golden/cases.txt`). Every case
//! is run again through the binary at several budgets (tiny ones force bands of a few rows)
//! and with one and two threads; each run must give exactly those bytes, or, for work that
//! needs the whole image, a one-line error when the budget cannot hold it.

use std::path::{Path, PathBuf};
use std::process::Command;

use halftone::io::{Format, ReadOptions, WriteOptions};
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::method::ordered::Ordered;
use halftone::pipeline::{self, Job, MaxMemory};
use halftone::resize::SizeRequest;
use halftone::{ColorMode, Mask, Method, ToneOptions};

fn golden() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

struct Case {
    name: String,
    input: PathBuf,
    ext: String,
    args: Vec<String>,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(golden().join("cases.txt")).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut f = l.split_whitespace();
            let name = f.next().unwrap().to_string();
            let input = golden().join("inputs").join(f.next().unwrap());
            let ext = f.next().unwrap().to_string();
            Case {
                name,
                input,
                ext,
                args: f.map(String::from).collect(),
            }
        })
        .collect()
}

/// Cases that need the whole image: Riemersma's curve and resizing (palettes stream).
fn whole_only(c: &Case) -> bool {
    let a = c.args.join(" ");
    a.contains("riemersma") || a.contains("--width")
}

fn run(c: &Case, out: &Path, budget: Option<&str>, threads: usize) -> std::process::Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_halftone"));
    cmd.arg("convert").arg(&c.input).arg("-o").arg(out);
    cmd.args(&c.args);
    if let Some(b) = budget {
        cmd.args(["--max-memory", b]);
    }
    cmd.env("RAYON_NUM_THREADS", threads.to_string());
    cmd.output().unwrap()
}

#[test]
fn every_budget_and_thread_count_gives_the_golden_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (mut checked, mut too_small) = (0, 0);
    for c in cases() {
        let want = std::fs::read(golden().join("out").join(format!("{}.{}", c.name, c.ext)))
            .unwrap_or_else(|e| panic!("golden {}: {e}", c.name));
        for budget in [None, Some("6K"), Some("12K"), Some("40K"), Some("1G")] {
            for threads in [1, 2] {
                let out = dir.path().join(format!("{}.{}", c.name, c.ext));
                let _ = std::fs::remove_file(&out);
                let o = run(&c, &out, budget, threads);
                let what = format!("{} budget {budget:?} threads {threads}", c.name);
                let stderr = String::from_utf8_lossy(&o.stderr);
                if !o.status.success() {
                    // Only whole-image work may fail, and only for a small budget (or the
                    // smallest budget, too small for one band of the widest cases), with one
                    // line that says what to do.
                    // (A band holds at least one tile of the mask: 64 rows for blue-noise-64.)
                    let small = budget.is_some_and(|b| b.ends_with('K'));
                    let narrow = small && stderr.contains("too small");
                    assert!(whole_only(&c) && small || narrow, "{what}: {stderr}");
                    too_small += narrow as usize;
                    assert_eq!(stderr.lines().count(), 1, "{what}: {stderr}");
                    assert!(stderr.contains("--max-memory"), "{what}: {stderr}");
                    assert!(!out.exists(), "{what}: output left behind");
                    continue;
                }
                let got = std::fs::read(&out).unwrap();
                assert!(got == want, "{what}: bytes differ from the golden file");
                checked += 1;
            }
        }
    }
    assert!(checked > 300, "only {checked} runs compared");
    // Two bands are in flight at once (one read ahead, one written behind), so the 6K
    // budget cannot hold the widest cases; nor can 6K or 12K hold an AM screen's task
    // scratch (its 32 rows and their margin of located pixels, ~20 bytes a pixel): the
    // three screen cases at both budgets and thread counts are 12 of these runs. Palette
    // diffusion keeps 16 input rows for the next band's warm-up and a band's error rows for
    // each thread, which 12K cannot hold either: its four cases at both thread counts are 8.
    assert!(too_small <= 60, "{too_small} runs too small for one band");
}

#[test]
fn standard_input_streams_too() {
    let input = std::fs::read(golden().join("inputs/grey8.pgm")).unwrap();
    let want = std::fs::read(golden().join("out/fs-pbm.pbm")).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_halftone"));
    cmd.args([
        "convert",
        "-",
        "-o",
        "-",
        "--format",
        "pbm",
        "--method",
        "diffuse",
        "--max-memory",
        "4K",
    ]);
    let out = assert_cmd::Command::from_std(cmd)
        .write_stdin(input)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stdout == want,
        "stdin → stdout differs from the golden file"
    );
}

fn job<'a>(
    method: &'a dyn Method,
    tone: &'a ToneOptions,
    read: &'a ReadOptions,
    write: &'a WriteOptions,
    size: &'a SizeRequest<'a>,
    budget: MaxMemory,
) -> Job<'a> {
    Job {
        method,
        color: ColorMode::Gray,
        tone,
        read,
        size,
        write,
        max_memory: budget,
    }
}

#[test]
fn tiny_budgets_use_many_bands() {
    // The library call the CLI makes: a small budget streams in many bands, a large one
    // takes the whole image, and both give the golden bytes.
    let dir = tempfile::tempdir().unwrap();
    let input = golden().join("inputs/grey8.pgm");
    let (tone, read) = (ToneOptions::default(), ReadOptions::default());
    let write = WriteOptions::new(Format::Pbm);
    let fs = Diffuse::new("floyd-steinberg", DiffuseOptions::default()).unwrap();
    let ordered = Ordered::new(Mask::load("bayer-8", false).unwrap(), 2).unwrap();
    for (method, golden_name, small) in [
        (&fs as &dyn Method, "fs-pbm.pbm", 12000),
        (&ordered, "ord-pbm.pbm", 24000),
    ] {
        let want = std::fs::read(golden().join("out").join(golden_name)).unwrap();
        // A PNM input streams under the automatic budget too (reading overlaps halftoning);
        // a large explicit budget takes the whole image.
        for (budget, streamed) in [
            (MaxMemory::Bytes(small), true),
            (MaxMemory::Bytes(small + 3000), true),
            (MaxMemory::Bytes(1 << 30), false),
            (MaxMemory::Auto, true),
        ] {
            let out = dir.path().join("o.pbm");
            let size = SizeRequest::default();
            let job = job(method, &tone, &read, &write, &size, budget);
            let r = pipeline::convert(&input, &out, &job).unwrap();
            assert_eq!(r.streamed, streamed, "{golden_name} {budget:?}");
            if let (true, MaxMemory::Bytes(_)) = (streamed, budget) {
                assert!(r.bands >= 3, "{golden_name} {budget:?}: {} bands", r.bands);
                assert!(
                    r.estimate <= small + 3000,
                    "{golden_name}: estimate {}",
                    r.estimate
                );
                // Ordered bands start where the mask's rows restart.
                if golden_name.starts_with("ord") {
                    assert_eq!(r.band_rows % 8, 0);
                }
            }
            assert!(
                std::fs::read(&out).unwrap() == want,
                "{golden_name} {budget:?}"
            );
        }
    }
}

/// `halftone convert` of the golden grey input to `out` with `args` under `--max-memory`.
fn convert_grey8(out: &std::path::Path, args: &[&str], budget: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_halftone"))
        .arg("convert")
        .arg(golden().join("inputs/grey8.pgm"))
        .arg("-o")
        .arg(out)
        .args(args)
        .args(["--max-memory", budget])
        .output()
        .unwrap()
}

#[test]
fn whole_image_method_over_budget_is_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.pbm");
    let o = convert_grey8(
        &out,
        &["--method", "diffuse", "--kernel", "riemersma"],
        "4K",
    );
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(
        e.starts_with("halftone: ") && e.contains("grey8.pgm"),
        "{e}"
    );
    assert!(
        e.contains("whole image") && e.contains("--max-memory"),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn budget_too_small_for_one_band_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.pbm");
    let o = convert_grey8(&out, &["--method", "ordered", "--mask", "bayer-8"], "100");
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("too small"), "{e}");
    assert!(!out.exists());
}

#[test]
fn truncated_stream_is_an_error_not_made_up_rows() {
    // A greymap whose data stops part-way: streamed, the rows before the cut are encoded
    // already, but the file must not appear.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cut.pgm");
    let mut bytes = b"P5\n300 200\n255\n".to_vec();
    bytes.extend((0..300 * 150).map(|i| (i % 251) as u8));
    std::fs::write(&input, bytes).unwrap();
    let out = dir.path().join("o.pbm");
    let o = Command::new(env!("CARGO_BIN_EXE_halftone"))
        .arg("convert")
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--method", "diffuse", "--max-memory", "8K"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("cut.pgm") && e.contains("truncated"), "{e}");
    assert!(!out.exists());
}

#[test]
fn max_memory_sizes_parse() {
    assert_eq!(MaxMemory::parse("auto").unwrap(), MaxMemory::Auto);
    assert_eq!(MaxMemory::parse("64M").unwrap(), MaxMemory::Bytes(64 << 20));
    assert_eq!(MaxMemory::parse("2G").unwrap(), MaxMemory::Bytes(2 << 30));
    assert_eq!(
        MaxMemory::parse("64KiB").unwrap(),
        MaxMemory::Bytes(64 << 10)
    );
    assert_eq!(MaxMemory::parse("1.5k").unwrap(), MaxMemory::Bytes(1536));
    assert_eq!(MaxMemory::parse("5000").unwrap(), MaxMemory::Bytes(5000));
    for bad in ["", "M", "12Q", "-5M", "0"] {
        assert!(MaxMemory::parse(bad).is_err(), "{bad}");
    }
}
