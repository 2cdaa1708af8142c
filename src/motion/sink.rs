//! Frame sinks: animated GIF, YUV4MPEG2 and numbered series of files (any still
//! format, panel buffers among them, with each frame's changed windows listed).
//!
//! GIF stores a frame as the rectangle that changed from the frame shown before
//! it and marks the pixels inside it that did not change as transparent (runs the LZW
//! coder packs to almost nothing). A frame identical to the one before is not stored: its
//! time is added to that frame's delay. Files are replaced atomically when finished
//! (a failure leaves nothing); pipes are written straight.

use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::y4m::{colours_of, Y4mWriter};
use super::{ClipInfo, Delay, Loops};
use crate::api::Output;
use crate::error::{Error, Result};
use crate::io::{Format, OutputFile, WriteOptions};
use crate::options::Options;
use crate::raster::Halftone;
use crate::tone::Encoding;

/// Where a clip's halftones go, one at a time.
pub trait FrameSink {
    /// Takes the next frame, shown for `delay`.
    fn frame(&mut self, h: &Halftone, delay: Delay, info: &ClipInfo) -> Result<()>;
    /// Writes what remains and puts the file in place.
    fn finish(&mut self, info: &ClipInfo) -> Result<()>;
}

/// The clip formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClipFormat {
    /// Animated GIF.
    Gif,
    /// A YUV4MPEG2 stream.
    Y4m,
    /// A numbered series of files of a still format (`frames/%04d.png`).
    Series(Format),
}

impl ClipFormat {
    /// The clip format for a still-image format name, if it is one.
    pub fn of(format: Format) -> Option<ClipFormat> {
        match format {
            Format::Gif => Some(ClipFormat::Gif),
            Format::Y4m => Some(ClipFormat::Y4m),
            _ => None,
        }
    }
}

/// An output being written: a file (atomically) or a stream.
enum Out {
    File(OutputFile),
    Stream(Box<dyn Write + Send>),
    Done,
}

impl Out {
    fn open(output: Output) -> Result<(Out, PathBuf)> {
        Ok(match output {
            Output::Path(p) => (Out::File(OutputFile::create(&p)?), p),
            Output::Writer { writer, name } => (Out::Stream(writer), PathBuf::from(name)),
        })
    }

    fn commit(&mut self, name: &Path) -> Result<()> {
        match std::mem::replace(self, Out::Done) {
            Out::File(f) => f.commit(),
            Out::Stream(mut w) => w.flush().map_err(|e| Error::io(name, e)),
            Out::Done => Ok(()),
        }
    }
}

impl Write for Out {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Out::File(f) => f.write(buf),
            Out::Stream(w) => w.write(buf),
            Out::Done => Err(std::io::Error::other("written after the end")),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        match self {
            Out::File(f) => f.write_all(buf),
            Out::Stream(w) => w.write_all(buf),
            Out::Done => Err(std::io::Error::other("written after the end")),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Out::File(f) => f.flush(),
            Out::Stream(w) => w.flush(),
            Out::Done => Ok(()),
        }
    }
}

/// Opens the sink of `format` writing to `output` (a series: `output` is the pattern).
pub fn open_sink(output: Output, format: ClipFormat, opts: &Options) -> Result<Box<dyn FrameSink>> {
    let display = if opts.linearize {
        Encoding::Srgb
    } else {
        Encoding::Linear
    };
    if let ClipFormat::Series(f) = format {
        let Output::Path(p) = output else {
            return Err(Error::Invalid(
                "a series of files is written to a pattern such as frames/%04d.png".into(),
            ));
        };
        return Ok(Box::new(SeriesSink::new(&p, opts.write_options(f))?));
    }
    let (out, name) = Out::open(output)?;
    Ok(match format {
        ClipFormat::Gif => Box::new(GifSink {
            enc: None,
            out: Some(out),
            name,
            display,
            differ: Differ::default(),
            colours: 0,
        }),
        ClipFormat::Y4m => Box::new(Y4mSink {
            out,
            name,
            display,
            writer: Y4mWriter::new(),
        }),
        ClipFormat::Series(_) => unreachable!("handled above"),
    })
}

