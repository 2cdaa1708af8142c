//! Hostile inputs, special files, signals and full disks, through the real binary. Every
//! case is generated here (no large committed files) and must end cleanly: exit 0 where the
//! case is valid, else exit 1 with exactly one `halftone:` line on stderr; no panic, no
//! abort; bounded time and peak memory (the child's own `VmHWM`, see `common::PeakFile`); nothing partial and
//! no temp file left behind; devices, FIFOs and symlinks written through and left as they
//! were.
#![cfg(unix)]

use std::io::{Read, Write};
use std::os::unix::fs::{FileTypeExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_halftone");

/// Peak memory allowed for every case here, the issue's bound for unbounded inputs.
const MAX_RSS_MIB: u64 = 300;

/// What a finished run left.
struct Run {
    code: i32,
    stdout: Vec<u8>,
    stderr: String,
    rss_mib: u64,
    seconds: f64,
}

/// Runs `cmd` to the end (killed after `limit`), with its peak resident memory. `stdin` is fed in from a thread when given.
fn run_with(mut cmd: Command, stdin: Option<Stdio>, limit: Duration) -> Run {
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
    cmd.stdin(stdin.unwrap_or(Stdio::null()));
    let peak = crate::common::PeakFile::new(&mut cmd);
    let start = Instant::now();
    let mut child = cmd.spawn().expect("spawn halftone");
    let pid = child.id() as libc::pid_t;
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_t = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = out.read_to_end(&mut v);
        v
    });
    let err_t = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = err.read_to_end(&mut v);
        v
    });
    let mut status = 0;
    // SAFETY: rusage is plain old data, filled in by wait4.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        // SAFETY: waits for our own child; status and usage are valid out-pointers.
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if r == pid {
            break;
        }
        assert!(r == 0, "wait4 failed");
        if start.elapsed() > limit {
            // SAFETY: signals our own child, not yet reaped.
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("{cmd:?}: still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let seconds = start.elapsed().as_secs_f64();
    std::mem::forget(child); // already reaped by wait4
    let code = if libc::WIFEXITED(status) {
        libc::WEXITSTATUS(status)
    } else {
        128 + libc::WTERMSIG(status)
    };
    let rss_mib = peak.kib(&usage) / 1024;
    let args: Vec<String> = cmd
        .get_args()
        .map(|a| a.to_string_lossy().chars().take(60).collect())
        .collect();
    // The figures, for `cargo test --test it hostile -- --nocapture`.
    eprintln!(
        "measured: exit {code}, {seconds:.3} s, {rss_mib} MiB peak: {}",
        args.join(" ")
    );
    Run {
        code,
        stdout: out_t.join().unwrap(),
        stderr: String::from_utf8_lossy(&err_t.join().unwrap()).into_owned(),
        rss_mib,
        seconds,
    }
}

fn halftone(args: &[&str]) -> Command {
    let mut c = Command::new(BIN);
    c.args(args);
    c
}

fn run(args: &[&str]) -> Run {
    run_with(halftone(args), None, Duration::from_secs(30))
}

/// The failure contract: exit 1, one `halftone:` line containing `want`, within `secs` and
/// [`MAX_RSS_MIB`].
fn assert_fails(r: &Run, want: &str, secs: f64) {
    assert_eq!(r.code, 1, "exit code; stderr: {}", r.stderr);
    let lines: Vec<&str> = r.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "exactly one line: {}", r.stderr);
    assert!(lines[0].starts_with("halftone: "), "{}", r.stderr);
    assert!(lines[0].contains(want), "wanted {want:?} in: {}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    assert_bounded(r, secs);
}

fn assert_bounded(r: &Run, secs: f64) {
    assert!(r.seconds < secs, "took {:.1} s (limit {secs})", r.seconds);
    assert!(
        r.rss_mib < MAX_RSS_MIB,
        "peak memory {} MiB (limit {MAX_RSS_MIB})",
        r.rss_mib
    );
}

fn assert_ok(r: &Run) {
    assert_eq!(r.code, 0, "stderr: {}", r.stderr);
    assert_bounded(r, 10.0);
}

/// The names in a folder, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A binary greymap (P5) of a diagonal ramp.
fn pgm(w: usize, h: usize) -> Vec<u8> {
    let mut v = format!("P5\n{w} {h}\n255\n").into_bytes();
    v.extend((0..w * h).map(|i| ((i % w + i / w) * 255 / (w + h)) as u8));
    v
}

/// An 8-bit RGB JPEG of a ramp, from the image crate's encoder.
fn jpeg(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, 128]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Jpeg).unwrap();
    out.into_inner()
}

/// CRC-32 (ISO 3309), for PNG chunks.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut out = (data.len() as u32).to_be_bytes().to_vec();
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let mut c = kind.to_vec();
    c.extend_from_slice(data);
    out.extend_from_slice(&crc32(&c).to_be_bytes());
    out
}

