//! JPEG as a streaming source, through libjpeg-turbo ([`crate::io::codec::jpeg`]): rows as the
//! decoder makes them (by MCU rows inside libjpeg), and shrink-on-load by DCT scaling when
//! the output is much smaller than the image ([`shrink_denominator`]).

use std::io::Read;
use std::path::Path;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

use super::band::{RowSource, SourceInfo};
use crate::error::{Error, Result};
use crate::io::codec::jpeg::Jpeg;
use crate::io::ReadOptions;
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::{Encoding, ToneOptions, ToneTable};

/// A JPEG file decoded row by row, on a thread of its own: while the caller converts and
/// halftones one part of the image, the decoder makes the next.
///
/// The decoding thread does nothing but decode: it hands on libjpeg's interleaved rows in
/// chunks of a few hundred KiB, whatever the band the caller asks for, and the caller makes
/// planes (or luminance) of them straight into its band. So even a whole image read at once
/// (the whole-image way, a resize) is converted while the rest is still being decoded, and
/// the decoder, which is most of the work, carries no other.
pub struct JpegSource {
    name: std::path::PathBuf,
    /// The decoder until the first band is asked for; then it moves to its thread.
    jpeg: Option<Jpeg>,
    info: SourceInfo,
    /// Decode at 1/`denom` (1, 2 or 4).
    denom: usize,
    /// Bytes of the file and of what libjpeg keeps (a progressive file's coefficients).
    progressive_bytes: usize,
    /// The EXIF orientation (1: none). Any other is applied to the whole decoded image
    /// (shrunk on load, if it is), which the bands are then cut from.
    orientation: u16,
    channels: usize,
    /// Luminance in place of RGB, when the job is grey: `linearize`, then its tables.
    luma: Option<bool>,
    luma_tables: Option<Luma>,
    /// The resize's 16-bit codes in place of 8-bit ones, when the job resizes a shrunk
    /// decode: `linearize`, then the table.
    linear: Option<bool>,
    linear_table: Option<[u16; 256]>,
    /// The bands' encoding.
    encoding: Encoding,
    /// Chunks from the decoding thread, and their buffers sent back to be filled again.
    chunks: Option<Chunks>,
    /// The chunk being read, its rows, and the rows of it already handed on.
    chunk: Vec<u8>,
    chunk_rows: usize,
    chunk_used: usize,
    rows_read: usize,
}

/// The decoding thread's chunks, and the way their buffers go back to it.
type Chunks = (Receiver<Result<Vec<u8>>>, SyncSender<Vec<u8>>);

/// Chunks decoded ahead of the one being converted.
const AHEAD: usize = 2;

/// Bytes of interleaved rows a chunk holds, about (never more rows than the first band).
const CHUNK_BYTES: usize = 256 << 10;

/// Linear-light luminance of 8-bit sRGB codes, exactly as [`Image::to_luminance`] makes
/// it: the weighted channels are read from tables of the same `f32` products, added in the
/// same order, clamped, scaled and rounded half up the same way.
pub struct Luma {
    weighted: [[f32; 256]; 3],
}

impl Luma {
    /// The tables for `linearize` (`--no-linearize` weights the codes themselves).
    pub fn new(linearize: bool) -> Luma {
        let plain = ToneOptions {
            linearize,
            ..ToneOptions::default()
        };
        let table = ToneTable::new(8, Encoding::Srgb, &plain);
        let t = table.as_slice();
        let mut weighted = [[0.0; 256]; 3];
        for (w, k) in weighted.iter_mut().zip([0.2126f32, 0.7152, 0.0722]) {
            for (o, &v) in w.iter_mut().zip(t) {
                *o = k * v;
            }
        }
        Luma { weighted }
    }

    /// Interleaved RGB codes to 16-bit luminance codes (eight at a time where the CPU has
    /// AVX2: the same `f32` operations, so the same codes).
    pub fn convert(&self, rgb: &[u8], out: &mut [u16]) {
        let n = out.len().min(rgb.len() / 3);
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::avx2() {
            // SAFETY: AVX2 is present (the level never exceeds what the CPU has).
            let done = unsafe { self.convert_avx2(&rgb[..3 * n], &mut out[..n]) };
            return self.convert_scalar(&rgb[3 * done..3 * n], &mut out[done..n]);
        }
        self.convert_scalar(&rgb[..3 * n], &mut out[..n]);
    }

