//! `halftone serve`: the real binary on 127.0.0.1 with a free port, spoken to over HTTP
//! with hand-made IPP requests, and CUPS's own conformance suite (`ipptool` with
//! `ipp-everywhere.test`, Debian's cups-ipp-utils) against it.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common;

/// A running `halftone serve`, stopped when dropped.
pub(crate) struct Server {
    pub(crate) child: Child,
    pub(crate) port: u16,
}

impl Server {
    /// Starts `halftone serve --listen 127.0.0.1:0 ARGS` and reads the port it prints.
    pub(crate) fn start(args: &[&str]) -> Server {
        Server::start_on("127.0.0.1:0", args)
    }

    /// A server of one queue, `receipt` (the `thermal-203` preset), sending its jobs to
    /// `backend`, with `extra` flags.
    pub(crate) fn receipt(backend: &str, extra: &[&str]) -> Server {
        Server::start(&Server::receipt_args(backend, extra))
    }

    /// The flags of [`Server::receipt`].
    pub(crate) fn receipt_args<'a>(backend: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
        let mut v = vec![
            "--queue",
            "receipt",
            "--preset",
            "thermal-203",
            "--backend",
            backend,
        ];
        v.extend_from_slice(extra);
        v
    }

    /// Starts `halftone serve --listen LISTEN ARGS` and reads the port it prints.
    pub(crate) fn start_on(listen: &str, args: &[&str]) -> Server {
        let mut child = Command::new(assert_cmd::cargo::cargo_bin("halftone"))
            .args(["serve", "--listen", listen])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start halftone serve");
        let mut line = String::new();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        stdout.read_line(&mut line).unwrap();
        // The other queues' lines are read on, so the server never writes to a closed pipe.
        std::thread::spawn(move || std::io::copy(&mut stdout, &mut std::io::sink()));
        // "halftone: serving ipp://127.0.0.1:PORT/ipp/print/NAME (…)"
        let port = line
            .split("ipp://")
            .nth(1)
            .and_then(|r| r.split('/').next())
            .and_then(|h| h.rsplit(':').next())
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no port in {line:?}"));
        Server { child, port }
    }

    /// Stops the server as `kill` or systemd would (SIGTERM); its exit status.
    pub(crate) fn terminate(&mut self) -> std::process::ExitStatus {
        let pid = self.child.id().to_string();
        let ok = Command::new("kill").args(["-TERM", &pid]).status().unwrap();
        assert!(ok.success());
        self.child.wait().unwrap()
    }

    pub(crate) fn uri(&self, queue: &str) -> String {
        format!("ipp://127.0.0.1:{}/ipp/print/{queue}", self.port)
    }

    /// POSTs `body` as application/ipp; `chunked` sends it in chunks after an
    /// `Expect: 100-continue`. Returns the IPP response.
    pub(crate) fn post(&self, queue: &str, body: &[u8], chunked: bool) -> Vec<u8> {
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let head = format!(
            "POST /ipp/print/{queue} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Type: \
             application/ipp\r\nConnection: close\r\n",
            self.port
        );
        s.write_all(head.as_bytes()).unwrap();
        if chunked {
            s.write_all(b"Transfer-Encoding: chunked\r\nExpect: 100-continue\r\n\r\n")
                .unwrap();
            // The interim response, headers and all, before the body is sent.
            let mut cont = Vec::new();
            while !cont.ends_with(b"\r\n\r\n") {
                let mut byte = [0u8];
                s.read_exact(&mut byte).unwrap();
                cont.push(byte[0]);
            }
            assert!(cont.starts_with(b"HTTP/1.1 100 Continue"), "{cont:?}");
            for part in body.chunks(1000) {
                s.write_all(format!("{:x}\r\n", part.len()).as_bytes())
                    .unwrap();
                s.write_all(part).unwrap();
                s.write_all(b"\r\n").unwrap();
            }
            s.write_all(b"0\r\n\r\n").unwrap();
        } else {
            s.write_all(format!("Content-Length: {}\r\n\r\n", body.len()).as_bytes())
                .unwrap();
            s.write_all(body).unwrap();
        }
        let mut resp = Vec::new();
        s.read_to_end(&mut resp).unwrap();
        let end = resp
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .expect("an HTTP response");
        assert!(
            resp.starts_with(b"HTTP/1.1 200"),
            "{:?}",
            String::from_utf8_lossy(&resp[..end])
        );
        resp[end + 4..].to_vec()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        common::stop_server(&mut self.child);
    }
}