/// A PNG whose header claims `w × h` RGB at 8 bits, followed by `idat` as its data.
fn png_claiming(w: u32, h: u32, idat: &[u8]) -> Vec<u8> {
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let mut v = b"\x89PNG\r\n\x1a\n".to_vec();
    v.extend(png_chunk(b"IHDR", &ihdr));
    v.extend(png_chunk(b"IDAT", idat));
    v.extend(png_chunk(b"IEND", &[]));
    v
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

// ---- outputs that are not regular files -------------------------------------------------

#[test]
fn device_outputs_are_written_through_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(64, 48));
    let r = run(&[
        "convert",
        s(&input),
        "-o",
        "/dev/null",
        "--format",
        "pbm",
        "-m",
        "threshold",
    ]);
    assert_ok(&r);
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    // /dev/full: every write fails with ENOSPC; the device stays a device.
    let r = run(&[
        "convert",
        s(&input),
        "-o",
        "/dev/full",
        "--format",
        "pbm",
        "-m",
        "threshold",
    ]);
    assert_fails(&r, "/dev/full: ", 10.0);
    assert!(std::fs::metadata("/dev/full")
        .unwrap()
        .file_type()
        .is_char_device());
    // Through a symlink to a device.
    let link = dir.path().join("printer");
    std::os::unix::fs::symlink("/dev/null", &link).unwrap();
    assert_ok(&run(&[
        "convert",
        s(&input),
        "-o",
        s(&link),
        "--format",
        "pbm",
        "-m",
        "threshold",
    ]));
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    assert_eq!(listing(dir.path()), ["in.pgm", "printer"]);
}

#[test]
fn fifo_output_is_written_into_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(64, 48));
    let fifo = dir.path().join("pipe.pbm");
    let c = std::ffi::CString::new(s(&fifo)).unwrap();
    // SAFETY: a valid C string; mkfifo only creates the node.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let r = run(&["convert", s(&input), "-o", s(&fifo), "-m", "threshold"]);
    assert_ok(&r);
    let bytes = reader.join().unwrap();
    assert!(bytes.starts_with(b"P4\n64 48\n"), "{:?}", &bytes[..8]);
    assert_eq!(bytes.len(), 9 + 8 * 48);
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    assert_eq!(listing(dir.path()), ["in.pgm", "pipe.pbm"]);
}

#[test]
fn symlink_output_replaces_the_target_and_keeps_the_link() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(64, 48));
    std::fs::create_dir(dir.path().join("real")).unwrap();
    let target = write(dir.path(), "real/out.pbm", b"old");
    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o640)).unwrap();
    let link = dir.path().join("out.pbm");
    std::os::unix::fs::symlink("real/out.pbm", &link).unwrap();
    assert_ok(&run(&[
        "convert",
        s(&input),
        "-o",
        s(&link),
        "-m",
        "threshold",
    ]));
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read(&target).unwrap().starts_with(b"P4\n64 48\n"));
    let mode = std::fs::metadata(&target).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640, "the replaced file keeps its permissions");
    assert_eq!(listing(&dir.path().join("real")), ["out.pbm"]);
}

#[test]
fn longest_legal_output_name_works() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(16, 16));
    let name = format!("{}.pbm", "n".repeat(251));
    let out = dir.path().join(&name);
    assert_ok(&run(&[
        "convert",
        s(&input),
        "-o",
        s(&out),
        "-m",
        "threshold",
    ]));
    assert_eq!(listing(dir.path()), vec!["in.pgm".to_string(), name]);
}

// ---- unbounded and hostile inputs -------------------------------------------------------