    /// [`Self::convert`] a pixel at a time.
    fn convert_scalar(&self, rgb: &[u8], out: &mut [u16]) {
        let [wr, wg, wb] = &self.weighted;
        for (o, px) in out.iter_mut().zip(rgb.chunks_exact(3)) {
            let l = wr[px[0] as usize] + wg[px[1] as usize] + wb[px[2] as usize];
            let x = l.clamp(0.0, 1.0) * 65535.0;
            let t = x as u16;
            *o = t + (x - t as f32 >= 0.5) as u16;
        }
    }

    /// [`Self::convert_scalar`] eight pixels at a time, for as many whole groups of eight
    /// as leave the loads inside `rgb`; returns the pixels done. The three tables are read
    /// by gathers; the sum, clamp, scale, truncation and rounding are the scalar loop's
    /// operations lane by lane (a clamp of −0 gives +0, which scales and rounds the same).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn convert_avx2(&self, rgb: &[u8], out: &mut [u16]) -> usize {
        use std::arch::x86_64::*;
        let [wr, wg, wb] = &self.weighted;
        // Byte k of pixels 0–3 (low half) and 4–7 (high half) into 32-bit lanes: shuffle
        // masks for k = 0, 1, 2.
        let mut masks = [[-1i8; 32]; 3];
        for (k, m) in masks.iter_mut().enumerate() {
            for p in 0..8 {
                m[4 * p] = (3 * (p % 4) + k) as i8;
            }
        }
        let [pr, pg, pb] = masks.map(|m| _mm256_loadu_si256(m.as_ptr().cast()));
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let (scale, half) = (_mm256_set1_ps(65535.0), _mm256_set1_ps(0.5));
        let ones = _mm256_set1_epi32(1);
        let mut i = 0;
        // Two 16-byte loads at 3i and 3i + 12 read up to byte 3i + 27.
        while i + 8 <= out.len() && 3 * i + 28 <= rgb.len() {
            let p = rgb.as_ptr().add(3 * i);
            let lo = _mm_loadu_si128(p.cast());
            let hi = _mm_loadu_si128(p.add(12).cast());
            let v = _mm256_set_m128i(hi, lo);
            let r = _mm256_i32gather_ps::<4>(wr.as_ptr(), _mm256_shuffle_epi8(v, pr));
            let g = _mm256_i32gather_ps::<4>(wg.as_ptr(), _mm256_shuffle_epi8(v, pg));
            let b = _mm256_i32gather_ps::<4>(wb.as_ptr(), _mm256_shuffle_epi8(v, pb));
            let l = _mm256_add_ps(_mm256_add_ps(r, g), b);
            let x = _mm256_mul_ps(_mm256_min_ps(_mm256_max_ps(l, zero), one), scale);
            let t = _mm256_cvttps_epi32(x);
            let frac = _mm256_sub_ps(x, _mm256_cvtepi32_ps(t));
            let up = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(frac, half));
            let code = _mm256_add_epi32(t, _mm256_and_si256(up, ones));
            // 0..=65535 in each lane: pack to 16 bits, halves back in order.
            let packed = _mm256_permute4x64_epi64::<0b1000>(_mm256_packus_epi32(code, code));
            _mm_storeu_si128(
                out.as_mut_ptr().add(i).cast(),
                _mm256_castsi256_si128(packed),
            );
            i += 8;
        }
        i
    }
}

/// The decoding thread: chunks of `rows` interleaved rows (the last one shorter), in
/// buffers sent back by the caller when it can.
fn decode_chunks(
    mut jpeg: Jpeg,
    rows: usize,
    denom: usize,
    tx: SyncSender<Result<Vec<u8>>>,
    spare: Receiver<Vec<u8>>,
) {
    let mut run = || -> Result<()> {
        let (_, h) = jpeg.start(denom)?;
        let mut y = 0;
        while y < h {
            let n = rows.min(h - y);
            let mut buf = spare.try_recv().unwrap_or_default();
            jpeg.read_rows(n, &mut buf)?;
            y += n;
            if tx.send(Ok(buf)).is_err() {
                // The reader has gone (an error downstream): stop decoding.
                return Ok(());
            }
        }
        Ok(())
    };
    if let Err(e) = run() {
        let _ = tx.send(Err(e));
    }
}