/// An IPP/2.0 request by hand: header, operation attributes (charset and language first),
/// job attributes, then the document.
pub(crate) fn request(
    op: u16,
    uri: &str,
    ops: &[(u8, &str, &[u8])],
    job: &[(u8, &str, &[u8])],
    doc: &[u8],
) -> Vec<u8> {
    let mut b = vec![2, 0];
    b.extend_from_slice(&op.to_be_bytes());
    b.extend_from_slice(&1i32.to_be_bytes());
    let put = |b: &mut Vec<u8>, tag: u8, n: &str, v: &[u8]| {
        b.push(tag);
        b.extend_from_slice(&(n.len() as u16).to_be_bytes());
        b.extend_from_slice(n.as_bytes());
        b.extend_from_slice(&(v.len() as u16).to_be_bytes());
        b.extend_from_slice(v);
    };
    b.push(0x01);
    put(&mut b, 0x47, "attributes-charset", b"utf-8");
    put(&mut b, 0x48, "attributes-natural-language", b"en");
    put(&mut b, 0x45, "printer-uri", uri.as_bytes());
    for (t, n, v) in ops {
        put(&mut b, *t, n, v);
    }
    if !job.is_empty() {
        b.push(0x02);
        for (t, n, v) in job {
            put(&mut b, *t, n, v);
        }
    }
    b.push(0x03);
    b.extend_from_slice(doc);
    b
}

pub(crate) fn parse(resp: Vec<u8>) -> ipp::request::IppRequestResponse {
    ipp::parser::IppParser::new(ipp::reader::IppReader::new(std::io::Cursor::new(resp)))
        .parse()
        .expect("an IPP response")
}

/// Waits for `path` to appear (the worker writes it atomically).
pub(crate) fn wait_for(path: &Path) -> Vec<u8> {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(60) {
        if let Ok(b) = std::fs::read(path) {
            return b;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("{} never came", path.display());
}

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("samples")
        .join(name)
}

#[test]
fn print_job_bytes_equal_convert_and_printer_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("jobs");
    std::fs::create_dir(&out).unwrap();
    let backend = format!("file://{}", out.display());
    let server = Server::receipt(&backend, &[]);
    let uri = server.uri("receipt");

    // Get-Printer-Attributes.
    let r = parse(server.post("receipt", &request(0x0b, &uri, &[], &[], &[]), false));
    assert_eq!(r.header().operation_or_status, 0);
    let g = r
        .attributes()
        .first_of(ipp::model::DelimiterTag::PrinterAttributes)
        .unwrap();
    assert_eq!(
        g.get("printer-uri-supported").unwrap().value().to_string(),
        uri
    );
    let formats = g
        .get("document-format-supported")
        .unwrap()
        .value()
        .to_string();
    assert!(
        formats.contains("image/jpeg") && formats.contains("image/png"),
        "{formats}"
    );
    assert_eq!(
        g.get("printer-resolution-default").unwrap().value(),
        &ipp::value::IppValue::Resolution {
            cross_feed: 203,
            feed: 203,
            units: 3
        }
    );

    // Print-Job with a PNG, sent in chunks after Expect: 100-continue; then a second with
    // a vendor attribute choosing the method.
    let png = std::fs::read(sample("shading.png")).unwrap();
    let ops = [
        (0x42u8, "requesting-user-name", &b"test"[..]),
        (0x42, "job-name", b"shading"),
        (0x49, "document-format", b"image/png"),
    ];
    let r = parse(server.post("receipt", &request(0x02, &uri, &ops, &[], &png), true));
    assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
    let got = wait_for(&out.join("job-1.escpos"));
    let want = common::halftone()
        .arg("convert")
        .arg(sample("shading.png"))
        .args(["-o", "-", "--format", "escpos", "--preset", "thermal-203"])
        .output()
        .unwrap();
    assert!(want.status.success());
    assert_eq!(got, want.stdout, "the queue's bytes differ from convert's");

    let job = [(0x44u8, "halftone-method", &b"ordered"[..])];
    let r = parse(server.post("receipt", &request(0x02, &uri, &ops, &job, &png), false));
    assert_eq!(r.header().operation_or_status, 0);
    let got = wait_for(&out.join("job-2.escpos"));
    let want = common::halftone()
        .arg("convert")
        .arg(sample("shading.png"))
        .args(["-o", "-", "--format", "escpos", "--preset", "thermal-203"])
        .args(["--method", "ordered"])
        .output()
        .unwrap();
    assert_eq!(
        got, want.stdout,
        "halftone-method ordered differs from --method ordered"
    );

    // Garbage and a truncated request get IPP errors, and the server still serves.
    let bad = parse(server.post(
        "receipt",
        b"\x02\x00\x00\x0b\x00\x00\x00\x07\x01\x47\xff",
        false,
    ));
    assert_eq!(bad.header().operation_or_status, 0x0400);
    let r = parse(server.post("receipt", &request(0x0b, &uri, &[], &[], &[]), false));
    assert_eq!(r.header().operation_or_status, 0);
}

