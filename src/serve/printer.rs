//! The IPP printer: requests in, responses out, jobs kept and processed. No sockets and no
//! threads here: the binary's HTTP server hands each request's body to [`Printer::handle`]
//! and runs [`Printer::wait_for_job`] / [`Printer::process`] on a worker thread.

use std::collections::VecDeque;
use std::io::{Cursor, Read};
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use ipp::attribute::{IppAttribute, IppAttributes};
use ipp::model::{DelimiterTag, IppVersion, StatusCode};
use ipp::parser::IppParser;
use ipp::reader::IppReader;
use ipp::value::{IppName, IppValue};
use ipp::IppHeader;

use super::attributes::{self as attrs, kw, name, text, uri, DOCUMENT_FORMATS};
use super::config::{Backend, Config, Queue};
use super::document;
use super::spool::{self, Spool};
use crate::api::Converter;
use crate::options::value::Value;

/// Limits that keep one client from exhausting the server.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// The largest request body (IPP attributes and document) accepted, in bytes.
    pub max_request: u64,
    /// Jobs kept for Get-Jobs; the oldest finished ones are dropped first, and a new job is
    /// refused with `server-error-busy` when this many are still waiting.
    pub max_jobs: usize,
    /// Pages halftoned for one job: a document with more aborts the job with a message
    /// saying so (the pages are held until the job is sent, so this bounds its memory).
    pub max_pages: usize,
    /// Seconds one job may take to halftone, checked before each page: past it the job is
    /// aborted with a message saying so.
    pub max_job_seconds: u64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_request: 64 << 20,
            max_jobs: 100,
            max_pages: 500,
            max_job_seconds: 600,
        }
    }
}

/// A job's state (RFC 8011 section 5.3.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobState {
    /// Waiting for the worker.
    Pending = 3,
    /// Created, waiting for its document (Create-Job before Send-Document).
    PendingHeld = 4,
    /// Being halftoned or sent.
    Processing = 5,
    /// Cancelled by its user.
    Canceled = 7,
    /// Failed: bad document, options or backend (see its message).
    Aborted = 8,
    /// Sent to the backend.
    Completed = 9,
}

impl JobState {
    /// True once the job can change no more.
    pub fn is_finished(self) -> bool {
        matches!(
            self,
            JobState::Canceled | JobState::Aborted | JobState::Completed
        )
    }
}

/// One job as the server keeps it.
#[derive(Debug)]
pub struct Job {
    /// Its number (job-id), from 1.
    pub id: i32,
    /// Index of its queue in the configuration.
    pub queue: usize,
    /// job-name.
    pub name: String,
    /// job-originating-user-name.
    pub user: String,
    /// Its state.
    pub state: JobState,
    /// job-state-reasons.
    pub reasons: Vec<&'static str>,
    /// job-state-message: what happened, in words.
    pub message: String,
    /// Seconds of printer-up-time at creation, start and end of processing.
    pub times: [Option<u64>; 3],
    /// The document, until it is processed.
    pub document: Option<Vec<u8>>,
    /// Its size in bytes.
    pub octets: u64,
    /// The options it asked for, by their one names, mapped from its attributes.
    pub settings: Vec<(String, Value<'static>)>,
    /// Copies asked for.
    pub copies: u32,
    /// The method used, once known.
    pub method: Option<String>,
    /// Pages halftoned, once known.
    pub pages: usize,
    /// page-ranges and overrides.
    pub plan: PagePlan,
    /// The job-creating request up to the end of its attributes, as it came (spooled with
    /// the document).
    pub request: Vec<u8>,
    /// When it was created, in seconds since the Unix epoch.
    pub created: u64,
    /// Deliveries tried and failed, and when the next may be tried (the backend was down).
    pub retry: Option<(u32, Instant)>,
    /// The halftoned files kept while the backend is down, so a retry sends the same bytes.
    pub output: Option<Vec<(Vec<u8>, String)>>,
}

struct State {
    jobs: VecDeque<Job>,
    next_id: i32,
    /// Job numbers below this one are reserved in the spool's `next-id`.
    reserved: i32,
    identified: u64,
    /// Why each queue's backend cannot be reached, while it cannot.
    down: Vec<Option<String>>,
}

/// How long a job waits before delivery attempt `n + 1` when attempt `n` (from 1) found the
/// backend down: 1, 2, 4, 8, 16 seconds, then every 30 seconds until it is delivered or
/// cancelled.
pub fn retry_delay(n: u32) -> Duration {
    Duration::from_secs((1u64 << n.saturating_sub(1).min(5)).min(30))
}

/// One job for the status page.
#[derive(Clone, Debug)]
pub struct JobSummary {
    /// job-id.
    pub id: i32,
    /// Its queue's name.
    pub queue: String,
    /// job-name.
    pub name: String,
    /// job-originating-user-name.
    pub user: String,
    /// Its state.
    pub state: JobState,
    /// job-state-message.
    pub message: String,
    /// Pages halftoned (0 until known).
    pub pages: usize,
    /// The method, once known.
    pub method: Option<String>,
    /// Created, in seconds since the Unix epoch.
    pub created: u64,
}

/// An IPP Everywhere printer with one or more queues.
pub struct Printer {
    config: Config,
    host: String,
    limits: Limits,
    started: Instant,
    started_unix: u64,
    state: Mutex<State>,
    work: Condvar,
    spool: Option<Spool>,
}

/// A response to one HTTP request: its body and whether the connection must close (the
/// request was refused before its body was read to the end).
#[derive(Debug)]
pub struct Response {
    /// The IPP response (`application/ipp`).
    pub body: Vec<u8>,
    /// Close the connection after sending it.
    pub close: bool,
}

/// An IPP error: status and message.
struct Refusal(StatusCode, String);

fn refuse<T>(status: StatusCode, msg: impl Into<String>) -> Result<T, Refusal> {
    Err(Refusal(status, msg.into()))
}

impl Printer {
    /// A printer for `config`'s queues, reachable at `host` (`HOST:PORT`, used in the
    /// URIs it reports).
    pub fn new(config: Config, host: &str, limits: Limits) -> Printer {
        Printer {
            host: host.to_string(),
            limits,
            started: Instant::now(),
            started_unix: SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
            state: Mutex::new(State {
                jobs: VecDeque::new(),
                next_id: 1,
                reserved: i32::MAX,
                identified: 0,
                down: vec![None; config.queues.len()],
            }),
            config,
            work: Condvar::new(),
            spool: None,
        }
    }

    /// Keeps every acknowledged job in `spool` from now on, and takes back the jobs it
    /// holds (a server stopped or killed with jobs queued): they are queued again, in
    /// order, under their numbers, and numbering goes on after them. Returns one line for
    /// each job taken back or set aside, for the log.
    pub fn recover(&mut self, spool: Spool) -> Result<Vec<String>, crate::error::Error> {
        // A file is a request and its document: the request limit plus a header.
        let contents = spool.load(self.limits.max_request.saturating_add(64 << 10))?;
        let mut log = contents.problems;
        let next = contents.next_id;
        spool.reserve_ids(next.saturating_add(spool::ID_BLOCK))?;
        let mut gone = Vec::new();
        {
            let st = self.state.get_mut().unwrap_or_else(|p| p.into_inner());
            st.next_id = next;
            st.reserved = next.saturating_add(spool::ID_BLOCK);
        }
        for e in contents.jobs {
            let job = self.job_from_spool(&e);
            let st = self.state.get_mut().unwrap_or_else(|p| p.into_inner());
            match job {
                Ok(j) => {
                    log.push(format!(
                        "job {}: taken back from the spool ({} bytes for {})",
                        e.id, j.octets, self.config.queues[j.queue].name
                    ));
                    st.jobs.push_back(j);
                }
                Err(why) => {
                    log.push(format!(
                        "job {}: spooled but not printable now: {why}",
                        e.id
                    ));
                    gone.push(e.id);
                }
            }
        }
        for id in gone {
            let _ = spool.remove(id);
        }
        self.spool = Some(spool);
        Ok(log)
    }

    /// A job from its spool file: its request mapped again through its queue's options.
    fn job_from_spool(&self, e: &spool::Entry) -> Result<Job, String> {
        let queue = self
            .config
            .queues
            .iter()
            .position(|q| q.name == e.queue)
            .ok_or_else(|| format!("no queue {} any more", e.queue))?;
        super::wire::check_wire(&e.request)
            .map_err(|err| format!("its request does not parse: {err}"))?;
        let parsed = IppParser::new(IppReader::new(Cursor::new(e.request.clone())))
            .parse_parts()
            .map_err(|err| format!("its request does not parse: {err}"))?;
        let r = Request {
            header: parsed.0,
            attributes: parsed.1,
            document: Vec::new(),
            head: Vec::new(),
            host: self.host.clone(),
        };
        let t = self
            .job_template(&r, &self.config.queues[queue], &mut Out::default())
            .map_err(|Refusal(_, msg)| msg)?;
        let mut j = new_job(e.id, queue, &r, t, Some(e.document.clone()), 1);
        j.request = e.request.clone();
        j.created = e.created;
        j.message = "queued (taken back from the spool after a restart)".into();
        Ok(j)
    }

    /// The queues.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// `HOST:PORT` as the URIs give it.
    pub fn host(&self) -> &str {
        &self.host
    }

    /// The limits in force.
    pub fn limits(&self) -> Limits {
        self.limits
    }

    /// A queue's URI: `ipp://HOST:PORT/ipp/print/NAME`.
    pub fn queue_uri(&self, q: &Queue) -> String {
        queue_uri_at(&self.host, q)
    }

    /// Seconds since the printer started, from 1 (printer-up-time).
    pub fn up_time(&self) -> u64 {
        self.started.elapsed().as_secs() + 1
    }

