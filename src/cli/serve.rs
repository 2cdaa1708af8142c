//! `halftone serve`: an IPP Everywhere printer. The library answers the IPP requests and
//! processes the jobs (`halftone::serve`); this file is the process around it: the HTTP
//! server and its threads, the worker that prints, and the log lines.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{bail, Context};
use clap::Args;

use halftone::serve::dnssd::Advertiser;
use halftone::serve::printer::request_host;
use halftone::serve::spool::Spool;
use halftone::serve::{Backend, Config, JobState, Limits, Printer, Queue};

use super::convert::FormatArg;
use super::option_args::CommonArgs;

pub const EXAMPLES: &str = "Examples:
  halftone serve --queue receipt --preset thermal-203 --backend socket://192.168.1.50:9100
  halftone serve --queue receipt --preset thermal-203 --backend file:///tmp/jobs   # a file a job
  halftone serve --config queues.toml --listen 0.0.0.0:631   # several queues (docs/serve.md)
  halftone serve --queue lab --preset label-203 --backend /dev/usb/lp0 --no-dnssd   # unlisted
  halftone serve --config queues.toml --spool /var/spool/halftone   # jobs kept across restarts";

/// `halftone serve` arguments.
#[derive(Args, Debug)]
pub struct ServeArgs {
    /// A queue file: one [queue.NAME] table a queue (backend, format, preset and options by
    /// the names `convert` takes); see docs/serve.md. Without it, the flags make one queue.
    #[arg(long, short = 'c', value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// Address to listen on (localhost unless told otherwise; port 0: any free port).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8631")]
    pub listen: String,

    /// Port to listen on (replaces the port of --listen).
    #[arg(long, value_name = "PORT")]
    pub port: Option<u16>,

    /// The single queue's name: ipp://HOST:PORT/ipp/print/NAME.
    #[arg(long, value_name = "NAME", default_value = "halftone")]
    pub queue: String,

    /// The single queue's backend: file:///FOLDER (one file a job), socket://HOST[:9100]
    /// (AppSocket) or a device path such as /dev/usb/lp0.
    #[arg(long, value_name = "URI")]
    pub backend: Option<String>,

    /// The single queue's printer language (default: the preset's).
    #[arg(long, short = 'f', value_enum)]
    pub format: Option<FormatArg>,

    /// The single queue's name in print dialogs (DNS-SD); default "halftone NAME @ HOST".
    #[arg(long, value_name = "NAME")]
    pub dnssd_name: Option<String>,

    /// Do not advertise the queues over DNS-SD (mDNS). A server on 127.0.0.1 or ::1 is
    /// advertised on the loopback interface only; on 0.0.0.0, on every interface.
    #[arg(long)]
    pub no_dnssd: bool,

    /// Largest request accepted (IPP attributes and document), in MiB.
    #[arg(long, value_name = "MIB", default_value_t = 64)]
    pub max_request_mib: u64,

    /// Folder where each job waits on disk until it is printed, so a restart prints it (once).
    /// Default: $XDG_STATE_HOME/halftone/spool/PORT (~/.local/state/…); none with port 0.
    #[arg(long, value_name = "DIR")]
    pub spool: Option<PathBuf>,

    /// Jobs kept (finished ones are dropped oldest first); more waiting jobs than this get
    /// server-error-busy.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub max_jobs: usize,

    /// Pages one job may have; a document with more is aborted with a message saying so.
    #[arg(long, value_name = "N", default_value_t = 500)]
    pub max_pages: usize,

    /// Seconds one job may spend being halftoned (checked before each page); past it the job
    /// is aborted with a message saying so.
    #[arg(long, value_name = "SECONDS", default_value_t = 600)]
    pub max_job_seconds: u64,

    #[command(flatten)]
    pub common: CommonArgs,
}

/// Requests handled at once; more wait in the HTTP server's queue.
const MAX_IN_FLIGHT: usize = 16;

