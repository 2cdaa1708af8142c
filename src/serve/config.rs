//! Print queues: their printer (a preset or options by the names `convert` takes), their
//! output language and their backend, from a TOML file or from one set of flags.
//!
//! ```toml
//! [queue.receipt]
//! preset = "thermal-203"          # any option by its one name, as `convert` takes them
//! kernel = "floyd-steinberg"
//! format = "escpos"               # the printer's language (else the preset's)
//! backend = "socket://192.168.1.50:9100"
//!
//! [queue.labels]
//! preset = "label-203"
//! backend = "file:///var/spool/halftone/labels"
//! dnssd_name = "Shipping labels"  # the name print dialogs show (DNS-SD); dnssd = false: none
//! ```

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::Format;
use crate::options::table::find;
use crate::options::value::Value;
use crate::options::{Options, Settings};

/// Where a queue's jobs go once halftoned.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Backend {
    /// A folder: one file a job, written atomically (a temporary file, then a rename).
    Folder(PathBuf),
    /// A device file (`/dev/usb/lp0`) or any other path, written straight.
    Device(PathBuf),
    /// A raw TCP printer port (AppSocket / JetDirect, usually port 9100): `host:port`.
    Socket(String),
    /// Another IPP printer (`ipp://HOST[:PORT]/PATH`): each job sent with Print-Job in a
    /// format it lists (see [`super::client`]).
    Ipp(super::client::Target),
}

impl Backend {
    /// Parses `file:///folder`, `socket://host[:port]`, `ipp://host[:port]/path` or a
    /// device path (`/dev/usb/lp0`).
    pub fn parse(text: &str) -> std::result::Result<Backend, String> {
        let text = text.trim();
        if text.starts_with("ipp://") || text.starts_with("ipps://") {
            return super::client::Target::parse(text).map(Backend::Ipp);
        }
        if let Some(path) = text.strip_prefix("file://") {
            if path.is_empty() {
                return Err("file:// needs a folder: file:///var/spool/halftone".into());
            }
            return Ok(Backend::Folder(PathBuf::from(path)));
        }
        if let Some(rest) = text.strip_prefix("socket://") {
            let host = rest.trim_end_matches('/');
            if host.is_empty() || host.contains('/') {
                return Err(format!("'{text}': expected socket://HOST[:PORT]"));
            }
            let addr = if host
                .rsplit_once(':')
                .is_some_and(|(_, p)| p.parse::<u16>().is_ok())
                && !host.ends_with(']')
            {
                host.to_string()
            } else {
                format!("{host}:9100")
            };
            return Ok(Backend::Socket(addr));
        }
        if text.contains("://") {
            return Err(format!(
                "'{text}': unknown backend; expected file:///FOLDER, socket://HOST:PORT, \
                 ipp://HOST:PORT/PATH or a device path such as /dev/usb/lp0"
            ));
        }
        if text.is_empty() {
            return Err("empty backend".into());
        }
        Ok(Backend::Device(PathBuf::from(text)))
    }

    /// The backend as it is written in a queue file.
    pub fn uri(&self) -> String {
        match self {
            Backend::Folder(p) => format!("file://{}", p.display()),
            Backend::Device(p) => p.display().to_string(),
            Backend::Socket(a) => format!("socket://{a}"),
            Backend::Ipp(t) => t.uri.clone(),
        }
    }
}

