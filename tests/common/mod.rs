//! What the integration tests share: the rule for checks that cannot run here ([`skip`]:
//! a failure under CI, a loud line and an end-of-run summary elsewhere), the real
//! photographs the photo tests run on, a camera-like grain, and the binary's `compare` score.

use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// Grace Hopper (Debian's python-matplotlib-data, installed by .ci/run).
pub const HOPPER: &str = "/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg";
/// scikit-image's sample photos (Debian's python3-skimage), unless `HALFTONE_SKIMAGE_DATA`
/// names another folder (.ci/run unpacks the package's files without installing it).
pub const SKIMAGE: &str = "/usr/lib/python3/dist-packages/skimage/data";

fn skimage_dir() -> PathBuf {
    std::env::var_os("HALFTONE_SKIMAGE_DATA").map_or_else(|| PathBuf::from(SKIMAGE), PathBuf::from)
}

/// The binary under test.
pub fn halftone() -> Command {
    Command::cargo_bin("halftone").unwrap()
}

/// `halftone convert INPUT -o OUT ARGS --max-memory BUDGET`, run to its end.
pub fn convert_with_budget(
    input: &Path,
    out: &Path,
    args: &[&str],
    budget: &str,
) -> std::process::Output {
    convert_cmd(input, out, args, budget).output().unwrap()
}

fn convert_cmd(input: &Path, out: &Path, args: &[&str], budget: &str) -> Command {
    let mut c = halftone();
    c.arg("convert")
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(args)
        .args(["--max-memory", budget]);
    c
}

/// The photos, decoded: Grace Hopper (required under CI) and whichever of `skimage` (file
/// names in [`SKIMAGE`]) are installed. HALFTONE_TEST_PHOTOS, a path list, replaces them.
pub fn photos(skimage: &[&str]) -> Vec<(String, image::RgbImage)> {
    let mut out = Vec::new();
    if let Some(extra) = std::env::var_os("HALFTONE_TEST_PHOTOS") {
        for p in std::env::split_paths(&extra) {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            out.push((name, image::open(&p).unwrap().to_rgb8()));
        }
        return out;
    }
    match image::open(HOPPER) {
        Ok(img) => out.push(("grace_hopper".into(), img.to_rgb8())),
        Err(_) => skip(
            "photos: grace_hopper.jpg",
            &format!("{HOPPER} is missing (apt-get install python-matplotlib-data)"),
        ),
    }
    let dir = skimage_dir();
    for name in skimage {
        match image::open(dir.join(name)) {
            Ok(img) => out.push((name.split('.').next().unwrap().into(), img.to_rgb8())),
            Err(_) => skip(
                &format!("photos: {name}"),
                &format!(
                    "not in {} (python3-skimage's data; .ci/run unpacks it and sets HALFTONE_SKIMAGE_DATA)",
                    dir.display()
                ),
            ),
        }
    }
    out
}

/// A fine grain of ±8 codes (a fixed xorshift sequence), as a camera's sensor leaves and an
/// enlarged small photo lacks.
pub fn grain<'a>(v: impl Iterator<Item = &'a mut u8>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for v in v {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        *v = (*v as i32 + (state % 17) as i32 - 8).clamp(0, 255) as u8;
    }
}

