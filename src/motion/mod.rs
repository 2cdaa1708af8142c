//! Pictures that move: clips in, clips out, halftoned frame by frame without flicker.
//!
//! A clip is a [`FrameSource`] (an animated GIF, APNG or WebP, a YUV4MPEG2 stream, a
//! numbered series of files) that yields one decoded [`Frame`] at a time, and a
//! [`FrameSink`] (an animated GIF, an APNG, a YUV4MPEG2 stream, a series of files with the
//! changed windows of each frame listed) that takes one halftone at a time. [`convert_clip`]
//! joins the two: memory holds a few frames whatever the clip's length.
//!
//! Methods whose dots depend on the pixel alone (threshold, ordered and blue-noise masks,
//! screens) are stable by construction: a pixel whose input does not change keeps its dot.
//! Error diffusion is not: a change anywhere reroutes the error downstream and every dot
//! after it moves. [`stable::StableDiffusion`] re-decides a dot only where the picture
//! changed enough for the eye to see it (see [`stable`]).
//!
//! When the source fails part-way (a truncated GIF or stream), the frames decoded before
//! the failure are halftoned and the output is finished and put in place with them; the
//! error is returned after that, naming the input and how many frames were written.

pub mod measure;
pub mod sink;
pub mod source;
pub mod stable;
pub mod y4m;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::options::{MethodKind, Options};
use crate::raster::{Halftone, Image};

pub use sink::{open_sink, ClipFormat, FrameSink};
pub use source::open_source;
pub use stable::StableDiffusion;
// How frames are halftoned in time: the option `temporal`, whose home is the options layer.
pub use crate::options::Temporal;

/// How long a frame is shown: `num / den` seconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delay {
    /// Numerator, seconds.
    pub num: u32,
    /// Denominator (never 0).
    pub den: u32,
}

impl Delay {
    /// A delay of `ms` milliseconds.
    pub fn ms(ms: u32) -> Delay {
        Delay { num: ms, den: 1000 }
    }

    /// The delay in seconds.
    pub fn seconds(self) -> f64 {
        self.num as f64 / self.den.max(1) as f64
    }
}

/// How often a clip plays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loops {
    /// Over and over.
    Forever,
    /// This many times in all (1: once).
    Plays(u32),
}

/// What a source knows of its clip before the first frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipInfo {
    /// Width of every frame.
    pub width: usize,
    /// Height of every frame.
    pub height: usize,
    /// How often the clip plays.
    pub loops: Loops,
    /// Frames a second (`num / den`), for streams that have a rate.
    pub rate: Option<(u32, u32)>,
}

/// One decoded frame: the whole picture (alpha composited over white), and how long it shows.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The picture.
    pub image: Image,
    /// How long it shows.
    pub delay: Delay,
}

/// What a clip conversion did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClipReport {
    /// Frames written.
    pub frames: usize,
    /// Output frame size.
    pub size: (usize, usize),
    /// Share of the output's dots that changed from one frame to the next, over all frames.
    pub changed: f64,
    /// The method, as reports name it.
    pub method: String,
}

/// The per-frame halftoner of a clip: the options' method frame by frame, or stable error
/// diffusion with its state from the previous frame.
pub struct ClipMethod {
    method: Box<dyn crate::Method>,
    stable: Option<StableDiffusion>,
    color: crate::raster::ColorMode,
    tone: crate::tone::ToneOptions,
    opts: Options,
}

impl ClipMethod {
    /// Builds the method of `opts` with its `temporal` handling. Stable diffusion covers
    /// grey and RGB levels with a fixed kernel; a palette, a device or another kernel is
    /// halftoned frame by frame (still stable for the methods that are stable by construction).
    pub fn new(opts: &Options) -> Result<ClipMethod> {
        let method = opts.method()?;
        let stable = if opts.temporal == Temporal::Stable && StableDiffusion::applies(opts) {
            Some(StableDiffusion::new(opts)?)
        } else {
            None
        };
        Ok(ClipMethod {
            method,
            stable,
            color: opts.color_mode(),
            tone: opts.tone()?,
            opts: opts.clone(),
        })
    }

    /// The method's name for reports.
    pub fn name(&self) -> String {
        match &self.stable {
            Some(s) => s.name(),
            None => self.method.name(),
        }
    }

