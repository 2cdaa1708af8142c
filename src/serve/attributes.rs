//! What a queue tells IPP clients about itself (the printer attributes of RFC 8011 and
//! PWG 5100.14, from the queue's options: its paper, resolution and method), and how a
//! job's attributes become option names and values for [`Settings`](crate::options::Settings).

use std::collections::BTreeMap;

use ipp::attribute::IppAttribute;
use ipp::value::{IppDateTime, IppName, IppValue};

use super::config::Queue;
use crate::io::lang::ZPL_MAX_LENGTH;
use crate::io::Format;
use crate::mask::screen::Spot;
use crate::options::table::{find, Choices};
use crate::options::value::Value;
use crate::options::MethodKind;

/// The operations this printer supports (RFC 8011, PWG 5100.14, 5100.11).
pub const OPERATIONS: [i32; 11] = [
    0x0002, 0x0004, 0x0005, 0x0006, 0x0008, 0x0009, 0x000a, 0x000b, 0x0039, 0x003b, 0x003c,
];

/// The document formats accepted (the bytes of every one are sniffed): images, PWG raster
/// and Apple raster ([`crate::io::lang`]), and PDF with the `pdf` feature.
#[cfg(feature = "pdf")]
pub const DOCUMENT_FORMATS: &[&str] = &[
    "application/octet-stream",
    "application/pdf",
    "image/jpeg",
    "image/png",
    "image/pwg-raster",
    "image/urf",
];

/// The document formats accepted (the bytes of every one are sniffed): images, PWG raster
/// and Apple raster ([`crate::io::lang`]); PDF needs the `pdf` feature.
#[cfg(not(feature = "pdf"))]
pub const DOCUMENT_FORMATS: &[&str] = &[
    "application/octet-stream",
    "image/jpeg",
    "image/png",
    "image/pwg-raster",
    "image/urf",
];

/// A keyword value.
pub fn kw(s: &str) -> IppValue {
    IppValue::Keyword(ipp::value::IppKeyword::new_truncated(s))
}

/// A name value.
pub fn name(s: &str) -> IppValue {
    IppValue::NameWithoutLanguage(IppName::new_truncated(s))
}

/// A text value.
pub fn text(s: &str) -> IppValue {
    IppValue::TextWithoutLanguage(ipp::value::IppTextValue::from(
        ipp::value::IppString::new_truncated(s),
    ))
}

/// A URI value.
pub fn uri(s: &str) -> IppValue {
    IppValue::Uri(ipp::value::IppString::new_truncated(s))
}

fn mime(s: &str) -> IppValue {
    IppValue::MimeMediaType(ipp::value::IppMimeMediaType::new_truncated(s))
}

fn attr(n: &str, v: IppValue) -> IppAttribute {
    IppAttribute::new(IppName::new_truncated(n), v)
}

fn list(v: Vec<IppValue>) -> IppValue {
    if v.len() == 1 {
        v.into_iter().next().unwrap_or(IppValue::NoValue)
    } else {
        IppValue::Array(v)
    }
}

fn kws(v: &[&str]) -> IppValue {
    list(v.iter().map(|s| kw(s)).collect())
}

fn collection(members: Vec<(&str, IppValue)>) -> IppValue {
    let map: BTreeMap<IppName, IppValue> = members
        .into_iter()
        .map(|(k, v)| (IppName::new_truncated(k), v))
        .collect();
    IppValue::Collection(map)
}

/// What the printer's state is now.
#[derive(Clone, Copy, Debug)]
pub struct PrinterStatus {
    /// printer-up-time, seconds from 1.
    pub up_time: u64,
    /// The Unix time of the start.
    pub started_unix: u64,
    /// Jobs not finished.
    pub queued: usize,
    /// A job is being processed.
    pub processing: bool,
}

/// A medium: its PWG self-describing name and size in hundredths of millimetres.
#[derive(Clone, Debug, PartialEq)]
pub struct Media {
    /// `iso_a4_210x297mm`, `na_index-4x6_4x6in`, `roll_receipt_48.04x200mm`…
    pub name: String,
    /// Width, 1/100 mm.
    pub x: i32,
    /// Length, 1/100 mm.
    pub y: i32,
}

/// The resolution a queue prints at (its `dpi`, else 300).
pub fn queue_dpi(q: &Queue) -> i32 {
    q.options
        .dpi
        .map_or(300, |d| d.round().clamp(1.0, 100_000.0) as i32)
}

/// A receipt roll's nominal length: receipts are as long as the image; clients need one.
const ROLL_LENGTH: i32 = 20_000;