#[test]
fn a_queue_file_and_its_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        "[queue.labels]\npreset = \"label-203\"\nmethd = \"dbs\"\nbackend = \"file:///tmp\"\n",
    )
    .unwrap();
    let out = common::halftone()
        .args(["serve", "--listen", "127.0.0.1:0", "--config"])
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("queue.labels") && err.contains("methd"),
        "{err}"
    );
}

/// CUPS's IPP Everywhere suite (it includes ipp-2.0.test and ipp-1.1.test), against a
/// 4×6 in label queue from a queue file (so the 4×6 photo tests with each print-quality
/// run too) and a receipt queue. Prints the tally; every test must pass (32 here), the
/// optional Print-URI and Send-URI ones are skipped.
#[test]
fn ipptool_ipp_everywhere() {
    if !common::have_tool(
        "ipptool",
        "cups-ipp-utils",
        "serve: ipptool ipp-everywhere.test",
    ) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let jobs = dir.path().join("jobs");
    std::fs::create_dir(&jobs).unwrap();
    let config = dir.path().join("queues.toml");
    std::fs::write(
        &config,
        format!(
            "[queue.labels]\npreset = \"label-203\"\nbackend = \"file://{0}\"\n\n\
             [queue.receipt]\npreset = \"thermal-203\"\nbackend = \"file://{0}\"\n",
            jobs.display()
        ),
    )
    .unwrap();
    let photo = dir.path().join("photo.jpg");
    let img = image::open(sample("raytrace.png")).unwrap().to_rgb8();
    img.save(&photo).unwrap();
    let server = Server::start(&["--config", config.to_str().unwrap()]);
    for queue in ["labels", "receipt"] {
        let out = Command::new("ipptool")
            .arg("-V")
            .arg("2.0")
            .arg("-tf")
            .arg(&photo)
            .arg(server.uri(queue))
            .arg("ipp-everywhere.test")
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let count = |w: &str| text.matches(w).count();
        let (pass, fail, skip) = (count("[PASS]"), count("[FAIL]"), count("[SKIP]"));
        eprintln!(
            "ipptool ipp-everywhere.test on {queue}: {pass} passed, {fail} failed, {skip} skipped"
        );
        let failed: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("[FAIL]"))
            .map(str::trim)
            .collect();
        // Everything passes; the skipped tests are the optional Print-URI and Send-URI ones.
        assert!(failed.is_empty(), "{queue}: {failed:?}\n{text}");
        let skipped: Vec<&str> = text.lines().filter(|l| l.contains("[SKIP]")).collect();
        assert!(skip <= 7, "{queue}: {skipped:?}");
        assert!(pass >= 32, "{queue}: only {pass} passed\n{text}");
    }
}

