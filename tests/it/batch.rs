//! `halftone batch` end to end: 200 generated images of mixed formats, three of them broken.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use assert_cmd::Command;

fn halftone() -> Command {
    Command::cargo_bin("halftone").unwrap()
}

/// Writes 200 small images in six formats under `dir` (some in a subfolder with spaces and
/// non-ASCII characters); three are broken. Returns the relative paths of the good ones.
fn make_inputs(dir: &Path) -> Vec<PathBuf> {
    let formats = [
        ("png", image::ImageFormat::Png),
        ("jpg", image::ImageFormat::Jpeg),
        ("bmp", image::ImageFormat::Bmp),
        ("pgm", image::ImageFormat::Pnm),
        ("tif", image::ImageFormat::Tiff),
        ("gif", image::ImageFormat::Gif),
    ];
    let mut good = Vec::new();
    for i in 0..200usize {
        let (ext, fmt) = formats[i % formats.len()];
        let rel = if i % 4 == 0 {
            PathBuf::from(format!("sub dir/ñandú {i:03}.{ext}"))
        } else {
            PathBuf::from(format!("img {i:03}.{ext}"))
        };
        let path = dir.join(&rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        match i {
            17 => std::fs::write(&path, b"").unwrap(), // empty
            88 => std::fs::write(&path, b"this is a text file, not a picture\n").unwrap(),
            150 => {
                // A truncated PNG (its extension is .png for i % 6 == 0).
                let img =
                    image::GrayImage::from_fn(32, 32, |x, y| image::Luma([(x * 8 + y) as u8]));
                let mut buf = std::io::Cursor::new(Vec::new());
                img.write_to(&mut buf, image::ImageFormat::Png).unwrap();
                std::fs::write(&path, &buf.get_ref()[..buf.get_ref().len() / 2]).unwrap();
            }
            _ => {
                let img = image::RgbImage::from_fn(24, 16, |x, y| {
                    image::Rgb([(x * 10) as u8, (y * 15) as u8, (i % 256) as u8])
                });
                let dynamic = if ext == "pgm" {
                    image::DynamicImage::ImageLuma8(image::DynamicImage::ImageRgb8(img).to_luma8())
                } else {
                    image::DynamicImage::ImageRgb8(img)
                };
                dynamic.save_with_format(&path, fmt).unwrap();
                good.push(rel);
            }
        }
    }
    good
}

fn files_under(dir: &Path) -> BTreeSet<PathBuf> {
    walkdir::WalkDir::new(dir)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file())
        .map(|e| e.path().strip_prefix(dir).unwrap().to_path_buf())
        .collect()
}

#[test]
fn two_hundred_files_three_broken() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let out = tmp.path().join("out");
    let good = make_inputs(&input);
    assert_eq!(good.len(), 197);
    let report = tmp.path().join("report.jsonl");
    let assert = halftone()
        .args([
            "batch",
            "--recursive",
            "--format",
            "pbm",
            "--method",
            "ordered",
            "--jobs",
            "2",
        ])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .arg("--report")
        .arg(&report)
        .assert()
        .code(3);
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).into_owned();
    assert!(
        stderr.contains("197 done, 0 skipped, 3 failed (3 inputs rejected, 0 errors)"),
        "{stderr}"
    );
    for broken in ["img 017.gif", "sub dir/ñandú 088.tif", "img 150.png"] {
        assert!(
            stderr.contains(&format!("failed: {}", input.join(broken).display())),
            "summary names {broken}: {stderr}"
        );
    }
    assert!(!stderr.contains("panicked"));

    // Exactly the good inputs' outputs, mirrored, with the new extension; no temp files.
    let expected: BTreeSet<PathBuf> = good.iter().map(|p| p.with_extension("pbm")).collect();
    assert_eq!(files_under(&out), expected);
    for p in &expected {
        let img = image::open(out.join(p)).expect("every output decodes");
        assert_eq!((img.width(), img.height()), (24, 16));
    }

    // The report has a line per file with its status.
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&report)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 200);
    let failed: Vec<&serde_json::Value> =
        lines.iter().filter(|l| l["status"] == "rejected").collect();
    assert_eq!(failed.len(), 3);
    assert!(failed
        .iter()
        .all(|l| l["error"].as_str().is_some_and(|e| !e.is_empty())));
    assert!(lines
        .iter()
        .filter(|l| l["status"] == "done")
        .all(|l| l["pixels"] == 384 && l["method"] == "ordered(bayer-8)"));
    assert!(lines
        .iter()
        .all(|l| l["shard"] == "1/1" && l["planned"] == 200));

    // Resuming skips what exists and still reports the broken files.
    let assert = halftone()
        .args(["batch", "-r", "-q", "--skip-existing", "--format", "pbm"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(3);
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).into_owned();
    assert!(stderr.contains("0 done, 197 skipped, 3 failed"), "{stderr}");
}

