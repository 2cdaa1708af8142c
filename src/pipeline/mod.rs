//! The road from a file to a halftone, as one library call: read → resize → tone → colour →
//! method → encode, moving bands of rows from the decoder to the encoder under a memory
//! budget.
//!
//! [`convert`] writes one file (atomically); [`run_page`] runs one input into an encoder the
//! caller has opened, as one page of a possibly multi-page file. Both choose between two
//! ways:
//!
//! - **Whole image**: decode everything, halftone, encode. Every method, every input format,
//!   and resizing take this way; the pixel limit (`--max-pixels`) guards it, and with an
//!   explicit budget it is refused, before any pixel is decoded, when its estimate does not
//!   fit.
//! - **Streaming**: a [`source::RowSource`] decodes bands of rows, the method's
//!   [`RowMethod`] halftones them carrying its own state (error rows for diffusion), and the
//!   encoder writes them as they come. Memory is a few bands, whatever the image's height.
//!
//! The output is the same, byte for byte, either way, for any budget and any thread count:
//! every row method reproduces its whole-image code, and the encoders see the same rows.
//! With the budget on automatic, the whole image is used when it fits easily (a quarter of
//! the memory available, at most 1 GiB), streaming beyond.

pub mod band;
#[cfg(feature = "calibrate")]
pub mod calibrate;
#[cfg(halftone_libjpeg)]
pub mod jpeg;
pub mod plates;
pub mod reduce;
pub mod shrink;
pub mod source;

use std::io::{Read, Write};
use std::path::Path;

use crate::error::{Error, Result};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{self, ReadOptions, WriteOptions};
use crate::method::rows::RowMethod;
use crate::raster::ColorMode;
use crate::raster::{ColorKind, Halftone, Image};
use crate::resize::Shrunk;
use crate::tone::ToneTable;
use crate::{Method, ToneOptions};

use source::{Opened, RowSource, SourceInfo};

/// Whole-image work is preferred under an automatic budget up to this many bytes.
const AUTO_WHOLE_MAX: u64 = 1 << 30;
/// Bands of one plane's input are kept to about this size even when the budget allows more:
/// a band that stays in the caches is as fast as a larger one.
const BAND_TARGET: u64 = 4 << 20;

pub use crate::options::MaxMemory;

/// Everything one conversion needs besides its input and output.
#[derive(Clone, Copy)]
pub struct Job<'a> {
    /// The halftoning method.
    pub method: &'a dyn Method,
    /// Grey or RGB.
    pub color: ColorMode,
    /// Tone options.
    pub tone: &'a ToneOptions,
    /// Decoding limits.
    pub read: &'a ReadOptions,
    /// Turns and resizing asked for (`--width`, `--height`, `--fit`, `--size`, `--rotate`);
    /// they need the whole image.
    pub size: &'a crate::resize::SizeRequest<'a>,
    /// Output format and its options.
    pub write: &'a WriteOptions,
    /// The memory budget.
    pub max_memory: MaxMemory,
}

/// What a conversion did.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Input size in pixels.
    pub input: (usize, usize),
    /// Output size in pixels.
    pub output: (usize, usize),
    /// True when the image went through in bands.
    pub streamed: bool,
    /// Input rows a band (the image's height when whole).
    pub band_rows: usize,
    /// Bands used.
    pub bands: usize,
    /// The pipeline's estimate of its peak bytes of image data.
    pub estimate: u64,
    /// The resolution chosen for a printed page (PDF, PostScript, PCL) when the job gave
    /// none, so that the caller can say so: the image's recorded one, or the default.
    pub assumed_dpi: Option<AssumedDpi>,
}

/// A printed page's resolution chosen in the absence of `WriteOptions::dpi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AssumedDpi {
    /// The resolution recorded in the input image.
    Recorded(f64),
    /// [`io::lang::DEFAULT_PAGE_DPI`]: the image records none the format can print at.
    Default(f64),
}

