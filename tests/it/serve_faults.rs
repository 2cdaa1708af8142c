//! `halftone serve` under load and faults, the real binary: many clients at once, a server
//! killed (SIGKILL) with jobs queued and started again on its spool, a printer that is
//! off, malformed and oversized requests, and the URIs and status page following the
//! `Host` header.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::serve::{parse, request, wait_for, Server};
use crate::common;

/// A small grey PNG, different for every `k`.
fn doc(k: usize) -> Vec<u8> {
    let img = image::GrayImage::from_fn(48, 32, |x, y| {
        image::Luma([((x * 5 + y * 3 + k as u32 * 37) % 256) as u8])
    });
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// `halftone convert` of each document (thermal-203, ESC/POS), five at a time.
fn converted(dir: &Path, docs: &[Vec<u8>]) -> Vec<Vec<u8>> {
    let paths: Vec<PathBuf> = docs
        .iter()
        .enumerate()
        .map(|(k, d)| {
            let p = dir.join(format!("doc-{k}.png"));
            std::fs::write(&p, d).unwrap();
            p
        })
        .collect();
    let out = Arc::new(Mutex::new(vec![Vec::new(); docs.len()]));
    std::thread::scope(|s| {
        for t in 0..5 {
            let (paths, out) = (&paths, Arc::clone(&out));
            s.spawn(move || {
                for k in (t..paths.len()).step_by(5) {
                    let o = common::halftone()
                        .arg("convert")
                        .arg(&paths[k])
                        .args(["-o", "-", "--format", "escpos", "--preset", "thermal-203"])
                        .output()
                        .unwrap();
                    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
                    out.lock().unwrap()[k] = o.stdout;
                }
            });
        }
    });
    Arc::try_unwrap(out).unwrap().into_inner().unwrap()
}

/// Print-Job of a PNG; returns the job-id.
fn print(server: &Server, queue: &str, png: &[u8], name: &str) -> i32 {
    let ops = [
        (0x42u8, "requesting-user-name", &b"load"[..]),
        (0x42, "job-name", name.as_bytes()),
        (0x49, "document-format", b"image/png"),
    ];
    let r = parse(server.post(
        queue,
        &request(0x02, &server.uri(queue), &ops, &[], png),
        false,
    ));
    assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
    let g = r
        .attributes()
        .first_of(ipp::model::DelimiterTag::JobAttributes)
        .unwrap();
    match g.get("job-id").unwrap().value() {
        ipp::value::IppValue::Integer(i) => *i,
        v => panic!("{v:?}"),
    }
}

/// One job attribute as text.
fn job_attr(server: &Server, queue: &str, id: i32, name: &str) -> String {
    let idb = id.to_be_bytes();
    let r = parse(server.post(
        queue,
        &request(
            0x09,
            &server.uri(queue),
            &[(0x21, "job-id", &idb[..])],
            &[],
            &[],
        ),
        false,
    ));
    r.attributes()
        .first_of(ipp::model::DelimiterTag::JobAttributes)
        .and_then(|g| g.get(name))
        .map(|a| a.value().to_string())
        .unwrap_or_default()
}

/// One printer attribute as text.
fn printer_attr(server: &Server, queue: &str, name: &str) -> String {
    let r = parse(server.post(
        queue,
        &request(0x0b, &server.uri(queue), &[], &[], &[]),
        false,
    ));
    r.attributes()
        .first_of(ipp::model::DelimiterTag::PrinterAttributes)
        .and_then(|g| g.get(name))
        .map(|a| a.value().to_string())
        .unwrap_or_default()
}

/// The files `job-*.escpos` in `dir`, sorted.
fn outputs(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("job-") && n.ends_with(".escpos"))
        .collect();
    v.sort();
    v
}

/// The jobs left in a spool folder.
fn spooled(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".ipp")
        })
        .count()
}

/// SIGKILL: the server has no chance to finish anything.
fn kill(mut server: Server) {
    server.child.kill().unwrap();
    server.child.wait().unwrap();
    // Reaped: nothing is left to stop (dropping it would signal a pid no longer ours).
    std::mem::forget(server);
}