pub fn run(a: ServeArgs) -> anyhow::Result<ExitCode> {
    let config = match &a.config {
        Some(path) => {
            if a.backend.is_some()
                || a.format.is_some()
                || a.dnssd_name.is_some()
                || !a.common.given_entries().is_empty()
            {
                bail!(
                    "{}: give the queues' options in the file, or one queue's by flags, not both",
                    path.display()
                );
            }
            Config::load(path)?
        }
        None => {
            let Some(backend) = &a.backend else {
                bail!(
                    "give --backend (file:///DIR, socket://HOST:9100 or a device) or --config FILE"
                );
            };
            let backend = Backend::parse(backend).map_err(|e| anyhow::anyhow!("--backend {e}"))?;
            let mut entries = a.common.given_entries();
            if let Some(f) = a.format {
                entries.push(("format".into(), f.0.name().to_string().into()));
            }
            let mut q = Queue::new(&a.queue, entries, backend)
                .map_err(|e| anyhow::anyhow!(super::flags_for_options(&e.to_string())))?;
            if let Some(name) = &a.dnssd_name {
                if name.trim().is_empty() {
                    bail!("--dnssd-name: give a name such as \"Office printer\"");
                }
                q.dnssd_name = Some(name.trim().to_string());
            }
            Config {
                queues: vec![q],
                spool: None,
            }
        }
    };
    let mut addr: SocketAddr = a.listen.parse().with_context(|| {
        format!(
            "--listen {}: expected HOST:PORT such as 127.0.0.1:8631",
            a.listen
        )
    })?;
    if let Some(p) = a.port {
        addr.set_port(p);
    }
    let server = tiny_http::Server::http(addr)
        .map_err(|e| anyhow::anyhow!("cannot listen on {addr}: {e}"))?;
    let bound = server
        .server_addr()
        .to_ip()
        .context("the server has no IP address")?;
    let limits = Limits {
        max_request: a.max_request_mib.saturating_mul(1 << 20),
        max_jobs: a.max_jobs.max(1),
        max_pages: a.max_pages.max(1),
        max_job_seconds: a.max_job_seconds.max(1),
    };
    let spool_dir = a
        .spool
        .clone()
        .or_else(|| config.spool.clone())
        .or_else(|| default_spool(addr.port()));
    let mut printer = Printer::new(config, &bound.to_string(), limits);
    if let Some(dir) = &spool_dir {
        let spool = Spool::open(dir)?;
        for line in printer.recover(spool)? {
            eprintln!("halftone: {line}");
        }
    }
    let printer = Arc::new(printer);
    {
        // Best effort: a server does not stop because its standard output was closed.
        let mut out = std::io::stdout().lock();
        for q in &printer.config().queues {
            let _ = writeln!(
                out,
                "halftone: serving {} ({} to {})",
                printer.queue_uri(q),
                q.format.name(),
                q.backend.uri()
            );
        }
        let _ = match &spool_dir {
            Some(d) => writeln!(out, "halftone: jobs spooled in {}", d.display()),
            None => writeln!(
                out,
                "halftone: no spool (port 0 and no --spool): jobs are kept in memory only"
            ),
        };
        let _ = out.flush();
    }
    if !a.no_dnssd {
        // Kept for as long as the server runs; the interrupt handler withdraws it.
        let adv = advertise(&printer, bound);
        *ADVERTISER.lock().unwrap_or_else(|p| p.into_inner()) = adv;
    }
    let worker = Arc::clone(&printer);
    std::thread::spawn(move || loop {
        if let Some(id) = worker.wait_for_job(Duration::from_secs(1)) {
            match worker.process(id) {
                Ok(to) => eprintln!("halftone: job {id}: printed to {to}"),
                Err(e) => match worker.job_state(id) {
                    Some((JobState::Pending, _)) => eprintln!("halftone: job {id} waits: {e}"),
                    _ => eprintln!("halftone: job {id}: {e}"),
                },
            }
        }
    });
    let icon = Arc::new(icon_png());
    let in_flight = Arc::new(AtomicUsize::new(0));
    for request in server.incoming_requests() {
        if in_flight.load(Ordering::SeqCst) >= MAX_IN_FLIGHT {
            let _ = request.respond(tiny_http::Response::empty(503));
            continue;
        }
        in_flight.fetch_add(1, Ordering::SeqCst);
        let printer = Arc::clone(&printer);
        let icon = Arc::clone(&icon);
        let count = Arc::clone(&in_flight);
        std::thread::spawn(move || {
            // Given back however the thread ends: a request whose handling panicked must
            // not hold its place, or 16 of them would leave every later client a 503.
            let _slot = Slot(count);
            answer(&printer, &icon, request);
        });
    }
    Ok(ExitCode::SUCCESS)
}