/// One print queue: its name (the last part of `ipp://HOST:PORT/ipp/print/NAME`), its
/// option values as given (re-applied through [`Settings`] for every job, the job's own
/// attributes on top), the options they make, its output language and its backend.
#[derive(Clone, Debug)]
pub struct Queue {
    /// The queue's name.
    pub name: String,
    /// The option values given (`preset` among them), by their one names, in order.
    pub entries: Vec<(String, Value<'static>)>,
    /// The options made from `entries` (the preset filling in the rest).
    pub options: Options,
    /// The printer's language.
    pub format: Format,
    /// Where the halftoned jobs go.
    pub backend: Backend,
    /// Advertised over DNS-SD (`dnssd = false` in a queue file turns it off).
    pub dnssd: bool,
    /// The DNS-SD instance name print dialogs show (`dnssd_name`; default `halftone NAME @
    /// HOST`).
    pub dnssd_name: Option<String>,
}

impl Queue {
    /// A queue from option values (`preset`, `format` and any option by its one name) and a
    /// backend; the values go through [`Settings`] as every door's do. An error names the
    /// offending key.
    pub fn new(
        name: &str,
        entries: Vec<(String, Value<'static>)>,
        backend: Backend,
    ) -> Result<Queue> {
        check_name(name)?;
        let mut settings = Settings::new();
        for (key, value) in &entries {
            settings.set_value(key, value).map_err(|e| keyed(key, e))?;
        }
        let given = settings.given();
        let options = settings.finish()?;
        let format = options.format.ok_or_else(|| {
            Error::Invalid(
                "format: no output language given and the preset names none (escpos, zpl, pcl, \
                 ps, pdf, png, pbm…)"
                    .into(),
            )
        })?;
        options.check_used(&given, Some(format))?;
        Ok(Queue {
            name: name.to_string(),
            entries,
            options,
            format,
            backend,
            dnssd: true,
            dnssd_name: None,
        })
    }

    /// The options for one job: the queue's values, then the job's own (names and values
    /// mapped from its IPP attributes), then the preset for the rest: one [`Settings`].
    pub fn job_options(&self, job: &[(String, Value<'static>)]) -> Result<Options> {
        let mut settings = Settings::new();
        for (key, value) in self.entries.iter().chain(job) {
            settings.set_value(key, value)?;
        }
        let mut o = settings.finish()?;
        o.format = Some(self.format);
        Ok(o)
    }
}

/// Queue names are one path segment of a URI: letters, digits, `-`, `_`, `.`.
fn check_name(name: &str) -> Result<()> {
    if name.is_empty()
        || name.len() > 127
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
    {
        return Err(Error::Invalid(format!(
            "queue name '{name}': use letters, digits, '-', '_' or '.' (it is part of the URI)"
        )));
    }
    Ok(())
}

/// An option error with the key it came from in front, unless it names it already.
fn keyed(key: &str, e: Error) -> Error {
    match e {
        Error::Option { .. } => e,
        other => Error::Invalid(format!("`{}`: {other}", key.replace('-', "_"))),
    }
}

/// The queues of a server.
#[derive(Clone, Debug, Default)]
pub struct Config {
    /// The queues, in the file's order.
    pub queues: Vec<Queue>,
    /// The spool folder (`spool = "DIR"` at the file's top level; relative to the file).
    pub spool: Option<PathBuf>,
}

impl Config {
    /// Reads a queue file: one `[queue.NAME]` table a queue, each with a `backend` and the
    /// printer's options. An error is one line naming the file and the key.
    pub fn load(path: &Path) -> Result<Config> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut c =
            Config::parse(&text).map_err(|e| Error::Invalid(format!("{}: {e}", path.display())))?;
        if let Some(s) = &c.spool {
            c.spool = Some(path.parent().unwrap_or(Path::new(".")).join(s));
        }
        Ok(c)
    }

    /// Parses the text of a queue file (see [`Config::load`]).
    pub fn parse(text: &str) -> Result<Config> {
        let doc: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| Error::Invalid(one_line(&e.to_string())))?;
        let mut queues = Vec::new();
        let mut spool = None;
        for (key, value) in &doc {
            if key == "spool" {
                match value.as_str().map(str::trim) {
                    Some(s) if !s.is_empty() => spool = Some(PathBuf::from(s)),
                    _ => {
                        return Err(Error::Invalid(
                            "`spool`: expected a folder such as \"/var/spool/halftone\"".into(),
                        ))
                    }
                }
                continue;
            }
            if key != "queue" {
                return Err(Error::Invalid(format!(
                    "`{key}`: unknown table; queues are [queue.NAME] tables"
                )));
            }
            let Some(table) = value.as_table() else {
                return Err(Error::Invalid(
                    "`queue`: expected [queue.NAME] tables".into(),
                ));
            };
            for (name, q) in table {
                let Some(q) = q.as_table() else {
                    return Err(Error::Invalid(format!(
                        "`queue.{name}`: expected a table of options"
                    )));
                };
                queues.push(queue_from_table(name, q).map_err(|e| match e {
                    Error::Option { field, value, msg } => {
                        Error::Invalid(format!("queue.{name}.{field}: {value}: {msg}"))
                    }
                    other => Error::Invalid(format!("queue.{name}: {other}")),
                })?);
            }
        }
        if queues.is_empty() {
            return Err(Error::Invalid("no queues: add a [queue.NAME] table".into()));
        }
        Ok(Config { queues, spool })
    }

    /// The queue called `name`.
    pub fn queue(&self, name: &str) -> Option<&Queue> {
        self.queues.iter().find(|q| q.name == name)
    }
}

/// A queue from its TOML table.
fn queue_from_table(name: &str, table: &toml::Table) -> Result<Queue> {
    let mut backend = None;
    let mut dnssd = true;
    let mut dnssd_name = None;
    let mut entries = Vec::new();
    for (key, value) in table {
        let k = key.replace('-', "_");
        if k == "dnssd" {
            dnssd = value.as_bool().ok_or_else(|| {
                Error::Invalid("`dnssd`: expected true or false (advertise the queue)".into())
            })?;
            continue;
        }
        if k == "dnssd_name" {
            let name = value.as_str().map(str::trim).unwrap_or("");
            if name.is_empty() {
                return Err(Error::Invalid(
                    "`dnssd_name`: expected a name such as \"Office printer\"".into(),
                ));
            }
            dnssd_name = Some(name.to_string());
            continue;
        }
        if k == "backend" {
            let text = value.as_str().ok_or_else(|| {
                Error::Invalid("`backend`: expected a string such as \"file:///DIR\"".into())
            })?;
            backend =
                Some(Backend::parse(text).map_err(|e| Error::Invalid(format!("`backend`: {e}")))?);
            continue;
        }
        if k != "preset" && k != "presets" && find(&k).is_none() {
            // Through Settings for its message (the nearest name).
            let mut s = Settings::new();
            s.set_value(&k, &Value::from_toml(value))?;
        }
        entries.push((k, Value::from_toml(value)));
    }
    let backend = backend.ok_or_else(|| {
        Error::Invalid("`backend`: missing (file:///DIR, socket://HOST:9100 or a device)".into())
    })?;
    let mut q = Queue::new(name, entries, backend)?;
    q.dnssd = dnssd;
    q.dnssd_name = dnssd_name;
    Ok(q)
}

/// The first line of a multi-line message (toml's errors quote the line with a caret).
fn one_line(msg: &str) -> String {
    let mut lines = msg.lines().filter(|l| !l.trim().is_empty());
    let first = lines.next().unwrap_or("").trim().to_string();
    // toml puts the location first ("TOML parse error at line 3, column 9") and the reason
    // last.
    match msg.lines().map(str::trim).rfind(|l| !l.is_empty()) {
        Some(last) if last != first => format!("{first}: {last}"),
        _ => first,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backends_parse() {
        assert_eq!(
            Backend::parse("file:///tmp/x"),
            Ok(Backend::Folder("/tmp/x".into()))
        );
        assert_eq!(
            Backend::parse("socket://printer.local"),
            Ok(Backend::Socket("printer.local:9100".into()))
        );
        assert_eq!(
            Backend::parse("socket://10.0.0.5:9101"),
            Ok(Backend::Socket("10.0.0.5:9101".into()))
        );
        assert_eq!(
            Backend::parse("/dev/usb/lp0"),
            Ok(Backend::Device("/dev/usb/lp0".into()))
        );
        assert!(Backend::parse("lpd://x").is_err());
        let ipp = Backend::parse("ipp://127.0.0.1:8000/ipp/print").unwrap();
        assert_eq!(ipp.uri(), "ipp://127.0.0.1:8000/ipp/print");
        assert!(Backend::parse("ipps://p/ipp/print")
            .unwrap_err()
            .contains("TLS"));
        assert!(Backend::parse("file://").is_err());
    }

    #[test]
    fn a_queue_file_goes_through_settings() {
        let c = Config::parse(
            "[queue.receipt]\npreset = \"thermal-203\"\nkernel = \"floyd-steinberg\"\n\
             backend = \"file:///tmp/r\"\n\n[queue.labels]\npreset = \"label-203\"\n\
             backend = \"socket://lp:9100\"\n",
        )
        .unwrap();
        let r = c.queue("receipt").unwrap();
        assert_eq!(r.format, Format::EscPos);
        assert_eq!(r.options.kernel, "floyd-steinberg");
        assert_eq!(r.options.print.paper_width, Some(384));
        let l = c.queue("labels").unwrap();
        assert_eq!(l.format, Format::Zpl);
        assert_eq!(l.backend, Backend::Socket("lp:9100".into()));
    }

    #[test]
    fn bad_queue_files_name_the_key() {
        let err = |t: &str| Config::parse(t).unwrap_err().to_string();
        let e =
            err("[queue.a]\npreset = \"thermal-203\"\nkernl = \"x\"\nbackend = \"file:///t\"\n");
        assert!(
            e.contains("queue.a") && e.contains("kernl") && e.contains("kernel"),
            "{e}"
        );
        let e = err("[queue.a]\npreset = \"thermal-203\"\nlevels = 1\nbackend = \"file:///t\"\n");
        assert!(e.starts_with("queue.a.levels: 1:"), "{e}");
        let e = err("[queue.a]\npreset = \"thermal-203\"\n");
        assert!(e.contains("queue.a") && e.contains("backend"), "{e}");
        let e = err("[queue.a]\npreset = \"no-such\"\nbackend = \"file:///t\"\n");
        assert!(e.contains("queue.a") && e.contains("no-such"), "{e}");
        let e = err("[queue.a]\nbackend = \"file:///t\"\n");
        assert!(e.contains("format"), "{e}");
        let e = err("[printer]\nx = 1\n");
        assert!(e.contains("printer"), "{e}");
        let e = err("[queue.a\n");
        assert!(!e.contains('\n'), "{e}");
        assert!(err("").contains("no queues"));
        let e =
            err("[queue.a]\npreset = \"thermal-203\"\ndnssd = \"no\"\nbackend = \"file:///t\"\n");
        assert!(e.starts_with("queue.a: `dnssd`"), "{e}");
        let e =
            err("[queue.a]\npreset = \"thermal-203\"\ndnssd_name = 3\nbackend = \"file:///t\"\n");
        assert!(e.starts_with("queue.a: `dnssd_name`"), "{e}");
    }

    #[test]
    fn dnssd_keys_are_the_queues_not_options() {
        let c = Config::parse(
            "[queue.a]\npreset = \"thermal-203\"\nbackend = \"file:///t\"\n\
             dnssd_name = \"Front desk\"\n[queue.b]\npreset = \"label-203\"\n\
             backend = \"file:///t\"\ndnssd = false\n",
        )
        .unwrap();
        let (a, b) = (c.queue("a").unwrap(), c.queue("b").unwrap());
        assert!(a.dnssd && !b.dnssd);
        assert_eq!(a.dnssd_name.as_deref(), Some("Front desk"));
        assert_eq!(b.dnssd_name, None);
        assert!(a.entries.iter().all(|(k, _)| !k.starts_with("dnssd")));
    }
}
