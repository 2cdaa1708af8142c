//! The client side of IPP: asking a printer what it takes (Get-Printer-Attributes),
//! sending it a document (Print-Job) and following the job (Get-Job-Attributes), for
//! `halftone print` and the `ipp://` backend of a print queue.
//!
//! IPP over HTTP/1.1 is written by hand on a `TcpStream` (one request a connection,
//! `Content-Length`; a response with a length, chunked or to the end): IPP needs one POST,
//! and an HTTP client crate would bring a tree larger than the rest of this module. The IPP
//! encoding is the `ipp` crate's, as the server's. `ipps://` (IPP over TLS) is refused
//! with a message: no TLS stack is built in.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Cursor, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use ipp::attribute::IppAttribute;
use ipp::model::{DelimiterTag, IppVersion, Operation};
use ipp::parser::IppParser;
use ipp::reader::IppReader;
use ipp::request::IppRequestResponse;
use ipp::value::IppValue;

use crate::error::{Error, Result};
use crate::io::Format;

/// How long a printer may take to accept a connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);
/// How long a printer may take to answer a request (a large document's Print-Job included).
const READ_TIMEOUT: Duration = Duration::from_secs(300);
/// How long Print-Job is tried again while the printer says it is busy.
const BUSY_WAIT: Duration = Duration::from_secs(300);
/// The largest response taken (attributes, never documents).
const MAX_RESPONSE: u64 = 16 << 20;

/// An IPP printer's address: `ipp://HOST[:PORT]/PATH` (port 631 when not given).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Target {
    /// The URI as given (the `printer-uri` sent).
    pub uri: String,
    /// Host name or address (IPv6 without brackets).
    pub host: String,
    /// TCP port.
    pub port: u16,
    /// The HTTP path (`/ipp/print`).
    pub path: String,
}