#[test]
fn dev_zero_and_streams_of_zeros_fail_fast() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    let r = run(&["convert", "/dev/zero", "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "/dev/zero: not an image format", 10.0);
    let zero = std::fs::File::open("/dev/zero").unwrap();
    let r = run_with(
        halftone(&["convert", "-", "-o", s(&out), "-m", "threshold"]),
        Some(Stdio::from(zero)),
        Duration::from_secs(30),
    );
    assert_fails(&r, "<stdin>: not an image format", 10.0);
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn huge_sparse_files_fail_fast() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    // 20 GB of nothing: sparse, so it costs no disk.
    let sparse = dir.path().join("sparse.png");
    let f = std::fs::File::create(&sparse).unwrap();
    if let Err(e) = f.set_len(20_000_000_000) {
        crate::common::skip(
            "hostile::huge_sparse_files_fail_fast",
            &format!(
                "this file system makes no 20 GB sparse file ({e}); set TMPDIR to one that does"
            ),
        );
        return;
    }
    drop(f);
    let r = run(&["convert", s(&sparse), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "not an image format", 10.0);
    // The same with a PNG signature in front: refused from its length.
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(&sparse)
        .unwrap();
    f.write_all(b"\x89PNG\r\n\x1a\n").unwrap();
    drop(f);
    let r = run(&[
        "convert",
        s(&sparse),
        "-o",
        s(&out),
        "--max-pixels",
        "100000000",
    ]);
    assert_fails(&r, "sparse.png: ", 10.0);
    assert_eq!(listing(dir.path()), ["sparse.png"]);
}

#[test]
fn gif_with_a_huge_logical_screen_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // 30000×30000 logical screen, one 1×1 frame: 35 bytes.
    let mut gif = b"GIF89a".to_vec();
    gif.extend_from_slice(&30000u16.to_le_bytes());
    gif.extend_from_slice(&30000u16.to_le_bytes());
    gif.extend_from_slice(&[0x80, 0, 0, 0, 0, 0, 255, 255, 255]); // 2-colour table
    gif.extend_from_slice(&[0x2C, 0, 0, 0, 0, 1, 0, 1, 0, 0]); // image descriptor 1×1
    gif.extend_from_slice(&[2, 2, 0x44, 0x01, 0, 0x3B]);
    let input = write(dir.path(), "screen.gif", &gif);
    let out = dir.path().join("out.pbm");
    let r = run(&["convert", s(&input), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "screen.gif: decoding this GIF needs more than", 10.0);
    assert_eq!(listing(dir.path()), ["screen.gif"]);
}

#[test]
fn decompression_bomb_is_refused_before_inflating() {
    let dir = tempfile::tempdir().unwrap();
    // Claims 26000×26000 RGB (2 GB decoded, under the pixel limit); an empty zlib stream.
    let idat = [
        0x78, 0x01, 0x01, 0x00, 0x00, 0xFF, 0xFF, 0x00, 0x00, 0x00, 0x01,
    ];
    let input = write(dir.path(), "bomb.png", &png_claiming(26000, 26000, &idat));
    let out = dir.path().join("out.pbm");
    let r = run(&["convert", s(&input), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "bomb.png: ", 10.0);
    assert_eq!(listing(dir.path()), ["bomb.png"]);
}

#[test]
fn truncated_and_impossible_jpegs_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    let good = jpeg(64, 64);
    let ok = write(dir.path(), "good.jpg", &good);
    assert_ok(&run(&["convert", s(&ok), "-o", s(&out), "-m", "threshold"]));
    std::fs::remove_file(&out).unwrap();
    // The last third cut off: no end-of-image marker.
    let cut = write(dir.path(), "cut.jpg", &good[..good.len() * 2 / 3]);
    let r = run(&["convert", s(&cut), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "cut.jpg: truncated", 10.0);
    // A small JPEG whose frame header claims 30000×30000.
    let mut claim = jpeg(16, 16);
    let sof = claim.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
    claim[sof + 5..sof + 9].copy_from_slice(&[0x75, 0x30, 0x75, 0x30]);
    assert!(claim.len() < 1000);
    let claim = write(dir.path(), "claim.jpg", &claim);
    let r = run(&["convert", s(&claim), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "claim.jpg: truncated or corrupt", 10.0);
    assert_eq!(listing(dir.path()), ["claim.jpg", "cut.jpg", "good.jpg"]);
}

#[test]
fn truncated_greymap_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut data = pgm(300, 200);
    data.truncate(data.len() - 1);
    let input = write(dir.path(), "short.pgm", &data);
    // A header claiming 30000×30000 with almost no data: refused from the file's length.
    let claim = write(dir.path(), "claim.pgm", b"P5\n30000 30000\n255\n\0\0\0");
    let out = dir.path().join("out.pbm");
    for f in [&input, &claim] {
        let r = run(&["convert", s(f), "-o", s(&out), "-m", "threshold"]);
        assert_fails(&r, "truncated", 10.0);
    }
    // Shrunk on load, with the pixel limit raised past a claimed 10 gigapixels: still refused
    // from the file's length, before the shrunk image (1.25 GB here) is allocated.
    let huge = write(dir.path(), "huge.pgm", b"P5\n100000 100000\n255\n\0\0\0");
    let r = run(&[
        "convert",
        s(&huge),
        "-o",
        s(&out),
        "--width",
        "384",
        "--max-pixels",
        "20000000000",
    ]);
    assert_fails(&r, "huge.pgm: truncated", 10.0);
    assert_eq!(listing(dir.path()), ["claim.pgm", "huge.pgm", "short.pgm"]);
}

#[test]
fn folder_and_text_given_as_images_fail() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    let r = run(&["convert", s(dir.path()), "-o", s(&out), "-m", "threshold"]);
    let folder = format!("{}: is a folder, not an image", dir.path().display());
    assert_fails(&r, &folder, 10.0);
    let txt = write(dir.path(), "notes.txt", b"hello\n");
    let r = run(&["convert", s(&txt), "-o", s(&out), "-m", "threshold"]);
    assert_fails(&r, "notes.txt: not an image format", 10.0);
}

// ---- sizes asked for ------------------------------------------------------------------

#[test]
fn expand_output_over_the_pixel_limit_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(500, 400));
    let out = dir.path().join("out.pbm");
    let r = run(&[
        "convert",
        s(&input),
        "-o",
        s(&out),
        "-m",
        "pattern",
        "--mask",
        "seed-3x3",
        "--cell",
        "expand",
        "--max-pixels",
        "1000000",
    ]);
    assert_fails(&r, "1500x1200 halftone (1800000 pixels)", 5.0);
    // Within the limit it runs.
    let r = run(&[
        "convert",
        s(&input),
        "-o",
        s(&out),
        "-m",
        "pattern",
        "--mask",
        "seed-3x3",
        "--cell",
        "expand",
        "--max-pixels",
        "2000000",
    ]);
    assert_ok(&r);
}

#[test]
fn compare_too_large_for_memory_is_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let idat = [
        0x78, 0x01, 0x01, 0x00, 0x00, 0xFF, 0xFF, 0x00, 0x00, 0x00, 0x01,
    ];
    let a = write(dir.path(), "a.png", &png_claiming(40000, 25000, &idat));
    let b = write(dir.path(), "b.png", &png_claiming(40000, 25000, &idat));
    let r = run(&["compare", s(&a), s(&b)]);
    assert_fails(&r, "needs about", 5.0);
    assert!(r.stderr.contains("MB of memory available"), "{}", r.stderr);
}

#[test]
fn patterns_of_a_large_mask_are_refused() {
    let r = run(&["patterns", "--mask", "blue-noise-128"]);
    assert_fails(
        &r,
        "blue-noise-128: a 128x128 mask at 2 levels has 16385 patterns",
        5.0,
    );
    let dir = tempfile::tempdir().unwrap();
    let sheet = dir.path().join("sheet.png");
    let r = run(&["patterns", "--mask", "blue-noise-128", "-o", s(&sheet)]);
    assert_fails(&r, "over the 1048576 a pattern table may hold", 5.0);
    assert!(listing(dir.path()).is_empty());
    // A mask the table is meant for still works.
    let r = run(&["patterns", "--mask", "bayer-8"]);
    assert_ok(&r);
    assert!(r.stdout.starts_with(b"bayer-8: 8x8 mask"));
}