#[test]
fn shards_cover_every_file_once() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let good = make_inputs(&input);
    let mut seen: Vec<PathBuf> = Vec::new();
    let mut failures = 0;
    for k in 1..=3 {
        let out = tmp.path().join(format!("out{k}"));
        let run = halftone()
            .args([
                "batch",
                "-r",
                "-q",
                "--format",
                "png",
                "--shard",
                &format!("{k}/3"),
            ])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        let failed_here = stderr.matches("  failed: ").count();
        // Exit status 0 exactly when this shard's files all succeeded, 3 when some inputs
        // were rejected.
        let want = if failed_here == 0 { 0 } else { 3 };
        assert_eq!(run.status.code(), Some(want), "{stderr}");
        failures += failed_here;
        seen.extend(files_under(&out));
    }
    assert_eq!(failures, 3, "each broken file fails in exactly one shard");
    seen.sort();
    let expected: Vec<PathBuf> = good
        .iter()
        .map(|p| p.with_extension("png"))
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    assert_eq!(
        seen, expected,
        "every good file once, across the three shards"
    );
}

/// Runs `halftone batch` with exactly the given scheduler variables (the test's own
/// environment may hold some).
fn batch_with_env(vars: &[(&str, &str)]) -> Command {
    let mut c = halftone();
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_MAX",
        "SLURM_ARRAY_TASK_STEP",
        "SLURM_CPUS_PER_TASK",
        "JOB_COMPLETION_INDEX",
    ] {
        c.env_remove(v);
    }
    for (k, v) in vars {
        c.env(k, v);
    }
    c.arg("batch");
    c
}