impl Target {
    /// Parses `ipp://HOST[:PORT]/PATH`; `ipps://` and other schemes are refused with a line
    /// saying why.
    pub fn parse(uri: &str) -> std::result::Result<Target, String> {
        let uri = uri.trim();
        if uri.starts_with("ipps://") {
            return Err(format!(
                "{uri}: ipps:// (IPP over TLS) is not supported; use the printer's ipp:// URI"
            ));
        }
        let Some(rest) = uri.strip_prefix("ipp://") else {
            return Err(format!("{uri}: expected ipp://HOST[:PORT]/PATH"));
        };
        let (authority, path) = match rest.find('/') {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, "/ipp/print"),
        };
        let bad = || format!("{uri}: expected ipp://HOST[:PORT]/PATH");
        let (host, port) = if let Some(v6) = authority.strip_prefix('[') {
            let (h, after) = v6.split_once(']').ok_or_else(bad)?;
            let port = match after.strip_prefix(':') {
                Some(p) => p.parse().map_err(|_| bad())?,
                None if after.is_empty() => 631,
                None => return Err(bad()),
            };
            (h.to_string(), port)
        } else {
            match authority.rsplit_once(':') {
                Some((h, p)) => (h.to_string(), p.parse().map_err(|_| bad())?),
                None => (authority.to_string(), 631),
            }
        };
        if host.is_empty() || path.contains(char::is_whitespace) {
            return Err(bad());
        }
        Ok(Target {
            uri: uri.to_string(),
            host,
            port,
            path: path.to_string(),
        })
    }

    fn fail(&self, msg: impl std::fmt::Display) -> Error {
        Error::Invalid(format!("{}: {msg}", self.uri))
    }

    /// A failure that may pass (the printer off, unreachable, restarting or busy): the
    /// same words as [`Self::fail`], as an I/O error, which a queue's backend waits on and
    /// tries again rather than aborting the job (see `Backend::may_pass`).
    fn passing(&self, msg: impl std::fmt::Display) -> Error {
        Error::Io {
            path: std::path::PathBuf::from(&self.uri),
            cause: std::io::Error::other(msg.to_string()),
        }
    }

    /// Sends one IPP request (`body` = the encoded request, then any document) and returns
    /// the response.
    pub fn post(&self, body: &[u8]) -> Result<IppRequestResponse> {
        let io = |e: std::io::Error| self.passing(e);
        let addr = (self.host.as_str(), self.port)
            .to_socket_addrs()
            .map_err(io)?
            .next()
            .ok_or_else(|| self.passing("no address for the host"))?;
        let mut s = TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT).map_err(io)?;
        s.set_read_timeout(Some(READ_TIMEOUT)).map_err(io)?;
        s.set_write_timeout(Some(READ_TIMEOUT)).map_err(io)?;
        let host = if self.host.contains(':') {
            format!("[{}]:{}", self.host, self.port)
        } else {
            format!("{}:{}", self.host, self.port)
        };
        let head = format!(
            "POST {} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/ipp\r\n\
             Content-Length: {}\r\nConnection: close\r\nUser-Agent: halftone\r\n\r\n",
            self.path,
            body.len()
        );
        s.write_all(head.as_bytes())
            .and_then(|_| s.write_all(body))
            .and_then(|_| s.flush())
            .map_err(io)?;
        let mut r = BufReader::new(s);
        let (code, reason, headers) = loop {
            let (code, reason, headers) = read_head(&mut r).map_err(|e| self.passing(e))?;
            // 100 Continue comes before the real answer.
            if code != 100 {
                break (code, reason, headers);
            }
        };
        if code != 200 {
            let msg = format!("HTTP {code} {reason}");
            return Err(if code >= 500 {
                self.passing(msg)
            } else {
                self.fail(msg)
            });
        }
        let header = |name: &str| {
            headers
                .iter()
                .find(|(k, _)| k.eq_ignore_ascii_case(name))
                .map(|(_, v)| v.as_str())
        };
        let mut data = Vec::new();
        if header("transfer-encoding").is_some_and(|v| v.to_ascii_lowercase().contains("chunked")) {
            read_chunked(&mut r, &mut data).map_err(|e| self.passing(e))?;
        } else if let Some(n) = header("content-length") {
            let n: u64 = n
                .trim()
                .parse()
                .map_err(|_| self.fail("a bad Content-Length"))?;
            if n > MAX_RESPONSE {
                return Err(self.fail(format!("a response of {n} bytes")));
            }
            r.take(n).read_to_end(&mut data).map_err(io)?;
        } else {
            r.take(MAX_RESPONSE).read_to_end(&mut data).map_err(io)?;
        }
        // A printer's response is as untrusted as a client's request (see `check_wire`).
        super::wire::check_wire(&data)
            .map_err(|e| self.fail(format!("an unreadable IPP response ({e})")))?;
        IppParser::new(IppReader::new(Cursor::new(data)))
            .parse()
            .map_err(|e| self.fail(format!("an unreadable IPP response ({e})")))
    }

    /// A request for `op` to this printer, with `printer-uri` and `requesting-user-name`.
    fn request(&self, op: Operation) -> Result<IppRequestResponse> {
        let mut req =
            IppRequestResponse::new(IppVersion::v2_0(), op, None).map_err(|e| self.fail(e))?;
        let uri = IppValue::new_uri(self.uri.clone()).map_err(|e| self.fail(e))?;
        req.attributes_mut()
            .add(DelimiterTag::OperationAttributes, attr("printer-uri", uri));
        req.attributes_mut().add(
            DelimiterTag::OperationAttributes,
            attr(
                "requesting-user-name",
                IppValue::NameWithoutLanguage(ipp::value::IppName::new_truncated(user())),
            ),
        );
        Ok(req)
    }

    /// Sends `req` (and `document`) and returns the response, or the printer's error status
    /// and message as one line.
    fn call(&self, req: &IppRequestResponse, document: &[u8]) -> Result<IppRequestResponse> {
        self.call_status(req, document)?
            .map_err(|(status, msg)| self.status_error(status, msg))
    }

    /// Sends `req` and `document`: the response, or the printer's error status and message.
    fn call_status(&self, req: &IppRequestResponse, document: &[u8]) -> Result<Answer> {
        let mut body = req.to_bytes().to_vec();
        body.extend_from_slice(document);
        let resp = self.post(&body)?;
        let status = resp.header().operation_or_status as u16;
        if status >= 0x0100 {
            return Ok(Err((status, operation_text(&resp, "status-message"))));
        }
        Ok(Ok(resp))
    }

    fn status_error(&self, status: u16, msg: Option<String>) -> Error {
        let text = format!(
            "{} (0x{status:04x}){}",
            status_name(status),
            msg.map(|m| format!(": {m}")).unwrap_or_default()
        );
        // A server error (0x05xx: busy, unavailable, a temporary error) may pass; a
        // client error (the job's format or attributes refused) will not.
        if status >= 0x0500 {
            self.passing(text)
        } else {
            self.fail(text)
        }
    }

    /// Asks the printer what it takes (Get-Printer-Attributes).
    pub fn printer_info(&self) -> Result<PrinterInfo> {
        let mut req = self.request(Operation::GetPrinterAttributes)?;
        let names = [
            "document-format-supported",
            "pwg-raster-document-resolution-supported",
            "pwg-raster-document-type-supported",
            "urf-supported",
            "printer-resolution-default",
            "printer-resolution-supported",
            "printer-state",
            "printer-make-and-model",
            "media-default",
        ];
        let list = names
            .iter()
            .map(|n| IppValue::Keyword(ipp::value::IppKeyword::new_truncated(*n)))
            .collect();
        req.attributes_mut().add(
            DelimiterTag::OperationAttributes,
            attr("requested-attributes", IppValue::Array(list)),
        );
        let resp = self.call(&req, &[])?;
        let mut info = PrinterInfo::default();
        for g in resp.attributes().groups_of(DelimiterTag::PrinterAttributes) {
            for a in g.attributes() {
                let vals = values(a.value());
                match a.name().as_str() {
                    "document-format-supported" => {
                        info.formats = vals.iter().map(|v| v.to_string()).collect()
                    }
                    "pwg-raster-document-resolution-supported" => {
                        info.pwg_resolutions = vals.iter().filter_map(|v| dpi(v)).collect()
                    }
                    "pwg-raster-document-type-supported" => {
                        info.pwg_types = vals.iter().map(|v| v.to_string()).collect()
                    }
                    "urf-supported" => info.urf = vals.iter().map(|v| v.to_string()).collect(),
                    "printer-resolution-default" => info.default_resolution = dpi(a.value()),
                    "printer-make-and-model" => info.model = Some(a.value().to_string()),
                    "media-default" => info.media_default = Some(a.value().to_string()),
                    "printer-state" => {
                        if let IppValue::Enum(e) = a.value() {
                            info.state = Some(*e)
                        }
                    }
                    _ => {}
                }
            }
        }
        Ok(info)
    }

    /// [`Target::printer_info`], asked once for each printer in this process.
    pub fn printer_info_cached(&self) -> Result<PrinterInfo> {
        static CACHE: OnceLock<Mutex<HashMap<Target, PrinterInfo>>> = OnceLock::new();
        let cache = CACHE.get_or_init(Default::default);
        if let Some(i) = cache.lock().ok().and_then(|c| c.get(self).cloned()) {
            return Ok(i);
        }
        let info = self.printer_info()?;
        if let Ok(mut c) = cache.lock() {
            c.insert(self.clone(), info.clone());
        }
        Ok(info)
    }

    /// Sends `document` in `format` with Print-Job; returns the printer's job id.
    pub fn print_job(&self, document: &[u8], format: Format, job_name: &str) -> Result<i32> {
        let mut req = self.request(Operation::PrintJob)?;
        let op = DelimiterTag::OperationAttributes;
        req.attributes_mut().add(
            op,
            attr(
                "job-name",
                IppValue::NameWithoutLanguage(ipp::value::IppName::new_truncated(job_name)),
            ),
        );
        let mime = mime_type(format)
            .ok_or_else(|| self.fail(format!("{} is not a document format", format.name())))?;
        req.attributes_mut().add(
            op,
            attr(
                "document-format",
                IppValue::MimeMediaType(ipp::value::IppMimeMediaType::new_truncated(mime)),
            ),
        );
        // A printer busy with another job (as CUPS's ippeveprinter answers while it prints)
        // or briefly unavailable: try again, for up to BUSY_WAIT.
        let start = std::time::Instant::now();
        let mut pause = Duration::from_millis(250);
        let resp = loop {
            match self.call_status(&req, document)? {
                Ok(resp) => break resp,
                Err((status @ (0x0502 | 0x0505 | 0x0507), msg)) => {
                    if start.elapsed() > BUSY_WAIT {
                        return Err(self.status_error(status, msg));
                    }
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_secs(5));
                }
                Err((status, msg)) => return Err(self.status_error(status, msg)),
            }
        };
        job_attr(&resp, "job-id")
            .and_then(|v| v.as_integer().copied())
            .ok_or_else(|| self.fail("the printer answered Print-Job without a job-id"))
    }

    /// The state of job `id` (Get-Job-Attributes).
    pub fn job_status(&self, id: i32) -> Result<JobStatus> {
        let mut req = self.request(Operation::GetJobAttributes)?;
        req.attributes_mut().add(
            DelimiterTag::OperationAttributes,
            attr("job-id", IppValue::Integer(id)),
        );
        let resp = self.call(&req, &[])?;
        let state = job_attr(&resp, "job-state")
            .and_then(|v| v.as_enum().copied())
            .ok_or_else(|| self.fail(format!("job {id}: no job-state in the answer")))?;
        let reasons = job_attr(&resp, "job-state-reasons")
            .map(|v| values(v).iter().map(|r| r.to_string()).collect::<Vec<_>>())
            .unwrap_or_default();
        let message = job_attr(&resp, "job-state-message")
            .map(|v| v.to_string())
            .filter(|m| !m.is_empty());
        let pages =
            job_attr(&resp, "job-impressions-completed").and_then(|v| v.as_integer().copied());
        Ok(JobStatus {
            state,
            reasons,
            message,
            impressions: pages,
        })
    }

    /// Polls job `id` until it ends (completed, canceled or aborted) or `timeout` passes.
    /// A job that does not complete is an error naming its state and the printer's words.
    pub fn wait_for_job(&self, id: i32, timeout: Duration) -> Result<JobStatus> {
        let start = std::time::Instant::now();
        let mut pause = Duration::from_millis(100);
        loop {
            let st = self.job_status(id)?;
            if st.state >= 7 {
                if st.state == 9 {
                    return Ok(st);
                }
                return Err(self.fail(format!("job {id} {}", st.describe())));
            }
            if start.elapsed() > timeout {
                return Err(self.fail(format!(
                    "job {id} still {} after {} s",
                    st.describe(),
                    timeout.as_secs()
                )));
            }
            std::thread::sleep(pause);
            pause = (pause * 2).min(Duration::from_secs(2));
        }
    }
}