impl AssumedDpi {
    /// The resolution, dots per inch.
    pub fn dpi(self) -> f64 {
        match self {
            AssumedDpi::Recorded(d) | AssumedDpi::Default(d) => d,
        }
    }
}

/// The write options with a printed page's resolution filled in when the job gave none
/// (see [`io::lang::default_dpi`]), and what was chosen.
fn with_print_dpi(
    write: &WriteOptions,
    recorded: Option<f64>,
) -> (WriteOptions, Option<AssumedDpi>) {
    let mut w = write.clone();
    let Some(lang) = write.format.language() else {
        return (w, None);
    };
    if write.dpi.is_some() {
        return (w, None);
    }
    let Some(d) = io::lang::default_dpi(lang, recorded) else {
        return (w, None);
    };
    w.dpi = Some(d);
    let assumed = if recorded == Some(d) {
        AssumedDpi::Recorded(d)
    } else {
        AssumedDpi::Default(d)
    };
    (w, Some(assumed))
}

impl Report {
    /// Input pixels.
    pub fn pixels(&self) -> u64 {
        self.input.0 as u64 * self.input.1 as u64
    }
}

/// Converts the file `input` to the file `output`, written atomically: a failure leaves
/// nothing behind. (Streams go through [`run_reader`] with a caller's writer.)
pub fn convert(input: &Path, output: &Path, job: &Job<'_>) -> Result<Report> {
    let mut enc = io::page_encoder(job.write);
    let mut run = |out: &mut dyn Write| -> Result<Report> {
        let report = run_page(input, job, enc.as_mut(), out, output)?;
        enc.finish(out).map_err(|e| e.named(output))?;
        Ok(report)
    };
    let mut report = None;
    io::write_atomic_with(output, |out| {
        let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
        report = Some(run(&mut out)?);
        out.flush().map_err(|e| Error::io(output, e))
    })?;
    Ok(report.expect("set when the write succeeded"))
}

/// Runs `input` through the job into `enc` as one page: `begin_page`, the rows, `end_page`
/// (not `finish`, which the caller calls after its last page). `output` names the file in
/// error messages.
///
/// A multi-page writer opens one encoder and one output, calls `run_page` for each input,
/// then `enc.finish(out)`.
pub fn run_page(
    input: &Path,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    let source::Input { name, reader, file } = source::open_input(input, job.read)?;
    run_reader(&name, file.as_deref(), reader, job, enc, out, output)
}