    /// How many Identify-Printer requests arrived (the binary shows them).
    pub fn identified(&self) -> u64 {
        self.lock().identified
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock leaves consistent data (every change is one
        // assignment), so a poisoned lock is taken over.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Reads one request body from `body` (at most the request limit) and answers it.
    pub fn handle(&self, body: &mut dyn Read) -> Response {
        self.handle_from(None, body)
    }

    /// As [`Printer::handle`], for a request whose HTTP `Host` header was `host`: the URIs
    /// in the response name the host the client used (see [`request_host`]).
    pub fn handle_from(&self, host: Option<&str>, body: &mut dyn Read) -> Response {
        let mut buf = Vec::new();
        let read = body
            .take(self.limits.max_request.saturating_add(1))
            .read_to_end(&mut buf);
        let too_long = buf.len() as u64 > self.limits.max_request;
        match read {
            // A body cut short (the client went away, or sent less than it announced) is
            // never taken as a request: it could be a job with half its document.
            Err(e) => {
                let id = buf
                    .get(4..8)
                    .map_or(1, |b| i32::from_be_bytes([b[0], b[1], b[2], b[3]]).max(1));
                Response {
                    body: error_response(
                        id,
                        StatusCode::ClientErrorBadRequest,
                        &format!("the request could not be read to its end: {e}"),
                    ),
                    close: true,
                }
            }
            _ => Response {
                body: self.answer(host, buf, too_long),
                close: too_long || read.is_err(),
            },
        }
    }

    /// Answers one request given as bytes; `too_long`: the body was cut at the limit.
    pub fn handle_bytes(&self, bytes: Vec<u8>, too_long: bool) -> Vec<u8> {
        self.answer(None, bytes, too_long)
    }

    fn answer(&self, host: Option<&str>, bytes: Vec<u8>, too_long: bool) -> Vec<u8> {
        if let Err(e) = super::wire::check_wire(&bytes) {
            return error_response(
                1,
                StatusCode::ClientErrorBadRequest,
                &format!("malformed IPP request: {e}"),
            );
        }
        let parsed = IppParser::new(IppReader::new(Cursor::new(bytes))).parse_parts();
        let (header, attributes, reader) = match parsed {
            Ok(p) => p,
            Err(e) => {
                return error_response(
                    1,
                    StatusCode::ClientErrorBadRequest,
                    &format!("malformed IPP request: {e}"),
                )
            }
        };
        let cursor = reader.into_inner();
        let offset = (cursor.position() as usize).min(cursor.get_ref().len());
        let mut bytes = cursor.into_inner();
        let document = bytes.split_off(offset);
        let request = Request {
            header,
            attributes,
            document,
            head: bytes,
            host: request_host(host, &self.host),
        };
        let id = header.request_id;
        let version = match header.version.0 >> 8 {
            1 | 2 => header.version,
            _ => IppVersion::v1_1(),
        };
        let mut out = Out::default();
        let status = match self.dispatch(&request, too_long, &mut out) {
            Ok(s) => s,
            Err(Refusal(status, msg)) => {
                out.groups.clear();
                out.message = Some(msg);
                status
            }
        };
        out.encode(version, status, id)
    }

    fn dispatch(&self, r: &Request, too_long: bool, out: &mut Out) -> Result<StatusCode, Refusal> {
        let major = r.header.version.0 >> 8;
        if !(1..=2).contains(&major) {
            return refuse(
                StatusCode::ServerErrorVersionNotSupported,
                "IPP versions 1.1 and 2.0 are supported",
            );
        }
        if r.header.request_id <= 0 {
            return refuse(
                StatusCode::ClientErrorBadRequest,
                "request-id must be positive",
            );
        }
        r.check_operation_group()?;
        if too_long {
            return refuse(
                StatusCode::ClientErrorRequestEntityTooLong,
                format!(
                    "the request is larger than the server's limit of {} bytes",
                    self.limits.max_request
                ),
            );
        }
        let op = r.header.operation_or_status as i32;
        let queue = self.target_queue(r)?;
        let q = &self.config.queues[queue];
        match op {
            0x000b => self.get_printer_attributes(r, queue, out),
            0x0004 => {
                r.document_format()?;
                let job = self.job_template(r, q, out)?;
                Ok(job.status)
            }
            0x0002 => {
                let format = r.document_format()?;
                let job = self.job_template(r, q, out)?;
                let doc = r.document.clone();
                let doc = self.check_document(doc, &format, queue)?;
                let status = job.status;
                let id = self.add_job(queue, r, job, Some(doc))?;
                self.job_response(id, &r.host, out);
                Ok(status)
            }
            0x0005 => {
                let job = self.job_template(r, q, out)?;
                let status = job.status;
                let id = self.add_job(queue, r, job, None)?;
                self.job_response(id, &r.host, out);
                Ok(status)
            }
            0x0006 => self.send_document(r, queue, out),
            0x0008 => self.cancel_job(r, queue),
            0x0039 => self.cancel_my_jobs(r, queue),
            0x003b => self.close_job(r, queue, out),
            0x0009 => self.get_job_attributes(r, queue, out),
            0x000a => self.get_jobs(r, queue, out),
            0x003c => {
                self.lock().identified += 1;
                Ok(StatusCode::SuccessfulOk)
            }
            _ => refuse(
                StatusCode::ServerErrorOperationNotSupported,
                format!("operation 0x{op:04x} is not supported"),
            ),
        }
    }

    /// The queue a request is for: its printer-uri's (or job-uri's) path,
    /// `/ipp/print/NAME`; with one queue `/ipp/print` is it too.
    fn target_queue(&self, r: &Request) -> Result<usize, Refusal> {
        let target = r
            .op_text("printer-uri")
            .or_else(|| r.op_text("job-uri"))
            .ok_or(Refusal(
                StatusCode::ClientErrorBadRequest,
                "no printer-uri operation attribute".into(),
            ))?;
        let path = uri_path(&target);
        let path = path.trim_end_matches('/');
        let rest = path.strip_prefix("/ipp/print").unwrap_or("\u{0}");
        let name = rest.trim_start_matches('/');
        // A job-uri is the queue's URI with `/JOB-ID` after it.
        let name = name.split('/').next().unwrap_or("");
        if name.is_empty() && rest.is_empty() && self.config.queues.len() == 1 {
            return Ok(0);
        }
        self.config
            .queues
            .iter()
            .position(|q| q.name == name)
            .ok_or(Refusal(
                StatusCode::ClientErrorNotFound,
                format!("no queue at {target}"),
            ))
    }

    fn get_printer_attributes(
        &self,
        r: &Request,
        queue: usize,
        out: &mut Out,
    ) -> Result<StatusCode, Refusal> {
        if let Some(f) = r.op_text("document-format") {
            if !DOCUMENT_FORMATS.contains(&f.as_str()) {
                return refuse(
                    StatusCode::ClientErrorDocumentFormatNotSupported,
                    format!("document-format {f} is not supported"),
                );
            }
        }
        let requested = r.requested_attributes();
        let q = &self.config.queues[queue];
        let (queued, processing, down) = {
            let st = self.lock();
            let mine = st.jobs.iter().filter(|j| j.queue == queue);
            let queued = mine.clone().filter(|j| !j.state.is_finished()).count();
            let processing = mine.clone().any(|j| j.state == JobState::Processing);
            (queued, processing, st.down[queue].clone())
        };
        let status = attrs::PrinterStatus {
            up_time: self.up_time(),
            started_unix: self.started_unix,
            queued,
            processing,
        };
        let mut all = attrs::printer_attributes(q, &queue_uri_at(&r.host, q), &r.host, &status);
        if let Some(why) = down {
            // The backend cannot be reached: the jobs wait, and the printer says why.
            for a in all.iter_mut() {
                match a.name().as_str() {
                    "printer-state-reasons" => {
                        *a = attr(
                            "printer-state-reasons",
                            list_of(vec![kw("offline-report"), kw("connecting-to-device")]),
                        )
                    }
                    "printer-state-message" => *a = attr("printer-state-message", text(&why)),
                    _ => {}
                }
            }
        }
        let wanted: Vec<IppAttribute> = all
            .into_iter()
            .filter(|a| match &requested {
                None => a.name().as_str() != "media-col-database",
                Some(list) => wants(
                    list,
                    a.name().as_str(),
                    attrs::printer_group(a.name().as_str()),
                ),
            })
            .collect();
        out.groups.push((DelimiterTag::PrinterAttributes, wanted));
        Ok(StatusCode::SuccessfulOk)
    }

    /// Checks a job's template attributes and maps them to option names and values.
    fn job_template(&self, r: &Request, q: &Queue, out: &mut Out) -> Result<JobTemplate, Refusal> {
        let fidelity = r.op_bool("ipp-attribute-fidelity").unwrap_or(false);
        let mut unsupported = Vec::new();
        let mut settings = Vec::new();
        let mut copies = 1;
        let mut pages = PagePlan::default();
        for a in r.group(DelimiterTag::JobAttributes) {
            let n = a.name().as_str();
            let bad = |why: String| {
                refuse(
                    StatusCode::ClientErrorAttributesOrValuesNotSupported,
                    format!("{n}: {why}"),
                )
            };
            if n == "page-ranges" {
                match page_ranges(a.value()) {
                    Ok(r) => pages.ranges = r,
                    Err(why) => return bad(why),
                }
                continue;
            }
            if n == "overrides" {
                match overrides(q, a.value(), &settings) {
                    Ok(o) => pages.overrides = o,
                    Err(why) => return bad(why),
                }
                continue;
            }
            match attrs::map_job_attribute(q, n, a.value()) {
                Ok(attrs::Mapped::Setting(list)) => settings.extend(list),
                Ok(attrs::Mapped::Copies(c)) => copies = c,
                Ok(attrs::Mapped::Ignored) => {}
                Err(why) => {
                    if fidelity || n.starts_with("halftone-") {
                        // A vendor attribute is asked for by name: never silently ignored.
                        return refuse(
                            StatusCode::ClientErrorAttributesOrValuesNotSupported,
                            format!("{n}: {why}"),
                        );
                    }
                    unsupported.push(a.clone());
                }
            }
        }
        // The options must make a printable job on this queue.
        if let Err(e) = q.job_options(&settings) {
            return refuse(
                StatusCode::ClientErrorAttributesOrValuesNotSupported,
                format!("{e}"),
            );
        }
        let status = if unsupported.is_empty() {
            StatusCode::SuccessfulOk
        } else {
            StatusCode::SuccessfulOkIgnoredOrSubstitutedAttributes
        };
        if !unsupported.is_empty() {
            let list = unsupported
                .into_iter()
                .map(|a| {
                    IppAttribute::new(
                        a.name().clone(),
                        IppValue::Other {
                            tag: 0x10,
                            data: Default::default(),
                        },
                    )
                })
                .collect();
            out.groups.push((DelimiterTag::UnsupportedAttributes, list));
        }
        // Each override on top of the job's options must make a printable job too.
        for o in &pages.overrides {
            let mut all = settings.clone();
            all.extend(o.settings.iter().cloned());
            if let Err(e) = q.job_options(&all) {
                return refuse(
                    StatusCode::ClientErrorAttributesOrValuesNotSupported,
                    format!("overrides: {e}"),
                );
            }
        }
        Ok(JobTemplate {
            settings,
            copies,
            pages,
            status,
        })
    }

    fn check_document(&self, doc: Vec<u8>, format: &str, queue: usize) -> Result<Vec<u8>, Refusal> {
        if doc.is_empty() {
            return refuse(StatusCode::ClientErrorBadRequest, "no document data");
        }
        let sniffed = document::sniff(&doc);
        if let Some(kind) = sniffed
            .filter(|s| s.starts_with("image/") && *s != "image/pwg-raster" && *s != "image/urf")
        {
            // An image whose header claims more pixels than the queue takes is refused
            // now, not accepted and aborted later (PWG and Apple raster are checked page by
            // page as they are decoded).
            let limit = self.config.queues[queue].options.max_pixels;
            let dims = image::ImageReader::new(Cursor::new(&doc[..]))
                .with_guessed_format()
                .ok()
                .and_then(|r| r.into_dimensions().ok());
            if let Some((w, h)) = dims {
                let px = u64::from(w) * u64::from(h);
                if px > limit {
                    return refuse(
                        StatusCode::ClientErrorRequestEntityTooLong,
                        format!(
                            "the {kind} document is {w}x{h} = {px} pixels, over the queue's \
                             limit of {limit}"
                        ),
                    );
                }
            }
        }
        match (format, sniffed) {
            (_, None) => refuse(
                StatusCode::ClientErrorDocumentFormatNotSupported,
                "the document is none of the formats the server reads (images, PWG or Apple \
                 raster, PDF)",
            ),
            (_, Some(s)) if !DOCUMENT_FORMATS.contains(&s) && !s.starts_with("image/") => refuse(
                StatusCode::ClientErrorDocumentFormatNotSupported,
                format!("the document is {s}, which this server does not read"),
            ),
            (f, Some(s)) if f != "application/octet-stream" && f != s => refuse(
                StatusCode::ClientErrorDocumentFormatError,
                format!("document-format says {f} but the data is {s}"),
            ),
            (_, Some(_)) => Ok(doc),
        }
    }

    fn add_job(
        &self,
        queue: usize,
        r: &Request,
        job: JobTemplate,
        document: Option<Vec<u8>>,
    ) -> Result<i32, Refusal> {
        let up = self.up_time();
        let id = {
            let mut st = self.lock();
            let waiting = st.jobs.iter().filter(|j| !j.state.is_finished()).count();
            if waiting >= self.limits.max_jobs {
                return refuse(
                    StatusCode::ServerErrorBusy,
                    format!("{waiting} jobs are waiting; try again later"),
                );
            }
            while st.jobs.len() >= self.limits.max_jobs {
                match st.jobs.iter().position(|j| j.state.is_finished()) {
                    Some(i) => {
                        st.jobs.remove(i);
                    }
                    None => break,
                }
            }
            let id = st.next_id;
            if let Some(sp) = &self.spool {
                if id >= st.reserved {
                    let next = id.saturating_add(spool::ID_BLOCK);
                    sp.reserve_ids(next).map_err(|e| {
                        Refusal(StatusCode::ServerErrorInternalError, format!("spool: {e}"))
                    })?;
                    st.reserved = next;
                }
            }
            st.next_id = st.next_id.checked_add(1).unwrap_or(1);
            id
        };
        let mut j = new_job(id, queue, r, job, document, up);
        j.request = r.head.clone();
        if let Some(doc) = &j.document {
            // On disk before the job is acknowledged; the worker sees it only after.
            self.spool_job(j.id, queue, j.created, &j.request, doc)?;
        }
        let has_doc = j.document.is_some();
        self.lock().jobs.push_back(j);
        if has_doc {
            self.work.notify_all();
        }
        Ok(id)
    }

    /// Writes job `id` (its request up to the document, and the document `doc`) to the
    /// spool, if there is one.
    fn spool_job(
        &self,
        id: i32,
        queue: usize,
        created: u64,
        request: &[u8],
        doc: &[u8],
    ) -> Result<(), Refusal> {
        let Some(sp) = &self.spool else {
            return Ok(());
        };
        sp.write_parts(id, &self.config.queues[queue].name, created, request, doc)
            .map_err(|e| {
                Refusal(
                    StatusCode::ServerErrorInternalError,
                    format!("the job could not be spooled: {e}"),
                )
            })
    }

    /// Removes an ended job from the spool. A failure leaves the file, and the job would be
    /// printed again after a restart; nothing better can be done here.
    fn unspool(&self, id: i32) {
        if let Some(sp) = &self.spool {
            let _ = sp.remove(id);
        }
    }

    /// The job a request names (job-id, or the number at the end of job-uri) on `queue`.
    fn job_id(&self, r: &Request, queue: usize) -> Result<i32, Refusal> {
        let id = match r.op("job-id") {
            Some(IppValue::Integer(i)) => *i,
            Some(_) => {
                return refuse(
                    StatusCode::ClientErrorBadRequest,
                    "job-id must be an integer",
                )
            }
            None => match r.op_text("job-uri") {
                Some(u) => uri_path(&u)
                    .rsplit('/')
                    .next()
                    .and_then(|s| s.parse().ok())
                    .ok_or(Refusal(
                        StatusCode::ClientErrorBadRequest,
                        format!("bad job-uri {u}"),
                    ))?,
                None => return refuse(StatusCode::ClientErrorBadRequest, "no job-id or job-uri"),
            },
        };
        let st = self.lock();
        match st.jobs.iter().find(|j| j.id == id) {
            Some(j) if j.queue == queue => Ok(id),
            _ => refuse(StatusCode::ClientErrorNotFound, format!("no job {id}")),
        }
    }

    fn send_document(
        &self,
        r: &Request,
        queue: usize,
        out: &mut Out,
    ) -> Result<StatusCode, Refusal> {
        let id = self.job_id(r, queue)?;
        let format = r.document_format()?;
        match r.op("last-document") {
            Some(IppValue::Boolean(true)) => {}
            Some(IppValue::Boolean(false)) => {
                return refuse(
                    StatusCode::ServerErrorMultipleDocumentJobsNotSupported,
                    "one document a job: send it with last-document true",
                )
            }
            _ => {
                return refuse(
                    StatusCode::ClientErrorBadRequest,
                    "last-document is required",
                )
            }
        }
        let entry = {
            let st = self.lock();
            let job = st.jobs.iter().find(|j| j.id == id);
            match job {
                Some(j) if j.state != JobState::PendingHeld => {
                    return refuse(
                        StatusCode::ClientErrorNotPossible,
                        format!("job {id} is not waiting for a document"),
                    );
                }
                Some(j) => (j.request.clone(), j.created),
                None => return refuse(StatusCode::ClientErrorNotFound, format!("no job {id}")),
            }
        };
        let doc = self.check_document(r.document.clone(), &format, queue)?;
        self.spool_job(id, queue, entry.1, &entry.0, &doc)?;
        {
            let mut st = self.lock();
            if let Some(j) = st.jobs.iter_mut().find(|j| j.id == id) {
                if j.state != JobState::PendingHeld {
                    drop(st);
                    self.unspool(id);
                    return refuse(
                        StatusCode::ClientErrorNotPossible,
                        format!("job {id} is not waiting for a document"),
                    );
                }
                j.octets = doc.len() as u64;
                j.document = Some(doc);
                j.state = JobState::Pending;
                j.reasons = vec!["none"];
                j.message = "queued".into();
            }
        }
        self.work.notify_all();
        self.job_response(id, &r.host, out);
        Ok(StatusCode::SuccessfulOk)
    }

    fn cancel_job(&self, r: &Request, queue: usize) -> Result<StatusCode, Refusal> {
        let id = self.job_id(r, queue)?;
        let up = self.up_time();
        let mut st = self.lock();
        let Some(j) = st.jobs.iter_mut().find(|j| j.id == id) else {
            return refuse(StatusCode::ClientErrorNotFound, format!("no job {id}"));
        };
        if j.state.is_finished() {
            return refuse(
                StatusCode::ClientErrorNotPossible,
                format!("job {id} has finished"),
            );
        }
        cancel(j, up);
        drop(st);
        self.unspool(id);
        Ok(StatusCode::SuccessfulOk)
    }

    fn cancel_my_jobs(&self, r: &Request, queue: usize) -> Result<StatusCode, Refusal> {
        let user = r.op_text("requesting-user-name").unwrap_or_default();
        let up = self.up_time();
        let mut st = self.lock();
        let mut ids = Vec::new();
        for j in st
            .jobs
            .iter_mut()
            .filter(|j| j.queue == queue && j.user == user && !j.state.is_finished())
        {
            cancel(j, up);
            ids.push(j.id);
        }
        drop(st);
        for id in ids {
            self.unspool(id);
        }
        Ok(StatusCode::SuccessfulOk)
    }

    fn close_job(&self, r: &Request, queue: usize, out: &mut Out) -> Result<StatusCode, Refusal> {
        let id = self.job_id(r, queue)?;
        let up = self.up_time();
        {
            let mut st = self.lock();
            if let Some(j) = st.jobs.iter_mut().find(|j| j.id == id) {
                if j.state == JobState::PendingHeld {
                    j.state = JobState::Aborted;
                    j.reasons = vec!["aborted-by-system"];
                    j.message = "closed without a document".into();
                    j.times[2] = Some(up);
                }
            }
        }
        self.job_response(id, &r.host, out);
        Ok(StatusCode::SuccessfulOk)
    }

    fn get_job_attributes(
        &self,
        r: &Request,
        queue: usize,
        out: &mut Out,
    ) -> Result<StatusCode, Refusal> {
        let id = self.job_id(r, queue)?;
        let requested = r.requested_attributes();
        let st = self.lock();
        let Some(j) = st.jobs.iter().find(|j| j.id == id) else {
            return refuse(StatusCode::ClientErrorNotFound, format!("no job {id}"));
        };
        let list = self
            .job_attributes(j, &st, &r.host)
            .into_iter()
            .filter(|a| {
                requested
                    .as_ref()
                    .is_none_or(|l| wants(l, a.name().as_str(), "job-description"))
            })
            .collect();
        out.groups.push((DelimiterTag::JobAttributes, list));
        Ok(StatusCode::SuccessfulOk)
    }

    fn get_jobs(&self, r: &Request, queue: usize, out: &mut Out) -> Result<StatusCode, Refusal> {
        let which = r
            .op_text("which-jobs")
            .unwrap_or_else(|| "not-completed".into());
        let keep: fn(JobState) -> bool = match which.as_str() {
            "not-completed" => |s| !s.is_finished(),
            "completed" => |s| s.is_finished(),
            "all" => |_| true,
            other => {
                return refuse(
                    StatusCode::ClientErrorAttributesOrValuesNotSupported,
                    format!("which-jobs {other} is not supported"),
                )
            }
        };
        let mine = r.op_bool("my-jobs").unwrap_or(false);
        let user = r.op_text("requesting-user-name").unwrap_or_default();
        let limit = match r.op("limit") {
            Some(IppValue::Integer(n)) if *n > 0 => *n as usize,
            _ => usize::MAX,
        };
        let requested = r
            .requested_attributes()
            .unwrap_or_else(|| vec!["job-id".into(), "job-uri".into()]);
        let st = self.lock();
        // Newest first for completed jobs, oldest first for waiting ones (as CUPS does).
        let mut jobs: Vec<&Job> = st
            .jobs
            .iter()
            .filter(|j| j.queue == queue && keep(j.state) && (!mine || j.user == user))
            .collect();
        if which != "not-completed" {
            jobs.reverse();
        }
        for j in jobs.into_iter().take(limit) {
            let list = self
                .job_attributes(j, &st, &r.host)
                .into_iter()
                .filter(|a| wants(&requested, a.name().as_str(), "job-description"))
                .collect();
            out.groups.push((DelimiterTag::JobAttributes, list));
        }
        Ok(StatusCode::SuccessfulOk)
    }

    /// The job attributes of a job-creating operation's response.
    fn job_response(&self, id: i32, host: &str, out: &mut Out) {
        let st = self.lock();
        if let Some(j) = st.jobs.iter().find(|j| j.id == id) {
            let keep = [
                "job-id",
                "job-uri",
                "job-state",
                "job-state-reasons",
                "job-state-message",
                "number-of-intervening-jobs",
            ];
            let list = self
                .job_attributes(j, &st, host)
                .into_iter()
                .filter(|a| keep.contains(&a.name().as_str()))
                .collect();
            out.groups.push((DelimiterTag::JobAttributes, list));
        }
    }

    fn job_attributes(&self, j: &Job, st: &State, host: &str) -> Vec<IppAttribute> {
        let q = &self.config.queues[j.queue];
        let queue_uri = queue_uri_at(host, q);
        let ahead = st
            .jobs
            .iter()
            .filter(|o| o.queue == j.queue && o.id < j.id && !o.state.is_finished())
            .count();
        let time = |t: Option<u64>| t.map_or(IppValue::NoValue, |s| IppValue::Integer(clamp(s)));
        let date = |t: Option<u64>| {
            t.map_or(IppValue::NoValue, |s| {
                IppValue::DateTime(attrs::date_time(self.started_unix + s.saturating_sub(1)))
            })
        };
        let mut list = vec![
            attr("job-id", IppValue::Integer(j.id)),
            attr("job-uri", uri(&format!("{queue_uri}/{}", j.id))),
            attr("job-printer-uri", uri(&queue_uri)),
            attr("job-more-info", uri(&format!("http://{host}/"))),
            attr("job-name", name(&j.name)),
            attr("job-originating-user-name", name(&j.user)),
            attr("job-state", IppValue::Enum(j.state as i32)),
            attr(
                "job-state-reasons",
                list_of(j.reasons.iter().map(|r| kw(r)).collect()),
            ),
            attr("job-state-message", text(&j.message)),
            attr(
                "number-of-documents",
                IppValue::Integer(i32::from(j.octets > 0)),
            ),
            attr(
                "number-of-intervening-jobs",
                IppValue::Integer(clamp(ahead as u64)),
            ),
            attr("output-device-assigned", name(&q.name)),
            attr("time-at-creation", time(j.times[0])),
            attr("time-at-processing", time(j.times[1])),
            attr("time-at-completed", time(j.times[2])),
            attr("date-time-at-creation", date(j.times[0])),
            attr("date-time-at-processing", date(j.times[1])),
            attr("date-time-at-completed", date(j.times[2])),
            attr(
                "job-printer-up-time",
                IppValue::Integer(clamp(self.up_time())),
            ),
            attr(
                "job-k-octets",
                IppValue::Integer(clamp(j.octets.div_ceil(1024))),
            ),
            attr("copies", IppValue::Integer(j.copies as i32)),
        ];
        if j.state == JobState::Completed {
            list.push(attr(
                "job-impressions-completed",
                IppValue::Integer(clamp(j.pages.max(1) as u64 * u64::from(j.copies))),
            ));
        }
        if let Some(m) = &j.method {
            list.push(attr("halftone-method", kw(m)));
        }
        list
    }

    /// Waits up to `timeout` for a job with its document that may be processed now (not
    /// waiting to retry a backend that was down, nor queued behind such a job on its
    /// queue); returns its id.
    pub fn wait_for_job(&self, timeout: Duration) -> Option<i32> {
        let end = Instant::now() + timeout;
        let mut st = self.lock();
        loop {
            let now = Instant::now();
            if let Some(id) = next_due(&st, self.config.queues.len(), now) {
                return Some(id);
            }
            if now >= end {
                return None;
            }
            // Wake for a new job, or when the earliest retry is due.
            let retry = st
                .jobs
                .iter()
                .filter(|j| j.state == JobState::Pending)
                .filter_map(|j| j.retry.map(|r| r.1))
                .min();
            let until = retry.map_or(end, |r| r.clamp(now, end));
            let wait = until
                .saturating_duration_since(now)
                .max(Duration::from_millis(1));
            st = self
                .work
                .wait_timeout(st, wait)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Halftones job `id` with its queue's options and its own, and sends the bytes to the
    /// queue's backend. The job ends completed, or aborted with the reason in its message
    /// (which is also returned); it is then removed from the spool. A backend that cannot
    /// be reached (a printer switched off, a device missing) leaves the job pending, its
    /// halftoned bytes kept, to be tried again after [`retry_delay`]; the queue's
    /// `printer-state-reasons` say why meanwhile, and the error returned says when.
    pub fn process(&self, id: i32) -> std::result::Result<String, String> {
        let up = self.up_time();
        let (queue, doc, settings, copies, plan, output) = {
            let mut st = self.lock();
            let Some(j) = st.jobs.iter_mut().find(|j| j.id == id) else {
                return Err(format!("no job {id}"));
            };
            if j.state != JobState::Pending {
                return Err(format!("job {id} is not pending"));
            }
            j.state = JobState::Processing;
            j.reasons = vec!["job-printing"];
            j.message = if j.output.is_some() {
                "sending".into()
            } else {
                "halftoning".into()
            };
            j.times[1] = Some(up);
            (
                j.queue,
                if j.output.is_some() {
                    None
                } else {
                    j.document.clone()
                },
                j.settings.clone(),
                j.copies,
                j.plan.clone(),
                j.output.take(),
            )
        };
        let q = &self.config.queues[queue];
        let files = match output {
            Some(files) => Ok(files),
            None => self.halftone_job(id, q, doc, &settings, copies, &plan),
        };
        let result = files.map(|files| {
            let mut to = String::new();
            for (bytes, file) in &files {
                match q.backend.deliver(bytes, file) {
                    Ok(t) => to = t,
                    Err(e) if Backend::may_pass(&e) => return Err(Ok((files, e.to_string()))),
                    Err(e) => return Err(Err(e.to_string())),
                }
            }
            // Delivered: out of the spool at once, the only step between the backend
            // taking the bytes and the job being marked done.
            self.unspool(id);
            Ok(to)
        });
        let done = self.up_time();
        let mut st = self.lock();
        let Some(j) = st.jobs.iter_mut().find(|j| j.id == id) else {
            return Err(format!("no job {id}"));
        };
        if j.state == JobState::Canceled {
            drop(st);
            self.unspool(id);
            return Err("canceled".into());
        }
        match result {
            Ok(Ok(to)) => {
                j.state = JobState::Completed;
                j.reasons = vec!["job-completed-successfully"];
                j.message = format!("printed to {to}");
                j.times[2] = Some(done);
                j.document = None;
                j.retry = None;
                st.down[queue] = None;
                Ok(to)
            }
            Ok(Err(Ok((files, why)))) => {
                let n = j.retry.map_or(1, |r| r.0 + 1);
                let after = retry_delay(n);
                let msg = truncate(
                    &format!(
                        "{why}; the job waits, next try in {} s (attempt {n} failed)",
                        after.as_secs()
                    ),
                    1023,
                );
                j.state = JobState::Pending;
                j.reasons = vec!["resources-are-not-ready"];
                j.message = msg.clone();
                j.retry = Some((n, Instant::now() + after));
                j.output = Some(files);
                st.down[queue] = Some(format!("the printer cannot be reached: {msg}"));
                Err(msg)
            }
            Err(e) | Ok(Err(Err(e))) => {
                j.state = JobState::Aborted;
                j.reasons = vec!["aborted-by-system"];
                j.message = truncate(&e, 1023);
                j.times[2] = Some(done);
                j.document = None;
                drop(st);
                self.unspool(id);
                Err(e)
            }
        }
    }

    /// A job's output files: its document halftoned page by page, copies made.
    fn halftone_job(
        &self,
        id: i32,
        q: &Queue,
        doc: Option<Vec<u8>>,
        settings: &[(String, Value<'static>)],
        copies: u32,
        plan: &PagePlan,
    ) -> std::result::Result<Vec<(Vec<u8>, String)>, String> {
        let doc = doc.ok_or_else(|| "no document".to_string())?;
        let opts = q.job_options(settings).map_err(|e| e.to_string())?;
        self.set_method(id, opts.method.name());
        // One converter for each set of overrides met, made when first needed.
        let mut made: Vec<(u64, std::rc::Rc<Converter>, f64)> = Vec::new();
        let (started, limits) = (Instant::now(), self.limits);
        let mut pick = |page: usize| -> Result<Option<document::PageJob>, String> {
            if page > limits.max_pages {
                return Err(format!(
                    "the document has more than {} pages, the limit of this server \
                     (--max-pages)",
                    limits.max_pages
                ));
            }
            if started.elapsed().as_secs() >= limits.max_job_seconds {
                return Err(format!(
                    "halftoning took longer than {} s, the limit of this server \
                     (--max-job-seconds), before page {page}",
                    limits.max_job_seconds
                ));
            }
            if !plan.prints(page) {
                return Ok(None);
            }
            let key = plan.covering(page);
            if let Some((_, c, dpi)) = made.iter().find(|m| m.0 == key) {
                return Ok(Some((c.clone(), *dpi)));
            }
            let mut all = settings.to_vec();
            for (i, o) in plan.overrides.iter().enumerate() {
                if key & 1 << i != 0 {
                    all.extend(o.settings.iter().cloned());
                }
            }
            let opts = q.job_options(&all).map_err(|e| e.to_string())?;
            let dpi = opts.dpi.unwrap_or(f64::from(attrs::queue_dpi(q)));
            let conv = std::rc::Rc::new(Converter::new(&opts).map_err(|e| e.to_string())?);
            made.push((key, conv.clone(), dpi));
            Ok(Some((conv, dpi)))
        };
        let canceled = || self.is_canceled(id);
        let (files, pages) =
            document::halftone(doc, q.format, id, opts.max_pixels, &mut pick, &canceled)?;
        self.set_pages(id, pages);
        if self.is_canceled(id) {
            return Err("canceled".into());
        }
        Ok(files
            .into_iter()
            .map(|(one, file)| {
                let bytes = if copies > 1 && attrs::concatenates(q.format) {
                    one.repeat(copies as usize)
                } else {
                    one
                };
                (bytes, file)
            })
            .collect())
    }

    /// The jobs kept, newest first, for the status page.
    pub fn jobs(&self) -> Vec<JobSummary> {
        self.lock()
            .jobs
            .iter()
            .rev()
            .map(|j| JobSummary {
                id: j.id,
                queue: self.config.queues[j.queue].name.clone(),
                name: j.name.clone(),
                user: j.user.clone(),
                state: j.state,
                message: j.message.clone(),
                pages: j.pages,
                method: j.method.clone(),
                created: j.created,
            })
            .collect()
    }

    /// Why queue `queue`'s backend cannot be reached, while it cannot.
    pub fn queue_down(&self, queue: usize) -> Option<String> {
        self.lock().down.get(queue).cloned().flatten()
    }

    fn set_pages(&self, id: i32, pages: usize) {
        if let Some(j) = self.lock().jobs.iter_mut().find(|j| j.id == id) {
            j.pages = pages;
        }
    }

    fn set_method(&self, id: i32, method: &str) {
        if let Some(j) = self.lock().jobs.iter_mut().find(|j| j.id == id) {
            j.method = Some(method.to_string());
        }
    }

    fn is_canceled(&self, id: i32) -> bool {
        self.lock()
            .jobs
            .iter()
            .any(|j| j.id == id && j.state == JobState::Canceled)
    }

    /// A job's state and message (for the binary's log and the tests).
    pub fn job_state(&self, id: i32) -> Option<(JobState, String)> {
        self.lock()
            .jobs
            .iter()
            .find(|j| j.id == id)
            .map(|j| (j.state, j.message.clone()))
    }
}

/// The first job that may be processed now: pending, not waiting for a retry, and not
/// behind a job of its queue that is (a queue's jobs print in order).
fn next_due(st: &State, queues: usize, now: Instant) -> Option<i32> {
    let mut blocked = vec![false; queues];
    for j in &st.jobs {
        if j.state != JobState::Pending || blocked[j.queue] {
            continue;
        }
        match j.retry {
            Some((_, at)) if at > now => blocked[j.queue] = true,
            _ => return Some(j.id),
        }
    }
    None
}

/// A new job from its request and template: pending with its document, held without.
fn new_job(
    id: i32,
    queue: usize,
    r: &Request,
    t: JobTemplate,
    document: Option<Vec<u8>>,
    up: u64,
) -> Job {
    let user = r
        .op_text("requesting-user-name")
        .unwrap_or_else(|| "anonymous".into());
    let name = r
        .op_text("job-name")
        .or_else(|| r.op_text("document-name"))
        .unwrap_or_else(|| "untitled".into());
    let has_doc = document.is_some();
    Job {
        id,
        queue,
        name: truncate(&name, 255),
        user: truncate(&user, 255),
        state: if has_doc {
            JobState::Pending
        } else {
            JobState::PendingHeld
        },
        reasons: vec![if has_doc { "none" } else { "job-incoming" }],
        message: if has_doc {
            "queued".into()
        } else {
            "waiting for its document".into()
        },
        times: [Some(up), None, None],
        octets: document.as_ref().map_or(0, |d| d.len() as u64),
        document,
        settings: t.settings,
        copies: t.copies,
        method: None,
        pages: 0,
        plan: t.pages,
        request: Vec::new(),
        created: unix_now(),
        retry: None,
        output: None,
    }
}

/// Seconds since the Unix epoch.
fn unix_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

/// A queue's URI on `host` (`HOST:PORT`).
fn queue_uri_at(host: &str, q: &Queue) -> String {
    format!("ipp://{host}/ipp/print/{}", q.name)
}

/// The `HOST:PORT` a client reached the server at, from its HTTP `Host` header: a DNS
/// name, an IPv4 address or a bracketed IPv6 address, with an optional port (the
/// server's own when absent). Anything else (no header, a malformed one, characters a
/// URI cannot carry) gives `bound`, the address the server listens on.
pub fn request_host(header: Option<&str>, bound: &str) -> String {
    let Some(h) = header.map(str::trim) else {
        return bound.to_string();
    };
    let bound_port = bound.rsplit_once(':').map_or("", |(_, p)| p);
    let (name, port) = if let Some(rest) = h.strip_prefix('[') {
        let Some((inside, after)) = rest.split_once(']') else {
            return bound.to_string();
        };
        if inside.parse::<std::net::Ipv6Addr>().is_err() {
            return bound.to_string();
        }
        match after.strip_prefix(':') {
            Some(p) => (format!("[{inside}]"), p),
            None if after.is_empty() => (format!("[{inside}]"), bound_port),
            None => return bound.to_string(),
        }
    } else {
        let (n, p) = h.rsplit_once(':').unwrap_or((h, bound_port));
        let label_ok = |l: &str| {
            !l.is_empty()
                && l.len() <= 63
                && !l.starts_with('-')
                && !l.ends_with('-')
                && l.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
        };
        let n = n.strip_suffix('.').unwrap_or(n);
        if n.len() > 253 || !n.split('.').all(label_ok) {
            return bound.to_string();
        }
        (n.to_ascii_lowercase(), p)
    };
    match port.parse::<u16>() {
        Ok(p) if p > 0 && !port.starts_with('+') => format!("{name}:{p}"),
        _ => bound.to_string(),
    }
}

fn cancel(j: &mut Job, up: u64) {
    j.state = JobState::Canceled;
    j.reasons = vec!["job-canceled-by-user"];
    j.message = "canceled".into();
    j.document = None;
    j.output = None;
    j.times[2] = Some(up);
}

struct JobTemplate {
    settings: Vec<(String, Value<'static>)>,
    copies: u32,
    pages: PagePlan,
    status: StatusCode,
}

/// Which pages of a job are printed and with what: `page-ranges` and `overrides`
/// (PWG 5100.6; one document a job, so `document-numbers` can only name document 1).
#[derive(Clone, Debug, Default)]
pub struct PagePlan {
    /// page-ranges: the pages printed (all when empty).
    pub ranges: Vec<(i32, i32)>,
    /// overrides, in order: a later one wins where two set the same option.
    pub overrides: Vec<Override>,
}

/// One member of `overrides`: options for some pages.
#[derive(Clone, Debug)]
pub struct Override {
    /// The pages it covers (all when empty).
    pub pages: Vec<(i32, i32)>,
    /// The documents it covers (all when empty).
    pub documents: Vec<(i32, i32)>,
    /// The options it sets, by their one names.
    pub settings: Vec<(String, Value<'static>)>,
}

impl PagePlan {
    /// True when page `page` (from 1) is printed.
    pub fn prints(&self, page: usize) -> bool {
        in_ranges(&self.ranges, page)
    }

    /// The overrides covering page `page` of document 1, as a bit set (bit i: override i).
    pub fn covering(&self, page: usize) -> u64 {
        self.overrides
            .iter()
            .enumerate()
            .filter(|(_, o)| in_ranges(&o.documents, 1) && in_ranges(&o.pages, page))
            .fold(0, |m, (i, _)| m | 1 << i)
    }
}

fn in_ranges(r: &[(i32, i32)], n: usize) -> bool {
    r.is_empty()
        || r.iter()
            .any(|&(a, b)| (a as usize..=b as usize).contains(&n))
}

/// `overrides`: each member's `pages` and `document-numbers`, and its other attributes
/// mapped to options as a job's are (refused, never ignored, when one does not map).
fn overrides(
    q: &Queue,
    v: &IppValue,
    _job: &[(String, Value<'static>)],
) -> Result<Vec<Override>, String> {
    let members: Vec<&IppValue> = match v {
        IppValue::Array(a) => a.iter().collect(),
        v => vec![v],
    };
    if members.len() > 64 {
        return Err(format!("{} members; at most 64 are taken", members.len()));
    }
    members
        .into_iter()
        .map(|m| {
            let IppValue::Collection(c) = m else {
                return Err("a member is not a collection".to_string());
            };
            let mut o = Override {
                pages: Vec::new(),
                documents: Vec::new(),
                settings: Vec::new(),
            };
            for (k, v) in c {
                match k.as_str() {
                    "pages" => o.pages = page_ranges(v)?,
                    "document-numbers" => o.documents = page_ranges(v)?,
                    "document-copies" => return Err("document-copies is not supported".into()),
                    n => match attrs::map_job_attribute(q, n, v) {
                        Ok(attrs::Mapped::Setting(list)) => o.settings.extend(list),
                        Ok(attrs::Mapped::Ignored) => {}
                        Ok(attrs::Mapped::Copies(_)) => {
                            return Err("copies cannot differ between pages".into())
                        }
                        Err(why) => return Err(format!("{n}: {why}")),
                    },
                }
            }
            Ok(o)
        })
        .collect()
}

/// Page ranges from a rangeOfInteger, an integer or a 1setOf them.
fn page_ranges(v: &IppValue) -> Result<Vec<(i32, i32)>, String> {
    let one = |v: &IppValue| match v {
        IppValue::RangeOfInteger { min, max } if *min >= 1 && min <= max => Ok((*min, *max)),
        IppValue::Integer(i) if *i >= 1 => Ok((*i, *i)),
        _ => Err(format!(
            "{} is not a range of pages",
            value_text(v).unwrap_or_default()
        )),
    };
    match v {
        IppValue::Array(a) => a.iter().map(one).collect(),
        v => one(v).map(|r| vec![r]),
    }
}

/// A parsed request.
struct Request {
    /// The request up to the end of its attributes, as it came.
    head: Vec<u8>,
    /// `HOST:PORT` for the URIs of the response.
    host: String,
    header: IppHeader,
    attributes: IppAttributes,
    document: Vec<u8>,
}

impl Request {
    fn group(&self, tag: DelimiterTag) -> impl Iterator<Item = &IppAttribute> {
        self.attributes
            .groups_of(tag)
            .flat_map(|g| g.attributes().iter())
    }

    fn op(&self, n: &str) -> Option<&IppValue> {
        self.group(DelimiterTag::OperationAttributes)
            .find(|a| a.name().as_str() == n)
            .map(|a| a.value())
    }

    fn op_text(&self, n: &str) -> Option<String> {
        self.op(n).and_then(value_text)
    }

    fn op_bool(&self, n: &str) -> Option<bool> {
        match self.op(n) {
            Some(IppValue::Boolean(b)) => Some(*b),
            _ => None,
        }
    }

    /// RFC 8011 section 4.1.4: the operation attributes come first, attributes-charset
    /// first among them and attributes-natural-language second.
    fn check_operation_group(&self) -> Result<(), Refusal> {
        let groups = self.attributes.groups();
        let Some(first) = groups.first() else {
            return refuse(StatusCode::ClientErrorBadRequest, "no operation attributes");
        };
        if first.tag() != DelimiterTag::OperationAttributes {
            return refuse(
                StatusCode::ClientErrorBadRequest,
                "the operation attributes must come first",
            );
        }
        let a = first.attributes();
        match (a.first(), a.get(1)) {
            (Some(c), Some(l))
                if c.name().as_str() == "attributes-charset"
                    && l.name().as_str() == "attributes-natural-language" =>
            {
                let charset = value_text(c.value())
                    .unwrap_or_default()
                    .to_ascii_lowercase();
                if charset != "utf-8" && charset != "us-ascii" {
                    return refuse(
                        StatusCode::ClientErrorCharsetNotSupported,
                        format!("charset {charset} is not supported (utf-8 is)"),
                    );
                }
                Ok(())
            }
            _ => refuse(
                StatusCode::ClientErrorBadRequest,
                "attributes-charset and attributes-natural-language must be the first two \
                 operation attributes",
            ),
        }
    }

    fn document_format(&self) -> Result<String, Refusal> {
        if let Some(c) = self.op_text("compression") {
            if c != "none" {
                return refuse(
                    StatusCode::ClientErrorCompressionNotSupported,
                    format!("compression {c} is not supported"),
                );
            }
        }
        let f = self
            .op_text("document-format")
            .unwrap_or_else(|| "application/octet-stream".into());
        if !DOCUMENT_FORMATS.contains(&f.as_str()) {
            return refuse(
                StatusCode::ClientErrorDocumentFormatNotSupported,
                format!(
                    "document-format {f} is not supported ({})",
                    DOCUMENT_FORMATS.join(", ")
                ),
            );
        }
        Ok(f)
    }

    fn requested_attributes(&self) -> Option<Vec<String>> {
        let v = self.op("requested-attributes")?;
        let list = match v {
            IppValue::Array(a) => a.iter().filter_map(value_text).collect(),
            one => value_text(one).into_iter().collect(),
        };
        Some(list)
    }
}

/// True when `requested` asks for attribute `n` of group `group` (by name, `all`, or the
/// group's name).
fn wants(requested: &[String], n: &str, group: &str) -> bool {
    requested
        .iter()
        .any(|r| r == n || (r == "all" && n != "media-col-database") || r == group)
}

/// The text of a string-like value.
fn value_text(v: &IppValue) -> Option<String> {
    Some(match v {
        IppValue::Keyword(s) | IppValue::NameWithoutLanguage(s) | IppValue::MemberAttrName(s) => {
            s.as_str().to_string()
        }
        IppValue::Charset(s) => s.as_str().to_string(),
        IppValue::NaturalLanguage(s) => s.as_str().to_string(),
        IppValue::MimeMediaType(s) => s.as_str().to_string(),
        IppValue::Uri(s) | IppValue::UriScheme(s) => s.as_str().to_string(),
        IppValue::NameWithLanguage { name, .. } => name.as_str().to_string(),
        IppValue::TextWithoutLanguage(t) | IppValue::TextWithLanguage { text: t, .. } => {
            t.to_string()
        }
        _ => return None,
    })
}

/// The path of a URI (`ipp://host:631/ipp/print/x` → `/ipp/print/x`).
fn uri_path(u: &str) -> String {
    let rest = u.split_once("://").map_or(u, |(_, r)| r);
    match rest.find('/') {
        Some(i) => rest[i..].to_string(),
        None => String::new(),
    }
}

fn truncate(s: &str, max: usize) -> String {
    let mut end = s.len().min(max);
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    s[..end].to_string()
}

fn clamp(v: u64) -> i32 {
    v.min(i32::MAX as u64) as i32
}

fn attr(n: &str, v: IppValue) -> IppAttribute {
    IppAttribute::new(IppName::new_truncated(n), v)
}

/// One value, or a 1setOf of several.
fn list_of(mut v: Vec<IppValue>) -> IppValue {
    if v.len() == 1 {
        v.remove(0)
    } else {
        IppValue::Array(v)
    }
}

/// A response being built.
#[derive(Default)]
struct Out {
    message: Option<String>,
    groups: Vec<(DelimiterTag, Vec<IppAttribute>)>,
}

impl Out {
    fn encode(self, version: IppVersion, status: StatusCode, id: i32) -> Vec<u8> {
        let mut a = IppAttributes::new();
        a.add(
            DelimiterTag::OperationAttributes,
            attr(
                "attributes-charset",
                IppValue::Charset(ipp::value::IppCharset::new_truncated("utf-8")),
            ),
        );
        a.add(
            DelimiterTag::OperationAttributes,
            attr(
                "attributes-natural-language",
                IppValue::NaturalLanguage(ipp::value::IppLanguage::new_truncated("en")),
            ),
        );
        if let Some(m) = &self.message {
            a.add(
                DelimiterTag::OperationAttributes,
                attr("status-message", text(m)),
            );
        }
        for (tag, list) in self.groups {
            let mut g = ipp::attribute::IppAttributeGroup::new(tag);
            g.attributes_mut().extend(list);
            a.groups_mut().push(g);
        }
        let header = IppHeader::new(version, status as i16, id);
        let mut out = header.to_bytes().to_vec();
        out.extend_from_slice(&a.to_bytes());
        out
    }
}

/// A response with only a status and message.
fn error_response(id: i32, status: StatusCode, msg: &str) -> Vec<u8> {
    Out {
        message: Some(msg.to_string()),
        groups: Vec::new(),
    }
    .encode(IppVersion::v1_1(), status, id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn printer(dir: &std::path::Path) -> Printer {
        let q = Queue::new(
            "receipt",
            vec![("preset".into(), Value::from("thermal-203".to_string()))],
            super::super::config::Backend::Folder(dir.to_path_buf()),
        )
        .unwrap();
        Printer::new(
            Config {
                queues: vec![q],
                spool: None,
            },
            "127.0.0.1:8631",
            Limits::default(),
        )
    }

    /// An IPP request by hand: header, operation attributes, optional job attributes.
    fn request(op: u16, id: i32, ops: &[(u8, &str, &[u8])], job: &[(u8, &str, &[u8])]) -> Vec<u8> {
        let mut b = vec![2, 0];
        b.extend_from_slice(&op.to_be_bytes());
        b.extend_from_slice(&id.to_be_bytes());
        let group = |b: &mut Vec<u8>, tag: u8, list: &[(u8, &str, &[u8])]| {
            b.push(tag);
            for (t, n, v) in list {
                b.push(*t);
                b.extend_from_slice(&(n.len() as u16).to_be_bytes());
                b.extend_from_slice(n.as_bytes());
                b.extend_from_slice(&(v.len() as u16).to_be_bytes());
                b.extend_from_slice(v);
            }
        };
        group(&mut b, 1, ops);
        if !job.is_empty() {
            group(&mut b, 2, job);
        }
        b.push(3);
        b
    }

    const URI: &str = "ipp://127.0.0.1:8631/ipp/print/receipt";

    fn base() -> Vec<(u8, &'static str, &'static [u8])> {
        vec![
            (0x47, "attributes-charset", b"utf-8"),
            (0x48, "attributes-natural-language", b"en"),
            (0x45, "printer-uri", URI.as_bytes()),
        ]
    }

    fn status(resp: &[u8]) -> u16 {
        u16::from_be_bytes([resp[2], resp[3]])
    }

    fn parse(resp: Vec<u8>) -> ipp::request::IppRequestResponse {
        IppParser::new(IppReader::new(Cursor::new(resp)))
            .parse()
            .unwrap()
    }

    /// A small PNG (a ramp shifted by `k`).
    fn png(k: usize) -> Vec<u8> {
        let img = crate::Image::gray8(
            40,
            24,
            (0..40 * 24).map(|i| ((i + k) % 40 * 6) as u8).collect(),
        );
        let o = crate::Options {
            levels: 256,
            ..Default::default()
        };
        crate::encode(&crate::convert(img, &o).unwrap(), crate::Format::Png, &o).unwrap()
    }

    fn print_job(p: &Printer, doc: &[u8], user: &str) -> i32 {
        let mut ops = base();
        ops.push((0x49, "document-format", b"image/png"));
        ops.push((0x42, "requesting-user-name", user.as_bytes()));
        let mut req = request(0x02, 7, &ops, &[]);
        req.extend_from_slice(doc);
        let r = parse(p.handle_bytes(req, false));
        assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
        let j = r
            .attributes()
            .first_of(DelimiterTag::JobAttributes)
            .unwrap();
        match j.get("job-id").unwrap().value() {
            IppValue::Integer(i) => *i,
            v => panic!("{v:?}"),
        }
    }

    fn printer_attr(p: &Printer, name: &str) -> String {
        let r = parse(p.handle_bytes(request(0x0b, 9, &base(), &[]), false));
        let g = r
            .attributes()
            .first_of(DelimiterTag::PrinterAttributes)
            .unwrap();
        g.get(name).unwrap().value().to_string()
    }

    #[test]
    fn spooled_jobs_come_back_once_with_their_numbers() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let sp = dir.path().join("spool");
        let mut p = printer(&out);
        assert!(p.recover(Spool::open(&sp).unwrap()).unwrap().is_empty());
        let ids: Vec<i32> = (0..3)
            .map(|k| print_job(&p, &png(k), &format!("u{k}")))
            .collect();
        assert_eq!(ids, vec![1, 2, 3]);
        // Three acknowledged jobs are three files on disk.
        let spooled = |d: &std::path::Path| {
            let mut v: Vec<String> = std::fs::read_dir(d)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".ipp"))
                .collect();
            v.sort();
            v
        };
        assert_eq!(spooled(&sp), ["job-1.ipp", "job-2.ipp", "job-3.ipp"]);
        assert_eq!(p.wait_for_job(Duration::ZERO), Some(1));
        p.process(1).unwrap();
        assert_eq!(spooled(&sp), ["job-2.ipp", "job-3.ipp"]);
        // The server stops with two jobs queued; another takes them back.
        drop(p);
        let mut p = printer(&out);
        let log = p.recover(Spool::open(&sp).unwrap()).unwrap();
        assert_eq!(log.len(), 2, "{log:?}");
        assert!(log[0].starts_with("job 2: taken back"), "{log:?}");
        for id in [2, 3] {
            assert_eq!(p.wait_for_job(Duration::ZERO), Some(id));
            p.process(id).unwrap();
            let got = std::fs::read(out.join(format!("job-{id}.escpos"))).unwrap();
            let opts = p.config().queues[0].job_options(&[]).unwrap();
            let want = crate::convert_to_bytes(png(id as usize - 1), crate::Format::EscPos, &opts)
                .unwrap();
            assert_eq!(got, want, "job {id}");
        }
        let jobs = p.jobs();
        assert_eq!(jobs[0].user, "u2");
        assert!(spooled(&sp).is_empty());
        assert_eq!(p.wait_for_job(Duration::ZERO), None);
        // Numbers go on after the restart: none is used twice.
        let next = print_job(&p, &png(9), "v");
        assert!(next > 3, "{next}");
        // A cancelled job leaves the spool too.
        let mut c = base();
        let idb = next.to_be_bytes();
        c.push((0x21, "job-id", &idb));
        assert_eq!(status(&p.handle_bytes(request(0x08, 3, &c, &[]), false)), 0);
        assert!(spooled(&sp).is_empty());
    }

    #[test]
    fn a_backend_that_is_down_keeps_the_job_pending() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("not-yet");
        let p = printer(&out);
        assert_eq!(printer_attr(&p, "printer-state-reasons"), "none");
        let id = print_job(&p, &png(0), "ann");
        assert_eq!(p.wait_for_job(Duration::ZERO), Some(id));
        let err = p.process(id).unwrap_err();
        assert!(
            err.contains("not-yet") && err.contains("next try in 1 s"),
            "{err}"
        );
        let (state, msg) = p.job_state(id).unwrap();
        assert_eq!(state, JobState::Pending, "{msg}");
        let reasons = printer_attr(&p, "printer-state-reasons");
        assert!(reasons.contains("offline-report"), "{reasons}");
        assert!(printer_attr(&p, "printer-state-message").contains("cannot be reached"));
        let mut g = base();
        let idb = id.to_be_bytes();
        g.push((0x21, "job-id", &idb));
        let r = parse(p.handle_bytes(request(0x09, 4, &g, &[]), false));
        let j = r
            .attributes()
            .first_of(DelimiterTag::JobAttributes)
            .unwrap();
        assert_eq!(j.get("job-state").unwrap().value().to_string(), "3");
        assert_eq!(
            j.get("job-state-reasons").unwrap().value().to_string(),
            "resources-are-not-ready"
        );
        // Not tried again before its time.
        assert_eq!(p.wait_for_job(Duration::from_millis(100)), None);
        // A second job of the queue waits behind it.
        let second = print_job(&p, &png(1), "bob");
        assert_eq!(p.wait_for_job(Duration::from_millis(100)), None);
        // The printer comes back: the job is sent at its next try, then the next one.
        std::fs::create_dir(&out).unwrap();
        assert_eq!(p.wait_for_job(Duration::from_secs(3)), Some(id));
        p.process(id).unwrap();
        assert_eq!(p.wait_for_job(Duration::ZERO), Some(second));
        p.process(second).unwrap();
        assert_eq!(p.job_state(id).unwrap().0, JobState::Completed);
        assert_eq!(printer_attr(&p, "printer-state-reasons"), "none");
        let opts = p.config().queues[0].job_options(&[]).unwrap();
        let want = crate::convert_to_bytes(png(0), crate::Format::EscPos, &opts).unwrap();
        assert_eq!(
            std::fs::read(out.join(format!("job-{id}.escpos"))).unwrap(),
            want
        );
        // A document that cannot be halftoned still aborts.
        let mut bad = png(2);
        bad.truncate(40);
        let id = print_job(&p, &bad, "eve");
        assert_eq!(p.wait_for_job(Duration::ZERO), Some(id));
        assert!(p.process(id).is_err());
        assert_eq!(p.job_state(id).unwrap().0, JobState::Aborted);
        // The schedule.
        let s: Vec<u64> = (1..=8).map(|n| retry_delay(n).as_secs()).collect();
        assert_eq!(s, [1, 2, 4, 8, 16, 30, 30, 30]);
    }

    #[test]
    fn uris_follow_the_host_the_client_used() {
        let b = "0.0.0.0:8631";
        for (h, want) in [
            (Some("printer.local:8631"), "printer.local:8631"),
            (Some("Printer.Local."), "printer.local:8631"),
            (Some("192.168.1.5:631"), "192.168.1.5:631"),
            (Some("[fe80::1]:8631"), "[fe80::1]:8631"),
            (Some("[::1]"), "[::1]:8631"),
            (None, b),
            (Some(""), b),
            (Some("bad host:1"), b),
            (Some("a/b:1"), b),
            (Some("x:99999"), b),
            (Some("x:0"), b),
            (Some("[nonsense]:1"), b),
            (Some("-x.local:1"), b),
            (Some("x\"<y:1"), b),
        ] {
            assert_eq!(request_host(h, b), want, "{h:?}");
        }
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let r = p.handle_from(
            Some("printer.local:631"),
            &mut Cursor::new(request(0x0b, 1, &base(), &[])),
        );
        let r = parse(r.body);
        let g = r
            .attributes()
            .first_of(DelimiterTag::PrinterAttributes)
            .unwrap();
        assert_eq!(
            g.get("printer-uri-supported").unwrap().value().to_string(),
            "ipp://printer.local:631/ipp/print/receipt"
        );
        assert_eq!(
            g.get("printer-more-info").unwrap().value().to_string(),
            "http://printer.local:631/"
        );
    }

    #[test]
    fn get_printer_attributes_has_what_ipp_everywhere_asks() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let resp = p.handle_bytes(request(0x0b, 7, &base(), &[]), false);
        assert_eq!(status(&resp), 0);
        assert_eq!(i32::from_be_bytes([resp[4], resp[5], resp[6], resp[7]]), 7);
        let r = parse(resp);
        let g = r
            .attributes()
            .first_of(DelimiterTag::PrinterAttributes)
            .unwrap();
        for n in [
            "printer-uri-supported",
            "uri-security-supported",
            "uri-authentication-supported",
            "printer-name",
            "printer-state",
            "printer-state-reasons",
            "ipp-versions-supported",
            "operations-supported",
            "charset-supported",
            "document-format-supported",
            "media-supported",
            "media-default",
            "media-col-default",
            "printer-resolution-supported",
            "print-color-mode-supported",
            "print-quality-supported",
            "pwg-raster-document-resolution-supported",
            "copies-supported",
            "sides-supported",
        ] {
            assert!(g.get(n).is_some(), "{n} missing");
        }
        assert_eq!(g.get("printer-uri-supported").unwrap().value(), &uri(URI));
        // 384 dots at 203 dpi: a 48 mm roll.
        let media = value_text(g.get("media-default").unwrap().value()).unwrap();
        assert!(media.contains("48.05x"), "{media}");
        assert_eq!(
            g.get("printer-resolution-default").unwrap().value(),
            &IppValue::Resolution {
                cross_feed: 203,
                feed: 203,
                units: 3
            }
        );
    }

    #[test]
    fn requested_attributes_filter() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let mut ops = base();
        ops.push((0x44, "requested-attributes", b"printer-name"));
        let r = parse(p.handle_bytes(request(0x0b, 1, &ops, &[]), false));
        let g = r
            .attributes()
            .first_of(DelimiterTag::PrinterAttributes)
            .unwrap();
        assert_eq!(g.attributes().len(), 1);
    }

    #[test]
    fn malformed_requests_get_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let good = request(0x0b, 1, &base(), &[]);
        // Every truncation of a good request, and garbage.
        for n in 0..good.len() {
            let resp = p.handle_bytes(good[..n].to_vec(), false);
            assert_eq!(status(&resp), 0x0400, "truncated at {n}");
        }
        let mut seed = 12345u64;
        for _ in 0..2000 {
            let len = (seed % 200) as usize;
            let mut b = Vec::with_capacity(len);
            for _ in 0..len {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                b.push((seed >> 33) as u8);
            }
            let resp = p.handle_bytes(b, false);
            assert!(status(&resp) >= 0x0400, "garbage accepted");
        }
        // Bit flips of a good Print-Job.
        let png = crate::encode(
            &crate::convert(
                crate::Image::gray8(8, 8, vec![128; 64]),
                &crate::Options::default(),
            )
            .unwrap(),
            crate::Format::Png,
            &crate::Options::default(),
        )
        .unwrap();
        let mut job = request(0x02, 3, &base(), &[]);
        job.extend_from_slice(&png);
        for i in 0..job.len().min(300) {
            let mut b = job.clone();
            b[i] ^= 0x55;
            let _ = p.handle_bytes(b, false);
        }
    }

    #[test]
    fn bad_headers_and_groups() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        // request-id 0
        assert_eq!(
            status(&p.handle_bytes(request(0x0b, 0, &base(), &[]), false)),
            0x0400
        );
        // version 0.0
        let mut v0 = request(0x0b, 1, &base(), &[]);
        v0[0] = 0;
        assert_eq!(status(&p.handle_bytes(v0, false)), 0x0503);
        // natural language before charset
        let mut swapped = base();
        swapped.swap(0, 1);
        assert_eq!(
            status(&p.handle_bytes(request(0x0b, 1, &swapped, &[]), false)),
            0x0400
        );
        // no printer-uri
        let no_uri = &base()[..2];
        assert_eq!(
            status(&p.handle_bytes(request(0x0b, 1, no_uri, &[]), false)),
            0x0400
        );
        // unknown queue
        let mut other = base();
        other[2] = (0x45, "printer-uri", b"ipp://127.0.0.1:8631/ipp/print/nope");
        assert_eq!(
            status(&p.handle_bytes(request(0x0b, 1, &other, &[]), false)),
            0x0406
        );
        // unknown operation
        assert_eq!(
            status(&p.handle_bytes(request(0x0010, 1, &base(), &[]), false)),
            0x0501
        );
        // too long
        assert_eq!(
            status(&p.handle_bytes(request(0x02, 1, &base(), &[]), true)),
            0x0408
        );
    }

    #[test]
    fn print_job_to_a_folder_and_its_states() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let img = crate::Image::gray8(64, 32, (0..64 * 32).map(|i| (i % 64 * 4) as u8).collect());
        let png = crate::encode(
            &crate::convert(
                img,
                &crate::Options {
                    levels: 256,
                    ..Default::default()
                },
            )
            .unwrap(),
            crate::Format::Png,
            &crate::Options::default(),
        );
        let png = png.unwrap();
        let mut ops = base();
        ops.push((0x49, "document-format", b"image/png"));
        ops.push((0x42, "requesting-user-name", b"ann"));
        let mut req = request(0x02, 2, &ops, &[(0x44, "halftone-method", b"ordered")]);
        req.extend_from_slice(&png);
        let r = parse(p.handle_bytes(req, false));
        assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
        let j = r
            .attributes()
            .first_of(DelimiterTag::JobAttributes)
            .unwrap();
        let id = match j.get("job-id").unwrap().value() {
            IppValue::Integer(i) => *i,
            v => panic!("{v:?}"),
        };
        assert_eq!(p.wait_for_job(Duration::from_millis(10)), Some(id));
        p.process(id).unwrap();
        assert_eq!(p.job_state(id).unwrap().0, JobState::Completed);
        let got = std::fs::read(dir.path().join(format!("job-{id}.escpos"))).unwrap();
        let q = &p.config().queues[0];
        let opts = q
            .job_options(&[("method".into(), Value::from("ordered".to_string()))])
            .unwrap();
        let want = crate::convert_to_bytes(png.clone(), crate::Format::EscPos, &opts).unwrap();
        assert_eq!(got, want);
        // Cancelling a completed job is not possible.
        let mut c = base();
        c.push((0x21, "job-id", &[0, 0, 0, 1]));
        assert_eq!(
            status(&p.handle_bytes(request(0x08, 3, &c, &[]), false)),
            0x0404
        );
        // A method the table does not know is refused by name.
        let mut bad = request(0x02, 4, &ops, &[(0x44, "halftone-method", b"nonesuch")]);
        bad.extend_from_slice(&png);
        assert_eq!(status(&p.handle_bytes(bad, false)), 0x040b);
        // Not an image.
        let mut junk = request(0x02, 5, &base(), &[]);
        junk.extend_from_slice(b"%!PS-Adobe-3.0\n");
        assert_eq!(status(&p.handle_bytes(junk, false)), 0x040a);
    }

    #[test]
    fn create_job_send_document_and_cancel() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let r = parse(p.handle_bytes(request(0x05, 1, &base(), &[]), false));
        assert_eq!(r.header().operation_or_status, 0);
        let mut ops = base();
        ops.push((0x21, "job-id", &[0, 0, 0, 1]));
        // Send-Document without last-document is a bad request.
        let mut sd = request(0x06, 2, &ops, &[]);
        sd.extend_from_slice(b"\x89PNG\r\n\x1a\n");
        assert_eq!(status(&p.handle_bytes(sd, false)), 0x0400);
        assert_eq!(
            status(&p.handle_bytes(request(0x08, 3, &ops, &[]), false)),
            0
        );
        assert_eq!(p.job_state(1).unwrap().0, JobState::Canceled);
        assert_eq!(p.wait_for_job(Duration::from_millis(1)), None);
    }

    /// A PWG raster file of sgray_8 pages, each stored as literal runs of one line each.
    fn pwg(pages: &[&crate::Image]) -> Vec<u8> {
        let mut f = b"RaS2".to_vec();
        for img in pages {
            let mut hd = vec![0u8; 1796];
            let mut put = |at: usize, v: u32| hd[at..at + 4].copy_from_slice(&v.to_be_bytes());
            put(276, 203);
            put(280, 203);
            put(372, img.width as u32);
            put(376, img.height as u32);
            put(384, 8);
            put(388, 8);
            put(392, img.width as u32);
            put(400, 18);
            f.extend(hd);
            let crate::raster::Samples::U8(v) = &img.planes[0] else {
                panic!()
            };
            for row in v.chunks(img.width) {
                f.push(0);
                for run in row.chunks(128) {
                    f.push((257 - run.len()) as u8);
                    f.extend_from_slice(run);
                }
            }
        }
        f
    }

    #[test]
    fn a_job_past_the_page_or_time_limit_is_aborted_saying_which() {
        let dir = tempfile::tempdir().unwrap();
        let with = |limits: Limits| {
            let p = printer(dir.path());
            Printer::new(p.config().clone(), "127.0.0.1:8631", limits)
        };
        let mut page = crate::Image::gray8(16, 8, vec![100; 16 * 8]);
        page.dpi = Some(203.0);
        let run = |p: &Printer, pages: usize| -> (JobState, String) {
            let mut ops = base();
            ops.push((0x49, "document-format", b"image/pwg-raster"));
            let mut req = request(0x02, 2, &ops, &[]);
            req.extend_from_slice(&pwg(&vec![&page; pages]));
            let r = parse(p.handle_bytes(req, false));
            assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
            let id = p.wait_for_job(Duration::from_millis(10)).unwrap();
            let _ = p.process(id);
            p.job_state(id).unwrap()
        };
        let two = with(Limits {
            max_pages: 2,
            ..Limits::default()
        });
        assert_eq!(run(&two, 2).0, JobState::Completed);
        let (state, msg) = run(&two, 3);
        assert_eq!(state, JobState::Aborted);
        assert!(
            msg.contains("more than 2 pages") && msg.contains("--max-pages"),
            "{msg}"
        );
        let (state, msg) = run(
            &with(Limits {
                max_job_seconds: 0,
                ..Limits::default()
            }),
            1,
        );
        assert_eq!(state, JobState::Aborted);
        assert!(
            msg.contains("longer than 0 s") && msg.contains("--max-job-seconds"),
            "{msg}"
        );
    }

    #[test]
    fn pwg_pages_page_ranges_and_overrides() {
        let dir = tempfile::tempdir().unwrap();
        let p = printer(dir.path());
        let mut a = crate::Image::gray8(64, 32, (0..64 * 32).map(|i| (i % 64 * 4) as u8).collect());
        let mut b = crate::Image::gray8(64, 32, vec![128; 64 * 32]);
        a.dpi = Some(203.0);
        b.dpi = Some(203.0);
        let doc = pwg(&[&a, &b]);
        let q = &p.config().queues[0];
        // What the library writes for these pages, each with its own options.
        let book = |pages: &[(&crate::Image, &[(String, Value<'static>)])]| {
            let base = q.job_options(&[]).unwrap();
            let mut enc = crate::io::page_encoder(&base.write_options(q.format));
            let mut out = Vec::new();
            for (img, s) in pages {
                let conv = Converter::new(&q.job_options(s).unwrap()).unwrap();
                conv.add_page(
                    (*img).clone(),
                    q.format,
                    enc.as_mut(),
                    &mut out,
                    std::path::Path::new("x"),
                )
                .unwrap();
            }
            enc.finish(&mut out).unwrap();
            out
        };
        let run = |job: &[(u8, &str, &[u8])]| -> (Vec<u8>, i32) {
            let mut ops = base();
            ops.push((0x49, "document-format", b"image/pwg-raster"));
            let mut req = request(0x02, 2, &ops, job);
            req.extend_from_slice(&doc);
            let r = parse(p.handle_bytes(req, false));
            assert_eq!(r.header().operation_or_status, 0, "{:?}", r.attributes());
            let id = p.wait_for_job(Duration::from_millis(10)).unwrap();
            p.process(id).unwrap();
            let got = std::fs::read(dir.path().join(format!("job-{id}.escpos"))).unwrap();
            (got, id)
        };
        let none: &[(String, Value<'static>)] = &[];
        let (got, id) = run(&[]);
        assert_eq!(got, book(&[(&a, none), (&b, none)]));
        let st = p.lock();
        assert_eq!(st.jobs.iter().find(|j| j.id == id).unwrap().pages, 2);
        drop(st);
        let range2 = [0, 0, 0, 2, 0, 0, 0, 2];
        let (got, _) = run(&[(0x33, "page-ranges", &range2)]);
        assert_eq!(got, book(&[(&b, none)]));
        // Page 2 at print-quality high (DBS), page 1 as the queue says.
        let (got, _) = run(&[
            (0x34, "overrides", b""),
            (0x4a, "", b"pages"),
            (0x33, "", &range2),
            (0x4a, "", b"print-quality"),
            (0x23, "", &[0, 0, 0, 5]),
            (0x37, "", b""),
        ]);
        let dbs: &[(String, Value<'static>)] = &[("method".into(), Value::from("dbs".to_string()))];
        assert_eq!(got, book(&[(&a, none), (&b, dbs)]));
        assert_ne!(got, book(&[(&a, none), (&b, none)]));
        // An override that does not map is refused by name.
        let mut ops = base();
        ops.push((0x49, "document-format", b"image/pwg-raster"));
        let mut req = request(
            0x02,
            3,
            &ops,
            &[
                (0x34, "overrides", b""),
                (0x4a, "", b"halftone-method"),
                (0x44, "", b"nonesuch"),
                (0x37, "", b""),
            ],
        );
        req.extend_from_slice(&doc);
        assert_eq!(status(&p.handle_bytes(req, false)), 0x040b);
        // A truncated raster: the job aborts with the decoder's one line.
        let mut ops = base();
        ops.push((0x49, "document-format", b"image/pwg-raster"));
        let mut req = request(0x02, 4, &ops, &[]);
        req.extend_from_slice(&doc[..doc.len() - 10]);
        assert_eq!(status(&p.handle_bytes(req, false)), 0);
        let id = p.wait_for_job(Duration::from_millis(10)).unwrap();
        let e = p.process(id).unwrap_err();
        assert!(e.contains("page 2: truncated in line 32 of 32"), "{e}");
        assert_eq!(p.job_state(id).unwrap().0, JobState::Aborted);
        // Data that is not what document-format says.
        let mut req = request(0x02, 5, &ops, &[]);
        req.extend_from_slice(b"UNIRAST\0\0\0\0\0");
        assert_eq!(status(&p.handle_bytes(req, false)), 0x0411);
    }
}
