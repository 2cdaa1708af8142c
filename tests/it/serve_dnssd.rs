//! `halftone serve`'s DNS-SD advertisement, seen by an independent browser: Debian's Avahi
//! (`avahi-browse`), with the system bus and `avahi-daemon` started here when they are not
//! running. The server listens on 127.0.0.1, so its queues must be heard on the loopback
//! interface only; their TXT keys must say what Get-Printer-Attributes says; and CUPS's
//! `ippfind` must find a queue and `ipptool` reach it through the URI it builds.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;
use crate::serve::Server;

const CHECK: &str = "serve: DNS-SD advertisement seen by avahi-browse";

/// Get-Printer-Attributes of a queue, by hand: the values of each attribute as text.
fn printer_attributes(port: u16, queue: &str) -> Vec<(String, Vec<String>)> {
    let uri = format!("ipp://127.0.0.1:{port}/ipp/print/{queue}");
    let mut b = vec![2, 0, 0x00, 0x0b, 0, 0, 0, 1, 0x01];
    for (tag, n, v) in [
        (0x47u8, "attributes-charset", "utf-8"),
        (0x48, "attributes-natural-language", "en"),
        (0x45, "printer-uri", uri.as_str()),
    ] {
        b.push(tag);
        b.extend_from_slice(&(n.len() as u16).to_be_bytes());
        b.extend_from_slice(n.as_bytes());
        b.extend_from_slice(&(v.len() as u16).to_be_bytes());
        b.extend_from_slice(v.as_bytes());
    }
    b.push(0x03);
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let head = format!(
        "POST /ipp/print/{queue} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: \
         application/ipp\r\nConnection: close\r\nContent-Length: {}\r\n\r\n",
        b.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&b).unwrap();
    let mut resp = Vec::new();
    s.read_to_end(&mut resp).unwrap();
    let end = resp.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let r = ipp::parser::IppParser::new(ipp::reader::IppReader::new(std::io::Cursor::new(
        resp[end + 4..].to_vec(),
    )))
    .parse()
    .expect("an IPP response");
    let mut out = Vec::new();
    for group in r.attributes().groups() {
        for a in group.attributes() {
            let values = match a.value() {
                ipp::value::IppValue::Array(v) => v.iter().map(|x| x.to_string()).collect(),
                v => vec![v.to_string()],
            };
            out.push((a.name().to_string(), values));
        }
    }
    out
}

/// One resolved service from `avahi-browse -p` (`=;IFACE;PROTO;NAME;TYPE;DOMAIN;HOST;ADDR;
/// PORT;"k=v" "k=v"…`).
#[derive(Debug)]
struct Seen {
    iface: String,
    proto: String,
    name: String,
    addr: String,
    port: u16,
    txt: Vec<(String, String)>,
}

