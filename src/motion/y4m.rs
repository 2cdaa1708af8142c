//! YUV4MPEG2, the stream format of `ffmpeg -f yuv4mpegpipe`: a header line
//! (`YUV4MPEG2 W H F I A C X…`), then each frame as a `FRAME` line and its planes, 8 bits a
//! sample. Reader: mono, 4:2:0 (every siting), 4:2:2, 4:4:4 and 4:4:4 with alpha (ignored),
//! limited range unless the header says `XCOLORRANGE=FULL` (mono is full range, as ffmpeg
//! writes grey), BT.601 colour. Writer: grey halftones as mono, colour as 4:4:4.

use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};

use super::{decode_err, read_full, ClipInfo, Delay, Frame, FrameSource, Loops};
use crate::error::Result;
use crate::io::ReadOptions;
use crate::raster::{ColorKind, Halftone, Image, Samples};
use crate::tone::Encoding;

/// The longest header or `FRAME` line read (the format sets none; real ones are short).
const MAX_LINE: usize = 4096;

/// How the chroma planes are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Chroma {
    Mono,
    C420,
    C422,
    C444,
    C444Alpha,
}

/// A YUV4MPEG2 stream read frame by frame: one frame's bytes in memory.
pub struct Y4mSource {
    r: Box<dyn BufRead + Send>,
    info: ClipInfo,
    name: PathBuf,
    chroma: Chroma,
    full: bool,
    gray: bool,
    delay: Delay,
    buf: Vec<u8>,
    frames: usize,
}

/// Reads a line up to `\n` (not kept), at most [`MAX_LINE`] bytes. `Ok(None)` at the end
/// of the stream before any byte.
fn read_line(r: &mut dyn BufRead, name: &Path, what: &str) -> Result<Option<Vec<u8>>> {
    let mut line = Vec::new();
    (&mut *r)
        .take(MAX_LINE as u64 + 1)
        .read_until(b'\n', &mut line)
        .map_err(|e| crate::error::Error::io(name, e))?;
    if line.is_empty() {
        return Ok(None);
    }
    if line.last() != Some(&b'\n') {
        return Err(decode_err(
            name,
            if line.len() > MAX_LINE {
                format!("{what} line longer than {MAX_LINE} bytes")
            } else {
                format!("truncated in the {what} line")
            },
        ));
    }
    line.pop();
    Ok(Some(line))
}

impl Y4mSource {
    /// Reads the header. `gray`: make grey frames from the luma plane alone.
    pub fn open(
        mut r: Box<dyn BufRead + Send>,
        name: PathBuf,
        opts: &ReadOptions,
        gray: bool,
    ) -> Result<Y4mSource> {
        let line = read_line(&mut *r, &name, "header")?
            .ok_or_else(|| decode_err(&name, "empty stream".into()))?;
        let text = String::from_utf8_lossy(&line).into_owned();
        let mut tokens = text.split(' ');
        if tokens.next() != Some("YUV4MPEG2") {
            return Err(decode_err(&name, "not a YUV4MPEG2 stream".into()));
        }
        let (mut w, mut h, mut rate) = (0usize, 0usize, (25u32, 1u32));
        let mut chroma = Chroma::C420;
        let mut full = false;
        let bad = |t: &str| decode_err(&name, format!("bad header field `{t}`"));
        for t in tokens.filter(|t| !t.is_empty()) {
            let (k, v) = t.split_at(1);
            match k {
                "W" => w = v.parse().map_err(|_| bad(t))?,
                "H" => h = v.parse().map_err(|_| bad(t))?,
                "F" => {
                    let (n, d) = v.split_once(':').ok_or_else(|| bad(t))?;
                    rate = (
                        n.parse().map_err(|_| bad(t))?,
                        d.parse().map_err(|_| bad(t))?,
                    );
                    if rate.0 == 0 || rate.1 == 0 {
                        return Err(bad(t));
                    }
                }
                "C" => {
                    chroma = match v {
                        "mono" => {
                            full = true;
                            Chroma::Mono
                        }
                        "420" | "420jpeg" | "420paldv" | "420mpeg2" => Chroma::C420,
                        "422" => Chroma::C422,
                        "444" => Chroma::C444,
                        "444alpha" => Chroma::C444Alpha,
                        other => {
                            return Err(decode_err(
                                &name,
                                format!(
                                "colour space `C{other}` is not read: 8-bit mono, 420, 422, 444 \
                                     (convert with ffmpeg -pix_fmt yuv420p or gray)"
                            ),
                            ))
                        }
                    }
                }
                "X" if v == "COLORRANGE=FULL" => full = true,
                "X" if v == "COLORRANGE=LIMITED" => full = false,
                "I" | "A" | "X" => {}
                _ => return Err(bad(t)),
            }
        }
        if w == 0 || h == 0 {
            return Err(decode_err(
                &name,
                "the header gives no size (W and H)".into(),
            ));
        }
        super::check_pixels(&name, w as u32, h as u32, opts)?;
        Ok(Y4mSource {
            r,
            info: ClipInfo {
                width: w,
                height: h,
                loops: Loops::Plays(1),
                rate: Some(rate),
            },
            name,
            chroma,
            full,
            gray,
            delay: Delay {
                num: rate.1,
                den: rate.0,
            },
            buf: Vec::new(),
            frames: 0,
        })
    }