/// What a printer takes, from its Get-Printer-Attributes answer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PrinterInfo {
    /// `document-format-supported`.
    pub formats: Vec<String>,
    /// `pwg-raster-document-resolution-supported`, square resolutions in dpi.
    pub pwg_resolutions: Vec<u32>,
    /// `pwg-raster-document-type-supported` (`black_1`, `sgray_8`, `srgb_8`…).
    pub pwg_types: Vec<String>,
    /// `urf-supported` (`RS300-600`, `W8`, `SRGB24`…).
    pub urf: Vec<String>,
    /// `printer-resolution-default` in dpi.
    pub default_resolution: Option<u32>,
    /// `printer-make-and-model`.
    pub model: Option<String>,
    /// `printer-state` (3 idle, 4 processing, 5 stopped).
    pub state: Option<i32>,
    /// `media-default` (a PWG media name such as `na_letter_8.5x11in`).
    pub media_default: Option<String>,
}

impl PrinterInfo {
    /// True when the printer lists `format`'s media type.
    pub fn takes(&self, format: Format) -> bool {
        mime_type(format).is_some_and(|m| self.formats.iter().any(|f| f == m))
    }

    /// The format to send: `wanted` when the printer takes it, else PWG raster, Apple
    /// raster, PDF, in that order. `colour` asks for a format that prints colour (a URF
    /// printer must list `SRGB24`).
    pub fn choose_format(&self, wanted: Option<Format>, colour: bool) -> Option<Format> {
        if let Some(w) = wanted.filter(|&w| self.takes(w)) {
            return Some(w);
        }
        [Format::Pwg, Format::Urf, Format::Pdf]
            .into_iter()
            .find(|&f| {
                self.takes(f)
                    && match f {
                        Format::Pwg if colour => self.pwg_types.iter().any(|t| t == "srgb_8"),
                        Format::Pwg => {
                            self.pwg_types.is_empty()
                                || self.pwg_types.iter().any(|t| t == "black_1")
                        }
                        Format::Urf if colour => self.urf.iter().any(|t| t == "SRGB24"),
                        _ => true,
                    }
            })
    }

