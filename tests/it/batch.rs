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
        .failure();
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).into_owned();
    assert!(stderr.contains("197 done, 0 skipped, 3 failed"), "{stderr}");
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
        lines.iter().filter(|l| l["status"] == "failed").collect();
    assert_eq!(failed.len(), 3);
    assert!(failed
        .iter()
        .all(|l| l["error"].as_str().is_some_and(|e| !e.is_empty())));
    assert!(lines
        .iter()
        .filter(|l| l["status"] == "done")
        .all(|l| l["pixels"] == 384 && l["method"] == "ordered(bayer-8)"));

    // Resuming skips what exists and still reports the broken files.
    let assert = halftone()
        .args(["batch", "-r", "-q", "--skip-existing", "--format", "pbm"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .assert()
        .failure();
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
        // Exit status 0 exactly when this shard's files all succeeded.
        assert_eq!(run.status.success(), failed_here == 0, "{stderr}");
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