/// Ghostscript's rendering of a two-page PostScript file, as PWG raster (black_1, sgray_8,
/// srgb_8, srgb_16) and Apple raster (sgray_8, srgb_8) from its `pwgraster` and `urf`
/// devices, and as PBM/PGM/PPM: the library's decoders give the very pixels of the latter.
#[test]
fn pwg_and_urf_from_ghostscript_decode_to_its_pixels() {
    if !common::have_tool("gs", "ghostscript", "serve: PWG and Apple raster decoders") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // Grey pages for the grey types (a colour's grey differs between Ghostscript's devices:
    // pwgraster converts through its sGray profile), colour pages for the RGB ones.
    let page = |colour: &str| {
        format!(
            "%!PS\n<< /PageSize [144 72] >> setpagedevice\n0.5 setgray 10 10 100 40 rectfill\n\
             {colour} 0 0 20 20 rectfill\n0 setgray 50 50 moveto 140 70 lineto stroke\n\
             showpage\n0.2 setgray 0 0 72 72 rectfill\n0.8 setgray 3 3 30 30 rectfill\nshowpage\n"
        )
    };
    std::fs::write(dir.path().join("grey.ps"), page("0.1 setgray")).unwrap();
    std::fs::write(dir.path().join("colour.ps"), page("1 0 0 setrgbcolor")).unwrap();
    let gs = |args: &[&str], out: &str| {
        let ps = dir.path().join(
            if out.ends_with(".pbm")
                || out.ends_with(".pgm")
                || out.contains("gray")
                || out.contains("black")
            {
                "grey.ps"
            } else {
                "colour.ps"
            },
        );
        let st = Command::new("gs")
            .args(["-q", "-dSAFER", "-dBATCH", "-dNOPAUSE", "-r100"])
            .args(args)
            .arg("-o")
            .arg(dir.path().join(out))
            .arg(&ps)
            .stderr(Stdio::null())
            .status()
            .unwrap();
        assert!(st.success(), "gs {args:?}");
    };
    gs(&["-sDEVICE=pbmraw"], "ref-%d.pbm");
    gs(&["-sDEVICE=pgmraw"], "ref-%d.pgm");
    gs(&["-sDEVICE=ppmraw"], "ref-%d.ppm");
    let cases: [(&str, &[&str], &str, &str); 6] = [
        ("black1.pwg", &["-sDEVICE=pwgraster"], "pbm", "pwg"),
        (
            "sgray8.pwg",
            &[
                "-sDEVICE=pwgraster",
                "-dcupsColorSpace=18",
                "-dcupsBitsPerColor=8",
            ],
            "pgm",
            "pwg",
        ),
        (
            "srgb8.pwg",
            &[
                "-sDEVICE=pwgraster",
                "-dcupsColorSpace=19",
                "-dcupsBitsPerColor=8",
            ],
            "ppm",
            "pwg",
        ),
        (
            "srgb16.pwg",
            &[
                "-sDEVICE=pwgraster",
                "-dcupsColorSpace=19",
                "-dcupsBitsPerColor=16",
            ],
            "ppm",
            "pwg",
        ),
        (
            "sgray8.urf",
            &[
                "-sDEVICE=urf",
                "-dcupsColorSpace=18",
                "-dcupsBitsPerColor=8",
            ],
            "pgm",
            "urf",
        ),
        (
            "srgb8.urf",
            &[
                "-sDEVICE=urf",
                "-dcupsColorSpace=19",
                "-dcupsBitsPerColor=8",
            ],
            "ppm",
            "urf",
        ),
    ];
    let opts = halftone::io::ReadOptions::default();
    for (file, args, reference, kind) in cases {
        gs(args, file);
        let data = std::fs::read(dir.path().join(file)).unwrap();
        let name = Path::new(file);
        let pages: Vec<halftone::raster::Image> = if kind == "pwg" {
            halftone::io::lang::pwg::pages(&data, name, &opts)
                .unwrap()
                .collect::<Result<_, _>>()
        } else {
            halftone::io::lang::urf::pages(&data, name, &opts)
                .unwrap()
                .collect::<Result<_, _>>()
        }
        .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(pages.len(), 2, "{file}");
        for (i, page) in pages.iter().enumerate() {
            let r = image::open(dir.path().join(format!("ref-{}.{reference}", i + 1)))
                .unwrap()
                .to_rgb8();
            assert_eq!((page.width, page.height), (200, 100), "{file}");
            assert_eq!(page.dpi, Some(100.0), "{file}");
            let at = |c: usize, k: usize| -> u8 {
                match &page.planes[c.min(page.planes.len() - 1)] {
                    halftone::raster::Samples::U8(v) => v[k],
                    halftone::raster::Samples::U16(v) => (v[k] >> 8) as u8,
                }
            };
            let differ = (0..200 * 100)
                .filter(|&k| (0..3).any(|c| at(c, k) != r.as_raw()[k * 3 + c]))
                .count();
            assert_eq!(differ, 0, "{file} page {}: {differ} pixels differ", i + 1);
        }
    }
}