#[test]
fn masks_show_is_bounded() {
    let dir = tempfile::tempdir().unwrap();
    // 1000×1000 ranks: shown (8 MB of text) without the quadratic warning check.
    let (w, h) = (1000usize, 1000usize);
    let mut text = String::with_capacity(w * h * 8);
    for y in 0..h {
        for x in 0..w {
            text.push_str(&((y * w + x) * 7919 % (w * h)).to_string());
            text.push(if x + 1 == w { '\n' } else { ' ' });
        }
    }
    let big = write(dir.path(), "big.mask", text.as_bytes());
    let r = run(&["masks", "show", s(&big)]);
    assert_ok(&r);
    assert!(String::from_utf8_lossy(&r.stdout).contains("not checked: over 4096 cells"));
    // Over 2^20 cells: refused while parsing, at the row that passes 2^20 (the 1049th).
    for _ in 0..100 {
        text.push_str(&"1 ".repeat(w));
        text.push('\n');
    }
    let bigger = write(dir.path(), "bigger.mask", text.as_bytes());
    let r = run(&["masks", "show", s(&bigger)]);
    assert_fails(
        &r,
        "bigger.mask:1049: the mask has more than 1048576 cells",
        5.0,
    );
    // A device given as a mask: refused after a bounded read.
    let r = run(&["masks", "show", "/dev/zero"]);
    assert_fails(&r, "/dev/zero", 10.0);
}

#[test]
fn kernel_weights_that_overflow_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(32, 32));
    let out = dir.path().join("out.pbm");
    for (name, text) in [
        ("wrap0.kernel", "- X 4294967295\n1 - -\n"),
        ("wrap6.kernel", "- X 4294967295\n3 5 -\n/ 16\n"),
    ] {
        let k = write(dir.path(), name, text.as_bytes());
        let r = run(&[
            "convert",
            s(&input),
            "-o",
            s(&out),
            "-m",
            "diffuse",
            "--kernel",
            s(&k),
        ]);
        assert_fails(&r, "the weights sum to 42949", 5.0);
    }
    assert!(!out.exists());
}

// ---- signals ----------------------------------------------------------------------------