    /// The resolutions the printer lists for `format`: PWG raster's, URF's `RS` list,
    /// else the default resolution.
    pub fn resolutions(&self, format: Format) -> Vec<u32> {
        let v: Vec<u32> = match format {
            Format::Pwg => self.pwg_resolutions.clone(),
            Format::Urf => self
                .urf
                .iter()
                .find_map(|k| k.strip_prefix("RS"))
                .map(|l| l.split('-').filter_map(|d| d.parse().ok()).collect())
                .unwrap_or_default(),
            _ => Vec::new(),
        };
        if v.is_empty() {
            self.default_resolution.into_iter().collect()
        } else {
            v
        }
    }

    /// The resolution to print `format` at: `wanted` if listed (an error naming the list
    /// if not and `strict`), else the printer's default when listed, else the first listed.
    pub fn choose_resolution(
        &self,
        format: Format,
        wanted: Option<u32>,
        strict: bool,
    ) -> std::result::Result<Option<u32>, String> {
        let list = self.resolutions(format);
        if let Some(w) = wanted {
            if list.is_empty() || list.contains(&w) {
                return Ok(Some(w));
            }
            if strict {
                let l: Vec<String> = list.iter().map(u32::to_string).collect();
                return Err(format!(
                    "the printer takes {} at {} dpi, not {w}; pass --dpi {}",
                    format.name(),
                    l.join(", "),
                    l[0]
                ));
            }
        }
        Ok(self
            .default_resolution
            .filter(|d| list.contains(d))
            .or_else(|| list.first().copied()))
    }
}

