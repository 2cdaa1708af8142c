//! Sending a job's bytes to its queue's backend: a folder (one file a job, written
//! atomically), a device file (written straight), an AppSocket printer (TCP port 9100) or
//! another IPP printer (Print-Job in a format it lists: the queue's own when it takes it,
//! else the same pages re-wrapped, bit for bit, in PWG raster, Apple raster or PDF).

use std::io::Write;
use std::net::{TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::time::Duration;

use super::client::Target;
use super::config::Backend;
use crate::error::{Error, Result};
use crate::io::{Format, WriteOptions};
use crate::raster::{Halftone, Image, Samples};
use crate::tone::Encoding;

/// How long a socket printer may take to accept a connection or a write.
const SOCKET_TIMEOUT: Duration = Duration::from_secs(30);

impl Backend {
    /// True when a failed delivery may succeed if tried again: an I/O error (a printer off,
    /// unplugged or unreachable, a folder not there yet, an IPP printer busy or restarting).
    /// Anything else (an IPP printer that refuses the job's format or attributes) will not
    /// pass, and the job is aborted with the reason.
    pub fn may_pass(e: &Error) -> bool {
        matches!(e, Error::Io { .. })
    }

    /// Delivers one job's bytes; `file_name` names the file in a folder backend (the
    /// job's number and the format's extension). Returns where the bytes went.
    pub fn deliver(&self, bytes: &[u8], file_name: &str) -> Result<String> {
        match self {
            Backend::Folder(dir) => {
                let path = dir.join(file_name);
                crate::io::write_atomic(&path, |w| w.write_all(bytes))?;
                Ok(path.display().to_string())
            }
            Backend::Device(path) => {
                let mut f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(|e| Error::io(path, e))?;
                f.write_all(bytes)
                    .and_then(|_| f.flush())
                    .map_err(|e| Error::io(path, e))?;
                Ok(path.display().to_string())
            }
            Backend::Socket(addr) => {
                let name = PathBuf::from(format!("socket://{addr}"));
                let io = |e| Error::io(&name, e);
                let target = addr.to_socket_addrs().map_err(io)?.next().ok_or_else(|| {
                    Error::io(&name, std::io::Error::other("the host has no address"))
                })?;
                let mut s = TcpStream::connect_timeout(&target, SOCKET_TIMEOUT).map_err(io)?;
                s.set_write_timeout(Some(SOCKET_TIMEOUT)).map_err(io)?;
                s.write_all(bytes).and_then(|_| s.flush()).map_err(io)?;
                let _ = s.shutdown(std::net::Shutdown::Write);
                Ok(format!("socket://{addr}"))
            }
            Backend::Ipp(t) => deliver_ipp(t, bytes, file_name),
        }
    }
}

/// Sends a job to another IPP printer: as it is when the printer lists the queue's format,
/// else its pages decoded and written again in the format the printer prefers.
fn deliver_ipp(t: &Target, bytes: &[u8], file_name: &str) -> Result<String> {
    let info = t.printer_info_cached()?;
    let own = Format::from_path(std::path::Path::new(file_name));
    let fail = |msg: String| Error::Invalid(format!("{}: {msg}", t.uri));
    let (data, format) = match own {
        Some(f) if info.takes(f) => (bytes.to_vec(), f),
        _ => {
            let lang = own
                .and_then(Format::language)
                .or_else(|| crate::io::lang::Language::sniff(bytes))
                .ok_or_else(|| {
                    fail(format!(
                        "the printer takes {}; give the queue a printer format (pwg, urf, pdf)",
                        info.formats.join(", ")
                    ))
                })?;
            let pages = lang
                .pages(bytes)
                .map_err(|e| fail(format!("reading the job's {}: {e}", lang.name())))?;
            let colour = pages.iter().any(|p| p.planes.len() == 3);
            let format = info.choose_format(None, colour).ok_or_else(|| {
                fail(format!(
                    "the printer lists none of PWG raster, Apple raster and PDF{} ({})",
                    if colour { " in colour" } else { "" },
                    info.formats.join(", ")
                ))
            })?;
            let fallback = info
                .choose_resolution(format, None, false)
                .ok()
                .flatten()
                .map_or(300.0, f64::from);
            (rewrap(&pages, format, fallback)?, format)
        }
    };
    let id = t.print_job(&data, format, file_name)?;
    Ok(format!("{} job {id} ({})", t.uri, format.name()))
}

/// Decoded pages (codes 0..255, grey or RGB) written again in `format`, sample for sample:
/// black and white pages as bilevel (PWG `black_1`), others as 256 levels written
/// linearly, so each code is the one decoded.
fn rewrap(pages: &[Image], format: Format, fallback_dpi: f64) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut enc: Option<Box<dyn crate::io::sink::PageEncoder>> = None;
    let name = std::path::Path::new(format.name());
    for img in pages {
        let planes: Vec<&[u8]> = img
            .planes
            .iter()
            .filter_map(|p| match p {
                Samples::U8(v) => Some(v.as_slice()),
                Samples::U16(_) => None,
            })
            .collect();
        if planes.len() != img.planes.len() {
            return Err(Error::Invalid("a 16-bit page to forward".into()));
        }
        let bilevel = planes.len() == 1 && planes[0].iter().all(|&v| v == 0 || v == 255);
        let levels = if bilevel { 2 } else { 256 };
        let mut h = Halftone::new(img.width, img.height, planes.len(), levels);
        for (c, p) in planes.iter().enumerate() {
            for (i, &v) in p.iter().enumerate() {
                let level = if bilevel { v / 255 } else { v };
                h.set(c, i % img.width, i / img.width, level);
            }
        }
        let dpi = Some(img.dpi.unwrap_or(fallback_dpi));
        let mut w = WriteOptions::new(format);
        w.dpi = dpi;
        w.display = Encoding::Linear;
        let e = enc.get_or_insert_with(|| crate::io::page_encoder(&w));
        crate::io::sink::encode_halftone(e.as_mut(), &h, dpi, &mut out)
            .map_err(|e| e.named(name))?;
    }
    if let Some(mut e) = enc {
        e.finish(&mut out).map_err(|e| e.named(name))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_gets_one_file_a_job_and_a_socket_the_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let b = Backend::Folder(dir.path().to_path_buf());
        b.deliver(b"abc", "job-1.escpos").unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("job-1.escpos")).unwrap(),
            b"abc"
        );

        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let t = std::thread::spawn(move || {
            let (mut c, _) = listener.accept().unwrap();
            let mut got = Vec::new();
            std::io::Read::read_to_end(&mut c, &mut got).unwrap();
            got
        });
        Backend::Socket(addr.to_string())
            .deliver(b"\x1b@hello", "x")
            .unwrap();
        assert_eq!(t.join().unwrap(), b"\x1b@hello");

        // Pages re-wrapped from ZPL into PWG raster keep every bit.
        let mut ht = Halftone::new(21, 5, 1, 2);
        for i in 0..105 {
            ht.set(0, i % 21, i / 21, (i * 7 % 3 == 0) as u8);
        }
        let zpl = crate::api::encode(
            &ht,
            Format::Zpl,
            &crate::Options {
                format: Some(Format::Zpl),
                ..Default::default()
            },
        )
        .unwrap();
        let pages = crate::io::lang::Language::Zpl.pages(&zpl).unwrap();
        let pwg = rewrap(&pages, Format::Pwg, 203.0).unwrap();
        let back = crate::io::lang::Language::Pwg.pages(&pwg).unwrap();
        assert_eq!(back[0].planes, pages[0].planes);
        assert_eq!(back[0].dpi, Some(203.0));

        // A printer that is off may come back; a refusal will not.
        let down = Backend::Folder(dir.path().join("not-yet"))
            .deliver(b"x", "job-2.escpos")
            .unwrap_err();
        assert!(Backend::may_pass(&down), "{down}");
        assert!(!Backend::may_pass(&Error::Invalid("refused".into())));
        let missing = Backend::Device(dir.path().join("no/such/lp0"));
        assert!(missing
            .deliver(b"x", "x")
            .unwrap_err()
            .to_string()
            .contains("lp0"));
    }
}