/// [`run_page`] for an input already open: `reader` holds the encoded image named `name`
/// (buffered by the caller); `file` is its path when it is a regular file the whole-image
/// reader may open again (it reads large greymaps in parallel), `None` for a stream or bytes
/// in memory.
pub(crate) fn run_reader(
    name: &Path,
    file: Option<&Path>,
    reader: Box<dyn Read + Send>,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    match source::open(name, file, reader, job.read)? {
        Opened::Rows(mut src) => {
            let (write, assumed_dpi) = with_print_dpi(job.write, src.info().dpi);
            let job = &Job {
                write: &write,
                ..*job
            };
            let orig = (src.info().width, src.info().height);
            if job.color == ColorMode::Gray && resized(job, orig.0, orig.1)?.is_none() {
                // Colour made grey as it is decoded, when the decoder can (JPEG).
                src.to_luminance(job.tone);
            }
            // Before planning, so the estimate is of the image as it will be decoded.
            let (mut src, shrunk_by) = shrink_on_load(src, orig, job)?;
            if shrunk_by > 1 {
                // The resize's 16-bit linear codes, made as the rows are decoded (JPEG).
                src.to_linear(job.tone);
            }
            let plan = plan_rows(name, src.as_ref(), job)?;
            let report = match plan {
                Plan::Stream(rows, estimate) => {
                    stream(name, src, rows, estimate, job, enc, out, output)
                }
                Plan::Whole(estimate) => {
                    // A file goes through the whole-image reader (parallel reads of large
                    // greymaps); standard input, files a source decodes as well (JPEG), and
                    // images shrunk on load for a smaller output, through this one.
                    let through_source =
                        shrunk_by > 1 || src.decodes_whole_well() || file.is_none();
                    let from = Shrunk {
                        full: orig,
                        factor: shrunk_by,
                        remainder_at: src.remainder_at(),
                    };
                    let img = match file {
                        Some(path) if !through_source => {
                            drop(src);
                            io::read_image(path, job.read)?
                        }
                        _ => read_all(src)?,
                    };
                    whole_from(name, img, from, estimate, job, enc, out, output)
                }
            };
            report.map(|r| Report { assumed_dpi, ..r })
        }
        Opened::Whole(rest) => {
            let img = if let Some(path) = file {
                drop(rest);
                let head = peek_file(path)?;
                check_whole(name, &head, job)?;
                io::read_image(path, job.read)?
            } else {
                let bytes = io::read_stream(&mut { rest }, name, job.read)?;
                check_whole(name, &whole_header(&bytes), job)?;
                io::read_image_bytes(&bytes, name, job.read)?
            };
            let (write, assumed_dpi) = with_print_dpi(job.write, img.dpi);
            let job = &Job {
                write: &write,
                ..*job
            };
            let resized = resized(job, img.width, img.height)?;
            let estimate = whole_estimate(&img_info(&img), resized, job);
            whole(name, img, estimate, job, enc, out, output).map(|r| Report { assumed_dpi, ..r })
        }
    }
}

/// Halftones a decoded image: colour handling, tone table, then the method.
pub fn halftone_image(
    img: &Image,
    method: &dyn Method,
    color: ColorMode,
    tone: &ToneOptions,
) -> Result<Halftone> {
    let gray;
    let src = match (color, img.color) {
        (ColorMode::Gray, ColorKind::Rgb) => {
            gray = img.to_luminance(tone);
            &gray
        }
        _ => img,
    };
    let table = src.tone_table(tone);
    let mut planes = src.planes(&table);
    if color == ColorMode::Rgb && planes.planes.len() == 1 {
        let p = planes.planes[0];
        planes.planes = vec![p, p, p];
    }
    method.halftone(&planes)
}

/// [`run_page`] for an image already decoded: the whole-image way.
pub(crate) fn run_image(
    img: Image,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    let resized = resized(job, img.width, img.height)?;
    let estimate = whole_estimate(&img_info(&img), resized, job);
    whole(Path::new("<image>"), img, estimate, job, enc, out, output)
}

/// Reads the dimensions and sample size of a file the whole-image decoders will read, from
/// its header: `(width, height, bytes a pixel decoded)`, or `None` when unknown.
fn peek_file(path: &Path) -> Result<Option<(usize, usize, usize)>> {
    let Ok(reader) = image::ImageReader::open(path).and_then(|r| r.with_guessed_format()) else {
        return Ok(None);
    };
    Ok(reader.into_decoder().ok().map(|d| {
        use image::ImageDecoder;
        let (w, h) = d.dimensions();
        (
            w as usize,
            h as usize,
            d.color_type().bytes_per_pixel() as usize,
        )
    }))
}

/// [`peek_file`] for bytes in memory.
fn whole_header(bytes: &[u8]) -> Option<(usize, usize, usize)> {
    use image::ImageDecoder;
    let r = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .ok()?;
    let d = r.into_decoder().ok()?;
    let (w, h) = d.dimensions();
    Some((
        w as usize,
        h as usize,
        d.color_type().bytes_per_pixel() as usize,
    ))
}