/// The size a PWG self-describing media name ends with (`na_letter_8.5x11in`,
/// `iso_a4_210x297mm`), as a page size.
pub fn media_size(name: &str) -> Option<crate::io::lang::PageSize> {
    name.rsplit('_').next()?.parse().ok()
}

/// What Get-Job-Attributes said of a job.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobStatus {
    /// `job-state`: 3 pending, 4 held, 5 processing, 6 stopped, 7 canceled, 8 aborted,
    /// 9 completed.
    pub state: i32,
    /// `job-state-reasons`.
    pub reasons: Vec<String>,
    /// `job-state-message`, when the printer gave one.
    pub message: Option<String>,
    /// `job-impressions-completed`, when the printer gave it.
    pub impressions: Option<i32>,
}

impl JobStatus {
    /// The state's keyword (RFC 8011 §5.3.7).
    pub fn state_name(&self) -> &'static str {
        match self.state {
            3 => "pending",
            4 => "pending-held",
            5 => "processing",
            6 => "processing-stopped",
            7 => "canceled",
            8 => "aborted",
            9 => "completed",
            _ => "in an unknown state",
        }
    }

    /// The state, the reasons and the message as one phrase.
    pub fn describe(&self) -> String {
        let mut s = self.state_name().to_string();
        let reasons: Vec<&str> = self
            .reasons
            .iter()
            .map(String::as_str)
            .filter(|r| *r != "none")
            .collect();
        if !reasons.is_empty() {
            s += &format!(" ({})", reasons.join(", "));
        }
        if let Some(m) = &self.message {
            s += &format!(": {m}");
        }
        s
    }
}