/// A two-page 4×6 in PDF by hand: page 1 a black bar along the bottom, page 2 its right
/// half black.
fn label_pdf() -> Vec<u8> {
    pdf_pages(&["0 g 20 20 248 40 re f", "0 g 144 0 144 432 re f"])
}

/// A PDF of 4×6 in pages (288 × 432 pt), one a content stream.
fn pdf_pages(contents: &[&str]) -> Vec<u8> {
    let n = contents.len();
    let kids: Vec<String> = (0..n).map(|i| format!("{} 0 R", 3 + i)).collect();
    let mut objs = vec![
        "<< /Type /Catalog /Pages 2 0 R >>".to_string(),
        format!("<< /Type /Pages /Kids [{}] /Count {n} >>", kids.join(" ")),
    ];
    for i in 0..n {
        objs.push(format!(
            "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 288 432] /Contents {} 0 R >>",
            3 + n + i
        ));
    }
    for c in contents {
        objs.push(format!("<< /Length {} >>\nstream\n{c}\nendstream", c.len()));
    }
    let mut out = b"%PDF-1.4\n".to_vec();
    let mut offsets = Vec::new();
    for (i, o) in objs.iter().enumerate() {
        offsets.push(out.len());
        out.extend(format!("{} 0 obj\n{o}\nendobj\n", i + 1).bytes());
    }
    let xref = out.len();
    out.extend(format!("xref\n0 {}\n0000000000 65535 f \n", objs.len() + 1).bytes());
    for o in offsets {
        out.extend(format!("{o:010} 00000 n \n").bytes());
    }
    out.extend(
        format!(
            "trailer\n<< /Size {} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n",
            objs.len() + 1
        )
        .bytes(),
    );
    out
}

/// A Code 128 of `1Z999AA10123456784`, as `zint -b 20 -d 1Z999AA10123456784 --dump` (zint
/// 2.11.1) prints it: the modules left to right, 1 for a bar, hex, padded with zeros.
const CODE128_DUMP: &str =
    "D2 13 9B B1 72 CE 59 CB 28 C5 18 9C D7 7B 36 76 EB B1 0B 27 A6 66 C7 58";
/// The QR code (version 3, 29×29) of `QR_TEXT`, as `zint -b 58 --vers=3 -d QR_TEXT --dump`
/// prints it: a row a line, hex, each padded to 32 modules.
const QR_DUMP: [&str; 29] = [
    "FE 38 33 F8",
    "82 FD 92 08",
    "BA 04 12 E8",
    "BA 30 A2 E8",
    "BA 84 FA E8",
    "82 46 3A 08",
    "FE AA AB F8",
    "00 46 78 00",
    "AA 20 48 90",
    "B9 CC 0E 48",
    "AB 02 89 38",
    "9D 7C FB 10",
    "06 AA 7A 58",
    "49 01 4E 48",
    "16 84 AD D8",
    "3D F9 57 50",
    "6A A1 86 58",
    "4D C5 4E 68",
    "93 52 C6 18",
    "40 96 B9 50",
    "87 62 BF 80",
    "00 CA F8 B8",
    "FE 15 BA D8",
    "82 79 08 C0",
    "BA B1 0F 80",
    "BA 74 C0 A0",
    "BA 8A CD C8",
    "82 7C DF 10",
    "FE A8 BB D8",
];
const QR_TEXT: &str = "https://track.example.com/1Z999AA10123456784";