/// Refuses a whole-image decode that an explicit budget cannot hold, from the header.
fn check_whole(name: &Path, head: &Option<(usize, usize, usize)>, job: &Job<'_>) -> Result<()> {
    let (MaxMemory::Bytes(budget), Some((w, h, bpp))) = (job.max_memory, *head) else {
        return Ok(());
    };
    let info = SourceInfo {
        width: w,
        height: h,
        color: ColorKind::Gray,
        bits: 8,
        dpi: None,
    };
    // The decoder's own buffer (interleaved, with alpha) and the planes made from it, each
    // at most `bpp` bytes a pixel, in place of the grey plane counted by the estimate.
    let px = (w * h) as u64;
    let estimate = whole_estimate(&info, resized(job, w, h)?, job) - px
        + 2 * px * bpp as u64
        + if job.color == ColorMode::Gray && bpp >= 3 {
            2 * px
        } else {
            0
        };
    if estimate > budget {
        return Err(too_big(
            name,
            estimate,
            budget,
            "this input format is decoded whole",
        ));
    }
    Ok(())
}

/// The shape of a decoded image, as a source would report it.
fn img_info(img: &Image) -> SourceInfo {
    SourceInfo {
        width: img.width,
        height: img.height,
        color: img.color,
        bits: img.bits(),
        dpi: img.dpi,
    }
}

/// How a streamable input will go.
enum Plan {
    /// In bands of this many rows; the estimate of peak bytes.
    Stream(usize, u64),
    /// Whole; the estimate of peak bytes.
    Whole(u64),
}

/// The size after the turns and resizing the job asks for, when it asks for any.
fn resized(job: &Job<'_>, w: usize, h: usize) -> Result<Option<(usize, usize)>> {
    Ok(crate::resize::plan(job.size, w, h)?.map(|p| (p.width, p.height)))
}

/// Bytes of the whole-image way for an input of `info`'s shape: the planes, a luminance
/// plane for colour input made grey, a resized copy (`resized`: its size), and the packed
/// output.
fn whole_estimate(info: &SourceInfo, resized: Option<(usize, usize)>, job: &Job<'_>) -> u64 {
    let (w64, h64) = (info.width as u64, info.height as u64);
    let mut bytes = w64 * h64 * info.channels() as u64 * (info.bits as u64 / 8);
    let (mut ow, mut oh) = (w64, h64);
    if let Some((rw, rh)) = resized {
        (ow, oh) = (rw as u64, rh as u64);
        bytes += ow * oh * info.channels() as u64 * 2;
    }
    if job.color == ColorMode::Gray && info.color == ColorKind::Rgb {
        bytes += ow * oh * 2;
    }
    let (mw, mh) = job.method.output_size(ow as usize, oh as usize);
    let planes = if job.color == ColorMode::Rgb { 3 } else { 1 };
    // Packed output is at most a byte a sample.
    bytes += mw as u64 * mh as u64 * planes;
    bytes
}

/// Refuses a halftone over the pixel limit (pattern `--cell expand` enlarges its input)
/// before it is allocated, naming the input.
fn check_output_size(name: &Path, job: &Job<'_>, w: usize, h: usize) -> Result<()> {
    crate::method::check_output_size(job.method, w, h, job.read.max_pixels)
        .map_err(|e| Error::Invalid(format!("{}: {e}", name.display())))
}

/// The one-line error for work that does not fit the budget.
fn too_big(name: &Path, estimate: u64, budget: u64, why: &str) -> Error {
    Error::Invalid(format!(
        "{}: needs the whole image in memory ({why}): about {}, over `max_memory` {}; raise `max_memory`",
        name.display(),
        size(estimate),
        size(budget)
    ))
}

/// A size for messages: KiB below a MiB, else MiB.
fn size(bytes: u64) -> String {
    if bytes < 1 << 20 {
        format!("{} KiB", bytes.div_ceil(1024))
    } else {
        format!("{} MiB", bytes.div_ceil(1 << 20))
    }
}