fn eventually(what: &str, secs: u64, mut f: impl FnMut() -> bool) {
    let start = Instant::now();
    while !f() {
        assert!(
            start.elapsed() < Duration::from_secs(secs),
            "{what}: timed out"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn fifty_jobs_from_five_clients_none_lost_mixed_or_printed_twice() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let spool = dir.path().join("spool");
    let docs: Vec<Vec<u8>> = (0..50).map(doc).collect();
    let want = converted(dir.path(), &docs);
    let backend = format!("file://{}", out.display());
    let spool_arg = spool.display().to_string();
    let server = Server::receipt(&backend, &["--spool", &spool_arg, "--no-dnssd"]);
    let start = Instant::now();
    let ids = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for t in 0..5 {
            let (server, docs, ids) = (&server, &docs, &ids);
            s.spawn(move || {
                for (k, d) in docs.iter().enumerate().skip(t * 10).take(10) {
                    let id = print(server, "receipt", d, &format!("doc-{k}"));
                    ids.lock().unwrap().push((id, k));
                }
            });
        }
    });
    let acknowledged = start.elapsed();
    let ids = ids.into_inner().unwrap();
    let mut numbers: Vec<i32> = ids.iter().map(|p| p.0).collect();
    numbers.sort();
    numbers.dedup();
    assert_eq!(numbers.len(), 50, "job numbers handed out twice");
    eventually("50 outputs", 60, || outputs(&out).len() >= 50);
    let printed = start.elapsed();
    assert_eq!(outputs(&out).len(), 50);
    for (id, k) in &ids {
        let got = wait_for(&out.join(format!("job-{id}.escpos")));
        assert!(got == want[*k], "job {id} is not document {k}");
        assert_eq!(job_attr(&server, "receipt", *id, "job-state"), "9");
        assert_eq!(
            job_attr(&server, "receipt", *id, "job-name"),
            format!("doc-{k}")
        );
    }
    eventually("spool emptied", 10, || spooled(&spool) == 0);
    eprintln!(
        "50 jobs from 5 clients: all acknowledged in {:.2} s, all printed in {:.2} s \
         ({:.1} jobs/s)",
        acknowledged.as_secs_f64(),
        printed.as_secs_f64(),
        50.0 / printed.as_secs_f64()
    );
    // The status page lists them.
    let page = http(
        server.port,
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
        b"",
    );
    assert!(page.0.starts_with("HTTP/1.1 200"), "{}", page.0);
    let text = String::from_utf8_lossy(&page.1).into_owned();
    assert!(text.contains("recent jobs (50 of 50"), "{text}");
    assert_eq!(text.matches(" completed ").count(), 50, "{text}");
    assert!(text.contains("doc-49  load"), "{text}");
}