/// The media a queue has, the default first: the roll or label of its printer's width
/// (`paper_width` or `width` in dots at its `dpi`; a label's length from `max_length`), or
/// for a page printer its `page`, else A4 and US Letter.
pub fn queue_media(q: &Queue) -> Vec<Media> {
    let dpi = queue_dpi(q) as i64;
    let dots_to_hmm =
        |d: usize| ((d as i64 * 2540 + dpi / 2) / dpi).clamp(1, i32::MAX as i64) as i32;
    let width = q.options.print.paper_width.or(q.options.width);
    if let Some(w) = width {
        let x = dots_to_hmm(w);
        let label = q.format == Format::Zpl || q.options.print.max_length < ZPL_MAX_LENGTH;
        if label && q.options.print.max_length < ZPL_MAX_LENGTH {
            let y = dots_to_hmm(q.options.print.max_length);
            return vec![Media {
                name: pwg_name("label", x, y),
                x,
                y,
            }];
        }
        return vec![Media {
            name: format!("roll_receipt_{}x{}mm", mm(x), mm(ROLL_LENGTH)),
            x,
            y: ROLL_LENGTH,
        }];
    }
    if let Some(p) = q.options.print.page {
        let pt = |v: f64| (v / 72.0 * 2540.0).round() as i32;
        let (x, y) = (pt(p.width), pt(p.height));
        return vec![Media {
            name: pwg_name("page", x, y),
            x,
            y,
        }];
    }
    vec![
        Media {
            name: "iso_a4_210x297mm".into(),
            x: 21000,
            y: 29700,
        },
        Media {
            name: "na_letter_8.5x11in".into(),
            x: 21590,
            y: 27940,
        },
    ]
}

/// Hundredths of a millimetre as millimetres, at most two decimals, no trailing zeros.
fn mm(hmm: i32) -> String {
    let s = format!("{}.{:02}", hmm / 100, hmm % 100);
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A PWG 5101.1 self-describing media name for a size (`na_index-4x6_4x6in` for the
/// common label, inches when the size is whole tenths of an inch, else millimetres).
fn pwg_name(what: &str, x: i32, y: i32) -> String {
    match (x, y) {
        (21000, 29700) => return "iso_a4_210x297mm".into(),
        (21590, 27940) => return "na_letter_8.5x11in".into(),
        (10160, 15240) => return "na_index-4x6_4x6in".into(),
        _ => {}
    }
    if x % 254 == 0 && y % 254 == 0 {
        let inch = |v: i32| {
            let tenths = v / 254;
            if tenths % 10 == 0 {
                format!("{}", tenths / 10)
            } else {
                format!("{}.{}", tenths / 10, tenths % 10)
            }
        };
        format!("oe_{what}_{}x{}in", inch(x), inch(y))
    } else {
        format!("om_{what}_{}x{}mm", mm(x), mm(y))
    }
}

fn media_col(m: &Media) -> IppValue {
    collection(vec![
        (
            "media-size",
            collection(vec![
                ("x-dimension", IppValue::Integer(m.x)),
                ("y-dimension", IppValue::Integer(m.y)),
            ]),
        ),
        ("media-size-name", kw(&m.name)),
        ("media-top-margin", IppValue::Integer(0)),
        ("media-bottom-margin", IppValue::Integer(0)),
        ("media-left-margin", IppValue::Integer(0)),
        ("media-right-margin", IppValue::Integer(0)),
        ("media-source", kw("main")),
        ("media-type", kw(media_type(m))),
    ])
}

fn media_type(m: &Media) -> &'static str {
    if m.name.starts_with("roll_") {
        "continuous"
    } else if m.name.contains("label") || m.name.contains("index-4x6") {
        "labels"
    } else {
        "stationery"
    }
}

/// A Unix time as an IPP dateTime in UTC.
pub fn date_time(unix: u64) -> IppDateTime {
    let days = (unix / 86_400) as i64;
    let secs = unix % 86_400;
    // Howard Hinnant's days-to-civil.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u8;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u8;
    let year = (yoe + era * 400 + i64::from(month <= 2)) as u16;
    IppDateTime {
        year,
        month,
        day,
        hour: (secs / 3600) as u8,
        minutes: (secs / 60 % 60) as u8,
        seconds: (secs % 60) as u8,
        deci_seconds: 0,
        utc_dir: '+',
        utc_hours: 0,
        utc_mins: 0,
    }
}

/// The printer-description or job-template group an attribute belongs to, for
/// `requested-attributes` given by group.
pub fn printer_group(n: &str) -> &'static str {
    const TEMPLATE: [&str; 14] = [
        "copies",
        "media",
        "media-col",
        "print-quality",
        "print-color-mode",
        "printer-resolution",
        "sides",
        "orientation-requested",
        "print-content-optimize",
        "finishings",
        "output-bin",
        "halftone-method",
        "page-ranges",
        "overrides",
    ];
    let base = n
        .strip_suffix("-default")
        .or_else(|| n.strip_suffix("-supported"))
        .unwrap_or(n);
    if TEMPLATE.contains(&base) {
        "job-template"
    } else {
        "printer-description"
    }
}