/// A frame's pixels as one index a pixel into [`colours_of`], refusing more than
/// `max` colours.
fn indices(h: &Halftone, max: usize, name: &Path, what: &str) -> Result<(Vec<u8>, usize)> {
    let n = if h.palette.is_some() {
        h.palette.as_ref().map_or(0, |p| p.len())
    } else if h.channels() == 1 {
        h.levels as usize
    } else {
        (h.levels as usize).pow(3)
    };
    if n > max {
        return Err(Error::Encode {
            path: name.to_path_buf(),
            msg: format!("{what} holds at most {max} colours; this halftone has {n} (use fewer levels or a palette)"),
        });
    }
    let w = h.width;
    let mut idx = vec![0u8; w * h.height];
    let mut tmp = vec![0u8; w];
    for y in 0..h.height {
        let row = &mut idx[y * w..(y + 1) * w];
        if h.channels() == 1 {
            h.unpack_row(0, y, row);
        } else {
            for c in 0..3 {
                h.unpack_row(c, y, &mut tmp);
                for (o, &t) in row.iter_mut().zip(&tmp) {
                    *o = *o * h.levels as u8 + t;
                }
            }
        }
    }
    Ok((idx, n))
}

/// A frame waiting to be written: its indices, the rectangle that changed from the frame
/// shown before it (x0, y0, x1, y1), and its start and end times in seconds.
struct Pending {
    idx: Vec<u8>,
    rect: [usize; 4],
    start: f64,
    end: f64,
}

/// Tracks what is on screen and holds back one frame, so that repeats become delay.
#[derive(Default)]
struct Differ {
    /// What is shown before the pending frame (empty before the first).
    shown: Vec<u8>,
    pending: Option<Pending>,
    width: usize,
    clock: f64,
}

impl Differ {
    /// Takes a frame; returns the frame that is now complete, with what was shown before it.
    fn push(&mut self, idx: Vec<u8>, width: usize, delay: Delay) -> Option<(Pending, Vec<u8>)> {
        let start = self.clock;
        self.clock += delay.seconds();
        let end = self.clock;
        let Some(p) = self.pending.as_mut() else {
            self.width = width;
            let h = idx.len() / width.max(1);
            self.pending = Some(Pending {
                idx,
                rect: [0, 0, width, h],
                start,
                end,
            });
            return None;
        };
        match changed_rect(&p.idx, &idx, self.width) {
            None => {
                p.end = end;
                None
            }
            Some(rect) => {
                let next = Pending {
                    idx,
                    rect,
                    start,
                    end,
                };
                let done = self.pending.replace(next).expect("pending");
                let before = std::mem::replace(&mut self.shown, done.idx.clone());
                Some((done, before))
            }
        }
    }

    /// The last frame, at the end.
    fn finish(&mut self) -> Option<(Pending, Vec<u8>)> {
        let p = self.pending.take()?;
        let before = std::mem::take(&mut self.shown);
        Some((p, before))
    }
}

/// The bounding rectangle of the pixels that differ, `None` when none do.
fn changed_rect(a: &[u8], b: &[u8], w: usize) -> Option<[usize; 4]> {
    let h = a.len() / w.max(1);
    let rows: Vec<usize> = (0..h)
        .filter(|&y| a[y * w..(y + 1) * w] != b[y * w..(y + 1) * w])
        .collect();
    let (&y0, &y1) = (rows.first()?, rows.last()?);
    let (mut x0, mut x1) = (w, 0);
    for &y in &rows {
        let (ra, rb) = (&a[y * w..(y + 1) * w], &b[y * w..(y + 1) * w]);
        if let Some(f) = ra.iter().zip(rb).position(|(p, q)| p != q) {
            x0 = x0.min(f);
        }
        if let Some(l) = ra.iter().zip(rb).rposition(|(p, q)| p != q) {
            x1 = x1.max(l + 1);
        }
    }
    Some([x0, y0, x1, y1 + 1])
}

/// Whole hundredths of a second from `start` to `end` (rounded at both ends, so the
/// clip's total time never drifts).
fn centiseconds(start: f64, end: f64) -> u16 {
    ((end * 100.0).round() - (start * 100.0).round()).clamp(0.0, 65535.0) as u16
}

