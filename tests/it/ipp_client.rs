//! The client side of printing: `convert -o page.pwg / .urf / .ras`, `halftone print` and
//! a queue's `ipp://` backend, checked through independent programs: CUPS's reference
//! printer `ippeveprinter` (started here, keeping what it receives), cups-filters'
//! `rastertopdf` (reads PWG, Apple and CUPS raster) and poppler's `pdftoppm`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common;
use crate::serve::Server;

const RASTERTOPDF: &str = "/usr/lib/cups/filter/rastertopdf";
const IPPEVEPRINTER: &str = "/usr/sbin/ippeveprinter";

/// A grey test picture of 200 × 150 pixels: at 100 dpi its page is 144 × 108 pt exactly,
/// so no renderer has to round the page's size.
fn picture(dir: &Path) -> PathBuf {
    let img = image::GrayImage::from_fn(200, 150, |x, y| {
        image::Luma([((x * 255 / 200 + (y % 7) * 3) % 256) as u8])
    });
    let p = dir.join("g.png");
    img.save(&p).unwrap();
    p
}

fn have(path: &str, package: &str, check: &str) -> bool {
    if Path::new(path).is_file() {
        return true;
    }
    common::skip(
        check,
        &format!("{path} is missing (apt-get install {package})"),
    );
    false
}

fn tools(check: &str) -> bool {
    have(RASTERTOPDF, "cups-filters", check)
        && common::have_tool("pdftoppm", "poppler-utils", check)
}

/// A decoded page: width, height, channels (1 or 3), samples.
type Page = (usize, usize, usize, Vec<u8>);

fn read_pnm(data: &[u8]) -> Page {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while data[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while !data[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&data[start..i]).into_owned());
        if fields[0] == "P4" && fields.len() == 3 {
            break;
        }
    }
    i += 1;
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    match fields[0].as_str() {
        // P4: 1 = ink, as grey codes 0 (ink) / 255.
        "P4" => {
            let stride = w.div_ceil(8);
            let px = (0..w * h)
                .map(|k| {
                    let (x, y) = (k % w, k / w);
                    if data[i + y * stride + x / 8] >> (7 - x % 8) & 1 == 1 {
                        0
                    } else {
                        255
                    }
                })
                .collect();
            (w, h, 1, px)
        }
        "P5" => (w, h, 1, data[i..i + w * h].to_vec()),
        "P6" => (w, h, 3, data[i..i + w * h * 3].to_vec()),
        t => panic!("not a PNM: {t}"),
    }
}

/// `file` (PWG, Apple or CUPS raster) through `rastertopdf`, then every page through
/// `pdftoppm` at four times `dpi`: each 4 × 4 block must be one colour (poppler smooths
/// images drawn at less than four times their size), and that colour is the pixel.
fn through_cups(file: &Path, dpi: u32, colour: bool) -> Vec<Page> {
    let dir = tempfile::tempdir().unwrap();
    let pdf = dir.path().join("out.pdf");
    let out = Command::new(RASTERTOPDF)
        .args(["1", "user", "title", "1", ""])
        .arg(file)
        .stderr(Stdio::null())
        .output()
        .unwrap();
    assert!(out.status.success(), "rastertopdf {}", file.display());
    std::fs::write(&pdf, &out.stdout).unwrap();
    let st = Command::new("pdftoppm")
        .args(["-r", &(4 * dpi).to_string()])
        .args(if colour { &[][..] } else { &["-gray"][..] })
        .arg(&pdf)
        .arg(dir.path().join("p"))
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(st.success());
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with("p-"))
        .collect();
    names.sort();
    names
        .iter()
        .map(|n| {
            let (w4, h4, ch, px) = read_pnm(&std::fs::read(n).unwrap());
            let (w, h) = (w4 / 4, h4 / 4);
            let mut out = Vec::with_capacity(w * h * ch);
            for y in 0..h {
                for x in 0..w {
                    for c in 0..ch {
                        let at =
                            |dx: usize, dy: usize| px[((4 * y + dy) * w4 + 4 * x + dx) * ch + c];
                        let v = at(0, 0);
                        for (dx, dy) in (0..16).map(|k| (k % 4, k / 4)) {
                            assert_eq!(
                                at(dx, dy),
                                v,
                                "{}: a smoothed block at {x},{y}",
                                file.display()
                            );
                        }
                        out.push(v);
                    }
                }
            }
            (w, h, ch, out)
        })
        .collect()
}