    /// Bytes of one frame's planes, and of its luma plane.
    fn frame_bytes(&self) -> (usize, usize) {
        let (w, h) = (self.info.width, self.info.height);
        let y = w * h;
        let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
        let total = match self.chroma {
            Chroma::Mono => y,
            Chroma::C420 => y + 2 * cw * ch,
            Chroma::C422 => y + 2 * cw * h,
            Chroma::C444 => 3 * y,
            Chroma::C444Alpha => 4 * y,
        };
        (total, y)
    }
}

/// Luma code to full-range grey code (identity when the stream is full range).
fn luma_table(full: bool) -> [u8; 256] {
    let mut t = [0u8; 256];
    for (i, v) in t.iter_mut().enumerate() {
        *v = if full {
            i as u8
        } else {
            ((i as f64 - 16.0) * 255.0 / 219.0)
                .round()
                .clamp(0.0, 255.0) as u8
        };
    }
    t
}

impl FrameSource for Y4mSource {
    fn info(&self) -> &ClipInfo {
        &self.info
    }

    fn name(&self) -> &Path {
        &self.name
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let Some(line) = read_line(&mut *self.r, &self.name, "FRAME")? else {
            return Ok(None);
        };
        if !line.starts_with(b"FRAME") {
            return Err(decode_err(
                &self.name,
                format!("frame {}: no FRAME marker", self.frames + 1),
            ));
        }
        let (total, ylen) = self.frame_bytes();
        self.buf.resize(total, 0);
        let got = read_full(&mut *self.r, &mut self.buf)
            .map_err(|e| crate::error::Error::io(&self.name, e))?;
        if got < total {
            return Err(decode_err(
                &self.name,
                format!(
                    "truncated in frame {} ({got} of its {total} bytes)",
                    self.frames + 1
                ),
            ));
        }
        self.frames += 1;
        let (w, h) = (self.info.width, self.info.height);
        let image = if self.gray || self.chroma == Chroma::Mono {
            let data: Vec<u8> = if self.full {
                self.buf[..ylen].to_vec()
            } else {
                let t = luma_table(self.full);
                self.buf[..ylen].iter().map(|&v| t[v as usize]).collect()
            };
            Image::gray8(w, h, data)
        } else {
            self.rgb(w, h)
        };
        Ok(Some(Frame {
            image,
            delay: self.delay,
        }))
    }
    fn sendable(&mut self) -> Option<&mut (dyn FrameSource + Send)> {
        Some(self)
    }
}