/// Animated GIF.
struct GifSink {
    enc: Option<gif::Encoder<Out>>,
    out: Option<Out>,
    name: PathBuf,
    display: Encoding,
    differ: Differ,
    colours: usize,
}

impl GifSink {
    fn gif_err(&self, e: gif::EncodingError) -> Error {
        match e {
            gif::EncodingError::Io(e) => Error::io(&self.name, e),
            other => Error::Encode {
                path: self.name.clone(),
                msg: other.to_string(),
            },
        }
    }

    fn write(&mut self, p: Pending, before: &[u8], colours: usize) -> Result<()> {
        let enc = self.enc.as_mut().expect("started");
        let w = self.differ.width;
        let [x0, y0, x1, y1] = p.rect;
        let transparent = (colours < 256 && !before.is_empty()).then_some(colours as u8);
        let mut buf = Vec::with_capacity((x1 - x0) * (y1 - y0));
        for y in y0..y1 {
            let row = &p.idx[y * w + x0..y * w + x1];
            match transparent {
                Some(t) => {
                    let old = &before[y * w + x0..y * w + x1];
                    buf.extend(
                        row.iter()
                            .zip(old)
                            .map(|(&n, &o)| if n == o { t } else { n }),
                    );
                }
                None => buf.extend_from_slice(row),
            }
        }
        let frame = gif::Frame {
            delay: centiseconds(p.start, p.end),
            dispose: gif::DisposalMethod::Keep,
            transparent,
            left: x0 as u16,
            top: y0 as u16,
            width: (x1 - x0) as u16,
            height: (y1 - y0) as u16,
            buffer: Cow::Owned(buf),
            ..gif::Frame::default()
        };
        let r = enc.write_frame(&frame);
        r.map_err(|e| self.gif_err(e))
    }
}

impl FrameSink for GifSink {
    fn frame(&mut self, h: &Halftone, delay: Delay, info: &ClipInfo) -> Result<()> {
        if h.width > 65535 || h.height > 65535 {
            return Err(Error::Encode {
                path: self.name.clone(),
                msg: format!(
                    "GIF frames are at most 65535x65535, not {}x{}",
                    h.width, h.height
                ),
            });
        }
        let (idx, n) = indices(h, 256, &self.name, "GIF")?;
        if self.enc.is_none() {
            let pal: Vec<u8> = colours_of(h, self.display).concat();
            let out = self.out.take().expect("open");
            let mut enc = gif::Encoder::new(out, h.width as u16, h.height as u16, &pal)
                .map_err(|e| self.gif_err(e))?;
            let repeat = match info.loops {
                Loops::Forever => gif::Repeat::Infinite,
                Loops::Plays(n) => gif::Repeat::Finite(n.saturating_sub(1).min(65535) as u16),
            };
            enc.set_repeat(repeat).map_err(|e| self.gif_err(e))?;
            self.enc = Some(enc);
        }
        if let Some((p, before)) = self.differ.push(idx, h.width, delay) {
            self.write(p, &before, n)?;
        }
        self.colours = n;
        Ok(())
    }

    fn finish(&mut self, _info: &ClipInfo) -> Result<()> {
        if let Some((p, before)) = self.differ.finish() {
            self.write(p, &before, self.colours)?;
        }
        let Some(enc) = self.enc.take() else {
            return Err(Error::Encode {
                path: self.name.clone(),
                msg: "no frame to write".into(),
            });
        };
        let mut out = enc.into_inner().map_err(|e| self.gif_err(e))?;
        out.commit(&self.name)
    }
}

/// A YUV4MPEG2 stream.
struct Y4mSink {
    out: Out,
    name: PathBuf,
    display: Encoding,
    writer: Y4mWriter,
}

impl FrameSink for Y4mSink {
    fn frame(&mut self, h: &Halftone, delay: Delay, info: &ClipInfo) -> Result<()> {
        if h.channels() != 1 || h.palette.is_some() {
            indices(h, 256, &self.name, "this stream")?;
        }
        self.writer
            .frame(h, delay, info, self.display, &mut self.out)
            .map_err(|e| Error::io(&self.name, e))
    }

    fn finish(&mut self, _info: &ClipInfo) -> Result<()> {
        self.out.commit(&self.name)
    }
}