/// Bits from a zint dump line.
fn dump_bits(hex: &str) -> Vec<bool> {
    hex.split_whitespace()
        .flat_map(|h| {
            let b = u8::from_str_radix(h, 16).unwrap();
            (0..8).rev().map(move |i| b >> i & 1 == 1)
        })
        .collect()
}

/// The Code 128's modules, trailing padding cut (the symbol ends with a bar).
fn code128_modules() -> Vec<bool> {
    let mut bits = dump_bits(CODE128_DUMP);
    while bits.last() == Some(&false) {
        bits.pop();
    }
    bits
}

/// A 4×6 in shipping label as a vector PDF, every module a rectangle placed off the 203 dpi
/// dot grid: the Code 128 with 0.33 mm modules (2.64 dots), 60 pt tall, its left edge at
/// 20.3 pt and its bottom 40 pt above the page's; the QR code with 0.5 mm modules (3.996
/// dots), its top left corner at (40.2 pt, 300.7 pt) from the page's bottom left.
fn barcode_label_pdf() -> Vec<u8> {
    let mut c = String::from("0 g\n");
    let m = 0.33 / 25.4 * 72.0;
    for (i, &bar) in code128_modules().iter().enumerate() {
        if bar {
            c += &format!("{:.4} 40 {m:.4} 60 re\n", 20.3 + i as f64 * m);
        }
    }
    let q = 0.5 / 25.4 * 72.0;
    for (y, row) in QR_DUMP.iter().enumerate() {
        for (x, &dark) in dump_bits(row).iter().take(29).enumerate() {
            if dark {
                let top = 300.7 - y as f64 * q;
                c += &format!(
                    "{:.4} {:.4} {q:.4} {q:.4} re\n",
                    40.2 + x as f64 * q,
                    top - q
                );
            }
        }
    }
    c += "f";
    pdf_pages(&[&c])
}

/// Waits for the next `job-N.*` file in `dir` not in `seen`; `why` is said when none comes
/// (what the client's logs show).
fn next_job_file(dir: &Path, seen: &mut Vec<PathBuf>, why: &dyn Fn() -> String) -> Vec<u8> {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(90) {
        let mut new: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                !seen.contains(p) && !p.file_name().unwrap().to_string_lossy().starts_with('.')
            })
            .collect();
        if let Some(p) = new.pop() {
            seen.push(p.clone());
            return std::fs::read(p).unwrap();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("no job reached {}{}", dir.display(), why());
}