/// Memory available to this process, from the kernel's estimate; `None` when unknown.
fn available_memory() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = s.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Chooses whole or streaming for a streamable input, and the band height.
fn plan_rows(name: &Path, src: &dyn RowSource, job: &Job<'_>) -> Result<Plan> {
    let info = src.info();
    let resized = resized(job, info.width, info.height)?;
    let mut whole = whole_estimate(info, resized, job);
    if src.decodes_whole_well() {
        // The whole image is read through the source: its own buffers too (a box shrink's
        // band of the full-size rows, a progressive JPEG's coefficients).
        whole += src.buffer_bytes() as u64;
    }
    let rows = job.method.rows();
    let why = if resized.is_some() {
        Some("resizing")
    } else if rows.is_none() {
        Some("the method")
    } else {
        None
    };
    let budget = match job.max_memory {
        MaxMemory::Auto => {
            let easy = available_memory().map_or(AUTO_WHOLE_MAX, |a| (a / 4).min(AUTO_WHOLE_MAX));
            if why.is_some() || (whole <= easy && !src.prefers_streaming()) {
                return Ok(Plan::Whole(whole));
            }
            64 << 20
        }
        MaxMemory::Bytes(b) => {
            if whole <= b.min(AUTO_WHOLE_MAX) {
                return Ok(Plan::Whole(whole));
            }
            if let Some(why) = why {
                if whole > b {
                    return Err(too_big(name, whole, b, why));
                }
                return Ok(Plan::Whole(whole));
            }
            b
        }
    };
    let rm = rows.expect("checked above");
    let per_row = band_row_bytes(info, src, job);
    let multiple = rm.band_multiple().max(1);
    // Tables and codec state (tone tables, compressor windows) are fixed costs outside the
    // budget; what grows with the image is counted.
    let fixed = rm.state_bytes(info.width, planes_of(info, job)) as u64 + src.buffer_bytes() as u64;
    let fit = budget.saturating_sub(fixed) / per_row.max(1);
    let target = (BAND_TARGET / (info.row_bytes() as u64).max(1)).max(1);
    let mut rows = fit.min(target).min(info.height as u64) as usize;
    rows -= rows % multiple;
    if rows == 0 {
        if fit >= info.height as u64 {
            rows = info.height;
        } else if job.max_memory == MaxMemory::Auto {
            // Bands do not fit the automatic budget (a TIFF in one huge strip, say): whole,
            // as without a budget; --max-pixels guards it.
            return Ok(Plan::Whole(whole));
        } else {
            let band = per_row * multiple as u64;
            let need = fixed + band;
            let rows = if multiple == 1 {
                "a band of 1 row".to_string()
            } else {
                format!("bands of {multiple} rows")
            };
            // Say so when most of it is what the decoder holds (a turned JPEG, a strip).
            let held = src.buffer_bytes() as u64;
            let held = if held > band {
                format!(", {} of it held by the decoder", size(held))
            } else {
                String::new()
            };
            return Err(Error::Invalid(format!(
                "{}: `max_memory` {} is too small for {rows} of {} pixels (needs about {}{held})",
                name.display(),
                size(budget),
                info.width,
                size(need)
            )));
        }
    }
    Ok(Plan::Stream(rows, fixed + per_row * rows as u64))
}

/// Planes the method sees.
fn planes_of(_info: &SourceInfo, job: &Job<'_>) -> usize {
    match job.color {
        ColorMode::Gray => 1,
        ColorMode::Rgb => 3,
    }
}

/// Bytes a band costs per input row: the decoded planes and the decoder's own row, a
/// luminance row for colour made grey, and the packed output rows (at a byte a sample, an
/// upper bound) with the encoder's copy of them.
fn band_row_bytes(info: &SourceInfo, src: &dyn RowSource, job: &Job<'_>) -> u64 {
    let mut b = info.row_bytes() as u64 + src.bytes_per_row() as u64;
    if job.color == ColorMode::Gray && info.color == ColorKind::Rgb {
        b += info.width as u64 * 2;
    }
    let (ow, oh) = job.method.output_size(info.width, 1);
    b += 2 * (ow * oh * planes_of(info, job)) as u64;
    // Two bands of each are in flight at once (see [`stream`]).
    2 * b
}