/// The media type a format is sent as, for the formats printers take.
pub fn mime_type(format: Format) -> Option<&'static str> {
    Some(match format {
        Format::Pwg => "image/pwg-raster",
        Format::Urf => "image/urf",
        Format::CupsRaster => "application/vnd.cups-raster",
        Format::Pdf => "application/pdf",
        Format::Ps => "application/postscript",
        Format::Pcl => "application/vnd.hp-pcl",
        Format::Png => "image/png",
        Format::Tiff => "image/tiff",
        Format::Pbm | Format::Pgm | Format::Ppm => "image/x-portable-anymap",
        _ => return None,
    })
}

/// RFC 8011 §B status names for the codes printers answer with.
fn status_name(code: u16) -> &'static str {
    match code {
        0x0400 => "client-error-bad-request",
        0x0401 => "client-error-forbidden",
        0x0402 => "client-error-not-authenticated",
        0x0403 => "client-error-not-authorized",
        0x0404 => "client-error-not-possible",
        0x0405 => "client-error-timeout",
        0x0406 => "client-error-not-found",
        0x0407 => "client-error-gone",
        0x0408 => "client-error-request-entity-too-large",
        0x040a => "client-error-document-format-not-supported",
        0x040b => "client-error-attributes-or-values-not-supported",
        0x040e => "client-error-document-format-error",
        0x040f => "client-error-document-access-error",
        0x0500 => "server-error-internal-error",
        0x0501 => "server-error-operation-not-supported",
        0x0502 => "server-error-service-unavailable",
        0x0503 => "server-error-version-not-supported",
        0x0504 => "server-error-device-error",
        0x0505 => "server-error-temporary-error",
        0x0506 => "server-error-not-accepting-jobs",
        0x0507 => "server-error-busy",
        0x0508 => "server-error-job-canceled",
        _ if code >= 0x0500 => "server-error",
        _ => "client-error",
    }
}

/// A value's members (one value is a list of one).
fn values(v: &IppValue) -> Vec<&IppValue> {
    match v {
        IppValue::Array(a) => a.iter().collect(),
        one => vec![one],
    }
}

/// A square resolution in dots per inch (units 3), or per cm converted.
fn dpi(v: &IppValue) -> Option<u32> {
    match *v {
        IppValue::Resolution {
            cross_feed,
            feed,
            units,
        } if cross_feed == feed && cross_feed > 0 => Some(if units == 4 {
            (cross_feed as f64 * 2.54).round() as u32
        } else {
            cross_feed as u32
        }),
        _ => None,
    }
}

fn operation_text(resp: &IppRequestResponse, name: &str) -> Option<String> {
    resp.attributes()
        .groups_of(DelimiterTag::OperationAttributes)
        .find_map(|g| g.get(name))
        .map(|a| a.value().to_string())
}

fn job_attr<'a>(resp: &'a IppRequestResponse, name: &str) -> Option<&'a IppValue> {
    resp.attributes()
        .groups_of(DelimiterTag::JobAttributes)
        .find_map(|g| g.get(name))
        .map(|a| a.value())
}

fn attr(name: &str, v: IppValue) -> IppAttribute {
    IppAttribute::new(ipp::value::IppName::new_truncated(name), v)
}

/// The user name sent as `requesting-user-name`.
fn user() -> String {
    std::env::var("USER")
        .ok()
        .filter(|u| !u.is_empty())
        .unwrap_or_else(|| "halftone".into())
}