#[test]
fn shard_auto_reads_slurm_and_kubernetes_tasks() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    for i in 0..7 {
        let img = image::GrayImage::from_fn(8, 8, |x, y| image::Luma([(x * 30 + y + i) as u8]));
        img.save(input.join(format!("p{i}.png"))).unwrap();
    }
    let outputs = |out: &Path| -> Vec<String> {
        files_under(out)
            .into_iter()
            .map(|p| p.display().to_string())
            .collect()
    };
    // Fixed 2/3 is the reference: the 2nd and 5th of the sorted list.
    let fixed = tmp.path().join("fixed");
    batch_with_env(&[])
        .args(["-q", "--shard", "2/3"])
        .arg(&input)
        .arg("-o")
        .arg(&fixed)
        .assert()
        .success();
    assert_eq!(outputs(&fixed), ["p1.png", "p4.png"]);
    let cases: &[(&str, &[(&str, &str)])] = &[
        (
            "auto",
            &[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "3"),
            ],
        ),
        (
            "auto",
            &[
                ("SLURM_ARRAY_TASK_ID", "11"),
                ("SLURM_ARRAY_TASK_MIN", "10"),
                ("SLURM_ARRAY_TASK_MAX", "12"),
            ],
        ),
        // Resubmitted alone: sbatch --array=2.
        (
            "auto/3",
            &[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", "2"),
                ("SLURM_ARRAY_TASK_MAX", "2"),
            ],
        ),
        ("auto/0-2", &[("SLURM_ARRAY_TASK_ID", "1")]),
        // Kubernetes counts from 0.
        ("auto/3", &[("JOB_COMPLETION_INDEX", "1")]),
    ];
    for (i, (spec, vars)) in cases.iter().enumerate() {
        let out = tmp.path().join(format!("auto{i}"));
        batch_with_env(vars)
            .args(["-q", "--shard", spec])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .assert()
            .success();
        assert_eq!(outputs(&out), outputs(&fixed), "{spec} {vars:?}");
    }
    // No scheduler, a lone task with plain auto, a bad CPU count: one clear line, exit 1.
    for (vars, spec, says) in [
        (&[][..], "auto", "JOB_COMPLETION_INDEX"),
        (
            &[
                ("SLURM_ARRAY_TASK_ID", "2"),
                ("SLURM_ARRAY_TASK_MIN", "2"),
                ("SLURM_ARRAY_TASK_MAX", "2"),
            ][..],
            "auto",
            "give it: --shard auto/N",
        ),
        (&[("JOB_COMPLETION_INDEX", "0")][..], "auto", "completions"),
        (
            &[("SLURM_CPUS_PER_TASK", "many")][..],
            "1/1",
            "SLURM_CPUS_PER_TASK",
        ),
    ] {
        let out = tmp.path().join("refused");
        let r = batch_with_env(vars)
            .args(["-q", "--shard", spec])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.starts_with("halftone: ") && stderr.contains(says),
            "{stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(!out.exists());
    }
    // The numbering is in --help.
    let help = halftone().args(["batch", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for says in [
        "counts K from 1",
        "JOB_COMPLETION_INDEX counts from 0",
        "Exit status:",
    ] {
        assert!(help.contains(says), "--help: {says}");
    }
}

#[test]
fn report_folder_is_created_and_reports_merge() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let good = make_inputs(&input);
    let reports = tmp.path().join("reports/deeper");
    for k in 1..=3 {
        let r = halftone()
            .args(["batch", "-r", "-q", "--format", "pbm", "-m", "threshold"])
            .args(["--shard", &format!("{k}/3")])
            .arg(&input)
            .arg("-o")
            .arg(tmp.path().join("out"))
            .arg("--report")
            .arg(reports.join(format!("{k}.jsonl")))
            .output()
            .unwrap();
        // 3 for a shard that meets a broken input, 0 for one that does not.
        assert!(matches!(r.status.code(), Some(0 | 3)), "{r:?}");
    }
    let merge = |names: &[&str]| {
        let mut c = halftone();
        c.args(["batch", "report", "merge"]);
        for n in names {
            c.arg(reports.join(n));
        }
        c.arg("-o").arg(tmp.path().join("merged/all.jsonl"));
        let r = c.output().unwrap();
        (
            r.status.code(),
            String::from_utf8_lossy(&r.stdout).into_owned(),
        )
    };
    let (code, text) = merge(&["1.jsonl", "2.jsonl", "3.jsonl"]);
    assert_eq!(code, Some(3), "{text}");
    assert!(
        text.contains("3 reports, 200 files: 197 done, 0 skipped, 3 rejected, 0 failed"),
        "{text}"
    );
    assert_eq!(text.matches("rejected: ").count(), 3, "{text}");
    let merged = std::fs::read_to_string(tmp.path().join("merged/all.jsonl")).unwrap();
    assert_eq!(merged.lines().count(), 200);
    assert_eq!(good.len(), 197);

    // A shard left out, and one given twice.
    let (code, text) = merge(&["1.jsonl", "3.jsonl", "3.jsonl"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("missing: shard 2/3 has no report line"),
        "{text}"
    );
    assert!(text.contains("duplicated: "), "{text}");
    // A report cut short (a killed run's lines).
    let one = std::fs::read_to_string(reports.join("1.jsonl")).unwrap();
    let cut: String = one.lines().take(10).map(|l| format!("{l}\n")).collect();
    std::fs::write(reports.join("cut.jsonl"), cut).unwrap();
    let (code, text) = merge(&["cut.jsonl", "2.jsonl", "3.jsonl"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("missing: shard 1/3 reports 57 file(s) fewer than it planned"),
        "{text}"
    );
    // Not a report: one line naming it.
    std::fs::write(reports.join("bad.jsonl"), "{\"x\": 1}\n").unwrap();
    let r = halftone()
        .args(["batch", "report", "merge"])
        .arg(reports.join("bad.jsonl"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1));
    assert!(
        stderr.contains("bad.jsonl:1: not a batch report line"),
        "{stderr}"
    );
}