#[test]
fn sigterm_sighup_and_sigint_leave_no_temp_files_in_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    let img = pgm(400, 300);
    for i in 0..400 {
        std::fs::write(inputs.join(format!("{i:03}.pgm")), &img).unwrap();
    }
    for (sig, name) in [
        (libc::SIGTERM, "SIGTERM"),
        (libc::SIGHUP, "SIGHUP"),
        (libc::SIGINT, "SIGINT"),
    ] {
        let out = dir.path().join(format!("out-{name}"));
        let report = dir.path().join(format!("report-{name}.jsonl"));
        let mut child = halftone(&[
            "batch",
            s(&inputs),
            "-o",
            s(&out),
            "--jobs",
            "1",
            "-m",
            "diffuse",
            "--format",
            "pbm",
            "--report",
            s(&report),
            "-q",
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
        // The report's temp file exists from the start to the end of the run; wait until
        // some outputs are done too, so files are being written when the signal comes.
        let start = Instant::now();
        loop {
            let done = std::fs::read_dir(&out).map(|d| d.count()).unwrap_or(0);
            if done >= 3 {
                break;
            }
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "batch made no progress"
            );
            assert!(
                child.try_wait().unwrap().is_none(),
                "batch ended before the signal"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        // SAFETY: signals our own running child.
        unsafe { libc::kill(child.id() as libc::pid_t, sig) };
        let status = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&status.stderr);
        assert_eq!(status.status.code(), Some(128 + sig), "{name}: {stderr}");
        assert!(
            stderr.contains(&format!("interrupted ({name})")),
            "{stderr}"
        );
        let temps: Vec<String> = listing(&out)
            .into_iter()
            .chain(listing(dir.path()))
            .filter(|n| n.ends_with(".tmp"))
            .collect();
        assert!(temps.is_empty(), "{name} left {temps:?}");
        assert!(!report.exists(), "{name}: no half report");
        // Every output that exists is complete.
        for f in listing(&out) {
            let bytes = std::fs::read(out.join(&f)).unwrap();
            assert_eq!(bytes.len(), "P4\n400 300\n".len() + 50 * 300, "{f}");
        }
    }
}

#[test]
fn sigterm_ends_a_single_convert_with_its_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    // Standard input that never ends: the convert waits in its read.
    let mut child = halftone(&["convert", "-", "-o", s(&out), "-m", "threshold"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(b"P5\n2000 2000\n255\n").unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert!(child.try_wait().unwrap().is_none(), "convert ended early");
    // SAFETY: signals our own running child.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let res = child.wait_with_output().unwrap();
    drop(stdin);
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(143), "{stderr}");
    assert_eq!(
        stderr.trim_end(),
        "halftone: interrupted (SIGTERM); no partial output left"
    );
    assert!(listing(dir.path()).is_empty());
}

// ---- write errors -----------------------------------------------------------------------

#[test]
fn closed_or_broken_stdout_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = write(dir.path(), "in.pgm", &pgm(64, 48));
    let sh = format!(
        "exec {BIN} convert {} -o - --format pbm -m threshold >&-",
        s(&input)
    );
    let mut c = Command::new("sh");
    c.args(["-c", &sh]);
    let r = run_with(c, None, Duration::from_secs(30));
    assert_fails(&r, "standard output is closed", 10.0);
    let mut c = Command::new("sh");
    c.args(["-c", &format!("exec {BIN} patterns >&-")]);
    let r = run_with(c, None, Duration::from_secs(30));
    assert_fails(&r, "standard output is closed", 10.0);
    // A reader that goes away: EPIPE is an error, not a panic.
    let mut child = halftone(&["masks", "show", "blue-noise-128"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
}

#[test]
fn batch_report_that_cannot_be_written_fails_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    std::fs::write(inputs.join("a.pgm"), pgm(32, 32)).unwrap();
    let out = dir.path().join("out");
    let r = run(&[
        "batch",
        s(&inputs),
        "-o",
        s(&out),
        "-m",
        "threshold",
        "--report",
        "/dev/full",
        "-q",
    ]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert!(
        r.stderr
            .contains("halftone: cannot write the report: /dev/full: "),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("panicked"));
}

#[test]
fn render_writes_the_format_its_name_says() {
    let dir = tempfile::tempdir().unwrap();
    let pbm = dir.path().join("x.pbm");
    let r = run(&["render", "polyhedra", "-o", s(&pbm), "--size", "32x24"]);
    assert_fails(&r, "x.pbm: render writes PNG (.png) or PPM (.ppm)", 10.0);
    let ppm = dir.path().join("x.ppm");
    assert_ok(&run(&[
        "render",
        "polyhedra",
        "-o",
        s(&ppm),
        "--size",
        "32x24",
    ]));
    let bytes = std::fs::read(&ppm).unwrap();
    assert!(bytes.starts_with(b"P6\n32 24\n255\n"));
    assert_eq!(bytes.len(), "P6\n32 24\n255\n".len() + 32 * 24 * 3);
    assert_eq!(listing(dir.path()), ["x.ppm"]);
}

#[test]
fn batch_does_not_halftone_its_own_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir_all(inputs.join("sub")).unwrap();
    std::fs::write(inputs.join("a.pgm"), pgm(32, 32)).unwrap();
    std::fs::write(inputs.join("sub/b.pgm"), pgm(32, 32)).unwrap();
    let out = inputs.join("halftones");
    let args = [
        "batch",
        s(&inputs),
        "-o",
        s(&out),
        "-r",
        "-m",
        "threshold",
        "--format",
        "png",
    ];
    for _ in 0..3 {
        let r = run(&args);
        assert_ok(&r);
        assert!(
            r.stderr.contains("2 done, 0 skipped, 0 failed"),
            "{}",
            r.stderr
        );
    }
    assert_eq!(listing(&out), ["a.png", "sub"]);
    assert_eq!(listing(&out.join("sub")), ["b.png"]);
}

// ---- a full disk ------------------------------------------------------------------------

/// A 64 KiB tmpfs, mounted for the closure and unmounted after; `None` when mounting is not
/// permitted here (not root, or no CAP_SYS_ADMIN in a container).
fn with_small_tmpfs(f: impl FnOnce(&Path)) -> Option<()> {
    let dir = tempfile::tempdir().unwrap();
    let ok = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs", s(dir.path())])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        return None;
    }
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(dir.path())));
    let _ = Command::new("umount").arg(dir.path()).status();
    if let Err(p) = res {
        std::panic::resume_unwind(p);
    }
    Some(())
}

#[test]
fn disk_full_leaves_nothing() {
    let src = tempfile::tempdir().unwrap();
    // 800×600 grey with 256 levels: a 480 KB PGM, far over 64 KiB.
    let input = write(src.path(), "in.pgm", &pgm(800, 600));
    let done = with_small_tmpfs(|disk| {
        let out = disk.join("out.pgm");
        let r = run(&[
            "convert",
            s(&input),
            "-o",
            s(&out),
            "-m",
            "threshold",
            "--levels",
            "256",
        ]);
        assert_fails(&r, "No space left on device", 10.0);
        assert!(listing(disk).is_empty(), "{:?}", listing(disk));
        // A batch whose report is on the full disk (filled first): the run fails and
        // leaves no report.
        let mut filler = std::fs::File::create(disk.join("filler")).unwrap();
        while filler.write_all(&[0u8; 4096]).is_ok() {}
        drop(filler);
        let report = disk.join("report.jsonl");
        let outs = tempfile::tempdir().unwrap();
        let r = run(&[
            "batch",
            s(src.path()),
            "-o",
            s(outs.path()),
            "-m",
            "threshold",
            "--report",
            s(&report),
            "-q",
        ]);
        assert_eq!(r.code, 1, "{}", r.stderr);
        assert!(
            r.stderr.contains("halftone: cannot write the report: "),
            "{}",
            r.stderr
        );
        assert!(r.stderr.contains("No space left on device"), "{}", r.stderr);
        assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
        assert_eq!(listing(disk), ["filler"]);
    });
    if done.is_none() {
        crate::common::skip(
            "hostile::disk_full_leaves_nothing",
            "cannot mount a tmpfs here (needs root or CAP_SYS_ADMIN); file_size_limit_leaves_nothing still ran",
        );
    }
}