/// A numbered series of files, each written atomically by the still writer of its
/// format, and beside them a list of the windows (x, y, w, h) that changed from each frame
/// to the next, for a panel's partial refresh: `PREFIX-windows.txt`.
struct SeriesSink {
    pattern: (String, usize, String),
    write: WriteOptions,
    next: usize,
    prev: Option<Halftone>,
    windows: String,
}

/// Rows a window band spans, and the column alignment of windows (a byte of 1-bit pixels).
const BAND: usize = 16;
const ALIGN: usize = 8;

impl SeriesSink {
    fn new(pattern: &Path, write: WriteOptions) -> Result<SeriesSink> {
        let p = super::series_pattern(pattern).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: a series is named with a number pattern such as frames/%04d.png",
                pattern.display()
            ))
        })?;
        Ok(SeriesSink {
            pattern: p,
            write,
            next: 0,
            prev: None,
            windows: "# frame x y w h: the windows that changed from the frame before (all of the first)\n".into(),
        })
    }

    fn windows_path(&self) -> PathBuf {
        let prefix = self.pattern.0.trim_end_matches(['-', '_', '.']);
        if prefix.is_empty() || prefix.ends_with('/') {
            PathBuf::from(format!("{prefix}windows.txt"))
        } else {
            PathBuf::from(format!("{prefix}-windows.txt"))
        }
    }
}

/// The windows (x, y, w, h) where `b` differs from `a`: bands of [`BAND`] rows, each
/// reduced to its changed columns aligned to [`ALIGN`], bands that overlap joined.
pub fn changed_windows(a: &Halftone, b: &Halftone) -> Vec<[usize; 4]> {
    let (w, h) = (b.width, b.height);
    if (a.width, a.height, a.channels()) != (w, h, b.channels()) {
        return vec![[0, 0, w, h]];
    }
    let mut ra = vec![0u8; w];
    let mut rb = vec![0u8; w];
    let mut out: Vec<[usize; 4]> = Vec::new();
    let mut y = 0;
    while y < h {
        let y1 = (y + BAND).min(h);
        let (mut x0, mut x1) = (w, 0);
        for c in 0..b.channels() {
            for yy in y..y1 {
                if a.row(c, yy) == b.row(c, yy) {
                    continue;
                }
                a.unpack_row(c, yy, &mut ra);
                b.unpack_row(c, yy, &mut rb);
                if let Some(f) = ra.iter().zip(&rb).position(|(p, q)| p != q) {
                    x0 = x0.min(f);
                }
                if let Some(l) = ra.iter().zip(&rb).rposition(|(p, q)| p != q) {
                    x1 = x1.max(l + 1);
                }
            }
        }
        if x1 > x0 {
            let (x0, x1) = (x0 / ALIGN * ALIGN, (x1.div_ceil(ALIGN) * ALIGN).min(w));
            match out.last_mut() {
                Some(r) if r[1] + r[3] == y && r[0] < x1 && x0 < r[0] + r[2] => {
                    let nx0 = r[0].min(x0);
                    let nx1 = (r[0] + r[2]).max(x1);
                    *r = [nx0, r[1], nx1 - nx0, y1 - r[1]];
                }
                _ => out.push([x0, y, x1 - x0, y1 - y]),
            }
        }
        y = y1;
    }
    out
}

impl FrameSink for SeriesSink {
    fn frame(&mut self, h: &Halftone, _delay: Delay, _info: &ClipInfo) -> Result<()> {
        let path = super::series_path(&self.pattern, self.next);
        crate::io::write_halftone(h, &path, &self.write)?;
        let windows = match &self.prev {
            None => vec![[0, 0, h.width, h.height]],
            Some(p) => changed_windows(p, h),
        };
        for [x, y, w, hh] in windows {
            self.windows
                .push_str(&format!("{} {x} {y} {w} {hh}\n", self.next));
        }
        self.next += 1;
        self.prev = Some(h.clone());
        Ok(())
    }

    fn finish(&mut self, _info: &ClipInfo) -> Result<()> {
        let path = self.windows_path();
        crate::io::write_atomic(&path, |w| w.write_all(self.windows.as_bytes()))
    }
}