/// Reads a streamable input whole (for the whole-image way).
fn read_all(mut src: Box<dyn RowSource>) -> Result<Image> {
    let h = src.info().height;
    let mut img = source::empty_band(src.info());
    src.read_rows(h, &mut img)?;
    Ok(img)
}

/// Shrink-on-load: when the job resizes to much less than the image's `orig` size, asks
/// `src` for a smaller image (JPEG's DCT scaling), or else wraps it in a box shrink in
/// linear light ([`shrink::BoxShrink`]), by the same rule. The size asked for is the
/// output's, turned back to the image's orientation, so the resize after it only shrinks.
/// Returns the source and the factor it now shrinks by (1: not at all).
fn shrink_on_load(
    mut src: Box<dyn RowSource>,
    orig: (usize, usize),
    job: &Job<'_>,
) -> Result<(Box<dyn RowSource>, usize)> {
    let Some(p) = crate::resize::plan(job.size, orig.0, orig.1)? else {
        return Ok((src, 1));
    };
    let (w, h) = if p.turns % 2 == 1 {
        (p.scaled.1, p.scaled.0)
    } else {
        p.scaled
    };
    let d = src.shrink_to(w, h);
    if d > 1 {
        return Ok((src, d));
    }
    let f = shrink::shrink_factor(orig.0, orig.1, w, h);
    if f == 1 {
        return Ok((src, 1));
    }
    Ok((Box::new(shrink::BoxShrink::new(src, f, job.tone)), f))
}

/// The whole-image way.
fn whole(
    name: &Path,
    img: Image,
    estimate: u64,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    let from = Shrunk {
        full: (img.width, img.height),
        factor: 1,
        remainder_at: (true, true),
    };
    whole_from(name, img, from, estimate, job, enc, out, output)
}

/// The whole-image way for an image decoded from one of `from.full` size (larger when it
/// was shrunk on load): the output size is planned from the full size, as without the
/// shrink, and the resize reads the shrunk image over exactly the full image's extent.
#[allow(clippy::too_many_arguments)]
fn whole_from(
    name: &Path,
    mut img: Image,
    from: Shrunk,
    estimate: u64,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    let input = from.full;
    if let Some(plan) = crate::resize::plan(job.size, input.0, input.1)? {
        img = if from.factor > 1 {
            crate::resize::apply_shrunk(&img, &plan, job.tone, from)?
        } else {
            crate::resize::apply(&img, &plan, job.tone)?
        };
    }
    check_output_size(name, job, img.width, img.height)?;
    let h = halftone_image(&img, job.method, job.color, job.tone)?;
    drop(img);
    io::check_page(&PageHeader::of(&h, job.write.dpi), job.write, output)?;
    crate::io::sink::encode_halftone(enc, &h, job.write.dpi, out).map_err(|e| e.named(output))?;
    Ok(Report {
        input,
        output: (h.width, h.height),
        streamed: false,
        band_rows: input.1,
        bands: 1,
        estimate,
        assumed_dpi: None,
    })
}