/// True when copies of the format can be sent one after the other as one job (printer
/// languages are streams; a PDF, PNG or PBM file holds one document).
pub fn concatenates(f: Format) -> bool {
    matches!(f, Format::EscPos | Format::Zpl | Format::Pcl)
}

/// The attributes the printer reports for queue `q` at `uri`.
pub fn printer_attributes(
    q: &Queue,
    uri_: &str,
    host: &str,
    s: &PrinterStatus,
) -> Vec<IppAttribute> {
    let media = queue_media(q);
    let dpi = queue_dpi(q);
    let res = IppValue::Resolution {
        cross_feed: dpi,
        feed: dpi,
        units: 3,
    };
    let language = q.format.name().to_ascii_uppercase();
    let info = format!(
        "halftone {} ({}, {} dpi, {})",
        q.name,
        language,
        dpi,
        q.options.method.name()
    );
    let make = format!("halftone {language} {dpi}dpi");
    let methods: Vec<String> = find("method").map(|(s, _)| s.values()).unwrap_or_default();
    let state = if s.processing { 4 } else { 3 };
    let when = date_time(s.started_unix);
    let more = format!("http://{host}/");
    let uuid = uuid_for(uri_);
    let mut a = vec![
        attr("printer-uri-supported", uri(uri_)),
        attr("uri-security-supported", kw("none")),
        attr("uri-authentication-supported", kw("none")),
        attr("printer-name", name(&q.name)),
        attr("printer-info", text(&info)),
        attr("printer-location", text("")),
        attr("printer-make-and-model", text(&make)),
        attr("printer-more-info", uri(&more)),
        attr("printer-supply-info-uri", uri(&more)),
        attr("printer-icons", uri(&format!("http://{host}/icon.png"))),
        attr("printer-uuid", uri(&uuid)),
        attr(
            "printer-device-id",
            text(&format!("MFG:halftone;MDL:{language} {dpi}dpi;CMD:{language};")),
        ),
        attr("printer-state", IppValue::Enum(state)),
        attr("printer-state-reasons", kw("none")),
        attr("printer-state-message", text(if s.processing { "printing" } else { "idle" })),
        attr("printer-is-accepting-jobs", IppValue::Boolean(true)),
        attr("printer-up-time", IppValue::Integer(s.up_time.min(i32::MAX as u64) as i32)),
        attr("printer-current-time", IppValue::DateTime(date_time(s.started_unix + s.up_time - 1))),
        attr("printer-config-change-time", IppValue::Integer(1)),
        attr("printer-config-change-date-time", IppValue::DateTime(when.clone())),
        attr("printer-state-change-time", IppValue::Integer(1)),
        attr("printer-state-change-date-time", IppValue::DateTime(when)),
        attr("printer-geo-location", IppValue::Other { tag: 0x12, data: Default::default() }),
        attr("printer-organization", text("")),
        attr("printer-organizational-unit", text("")),
        attr("printer-kind", kw(if q.format == Format::EscPos { "receipt" } else if q.format == Format::Zpl { "label" } else { "document" })),
        attr("queued-job-count", IppValue::Integer(s.queued.min(i32::MAX as usize) as i32)),
        attr("ipp-versions-supported", kws(&["1.1", "2.0"])),
        attr("ipp-features-supported", kw("ipp-everywhere")),
        attr(
            "operations-supported",
            list(OPERATIONS.iter().map(|&o| IppValue::Enum(o)).collect()),
        ),
        attr("charset-configured", IppValue::Charset(ipp::value::IppCharset::new_truncated("utf-8"))),
        attr(
            "charset-supported",
            list(vec![
                IppValue::Charset(ipp::value::IppCharset::new_truncated("utf-8")),
                IppValue::Charset(ipp::value::IppCharset::new_truncated("us-ascii")),
            ]),
        ),
        attr("natural-language-configured", IppValue::NaturalLanguage(ipp::value::IppLanguage::new_truncated("en"))),
        attr("generated-natural-language-supported", IppValue::NaturalLanguage(ipp::value::IppLanguage::new_truncated("en"))),
        attr("compression-supported", kw("none")),
        attr("document-format-default", mime("application/octet-stream")),
        attr(
            "document-format-supported",
            list(DOCUMENT_FORMATS.iter().map(|f| mime(f)).collect()),
        ),
        attr("pdl-override-supported", kw("attempted")),
        attr("color-supported", IppValue::Boolean(false)),
        attr("pages-per-minute", IppValue::Integer(1)),
        attr("multiple-document-jobs-supported", IppValue::Boolean(false)),
        attr("multiple-operation-time-out", IppValue::Integer(60)),
        attr("multiple-operation-time-out-action", kw("abort-job")),
        attr("job-ids-supported", IppValue::Boolean(true)),
        attr("preferred-attributes-supported", IppValue::Boolean(false)),
        attr("printer-get-attributes-supported", kw("document-format")),
        attr("which-jobs-supported", kws(&["completed", "not-completed", "all"])),
        attr("identify-actions-default", kw("display")),
        attr("identify-actions-supported", kw("display")),
        attr(
            "job-creation-attributes-supported",
            kws(&[
                "copies",
                "media",
                "media-col",
                "print-quality",
                "print-color-mode",
                "printer-resolution",
                "print-content-optimize",
                "sides",
                "orientation-requested",
                "halftone-method",
                "halftone-type",
                "page-ranges",
                "overrides",
            ]),
        ),
        attr("page-ranges-supported", IppValue::Boolean(true)),
        attr("overrides-supported", kws(&["document-number", "pages", "print-quality", "print-color-mode", "print-content-optimize", "printer-resolution", "halftone-type"])),
        attr("copies-default", IppValue::Integer(1)),
        attr("copies-supported", IppValue::RangeOfInteger { min: 1, max: 99 }),
        attr("finishings-default", IppValue::Enum(3)),
        attr("finishings-supported", IppValue::Enum(3)),
        attr("number-up-default", IppValue::Integer(1)),
        attr("number-up-supported", IppValue::Integer(1)),
        attr("orientation-requested-default", IppValue::Enum(3)),
        attr("orientation-requested-supported", IppValue::Enum(3)),
        // face-down: pages leave in the order sent. With face-up, CUPS's everywhere PPD
        // says "*DefaultOutputOrder: Reverse" and a two-page label job arrives backwards.
        attr("output-bin-default", kw("face-down")),
        attr("output-bin-supported", kw("face-down")),
        attr("sides-default", kw("one-sided")),
        attr("sides-supported", kw("one-sided")),
        attr("print-quality-default", IppValue::Enum(4)),
        attr(
            "print-quality-supported",
            list(vec![IppValue::Enum(3), IppValue::Enum(4), IppValue::Enum(5)]),
        ),
        attr("print-color-mode-default", kw("monochrome")),
        attr("print-color-mode-supported", kws(&["auto", "monochrome", "bi-level"])),
        attr("print-content-optimize-default", kw("auto")),
        attr(
            "print-content-optimize-supported",
            kws(&["auto", "photo", "graphic", "text", "text-and-graphic"]),
        ),
        attr("print-rendering-intent-default", kw("auto")),
        attr("print-rendering-intent-supported", kw("auto")),
        attr("printer-resolution-default", res.clone()),
        attr("printer-resolution-supported", res.clone()),
        attr("pwg-raster-document-resolution-supported", res),
        attr("pwg-raster-document-sheet-back", kw("normal")),
        attr(
            "pwg-raster-document-type-supported",
            kws(&["black_1", "sgray_8", "sgray_16", "srgb_8", "srgb_16", "cmyk_8"]),
        ),
        attr(
            "urf-supported",
            kws(&["V1.4", "CP1", "PQ3-4-5", &format!("RS{}", queue_dpi(q)), "W8", "SRGB24"]),
        ),
        attr(
            "printer-supply",
            IppValue::OctetString(
                "index=1;class=supplyThatIsConsumed;type=other;unit=percent;maxcapacity=100;level=-3;colorantname=black;"
                    .as_bytes()
                    .to_vec()
                    .into(),
            ),
        ),
        attr("printer-supply-description", text("Paper and ink")),
        attr("media-default", kw(&media[0].name)),
        attr("media-supported", list(media.iter().map(|m| kw(&m.name)).collect())),
        attr("media-ready", list(media.iter().map(|m| kw(&m.name)).collect())),
        attr("media-col-default", media_col(&media[0])),
        attr("media-col-ready", list(media.iter().map(media_col).collect())),
        attr("media-col-database", list(media.iter().map(media_col).collect())),
        attr(
            "media-col-supported",
            kws(&[
                "media-size",
                "media-size-name",
                "media-top-margin",
                "media-bottom-margin",
                "media-left-margin",
                "media-right-margin",
                "media-source",
                "media-type",
            ]),
        ),
        attr(
            "media-size-supported",
            list(
                media
                    .iter()
                    .map(|m| {
                        collection(vec![
                            ("x-dimension", IppValue::Integer(m.x)),
                            ("y-dimension", IppValue::Integer(m.y)),
                        ])
                    })
                    .collect(),
            ),
        ),
        attr("media-top-margin-supported", IppValue::Integer(0)),
        attr("media-bottom-margin-supported", IppValue::Integer(0)),
        attr("media-left-margin-supported", IppValue::Integer(0)),
        attr("media-right-margin-supported", IppValue::Integer(0)),
        attr("media-source-supported", kw("main")),
        attr("media-type-supported", kw(media_type(&media[0]))),
        attr("halftone-method-default", kw(q.options.method.name())),
    ];
    if !methods.is_empty() {
        a.push(attr(
            "halftone-method-supported",
            list(methods.iter().map(|m| kw(m)).collect()),
        ));
    }
    a
}

