//! Frame sources: animated GIF (decoded here, disposal and all, from a file or a pipe),
//! APNG and animated WebP (through the `image` crate's animation decoders), YUV4MPEG2
//! streams ([`super::y4m`]), numbered series of files, and a still image as a clip of one
//! frame. Each holds the frame being made and, for GIF, the canvas and the copy that
//! disposal "previous" restores: a few frames, whatever the clip's length.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor};
use std::path::{Path, PathBuf};

use image::AnimationDecoder;

use super::FrameSource;
use super::{ClipInfo, Delay, Frame, Loops};
use crate::error::{Error, Result};
use crate::io::ReadOptions;
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::Encoding;

/// The delay of a frame of a series or a still (25 frames a second).
pub const SERIES_DELAY: Delay = Delay { num: 1, den: 25 };

/// What kind of clip some bytes start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// GIF (animated or not).
    Gif,
    /// PNG (APNG when it has an `acTL` chunk).
    Png,
    /// WebP (animated or not).
    Webp,
    /// A YUV4MPEG2 stream.
    Y4m,
    /// Something else: a still image for the still reader.
    Other,
}

/// The kind of clip that starts with `head`.
pub fn sniff(head: &[u8]) -> Kind {
    if head.starts_with(b"GIF8") {
        Kind::Gif
    } else if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        Kind::Png
    } else if head.len() >= 12 && &head[..4] == b"RIFF" && &head[8..12] == b"WEBP" {
        Kind::Webp
    } else if head.starts_with(b"YUV4MPEG2") {
        Kind::Y4m
    } else {
        Kind::Other
    }
}

/// Opens a clip: `-` is standard input, a path with `%d` (`frames/%04d.png`) a numbered
/// series, anything else a file of any kind [`sniff`] tells (a still image is a clip of one
/// frame). `gray`: the method works on grey, so a stream's colour need not be made.
pub fn open_source(input: &Path, opts: &ReadOptions, gray: bool) -> Result<Box<dyn FrameSource>> {
    if super::is_series(input) && !input.exists() {
        return Ok(Box::new(Series::open(input, opts)?));
    }
    if input.as_os_str() == "-" {
        let r = BufReader::with_capacity(1 << 20, std::io::stdin());
        return open_reader(Box::new(r), Path::new("<stdin>"), opts, gray);
    }
    let f = File::open(input).map_err(|e| Error::io(input, e))?;
    open_reader(
        Box::new(BufReader::with_capacity(1 << 20, f)),
        input,
        opts,
        gray,
    )
}

/// [`open_source`] for a stream already open.
pub fn open_reader(
    mut r: Box<dyn BufRead + Send>,
    name: &Path,
    opts: &ReadOptions,
    gray: bool,
) -> Result<Box<dyn FrameSource>> {
    let head = r.fill_buf().map_err(|e| Error::io(name, e))?.to_vec();
    let name = name.to_path_buf();
    match sniff(&head) {
        Kind::Gif => Ok(Box::new(GifSource::open(r, name, opts)?)),
        Kind::Y4m => Ok(Box::new(super::y4m::Y4mSource::open(r, name, opts, gray)?)),
        Kind::Png | Kind::Webp => {
            let bytes = crate::io::read_stream(&mut r, &name, opts)?;
            animated(bytes, name, opts)
        }
        Kind::Other => {
            let bytes = crate::io::read_stream(&mut r, &name, opts)?;
            let img = crate::io::read_image_bytes(&bytes, &name, opts)?;
            Ok(Box::new(Still::new(img, name)))
        }
    }
}