/// Interleaved RGB into three planes, `rgb.len() / 3` samples each.
fn split(rgb: &[u8], r: &mut [u8], g: &mut [u8], b: &mut [u8]) {
    for (((px, r), g), b) in rgb
        .chunks_exact(3)
        .zip(r.iter_mut())
        .zip(g.iter_mut())
        .zip(b.iter_mut())
    {
        *r = px[0];
        *g = px[1];
        *b = px[2];
    }
}

/// Interleaved RGB into three planes through `t`, `rgb.len() / 3` samples each.
fn split_through(rgb: &[u8], t: &[u16; 256], r: &mut [u16], g: &mut [u16], b: &mut [u16]) {
    for (((px, r), g), b) in rgb
        .chunks_exact(3)
        .zip(r.iter_mut())
        .zip(g.iter_mut())
        .zip(b.iter_mut())
    {
        *r = t[px[0] as usize];
        *g = t[px[1] as usize];
        *b = t[px[2] as usize];
    }
}

/// The 16-bit code [`crate::resize`] filters for each 8-bit sRGB code: its linear light
/// (or, with `linearize` off, the code itself) times 65535, rounded, by the same `f32`
/// operations, so the resize's output is the same, byte for byte.
pub fn linear_table(linearize: bool) -> [u16; 256] {
    let plain = ToneOptions {
        linearize,
        ..ToneOptions::default()
    };
    let table = ToneTable::new(8, Encoding::Srgb, &plain);
    let mut out = [0u16; 256];
    for (o, &v) in out.iter_mut().zip(table.as_slice()) {
        *o = (v * 65535.0).round() as u16;
    }
    out
}

/// Makes `planes` `n` samples each, of the kind `u16` says, reusing their buffers.
fn size_planes(planes: &mut Vec<Samples>, count: usize, n: usize, u16: bool) {
    planes.resize(count, Samples::U8(Vec::new()));
    for p in planes.iter_mut() {
        match (p, u16) {
            (Samples::U16(v), true) => v.resize(n, 0),
            (Samples::U8(v), false) => v.resize(n, 0),
            (p, true) => *p = Samples::U16(vec![0; n]),
            (p, false) => *p = Samples::U8(vec![0; n]),
        }
    }
}

// One rule for every format: the threshold and the margin are the box shrink's (see there
// for why small images are decoded whole).
pub use super::shrink::{SHRINK_MARGIN, SHRINK_MIN_PIXELS};

/// The DCT-scaling denominator (4, 2, else 1) for an image of `w × h` to be resized to
/// `min_w × min_h`: the largest whose output, `⌈w/d⌉ × ⌈h/d⌉`, is still at least
/// [`SHRINK_MARGIN`] times that size; 1 for images under [`SHRINK_MIN_PIXELS`].
///
/// 1/8 is not used: on photos enlarged 4× (blocks of 8 pixels holding 2×2 of the photo's
/// own) it lost 0.5–1.0 dB, where 1/4 stayed within 0.25 dB (tests/it/photos.rs).
pub fn shrink_denominator(w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    super::shrink::largest_shrink(&[4, 2], w, h, min_w, min_h)
}

impl JpegSource {
    /// Opens the JPEG file at `path`, or `None` when libjpeg is not the decoder for it
    /// (CMYK): the whole-image reader takes it then.
    pub fn open(name: &Path, path: &Path, opts: &ReadOptions) -> Result<Option<JpegSource>> {
        let mut file = std::fs::File::open(path).map_err(|e| Error::io(name, e))?;
        let len = file.metadata().map_err(|e| Error::io(name, e))?.len();
        let cap = crate::io::max_input_bytes(opts);
        if len > cap {
            // The whole-image reader gives the message for files over the cap.
            return Ok(None);
        }
        let mut data = Vec::with_capacity(len as usize + 1);
        (&mut file)
            .take(cap.saturating_add(1))
            .read_to_end(&mut data)
            .map_err(|e| Error::io(name, e))?;
        if data.len() as u64 > cap {
            return Ok(None);
        }
        Self::from_data(name, data, opts)
    }