/// A stable `urn:uuid:` for a queue's URI (a name-based UUID from an FNV hash: no
/// randomness, so a restarted server is the same printer to its clients).
fn uuid_for(u: &str) -> String {
    let mut h: [u64; 2] = [0xcbf2_9ce4_8422_2325, 0x6c62_272e_07bb_0142];
    for (i, b) in u.bytes().enumerate() {
        let k = i % 2;
        h[k] ^= u64::from(b);
        h[k] = h[k].wrapping_mul(0x0000_0100_0000_01b3);
        h[1 - k] = h[1 - k].rotate_left(5) ^ h[k];
    }
    let (a, b) = (h[0], h[1]);
    format!(
        "urn:uuid:{:08x}-{:04x}-5{:03x}-{:04x}-{:012x}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xfff,
        0x8000 | ((b >> 48) & 0x3fff),
        b & 0xffff_ffff_ffff
    )
}

/// What a job attribute asks for.
pub enum Mapped {
    /// Options to set (names of the option table, values).
    Setting(Vec<(String, Value<'static>)>),
    /// Copies.
    Copies(u32),
    /// Supported with nothing to do (its only value, or one that changes nothing here).
    Ignored,
}

fn value_words(v: &IppValue) -> Option<Value<'static>> {
    Some(match v {
        IppValue::Keyword(s) | IppValue::NameWithoutLanguage(s) => {
            Value::from(s.as_str().to_string())
        }
        IppValue::NameWithLanguage { name, .. } => Value::from(name.as_str().to_string()),
        IppValue::TextWithoutLanguage(t) | IppValue::TextWithLanguage { text: t, .. } => {
            Value::from(t.to_string())
        }
        IppValue::Integer(i) | IppValue::Enum(i) => Value::Int(i64::from(*i)),
        IppValue::Boolean(b) => Value::Bool(*b),
        _ => return None,
    })
}

fn one(k: &str, v: &str) -> Mapped {
    Mapped::Setting(vec![(k.to_string(), Value::from(v.to_string()))])
}

/// Maps job attribute `n` = `v` on queue `q` to option names and values, or says why it
/// is not supported.
pub fn map_job_attribute(q: &Queue, n: &str, v: &IppValue) -> Result<Mapped, String> {
    let word = || {
        value_words(v)
            .map(|w| w.text().into_owned())
            .unwrap_or_default()
    };
    let media = queue_media(q);
    match (n, v) {
        ("copies", IppValue::Integer(c)) if (1..=99).contains(c) => Ok(Mapped::Copies(*c as u32)),
        ("media", _) => {
            let w = word();
            media
                .iter()
                .find(|m| m.name == w)
                .map(|m| media_settings(q, m))
                .ok_or_else(|| format!("{w} is not loaded (media-supported: {})", names(&media)))
        }
        ("media-col", IppValue::Collection(c)) => {
            let size = c
                .iter()
                .find(|(k, _)| k.as_str() == "media-size")
                .map(|(_, v)| v);
            let Some(IppValue::Collection(size)) = size else {
                return Ok(Mapped::Ignored);
            };
            let dim = |k: &str| {
                size.iter()
                    .find(|(n, _)| n.as_str() == k)
                    .and_then(|(_, v)| match v {
                        IppValue::Integer(i) => Some(*i),
                        _ => None,
                    })
            };
            let (Some(x), Some(y)) = (dim("x-dimension"), dim("y-dimension")) else {
                return Err("media-size needs x-dimension and y-dimension".into());
            };
            media
                .iter()
                .find(|m| (m.x - x).abs() <= 100 && (m.y - y).abs() <= 100)
                .map(|m| media_settings(q, m))
                .ok_or_else(|| format!("{x}x{y} (1/100 mm) is not loaded"))
        }
        ("print-quality", IppValue::Enum(3)) => Ok(one("method", "ordered")),
        ("print-quality", IppValue::Enum(4)) => Ok(Mapped::Ignored),
        ("print-quality", IppValue::Enum(5)) => Ok(one("method", "dbs")),
        ("print-color-mode", _) => match word().as_str() {
            "auto" | "monochrome" => Ok(Mapped::Ignored),
            "bi-level" => Ok(one("method", "threshold")),
            w => Err(format!("{w}: this printer prints black only")),
        },
        (
            "printer-resolution",
            IppValue::Resolution {
                cross_feed,
                feed,
                units: 3,
            },
        ) if *cross_feed == queue_dpi(q) && *feed == queue_dpi(q) => Ok(Mapped::Setting(vec![(
            "dpi".into(),
            Value::Int(i64::from(*feed)),
        )])),
        ("print-content-optimize", _) => match word().as_str() {
            "auto" => Ok(Mapped::Ignored),
            "photo" => Ok(one("content", "photo")),
            "graphic" | "text" => Ok(one("content", "line-art")),
            "text-and-graphic" => Ok(one("content", "auto")),
            w => Err(format!("{w} is not a print-content-optimize value")),
        },
        ("sides", _) if word() == "one-sided" => Ok(Mapped::Ignored),
        ("orientation-requested", IppValue::Enum(3)) => Ok(Mapped::Ignored),
        ("finishings", IppValue::Enum(3)) => Ok(Mapped::Ignored),
        ("number-up", IppValue::Integer(1)) => Ok(Mapped::Ignored),
        ("output-bin", _) if word() == "face-down" => Ok(Mapped::Ignored),
        ("print-rendering-intent", _) if word() == "auto" => Ok(Mapped::Ignored),
        ("job-hold-until", _) if word() == "no-hold" => Ok(Mapped::Ignored),
        ("job-sheets", _) if word() == "none" => Ok(Mapped::Ignored),
        ("job-priority", IppValue::Integer(1..=100)) => Ok(Mapped::Ignored),
        ("multiple-document-handling", _) => Ok(Mapped::Ignored),
        ("halftone-type", _) => halftone_type(&word()).map(Mapped::Setting),
        _ if n.starts_with("halftone-") => vendor(&n["halftone-".len()..], v),
        _ => Err("not supported".into()),
    }
}

/// `halftone-type`: one of our method names, or one of the names cups-filters' Ghostscript
/// filters take for the same job option (libcupsfilters `ghostscript.c`), mapped to the
/// nearest of ours:
/// - `dithering`: 8×8 ordered dithering (Bayer);
/// - `stochastic` (and `true`, `on`, `yes`): ordered dithering with a blue-noise mask, our
///   stochastic screen;
/// - `bi-level`: a threshold;
/// - `genordered[-LPI[-ANGLE[-SHAPE[-GAMMA]]]]`: an AM screen (`screen`) at LPI lines per
///   inch (default 133) and ANGLE degrees (45), with Ghostscript `.genordered`'s dot shapes
///   0–8 as the nearest spot functions of ours ([`GENORDERED_SHAPES`]);
/// - `spot[-LPI[-ANGLE[-SHAPE[-GAMMA]]]]`: the same screen with the PDF specification's spot
///   function number SHAPE (0–20, the order of its table and of [`Spot::ALL`]);
/// - GAMMA (1–99) is an exponent of 0.GAMMA on the tone (`gamma`).
///
/// Letters are compared without regard to case, as cups-filters does.
pub fn halftone_type(word: &str) -> Result<Vec<(String, Value<'static>)>, String> {
    let w = word.trim().to_ascii_lowercase();
    let set = |k: &str, v: Value<'static>| (k.to_string(), v);
    let text = |k: &str, v: &str| set(k, Value::from(v.to_string()));
    match w.as_str() {
        "dithering" => return Ok(vec![text("method", "ordered"), text("mask", "bayer-8")]),
        "stochastic" | "true" | "on" | "yes" => {
            return Ok(vec![
                text("method", "ordered"),
                text("mask", "blue-noise-64"),
            ])
        }
        "bi-level" => return Ok(vec![text("method", "threshold")]),
        "foo2zjs" => {
            return Err(format!(
                "{word}: foo2zjs's screen is not offered; genordered-LPI-ANGLE-SHAPE, \
                 spot-LPI-ANGLE-SHAPE or a method name are"
            ))
        }
        _ => {}
    }
    for (family, shapes) in [
        ("genordered", GENORDERED_SHAPES.len()),
        ("spot", Spot::ALL.len()),
    ] {
        let Some(rest) = w.strip_prefix(family) else {
            continue;
        };
        if !(rest.is_empty() || rest.starts_with('-')) {
            continue;
        }
        let mut nums = [133i64, 45, 0, 0];
        let parts: Vec<&str> = rest.split('-').skip(1).collect();
        if parts.len() > nums.len() {
            return Err(format!(
                "{word}: expected {family}-LPI-ANGLE-SHAPE-GAMMA at most"
            ));
        }
        for (slot, p) in nums.iter_mut().zip(&parts) {
            *slot = p
                .parse()
                .map_err(|_| format!("{word}: '{p}' is not a whole number"))?;
        }
        let [lpi, angle, shape, gamma] = nums;
        if !(1..=1000).contains(&lpi) {
            return Err(format!("{word}: {lpi} lines per inch is out of 1 to 1000"));
        }
        if !(0..shapes as i64).contains(&shape) {
            return Err(format!(
                "{word}: dot shape {shape} is out of 0 to {}",
                shapes - 1
            ));
        }
        if !(0..=99).contains(&gamma) {
            return Err(format!("{word}: gamma {gamma} is out of 1 to 99"));
        }
        let (spot, turn) = if family == "genordered" {
            GENORDERED_SHAPES[shape as usize]
        } else {
            (Spot::ALL[shape as usize], 0)
        };
        let mut v = vec![
            text("method", "screen"),
            set("lpi", Value::Int(lpi)),
            set("angle", Value::Int((angle + turn).rem_euclid(360))),
            text("spot", spot.name()),
        ];
        if gamma > 0 {
            v.push(set("gamma", Value::Float(gamma as f64 / 100.0)));
        }
        return Ok(v);
    }
    w.parse::<MethodKind>()
        .map(|m| vec![text("method", m.name())])
        .map_err(|e| e.to_string())
}

/// Ghostscript `.genordered`'s dot shapes by number (its `gen_ordered.c`), as the nearest
/// spot function of ours and the turn (degrees) that makes it one:
/// 0 CIRCLE `1 − (x² + y²)` is SimpleDot; 1 REDBOOK `(cos x + cos y)/2` takes cosines of
/// radians over `[−1, 1]`, which orders the cell as a circle does, so SimpleDot too;
/// 2 INVERTED is InvertedSimpleDot; 3 RHOMBOID `1 − (|x| + 0.8|y|)/2` is Rhomboid (0.9);
/// 4 LINE_X `1 − |y|` is Line; 5 LINE_Y `1 − |x|` is Line turned 90°; 6 DIAMOND1 is Diamond
/// (the same three pieces); 7 DIAMOND2, a function of `|x| + |y|` alone, is a square dot
/// turned 45° (Square); 8 ROUNDSPOT is Round (the same two pieces).
pub const GENORDERED_SHAPES: [(Spot, i64); 9] = [
    (Spot::SimpleDot, 0),
    (Spot::SimpleDot, 0),
    (Spot::InvertedSimpleDot, 0),
    (Spot::Rhomboid, 0),
    (Spot::Line, 0),
    (Spot::Line, 90),
    (Spot::Diamond, 0),
    (Spot::Square, 45),
    (Spot::Round, 0),
];

/// The settings a medium brings: none for a roll or a label (the queue's width decides),
/// the page and the box to fit the image in for a page printer without a size of its own.
fn media_settings(q: &Queue, m: &Media) -> Mapped {
    if q.options.print.paper_width.is_some() || q.options.width.is_some() {
        return Mapped::Ignored;
    }
    let o = &q.options;
    if o.height.is_some() || o.fit.is_some() || o.size.is_some() || o.device.is_some() {
        return Mapped::Ignored;
    }
    let dpi = f64::from(queue_dpi(q));
    let dots = |hmm: i32| (f64::from(hmm) / 2540.0 * dpi).floor() as i64;
    let mut v = vec![(
        "fit".to_string(),
        Value::from(format!("{}x{}", dots(m.x), dots(m.y))),
    )];
    if matches!(q.format, Format::Pdf | Format::Ps | Format::Pcl) {
        v.push((
            "page".into(),
            Value::from(format!("{}x{}mm", mm(m.x), mm(m.y))),
        ));
    }
    Mapped::Setting(v)
}

fn names(m: &[Media]) -> String {
    m.iter()
        .map(|m| m.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// A `halftone-NAME` attribute: the option NAME of the one table, with built-in names only
/// (a network client names no files on the server).
fn vendor(option: &str, v: &IppValue) -> Result<Mapped, String> {
    let key = option.replace('-', "_");
    if matches!(key.as_str(), "format" | "preset" | "presets") {
        return Err(format!("the queue decides `{key}`"));
    }
    let (spec, _) = find(&key).ok_or_else(|| format!("`{key}` is not an option"))?;
    let value = value_words(v).ok_or("expected a keyword, name, text, integer or boolean")?;
    let text = value.text().into_owned();
    match spec.choices {
        Choices::Named(_) => {
            let auto = spec.name == "palette" && text.starts_with("auto:");
            if !auto && !spec.values().contains(&text) {
                return Err(format!(
                    "{text}: not a built-in {} (files are not taken from a job)",
                    spec.name
                ));
            }
        }
        Choices::Open if spec.value_name.contains("FILE") => {
            return Err(format!(
                "`{}` names a file; set it in the queue's file",
                spec.name
            ));
        }
        _ => {}
    }
    spec.check(&value)?;
    Ok(Mapped::Setting(vec![(spec.name.to_string(), value)]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_and_names() {
        let d = date_time(1_796_601_600); // 2026-12-07 00:00:00 UTC
        assert_eq!((d.year, d.month, d.day, d.hour), (2026, 12, 7, 0));
        assert_eq!(pwg_name("label", 10160, 15240), "na_index-4x6_4x6in");
        assert_eq!(pwg_name("label", 5080, 2540), "oe_label_2x1in");
        assert_eq!(pwg_name("label", 4804, 3000), "om_label_48.04x30mm");
        assert!(uuid_for("ipp://a/ipp/print/x").starts_with("urn:uuid:"));
        assert_ne!(
            uuid_for("ipp://a/ipp/print/x"),
            uuid_for("ipp://a/ipp/print/y")
        );
    }

    #[test]
    fn vendor_attributes_take_built_in_names_only() {
        let m = |n: &str, v: &str| vendor(n, &kw(v));
        assert!(matches!(m("method", "ordered"), Ok(Mapped::Setting(_))));
        assert!(matches!(m("kernel", "atkinson"), Ok(Mapped::Setting(_))));
        assert!(m("kernel", "/etc/passwd").is_err());
        assert!(m("transfer", "x.csv").is_err());
        assert!(m("format", "pdf").is_err());
        assert!(m("levels", "1").is_err());
        assert!(m("no-such", "1").is_err());
    }

    #[test]
    fn halftone_type_takes_our_names_and_cups_filters_names() {
        let get = |w: &str| -> Vec<(String, String)> {
            let v = halftone_type(w).unwrap_or_else(|e| panic!("{w}: {e}"));
            // Every mapping is a set of options the table takes.
            let mut o = crate::Options::default();
            for (k, x) in &v {
                o.set_value(k, x)
                    .unwrap_or_else(|e| panic!("{w}: {k}={x}: {e}"));
            }
            v.into_iter().map(|(k, x)| (k, x.to_string())).collect()
        };
        let pairs = |p: &[(&str, &str)]| -> Vec<(String, String)> {
            p.iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        assert_eq!(get("dbs"), pairs(&[("method", "dbs")]));
        assert_eq!(
            get("dithering"),
            pairs(&[("method", "ordered"), ("mask", "bayer-8")])
        );
        assert_eq!(
            get("Stochastic"),
            pairs(&[("method", "ordered"), ("mask", "blue-noise-64")])
        );
        assert_eq!(get("yes"), get("stochastic"));
        assert_eq!(get("bi-level"), pairs(&[("method", "threshold")]));
        let screen = |lpi: &str, angle: &str, spot: &str| {
            pairs(&[
                ("method", "screen"),
                ("lpi", lpi),
                ("angle", angle),
                ("spot", spot),
            ])
        };
        // cups-filters' defaults: 133 lpi, 45 degrees, shape 0.
        assert_eq!(get("genordered"), screen("133", "45", "SimpleDot"));
        assert_eq!(get("spot"), screen("133", "45", "SimpleDot"));
        assert_eq!(get("genordered-60-45-8"), screen("60", "45", "Round"));
        assert_eq!(get("genordered-60-30-5"), screen("60", "120", "Line"));
        assert_eq!(get("genordered-53-0-7"), screen("53", "45", "Square"));
        assert_eq!(get("spot-106-15-11"), screen("106", "15", "Ellipse"));
        assert_eq!(get("spot-85-45-20"), screen("85", "45", "Diamond"));
        let mut g = screen("60", "45", "Round");
        g.push(("gamma".into(), "0.8".into()));
        assert_eq!(get("genordered-60-45-8-80"), g);
        for bad in [
            "genordered-60-45-9",
            "spot-85-45-21",
            "spot-x",
            "spot-85-45-0-100",
            "spot-0",
            "spot-1-2-3-4-5",
            "genorderedx",
            "foo2zjs",
            "",
        ] {
            let e = halftone_type(bad).expect_err(bad);
            assert!(!e.is_empty() && !e.contains('\n'), "{bad}: {e}");
        }
    }
}