/// Avahi's escapes in names: `\DDD` (decimal) and `\c`.
fn unescape(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'\\' && i + 3 < b.len() && b[i + 1..i + 4].iter().all(u8::is_ascii_digit) {
            let n: u32 = s[i + 1..i + 4].parse().unwrap();
            out.push(n as u8);
            i += 4;
        } else if b[i] == b'\\' && i + 1 < b.len() {
            out.push(b[i + 1]);
            i += 2;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// `avahi-browse -pkt TYPE` (parsable, no name database, terminate; `-r`: resolve): the
/// resolved services, and the names of every one browsed (`+` lines).
fn browse(ty: &str, resolve: bool) -> (Vec<Seen>, Vec<String>) {
    let flags = if resolve { "-rpkt" } else { "-pkt" };
    let out = Command::new("timeout")
        .args(["20", "avahi-browse", flags, ty])
        .output()
        .expect("run avahi-browse");
    let text = String::from_utf8_lossy(&out.stdout);
    let mut seen = Vec::new();
    let mut names = Vec::new();
    for line in text.lines() {
        let f: Vec<&str> = line.splitn(10, ';').collect();
        if f[0] == "+" && f.len() >= 4 {
            names.push(unescape(f[3]));
        }
        if f[0] != "=" || f.len() < 10 {
            continue;
        }
        let txt = f[9]
            .split('"')
            .skip(1)
            .step_by(2)
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        seen.push(Seen {
            iface: f[1].into(),
            proto: f[2].into(),
            name: unescape(f[3]),
            addr: f[7].into(),
            port: f[8].parse().unwrap_or(0),
            txt,
        });
    }
    (seen, names)
}

/// Starts the system bus and Avahi unless they run; false (after a skip) when they cannot be.
pub(crate) fn avahi_running() -> bool {
    for (tool, package) in [
        ("avahi-browse", "avahi-utils"),
        ("avahi-daemon", "avahi-daemon"),
        ("dbus-daemon", "dbus"),
    ] {
        if !common::have_tool(tool, package, CHECK) {
            return false;
        }
    }
    let running = || {
        Command::new("avahi-daemon")
            .arg("--check")
            .status()
            .is_ok_and(|s| s.success())
    };
    if running() {
        return true;
    }
    let root = Command::new("id").arg("-u").output().unwrap();
    if String::from_utf8_lossy(&root.stdout).trim() != "0" {
        common::skip(
            CHECK,
            "avahi-daemon is not running and starting it needs root",
        );
        return false;
    }
    let bus = std::path::Path::new("/run/dbus/system_bus_socket");
    if std::os::unix::net::UnixStream::connect(bus).is_err() {
        // Nothing answers on the socket, so a socket or pid file left there is stale (a
        // machine restored from a snapshot keeps both): dbus-daemon refuses to start over
        // an existing pid file.
        let _ = std::fs::remove_file(bus);
        let _ = std::fs::remove_file("/run/dbus/pid");
        std::fs::create_dir_all("/run/dbus").unwrap();
        let out = Command::new("dbus-daemon")
            .args(["--system", "--fork"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "dbus-daemon --system --fork failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    // Left running, as a system daemon is: other checks (and ippeveprinter) share it.
    let ok = Command::new("avahi-daemon")
        .args(["--no-drop-root", "-D"])
        .status()
        .unwrap();
    let start = Instant::now();
    while !running() {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "avahi-daemon did not start ({ok})"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    true
}

/// Browses `ty` until `want` says the answer is complete, for at most 20 s.
fn browse_until(
    ty: &str,
    resolve: bool,
    want: impl Fn(&[Seen], &[String]) -> bool,
) -> (Vec<Seen>, Vec<String>) {
    let start = Instant::now();
    loop {
        let (seen, names) = browse(ty, resolve);
        if want(&seen, &names) || start.elapsed() > Duration::from_secs(20) {
            return (seen, names);
        }
        std::thread::sleep(Duration::from_millis(300));
    }
}

fn txt<'a>(s: &'a Seen, key: &str) -> &'a str {
    s.txt
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
        .unwrap_or_else(|| panic!("{}: no TXT key {key}: {:?}", s.name, s.txt))
}

/// Two queues from a file (one with the default instance name, one named with
/// `dnssd_name`), a third with `dnssd = false`, and a single-queue server with `--no-dnssd`:
/// Avahi sees the first two, on loopback only, at 127.0.0.1 and the server's port, as
/// `_ipp._tcp` and as `_print._sub._ipp._tcp`, with the TXT keys of IPP Everywhere equal to
/// the printer's own attributes; it never sees the other two; after SIGTERM it sees none.
#[test]
fn avahi_sees_the_queues_with_their_printer_attributes() {
    if !avahi_running() {
        return;
    }
    let id = std::process::id();
    let (lab, receipt, hidden) = (
        format!("lab-{id}"),
        format!("receipt-{id}"),
        format!("hidden-{id}"),
    );
    let named = format!("Front desk {id}");
    let dir = tempfile::tempdir().unwrap();
    let jobs = format!("file://{}", dir.path().display());
    let quiet_queue = format!("quiet-{id}");
    let _quiet = Server::start(&[
        "--queue",
        &quiet_queue,
        "--preset",
        "thermal-203",
        "--backend",
        &jobs,
        "--no-dnssd",
    ]);
    let config = dir.path().join("queues.toml");
    std::fs::write(
        &config,
        format!(
            "[queue.{lab}]\npreset = \"label-203\"\nbackend = \"{jobs}\"\n\n\
             [queue.{receipt}]\npreset = \"thermal-203\"\nbackend = \"{jobs}\"\n\
             dnssd_name = \"{named}\"\n\n\
             [queue.{hidden}]\npreset = \"thermal-203\"\nbackend = \"{jobs}\"\ndnssd = false\n"
        ),
    )
    .unwrap();
    let mut server = Server::start(&["--config", config.to_str().unwrap()]);
    let lab_prefix = format!("halftone {lab} @ ");
    let ours = |n: &str| n.starts_with(&lab_prefix) || n == named;
    let both = |seen: &[Seen], _: &[String]| {
        seen.iter().any(|s| s.name.starts_with(&lab_prefix)) && seen.iter().any(|s| s.name == named)
    };
    let (seen, names) = browse_until("_ipp._tcp", true, both);
    let mine: Vec<&Seen> = seen.iter().filter(|s| ours(&s.name)).collect();
    assert!(both(&seen, &names), "not both queues seen: {names:?}");
    for n in &names {
        assert!(
            !n.contains(&hidden) && !n.contains(&quiet_queue),
            "{n} was not to be advertised"
        );
    }
    for s in &mine {
        assert_eq!(
            (s.iface.as_str(), s.proto.as_str(), s.addr.as_str(), s.port),
            ("lo", "IPv4", "127.0.0.1", server.port),
            "advertised beyond loopback or at the wrong address: {s:?}"
        );
        let queue = if s.name == named { &receipt } else { &lab };
        let attrs = printer_attributes(server.port, queue);
        let attr = |n: &str| {
            attrs
                .iter()
                .find(|(k, _)| k == n)
                .map(|(_, v)| v.clone())
                .unwrap_or_else(|| panic!("no {n}"))
        };
        assert_eq!(txt(s, "txtvers"), "1");
        assert_eq!(txt(s, "qtotal"), "1");
        assert_eq!(txt(s, "rp"), format!("ipp/print/{queue}"));
        assert_eq!(txt(s, "pdl"), attr("document-format-supported").join(","));
        assert_eq!(txt(s, "URF"), attr("urf-supported").join(","));
        assert_eq!(
            format!("urn:uuid:{}", txt(s, "UUID")),
            attr("printer-uuid")[0]
        );
        assert_eq!(txt(s, "ty"), attr("printer-make-and-model")[0]);
        assert_eq!(txt(s, "product"), format!("({})", txt(s, "ty")));
        assert_eq!(txt(s, "note"), attr("printer-location")[0]);
        assert_eq!(txt(s, "kind"), attr("printer-kind").join(","));
        assert_eq!(txt(s, "Color"), "F");
        assert_eq!(txt(s, "Duplex"), "F");
        assert_eq!(txt(s, "PaperMax"), "<legal-A4");
        assert_eq!(txt(s, "priority"), "0");
        assert_eq!(
            txt(s, "adminurl"),
            format!("http://127.0.0.1:{}/", server.port)
        );
        assert!(s.txt.iter().all(|(k, _)| k != "TLS"), "no TLS is served");
    }
    let lab_kind = mine
        .iter()
        .find(|s| s.name != named)
        .map(|s| txt(s, "kind"));
    assert_eq!(lab_kind, Some("label"));
    // The IPP Everywhere subtype: what a phone's print dialog browses.
    let (_, sub) = browse_until("_print._sub._ipp._tcp", false, |_, names| {
        names.iter().filter(|n| ours(n)).count() >= 2
    });
    assert_eq!(
        sub.iter().filter(|n| ours(n)).count(),
        2,
        "_print._sub._ipp._tcp: {sub:?}"
    );
    // CUPS's own browser finds the queue by the subtype and builds its URI from the SRV and
    // `rp`; ipptool then reaches it through that URI (the host name resolved over mDNS).
    if common::have_tool("ippfind", "cups-ipp-utils", CHECK)
        && common::have_tool("ipptool", "cups-ipp-utils", CHECK)
    {
        let out = Command::new("timeout")
            .args(["30", "ippfind", "-T", "3", "_ipp._tcp,_print", "--name"])
            .arg(format!("^{named}$"))
            .args(["--print", "--exec", "ipptool", "-q", "{}"])
            .args(["get-printer-attributes.test", ";"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        let uri = text.lines().next().unwrap_or("");
        assert!(
            uri.starts_with("ipp://")
                && uri.contains("-halftone.local:")
                && uri.ends_with(&format!(":{}/ipp/print/{receipt}", server.port)),
            "ippfind: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.status.success(),
            "ipptool get-printer-attributes.test through {uri} failed (libnss-mdns resolves \
             .local names): {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // SIGTERM: goodbye packets, and Avahi forgets both at once (not after 75 minutes).
    let status = server.terminate();
    assert_eq!(
        std::os::unix::process::ExitStatusExt::signal(&status).or(status.code()),
        Some(128 + 15),
        "halftone serve exits with 128 + SIGTERM"
    );
    let (_, left) = browse_until("_ipp._tcp", false, |_, names| {
        !names.iter().any(|n| ours(n))
    });
    assert!(
        !left.iter().any(|n| ours(n)),
        "still advertised after SIGTERM: {left:?}"
    );
}
