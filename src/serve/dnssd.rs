//! DNS-SD advertisement (RFC 6762, RFC 6763): each queue an IPP Everywhere printer that
//! phones' and laptops' print dialogs find without being told its address.
//!
//! A queue is registered as `_ipp._tcp` with the `_print` subtype (`_print._sub._ipp._tcp`),
//! at the server's port, with the TXT keys of PWG 5100.14 §4.2.1 and Apple's Bonjour
//! Printing Specification. Their values are read from the very attributes
//! Get-Printer-Attributes answers with ([`printer_attributes`]): `pdl` is
//! `document-format-supported`, `URF` is `urf-supported`, `UUID` is `printer-uuid`, `ty`
//! is `printer-make-and-model`, and so on, so the advertisement cannot drift from the printer.
//!
//! Where it is heard follows the address the server listens on ([`Reach::of`]): a server on
//! `127.0.0.1` or `::1` is advertised on the loopback interface only (local browsers such as
//! Avahi, and through it CUPS, find it; the network does not, as it could not connect);
//! a server on one address on the interface that holds it; a server on `0.0.0.0` or `::`
//! on every interface, with their addresses as they come and go.
//!
//! The responder is `mdns-sd` (pure Rust, one thread of its own, no system daemon needed);
//! it answers queries until the [`Advertiser`] is dropped, which sends the goodbyes.

use std::net::{IpAddr, SocketAddr};

use ipp::attribute::IppAttribute;
use ipp::value::IppValue;
use mdns_sd::{IfKind, ServiceDaemon, ServiceInfo};

use super::attributes::{printer_attributes, PrinterStatus};
use super::config::Queue;
use super::printer::Printer;
use crate::error::{Error, Result};

/// The service type of an IPP printer.
pub const SERVICE_TYPE: &str = "_ipp._tcp.local.";

/// The subtype that marks an IPP Everywhere printer (`_print._sub._ipp._tcp`).
pub const PRINT_SUBTYPE: &str = "_print._sub._ipp._tcp.local.";

/// The longest DNS label, and so the longest instance name, in bytes.
const MAX_LABEL: usize = 63;

/// The longest TXT string (`key=value`), in bytes (RFC 6763 §6.1).
const MAX_TXT: usize = 255;

/// Where the advertisement is heard, from the address the server listens on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reach {
    /// The loopback interface only, with this address: the server takes no other
    /// connections, so the network must not be told of it.
    Loopback(IpAddr),
    /// The interface holding this address, with this address.
    Interface(IpAddr),
    /// Every interface (IPv4 ones only when `v4_only`), with their own addresses.
    All {
        /// The server listens on `0.0.0.0`: IPv4 only.
        v4_only: bool,
    },
}

impl Reach {
    /// Where a server listening on `listen` is advertised.
    pub fn of(listen: SocketAddr) -> Reach {
        let ip = listen.ip();
        if ip.is_loopback() {
            Reach::Loopback(ip)
        } else if ip.is_unspecified() {
            Reach::All {
                v4_only: ip.is_ipv4(),
            }
        } else {
            Reach::Interface(ip)
        }
    }

    /// In words, for the log: `loopback only`, `the interface of 192.168.1.5`, `every
    /// interface`.
    pub fn describe(&self) -> String {
        match self {
            Reach::Loopback(_) => "loopback only".into(),
            Reach::Interface(ip) => format!("the interface of {ip}"),
            Reach::All { v4_only: true } => "every IPv4 interface".into(),
            Reach::All { v4_only: false } => "every interface".into(),
        }
    }

    /// The interfaces the responder uses.
    fn interfaces(&self) -> Vec<IfKind> {
        match self {
            Reach::Loopback(ip) if ip.is_ipv4() => vec![IfKind::LoopbackV4],
            Reach::Loopback(_) => vec![IfKind::LoopbackV6],
            Reach::Interface(ip) => vec![IfKind::Addr(*ip)],
            Reach::All { v4_only: true } => vec![IfKind::IPv4],
            Reach::All { v4_only: false } => vec![IfKind::All],
        }
    }
}