/// `halftone convert ARGS`.
/// `halftone convert SRC -o OUT FLAGS…`, which must succeed.
fn convert(src: &Path, out: &Path, flags: &[&str]) {
    let mut a: Vec<&std::ffi::OsStr> = vec![
        "convert".as_ref(),
        src.as_ref(),
        "-o".as_ref(),
        out.as_ref(),
    ];
    a.extend(flags.iter().map(std::ffi::OsStr::new));
    common::ok(&a);
}

/// Black and white as black (below 128) or white: rastertopdf colour-manages sGray, so
/// white may come back 250.
fn ink(p: &Page) -> Vec<bool> {
    p.3.iter().map(|&v| v < 128).collect()
}

#[test]
fn raster_writers_decode_through_cups_to_our_pixels() {
    const CHECK: &str = "ipp_client: PWG/URF/CUPS raster through rastertopdf";
    if !tools(CHECK) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let src = picture(dir.path());
    let o = |n: &str| dir.path().join(n);
    // Bilevel: black_1 (PWG, CUPS v3), sgray_8 0/255 (URF); the PBM's bits exactly.
    convert(&src, &o("b.pbm"), &["--dpi", "100"]);
    let want = read_pnm(&std::fs::read(o("b.pbm")).unwrap());
    for ext in ["pwg", "urf", "ras"] {
        let f = o(&format!("b.{ext}"));
        convert(&src, &f, &["--dpi", "100"]);
        let pages = through_cups(&f, 100, false);
        assert_eq!(pages.len(), 1, "{ext}");
        assert_eq!((pages[0].0, pages[0].1), (200, 150), "{ext}");
        assert_eq!(ink(&pages[0]), ink(&want), "{ext}: the bits differ");
        // And our own reader gives the same page back.
        let data = std::fs::read(&f).unwrap();
        let lang = halftone::io::lang::Language::sniff(&data).unwrap();
        let ours = lang.pages(&data).unwrap();
        let g = match &ours[0].planes[0] {
            halftone::raster::Samples::U8(v) => v.clone(),
            _ => panic!("16-bit"),
        };
        assert_eq!(g, want.3, "{ext}: our reader");
        eprintln!("bilevel 200x150 at 100 dpi as {ext}: {} bytes", data.len());
    }
    // Four grey levels (sgray_8): rastertopdf maps sGray through a colour profile, so each
    // of our codes must come back as one code of its own (the same four levels, in order).
    convert(&src, &o("l.pgm"), &["--dpi", "100", "--levels", "4"]);
    let want = read_pnm(&std::fs::read(o("l.pgm")).unwrap());
    for ext in ["pwg", "urf", "ras"] {
        let f = o(&format!("l.{ext}"));
        convert(&src, &f, &["--dpi", "100", "--levels", "4"]);
        let got = through_cups(&f, 100, false).remove(0);
        let mut map = std::collections::BTreeMap::new();
        for (&a, &b) in want.3.iter().zip(&got.3) {
            assert_eq!(
                *map.entry(a).or_insert(b),
                b,
                "{ext}: code {a} came back as two codes"
            );
        }
        assert_eq!(map.len(), 4, "{ext}");
        let back: Vec<u8> = map.values().copied().collect();
        assert!(back.windows(2).all(|w| w[0] < w[1]), "{ext}: {map:?}");
        assert_eq!(map[&0], 0, "{ext}");
    }
    // Colour (srgb_8) from PWG raster: every sample exactly.
    convert(
        &src,
        &o("c.ppm"),
        &["--dpi", "100", "--color", "rgb", "--levels", "3"],
    );
    convert(
        &src,
        &o("c.pwg"),
        &["--dpi", "100", "--color", "rgb", "--levels", "3"],
    );
    let want = read_pnm(&std::fs::read(o("c.ppm")).unwrap());
    let got = through_cups(&o("c.pwg"), 100, true).remove(0);
    assert_eq!((got.0, got.1, got.2), (200, 150, 3));
    assert_eq!(got.3, want.3, "srgb_8 samples differ");
}

/// A running `ippeveprinter` taking PWG and Apple raster, keeping each job's document in
/// its spool folder; stopped when dropped.
struct Eve {
    child: Child,
    port: u16,
    spool: tempfile::TempDir,
}

