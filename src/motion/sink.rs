//! Frame sinks: animated GIF, YUV4MPEG2 and numbered series of files (any still
//! format, panel buffers among them, with each frame's changed windows listed).
//!
//! GIF and APNG store a frame as the rectangle that changed from the frame shown before
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
pub trait FrameSink: Send {
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
    /// Animated PNG.
    Apng,
    /// A numbered series of files of a still format (`frames/%04d.png`).
    Series(Format),
}

impl ClipFormat {
    /// The clip format for a still-image format name, if it is one.
    pub fn of(format: Format) -> Option<ClipFormat> {
        match format {
            Format::Gif => Some(ClipFormat::Gif),
            Format::Y4m => Some(ClipFormat::Y4m),
            Format::Apng => Some(ClipFormat::Apng),
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
        ClipFormat::Apng => Box::new(ApngSink {
            out,
            name,
            display,
            differ: Differ::default(),
            spool: None,
            seq: 0,
            frames: 0,
            colours: 0,
            size: (0, 0),
            palette: Vec::new(),
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
            // The transparent index (one past the colours) gets an entry of its own, so
            // no frame holds an index outside the colour table.
            let mut pal: Vec<u8> = colours_of(h, self.display).concat();
            if n < 256 {
                pal.extend_from_slice(&[0, 0, 0]);
            }
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

/// Animated PNG: a palette image (1, 2, 4 or 8 bits a pixel), each frame after the first
/// cropped to the rectangle that changed, its unchanged pixels transparent and blended
/// over the frame before. The frame count comes first in the file (`acTL`), so the frames'
/// chunks are spooled to an unnamed temp file and copied out at the end: memory holds a
/// frame or two whatever the clip's length, and a pipe can take the result.
struct ApngSink {
    out: Out,
    name: PathBuf,
    display: Encoding,
    differ: Differ,
    spool: Option<std::io::BufWriter<std::fs::File>>,
    /// The next sequence number of `fcTL` and `fdAT` chunks.
    seq: u32,
    frames: u32,
    colours: usize,
    size: (usize, usize),
    palette: Vec<[u8; 3]>,
}

/// Writes one PNG chunk.
fn chunk(out: &mut dyn Write, kind: &[u8; 4], data: &[u8]) -> std::io::Result<()> {
    out.write_all(&(data.len() as u32).to_be_bytes())?;
    out.write_all(kind)?;
    out.write_all(data)?;
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    out.write_all(&crc.finalize().to_be_bytes())
}

/// Bits a pixel for `n` palette entries.
fn png_depth(n: usize) -> u8 {
    match n {
        0..=2 => 1,
        3..=4 => 2,
        5..=16 => 4,
        _ => 8,
    }
}

/// An unnamed temp file (removed from its folder at once where the system allows).
fn spool_file() -> std::io::Result<std::fs::File> {
    // No global counter (the library keeps no mutable state): the clock's nanoseconds and
    // the attempt tell apart the spool files of one process; `create_new` settles the rest.
    let dir = std::env::temp_dir();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    for k in 0..100u32 {
        let path = dir.join(format!(".halftone-apng-{}-{nanos}-{k}", std::process::id(),));
        match std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(f) => {
                let _ = std::fs::remove_file(&path);
                return Ok(f);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no temp file name free"))
}

impl ApngSink {
    fn write(&mut self, p: Pending, before: &[u8]) -> std::io::Result<()> {
        let w = self.size.0;
        let [x0, y0, x1, y1] = p.rect;
        let first = before.is_empty();
        let transparent = (!first && self.colours < 256).then_some(self.colours as u8);
        let depth = png_depth(self.colours + (self.colours < 256) as usize);
        let per = 8 / depth as usize;
        let (fw, fh) = (x1 - x0, y1 - y0);
        let stride = fw.div_ceil(per);
        let mut raw = Vec::with_capacity((stride + 1) * fh);
        for y in y0..y1 {
            raw.push(0u8);
            let row = &p.idx[y * w + x0..y * w + x1];
            let old = (!first).then(|| &before[y * w + x0..y * w + x1]);
            let at = raw.len();
            raw.resize(at + stride, 0);
            for (i, &n) in row.iter().enumerate() {
                let v = match (transparent, old) {
                    (Some(t), Some(o)) if o[i] == n => t,
                    _ => n,
                };
                let shift = 8 - depth as usize * (i % per + 1);
                raw[at + i / per] |= v << shift;
            }
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(&raw)?;
        let data = z.finish()?;
        // Milliseconds from start to end, rounded at both ends (no drift).
        let ms = ((p.end * 1000.0).round() - (p.start * 1000.0).round()).clamp(0.0, 65535.0);
        let spool = self.spool.as_mut().expect("started");
        let mut fctl = Vec::with_capacity(26);
        fctl.extend_from_slice(&self.seq.to_be_bytes());
        for v in [fw, fh, x0, y0] {
            fctl.extend_from_slice(&(v as u32).to_be_bytes());
        }
        fctl.extend_from_slice(&(ms as u16).to_be_bytes());
        fctl.extend_from_slice(&1000u16.to_be_bytes());
        // Dispose: none; blend: over the frame before where transparent, else source.
        fctl.push(0);
        fctl.push(transparent.is_some() as u8);
        chunk(spool, b"fcTL", &fctl)?;
        self.seq += 1;
        if first {
            chunk(spool, b"IDAT", &data)?;
        } else {
            let mut fdat = Vec::with_capacity(data.len() + 4);
            fdat.extend_from_slice(&self.seq.to_be_bytes());
            fdat.extend_from_slice(&data);
            chunk(spool, b"fdAT", &fdat)?;
            self.seq += 1;
        }
        self.frames += 1;
        Ok(())
    }

    fn io(&self, e: std::io::Error) -> Error {
        Error::io(&self.name, e)
    }
}

impl FrameSink for ApngSink {
    fn frame(&mut self, h: &Halftone, delay: Delay, _info: &ClipInfo) -> Result<()> {
        let (idx, n) = indices(h, 256, &self.name, "APNG")?;
        if self.spool.is_none() {
            let f = spool_file().map_err(|e| self.io(e))?;
            self.spool = Some(std::io::BufWriter::with_capacity(1 << 16, f));
            self.palette = colours_of(h, self.display);
            self.colours = n;
            self.size = (h.width, h.height);
        }
        if (h.width, h.height) != self.size {
            return Err(Error::Encode {
                path: self.name.clone(),
                msg: "the frames of a clip share one size".into(),
            });
        }
        if let Some((p, before)) = self.differ.push(idx, h.width, delay) {
            self.write(p, &before).map_err(|e| self.io(e))?;
        }
        Ok(())
    }

    fn finish(&mut self, info: &ClipInfo) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        if let Some((p, before)) = self.differ.finish() {
            self.write(p, &before).map_err(|e| self.io(e))?;
        }
        let Some(spool) = self.spool.take() else {
            return Err(Error::Encode {
                path: self.name.clone(),
                msg: "no frame to write".into(),
            });
        };
        let mut spool = spool.into_inner().map_err(|e| self.io(e.into_error()))?;
        let name = self.name.clone();
        let io = |e: std::io::Error| Error::io(&name, e);
        let out = &mut self.out;
        out.write_all(b"\x89PNG\r\n\x1a\n").map_err(io)?;
        let (w, h) = self.size;
        // Room for the transparent index of the frames after the first.
        let depth = png_depth(self.colours + (self.colours < 256) as usize);
        let mut ihdr = Vec::with_capacity(13);
        ihdr.extend_from_slice(&(w as u32).to_be_bytes());
        ihdr.extend_from_slice(&(h as u32).to_be_bytes());
        ihdr.extend_from_slice(&[depth, 3, 0, 0, 0]);
        chunk(out, b"IHDR", &ihdr).map_err(io)?;
        let plays = match info.loops {
            Loops::Forever => 0,
            Loops::Plays(n) => n.max(1),
        };
        let mut actl = self.frames.to_be_bytes().to_vec();
        actl.extend_from_slice(&plays.to_be_bytes());
        chunk(out, b"acTL", &actl).map_err(io)?;
        let mut plte: Vec<u8> = self.palette.concat();
        let mut trns = vec![255u8; self.palette.len()];
        if self.colours < 256 {
            plte.extend_from_slice(&[0, 0, 0]);
            trns.push(0);
        }
        chunk(out, b"PLTE", &plte).map_err(io)?;
        chunk(out, b"tRNS", &trns).map_err(io)?;
        spool.seek(SeekFrom::Start(0)).map_err(io)?;
        std::io::copy(&mut spool, out).map_err(io)?;
        chunk(out, b"IEND", &[]).map_err(io)?;
        self.out.commit(&self.name)
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