/// A regular file that cannot grow past 64 KiB, on any machine and without root: the
/// child's `RLIMIT_FSIZE`, with `SIGXFSZ` ignored so that the write past the limit fails
/// with `EFBIG` instead of killing the process (POSIX `setrlimit`). The convert fails with
/// one line and leaves nothing, as on a full disk.
#[test]
fn file_size_limit_leaves_nothing() {
    use std::os::unix::process::CommandExt;
    let src = tempfile::tempdir().unwrap();
    // 800×600 grey with 256 levels: a 480 KB PGM, far over 64 KiB.
    let input = write(src.path(), "in.pgm", &pgm(800, 600));
    let outs = tempfile::tempdir().unwrap();
    let out = outs.path().join("out.pgm");
    let args = [
        "convert",
        s(&input),
        "-o",
        s(&out),
        "-m",
        "threshold",
        "--levels",
        "256",
    ];
    let mut cmd = halftone(&args);
    // SAFETY: between fork and exec the closure makes only async-signal-safe calls
    // (setrlimit, signal) and allocates nothing.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 64 << 10,
                rlim_max: 64 << 10,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let r = run_with(cmd, None, Duration::from_secs(30));
    assert_fails(&r, "File too large", 10.0);
    assert!(
        listing(outs.path()).is_empty(),
        "{:?}",
        listing(outs.path())
    );
    // Without the limit the same command succeeds: the limit was the cause.
    assert_ok(&run(&args));
    assert_eq!(listing(outs.path()), ["out.pgm"]);
}

// ---- issue 45: report lines, report merge, calibration, PNG on stdin --------------------

/// A path from raw bytes (a name that is not UTF-8).
fn raw_path(dir: &Path, name: &[u8]) -> PathBuf {
    use std::os::unix::ffi::OsStrExt;
    dir.join(std::ffi::OsStr::from_bytes(name))
}

#[test]
fn batch_report_keeps_names_that_are_not_utf8() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    // Latin-1 "café.pgm", an image; Latin-1 "bad\xff.pgm", not one.
    std::fs::write(raw_path(&inputs, b"caf\xe9.pgm"), pgm(32, 32)).unwrap();
    std::fs::write(raw_path(&inputs, b"bad\xff.pgm"), b"not an image").unwrap();
    std::fs::write(inputs.join("ok.pgm"), pgm(32, 32)).unwrap();
    let out = dir.path().join("out");
    let report = dir.path().join("report.jsonl");
    let args = [
        "batch",
        s(&inputs),
        "-o",
        s(&out),
        "-m",
        "threshold",
        "-f",
        "pbm",
        "--report",
        s(&report),
        "-q",
    ];
    let r = run(&args);
    // Done but for the one rejected input: no panic, and the report is written.
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    assert!(
        r.stderr.contains("2 done, 0 skipped, 1 failed"),
        "{}",
        r.stderr
    );
    assert!(raw_path(&out, b"caf\xe9.pbm").is_file());
    assert!(out.join("ok.pbm").is_file());
    let text = std::fs::read_to_string(&report).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3, "{text}");
    let line = |name: &str| {
        lines
            .iter()
            .find(|l| l["input"].as_str().unwrap().ends_with(name))
            .unwrap_or_else(|| panic!("no line for {name} in {text}"))
    };
    // The escaped name to read, the exact bytes to take.
    let cafe = line("in/caf\\xe9.pgm");
    assert_eq!(cafe["status"], "done");
    assert!(cafe["output"]
        .as_str()
        .unwrap()
        .ends_with("out/caf\\xe9.pbm"));
    let want_hex: String = s(&inputs)
        .bytes()
        .chain(*b"/caf\xe9.pgm")
        .map(|b| format!("{b:02x}"))
        .collect();
    assert_eq!(cafe["input_bytes"], want_hex.as_str());
    let bad = line("in/bad\\xff.pgm");
    assert_eq!(bad["status"], "rejected");
    assert!(bad["input_bytes"].as_str().unwrap().ends_with("ff2e70676d"));
    let ok = line("in/ok.pgm");
    assert!(
        ok.get("input_bytes").is_none(),
        "UTF-8 names as before: {ok}"
    );

    // Read back: a resumed run keeps the line of the run that made café's output (its path
    // is matched byte for byte), and a merge sees every file once.
    let r = run(&[&args[..], &["--skip-existing"]].concat());
    assert_eq!(r.code, 3, "{}", r.stderr);
    assert!(
        r.stderr.contains("0 done, 2 skipped, 1 failed"),
        "{}",
        r.stderr
    );
    let again = std::fs::read_to_string(&report).unwrap();
    assert!(
        again
            .lines()
            .any(|l| l.contains("caf\\\\xe9.pgm") && l.contains("\"done\"")),
        "{again}"
    );
    let merged = dir.path().join("merged.jsonl");
    let r = run(&["batch", "report", "merge", s(&report), "-o", s(&merged)]);
    assert_eq!(
        r.code,
        3,
        "{}{}",
        String::from_utf8_lossy(&r.stdout),
        r.stderr
    );
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("3 files: 2 done"), "{stdout}");
    let m = std::fs::read_to_string(&merged).unwrap();
    assert!(
        m.contains(&format!("\"input_bytes\":\"{want_hex}\"")),
        "{m}"
    );
}

/// Peak memory allowed for a report merge on any file.
const MERGE_RSS_MIB: u64 = 64;