impl Y4mSource {
    /// The frame in `buf` as RGB (BT.601; chroma repeated over its block).
    fn rgb(&self, w: usize, h: usize) -> Image {
        let (sx, sy) = match self.chroma {
            Chroma::C420 => (2, 2),
            Chroma::C422 => (2, 1),
            _ => (1, 1),
        };
        let cw = w.div_ceil(sx);
        let ch = h.div_ceil(sy);
        let (yp, rest) = self.buf.split_at(w * h);
        let (up, vp) = rest.split_at(cw * ch);
        let mut planes = vec![vec![0u8; w * h]; 3];
        let (ys, cs) = if self.full {
            (1.0, 1.0)
        } else {
            (255.0 / 219.0, 255.0 / 224.0)
        };
        let y0 = if self.full { 0.0 } else { 16.0 };
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let c = (y / sy) * cw + x / sx;
                let l = (yp[i] as f32 - y0) * ys;
                let u = (up[c] as f32 - 128.0) * cs;
                let v = (vp[c] as f32 - 128.0) * cs;
                let rgb = [
                    l + 1.402 * v,
                    l - 0.344_136 * u - 0.714_136 * v,
                    l + 1.772 * u,
                ];
                for (p, &val) in planes.iter_mut().zip(&rgb) {
                    p[i] = val.round().clamp(0.0, 255.0) as u8;
                }
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
}

/// Writes halftones as a YUV4MPEG2 stream: grey as mono (full range, the level's display
/// code), colour and palettes as 4:4:4 (limited range, BT.601).
pub struct Y4mWriter {
    started: bool,
    row: Vec<u8>,
    levels: Vec<u8>,
}

impl Default for Y4mWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl Y4mWriter {
    /// A writer that has written nothing yet.
    pub fn new() -> Y4mWriter {
        Y4mWriter {
            started: false,
            row: Vec::new(),
            levels: Vec::new(),
        }
    }

    /// Writes the header (before the first frame) and one frame.
    pub fn frame(
        &mut self,
        h: &Halftone,
        delay: Delay,
        info: &ClipInfo,
        display: Encoding,
        out: &mut dyn Write,
    ) -> std::io::Result<()> {
        let grey = h.channels() == 1 && h.palette.is_none();
        if !self.started {
            // The stream's rate: the source's, else the first frame's delay.
            let (n, d) = info.rate.unwrap_or(if delay.num == 0 {
                (25, 1)
            } else {
                (delay.den, delay.num)
            });
            let c = if grey { "mono" } else { "444" };
            writeln!(
                out,
                "YUV4MPEG2 W{} H{} F{n}:{d} Ip A1:1 C{c}",
                h.width, h.height
            )?;
            self.started = true;
        }
        out.write_all(b"FRAME\n")?;
        let w = h.width;
        self.levels.resize(w, 0);
        self.row.resize(w, 0);
        if grey {
            let codes: Vec<u8> = (0..h.levels)
                .map(|k| crate::io::level_code(k as u8, h.levels, 255, display) as u8)
                .collect();
            if h.bits == 1 {
                // Eight pixels a packed byte, through a table of their eight codes.
                let table: Vec<[u8; 8]> = (0..256usize)
                    .map(|b| std::array::from_fn(|i| codes[(b >> (7 - i)) & 1]))
                    .collect();
                for y in 0..h.height {
                    for (o, &b) in self.row.chunks_mut(8).zip(h.row(0, y)) {
                        o.copy_from_slice(&table[b as usize][..o.len()]);
                    }
                    out.write_all(&self.row)?;
                }
                return Ok(());
            }
            for y in 0..h.height {
                h.unpack_row(0, y, &mut self.levels);
                for (o, &l) in self.row.iter_mut().zip(&self.levels) {
                    *o = codes[l as usize];
                }
                out.write_all(&self.row)?;
            }
            return Ok(());
        }
        // Colour: every pixel's sRGB colour, then Y, Cb, Cr planes one after the other.
        let colours = colours_of(h, display);
        let yuv: Vec<[u8; 3]> = colours.iter().map(|&c| ycbcr601(c)).collect();
        #[allow(clippy::needless_range_loop)]
        for plane in 0..3 {
            for y in 0..h.height {
                self.pixel_indices(h, y);
                for (o, &i) in self.row.iter_mut().zip(&self.levels) {
                    *o = yuv[i as usize][plane];
                }
                out.write_all(&self.row)?;
            }
        }
        Ok(())
    }