    /// Halftones the next frame of the clip (resized as the options ask).
    pub fn next(&mut self, img: &Image) -> Result<Halftone> {
        let size = self.opts.size_request();
        let resized;
        let img = match crate::resize::plan(&size, img.width, img.height)? {
            Some(plan) => {
                resized = crate::resize::apply(img, &plan, &self.tone)?;
                &resized
            }
            None => img,
        };
        match &mut self.stable {
            Some(s) => s.next(img, self.color, &self.tone),
            None => {
                crate::pipeline::halftone_image(img, self.method.as_ref(), self.color, &self.tone)
            }
        }
    }
}

/// Halftones every frame of `source` into `sink` with `method`, then finishes the sink.
/// When the source fails part-way, the frames before the failure are finished and written,
/// and the error then says so.
///
/// Reading, halftoning and writing overlap: the source is read on a thread of its own and
/// the sink written on another, each at most two frames ahead or behind, so memory stays a
/// few frames whatever the clip's length. The frames go through in order, so the bytes are
/// those of one thread doing all three in turn.
pub fn convert_clip(
    source: &mut dyn FrameSource,
    sink: &mut dyn FrameSink,
    method: &mut ClipMethod,
) -> Result<ClipReport> {
    use std::sync::mpsc::sync_channel;
    let mut report = ClipReport {
        method: method.name(),
        ..ClipReport::default()
    };
    let mut failed = None;
    let mut changed = 0u64;
    let mut dots = 0u64;
    let name = source.name().to_path_buf();
    std::thread::scope(|scope| -> Result<()> {
        let (frames_in, frames) = sync_channel::<(Result<Option<Frame>>, ClipInfo)>(2);
        let read = move |src: &mut (dyn FrameSource + Send)| loop {
            let f = src.next_frame();
            let last = !matches!(f, Ok(Some(_)));
            if frames_in.send((f, src.info().clone())).is_err() || last {
                break;
            }
        };
        // A source that cannot go to another thread is read a frame at a time below.
        let mut inline = None;
        if source.sendable().is_some() {
            let src = source.sendable().expect("asked just above");
            scope.spawn(move || read(src));
        } else {
            inline = Some(&mut *source);
        }
        let mut next = || match inline.as_deref_mut() {
            Some(src) => {
                let f = src.next_frame();
                Some((f, src.info().clone()))
            }
            None => frames.recv().ok(),
        };
        let (halftones, written) = sync_channel::<(Halftone, Delay, ClipInfo)>(2);
        let snk = &mut *sink;
        let writer = scope.spawn(move || -> Result<()> {
            for (h, delay, info) in written {
                snk.frame(&h, delay, &info)?;
            }
            Ok(())
        });
        let mut prev: Option<Halftone> = None;
        let mut sent = Ok(());
        while let Some((frame, info)) = next() {
            let frame = match frame {
                Ok(Some(f)) => f,
                Ok(None) => break,
                Err(e) => {
                    failed = Some(e);
                    break;
                }
            };
            let h = method.next(&frame.image)?;
            if let Some(p) = &prev {
                changed += changed_dots(p, &h);
                dots += (h.width * h.height * h.channels()) as u64;
            }
            report.size = (h.width, h.height);
            // The writer keeps its own copy; the method's next frame is compared to this.
            sent = halftones.send((h.clone(), frame.delay, info));
            if sent.is_err() {
                break; // the writer failed: its error is taken below
            }
            report.frames += 1;
            prev = Some(h);
        }
        drop(halftones);
        let wrote = writer
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        wrote?;
        debug_assert!(sent.is_ok());
        Ok(())
    })?;
    sink.finish(source.info())?;
    report.changed = if dots == 0 {
        0.0
    } else {
        changed as f64 / dots as f64
    };
    match failed {
        None => Ok(report),
        Some(e) => Err(after_frames(e, report.frames, &name)),
    }
}

/// A source's failure after `n` frames, saying the frames before it were written.
fn after_frames(e: Error, n: usize, name: &Path) -> Error {
    let what = match n {
        0 => "no complete frame to write".to_string(),
        1 => "the 1 complete frame before it was written".to_string(),
        n => format!("the {n} complete frames before it were written"),
    };
    match e {
        Error::Decode { path, msg } => Error::Decode {
            path,
            msg: format!("{msg}; {what}"),
        },
        Error::Io { path, cause } => Error::Decode {
            path,
            msg: format!("{cause}; {what}"),
        },
        other => Error::Decode {
            path: name.to_path_buf(),
            msg: format!("{other}; {what}"),
        },
    }
}