/// An HTTP answer's status code, reason and headers.
type Head = (u16, String, Vec<(String, String)>);

/// A printer's IPP answer, or its error status and `status-message`.
type Answer = std::result::Result<IppRequestResponse, (u16, Option<String>)>;

/// Reads an HTTP status line and headers.
fn read_head(r: &mut impl BufRead) -> std::result::Result<Head, String> {
    let mut line = String::new();
    let mut read_line = |line: &mut String| -> std::result::Result<(), String> {
        line.clear();
        let n = r
            .take(8192)
            .read_line(line)
            .map_err(|e| format!("reading the answer: {e}"))?;
        if n == 0 {
            return Err("the printer closed the connection without an answer".into());
        }
        Ok(())
    };
    read_line(&mut line)?;
    let mut parts = line.trim_end().splitn(3, ' ');
    let version = parts.next().unwrap_or("");
    if !version.starts_with("HTTP/1.") {
        return Err(format!("not an HTTP answer: {:?}", line.trim_end()));
    }
    let code: u16 = parts
        .next()
        .and_then(|c| c.parse().ok())
        .ok_or_else(|| format!("a bad HTTP status line: {:?}", line.trim_end()))?;
    let reason = parts.next().unwrap_or("").to_string();
    let mut headers = Vec::new();
    loop {
        read_line(&mut line)?;
        let l = line.trim_end();
        if l.is_empty() {
            break;
        }
        if headers.len() > 200 {
            return Err("too many HTTP headers".into());
        }
        if let Some((k, v)) = l.split_once(':') {
            headers.push((k.trim().to_string(), v.trim().to_string()));
        }
    }
    Ok((code, reason, headers))
}