    /// Row `y` as indices into [`colours_of`]: palette indices, or the RGB levels combined.
    fn pixel_indices(&mut self, h: &Halftone, y: usize) {
        if h.palette.is_some() {
            h.unpack_row(0, y, &mut self.levels);
            return;
        }
        let l = h.levels as usize;
        let mut tmp = vec![0u8; h.width];
        let mut acc = vec![0usize; h.width];
        for c in 0..3 {
            h.unpack_row(c, y, &mut tmp);
            for (a, &t) in acc.iter_mut().zip(&tmp) {
                *a = *a * l + t as usize;
            }
        }
        // Up to 6 levels a channel fit a byte (216 colours); more are written through
        // a wider table.
        for (o, a) in self.levels.iter_mut().zip(acc) {
            *o = a.min(255) as u8;
        }
    }
}

/// The sRGB colours of a halftone's pixel indices: the palette, or every combination of
/// RGB levels (red slowest), capped at 256.
pub fn colours_of(h: &Halftone, display: Encoding) -> Vec<[u8; 3]> {
    if let Some(p) = &h.palette {
        return p.clone();
    }
    let l = h.levels as usize;
    let code = |k: usize| crate::io::level_code(k as u8, h.levels, 255, display) as u8;
    if h.channels() == 1 {
        return (0..l).map(|k| [code(k); 3]).collect();
    }
    let mut out = Vec::new();
    for r in 0..l {
        for g in 0..l {
            for b in 0..l {
                out.push([code(r), code(g), code(b)]);
            }
        }
    }
    out.truncate(256);
    out
}

/// Limited-range BT.601 Y, Cb, Cr of an sRGB colour.
fn ycbcr601(c: [u8; 3]) -> [u8; 3] {
    let [r, g, b] = c.map(|v| v as f64);
    let y = 0.299 * r + 0.587 * g + 0.114 * b;
    let cb = (b - y) / 1.772;
    let cr = (r - y) / 1.402;
    [
        (16.0 + y * 219.0 / 255.0).round() as u8,
        (128.0 + cb * 224.0 / 255.0).round().clamp(16.0, 240.0) as u8,
        (128.0 + cr * 224.0 / 255.0).round().clamp(16.0, 240.0) as u8,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_stream_round_trip() {
        let mut h = Halftone::new(5, 3, 1, 2);
        h.set(0, 1, 1, 1);
        let info = ClipInfo {
            width: 5,
            height: 3,
            loops: Loops::Plays(1),
            rate: Some((30, 1)),
        };
        let mut out = Vec::new();
        let mut w = Y4mWriter::new();
        for _ in 0..2 {
            w.frame(&h, Delay::ms(33), &info, Encoding::Srgb, &mut out)
                .unwrap();
        }
        let mut s = Y4mSource::open(
            Box::new(std::io::Cursor::new(out.clone())),
            "t.y4m".into(),
            &ReadOptions::default(),
            true,
        )
        .unwrap();
        assert_eq!(s.info().rate, Some((30, 1)));
        let f = s.next_frame().unwrap().unwrap();
        let Samples::U8(v) = &f.image.planes[0] else {
            panic!()
        };
        assert_eq!(v[6], 255);
        assert_eq!(v[0], 0);
        assert!(s.next_frame().unwrap().is_some());
        assert!(s.next_frame().unwrap().is_none());
        // Cut inside the second frame: a one-line error naming the stream.
        out.truncate(out.len() - 4);
        let mut s = Y4mSource::open(
            Box::new(std::io::Cursor::new(out)),
            "t.y4m".into(),
            &ReadOptions::default(),
            true,
        )
        .unwrap();
        assert!(s.next_frame().is_ok());
        let e = s.next_frame().unwrap_err().to_string();
        assert!(e.starts_with("t.y4m: truncated in frame 2"), "{e}");
    }
}