/// Dots (samples) that differ between two halftones of one size.
pub fn changed_dots(a: &Halftone, b: &Halftone) -> u64 {
    if (a.width, a.height, a.channels()) != (b.width, b.height, b.channels()) {
        return (b.width * b.height * b.channels()) as u64;
    }
    let mut n = 0u64;
    if a.bits == 1 && b.bits == 1 {
        // One bit a dot: the differing bits of the packed rows (the padding masked off).
        let full = a.width / 8;
        let tail = (a.width % 8) as u32;
        for c in 0..a.channels() {
            for y in 0..a.height {
                let (ra, rb) = (a.row(c, y), b.row(c, y));
                if ra == rb {
                    continue;
                }
                n += ra[..full]
                    .iter()
                    .zip(&rb[..full])
                    .map(|(p, q)| (p ^ q).count_ones() as u64)
                    .sum::<u64>();
                if tail > 0 {
                    let mask = !(0xffu8 >> tail);
                    n += ((ra[full] ^ rb[full]) & mask).count_ones() as u64;
                }
            }
        }
        return n;
    }
    let mut ra = vec![0u8; a.width];
    let mut rb = vec![0u8; a.width];
    for c in 0..a.channels() {
        for y in 0..a.height {
            if a.row(c, y) == b.row(c, y) {
                continue;
            }
            a.unpack_row(c, y, &mut ra);
            b.unpack_row(c, y, &mut rb);
            n += ra.iter().zip(&rb).filter(|(x, y)| x != y).count() as u64;
        }
    }
    n
}

/// A one-line decode error naming the input.
pub(crate) fn decode_err(name: &Path, msg: String) -> Error {
    Error::Decode {
        path: name.to_path_buf(),
        msg: msg.replace(['\n', '\r'], " "),
    }
}

/// Refuses frames over the pixel limit, from a header's dimensions.
pub(crate) fn check_pixels(
    name: &Path,
    width: u32,
    height: u32,
    opts: &crate::io::ReadOptions,
) -> Result<()> {
    let pixels = width as u64 * height as u64;
    if pixels > opts.max_pixels {
        return Err(Error::TooLarge {
            path: name.to_path_buf(),
            width: width as u64,
            height: height as u64,
            pixels,
            limit: opts.max_pixels,
        });
    }
    Ok(())
}

/// True when a path names a numbered series of files (`frames/%04d.png`).
pub fn is_series(path: &Path) -> bool {
    series_pattern(path).is_some()
}

/// The parts of a series pattern: text before the number, the number's width (0: as
/// many digits as it takes), text after it.
pub(crate) fn series_pattern(path: &Path) -> Option<(String, usize, String)> {
    let s = path.to_str()?;
    let at = s.find('%')?;
    let rest = &s[at + 1..];
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    let after = rest[digits.len()..].strip_prefix('d')?;
    if after.contains('%') {
        return None;
    }
    let width = if digits.is_empty() {
        0
    } else {
        digits.parse().ok()?
    };
    Some((s[..at].to_string(), width.min(12), after.to_string()))
}

/// The file of frame `n` of a series pattern.
pub(crate) fn series_path(pattern: &(String, usize, String), n: usize) -> PathBuf {
    PathBuf::from(format!(
        "{}{:0w$}{}",
        pattern.0,
        n,
        pattern.2,
        w = pattern.1
    ))
}

/// True when the method of `opts` is error diffusion (the one that needs [`Temporal`]).
pub fn is_diffusion(opts: &Options) -> bool {
    opts.method == MethodKind::Diffuse
}

/// A clip's frames, one at a time.
pub trait FrameSource {
    /// The clip's size, loop count and rate.
    fn info(&self) -> &ClipInfo;
    /// The name used in messages.
    fn name(&self) -> &Path;
    /// The next frame; `None` after the last.
    fn next_frame(&mut self) -> Result<Option<Frame>>;
    /// The source as one that may be read on another thread ([`convert_clip`] reads ahead
    /// on one), when it is such.
    fn sendable(&mut self) -> Option<&mut (dyn FrameSource + Send)> {
        None
    }
}

/// Reads exactly `buf.len()` bytes; the count read, short only at the end of the stream.
pub(crate) fn read_full(r: &mut dyn std::io::Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_patterns() {
        let p = series_pattern(Path::new("out/f%04d.png")).unwrap();
        assert_eq!(p, ("out/f".into(), 4, ".png".into()));
        assert_eq!(series_path(&p, 7), PathBuf::from("out/f0007.png"));
        assert!(series_pattern(Path::new("a%d.pbm")).is_some());
        assert!(series_pattern(Path::new("plain.png")).is_none());
        assert!(series_pattern(Path::new("a%s.png")).is_none());
    }
}