/// One of the [`MAX_IN_FLIGHT`] places, given back when dropped.
struct Slot(Arc<AtomicUsize>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The running DNS-SD advertisement, withdrawn (goodbye packets: browsers drop the
/// printer at once rather than when its records expire) by [`withdraw_adverts`].
static ADVERTISER: Mutex<Option<Advertiser>> = Mutex::new(None);

/// Withdraws the queues' DNS-SD services, if any (the interrupt handler calls it before the
/// process exits).
pub fn withdraw_adverts() {
    let adv = ADVERTISER.lock().unwrap_or_else(|p| p.into_inner()).take();
    drop(adv);
}

/// Advertises the queues over DNS-SD; a failure is a warning, the server runs on without.
fn advertise(printer: &Printer, bound: SocketAddr) -> Option<Advertiser> {
    match Advertiser::start(printer, bound) {
        Ok(adv) => {
            let mut out = std::io::stdout().lock();
            for (ad, _) in adv.services() {
                let _ = writeln!(
                    out,
                    "halftone: advertising \"{}\" (_ipp._tcp, _print) on {}",
                    ad.instance,
                    adv.reach().describe()
                );
            }
            let _ = out.flush();
            Some(adv)
        }
        Err(e) => {
            eprintln!("halftone: warning: {e}; the queues are not advertised");
            None
        }
    }
}

/// The default spool folder for a server on `port`: `$XDG_STATE_HOME/halftone/spool/PORT`
/// (else `$HOME/.local/state/…`); none for port 0 (a new port each start: nothing to take
/// back) or without a home.
fn default_spool(port: u16) -> Option<PathBuf> {
    if port == 0 {
        return None;
    }
    let state = std::env::var_os("XDG_STATE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|v| !v.is_empty())
                .map(|h| PathBuf::from(h).join(".local/state"))
        })?;
    Some(state.join("halftone/spool").join(port.to_string()))
}

/// Answers one HTTP request: IPP on POST, the status page and icon on GET.
fn answer(printer: &Printer, icon: &[u8], mut request: tiny_http::Request) {
    let header = |k: &str, v: &str| {
        tiny_http::Header::from_bytes(k.as_bytes(), v.as_bytes()).expect("valid header")
    };
    let url = request.url().to_string();
    let host_header = request
        .headers()
        .iter()
        .find(|h| h.field.equiv("Host"))
        .map(|h| h.value.as_str().to_string());
    let host = request_host(host_header.as_deref(), printer.host());
    let response = match request.method() {
        tiny_http::Method::Post => {
            let ipp = request.headers().iter().any(|h| {
                h.field.equiv("Content-Type") && h.value.as_str().starts_with("application/ipp")
            });
            if !ipp {
                let _ = request.respond(tiny_http::Response::empty(400));
                return;
            }
            let announced = request.body_length();
            let mut body = Exact {
                inner: request.as_reader(),
                left: announced,
            };
            let r = printer.handle_from(Some(&host), &mut body);
            let mut resp = tiny_http::Response::from_data(r.body)
                .with_header(header("Content-Type", "application/ipp"));
            if r.close {
                resp = resp.with_header(header("Connection", "close"));
            }
            resp
        }
        tiny_http::Method::Get | tiny_http::Method::Head if url == "/icon.png" => {
            tiny_http::Response::from_data(icon.to_vec())
                .with_header(header("Content-Type", "image/png"))
        }
        tiny_http::Method::Get | tiny_http::Method::Head if url == "/" => {
            tiny_http::Response::from_data(status_page(printer, &host).into_bytes())
                .with_header(header("Content-Type", "text/plain; charset=utf-8"))
        }
        _ => tiny_http::Response::from_data(b"not found\n".to_vec()).with_status_code(404),
    };
    let _ = request.respond(response);
}

/// Jobs the status page lists, newest first.
const PAGE_JOBS: usize = 50;

/// A request body that must be as long as its Content-Length: ending early is an error,
/// not a shorter request.
struct Exact<R> {
    inner: R,
    left: Option<usize>,
}

impl<R: std::io::Read> std::io::Read for Exact<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        if let Some(left) = &mut self.left {
            if n == 0 && !buf.is_empty() && *left > 0 {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    format!("the body ended {left} bytes before its Content-Length"),
                ));
            }
            *left = left.saturating_sub(n);
        }
        Ok(n)
    }
}

