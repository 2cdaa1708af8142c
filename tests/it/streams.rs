//! Inputs that are not regular files, on the real binary: a FIFO with a slow writer, bash
//! process substitution, `/dev/stdin` from a pipe, a here-file, `/proc/self/fd/N`, and
//! standard input that never ends. Every readable input gives the bytes the regular file
//! gives; every endless one stops within seconds and a bounded amount of memory (peak
//! resident size from `wait4`), with a message that names the limit or the broken header.
#![cfg(unix)]

use std::io::Write;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use image::{ImageFormat, RgbImage};

/// The binary under test; `HALFTONE_BIN` names another build to run these tests against
/// (an older one, to see them fail).
fn bin() -> PathBuf {
    std::env::var_os("HALFTONE_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| assert_cmd::cargo::cargo_bin("halftone"))
}

/// Runs `cmd` to its end, killed after 60 s: a reader that opens a FIFO a second time
/// would wait for a writer for ever.
fn output_within(cmd: &mut Command) -> std::process::Output {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("{cmd:?}: still running after 60 s");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// True when `bash` runs; under CI its absence is a failure, elsewhere a loud skip.
fn have_bash() -> bool {
    let ok = Command::new("bash")
        .args(["-c", "true"])
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        crate::common::skip(
            "streams (process substitution)",
            "bash is not installed (apt-get install bash)",
        );
    }
    ok
}

/// A small photo-like RGB image: gradients and a ring, so every format has real content.
fn picture() -> RgbImage {
    RgbImage::from_fn(67, 45, |x, y| {
        let (dx, dy) = (x as f32 - 33.0, y as f32 - 22.0);
        let ring = ((dx * dx + dy * dy).sqrt() * 0.7).sin() * 60.0;
        image::Rgb([
            (x * 255 / 66) as u8,
            (y * 255 / 44) as u8,
            (128.0 + ring) as u8,
        ])
    })
}

/// The picture in every input format, as (extension, file bytes).
fn files() -> Vec<(&'static str, Vec<u8>)> {
    let img = picture();
    let grey = image::DynamicImage::ImageRgb8(img.clone()).to_luma8();
    let mut out = Vec::new();
    for (ext, format) in [
        ("png", ImageFormat::Png),
        ("jpg", ImageFormat::Jpeg),
        ("gif", ImageFormat::Gif),
        ("tif", ImageFormat::Tiff),
        ("bmp", ImageFormat::Bmp),
        ("webp", ImageFormat::WebP),
        ("ppm", ImageFormat::Pnm),
    ] {
        let mut c = std::io::Cursor::new(Vec::new());
        img.write_to(&mut c, format).unwrap();
        out.push((ext, c.into_inner()));
    }
    let mut c = std::io::Cursor::new(Vec::new());
    grey.write_to(&mut c, ImageFormat::Pnm).unwrap();
    out.push(("pgm", c.into_inner()));
    // PAM (P7) and plain PGM (P2), written by hand.
    let mut pam = format!(
        "P7\nWIDTH {}\nHEIGHT {}\nDEPTH 1\nMAXVAL 255\nTUPLTYPE GRAYSCALE\nENDHDR\n",
        grey.width(),
        grey.height()
    )
    .into_bytes();
    pam.extend_from_slice(grey.as_raw());
    out.push(("pam", pam));
    let mut plain = format!("P2\n{} {}\n255\n", grey.width(), grey.height());
    for row in grey.as_raw().chunks(grey.width() as usize) {
        let row: Vec<String> = row.iter().map(|v| v.to_string()).collect();
        plain.push_str(&row.join(" "));
        plain.push('\n');
    }
    out.push(("plain.pgm", plain.into_bytes()));
    out
}

/// `halftone convert INPUT -o OUT --levels 3` as a command.
fn convert(input: &Path, out: &Path) -> Command {
    let mut c = Command::new(bin());
    c.arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(["--levels", "3"]);
    c
}

fn check(out: std::process::Output, what: &str) {
    assert!(
        out.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn mkfifo(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

/// Writes `bytes` into `w` in small pieces with pauses, as a slow producer does.
fn slowly(mut w: impl Write, bytes: &[u8]) {
    let piece = (bytes.len() / 6).max(1);
    for chunk in bytes.chunks(piece) {
        if w.write_all(chunk).is_err() {
            return;
        }
        let _ = w.flush();
        std::thread::sleep(Duration::from_millis(30));
    }
}

#[test]
fn every_kind_of_stream_reads_like_the_regular_file() {
    let dir = tempfile::tempdir().unwrap();
    let bash = have_bash();
    for (ext, bytes) in files() {
        let file = dir.path().join(format!("in.{ext}"));
        std::fs::write(&file, &bytes).unwrap();
        let want_path = dir.path().join(format!("want-{ext}.pgm"));
        check(convert(&file, &want_path).output().unwrap(), ext);
        let want = std::fs::read(&want_path).unwrap();
        let out = dir.path().join("got.pgm");
        let same = |how: &str| {
            let got = std::fs::read(&out).unwrap();
            assert!(
                got == want,
                "{ext} through {how}: not the regular file's output"
            );
            std::fs::remove_file(&out).unwrap();
        };

        // A named FIFO, written slowly by another thread.
        let fifo = dir.path().join(format!("fifo-{ext}"));
        mkfifo(&fifo);
        let (f, b) = (fifo.clone(), bytes.clone());
        let writer = std::thread::spawn(move || slowly(std::fs::File::create(f).unwrap(), &b));
        check(output_within(&mut convert(&fifo, &out)), ext);
        writer.join().unwrap();
        same("a FIFO with a slow writer");

        // `/dev/stdin` on a pipe, written slowly.
        let mut child = convert(Path::new("/dev/stdin"), &out)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take().unwrap();
        let b = bytes.clone();
        let writer = std::thread::spawn(move || slowly(stdin, &b));
        check(child.wait_with_output().unwrap(), ext);
        writer.join().unwrap();
        same("/dev/stdin from a pipe");

        if !bash {
            continue;
        }
        let script = |s: &str| {
            let o = output_within(
                Command::new("bash")
                    .args(["-c", s])
                    .arg(bin())
                    .arg(&file)
                    .arg(&out),
            );
            check(o, &format!("{ext}: {s}"));
        };
        // Process substitution: `/dev/fd/63`, a pipe.
        script(r#""$0" convert <(cat "$1") -o "$2" --levels 3"#);
        same("process substitution");
        // A here-file: standard input redirected from the file, read as `/dev/stdin`.
        script(r#""$0" convert /dev/stdin -o "$2" --levels 3 < "$1""#);
        same("a here-file on /dev/stdin");
        // `/proc/self/fd/N` on a pipe.
        script(r#"exec 3< <(cat "$1"); "$0" convert /proc/self/fd/3 -o "$2" --levels 3"#);
        same("/proc/self/fd/3");
    }
}

#[test]
fn batch_takes_a_process_substitution_as_one_input() {
    if !have_bash() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (_, png) = files().into_iter().next().unwrap();
    let file = dir.path().join("in.png");
    std::fs::write(&file, png).unwrap();
    let outdir = dir.path().join("out");
    let o = Command::new("bash")
        .args(["-c", r#""$0" batch <(cat "$1") -o "$2" -f pgm --levels 3"#])
        .arg(bin())
        .arg(&file)
        .arg(&outdir)
        .output()
        .unwrap();
    check(o, "batch <(cat in.png)");
    let written: Vec<_> = std::fs::read_dir(&outdir).unwrap().flatten().collect();
    assert_eq!(written.len(), 1, "{written:?}");
    let want = dir.path().join("want.pgm");
    check(convert(&file, &want).output().unwrap(), "png");
    assert_eq!(
        std::fs::read(written[0].path()).unwrap(),
        std::fs::read(want).unwrap()
    );
}

/// The end of a run under [`endless`].
struct Run {
    code: Option<i32>,
    stderr: String,
    seconds: f64,
    peak_mib: f64,
}

/// Runs `convert - -o OUT` with `head` and then endless zeros on standard input, and
/// measures the child's time and peak resident size (see `common::PeakFile`). A run past
/// 20 s is killed (and fails the caller's time check).
// The child is reaped by `wait4` below, which `Child::wait` cannot replace: it gives no
// resource usage.
#[allow(clippy::zombie_processes)]
fn endless(head: &[u8], out: &Path) -> Run {
    let err = out.with_extension("err");
    let mut cmd = convert(Path::new("-"), out);
    let peak = crate::common::PeakFile::new(&mut cmd);
    let mut child = cmd
        .stdin(Stdio::piped())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut stdin = child.stdin.take().unwrap();
    let head = head.to_vec();
    // Ends when the reader closes the pipe (EPIPE: the test harness ignores SIGPIPE).
    let writer = std::thread::spawn(move || {
        let zeros = vec![0u8; 1 << 20];
        if stdin.write_all(&head).is_err() {
            return;
        }
        while stdin.write_all(&zeros).is_ok() {}
    });
    let pid = child.id() as libc::pid_t;
    let (status, usage) = loop {
        let mut status = 0;
        // SAFETY: `rusage` is plain data written by the kernel; `pid` is our child, reaped
        // only here.
        let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
        let r = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        assert!(r >= 0, "wait4: {}", std::io::Error::last_os_error());
        if r == pid {
            break (status, usage);
        }
        if start.elapsed() > Duration::from_secs(20) {
            // SAFETY: our own child, not yet reaped.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let seconds = start.elapsed().as_secs_f64();
    writer.join().unwrap();
    let status = std::process::ExitStatus::from_raw(status);
    Run {
        code: status.code(),
        stderr: std::fs::read_to_string(&err).unwrap(),
        seconds,
        // Linux reports kibibytes.
        peak_mib: peak.kib(&usage) as f64 / 1024.0,
    }
}

fn assert_bounded(run: &Run, what: &str) {
    eprintln!(
        "{what}: exit {:?} in {:.2} s, peak {:.0} MiB: {}",
        run.code,
        run.seconds,
        run.peak_mib,
        run.stderr.trim()
    );
    assert!(run.seconds < 5.0, "{what}: {:.2} s", run.seconds);
    assert!(run.peak_mib < 512.0, "{what}: {:.0} MiB", run.peak_mib);
}

#[test]
fn a_signature_then_endless_zeros_stops_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pgm");
    for (sig, why) in [
        (
            &b"\x89PNG\r\n\x1a\n"[..],
            "the first chunk is not the image header (IHDR)",
        ),
        (b"GIF89a", "input limit hit"),
        (b"II*\0", "its first directory (IFD) is at offset 0"),
        (b"MM\0*", "its first directory (IFD) is at offset 0"),
        (
            &[0xFF, 0xD8, 0xFF],
            "marker 0xFF00 at byte 2, before the frame header",
        ),
        (b"BM", "an info header of 0 bytes"),
        (
            b"RIFF\x24\0\0\0WEBPVP8L",
            "no VP8, VP8L or VP8X image header",
        ),
        (
            b"RIFF\xff\xff\xff\xffWEBPVP8X",
            "its RIFF header claims 4294967303 bytes",
        ),
    ] {
        let run = endless(sig, &out);
        let what = format!("{:?} then /dev/zero", String::from_utf8_lossy(sig));
        assert_bounded(&run, &what);
        assert_eq!(run.code, Some(1), "{what}");
        assert!(
            run.stderr.starts_with("halftone: <stdin>: ") && run.stderr.contains(why),
            "{what}: {}",
            run.stderr
        );
        assert!(!out.exists());
    }
}

#[test]
fn a_valid_image_then_endless_zeros_stops_at_its_bound() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.pgm");
    for (ext, bytes) in files() {
        let run = endless(&bytes, &out);
        let what = format!("a valid {ext} then /dev/zero");
        assert_bounded(&run, &what);
        if ["ppm", "pgm", "pam", "webp", "png"].contains(&ext) {
            // The header fixes the length (PNG's rows end with its image data, read as they
            // stream): the image is read, what follows is not.
            assert_eq!(run.code, Some(0), "{what}: {}", run.stderr);
            let want = dir.path().join("want.pgm");
            let file = dir.path().join(format!("in.{ext}"));
            std::fs::write(&file, &bytes).unwrap();
            check(convert(&file, &want).output().unwrap(), ext);
            assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&want).unwrap());
            std::fs::remove_file(&out).unwrap();
        } else {
            assert_eq!(run.code, Some(1), "{what}");
            assert!(
                run.stderr.contains("input limit hit: reading stopped at")
                    && run.stderr.contains("save it to a file"),
                "{what}: {}",
                run.stderr
            );
            assert!(!out.exists());
        }
    }
}

/// `halftone ARGS`: exit code 1 or 2 and the first line of standard error.
fn fails(args: &[&std::ffi::OsStr]) -> String {
    let o = Command::new(bin()).args(args).output().unwrap();
    assert!(!o.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_messages_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str, bytes: &[u8]| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    };
    let out = dir.path().join("out.pgm");
    let (_, png) = files().into_iter().next().unwrap();
    let png = p("in.png", &png);
    let conv = |input: &Path, extra: &[&str]| {
        let mut a: Vec<&std::ffi::OsStr> = vec!["convert".as_ref(), input.as_os_str()];
        a.extend(["-o".as_ref(), out.as_os_str()]);
        a.extend(extra.iter().map(|s| std::ffi::OsStr::new(*s)));
        fails(&a)
    };

    // A lossless WebP of 16384×16384 (the format's largest): the decoder reads 0×0.
    let bits: u32 = 16383 | (16383 << 14);
    let mut webp = b"RIFF\x1a\0\0\0WEBPVP8L\x0e\0\0\0\x2f".to_vec();
    webp.extend_from_slice(&bits.to_le_bytes());
    webp.extend_from_slice(&[0; 9]);
    let e = conv(&p("big.webp", &webp), &[]);
    assert!(e.contains("its header says 16384x16384"), "{e}");
    assert!(!e.contains("0x0"), "{e}");

    // A PAM of DEPTH 0, as a file and as a stream.
    let pam = b"P7\nWIDTH 4\nHEIGHT 4\nDEPTH 0\nMAXVAL 255\nENDHDR\n";
    let e = conv(&p("depth0.pam", pam), &[]);
    assert!(e.contains("depth0.pam: bad PAM header: DEPTH 0"), "{e}");

    // A palette with a mistyped colour: the line is named.
    let pal = p("pal.txt", b"#ff0000\n#gg0000\n#0000ff\n");
    let e = conv(
        &png,
        &["--method", "diffuse", "--palette", pal.to_str().unwrap()],
    );
    assert!(e.contains("pal.txt:2: `#gg0000` is not a colour"), "{e}");
    let pal = p("one.txt", b"#ff0000\n");
    let e = conv(
        &png,
        &["--method", "diffuse", "--palette", pal.to_str().unwrap()],
    );
    assert!(e.contains("only 1 colour in the file"), "{e}");

    // --levels: the real range.
    let e = conv(&png, &["--levels", "100000"]);
    assert!(e.contains("levels must be from 2 to 256"), "{e}");
    assert!(!e.contains("65535"), "{e}");

    // --dpi -5 and --dpi=-5: the same answer, no tip to write `-- -5`.
    for args in [&["--dpi", "-5"][..], &["--dpi=-5"]] {
        let e = conv(&png, args);
        assert!(
            e.contains("a resolution must be a positive number of dots per inch"),
            "{e}"
        );
        assert!(!e.contains("-- -5"), "{e}");
    }

    // --size in scientific notation: parsed, then refused for its size.
    let e = conv(&png, &["--size", "1e308in", "--dpi", "300"]);
    assert!(
        e.contains("--size 1e308in at 300 dpi: the width in pixels is too large to compute"),
        "{e}"
    );
    let mut ok = Command::new(bin());
    ok.arg("convert")
        .arg(&png)
        .arg("-o")
        .arg(&out)
        .args(["--size", "1e-1in", "--dpi", "300"]);
    check(ok.output().unwrap(), "--size 1e-1in");
    let (w, _) = image::image_dimensions(&out).unwrap();
    assert_eq!(w, 30);
}