#[test]
fn killed_with_jobs_queued_each_printed_once_after_a_restart() {
    let dir = tempfile::tempdir().unwrap();
    let docs: Vec<Vec<u8>> = (0..20).map(|k| doc(k + 100)).collect();
    let want = converted(dir.path(), &docs);

    // 1. The printer is off (nothing listens on its port): six jobs wait, the printer says
    // why; the server is killed; the printer comes on; the server starts again on its
    // spool: each job reaches the printer once.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let spool = dir.path().join("spool1");
    let spool_arg = spool.display().to_string();
    let backend = format!("socket://127.0.0.1:{port}");
    let args = Server::receipt_args(&backend, &["--spool", &spool_arg, "--no-dnssd"]);
    let server = Server::start(&args);
    let ids: Vec<i32> = (0..6)
        .map(|k| print(&server, "receipt", &docs[k], &format!("off-{k}")))
        .collect();
    eventually("the first job waits for the printer", 20, || {
        job_attr(&server, "receipt", ids[0], "job-state-reasons") == "resources-are-not-ready"
    });
    assert_eq!(job_attr(&server, "receipt", ids[0], "job-state"), "3");
    let reasons = printer_attr(&server, "receipt", "printer-state-reasons");
    assert!(reasons.contains("offline-report"), "{reasons}");
    let msg = printer_attr(&server, "receipt", "printer-state-message");
    assert!(msg.contains("refused"), "{msg}");
    assert_eq!(spooled(&spool), 6);
    kill(server);

    let printer = TcpListener::bind(("127.0.0.1", port)).unwrap();
    let got = Arc::new(Mutex::new(Vec::new()));
    {
        let got = Arc::clone(&got);
        std::thread::spawn(move || {
            for c in printer.incoming() {
                let mut c = c.unwrap();
                let mut bytes = Vec::new();
                c.read_to_end(&mut bytes).unwrap();
                got.lock().unwrap().push(bytes);
            }
        });
    }
    let start = Instant::now();
    let server = Server::start(&args);
    eventually("six jobs at the printer", 30, || {
        got.lock().unwrap().len() >= 6
    });
    let recovered = start.elapsed();
    std::thread::sleep(Duration::from_millis(1500));
    let mut received = got.lock().unwrap().clone();
    let mut expected: Vec<Vec<u8>> = want[..6].to_vec();
    received.sort();
    expected.sort();
    assert_eq!(received.len(), 6, "a job printed twice");
    assert!(received == expected, "the printer got other bytes");
    for id in &ids {
        assert_eq!(job_attr(&server, "receipt", *id, "job-state"), "9");
    }
    eventually("spool emptied", 10, || spooled(&spool) == 0);
    // Numbers go on: none is used twice.
    let next = print(&server, "receipt", &docs[6], "after");
    assert!(next > *ids.iter().max().unwrap(), "{next} after {ids:?}");
    eprintln!(
        "SIGKILL with 6 jobs waiting for a printer that was off: all 6 at the printer {:.2} s \
         after the restart",
        recovered.as_secs_f64()
    );
    drop(server);

    // 2. Fourteen jobs queued on a working printer, the server killed as soon as the last is
    // acknowledged (some printed, some not): after a restart each is there once.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let spool = dir.path().join("spool2");
    let spool_arg = spool.display().to_string();
    let backend = format!("file://{}", out.display());
    let args = Server::receipt_args(&backend, &["--spool", &spool_arg, "--no-dnssd"]);
    let server = Server::start(&args);
    let ids: Vec<i32> = (6..20)
        .map(|k| print(&server, "receipt", &docs[k], &format!("many-{k}")))
        .collect();
    kill(server);
    let before = outputs(&out).len();
    let left = spooled(&spool);
    let server = Server::start(&args);
    eventually("fourteen outputs", 30, || outputs(&out).len() >= 14);
    eventually("spool emptied", 10, || spooled(&spool) == 0);
    assert_eq!(outputs(&out).len(), 14);
    for (id, k) in ids.iter().zip(6..20) {
        let got = std::fs::read(out.join(format!("job-{id}.escpos"))).unwrap();
        assert!(got == want[k], "job {id} is not document {k}");
    }
    eprintln!(
        "SIGKILL with 14 jobs acknowledged: {before} printed before the kill, {left} spooled; \
         after the restart 14 printed, each once"
    );
    drop(server);
}

/// Sends `head` and `body` on a new connection; returns the HTTP status line and the
/// response body ("" and nothing when the server closed without answering).
fn http(port: u16, head: &str, body: &[u8]) -> (String, Vec<u8>) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let _ = s.write_all(head.as_bytes());
    let _ = s.write_all(body);
    let _ = s.shutdown(std::net::Shutdown::Write);
    let mut resp = Vec::new();
    let _ = s.read_to_end(&mut resp);
    let Some(end) = resp.windows(4).position(|w| w == b"\r\n\r\n") else {
        return (String::from_utf8_lossy(&resp).into_owned(), Vec::new());
    };
    let head = String::from_utf8_lossy(&resp[..end]).into_owned();
    let mut body = resp[end + 4..].to_vec();
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        let mut plain = Vec::new();
        let mut rest = &body[..];
        while let Some(nl) = rest.windows(2).position(|w| w == b"\r\n") {
            let n = usize::from_str_radix(std::str::from_utf8(&rest[..nl]).unwrap().trim(), 16)
                .unwrap_or(0);
            if n == 0 {
                break;
            }
            plain.extend_from_slice(&rest[nl + 2..nl + 2 + n]);
            rest = &rest[nl + 2 + n + 2..];
        }
        body = plain;
    }
    (head.lines().next().unwrap_or("").to_string(), body)
}