/// A plain-text page: the queues, their printers, backends and state, then the recent jobs
/// with state, pages, method and time. Read-only.
fn status_page(printer: &Printer, host: &str) -> String {
    let mut s = String::from("halftone serve\n\n");
    for (i, q) in printer.config().queues.iter().enumerate() {
        s.push_str(&format!(
            "ipp://{host}/ipp/print/{}\n  {} {} dpi, method {}\n  backend {}\n",
            q.name,
            q.format.name(),
            q.options.dpi.unwrap_or(0.0),
            q.options.method.name(),
            q.backend.uri()
        ));
        if let Some(why) = printer.queue_down(i) {
            s.push_str(&format!("  offline: {}\n", one_line(&why)));
        }
    }
    let jobs = printer.jobs();
    s.push_str(&format!(
        "\nrecent jobs ({} of {}, newest first)\n",
        jobs.len().min(PAGE_JOBS),
        jobs.len()
    ));
    s.push_str("  id  queue  state  pages  method  created (UTC)  name  user  message\n");
    for j in jobs.iter().take(PAGE_JOBS) {
        let state = match j.state {
            JobState::Pending => "pending",
            JobState::PendingHeld => "held",
            JobState::Processing => "processing",
            JobState::Canceled => "canceled",
            JobState::Aborted => "aborted",
            JobState::Completed => "completed",
        };
        s.push_str(&format!(
            "  {}  {}  {}  {}  {}  {}  {}  {}  {}\n",
            j.id,
            j.queue,
            state,
            j.pages,
            j.method.as_deref().unwrap_or("-"),
            utc(j.created),
            one_line(&j.name),
            one_line(&j.user),
            one_line(&j.message)
        ));
    }
    s
}

/// Text from a client on one line: control characters become spaces.
fn one_line(t: &str) -> String {
    t.chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect()
}

/// `YYYY-MM-DD HH:MM:SS` for seconds since the Unix epoch (UTC).
fn utc(secs: u64) -> String {
    let t = halftone::serve::attributes::date_time(secs);
    format!(
        "{:04}-{:02}-{:02} {:02}:{:02}:{:02}",
        t.year, t.month, t.day, t.hour, t.minutes, t.seconds
    )
}

/// The printer's icon: a grey ramp halftoned by the library (128×128 PNG).
fn icon_png() -> Vec<u8> {
    let ramp: Vec<u8> = (0..128 * 128).map(|i| ((i % 128) * 2) as u8).collect();
    let opts = halftone::Options::default();
    halftone::convert_to_bytes(
        halftone::Image::gray8(128, 128, ramp),
        halftone::Format::Png,
        &opts,
    )
    .unwrap_or_default()
}