/// An APNG or animated WebP through `image`'s decoders; a still PNG or WebP as one frame.
fn animated(bytes: Vec<u8>, name: PathBuf, opts: &ReadOptions) -> Result<Box<dyn FrameSource>> {
    use image::ImageDecoder;
    let err = |e: image::ImageError| super::decode_err(&name, e.to_string());
    let still = |bytes: &[u8]| -> Result<Box<dyn FrameSource>> {
        let img = crate::io::read_image_bytes(bytes, &name, opts)?;
        Ok(Box::new(Still::new(img, name.clone())))
    };
    let (frames, loops, (w, h)) = match sniff(&bytes) {
        Kind::Png => {
            let dec =
                image::codecs::png::PngDecoder::new(Cursor::new(bytes.clone())).map_err(err)?;
            if !dec.is_apng().map_err(err)? {
                return still(&bytes);
            }
            let size = dec.dimensions();
            let apng = dec.apng().map_err(err)?;
            let loops = apng.loop_count();
            (apng.into_frames(), loops, size)
        }
        _ => {
            let dec =
                image::codecs::webp::WebPDecoder::new(Cursor::new(bytes.clone())).map_err(err)?;
            if !dec.has_animation() {
                return still(&bytes);
            }
            let size = dec.dimensions();
            let loops = dec.loop_count();
            (dec.into_frames(), loops, size)
        }
    };
    super::check_pixels(&name, w, h, opts)?;
    let loops = match loops {
        image::metadata::LoopCount::Infinite => Loops::Forever,
        image::metadata::LoopCount::Finite(n) => Loops::Plays(n.get()),
    };
    Ok(Box::new(Animated {
        frames,
        info: ClipInfo {
            width: w as usize,
            height: h as usize,
            loops,
            rate: None,
        },
        name,
    }))
}

/// Frames from `image`'s animation decoders (already composited on the canvas).
struct Animated {
    frames: image::Frames<'static>,
    info: ClipInfo,
    name: PathBuf,
}

impl FrameSource for Animated {
    fn info(&self) -> &ClipInfo {
        &self.info
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let Some(f) = self.frames.next() else {
            return Ok(None);
        };
        let f = f.map_err(|e| super::decode_err(&self.name, e.to_string()))?;
        let (n, d) = f.delay().numer_denom_ms();
        let delay = reduce(n, d.saturating_mul(1000));
        let buf = f.into_buffer();
        let (w, h) = (buf.width() as usize, buf.height() as usize);
        Ok(Some(Frame {
            image: rgba_over_white(buf.as_raw(), w, h),
            delay,
        }))
    }
}

/// `num / den` in lowest terms (a zero denominator reads as 1).
fn reduce(num: u32, den: u32) -> Delay {
    let den = den.max(1);
    let (mut a, mut b) = (num, den);
    while b != 0 {
        (a, b) = (b, a % b);
    }
    let g = a.max(1);
    Delay {
        num: num / g,
        den: den / g,
    }
}

/// An RGB image from RGBA samples, alpha composited over white (8-bit sRGB, as the still
/// reader does).
fn rgba_over_white(rgba: &[u8], w: usize, h: usize) -> Image {
    let mut planes = vec![vec![0u8; w * h]; 3];
    for (i, p) in rgba.chunks_exact(4).enumerate() {
        let a = p[3] as u32;
        for c in 0..3 {
            planes[c][i] = ((p[c] as u32 * a + 255 * (255 - a) + 127) / 255) as u8;
        }
    }
    Image {
        width: w,
        height: h,
        color: ColorKind::Rgb,
        planes: planes.into_iter().map(Samples::U8).collect(),
        encoding: Encoding::Srgb,
        dpi: None,
    }
}

/// An animated GIF decoded frame by frame from any reader, with each frame's disposal.
struct GifSource {
    dec: gif::Decoder<Box<dyn BufRead + Send>>,
    info: ClipInfo,
    name: PathBuf,
    /// The canvas, RGBA (alpha 0 where nothing was drawn: shown as white).
    canvas: Vec<u8>,
    /// The canvas before the last frame, when its disposal is "previous".
    saved: Option<Vec<u8>>,
    /// The last frame's disposal and rectangle, applied before the next frame is drawn.
    dispose: Option<(gif::DisposalMethod, [usize; 4])>,
    /// The frame's pixels, reused.
    buf: Vec<u8>,
    /// The first frame's descriptor was read at open.
    primed: bool,
}