/// An IPP POST to `/ipp/print/receipt` with a Content-Length.
fn ipp_post(port: u16, body: &[u8]) -> (String, Vec<u8>) {
    let head = format!(
        "POST /ipp/print/receipt HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: \
         application/ipp\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    http(port, &head, body)
}

/// CRC-32 (PNG's) of `data`.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A valid PNG header claiming `w`×`h` pixels, with a few bytes of data.
fn huge_png(w: u32, h: u32) -> Vec<u8> {
    let mut p = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        p.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut c = kind.to_vec();
        c.extend_from_slice(data);
        p.extend_from_slice(&c);
        p.extend_from_slice(&crc32(&c).to_be_bytes());
    };
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[0x78, 0x9c, 0x63, 0, 0, 0, 1, 0, 1]);
    chunk(b"IEND", &[]);
    p
}

#[test]
fn malformed_and_oversized_requests_get_errors_and_the_server_serves_on() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let backend = format!("file://{}", out.display());
    let server = Server::receipt(&backend, &["--max-request-mib", "1", "--no-dnssd"]);
    let port = server.port;
    let uri = server.uri("receipt");
    let nope = uri.replace("/receipt", "/nope");
    let png = doc(7);
    let fmt = |f: &'static [u8]| (0x49u8, "document-format", f);
    // A held job for the Send-Document cases.
    let created = parse(server.post("receipt", &request(0x05, &uri, &[], &[], &[]), false));
    let held = match created
        .attributes()
        .first_of(ipp::model::DelimiterTag::JobAttributes)
        .unwrap()
        .get("job-id")
        .unwrap()
        .value()
    {
        ipp::value::IppValue::Integer(i) => i.to_be_bytes(),
        v => panic!("{v:?}"),
    };
    let gpa = request(0x0b, &uri, &[], &[], &[]);
    let with = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = gpa.clone();
        f(&mut b);
        b
    };
    // Operation attributes by hand: (tag, name, value) after the header.
    let raw = |op: u16, attrs: &[(u8, &str, &[u8])], tail: &[u8]| {
        let mut b = vec![2, 0];
        b.extend_from_slice(&op.to_be_bytes());
        b.extend_from_slice(&[0, 0, 0, 1, 1]);
        for (t, n, v) in attrs {
            b.push(*t);
            b.extend_from_slice(&(n.len() as u16).to_be_bytes());
            b.extend_from_slice(n.as_bytes());
            b.extend_from_slice(&(v.len() as u16).to_be_bytes());
            b.extend_from_slice(v);
        }
        b.extend_from_slice(tail);
        b
    };
    let cs = (0x47u8, "attributes-charset", &b"utf-8"[..]);
    let nl = (0x48u8, "attributes-natural-language", &b"en"[..]);
    let over = {
        let mut b = request(0x02, &uri, &[fmt(b"image/png")], &[], &png);
        b.resize((1 << 20) + 100, 0);
        b
    };
    let mut jpeg = vec![0xff, 0xd8, 0xff, 0xe0];
    jpeg.extend_from_slice(&[0; 64]);

    // (what, request body, expected IPP status or None for any client/server error)
    let cases: Vec<(&str, Vec<u8>, Option<u16>)> = vec![
        ("empty body", Vec::new(), Some(0x0400)),
        ("three bytes", vec![2, 0, 0], Some(0x0400)),
        ("header only", vec![2, 0, 0, 0x0b, 0, 0, 0, 1], Some(0x0400)),
        (
            "version 9.9",
            with(&|b| b[..2].copy_from_slice(&[9, 9])),
            Some(0x0503),
        ),
        (
            "version 0.0",
            with(&|b| b[..2].copy_from_slice(&[0, 0])),
            Some(0x0503),
        ),
        (
            "request-id 0",
            with(&|b| b[4..8].copy_from_slice(&[0; 4])),
            Some(0x0400),
        ),
        (
            "no operation group",
            vec![2, 0, 0, 0x0b, 0, 0, 0, 1, 3],
            Some(0x0400),
        ),
        (
            "charset not first",
            raw(0x0b, &[nl, cs], &[3]),
            Some(0x0400),
        ),
        (
            "charset an integer",
            raw(
                0x0b,
                &[(0x21, "attributes-charset", &[0, 0, 0, 1]), nl],
                &[3],
            ),
            Some(0x040d),
        ),
        (
            "bad value tag 0x0f",
            raw(0x0b, &[cs, nl, (0x0f, "printer-uri", b"x")], &[3]),
            None,
        ),
        (
            "name length past the end",
            raw(0x0b, &[cs], &[0x45, 0x7f, 0xff, b'p']),
            Some(0x0400),
        ),
        (
            "value length past the end",
            raw(0x0b, &[cs], &[0x45, 0, 1, b'p', 0x7f, 0xff, b'i']),
            Some(0x0400),
        ),
        (
            "cut inside a name",
            raw(0x0b, &[cs], &[0x45, 0, 11, b'p', b'r']),
            Some(0x0400),
        ),
        (
            "no end-of-attributes",
            raw(0x0b, &[cs, nl], &[]),
            Some(0x0400),
        ),
        (
            "unterminated collection",
            raw(0x0b, &[cs, nl, (0x34, "media-col", b"")], &[3]),
            Some(0x0400),
        ),
        (
            "unknown operation 0x4000",
            request(0x4000, &uri, &[], &[], &[]),
            Some(0x0501),
        ),
        ("no printer-uri", raw(0x0b, &[cs, nl], &[3]), Some(0x0400)),
        (
            "unknown queue",
            request(0x0b, &nope, &[], &[], &[]),
            Some(0x0406),
        ),
        (
            "Print-Job without a document",
            request(0x02, &uri, &[], &[], &[]),
            Some(0x0400),
        ),
        (
            "Print-Job of text",
            request(0x02, &uri, &[], &[], b"hello, printer\n"),
            Some(0x040a),
        ),
        (
            "png said, jpeg sent",
            request(0x02, &uri, &[fmt(b"image/png")], &[], &jpeg),
            Some(0x0411),
        ),
        (
            "document-format text/plain",
            request(0x02, &uri, &[fmt(b"text/plain")], &[], &png),
            Some(0x040a),
        ),
        (
            "halftone-method nonesuch",
            request(
                0x02,
                &uri,
                &[],
                &[(0x44, "halftone-method", b"nonesuch")],
                &png,
            ),
            Some(0x040b),
        ),
        (
            "page-ranges 5-2",
            request(
                0x02,
                &uri,
                &[],
                &[(0x33, "page-ranges", &[0, 0, 0, 5, 0, 0, 0, 2])],
                &png,
            ),
            Some(0x040b),
        ),
        (
            "overrides an integer",
            request(0x02, &uri, &[], &[(0x21, "overrides", &[0, 0, 0, 1])], &png),
            Some(0x040b),
        ),
        (
            "a PNG claiming 40000x40000",
            request(
                0x02,
                &uri,
                &[fmt(b"image/png")],
                &[],
                &huge_png(40000, 40000),
            ),
            Some(0x0408),
        ),
        ("a body over the limit", over.clone(), Some(0x0408)),
        (
            "Send-Document to job 99999",
            request(
                0x06,
                &uri,
                &[
                    (0x21, "job-id", &99999i32.to_be_bytes()),
                    (0x22, "last-document", &[1]),
                ],
                &[],
                &png,
            ),
            Some(0x0406),
        ),
        (
            "Send-Document without last-document",
            request(0x06, &uri, &[(0x21, "job-id", &held)], &[], &png),
            Some(0x0400),
        ),
        (
            "job-id as text",
            request(0x09, &uri, &[(0x41, "job-id", b"7")], &[], &[]),
            Some(0x0400),
        ),
        (
            "Cancel-Job of job 99999",
            request(
                0x08,
                &uri,
                &[(0x21, "job-id", &99999i32.to_be_bytes())],
                &[],
                &[],
            ),
            Some(0x0406),
        ),
        (
            "which-jobs bogus",
            request(0x0a, &uri, &[(0x44, "which-jobs", b"bogus")], &[], &[]),
            Some(0x040b),
        ),
    ];
    let mut table = Vec::new();
    for (what, body, want) in &cases {
        let (status, resp) = ipp_post(port, body);
        assert!(status.starts_with("HTTP/1.1 200"), "{what}: {status}");
        assert!(resp.len() >= 8, "{what}: no IPP response");
        let code = u16::from_be_bytes([resp[2], resp[3]]);
        match want {
            Some(w) => assert_eq!(code, *w, "{what}"),
            None => assert!(code >= 0x0400, "{what}: 0x{code:04x}"),
        }
        table.push(format!("{what}: 0x{code:04x}"));
    }
    // The same too-long body sent in chunks.
    let head = "POST /ipp/print/receipt HTTP/1.1\r\nHost: x\r\nContent-Type: application/ipp\r\n\
                Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n";
    let mut chunked = Vec::new();
    for part in over.chunks(64 << 10) {
        chunked.extend_from_slice(format!("{:x}\r\n", part.len()).as_bytes());
        chunked.extend_from_slice(part);
        chunked.extend_from_slice(b"\r\n");
    }
    chunked.extend_from_slice(b"0\r\n\r\n");
    let (status, resp) = http(port, head, &chunked);
    assert!(status.starts_with("HTTP/1.1 200"), "chunked: {status}");
    assert_eq!(u16::from_be_bytes([resp[2], resp[3]]), 0x0408);
    table.push("a body over the limit, chunked: 0x0408".into());
    // A body shorter than its Content-Length (the client gives up half way).
    let short = request(0x02, &uri, &[fmt(b"image/png")], &[], &png);
    let head = format!(
        "POST /ipp/print/receipt HTTP/1.1\r\nHost: x\r\nContent-Type: application/ipp\r\n\
         Content-Length: {}\r\n\r\n",
        short.len() + 500
    );
    let (status, resp) = http(port, &head, &short[..short.len() / 2]);
    let code = if resp.len() >= 4 {
        format!("0x{:04x}", u16::from_be_bytes([resp[2], resp[3]]))
    } else {
        "no IPP body".into()
    };
    assert!(
        status.starts_with("HTTP/1.1 200") && code.starts_with("0x04")
            || status.starts_with("HTTP/1.1 4"),
        "short body: {status} {code}"
    );
    table.push(format!(
        "a body shorter than its Content-Length: {status} {code}"
    ));
    // Not IPP at all: HTTP errors.
    for (what, head, want) in [
        (
            "POST of text/plain",
            "POST /ipp/print/receipt HTTP/1.1\r\nHost: x\r\nContent-Type: text/plain\r\n\
             Content-Length: 5\r\nConnection: close\r\n\r\nhello",
            "HTTP/1.1 400",
        ),
        (
            "GET of an unknown path",
            "GET /admin HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n",
            "HTTP/1.1 404",
        ),
        (
            "a request line of garbage",
            "HELLO THERE\r\n\r\n",
            "HTTP/1.1 400",
        ),
    ] {
        let (status, _) = http(port, head, b"");
        assert!(status.starts_with(want), "{what}: {status:?}");
        table.push(format!("{what}: {status}"));
    }
    assert!(table.len() >= 30, "{}", table.len());
    eprintln!(
        "{} malformed or oversized requests:\n  {}",
        table.len(),
        table.join("\n  ")
    );

    // The server still prints.
    let id = print(&server, "receipt", &png, "good");
    let got = wait_for(&out.join(format!("job-{id}.escpos")));
    let want = converted(dir.path(), &[png]);
    assert!(got == want[0], "the good job's bytes differ from convert's");
}