    /// [`JpegSource::open`] for a JPEG already read into memory (from a stream).
    pub fn from_data(name: &Path, data: Vec<u8>, opts: &ReadOptions) -> Result<Option<JpegSource>> {
        let Some(jpeg) = Jpeg::open(name, data, opts)? else {
            return Ok(None);
        };
        let (width, height) = oriented(jpeg.orientation, jpeg.width, jpeg.height);
        let info = SourceInfo {
            width,
            height,
            color: if jpeg.gray {
                ColorKind::Gray
            } else {
                ColorKind::Rgb
            },
            bits: 8,
            dpi: jpeg.dpi,
        };
        Ok(Some(JpegSource {
            name: name.to_path_buf(),
            progressive_bytes: if jpeg.progressive {
                // Every DCT coefficient (2 bytes each; chroma is usually subsampled, so
                // this is an upper bound) until the last scan.
                jpeg.width * jpeg.height * jpeg.channels() * 2
            } else {
                0
            },
            channels: jpeg.channels(),
            orientation: jpeg.orientation,
            jpeg: Some(jpeg),
            info,
            denom: 1,
            luma: None,
            luma_tables: None,
            linear: None,
            linear_table: None,
            encoding: Encoding::Srgb,
            chunks: None,
            chunk: Vec::new(),
            chunk_rows: 0,
            chunk_used: 0,
            rows_read: 0,
        }))
    }

    /// Receives every chunk of the decoded image, each row put where the orientation turns
    /// it, into the one chunk the bands are cut from (the image is held once).
    fn turn_whole(&mut self) -> Result<()> {
        let ch = self.channels;
        let (w, h) = oriented(self.orientation, self.info.width, self.info.height);
        let (rx, spare) = self.chunks.as_ref().expect("started");
        let mut out = vec![0u8; w * h * ch];
        let mut y = 0;
        while y < h {
            let chunk = rx.recv().map_err(|_| {
                crate::io::decode_err(&self.name, "the JPEG decoder stopped".into())
            })??;
            for row in chunk.chunks_exact(w * ch) {
                place_row(row, y, (w, h), ch, self.orientation, &mut out);
                y += 1;
            }
            let _ = spare.try_send(chunk);
        }
        self.chunk = out;
        self.chunk_rows = self.info.height;
        self.chunk_used = 0;
        Ok(())
    }
}

/// A `w × h` size as it is after orientation `o` (5–8 swap the sides).
fn oriented(o: u16, w: usize, h: usize) -> (usize, usize) {
    if (5..=8).contains(&o) {
        (h, w)
    } else {
        (w, h)
    }
}

/// Where EXIF orientation `o` puts pixel (`sx`, `sy`) of a `w × h` image, in the turned
/// image: 2 mirrors left to right, 3 turns half round, 4 mirrors top to bottom, 5
/// transposes, 6 turns a quarter clockwise, 7 transposes the other way, 8 turns a quarter
/// counter-clockwise.
#[inline(always)]
fn turned_at(o: u16, sx: usize, sy: usize, (w, h): (usize, usize)) -> (usize, usize) {
    match o {
        2 => (w - 1 - sx, sy),
        3 => (w - 1 - sx, h - 1 - sy),
        4 => (sx, h - 1 - sy),
        5 => (sy, sx),
        6 => (h - 1 - sy, sx),
        7 => (h - 1 - sy, w - 1 - sx),
        8 => (sy, w - 1 - sx),
        _ => (sx, sy),
    }
}

/// Puts row `sy` of a `w × h` image (interleaved, `ch` bytes a pixel) where orientation `o`
/// turns it in `out`, the turned image ([`turned_at`]).
fn place_row(row: &[u8], sy: usize, (w, h): (usize, usize), ch: usize, o: u16, out: &mut [u8]) {
    let ow = oriented(o, w, h).0;
    for (sx, px) in row.chunks_exact(ch).enumerate() {
        let (x, y) = turned_at(o, sx, sy, (w, h));
        let at = (y * ow + x) * ch;
        out[at..at + ch].copy_from_slice(px);
    }
}