impl GifSource {
    fn open(r: Box<dyn BufRead + Send>, name: PathBuf, opts: &ReadOptions) -> Result<GifSource> {
        let mut o = gif::DecodeOptions::new();
        o.set_color_output(gif::ColorOutput::RGBA);
        o.set_memory_limit(gif::MemoryLimit::Bytes(
            std::num::NonZeroU64::new(crate::io::max_input_bytes(opts).max(1 << 20))
                .expect("non-zero"),
        ));
        let err = |e: gif::DecodingError| super::decode_err(&name, e.to_string());
        let dec = o.read_info(r).map_err(err)?;
        let (w, h) = (dec.width() as usize, dec.height() as usize);
        super::check_pixels(&name, w as u32, h as u32, opts)?;
        if w == 0 || h == 0 {
            return Err(super::decode_err(
                &name,
                format!("the GIF is {w}x{h}: no pixels"),
            ));
        }
        let mut s = GifSource {
            dec,
            info: ClipInfo {
                width: w,
                height: h,
                loops: Loops::Plays(1),
                rate: None,
            },
            name,
            canvas: vec![0u8; w * h * 4],
            saved: None,
            dispose: None,
            buf: Vec::new(),
            primed: true,
        };
        // The loop count (NETSCAPE2.0) comes before the first frame: read up to it.
        s.dec
            .next_frame_info()
            .map_err(|e| super::decode_err(&s.name, e.to_string()))?;
        // Netscape's count is of repeats after the first play; 0 is forever.
        s.info.loops = match s.dec.repeat() {
            gif::Repeat::Infinite => Loops::Forever,
            gif::Repeat::Finite(n) => Loops::Plays(n as u32 + 1),
        };
        Ok(s)
    }
}

impl FrameSource for GifSource {
    fn info(&self) -> &ClipInfo {
        &self.info
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let name = self.name.clone();
        let err = |e: gif::DecodingError| super::decode_err(&name, e.to_string());
        let primed = std::mem::take(&mut self.primed);
        let next = if primed {
            self.dec.current_frame_info()
        } else {
            self.dec.next_frame_info().map_err(err)?
        };
        let Some(info) = next.cloned() else {
            return Ok(None);
        };
        let (cw, ch) = (self.info.width, self.info.height);
        // Cleared: the decoder leaves a pixel whose index is outside the colour table
        // untouched, so it reads as transparent rather than as the last frame's pixel.
        self.buf.clear();
        self.buf.resize(self.dec.buffer_size(), 0);
        self.dec.read_into_buffer(&mut self.buf).map_err(err)?;
        // The previous frame's disposal.
        match self.dispose.take() {
            Some((gif::DisposalMethod::Background, [x0, y0, x1, y1])) => {
                for y in y0..y1 {
                    self.canvas[(y * cw + x0) * 4..(y * cw + x1) * 4].fill(0);
                }
            }
            Some((gif::DisposalMethod::Previous, _)) => {
                if let Some(s) = self.saved.take() {
                    self.canvas = s;
                }
            }
            _ => {}
        }
        let (fl, ft) = (info.left as usize, info.top as usize);
        let (fw, fh) = (info.width as usize, info.height as usize);
        let rect = [fl.min(cw), ft.min(ch), (fl + fw).min(cw), (ft + fh).min(ch)];
        if info.dispose == gif::DisposalMethod::Previous {
            self.saved = Some(self.canvas.clone());
        }
        for y in rect[1]..rect[3] {
            let src = &self.buf[((y - ft) * fw) * 4..((y - ft) * fw + fw) * 4];
            for x in rect[0]..rect[2] {
                let p = &src[(x - fl) * 4..(x - fl) * 4 + 4];
                if p[3] != 0 {
                    self.canvas[(y * cw + x) * 4..(y * cw + x) * 4 + 4].copy_from_slice(p);
                }
            }
        }
        self.dispose = Some((info.dispose, rect));
        Ok(Some(Frame {
            image: rgba_over_white(&self.canvas, cw, ch),
            delay: Delay {
                num: info.delay as u32,
                den: 100,
            },
        }))
    }
    fn sendable(&mut self) -> Option<&mut (dyn FrameSource + Send)> {
        Some(self)
    }
}