#[test]
fn uris_follow_the_host_header_on_every_address() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let backend = format!("file://{}", out.display());
    let server = Server::start_on(
        "0.0.0.0:0",
        &Server::receipt_args(&backend, &["--no-dnssd"]),
    );
    let port = server.port;
    let ask = |host: Option<&str>, body: &[u8]| {
        let host = host.map_or(String::new(), |h| format!("Host: {h}\r\n"));
        let head = format!(
            "POST /ipp/print/receipt HTTP/1.0\r\n{host}Content-Type: application/ipp\r\n\
             Content-Length: {}\r\n\r\n",
            body.len()
        );
        let (status, body) = http(port, &head, body);
        assert!(status.contains(" 200"), "{status}");
        parse(body)
    };
    let gpa = request(0x0b, "ipp://localhost/ipp/print/receipt", &[], &[], &[]);
    let attr = |r: &ipp::request::IppRequestResponse, tag, n: &str| {
        r.attributes()
            .first_of(tag)
            .and_then(|g| g.get(n))
            .map(|a| a.value().to_string())
            .unwrap_or_default()
    };
    let p = ipp::model::DelimiterTag::PrinterAttributes;
    let named = format!("printer.example:{port}");
    for (host, want) in [
        (Some(named.as_str()), named.clone()),
        (Some("192.0.2.7:631"), "192.0.2.7:631".to_string()),
        (Some("Printer.Example"), named.clone()),
        (Some("bad host"), format!("0.0.0.0:{port}")),
        (None, format!("0.0.0.0:{port}")),
    ] {
        let r = ask(host, &gpa);
        assert_eq!(
            attr(&r, p, "printer-uri-supported"),
            format!("ipp://{want}/ipp/print/receipt"),
            "Host {host:?}"
        );
        assert_eq!(
            attr(&r, p, "printer-icons"),
            format!("http://{want}/icon.png")
        );
    }
    // A job's URIs too.
    let pj = request(
        0x02,
        "ipp://localhost/ipp/print/receipt",
        &[(0x49, "document-format", b"image/png")],
        &[],
        &doc(3),
    );
    let r = ask(Some(&named), &pj);
    let j = ipp::model::DelimiterTag::JobAttributes;
    let job_uri = attr(&r, j, "job-uri");
    assert!(
        job_uri.starts_with(&format!("ipp://{named}/ipp/print/receipt/")),
        "{job_uri}"
    );
    let id = job_uri.rsplit('/').next().unwrap().to_string();
    wait_for(&out.join(format!("job-{id}.escpos")));
    let ga = request(
        0x09,
        &job_uri,
        &[(0x21, "job-id", &id.parse::<i32>().unwrap().to_be_bytes())],
        &[],
        &[],
    );
    let r = ask(Some(&named), &ga);
    assert_eq!(
        attr(&r, j, "job-printer-uri"),
        format!("ipp://{named}/ipp/print/receipt")
    );
    assert_eq!(attr(&r, j, "job-more-info"), format!("http://{named}/"));
    // The status page: the queue at the host asked for, and the job with its state, pages,
    // method and time.
    let (status, body) = http(
        port,
        &format!("GET / HTTP/1.1\r\nHost: {named}\r\nConnection: close\r\n\r\n"),
        b"",
    );
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    let page = String::from_utf8(body).unwrap();
    assert!(
        page.contains(&format!("ipp://{named}/ipp/print/receipt")),
        "{page}"
    );
    let line = page
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{id}  receipt")))
        .unwrap_or_else(|| panic!("job {id} not listed:\n{page}"));
    assert!(line.contains("  completed  1  "), "{line}");
    let method = attr(&r, j, "halftone-method");
    assert!(
        !method.is_empty() && line.contains(&method),
        "{line} / {method}"
    );
    let year = line.split("  ").nth(6).unwrap_or("");
    assert!(year.starts_with("20") && year.len() == 19, "{line}");
}