impl Eve {
    fn start() -> Eve {
        let spool = tempfile::tempdir().unwrap();
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(IPPEVEPRINTER)
            .args([
                "-r",
                "off",
                "-n",
                "localhost",
                "-k",
                "-f",
                "image/pwg-raster,image/urf",
            ])
            .arg("-p")
            .arg(port.to_string())
            .arg("-d")
            .arg(spool.path())
            .arg("halftone-test")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut eve = Eve { child, port, spool };
        let start = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            if let Ok(Some(st)) = eve.child.try_wait() {
                panic!("ippeveprinter ended at once ({st}); is avahi-daemon running?");
            }
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "ippeveprinter never listened"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        eve.port = port;
        eve
    }

    fn uri(&self) -> String {
        format!("ipp://127.0.0.1:{}/ipp/print", self.port)
    }

    /// The documents kept so far, by name.
    fn files(&self) -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(self.spool.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "pwg" || e == "urf"))
            .collect();
        v.sort();
        v
    }

    /// Waits for a kept document that is not in `seen`.
    fn next_file(&self, seen: &mut Vec<PathBuf>) -> PathBuf {
        let start = Instant::now();
        loop {
            if let Some(f) = self.files().into_iter().find(|f| !seen.contains(f)) {
                // Written by ippeveprinter as it arrives: wait until its size settles.
                let mut size = 0;
                loop {
                    std::thread::sleep(Duration::from_millis(200));
                    let now = std::fs::metadata(&f).unwrap().len();
                    if now == size && now > 0 {
                        break;
                    }
                    size = now;
                }
                seen.push(f.clone());
                return f;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "no new document");
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Eve {
    fn drop(&mut self) {
        common::stop_server(&mut self.child);
    }
}

#[test]
fn print_and_forward_to_ippeveprinter() {
    const CHECK: &str = "ipp_client: halftone print and ipp:// to ippeveprinter";
    if !tools(CHECK)
        || !have(IPPEVEPRINTER, "cups-ipp-utils", CHECK)
        || !common::have_tool("ipptool", "cups-ipp-utils", CHECK)
        || !crate::serve_dnssd::avahi_running()
    {
        return;
    }
    let eve = Eve::start();
    let dir = tempfile::tempdir().unwrap();
    let src = picture(dir.path());
    let o = |n: &str| dir.path().join(n);
    let mut seen = Vec::new();

    // `halftone print`: PWG raster at the printer's default 600 dpi, fitted to its default
    // paper (Letter), waited for: the bytes `convert` writes with that page and box.
    let t = Instant::now();
    let line = common::ok(&["print".as_ref(), eve.uri().as_ref(), src.as_os_str()]);
    eprintln!(
        "halftone print to ippeveprinter: {:.2} s: {}",
        t.elapsed().as_secs_f64(),
        line.trim()
    );
    assert!(
        line.contains("completed") && line.contains("pwg at 600 dpi on na_letter_8.5x11in"),
        "{line}"
    );
    let got = eve.next_file(&mut seen);
    convert(
        &src,
        &o("m.pwg"),
        &["--dpi", "600", "--page", "letter", "--fit", "5100x6600"],
    );
    assert_eq!(
        std::fs::read(&got).unwrap(),
        std::fs::read(o("m.pwg")).unwrap()
    );
    let page = &halftone::io::lang::Language::Pwg
        .pages(&std::fs::read(&got).unwrap())
        .unwrap()[0];
    assert_eq!((page.width, page.height), (5100, 6600));

    // At the picture's own size (`--width`): decodes through CUPS to convert's PBM.
    let line = common::ok(&[
        "print".as_ref(),
        eve.uri().as_ref(),
        src.as_os_str(),
        "--width".as_ref(),
        "200".as_ref(),
    ]);
    assert!(
        line.contains("1 page of pwg at 600 dpi, 5531 bytes"),
        "{line}"
    );
    let got = eve.next_file(&mut seen);
    convert(&src, &o("p.pwg"), &["--dpi", "600"]);
    convert(&src, &o("p.pbm"), &["--dpi", "600"]);
    assert_eq!(
        std::fs::read(&got).unwrap(),
        std::fs::read(o("p.pwg")).unwrap()
    );
    let want = read_pnm(&std::fs::read(o("p.pbm")).unwrap());
    let pages = through_cups(&got, 600, false);
    assert_eq!(ink(&pages[0]), ink(&want));

    // Two files, Apple raster at the one resolution it lists, one job of two pages.
    let line = common::ok(&[
        "print".as_ref(),
        eve.uri().as_ref(),
        src.as_os_str(),
        src.as_os_str(),
        "--format".as_ref(),
        "urf".as_ref(),
        "--method".as_ref(),
        "ordered".as_ref(),
        "--width".as_ref(),
        "200".as_ref(),
    ]);
    assert!(line.contains("2 pages of urf at 600 dpi,"), "{line}");
    let got = eve.next_file(&mut seen);
    convert(&src, &o("u.pbm"), &["--dpi", "600", "--method", "ordered"]);
    let want = read_pnm(&std::fs::read(o("u.pbm")).unwrap());
    let pages = through_cups(&got, 600, false);
    assert_eq!(pages.len(), 2);
    for p in &pages {
        assert_eq!(ink(p), ink(&want));
    }

    // Errors: one line naming the URI and the cause, a non-zero exit.
    let err = |args: &[&str]| {
        let out = common::halftone().args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        let e = String::from_utf8_lossy(&out.stderr).trim().to_string();
        assert_eq!(e.lines().count(), 1, "{e}");
        e
    };
    let s = src.to_str().unwrap();
    let e = err(&["print", &eve.uri(), s, "--dpi", "300", "--format", "urf"]);
    assert!(e.contains(&eve.uri()) && e.contains("600"), "{e}");
    let e = err(&["print", &eve.uri(), s, "--color", "rgb"]);
    assert!(e.contains(&eve.uri()) && e.contains("colour"), "{e}");
    let e = err(&["print", "ipps://127.0.0.1:1/ipp/print", s]);
    assert!(e.contains("TLS"), "{e}");
    let e = err(&["print", "ipp://127.0.0.1:1/ipp/print", s]);
    assert!(
        e.contains("ipp://127.0.0.1:1/ipp/print") && e.contains("refused"),
        "{e}"
    );

    // A queue forwarding to ippeveprinter. In its own format (PWG raster at 600 dpi): the
    // bytes convert writes. In ESC/POS (thermal-203): the same dots, re-wrapped as PWG.
    for (args, reference) in [
        (vec!["--format", "pwg", "--dpi", "600"], "q.pwg"),
        (vec!["--preset", "thermal-203"], "q.escpos"),
    ] {
        let backend = eve.uri();
        let mut a = vec!["--queue", "q", "--backend", backend.as_str(), "--no-dnssd"];
        a.extend(&args);
        let server = Server::start(&a);
        let queue = format!("ipp://127.0.0.1:{}/ipp/print/q", server.port);
        let out = Command::new("ipptool")
            .arg("-tf")
            .arg(&src)
            .arg(&queue)
            .arg("print-job.test")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
        let got = eve.next_file(&mut seen);
        convert(&src, &o(reference), &args);
        let data = std::fs::read(&got).unwrap();
        let want = std::fs::read(o(reference)).unwrap();
        if reference.ends_with(".pwg") {
            assert_eq!(data, want, "forwarded as is");
        } else {
            let lang = halftone::io::lang::Language::sniff(&want).unwrap();
            let dots = &lang.pages(&want).unwrap()[0];
            let fwd = &halftone::io::lang::Language::Pwg.pages(&data).unwrap()[0];
            assert_eq!((fwd.width, fwd.height), (dots.width, dots.height));
            assert_eq!(fwd.planes, dots.planes, "the receipt's dots");
            let dpi = fwd.dpi.unwrap() as u32;
            let through = through_cups(&got, dpi, false);
            let g = match &dots.planes[0] {
                halftone::raster::Samples::U8(v) => v.clone(),
                _ => panic!(),
            };
            assert_eq!(
                ink(&through[0]),
                g.iter().map(|&v| v < 128).collect::<Vec<_>>()
            );
        }
        eprintln!("queue {args:?} → ippeveprinter: {} bytes", data.len());
    }

    // A queue whose jobs the printer cannot take (PNG): the job aborts with the backend's
    // reason, and `halftone print` to that queue says so in one line, exit 1; `--no-wait`
    // returns once the job is accepted.
    let backend = eve.uri();
    let server = Server::start(&[
        "--queue",
        "q",
        "--backend",
        &backend,
        "--no-dnssd",
        "--format",
        "png",
    ]);
    let queue = format!("ipp://127.0.0.1:{}/ipp/print/q", server.port);
    let e = err(&["print", &queue, s]);
    assert!(
        e.contains(&format!("{queue}: job 1 aborted"))
            && e.contains("give the queue a printer format"),
        "{e}"
    );
    let line = common::ok(&[
        "print".as_ref(),
        queue.as_ref(),
        src.as_os_str(),
        "--no-wait".as_ref(),
    ]);
    assert!(
        line.starts_with(&format!("{queue}: job 2 sent: 1 page of pwg")),
        "{line}"
    );
}