/// What one queue advertises.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Advert {
    /// The queue's name.
    pub queue: String,
    /// The service instance name shown in print dialogs (at most 63 bytes).
    pub instance: String,
    /// The TXT record: keys and values, in order.
    pub txt: Vec<(String, String)>,
}

/// The instance name of queue `q` on host `host`: its `dnssd_name`, else `halftone NAME @
/// HOST` (the host keeps two servers' queues of the same name apart on a network), cut to
/// 63 bytes on a character boundary.
pub fn instance_name(q: &Queue, host: &str) -> String {
    let name = match &q.dnssd_name {
        Some(n) => n.clone(),
        None => format!("halftone {} @ {host}", q.name),
    };
    cut(&name, MAX_LABEL).to_string()
}

/// The adverts of a printer's queues (those not turned off with `dnssd = false`).
/// `admin_host` is `HOST:PORT` as a browser on the network reaches the status page.
pub fn adverts(printer: &Printer, host: &str, admin_host: &str) -> Vec<Advert> {
    let status = PrinterStatus {
        up_time: 1,
        started_unix: 0,
        queued: 0,
        processing: false,
    };
    printer
        .config()
        .queues
        .iter()
        .filter(|q| q.dnssd)
        .map(|q| {
            let attrs = printer_attributes(q, &printer.queue_uri(q), printer.host(), &status);
            Advert {
                queue: q.name.clone(),
                instance: instance_name(q, host),
                txt: txt_record(q, &attrs, &format!("http://{admin_host}/")),
            }
        })
        .collect()
}

/// The TXT record of queue `q` from its printer attributes `attrs` (what
/// Get-Printer-Attributes reports): the keys PWG 5100.14 §4.2.1 names, `txtvers` first.
/// `adminurl` is the status page's URL.
pub fn txt_record(q: &Queue, attrs: &[IppAttribute], adminurl: &str) -> Vec<(String, String)> {
    let values = |name: &str| -> Vec<String> {
        attrs
            .iter()
            .find(|a| a.name().as_str() == name)
            .map(|a| match a.value() {
                IppValue::Array(v) => v.iter().map(|x| x.to_string()).collect(),
                v => vec![v.to_string()],
            })
            .unwrap_or_default()
    };
    let first = |name: &str| values(name).into_iter().next().unwrap_or_default();
    let yes = |b: bool| if b { "T" } else { "F" }.to_string();
    let make = first("printer-make-and-model");
    let uuid = first("printer-uuid");
    let duplex = values("sides-supported").iter().any(|s| s != "one-sided");
    let mut txt: Vec<(String, String)> = vec![
        ("txtvers".into(), "1".into()),
        ("qtotal".into(), "1".into()),
        ("rp".into(), format!("ipp/print/{}", q.name)),
        ("ty".into(), make.clone()),
        ("product".into(), format!("({make})")),
        ("adminurl".into(), adminurl.to_string()),
        ("note".into(), first("printer-location")),
        ("priority".into(), "0".into()),
        ("pdl".into(), String::new()),
        ("URF".into(), String::new()),
        (
            "UUID".into(),
            uuid.trim_start_matches("urn:uuid:").to_string(),
        ),
        ("Color".into(), yes(first("color-supported") == "true")),
        ("Duplex".into(), yes(duplex)),
        ("kind".into(), values("printer-kind").join(",")),
        ("PaperMax".into(), paper_max(attrs).into()),
    ];
    // Lists cut at a comma if the string would pass 255 bytes.
    for (key, list) in [
        ("pdl", values("document-format-supported")),
        ("URF", values("urf-supported")),
    ] {
        if let Some(entry) = txt.iter_mut().find(|(k, _)| k == key) {
            entry.1 = joined(key, &list);
        }
    }
    let secure = values("uri-security-supported");
    if secure.iter().any(|s| s != "none") {
        txt.push(("TLS".into(), "1.2".into()));
    }
    for (k, v) in &mut txt {
        let room = MAX_TXT.saturating_sub(k.len() + 1);
        if v.len() > room {
            *v = cut(v, room).to_string();
        }
    }
    txt
}