/// Reads a chunked HTTP body into `out`.
fn read_chunked(r: &mut impl BufRead, out: &mut Vec<u8>) -> std::result::Result<(), String> {
    let mut line = String::new();
    loop {
        line.clear();
        r.take(1024)
            .read_line(&mut line)
            .map_err(|e| format!("reading the answer: {e}"))?;
        let size = line.trim().split(';').next().unwrap_or("");
        let n = u64::from_str_radix(size, 16)
            .map_err(|_| format!("a bad chunk size {:?}", line.trim()))?;
        if n == 0 {
            return Ok(());
        }
        if out.len() as u64 + n > MAX_RESPONSE {
            return Err("an answer over 16 MiB".into());
        }
        let before = out.len();
        r.take(n)
            .read_to_end(out)
            .map_err(|e| format!("reading the answer: {e}"))?;
        if (out.len() - before) as u64 != n {
            return Err("the answer ended inside a chunk".into());
        }
        line.clear();
        r.take(2).read_line(&mut line).map_err(|e| e.to_string())?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_parse_and_ipps_is_refused() {
        let t = Target::parse("ipp://printer.local/ipp/print").unwrap();
        assert_eq!(
            (t.host.as_str(), t.port, t.path.as_str()),
            ("printer.local", 631, "/ipp/print")
        );
        let t = Target::parse("ipp://127.0.0.1:8631/ipp/print/labels").unwrap();
        assert_eq!((t.port, t.path.as_str()), (8631, "/ipp/print/labels"));
        let t = Target::parse("ipp://[::1]:9/x").unwrap();
        assert_eq!((t.host.as_str(), t.port), ("::1", 9));
        let e = Target::parse("ipps://p/ipp/print").unwrap_err();
        assert!(e.contains("TLS"), "{e}");
        for bad in ["http://p/", "ipp://", "ipp://h:x/p", "ipp://[::1/p"] {
            assert!(Target::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn formats_and_resolutions_are_chosen_from_what_the_printer_lists() {
        let info = PrinterInfo {
            formats: vec!["image/pwg-raster".into(), "image/urf".into()],
            pwg_resolutions: vec![300, 600],
            pwg_types: vec!["black_1".into(), "sgray_8".into()],
            urf: vec!["RS600".into(), "W8".into()],
            default_resolution: Some(600),
            ..Default::default()
        };
        assert_eq!(info.choose_format(None, false), Some(Format::Pwg));
        assert_eq!(
            info.choose_format(Some(Format::Urf), false),
            Some(Format::Urf)
        );
        assert_eq!(
            info.choose_format(Some(Format::Pdf), false),
            Some(Format::Pwg)
        );
        // Colour: neither lists a colour type.
        assert_eq!(info.choose_format(None, true), None);
        assert_eq!(
            info.choose_resolution(Format::Pwg, None, true),
            Ok(Some(600))
        );
        assert_eq!(
            info.choose_resolution(Format::Pwg, Some(300), true),
            Ok(Some(300))
        );
        assert_eq!(
            info.choose_resolution(Format::Urf, Some(300), false),
            Ok(Some(600))
        );
        let e = info
            .choose_resolution(Format::Urf, Some(300), true)
            .unwrap_err();
        assert!(e.contains("600") && e.contains("300"), "{e}");
    }

    /// A one-shot HTTP server answering with `answer`; returns the request it got.
    fn serve_once(answer: Vec<u8>) -> (u16, std::thread::JoinHandle<Vec<u8>>) {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = l.local_addr().unwrap().port();
        let t = std::thread::spawn(move || {
            let (mut c, _) = l.accept().unwrap();
            c.set_read_timeout(Some(Duration::from_millis(300)))
                .unwrap();
            let mut got = Vec::new();
            let mut buf = [0u8; 4096];
            while let Ok(n) = c.read(&mut buf) {
                if n == 0 {
                    break;
                }
                got.extend_from_slice(&buf[..n]);
            }
            c.write_all(&answer).unwrap();
            got
        });
        (port, t)
    }

    #[test]
    fn errors_name_the_uri_and_the_printers_status() {
        let mut resp = IppRequestResponse::new_response(
            IppVersion::v2_0(),
            ipp::model::StatusCode::ClientErrorDocumentFormatNotSupported,
            1,
        )
        .unwrap();
        resp.attributes_mut().add(
            DelimiterTag::OperationAttributes,
            attr(
                "status-message",
                IppValue::new_text_without_language("no such format").unwrap(),
            ),
        );
        let ipp = resp.to_bytes();
        // Chunked, to read that form too.
        let mut answer = format!(
            "HTTP/1.1 200 OK\r\nContent-Type: application/ipp\r\nTransfer-Encoding: chunked\r\n\r\n{:x}\r\n",
            ipp.len()
        )
        .into_bytes();
        answer.extend_from_slice(&ipp);
        answer.extend_from_slice(b"\r\n0\r\n\r\n");
        let (port, t) = serve_once(answer);
        let target = Target::parse(&format!("ipp://127.0.0.1:{port}/ipp/print")).unwrap();
        let e = target
            .print_job(b"RaS2", Format::Pwg, "t")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            format!(
                "ipp://127.0.0.1:{port}/ipp/print: client-error-document-format-not-supported \
                 (0x040a): no such format"
            )
        );
        let got = t.join().unwrap();
        let text = String::from_utf8_lossy(&got);
        assert!(text.starts_with("POST /ipp/print HTTP/1.1\r\n"), "{text}");
        assert!(text.contains("image/pwg-raster") && got.ends_with(b"RaS2"));
        // HTTP errors and closed connections: one line each.
        let (port, _t) =
            serve_once(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n".to_vec());
        let target = Target::parse(&format!("ipp://127.0.0.1:{port}/x")).unwrap();
        let e = target.printer_info().unwrap_err().to_string();
        assert!(e.ends_with("HTTP 404 Not Found"), "{e}");
        let (port, _t) = serve_once(Vec::new());
        let target = Target::parse(&format!("ipp://127.0.0.1:{port}/x")).unwrap();
        let e = target.printer_info().unwrap_err().to_string();
        assert!(
            e.contains("closed the connection") && !e.contains('\n'),
            "{e}"
        );
    }
}