/// Runs the binary with `args`, which must succeed; its standard output.
pub fn ok(args: &[&std::ffi::OsStr]) -> String {
    let out = halftone().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "halftone {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// HVS-PSNR of `halftone` against `original`, by `halftone compare`.
pub fn hvs_psnr(original: &Path, halftone: &Path) -> f64 {
    let json = ok(&[
        "compare".as_ref(),
        original.as_os_str(),
        halftone.as_os_str(),
        "--json".as_ref(),
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    v["quality"]["hvs_psnr_db"].as_f64().unwrap()
}

/// Converts `input` with `args` under every `--max-memory` of `budgets`, on one thread and
/// on two, and asserts that every run succeeds with the same output bytes.
pub fn same_bytes_for_every_budget(input: &Path, args: &[&str], budgets: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.out");
    let mut first: Option<Vec<u8>> = None;
    for budget in budgets {
        for threads in [1, 2] {
            let o = convert_cmd(input, &out, args, budget)
                .env("RAYON_NUM_THREADS", threads.to_string())
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "{input:?} {args:?} {budget}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let bytes = std::fs::read(&out).unwrap();
            match &first {
                None => first = Some(bytes),
                Some(f) => assert!(
                    *f == bytes,
                    "{input:?} {args:?}: budget {budget}, {threads} threads differ"
                ),
            }
        }
    }
}

/// The full decode `img` resized to `w × h` in linear light, as a 16-bit sRGB PGM of its
/// luminance at `out`.
pub fn reference(img: &halftone::Image, w: usize, h: usize, out: &Path) {
    let tone = halftone::ToneOptions::default();
    let small = halftone::resize::resize(img, w, h, &tone).unwrap();
    let y = small.to_luminance(&tone);
    let halftone::raster::Samples::U16(v) = &y.planes[0] else {
        panic!("16-bit linear luminance expected")
    };
    let mut pgm = format!("P5\n{w} {h}\n65535\n").into_bytes();
    for &c in v {
        let s = halftone::tone::linear_to_srgb(c as f64 / 65535.0);
        pgm.extend_from_slice(&((s * 65535.0).round() as u16).to_be_bytes());
    }
    std::fs::write(out, pgm).unwrap();
}

/// `jpeg` (a JPEG file's bytes, with no EXIF block) with an APP1 `Exif` block after its
/// start-of-image marker that gives EXIF orientation `o`.
pub fn with_orientation(jpeg: &[u8], o: u16) -> Vec<u8> {
    // Big-endian TIFF, one IFD0 entry: tag 0x0112 (orientation), SHORT, count 1.
    let mut tiff = b"MM\0\x2a\0\0\0\x08\0\x01".to_vec();
    tiff.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1]);
    tiff.extend_from_slice(&o.to_be_bytes());
    tiff.extend_from_slice(&[0, 0, 0, 0, 0, 0]);
    let mut seg = b"Exif\0\0".to_vec();
    seg.extend_from_slice(&tiff);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((seg.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&seg);
    out.extend_from_slice(&jpeg[2..]);
    out
}

// ---- checks that cannot run here ------------------------------------------------------

/// Whether the suite runs under CI (the `CI` variable set), where every check must run: a
/// missing tool, file, feature or CPU path is a failure there, never a skip.
pub fn in_ci() -> bool {
    std::env::var_os("CI").is_some_and(|v| !v.is_empty() && v != "false" && v != "0")
}

/// The checks skipped so far in this run, printed once more when the process exits.
static SKIPPED: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

/// Prints the list of skipped checks after the harness's own summary.
extern "C" fn print_skipped() {
    use std::io::Write;
    let list = SKIPPED.lock().unwrap_or_else(|e| e.into_inner());
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "\n==== {} check(s) SKIPPED (with CI=true each is a failure) ====",
        list.len()
    );
    for line in list.iter() {
        let _ = writeln!(err, "  {line}");
    }
}

extern "C" {
    /// The C library's `atexit`: run the summary when the test binary exits.
    fn atexit(f: extern "C" fn()) -> std::ffi::c_int;
}

/// A check named `check` cannot run here because of `why` (say what installs it). Under
/// CI this panics, failing the test; elsewhere it prints a loud line at once (to standard
/// error, past the harness's capture) and lists the check again when the run ends.
pub fn skip(check: &str, why: &str) {
    use std::io::Write;
    let line = format!("{check}: {why}");
    assert!(!in_ci(), "under CI every check must run: {line}");
    let _ = writeln!(std::io::stderr().lock(), "SKIPPED {line}");
    let mut list = SKIPPED.lock().unwrap_or_else(|e| e.into_inner());
    if list.is_empty() {
        // SAFETY: registers a plain function with no arguments; it only locks and prints.
        unsafe { atexit(print_skipped) };
    }
    list.push(line);
}

/// Whether the program `tool` is on the `PATH`; if not, [`skip`]s `check` naming the
/// Debian package `package` that has it.
pub fn have_tool(tool: &str, package: &str, check: &str) -> bool {
    let found = std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths).any(|d| {
            let p = d.join(tool);
            p.is_file()
                && std::fs::metadata(&p).is_ok_and(|m| {
                    std::os::unix::fs::PermissionsExt::mode(&m.permissions()) & 0o111 != 0
                })
        })
    });
    if !found {
        skip(
            check,
            &format!("{tool} is not installed (apt-get install {package})"),
        );
    }
    found
}

/// A child's own peak resident size. `wait4`'s `ru_maxrss` cannot be used alone: Linux
/// carries the parent's peak into the child across `exec`, so a test harness grown large by
/// other tests would count as the child's. The command line writes its `VmHWM` to the file
/// named by `HALFTONE_PEAK_FILE` on the way out; a child killed before that falls back to
/// `ru_maxrss` (an upper bound).
#[cfg(unix)]
pub struct PeakFile {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

#[cfg(unix)]
impl PeakFile {
    /// Sets `HALFTONE_PEAK_FILE` on `cmd` to a fresh file.
    pub fn new(cmd: &mut std::process::Command) -> PeakFile {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("peak");
        cmd.env("HALFTONE_PEAK_FILE", &path);
        PeakFile { _dir: dir, path }
    }

    /// The child's peak in KiB, once it has ended (`usage`: its `wait4` figures).
    pub fn kib(&self, usage: &libc::rusage) -> u64 {
        std::fs::read_to_string(&self.path)
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(usage.ru_maxrss as u64)
    }
}

/// Stops a `halftone serve` child as `kill` or systemd would: SIGTERM, so it withdraws its
/// DNS-SD services (else Avahi keeps them, unresolvable, for their records' lifetime), then
/// SIGKILL after 3 s.
pub fn stop_server(child: &mut std::process::Child) {
    let _ = std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let start = std::time::Instant::now();
    while start.elapsed() < std::time::Duration::from_secs(3) {
        if let Ok(Some(_)) = child.try_wait() {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let _ = child.kill();
    let _ = child.wait();
}