/// A real CUPS as the client: cupsd started here (as root, in a folder of its own),
/// `lpadmin -m everywhere` on our label queue, then `lp` of a photo (CUPS passes the JPEG
/// on: the label equals `halftone convert`'s byte for byte) and of a two-page 4×6 PDF (sent as
/// PDF with the `pdf` feature, else rasterised by cups-filters to PWG raster or URF: two
/// labels of 812 × 1218 dots with the bars where the PDF has them), then a shipping label
/// whose Code 128 and QR code zbarimg reads from the label that reaches the folder.
#[test]
fn cups_prints_through_the_queue() {
    for (tool, package) in [
        ("cupsd", "cups"),
        ("lpadmin", "cups-client"),
        ("lp", "cups-client"),
        ("zbarimg", "zbar-tools"),
    ] {
        if !common::have_tool(tool, package, "serve: a real CUPS as the client") {
            return;
        }
    }
    let root = Command::new("id").arg("-u").output().unwrap();
    if String::from_utf8_lossy(&root.stdout).trim() != "0" {
        common::skip("serve: a real CUPS as the client", "cupsd needs root");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let jobs = d.join("jobs");
    for sub in ["jobs", "spool", "cache", "state", "tmp", "log", "ppd"] {
        std::fs::create_dir(d.join(sub)).unwrap();
    }
    // CUPS's filters run as the `lp` user: they must reach the folder and write temp files.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::set_permissions(d.join("tmp"), std::fs::Permissions::from_mode(0o1777)).unwrap();
    let server = Server::start(&[
        "--queue",
        "lab",
        "--preset",
        "label-203",
        "--backend",
        &format!("file://{}", jobs.display()),
    ]);
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    std::fs::write(
        d.join("cupsd.conf"),
        format!(
            "Listen 127.0.0.1:{port}\nLogLevel info\nWebInterface No\nBrowsing No\n\
             DefaultAuthType None\n<Location />\n  Order allow,deny\n  Allow all\n</Location>\n\
             <Policy default>\n  <Limit All>\n    Order deny,allow\n  </Limit>\n</Policy>\n"
        ),
    )
    .unwrap();
    let p = |s: &str| d.join(s).display().to_string();
    std::fs::write(
        d.join("cups-files.conf"),
        format!(
            "ServerRoot {}\nRequestRoot {}\nCacheDir {}\nStateDir {}\nTempDir {}\n\
             ErrorLog {}\nAccessLog {}\nPageLog {}\nDataDir /usr/share/cups\n\
             ServerBin /usr/lib/cups\nSystemGroup root\n",
            p(""),
            p("spool"),
            p("cache"),
            p("state"),
            p("tmp"),
            p("log/error_log"),
            p("log/access_log"),
            p("log/page_log"),
        ),
    )
    .unwrap();
    struct Cupsd(Child);
    impl Drop for Cupsd {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let _cupsd = Cupsd(
        Command::new("cupsd")
            .arg("-f")
            .arg("-c")
            .arg(d.join("cupsd.conf"))
            .arg("-s")
            .arg(d.join("cups-files.conf"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let cups = format!("127.0.0.1:{port}");
    let start = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "cupsd never listened"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let run = |cmd: &str, args: &[&str]| {
        let out = Command::new(cmd)
            .env("CUPS_SERVER", &cups)
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{cmd} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(
        "lpadmin",
        &[
            "-p",
            "q",
            "-E",
            "-v",
            &server.uri("lab"),
            "-m",
            "everywhere",
        ],
    );
    let photo = d.join("photo.jpg");
    image::open(sample("raytrace.png"))
        .unwrap()
        .to_rgb8()
        .save(&photo)
        .unwrap();
    let mut seen = Vec::new();
    // What CUPS says of its jobs and queue when none reaches us: its log's end and lpstat.
    let why = || {
        let log = std::fs::read_to_string(d.join("log/error_log")).unwrap_or_default();
        let tail: Vec<&str> = log.lines().rev().take(80).collect();
        let lpstat = |args: &[&str]| {
            Command::new("lpstat")
                .env("CUPS_SERVER", &cups)
                .args(args)
                .output()
                .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
                .unwrap_or_default()
        };
        format!(
            "\n-- lpstat -l -p q:\n{}-- lpstat -W all -o:\n{}-- cupsd error_log, last lines:\n{}",
            lpstat(&["-l", "-p", "q"]),
            lpstat(&["-W", "all", "-o"]),
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        )
    };
    let t = Instant::now();
    run("lp", &["-d", "q", photo.to_str().unwrap()]);
    let got = next_job_file(&jobs, &mut seen, &why);
    eprintln!("cups: photo label in {:.2} s", t.elapsed().as_secs_f64());
    let want = d.join("want.zpl");
    let st = Command::new(assert_cmd::cargo::cargo_bin("halftone"))
        .args([
            "convert",
            photo.to_str().unwrap(),
            "-o",
            want.to_str().unwrap(),
        ])
        .args(["--preset", "label-203"])
        .status()
        .unwrap();
    assert!(st.success());
    assert_eq!(got, std::fs::read(&want).unwrap(), "the photo through CUPS");
    // The PDF. CUPS's everywhere PPD names a zero-margin size "4x6.Borderless" but makes
    // "4x6" its default, which pdftopdf does not find (it falls back to Letter): the media
    // is named, as `lp -o media=` does.
    // A 4×6 in PDF through `lp` on that media; the label's pages as they reach the folder.
    let print_4x6 = |name: &str, pdf: Vec<u8>, seen: &mut Vec<PathBuf>| {
        let path = d.join(name);
        std::fs::write(&path, pdf).unwrap();
        let media = ["-d", "q", "-o", "media=na_index-4x6_4x6in"];
        run("lp", &[&media[..], &[path.to_str().unwrap()]].concat());
        halftone::io::lang::zpl::decode(&next_job_file(&jobs, seen, &why)).unwrap()
    };
    let t = Instant::now();
    let pages = print_4x6("label.pdf", label_pdf(), &mut seen);
    eprintln!(
        "cups: two-page PDF label in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    assert_eq!(pages.len(), 2);
    for (i, b) in pages.iter().enumerate() {
        assert_eq!((b.width, b.height), (812, 1218), "page {}", i + 1);
        let black = |x0: usize, x1: usize, y0: usize, y1: usize| {
            let n = (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| b.get(x, y))
                .count();
            n as f64 / ((x1 - x0) * (y1 - y0)) as f64
        };
        if i == 0 {
            // The bar: 20..268 pt across, 20..60 pt up from the bottom.
            assert!(black(80, 730, 1218 - 160, 1218 - 80) > 0.99, "page 1 bar");
            assert!(black(0, 812, 0, 1000) < 0.01, "page 1 above the bar");
        } else {
            assert!(black(420, 812, 0, 1218) > 0.99, "page 2 right half");
            assert!(black(0, 390, 0, 1218) < 0.01, "page 2 left half");
        }
    }
    // The barcode case: a shipping label's Code 128 and QR code, vector modules off the dot
    // grid, through CUPS and the label-203 queue, read back by zbarimg.
    let pages = print_4x6("barcodes.pdf", barcode_label_pdf(), &mut seen);
    assert_eq!(pages.len(), 1);
    let b = &pages[0];
    assert_eq!((b.width, b.height), (812, 1218));
    // As a PNG with a quiet zone of 40 white dots around it, for zbarimg.
    let (w, h) = (b.width + 80, b.height + 80);
    let img = image::GrayImage::from_fn(w as u32, h as u32, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let inside = (40..40 + b.width).contains(&x) && (40..40 + b.height).contains(&y);
        image::Luma([if inside && b.get(x - 40, y - 40) {
            0
        } else {
            255
        }])
    });
    let png = d.join("barcodes.png");
    img.save(&png).unwrap();
    let out = Command::new("zbarimg")
        .args(["-q", "--raw"])
        .arg(&png)
        .output()
        .unwrap();
    let read = String::from_utf8_lossy(&out.stdout);
    let mut codes: Vec<&str> = read.lines().collect();
    codes.sort_unstable();
    assert_eq!(
        codes,
        ["1Z999AA10123456784", QR_TEXT],
        "zbarimg read {read:?} from the label ({})",
        String::from_utf8_lossy(&out.stderr)
    );
    // Every bar and space of the Code 128 is there, on the row through its middle: the bars
    // stand from 40 to 100 pt above the page's bottom edge, 20.3 pt from its left.
    let row = 1218 - (70.0 * 203.0 / 72.0) as usize;
    let modules = code128_modules();
    let want_bars = 1 + modules.windows(2).filter(|p| !p[0] && p[1]).count();
    let (x0, x1) = (40, 600);
    let got_bars = (x0..x1)
        .filter(|&x| b.get(x, row) && (x == x0 || !b.get(x - 1, row)))
        .count();
    assert_eq!(got_bars, want_bars, "bars on the Code 128's middle row");
}