impl RowSource for JpegSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn buffer_bytes(&self) -> usize {
        // An orientation to apply holds the whole image, turned as it is decoded.
        let turned = if self.orientation != 1 {
            self.info.width * self.info.height * self.channels
        } else {
            0
        };
        self.progressive_bytes + turned
    }

    fn bytes_per_row(&self) -> usize {
        // Interleaved chunks, each at most half a band high: the one being decoded, those
        // decoded ahead (AHEAD), and the one being converted.
        self.info.width * self.channels * (AHEAD + 2) / 2
    }

    fn shrink_to(&mut self, min_w: usize, min_h: usize) -> usize {
        let Some(jpeg) = &self.jpeg else {
            return 1;
        };
        // The size asked for is the turned image's; the decoder's is the file's.
        let (min_w, min_h) = oriented(self.orientation, min_w, min_h);
        let d = shrink_denominator(jpeg.width, jpeg.height, min_w, min_h);
        self.denom = d;
        let (w, h) = jpeg.scaled_size(d);
        (self.info.width, self.info.height) = oriented(self.orientation, w, h);
        d
    }

    fn remainder_at(&self) -> (bool, bool) {
        // The decoder's partial column and row meet at its bottom-right pixel: where the
        // turn puts that pixel, they are.
        let (ow, oh) = (self.info.width, self.info.height);
        let stored = oriented(self.orientation, ow, oh);
        let (x, y) = turned_at(self.orientation, stored.0 - 1, stored.1 - 1, stored);
        (x + 1 == ow, y + 1 == oh)
    }

    fn decodes_whole_well(&self) -> bool {
        true
    }

    fn to_luminance(&mut self, tone: &ToneOptions) -> bool {
        if self.jpeg.is_none() || self.info.color != ColorKind::Rgb {
            return false;
        }
        self.luma = Some(tone.linearize);
        self.info.color = ColorKind::Gray;
        self.info.bits = 16;
        if tone.linearize {
            self.encoding = Encoding::Linear;
        }
        true
    }

    fn to_linear(&mut self, tone: &ToneOptions) -> bool {
        if self.jpeg.is_none() || self.luma.is_some() {
            return false;
        }
        self.linear = Some(tone.linearize);
        self.info.bits = 16;
        if tone.linearize {
            self.encoding = Encoding::Linear;
        }
        true
    }

    fn prefers_streaming(&self) -> bool {
        // Bands overlap decoding with halftoning, and keep memory small (an image to be
        // turned is held whole as decoded, but its planes need not be).
        true
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        let rows = rows.min(self.info.height - self.rows_read);
        let w = self.info.width;
        let ch = self.channels;
        if let Some(jpeg) = self.jpeg.take() {
            // Chunks of about CHUNK_BYTES, and no taller than half this first band: the
            // AHEAD + 2 of them in flight hold no more than the plan counts.
            let chunk = (CHUNK_BYTES / (w * ch).max(1)).clamp(1, (rows / 2).max(1));
            let (tx, rx) = sync_channel(AHEAD);
            let (spare_tx, spare_rx) = sync_channel(AHEAD + 2);
            let denom = self.denom;
            self.luma_tables = self.luma.map(Luma::new);
            self.linear_table = self.linear.map(linear_table);
            std::thread::spawn(move || decode_chunks(jpeg, chunk, denom, tx, spare_rx));
            self.chunks = Some((rx, spare_tx));
            if self.orientation != 1 {
                self.turn_whole()?;
            }
        }
        band.width = w;
        band.height = rows;
        band.color = self.info.color;
        band.encoding = self.encoding;
        let luma = self.luma_tables.as_ref();
        let linear = self.linear_table.as_ref();
        let count = if luma.is_some() { 1 } else { ch };
        size_planes(
            &mut band.planes,
            count,
            w * rows,
            luma.is_some() || linear.is_some(),
        );
        let (rx, spare) = self.chunks.as_ref().expect("started above");
        let mut done = 0;
        while done < rows {
            if self.chunk_used == self.chunk_rows {
                let old = std::mem::take(&mut self.chunk);
                if !old.is_empty() {
                    let _ = spare.try_send(old);
                }
                self.chunk = rx.recv().map_err(|_| {
                    crate::io::decode_err(&self.name, "the JPEG decoder stopped".into())
                })??;
                self.chunk_rows = self.chunk.len() / (w * ch);
                self.chunk_used = 0;
            }
            let n = (self.chunk_rows - self.chunk_used).min(rows - done);
            let src = &self.chunk[self.chunk_used * w * ch..(self.chunk_used + n) * w * ch];
            let at = done * w..(done + n) * w;
            match (luma, linear, &mut band.planes[..]) {
                (Some(luma), _, [Samples::U16(y)]) => luma.convert(src, &mut y[at]),
                (None, None, [Samples::U8(g)]) => g[at].copy_from_slice(src),
                (None, None, [Samples::U8(r), Samples::U8(g), Samples::U8(b)]) => {
                    split(src, &mut r[at.clone()], &mut g[at.clone()], &mut b[at])
                }
                (None, Some(t), [Samples::U16(g)]) => {
                    for (o, &c) in g[at].iter_mut().zip(src) {
                        *o = t[c as usize];
                    }
                }
                (None, Some(t), [Samples::U16(r), Samples::U16(g), Samples::U16(b)]) => {
                    split_through(src, t, &mut r[at.clone()], &mut g[at.clone()], &mut b[at])
                }
                _ => unreachable!("planes sized above"),
            }
            self.chunk_used += n;
            done += n;
        }
        self.rows_read += rows;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_codes_resize_to_the_same_bytes() {
        // What the resize makes of 8-bit codes and of the 16-bit codes the source hands on
        // in their place: the same planes.
        let (w, h) = (61, 37);
        let mut s = 987_654_321u32;
        let rgb: Vec<u8> = (0..w * h * 3)
            .map(|_| {
                s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (s >> 16) as u8
            })
            .collect();
        let img = Image::rgb8(w, h, &rgb);
        for linearize in [true, false] {
            let tone = ToneOptions {
                linearize,
                ..ToneOptions::default()
            };
            let t = linear_table(linearize);
            let mut wide = img.clone();
            wide.planes = img
                .planes
                .iter()
                .map(|p| match p {
                    Samples::U8(v) => Samples::U16(v.iter().map(|&c| t[c as usize]).collect()),
                    Samples::U16(_) => unreachable!("8-bit"),
                })
                .collect();
            if linearize {
                wide.encoding = Encoding::Linear;
            }
            for (tw, th) in [(20, 12), (7, 5), (90, 50)] {
                let a = crate::resize::resize(&img, tw, th, &tone).unwrap();
                let b = crate::resize::resize(&wide, tw, th, &tone).unwrap();
                assert_eq!(a.planes, b.planes, "{tw}x{th} linearize {linearize}");
                assert_eq!(a.encoding, b.encoding);
            }
        }
    }

    #[test]
    fn luminance_is_that_of_the_image() {
        // Every code in every channel, and pseudo-random colours.
        let mut rgb: Vec<u8> = (0..=255u8)
            .flat_map(|c| [c, c, c, c, 0, 0, 0, c, 0, 0, 0, c])
            .collect();
        let mut s = 12345u32;
        for _ in 0..30000 {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            rgb.push((s >> 16) as u8);
        }
        let n = rgb.len() / 3;
        let img = Image::rgb8(n, 1, &rgb[..n * 3]);
        for linearize in [true, false] {
            let tone = ToneOptions {
                linearize,
                ..ToneOptions::default()
            };
            let reference = img.to_luminance(&tone);
            let mut ours = vec![0u16; n];
            Luma::new(linearize).convert(&rgb[..n * 3], &mut ours);
            let mut scalar = vec![0u16; n];
            Luma::new(linearize).convert_scalar(&rgb[..n * 3], &mut scalar);
            assert_eq!(ours, scalar, "linearize {linearize}");
            assert_eq!(
                reference.planes[0],
                Samples::U16(ours),
                "linearize {linearize}"
            );
            let encoding = if linearize {
                Encoding::Linear
            } else {
                Encoding::Srgb
            };
            assert_eq!(reference.encoding, encoding);
        }
    }

    /// The vector conversion against the scalar one on every 24-bit colour, at every
    /// alignment of the rows' ends.
    #[test]
    fn vector_luminance_is_the_scalar_one_for_every_colour() {
        use crate::cpu::{test_has, with_level, Level};
        let mut levels = vec![Level::Portable];
        if test_has(
            Level::Avx2,
            "jpeg::vector_luminance_is_the_scalar_one_for_every_colour",
        ) {
            levels.push(Level::Avx2);
        }
        let rgb: Vec<u8> = (0..1u32 << 24)
            .flat_map(|c| [c as u8, (c >> 8) as u8, (c >> 16) as u8])
            .collect();
        for linearize in [true, false] {
            let luma = Luma::new(linearize);
            let mut fast = vec![0u16; 1 << 24];
            let mut slow = vec![0u16; 1 << 24];
            luma.convert_scalar(&rgb, &mut slow);
            for &level in &levels {
                with_level(level, || luma.convert(&rgb, &mut fast));
                assert!(fast == slow, "{level:?}: linearize {linearize}");
                for len in 1..40 {
                    let (a, b) = (&rgb[3 * 1000..3 * (1000 + len)], 1000..1000 + len);
                    let mut part = vec![0u16; len];
                    with_level(level, || luma.convert(a, &mut part));
                    assert_eq!(part, slow[b], "{level:?}: length {len}");
                }
            }
        }
    }
}
