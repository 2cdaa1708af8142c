//! A batch killed with SIGKILL (what the out-of-memory killer does) and resumed: nothing
//! missing, nothing written twice, no temp file left, and a report that names every file once.

use std::collections::{BTreeMap, BTreeSet};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_halftone"))
}

/// A grey ramp with a per-file twist, as binary PGM.
fn pgm(w: usize, h: usize, seed: usize) -> Vec<u8> {
    let mut v = format!("P5\n{w} {h}\n255\n").into_bytes();
    v.extend((0..w * h).map(|i| ((i % w) * 255 / w + (i / w) * seed % 7) as u8));
    v
}

/// Every file under `dir`, relative, with its inode and modification time.
fn listing(dir: &Path) -> BTreeMap<PathBuf, (u64, i64, i64)> {
    walkdir::WalkDir::new(dir)
        .into_iter()
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_file())
        .map(|e| {
            let m = e.metadata().unwrap();
            (
                e.path().strip_prefix(dir).unwrap().to_path_buf(),
                (m.ino(), m.mtime(), m.mtime_nsec()),
            )
        })
        .collect()
}

fn temp_files(dir: &Path) -> BTreeSet<String> {
    listing(dir)
        .keys()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .filter(|n| n.starts_with('.') && n.ends_with(".tmp"))
        .collect()
}

fn report(path: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn sigkill_then_resume_misses_nothing_and_repeats_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    const GOOD: usize = 40;
    for i in 0..GOOD {
        std::fs::write(input.join(format!("img{i:02}.pgm")), pgm(256, 256, i)).unwrap();
    }
    std::fs::write(input.join("broken1.pgm"), b"P5\n256 256\n255\nshort").unwrap();
    std::fs::write(input.join("broken2.png"), b"not a png").unwrap();
    let out = tmp.path().join("out");
    let rep = tmp.path().join("reports/shard.jsonl");
    let args = |out: &Path, rep: &Path| {
        let mut c = Command::new(bin());
        c.args(["batch", "--format", "pbm", "-m", "dbs", "--jobs", "1"])
            .args(["--skip-existing", "-q"])
            .arg(&input)
            .arg("-o")
            .arg(out)
            .arg("--report")
            .arg(rep)
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        c
    };

    // The reference: the same batch, never interrupted.
    let reference = tmp.path().join("ref");
    let r = args(&reference, &tmp.path().join("ref.jsonl"))
        .output()
        .unwrap();
    assert_eq!(
        r.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );

    // Kill -9 once a few files are done.
    let mut child = args(&out, &rep).spawn().unwrap();
    let start = Instant::now();
    while listing(&out)
        .keys()
        .filter(|p| p.extension().is_some_and(|e| e == "pbm"))
        .count()
        < 5
    {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the batch ended before it was killed"
        );
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the batch made no progress"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    let status = child.wait().unwrap();
    assert!(!status.success());
    let before = listing(&out);
    let done_before: BTreeSet<PathBuf> = before
        .keys()
        .filter(|p| p.extension().is_some_and(|e| e == "pbm"))
        .cloned()
        .collect();
    let reports_dir = rep.parent().unwrap();
    let stale_report = temp_files(reports_dir);
    assert_eq!(
        stale_report.len(),
        1,
        "the killed run's report: {stale_report:?}"
    );
    assert!(!rep.exists(), "a killed run puts no report in place");
    let host = halftone::io::this_host();
    // A temp file of another dead process of this host, and one of another host.
    let dead = {
        let mut c = Command::new("true").spawn().unwrap();
        let pid = c.id();
        c.wait().unwrap();
        pid
    };
    std::fs::write(out.join(format!(".img99.pbm.{host}.{dead}.0.tmp")), b"P4\n").unwrap();
    let foreign = format!(".img98.pbm.elsewhere-node.{dead}.0.tmp");
    std::fs::write(out.join(&foreign), b"P4\n").unwrap();
    let stale_out = temp_files(&out).len() - 1;

    // Resume: the same command.
    let r = args(&out, &rep).output().unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "2 rejected inputs: {stderr}");
    assert!(
        stderr.contains("elsewhere-node"),
        "the foreign temp file is named: {stderr}"
    );

    // Nothing missing, nothing twice: every output of the reference run, byte-identical;
    // the outputs made before the kill untouched (same inode, same time).
    let after = listing(&out);
    let outputs: BTreeSet<PathBuf> = after
        .keys()
        .filter(|p| p.extension().is_some_and(|e| e == "pbm"))
        .cloned()
        .collect();
    let expected: BTreeSet<PathBuf> = listing(&reference).into_keys().collect();
    assert_eq!(outputs, expected);
    assert_eq!(outputs.len(), GOOD);
    for p in &outputs {
        assert_eq!(
            std::fs::read(out.join(p)).unwrap(),
            std::fs::read(reference.join(p)).unwrap(),
            "{}",
            p.display()
        );
    }
    for p in &done_before {
        assert_eq!(before[p], after[p], "{} was written again", p.display());
    }
    // No temp file left of this host; the other host's is left alone.
    assert_eq!(temp_files(&out), BTreeSet::from([foreign.clone()]));
    assert!(temp_files(reports_dir).is_empty());

    // The report: every input once; the files the killed run made keep its "done" lines.
    let lines = report(&rep);
    let inputs: BTreeSet<&str> = lines.iter().map(|l| l["input"].as_str().unwrap()).collect();
    assert_eq!((lines.len(), inputs.len()), (GOOD + 2, GOOD + 2));
    let status = |s: &str| lines.iter().filter(|l| l["status"] == s).count();
    assert_eq!(status("rejected"), 2);
    // A file finished between its rename and its report line can only be "skipped".
    assert!(status("skipped") <= 1, "{lines:?}");
    assert_eq!(status("done") + status("skipped"), GOOD);
    let summary = stderr
        .lines()
        .find(|l| l.starts_with("halftone batch:"))
        .unwrap();
    let redone: usize = summary["halftone batch: ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(redone, GOOD - done_before.len(), "{summary}");

    // The merged report agrees: complete but for the two rejected inputs.
    let m = Command::new(bin())
        .args(["batch", "report", "merge"])
        .arg(&rep)
        .output()
        .unwrap();
    let merged = String::from_utf8_lossy(&m.stdout);
    assert_eq!(m.status.code(), Some(3), "{merged}");
    assert!(merged.contains(&format!("{} files", GOOD + 2)), "{merged}");
    assert!(
        !merged.contains("missing") && !merged.contains("duplicated"),
        "{merged}"
    );
    eprintln!(
        "sigkill-resume: killed after {} of {GOOD} outputs; stale temp files: {} report + {stale_out} output; \
         resumed: {redone} done, {} skipped, {} done lines kept from the killed run; {} outputs byte-identical to an uninterrupted run",
        done_before.len(),
        stale_report.len(),
        status("skipped"),
        status("done") - redone,
        outputs.len()
    );
}