/// The streaming way: bands of `rows` input rows from `src` through the method's row
/// method into `enc`.
///
/// Three stages overlap, each on its own thread and each taking the bands in page order, so
/// the bytes are those of one thread doing all three: a reader decodes band k + 1 while band
/// k is halftoned (its planes in parallel) and the output of band k − 1 is encoded and
/// written here. At most two input bands and two output bands exist at once; the plan
/// counts both.
#[allow(clippy::too_many_arguments)]
fn stream(
    input_name: &Path,
    mut src: Box<dyn RowSource>,
    rows: usize,
    estimate: u64,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    use std::sync::mpsc::{channel, sync_channel};
    let info = src.info().clone();
    check_output_size(input_name, job, info.width, info.height)?;
    let mut rm = job.method.rows().expect("planned for streaming");
    let (ow, oh) = job.method.output_size(info.width, info.height);
    let height = info.height;
    std::thread::scope(|s| {
        // Reader → halftoner: decoded bands; halftoner → reader: bands to reuse.
        let (band_tx, band_rx) = sync_channel::<Result<Image>>(0);
        let (spare_tx, spare_rx) = channel::<Image>();
        // Halftoner → here: output bands.
        let (ht_tx, ht_rx) = sync_channel::<Result<Halftone>>(0);
        let info_r = info.clone();
        s.spawn(move || {
            let mut y = 0;
            let mut made = 0;
            while y < height {
                let n = rows.min(height - y);
                // Two bands at most: a new one only until the first comes back.
                let mut band = if made < 2 {
                    made += 1;
                    source::empty_band(&info_r)
                } else {
                    match spare_rx.recv() {
                        Ok(b) => b,
                        Err(_) => return,
                    }
                };
                let read = src.read_rows(n, &mut band).map(|()| band);
                let failed = read.is_err();
                if band_tx.send(read).is_err() || failed {
                    return;
                }
                y += n;
            }
        });
        s.spawn(move || {
            let mut tables: Option<(u32, crate::tone::Encoding, ToneTable)> = None;
            for band in band_rx {
                let h = band.and_then(|band| {
                    let h = halftone_band(&band, &mut tables, rm.as_mut(), job);
                    // The reader may have finished: then the band is simply dropped.
                    let _ = spare_tx.send(band);
                    h
                });
                let failed = h.is_err();
                if ht_tx.send(h).is_err() || failed {
                    return;
                }
            }
        });
        let (mut y_out, mut bands) = (0, 0);
        for h in ht_rx {
            let h = h?;
            if bands == 0 {
                let page = PageHeader {
                    width: ow,
                    height: oh,
                    channels: h.channels(),
                    levels: h.levels,
                    bits: h.bits,
                    stride: h.stride,
                    palette: h.palette.clone(),
                    dpi: job.write.dpi,
                };
                io::check_page(&page, job.write, output)?;
                enc.begin_page(&page, out).map_err(|e| e.named(output))?;
            }
            let planes: Vec<&[u8]> = h.planes.iter().map(Vec::as_slice).collect();
            enc.write_rows(
                &Band {
                    y: y_out,
                    rows: h.height,
                    planes: &planes,
                },
                out,
            )
            .map_err(|e| e.named(output))?;
            y_out += h.height;
            bands += 1;
        }
        enc.end_page(out).map_err(|e| e.named(output))?;
        Ok(Report {
            input: (info.width, info.height),
            output: (ow, oh),
            streamed: true,
            band_rows: rows,
            bands,
            estimate,
            assumed_dpi: None,
        })
    })
}

/// One band through colour, tone and the row method, as [`crate::halftone_image`] does for
/// a whole image. The tone table is built once, from the first band.
fn halftone_band(
    band: &Image,
    tables: &mut Option<(u32, crate::tone::Encoding, ToneTable)>,
    rm: &mut dyn RowMethod,
    job: &Job<'_>,
) -> Result<Halftone> {
    let gray;
    let src = match (job.color, band.color) {
        (ColorMode::Gray, ColorKind::Rgb) => {
            gray = band.to_luminance(job.tone);
            &gray
        }
        _ => band,
    };
    let key = (src.bits(), src.encoding);
    if tables.as_ref().is_none_or(|t| (t.0, t.1) != key) {
        *tables = Some((key.0, key.1, src.tone_table(job.tone)));
    }
    let table = &tables.as_ref().expect("set above").2;
    let mut planes = src.planes(table);
    if job.color == ColorMode::Rgb && planes.planes.len() == 1 {
        let p = planes.planes[0];
        planes.planes = vec![p, p, p];
    }
    rm.next_band(&planes)
}