/// A still image as a clip of one frame.
pub struct Still {
    img: Option<Image>,
    info: ClipInfo,
    name: PathBuf,
}

impl Still {
    /// A clip of `img` alone.
    pub fn new(img: Image, name: PathBuf) -> Still {
        Still {
            info: ClipInfo {
                width: img.width,
                height: img.height,
                loops: Loops::Plays(1),
                rate: None,
            },
            img: Some(img),
            name,
        }
    }
}

impl FrameSource for Still {
    fn info(&self) -> &ClipInfo {
        &self.info
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        Ok(self.img.take().map(|image| Frame {
            image,
            delay: SERIES_DELAY,
        }))
    }
    fn sendable(&mut self) -> Option<&mut (dyn FrameSource + Send)> {
        Some(self)
    }
}

/// Frames from a numbered series of files (`frames/%04d.png`), from 0 or 1 up to the
/// first number missing, each read by the still reader; every frame must have the first's
/// size.
pub struct Series {
    pattern: (String, usize, String),
    next: usize,
    first: Option<Image>,
    info: ClipInfo,
    name: PathBuf,
    opts: ReadOptions,
}

impl Series {
    /// Opens the series `pattern`; its first file must exist (number 0 or 1).
    pub fn open(pattern: &Path, opts: &ReadOptions) -> Result<Series> {
        let p = super::series_pattern(pattern)
            .ok_or_else(|| Error::Invalid(format!("{}: not a series", pattern.display())))?;
        let start = (0..2)
            .find(|&n| super::series_path(&p, n).is_file())
            .ok_or_else(|| {
                Error::io(
                    pattern,
                    std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        format!(
                            "no frame file (looked for {} and {})",
                            super::series_path(&p, 0).display(),
                            super::series_path(&p, 1).display()
                        ),
                    ),
                )
            })?;
        let first = crate::io::read_image(&super::series_path(&p, start), opts)?;
        Ok(Series {
            info: ClipInfo {
                width: first.width,
                height: first.height,
                loops: Loops::Plays(1),
                rate: None,
            },
            first: Some(first),
            next: start + 1,
            pattern: p,
            name: pattern.to_path_buf(),
            opts: opts.clone(),
        })
    }
}

impl FrameSource for Series {
    fn info(&self) -> &ClipInfo {
        &self.info
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let image = match self.first.take() {
            Some(i) => i,
            None => {
                let path = super::series_path(&self.pattern, self.next);
                if !path.is_file() {
                    return Ok(None);
                }
                self.next += 1;
                let img = crate::io::read_image(&path, &self.opts)?;
                if (img.width, img.height) != (self.info.width, self.info.height) {
                    return Err(super::decode_err(
                        &path,
                        format!(
                            "is {}x{}, the series' first frame {}x{}: frames of a clip share one size",
                            img.width, img.height, self.info.width, self.info.height
                        ),
                    ));
                }
                img
            }
        };
        Ok(Some(Frame {
            image,
            delay: SERIES_DELAY,
        }))
    }
    fn sendable(&mut self) -> Option<&mut (dyn FrameSource + Send)> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_reduce() {
        assert_eq!(reduce(40, 1000), Delay { num: 1, den: 25 });
        assert_eq!(reduce(0, 0), Delay { num: 0, den: 1 });
    }

    #[test]
    fn sniffs_kinds() {
        assert_eq!(sniff(b"GIF89a"), Kind::Gif);
        assert_eq!(sniff(b"YUV4MPEG2 W2"), Kind::Y4m);
        assert_eq!(sniff(b"P5\n"), Kind::Other);
    }
}