/// `list` joined by commas, as many whole items as fit in one TXT string after `key=`.
fn joined(key: &str, list: &[String]) -> String {
    let room = MAX_TXT - key.len() - 1;
    let mut s = String::new();
    for item in list {
        let extra = item.len() + usize::from(!s.is_empty());
        if s.len() + extra > room {
            break;
        }
        if !s.is_empty() {
            s.push(',');
        }
        s.push_str(item);
    }
    s
}

/// The Bonjour Printing Specification's `PaperMax` from `media-size-supported`: the class
/// of the largest medium (`<legal-A4`, `legal-A4`, `tabloid-A3`, `isoC-A2`, `>isoC-A2`).
fn paper_max(attrs: &[IppAttribute]) -> &'static str {
    let (mut x, mut y) = (0, 0);
    if let Some(a) = attrs
        .iter()
        .find(|a| a.name().as_str() == "media-size-supported")
    {
        let sizes = match a.value() {
            IppValue::Array(v) => v.clone(),
            v => vec![v.clone()],
        };
        for s in sizes {
            if let IppValue::Collection(c) = s {
                for (k, v) in c {
                    match (k.as_str(), v) {
                        ("x-dimension", IppValue::Integer(d)) => x = x.max(d),
                        ("y-dimension", IppValue::Integer(d)) => y = y.max(d),
                        // A range (a roll): its longest.
                        ("x-dimension", IppValue::RangeOfInteger { max, .. }) => x = x.max(max),
                        ("y-dimension", IppValue::RangeOfInteger { max, .. }) => y = y.max(max),
                        _ => {}
                    }
                }
            }
        }
    }
    // Sizes in 1/100 mm; each class is reached when both sides hold its smaller sheet:
    // A4 210 × 297 (legal 215.9 × 355.6), A3 297 × 420 (tabloid 279.4 × 431.8), C2 458 × 648.
    let holds = |w: i32, h: i32| x >= w && y >= h;
    if !holds(21000, 29700) {
        "<legal-A4"
    } else if !holds(27940, 42000) {
        "legal-A4"
    } else if !holds(45800, 64800) {
        "tabloid-A3"
    } else if x > 45800 || y > 64800 {
        ">isoC-A2"
    } else {
        "isoC-A2"
    }
}