#[test]
fn report_merge_refuses_what_is_not_a_report_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let sparse = dir.path().join("sparse.jsonl");
    let f = std::fs::File::create(&sparse).unwrap();
    if let Err(e) = f.set_len(2_000_000_000) {
        crate::common::skip(
            "hostile::report_merge_refuses_what_is_not_a_report_at_once",
            &format!("this file system makes no 2 GB sparse file ({e})"),
        );
        return;
    }
    drop(f);
    let merged = dir.path().join("merged.jsonl");
    for (input, name) in [(s(&sparse), "sparse.jsonl"), ("/dev/zero", "/dev/zero")] {
        let r = run(&["batch", "report", "merge", input, "-o", s(&merged)]);
        assert_fails(&r, &format!("{name}:1: not a batch report"), 10.0);
        assert!(
            r.rss_mib < MERGE_RSS_MIB,
            "{name}: peak memory {} MiB (limit {MERGE_RSS_MIB})",
            r.rss_mib
        );
    }
    // A short file without a line break, and a text that is not JSON lines: errors naming
    // the file and the line, no merged report written.
    let one = write(dir.path(), "one.jsonl", b"hello");
    let r = run(&["batch", "report", "merge", s(&one), "-o", s(&merged)]);
    assert_fails(&r, "one.jsonl:1: not a batch report line", 10.0);
    let text = write(dir.path(), "text.jsonl", b"\n\nsome notes\n");
    let r = run(&["batch", "report", "merge", s(&text), "-o", s(&merged)]);
    assert_fails(&r, "text.jsonl:3: not a batch report line", 10.0);
    assert!(!merged.exists());
}

/// A baseline JPEG of `w × h` flat grey (RGB, 4:4:4), written by hand: one Huffman code of
/// one bit for "no change" and one for "end of block", so every 8×8 block is two zero bits
/// and an 18000×18000 photo takes 3.8 MB, made in milliseconds.
fn flat_jpeg(w: u16, h: u16) -> Vec<u8> {
    let mut v = vec![0xFF, 0xD8];
    // Quantisation table 0: all ones.
    v.extend([0xFF, 0xDB, 0, 67, 0]);
    v.extend([1u8; 64]);
    // Frame: 8 bits, h × w, three components sampled 1×1 on table 0.
    v.extend([0xFF, 0xC0, 0, 17, 8]);
    v.extend(h.to_be_bytes());
    v.extend(w.to_be_bytes());
    v.extend([3, 1, 0x11, 0, 2, 0x11, 0, 3, 0x11, 0]);
    // DC and AC tables 0: one code of length 1, for symbol 0 (difference 0; end of block).
    for class in [0x00u8, 0x10] {
        v.extend([0xFF, 0xC4, 0, 20, class, 1]);
        v.extend([0u8; 15]);
        v.push(0);
    }
    v.extend([0xFF, 0xDA, 0, 12, 3, 1, 0, 2, 0, 3, 0, 0, 63, 0]);
    let blocks = (w as u64).div_ceil(8) * (h as u64).div_ceil(8) * 3;
    let bits = blocks * 2;
    v.extend(std::iter::repeat_n(0u8, (bits / 8) as usize));
    if !bits.is_multiple_of(8) {
        // Padding bits are ones (ITU T.81, F.1.2.3).
        v.push(0xFFu8 >> (bits % 8));
    }
    v.extend([0xFF, 0xD9]);
    v
}

#[test]
fn calibration_of_a_huge_photo_stays_small() {
    let dir = tempfile::tempdir().unwrap();
    // The issue's 324-megapixel photo (it peaked at 1.9 GB): flat grey, so no chart.
    let photo = write(dir.path(), "photo.jpg", &flat_jpeg(18000, 18000));
    let out = dir.path().join("panel.toml");
    let r = run_with(
        halftone(&[
            "devices",
            "calibrate",
            "bwry-4in2",
            s(&photo),
            "-o",
            s(&out),
        ]),
        None,
        Duration::from_secs(120),
    );
    assert_fails(&r, "photo.jpg: chart not found", 60.0);
    assert!(r.rss_mib < 256, "peak memory {} MiB (limit 256)", r.rss_mib);
    // The same photo at a size read whole is read as it was (the same message, no note of
    // averaging).
    let small = write(dir.path(), "small.jpg", &flat_jpeg(640, 480));
    let r = run(&[
        "devices",
        "calibrate",
        "bwry-4in2",
        s(&small),
        "-o",
        s(&out),
    ]);
    assert_fails(&r, "small.jpg: chart not found", 10.0);
    assert!(!r.stderr.contains("averaged down"), "{}", r.stderr);
    assert!(!out.exists());
}

/// Runs `args` with `head` then endless zeros on standard input.
fn run_fed(args: &[&str], head: Vec<u8>) -> Run {
    let (reader, mut writer) = std::io::pipe().unwrap();
    let feeder = std::thread::spawn(move || {
        if writer.write_all(&head).is_ok() {
            let zeros = vec![0u8; 1 << 16];
            while writer.write_all(&zeros).is_ok() {}
        }
    });
    let r = run_with(
        halftone(args),
        Some(Stdio::from(reader)),
        Duration::from_secs(60),
    );
    // The reader is closed once the command is dropped: the feeder sees EPIPE and ends.
    feeder.join().unwrap();
    r
}