/// `s` cut to at most `n` bytes on a character boundary.
fn cut(s: &str, n: usize) -> &str {
    if s.len() <= n {
        return s;
    }
    let mut end = n;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

/// This machine's host name as one DNS label (letters, digits and `-`), or `halftone`.
pub fn host_label() -> String {
    let raw = system_host_name();
    let first = raw.split('.').next().unwrap_or("");
    let label: String = first
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let label = label.trim_matches('-');
    if label.is_empty() {
        "halftone".into()
    } else {
        cut(label, MAX_LABEL - "-halftone".len()).to_string()
    }
}

#[cfg(unix)]
fn system_host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; gethostname writes at most that many
    // bytes and the result is read up to its first NUL (or the whole buffer).
    let rc = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if rc != 0 {
        return String::new();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

#[cfg(not(unix))]
fn system_host_name() -> String {
    std::env::var("COMPUTERNAME").unwrap_or_default()
}

/// A running advertisement: the responder and the services it answers for. Dropping it
/// withdraws them (goodbye packets) and stops the responder.
pub struct Advertiser {
    daemon: ServiceDaemon,
    services: Vec<(Advert, String)>,
    reach: Reach,
    host: String,
}

impl Advertiser {
    /// Advertises the queues of `printer` (those not turned off), which listens on
    /// `listen` (the bound address: its port is the one advertised). The services' host is
    /// `HOST-halftone.local`, `HOST` this machine's name: a name of its own, so it never
    /// contends with the system's responder for the machine's own name. An error (no
    /// responder: no socket, no interface) is one line; the server can run without it.
    pub fn start(printer: &Printer, listen: SocketAddr) -> Result<Advertiser> {
        let host = host_label();
        let mdns_host = format!("{host}-halftone.local.");
        let reach = Reach::of(listen);
        let admin_host = match reach {
            Reach::All { .. } => format!("{}:{}", mdns_host.trim_end_matches('.'), listen.port()),
            _ => printer.host().to_string(),
        };
        let adverts = adverts(printer, &host, &admin_host);
        let fail = |what: &str, e: mdns_sd::Error| Error::Invalid(format!("DNS-SD: {what}: {e}"));
        let daemon = ServiceDaemon::new().map_err(|e| fail("cannot start the responder", e))?;
        let kinds = reach.interfaces();
        daemon
            .disable_interface(IfKind::All)
            .and_then(|()| daemon.enable_interface(kinds.clone()))
            .map_err(|e| fail("cannot choose the interfaces", e))?;
        let mut services = Vec::new();
        for advert in adverts {
            let txt: Vec<(&str, &str)> = advert
                .txt
                .iter()
                .map(|(k, v)| (k.as_str(), v.as_str()))
                .collect();
            let ips: Vec<IpAddr> = match reach {
                Reach::Loopback(ip) | Reach::Interface(ip) => vec![ip],
                Reach::All { .. } => Vec::new(),
            };
            let info = ServiceInfo::new(
                PRINT_SUBTYPE,
                &advert.instance,
                &mdns_host,
                &ips[..],
                listen.port(),
                &txt[..],
            )
            .map_err(|e| fail(&format!("queue {}", advert.queue), e))?;
            let mut info = if ips.is_empty() {
                info.enable_addr_auto()
            } else {
                info
            };
            info.set_interfaces(kinds.clone());
            let full = info.get_fullname().to_string();
            daemon
                .register(info)
                .map_err(|e| fail(&format!("queue {}", advert.queue), e))?;
            services.push((advert, full));
        }
        Ok(Advertiser {
            daemon,
            services,
            reach,
            host: mdns_host,
        })
    }

    /// The adverts, each with its full service name (`INSTANCE._ipp._tcp.local.`).
    pub fn services(&self) -> impl Iterator<Item = (&Advert, &str)> {
        self.services.iter().map(|(a, n)| (a, n.as_str()))
    }

    /// Where the advertisement is heard.
    pub fn reach(&self) -> &Reach {
        &self.reach
    }

    /// The host name in the services' SRV records (`HOST-halftone.local.`).
    pub fn host(&self) -> &str {
        &self.host
    }
}

impl Drop for Advertiser {
    fn drop(&mut self) {
        for (_, name) in &self.services {
            if let Ok(done) = self.daemon.unregister(name) {
                let _ = done.recv_timeout(std::time::Duration::from_secs(1));
            }
        }
        if let Ok(done) = self.daemon.shutdown() {
            let _ = done.recv_timeout(std::time::Duration::from_secs(1));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serve::{Config, Limits};

    fn printer(text: &str) -> Printer {
        let config = Config::parse(text).unwrap();
        Printer::new(
            config,
            "127.0.0.1:8631",
            Limits {
                max_request: 1 << 20,
                max_jobs: 10,
                ..Limits::default()
            },
        )
    }

    fn get<'a>(txt: &'a [(String, String)], key: &str) -> &'a str {
        txt.iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .unwrap_or_else(|| panic!("no {key} in {txt:?}"))
    }

    #[test]
    fn reach_follows_the_listening_address() {
        let r = |s: &str| Reach::of(s.parse().unwrap());
        assert_eq!(
            r("127.0.0.1:631"),
            Reach::Loopback("127.0.0.1".parse().unwrap())
        );
        assert_eq!(r("[::1]:631"), Reach::Loopback("::1".parse().unwrap()));
        assert_eq!(r("0.0.0.0:631"), Reach::All { v4_only: true });
        assert_eq!(r("[::]:631"), Reach::All { v4_only: false });
        assert_eq!(
            r("192.168.1.5:631"),
            Reach::Interface("192.168.1.5".parse().unwrap())
        );
    }

    #[test]
    fn txt_keys_come_from_the_printer_attributes() {
        let p = printer(
            "[queue.lab]\npreset = \"label-203\"\nbackend = \"file:///tmp/x\"\n\
             [queue.laser]\npreset = \"laser-600\"\nbackend = \"file:///tmp/y\"\n\
             dnssd_name = \"Office laser\"\n\
             [queue.quiet]\npreset = \"thermal-203\"\nbackend = \"file:///tmp/z\"\n\
             dnssd = false\n",
        );
        let ads = adverts(&p, "box", "127.0.0.1:8631");
        assert_eq!(ads.len(), 2, "dnssd = false is not advertised");
        let status = PrinterStatus {
            up_time: 1,
            started_unix: 0,
            queued: 0,
            processing: false,
        };
        for (ad, q) in ads.iter().zip(&p.config().queues) {
            let attrs = printer_attributes(q, &p.queue_uri(q), p.host(), &status);
            let value = |n: &str| {
                let a = attrs.iter().find(|a| a.name().as_str() == n).unwrap();
                match a.value() {
                    IppValue::Array(v) => v.iter().map(|x| x.to_string()).collect(),
                    v => vec![v.to_string()],
                }
            };
            let t = &ad.txt;
            assert_eq!(t[0], ("txtvers".into(), "1".into()));
            assert_eq!(get(t, "qtotal"), "1");
            assert_eq!(get(t, "rp"), format!("ipp/print/{}", q.name));
            assert_eq!(get(t, "pdl"), value("document-format-supported").join(","));
            assert_eq!(get(t, "URF"), value("urf-supported").join(","));
            assert_eq!(
                format!("urn:uuid:{}", get(t, "UUID")),
                value("printer-uuid")[0]
            );
            assert_eq!(get(t, "ty"), value("printer-make-and-model")[0]);
            assert_eq!(get(t, "product"), format!("({})", get(t, "ty")));
            assert_eq!(get(t, "Color"), "F");
            assert_eq!(get(t, "Duplex"), "F");
            assert_eq!(get(t, "adminurl"), "http://127.0.0.1:8631/");
            assert!(t.iter().all(|(k, _)| k != "TLS"), "no TLS is served");
            assert!(t.iter().all(|(k, v)| k.len() + v.len() < 255));
        }
        assert_eq!(ads[0].instance, "halftone lab @ box");
        assert_eq!(get(&ads[0].txt, "kind"), "label");
        assert_eq!(get(&ads[0].txt, "PaperMax"), "<legal-A4");
        assert_eq!(ads[1].instance, "Office laser");
        assert_eq!(get(&ads[1].txt, "kind"), "document");
        assert_eq!(get(&ads[1].txt, "PaperMax"), "legal-A4");
    }

    #[test]
    fn long_names_and_lists_are_cut_to_dns_limits() {
        let long = "é".repeat(40);
        let p = printer(&format!(
            "[queue.a]\npreset = \"thermal-203\"\nbackend = \"file:///t\"\n\
             dnssd_name = \"{long}\"\n"
        ));
        let ad = &adverts(&p, "h", "h:1")[0];
        assert_eq!(ad.instance.len(), 62, "{}", ad.instance);
        assert!(ad.instance.chars().all(|c| c == 'é'));
        let items: Vec<String> = (0..40).map(|i| format!("image/x-{i:03}")).collect();
        let j = joined("pdl", &items);
        assert!(j.len() <= 251 && j.ends_with("image/x-020"), "{j}");
        assert!(host_label().len() <= 54);
    }
}