#[test]
fn png_header_on_stdin_then_zeros_stays_small() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pbm");
    let args = ["convert", "-", "-o", s(&out), "-m", "threshold"];
    // A real header declaring 31622×31622 grey (just within the default pixel limit),
    // then zeros: it buffered 1.95 GB before.
    let mut ihdr = 31622u32.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&31622u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut head = b"\x89PNG\r\n\x1a\n".to_vec();
    head.extend(png_chunk(b"IHDR", &ihdr));
    let r = run_fed(&args, head.clone());
    assert_fails(&r, "<stdin>: bad PNG file", 10.0);
    assert!(r.rss_mib < 256, "peak memory {} MiB", r.rss_mib);
    // Then an image-data chunk that claims 2 GB, of zeros: decoded as it comes, refused at
    // its first bytes.
    head.extend(0x7FFF_FFFFu32.to_be_bytes());
    head.extend(b"IDAT");
    let r = run_fed(&args, head);
    assert_fails(&r, "<stdin>: bad PNG file", 10.0);
    assert!(r.rss_mib < 256, "peak memory {} MiB", r.rss_mib);
    assert!(listing(dir.path()).is_empty());
}

#[test]
fn png_on_stdin_streams_with_the_bytes_of_a_file() {
    let dir = tempfile::tempdir().unwrap();
    {
        let img = image::RgbImage::from_fn(97, 61, |x, y| {
            image::Rgb([(x * 2) as u8, (y * 4) as u8, (x + y) as u8])
        });
        let mut bytes = Vec::new();
        let mut enc = png::Encoder::new(&mut bytes, 97, 61);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(img.as_raw()).unwrap();
        w.finish().unwrap();
        let file = write(dir.path(), "in.png", &bytes);
        let from_file = dir.path().join("file.pbm");
        let from_stdin = dir.path().join("stdin.pbm");
        assert_ok(&run(&["convert", s(&file), "-o", s(&from_file)]));
        let r = run_with(
            halftone(&["convert", "-", "-o", s(&from_stdin)]),
            Some(Stdio::from(std::fs::File::open(&file).unwrap())),
            Duration::from_secs(30),
        );
        assert_ok(&r);
        assert_eq!(
            std::fs::read(&from_file).unwrap(),
            std::fs::read(&from_stdin).unwrap()
        );
    }
}

#[test]
fn device_profile_over_the_pixel_limit_is_named_not_fit() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("devices/bwry-4in2.toml"),
    )
    .unwrap();
    let re = |t: &str, key: &str, v: &str| -> String {
        t.lines()
            .map(|l| {
                if l.starts_with(&format!("{key} =")) {
                    format!("{key} = {v}")
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    let big = re(&re(&text, "width", "100000"), "height", "100000");
    let profile = write(dir.path(), "huge-panel.toml", big.as_bytes());
    let input = write(dir.path(), "in.pgm", &pgm(64, 48));
    let out = dir.path().join("out.png");
    let r = run(&["convert", s(&input), "-o", s(&out), "--device", s(&profile)]);
    assert_fails(&r, "huge-panel.toml: its panel makes the output", 10.0);
    assert!(r.stderr.contains("100000x100000"), "{}", r.stderr);
    assert!(
        !r.stderr.contains("--fit:"),
        "not blamed on --fit: {}",
        r.stderr
    );
    // A --fit given is still named as the cause of its own size.
    let r = run(&[
        "convert",
        s(&input),
        "-o",
        s(&out),
        "--fit",
        "100000x100000",
    ]);
    assert_fails(&r, "--fit: the output would be 100000x75000", 10.0);
    assert!(listing(dir.path()).len() == 2);
}

#[test]
fn negative_slurm_task_id_says_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir(&inputs).unwrap();
    std::fs::write(inputs.join("a.pgm"), pgm(8, 8)).unwrap();
    let out = dir.path().join("out");
    let mut cmd = halftone(&["batch", s(&inputs), "-o", s(&out), "--shard", "auto/4"]);
    cmd.env("SLURM_ARRAY_TASK_ID", "-1");
    let r = run_with(cmd, None, Duration::from_secs(30));
    assert_fails(&r, "SLURM_ARRAY_TASK_ID=\"-1\" is below 0", 10.0);
    assert!(!r.stderr.contains("not a whole number"), "{}", r.stderr);
    assert!(!out.exists());
}

#[test]
fn compare_device_fits_the_original_as_convert_does() {
    let dir = tempfile::tempdir().unwrap();
    // A photo not of the panel's size (400x300 on the 400x300 panel turned: bwry-4in2 is
    // 400x300; take 800x450 so it must be fitted and padded).
    let photo = image::RgbImage::from_fn(800, 450, |x, y| {
        image::Rgb([(x / 4) as u8, (y / 2) as u8, ((x + y) / 5) as u8])
    });
    let photo_path = dir.path().join("photo.png");
    photo.save(&photo_path).unwrap();
    let frame = dir.path().join("frame.png");
    assert_ok(&run(&[
        "convert",
        s(&photo_path),
        "-o",
        s(&frame),
        "--device",
        "bwry-4in2",
    ]));
    let r = run(&[
        "compare",
        s(&photo_path),
        s(&frame),
        "--device",
        "bwry-4in2",
        "--json",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(!r.stderr.contains("warning"), "{}", r.stderr);
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let de = v["de2000"].as_f64().unwrap();
    assert!(de > 0.0 && de < 40.0, "{v}");
    // The same as comparing with the original fitted by hand to the panel: the photo made
    // panel-sized first by convert's own fit (as a continuous-tone PNG).
    // A "halftone" that is the photo itself, resized (thousands of colours): a warning.
    let fake = dir.path().join("fake.png");
    let small = image::imageops::resize(&photo, 400, 300, image::imageops::FilterType::Triangle);
    small.save(&fake).unwrap();
    let r = run(&["compare", s(&photo_path), s(&fake), "--device", "bwry-4in2"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stderr
            .contains("fake.png has 5 or more colours, more than the 4 inks"),
        "{}",
        r.stderr
    );
}
