//! Streaming decoders: images read band by band, top to bottom, into planes of the file's
//! own codes, with the same codes as the whole-image decoders of [`crate::io`].
//!
//! PNM (P4, P5, P6 at 8 and 16 bits), non-interlaced PNG and TIFF strips (grey or RGB)
//! stream. Every decoder checks the
//! header's size against the pixel limit before allocating, and data that ends early is an
//! error naming the file, never made-up pixels.

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::codec::pnm::{self, HeaderParse, PnmHeader, PnmKind};
use crate::io::{check_pixels, decode_err, ReadOptions};
use crate::raster::{ColorKind, Image, Samples};

pub use super::band::{empty_band, RowSource, SourceInfo};

/// An input opened for [`open`].
pub struct Input {
    /// The name messages give it.
    pub name: PathBuf,
    /// Its bytes, from the first.
    pub reader: Box<dyn Read + Send>,
    /// Its path when it is a regular file, which decoders may reopen and seek; `None` for
    /// a stream (standard input, a pipe, a FIFO, a device), which is read once.
    pub file: Option<PathBuf>,
}

/// Opens the file, pipe or device `input` for [`open`]. A regular file larger than any
/// image within the pixel limit is refused before it is read.
pub fn open_input(input: &Path, opts: &ReadOptions) -> Result<Input> {
    let file = std::fs::File::open(input).map_err(|e| Error::io(input, e))?;
    let meta = file.metadata().map_err(|e| Error::io(input, e))?;
    if meta.is_dir() {
        return Err(decode_err(input, "is a folder, not an image".into()));
    }
    if meta.is_file() && meta.len() > crate::io::max_input_bytes(opts) {
        // Larger than any image within the pixel limit: the whole-image reader says so
        // before reading it.
        crate::io::read_image(input, opts)?;
    }
    Ok(Input {
        name: input.to_path_buf(),
        reader: Box::new(std::io::BufReader::with_capacity(1 << 16, file)),
        file: meta.is_file().then(|| input.to_path_buf()),
    })
}

/// How many bytes of a stream are looked at to recognise its format.
pub const HEAD_BYTES: usize = 4096;

/// Opens a stream as a streaming decoder, or gives it back when its format does not stream
/// (then the caller decodes the whole image). `name` names it in messages; `file` is its
/// path when it is a file (PNG streams only from a file, which its decoder may seek).
pub fn open(
    name: &Path,
    file: Option<&Path>,
    mut reader: Box<dyn Read + Send>,
    opts: &ReadOptions,
) -> Result<Opened> {
    let mut head = Vec::with_capacity(HEAD_BYTES);
    (&mut reader)
        .take(HEAD_BYTES as u64)
        .read_to_end(&mut head)
        .map_err(|e| Error::io(name, e))?;
    let rest = std::io::Cursor::new(head.clone()).chain(reader);
    if head.is_empty() {
        return Err(decode_err(name, "empty file".into()));
    }
    // P6 has the header of P5 (width, height, maxval): parse it as one.
    let mut probe = head.clone();
    let pixmap = probe.starts_with(b"P6");
    if pixmap {
        probe[1] = b'5';
    }
    match pnm::parse_header(&probe) {
        HeaderParse::Ok(h) => {
            check_pixels(name, h.width, h.height, opts)?;
            let mut data = rest;
            // Skip the header: it is in the first bytes, which `head` holds.
            std::io::copy(
                &mut (&mut data).take(h.data_offset as u64),
                &mut std::io::sink(),
            )
            .map_err(|e| Error::io(name, e))?;
            let src = PnmSource::new(name, h, pixmap, Box::new(data));
            // A file shorter than its header claims is refused here, before anything the
            // claimed size would make the pipeline allocate (a shrunk image, a whole page).
            let need = src.file_row.saturating_mul(h.height as usize);
            if let Some(len) = file
                .and_then(|f| std::fs::metadata(f).ok())
                .map(|m| m.len())
            {
                if len < (h.data_offset as u64).saturating_add(need as u64) {
                    return Err(decode_err(name, pnm::truncated_message(&h, need)));
                }
            }
            Ok(Opened::Rows(Box::new(src)))
        }
        HeaderParse::Incomplete if head.len() < HEAD_BYTES => Err(decode_err(
            name,
            "truncated: the header is incomplete".into(),
        )),
        HeaderParse::Bad(msg) => Err(decode_err(name, msg)),
        _ => {
            if let (true, Some(path)) = (head.starts_with(PNG_SIGNATURE), file) {
                if let Some(src) = PngSource::open(name, path, opts)? {
                    return Ok(Opened::Rows(Box::new(src)));
                }
            }
            if head.starts_with(PNG_SIGNATURE) && file.is_none() {
                // A stream streams too: what it holds is decoded as it comes, so its bytes
                // are never gathered (a header claiming a gigapixel, then endless data,
                // fails on the first bytes that are not PNG).
                return png_stream(name, rest, opts);
            }
            #[cfg(halftone_libjpeg)]
            if head.starts_with(&[0xFF, 0xD8, 0xFF]) {
                match file {
                    Some(path) => {
                        if let Some(src) = super::jpeg::JpegSource::open(name, path, opts)? {
                            return Ok(Opened::Rows(Box::new(src)));
                        }
                    }
                    None => {
                        // The same decoder as for a file, so the same pixels.
                        let mut rest = rest;
                        let data = crate::io::read_stream(&mut rest, name, opts)?;
                        let src = super::jpeg::JpegSource::from_data(name, data.clone(), opts)?;
                        if let Some(src) = src {
                            return Ok(Opened::Rows(Box::new(src)));
                        }
                        return Ok(Opened::Whole(Box::new(std::io::Cursor::new(data))));
                    }
                }
            }
            let tiff = head.starts_with(b"II*\0") || head.starts_with(b"MM\0*");
            if let (true, Some(path)) = (tiff, file) {
                if let Some(src) = TiffSource::open(name, path, opts)? {
                    return Ok(Opened::Rows(Box::new(src)));
                }
            }
            // Not an image at all: say so now, before reading the rest (a stream of zeros
            // would otherwise be read to its cap).
            if image::guess_format(&head).is_err() {
                return Err(decode_err(
                    name,
                    "not an image format halftone reads (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM)"
                        .into(),
                ));
            }
            Ok(Opened::Whole(Box::new(rest)))
        }
    }
}

/// The first bytes of every PNG file.
const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

/// What the PNG decoder reads: a file, or a stream behind [`NoSeek`].
trait PngRead: std::io::BufRead + std::io::Seek + Send {}
impl<T: std::io::BufRead + std::io::Seek + Send> PngRead for T {}

/// A stream given to the PNG decoder, whose type asks for `Seek` though it reads front to
/// back (png 0.18 never seeks while decoding); a seek is an error, never a wrong read.
struct NoSeek<R>(R);

impl<R: std::io::Read> std::io::Read for NoSeek<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for NoSeek<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.0.fill_buf()
    }
    fn consume(&mut self, n: usize) {
        self.0.consume(n)
    }
}

impl<R> std::io::Seek for NoSeek<R> {
    fn seek(&mut self, _: std::io::SeekFrom) -> std::io::Result<u64> {
        Err(std::io::Error::new(
            std::io::ErrorKind::Unsupported,
            "a stream cannot seek",
        ))
    }
}

/// The most bytes of chunks a PNG stream may have before its image data (palette, ICC
/// profile, text): the metadata margin of the stream bound (`io::stream`).
const PNG_HEAD_MAX: u64 = 32 << 20;

/// A PNG's chunks up to its image data (IHDR, palette, metadata), as read from a stream.
struct PngHead {
    /// Every byte read, from the signature on.
    bytes: Vec<u8>,
    interlaced: bool,
    exif: bool,
}

/// Reads a PNG stream's chunks up to its first IDAT, checking each as it comes (IHDR first,
/// chunk types of four letters, CRCs, at most [`PNG_HEAD_MAX`] bytes of metadata), so
/// bytes that are not PNG are refused at once.
fn png_head(name: &Path, reader: &mut dyn Read, opts: &ReadOptions) -> Result<PngHead> {
    const MARGIN: u64 = PNG_HEAD_MAX;
    let mut bytes = Vec::with_capacity(HEAD_BYTES);
    let mut want = |bytes: &mut Vec<u8>, n: usize| -> Result<()> {
        let more = n.saturating_sub(bytes.len()) as u64;
        let got = (&mut *reader)
            .take(more)
            .read_to_end(bytes)
            .map_err(|e| Error::io(name, e))?;
        if (got as u64) < more {
            return Err(decode_err(
                name,
                "truncated: the PNG ends before its image data".into(),
            ));
        }
        Ok(())
    };
    want(&mut bytes, 8)?;
    let bad = |msg: String| decode_err(name, format!("bad PNG file: {msg}"));
    let (mut interlaced, mut exif) = (false, false);
    let mut at = 8;
    loop {
        want(&mut bytes, at + 8)?;
        let len = u32::from_be_bytes(bytes[at..at + 4].try_into().expect("4 bytes")) as usize;
        let kind: [u8; 4] = bytes[at + 4..at + 8].try_into().expect("4 bytes");
        if at == 8 && (&kind != b"IHDR" || len != 13) {
            return Err(bad("the first chunk is not the image header (IHDR)".into()));
        }
        if !kind.iter().all(u8::is_ascii_alphabetic) || len > i32::MAX as usize {
            return Err(bad(format!(
                "no chunk at byte {at} (type {:?}, length {len}): not PNG data",
                String::from_utf8_lossy(&kind)
            )));
        }
        if &kind == b"IDAT" {
            return Ok(PngHead {
                bytes,
                interlaced,
                exif,
            });
        }
        if &kind == b"IEND" {
            return Err(bad("no image data (IEND before any IDAT)".into()));
        }
        let end = at + 12 + len;
        if end as u64 > MARGIN {
            return Err(bad(format!(
                "over {} MiB of chunks before the image data",
                MARGIN >> 20
            )));
        }
        want(&mut bytes, end)?;
        let crc = u32::from_be_bytes(bytes[end - 4..end].try_into().expect("4 bytes"));
        if crc != png_crc(&bytes[at + 4..end - 4]) {
            let k = String::from_utf8_lossy(&kind).into_owned();
            return Err(bad(format!(
                "the {k} chunk's CRC does not match: corrupt data"
            )));
        }
        if &kind == b"IHDR" {
            let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().expect("4 bytes"));
            check_pixels(name, be(16), be(20), opts)?;
            interlaced = bytes[28] != 0;
        }
        exif |= &kind == b"eXIf";
        at = end;
    }
}

/// CRC-32 of ISO 3309, as PNG chunks carry it.
fn png_crc(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG read from a stream: row by row as from a file when it streams, else its bytes for
/// the whole-image reader (interlaced, or with an orientation to apply), behind the chunks
/// already checked.
fn png_stream(
    name: &Path,
    mut rest: impl Read + Send + 'static,
    opts: &ReadOptions,
) -> Result<Opened> {
    let head = png_head(name, &mut rest, opts)?;
    let whole = std::io::Cursor::new(head.bytes).chain(rest);
    if head.interlaced || head.exif {
        return Ok(Opened::Whole(Box::new(whole)));
    }
    let reader: Box<dyn PngRead> =
        Box::new(NoSeek(std::io::BufReader::with_capacity(1 << 16, whole)));
    match PngSource::from_reader(name, reader, opts)? {
        Some(src) => Ok(Opened::Rows(Box::new(src))),
        // Over the decode budget, or a form the row decoder does not give: the same error
        // or decode as for a file, which cannot be had once the stream is read.
        None => Err(decode_err(
            name,
            "this PNG cannot be decoded from a stream within the limits (over the decode \
             budget of `max_pixels`, or of a form read only whole); save it to a file and \
             pass its path"
                .into(),
        )),
    }
}

/// Non-interlaced PNG row by row through the png crate's `next_row`, with the codes the
/// `image` crate gives (the same transformations: palettes and low depths expanded, 16 bits
/// kept), alpha composited over white as the whole-image reader does.
struct PngSource {
    name: PathBuf,
    info: SourceInfo,
    reader: png::Reader<Box<dyn PngRead>>,
    /// Samples a pixel in a decoded row, alpha included.
    spp: usize,
    alpha: bool,
    /// Interleaved samples of a band (alpha included), when they need compositing.
    buf8: Vec<u8>,
    buf16: Vec<u16>,
    rows_read: usize,
}

impl PngSource {
    /// The decoder, or `None` when the file is a PNG that does not stream (interlaced, or
    /// with an EXIF orientation to apply): the whole-image reader takes it.
    fn open(name: &Path, path: &Path, opts: &ReadOptions) -> Result<Option<PngSource>> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(name, e))?;
        PngSource::from_reader(
            name,
            Box::new(std::io::BufReader::with_capacity(1 << 16, file)),
            opts,
        )
    }

    /// [`PngSource::open`] of a PNG read from its first byte by `reader`.
    fn from_reader(
        name: &Path,
        reader: Box<dyn PngRead>,
        opts: &ReadOptions,
    ) -> Result<Option<PngSource>> {
        let bad = |e: png::DecodingError| decode_err(name, format!("bad PNG file: {e}"));
        let mut dec = png::Decoder::new_with_limits(reader, png::Limits { bytes: usize::MAX });
        let header = dec.read_header_info().map_err(bad)?;
        check_pixels(name, header.width, header.height, opts)?;
        if header.width == 0 || header.height == 0 {
            return Ok(None);
        }
        dec.set_transformations(png::Transformations::EXPAND);
        let reader = dec.read_info().map_err(bad)?;
        let info = reader.info();
        if info.interlaced || info.exif_metadata.is_some() {
            return Ok(None);
        }
        let dpi = info
            .pixel_dims
            .filter(|d| d.unit == png::Unit::Meter && d.xppu > 0)
            .map(|d| d.xppu as f64 * 0.0254);
        let (width, height) = (info.width as usize, info.height as usize);
        let (color, depth) = reader.output_color_type();
        let (kind, spp, alpha) = match color {
            png::ColorType::Grayscale => (ColorKind::Gray, 1, false),
            png::ColorType::GrayscaleAlpha => (ColorKind::Gray, 2, true),
            png::ColorType::Rgb => (ColorKind::Rgb, 3, false),
            png::ColorType::Rgba => (ColorKind::Rgb, 4, true),
            png::ColorType::Indexed => return Ok(None),
        };
        let bits = match depth {
            png::BitDepth::Eight => 8,
            png::BitDepth::Sixteen => 16,
            _ => return Ok(None),
        };
        // The whole-image reader's bound on what a decoder may produce holds here too; over
        // it, that reader gives the error.
        let decoded = (width * height * spp) as u64 * (bits as u64 / 8);
        if decoded > crate::io::decode_budget(opts) {
            return Ok(None);
        }
        Ok(Some(PngSource {
            name: name.to_path_buf(),
            info: SourceInfo {
                width,
                height,
                color: kind,
                bits,
                dpi,
            },
            reader,
            spp,
            alpha,
            buf8: Vec::new(),
            buf16: Vec::new(),
            rows_read: 0,
        }))
    }
}

impl RowSource for PngSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn bytes_per_row(&self) -> usize {
        // The decoder's current and previous rows, and the interleaved band.
        let row = self.info.width * self.spp * (self.info.bits as usize / 8);
        3 * row
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        let rows = rows.min(self.info.height - self.rows_read);
        let w = self.info.width;
        let n = w * rows;
        band.width = w;
        band.height = rows;
        let (spp, sixteen) = (self.spp, self.info.bits == 16);
        self.buf8.clear();
        self.buf16.clear();
        for _ in 0..rows {
            let row = match self.reader.next_row() {
                Ok(Some(r)) => r,
                Ok(None) => {
                    return Err(decode_err(
                        &self.name,
                        format!("truncated: {} of {} rows", self.rows_read, self.info.height),
                    ))
                }
                Err(e) => return Err(decode_err(&self.name, format!("bad PNG file: {e}"))),
            };
            let data = row.data();
            if sixteen {
                self.buf16.extend(
                    data.chunks_exact(2)
                        .map(|b| u16::from_be_bytes([b[0], b[1]])),
                );
            } else {
                self.buf8.extend_from_slice(data);
            }
        }
        self.rows_read += rows;
        let channels = spp - self.alpha as usize;
        if self.alpha {
            if sixteen {
                for (p, v) in band
                    .planes
                    .iter_mut()
                    .zip(crate::io::composite16(&self.buf16, channels))
                {
                    *p = Samples::U16(v);
                }
            } else {
                for (p, v) in band
                    .planes
                    .iter_mut()
                    .zip(crate::io::composite8(&self.buf8, channels))
                {
                    *p = Samples::U8(v);
                }
            }
            return Ok(());
        }
        for (c, p) in band.planes.iter_mut().enumerate() {
            match p {
                Samples::U8(plane) => {
                    plane.resize(n, 0);
                    for (o, px) in plane.iter_mut().zip(self.buf8.chunks_exact(spp)) {
                        *o = px[c];
                    }
                }
                Samples::U16(plane) => {
                    plane.resize(n, 0);
                    for (o, px) in plane.iter_mut().zip(self.buf16.chunks_exact(spp)) {
                        *o = px[c];
                    }
                }
            }
        }
        Ok(())
    }
}

/// The outcome of [`open`].
pub enum Opened {
    /// A streaming decoder.
    Rows(Box<dyn RowSource>),
    /// A format that does not stream: the whole stream, from its first byte.
    Whole(Box<dyn Read + Send>),
}

/// P4, P5 and P6 row by row, with the codes of [`pnm::read_data`] and the `image` crate.
struct PnmSource {
    name: PathBuf,
    header: PnmHeader,
    info: SourceInfo,
    data: Box<dyn Read + Send>,
    /// Bytes of one file row.
    file_row: usize,
    /// File bytes of a band (P4, 16-bit and P6 data are converted from here).
    buf: Vec<u8>,
    /// 8-bit rescale table (maxval < 255) or 16-bit one (maxval not 255 or 65535).
    table8: Option<[u8; 256]>,
    table16: Option<Vec<u16>>,
    rows_read: usize,
}

impl PnmSource {
    fn new(name: &Path, header: PnmHeader, pixmap: bool, data: Box<dyn Read + Send>) -> Self {
        let w = header.width as usize;
        let channels = if pixmap { 3 } else { 1 };
        let bits = if header.maxval > 255 { 16 } else { 8 };
        let file_row = match header.kind {
            PnmKind::Bitmap => w.div_ceil(8),
            PnmKind::Greymap => w * channels * (bits / 8),
        };
        let table8 = (header.kind == PnmKind::Greymap && header.maxval < 255).then(|| {
            let mut t = [0u8; 256];
            for (v, o) in t.iter_mut().enumerate() {
                let mut b = [v as u8];
                pnm::rescale8(&mut b, header.maxval);
                *o = b[0];
            }
            t
        });
        // As pnm::read_data does: round(v × 65535/maxval) in f32.
        let table16 = (bits == 16 && header.maxval != 65535).then(|| {
            let factor = 65535.0f32 / header.maxval as f32;
            (0..=65535u32)
                .map(|v| (v as f32 * factor).round() as u16)
                .collect()
        });
        PnmSource {
            name: name.to_path_buf(),
            header,
            info: SourceInfo {
                width: w,
                height: header.height as usize,
                color: if pixmap {
                    ColorKind::Rgb
                } else {
                    ColorKind::Gray
                },
                bits: bits as u32,
                dpi: None,
            },
            data,
            file_row,
            buf: Vec::new(),
            table8,
            table16,
            rows_read: 0,
        }
    }

    fn truncated(&self, e: std::io::Error) -> Error {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            let total = self.file_row * self.info.height;
            decode_err(&self.name, pnm::truncated_message(&self.header, total))
        } else {
            Error::io(&self.name, e)
        }
    }
}

impl RowSource for PnmSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    /// Streamed, reading the next band overlaps halftoning and writing the last one (see the
    /// pipeline's streaming way), which the whole-image way cannot do: on 24 MP, RGB
    /// Floyd–Steinberg to PPM took 97 ms streamed against 130 ms whole, grey to PBM 40 ms
    /// against 46 ms.
    fn prefers_streaming(&self) -> bool {
        true
    }

    fn bytes_per_row(&self) -> usize {
        let direct = self.header.kind == PnmKind::Greymap
            && self.info.color == ColorKind::Gray
            && self.info.bits == 8;
        if direct {
            0
        } else {
            self.file_row
        }
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        let rows = rows.min(self.info.height - self.rows_read);
        let w = self.info.width;
        let n = w * rows;
        band.height = rows;
        band.width = w;
        let direct = self.header.kind == PnmKind::Greymap
            && self.info.color == ColorKind::Gray
            && self.info.bits == 8;
        if direct {
            // P5 at 8 bits: straight into the plane.
            let Samples::U8(plane) = &mut band.planes[0] else {
                unreachable!("8-bit band")
            };
            plane.resize(n, 0);
            let read = self.data.read_exact(plane);
            read.map_err(|e| self.truncated(e))?;
            if let Some(t) = &self.table8 {
                for v in plane.iter_mut() {
                    *v = t[*v as usize];
                }
            }
            self.rows_read += rows;
            return Ok(());
        }
        self.buf.resize(self.file_row * rows, 0);
        let read = self.data.read_exact(&mut self.buf);
        read.map_err(|e| self.truncated(e))?;
        match (self.header.kind, self.info.bits) {
            (PnmKind::Bitmap, _) => {
                let Samples::U8(plane) = &mut band.planes[0] else {
                    unreachable!("8-bit band")
                };
                plane.resize(n, 0);
                let fr = self.file_row;
                for (row, src) in plane.chunks_exact_mut(w).zip(self.buf.chunks_exact(fr)) {
                    // Bit 1 (ink) → 0, bit 0 (paper) → 255, as pnm::read_data.
                    for (x, o) in row.iter_mut().enumerate() {
                        *o = if src[x / 8] & (0x80 >> (x % 8)) != 0 {
                            0
                        } else {
                            255
                        };
                    }
                }
            }
            (_, 8) => {
                // P6 at 8 bits: deinterleave, the three planes in one pass over the pixels.
                let [Samples::U8(r), Samples::U8(g), Samples::U8(b)] = &mut band.planes[..] else {
                    unreachable!("three 8-bit planes")
                };
                for p in [&mut *r, &mut *g, &mut *b] {
                    p.resize(n, 0);
                }
                let (r, g, b) = (&mut r[..n], &mut g[..n], &mut b[..n]);
                let planes = r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut());
                for (((r, g), b), px) in planes.zip(self.buf.chunks_exact(3)) {
                    (*r, *g, *b) = (px[0], px[1], px[2]);
                }
                if let Some(t) = &self.table8 {
                    for v in r.iter_mut().chain(g.iter_mut()).chain(b.iter_mut()) {
                        *v = t[*v as usize];
                    }
                }
            }
            _ => {
                let channels = self.info.channels();
                for (c, p) in band.planes.iter_mut().enumerate() {
                    let Samples::U16(plane) = p else {
                        unreachable!("16-bit band")
                    };
                    plane.resize(n, 0);
                    for (o, px) in plane.iter_mut().zip(self.buf.chunks_exact(2 * channels)) {
                        let v = u16::from_be_bytes([px[2 * c], px[2 * c + 1]]);
                        *o = match &self.table16 {
                            Some(t) => t[v as usize],
                            None => v,
                        };
                    }
                }
            }
        }
        self.rows_read += rows;
        Ok(())
    }
}

/// TIFF strip by strip through the tiff crate's `read_chunk`, for the layouts whose codes the
/// `image` crate passes on unchanged: grey (BlackIsZero) or RGB, 8 or 16 bits, one plane of
/// interleaved samples, no alpha, top-left orientation. Others go whole.
struct TiffSource {
    name: PathBuf,
    info: SourceInfo,
    decoder: tiff::decoder::Decoder<std::io::BufReader<std::fs::File>>,
    strips: u32,
    rows_per_strip: usize,
    /// The strip last read.
    strip: Option<(u32, tiff::decoder::DecodingResult)>,
    rows_read: usize,
}

impl TiffSource {
    fn open(name: &Path, path: &Path, opts: &ReadOptions) -> Result<Option<TiffSource>> {
        use tiff::decoder::ChunkType;
        use tiff::tags::Tag;
        use tiff::ColorType;
        let file = std::fs::File::open(path).map_err(|e| Error::io(name, e))?;
        let Ok(mut d) =
            tiff::decoder::Decoder::new(std::io::BufReader::with_capacity(1 << 16, file))
        else {
            // The whole-image reader gives the error message.
            return Ok(None);
        };
        let Ok((w, h)) = d.dimensions() else {
            return Ok(None);
        };
        check_pixels(name, w, h, opts)?;
        let tag = |d: &mut tiff::decoder::Decoder<_>, t: Tag| -> Option<u32> {
            d.find_tag_unsigned::<u32>(t).ok().flatten()
        };
        let photometric = tag(&mut d, Tag::PhotometricInterpretation);
        let orientation = tag(&mut d, Tag::Orientation).unwrap_or(1);
        let planar = tag(&mut d, Tag::PlanarConfiguration).unwrap_or(1);
        let (color, bits) = match (d.colortype(), photometric) {
            (Ok(ColorType::Gray(8)), Some(1)) => (ColorKind::Gray, 8),
            (Ok(ColorType::Gray(16)), Some(1)) => (ColorKind::Gray, 16),
            (Ok(ColorType::RGB(8)), Some(2)) => (ColorKind::Rgb, 8),
            (Ok(ColorType::RGB(16)), Some(2)) => (ColorKind::Rgb, 16),
            _ => return Ok(None),
        };
        if d.get_chunk_type() != ChunkType::Strip || orientation != 1 || planar != 1 || w == 0 {
            return Ok(None);
        }
        let decoded =
            w as u64 * h as u64 * (bits as u64 / 8) * if color == ColorKind::Rgb { 3 } else { 1 };
        if decoded > crate::io::decode_budget(opts) {
            return Ok(None);
        }
        let Ok(strips) = d.strip_count() else {
            return Ok(None);
        };
        let rows_per_strip = d.chunk_dimensions().1 as usize;
        if rows_per_strip == 0 {
            return Ok(None);
        }
        Ok(Some(TiffSource {
            name: name.to_path_buf(),
            info: SourceInfo {
                width: w as usize,
                height: h as usize,
                color,
                bits,
                dpi: None,
            },
            decoder: d,
            strips,
            rows_per_strip,
            strip: None,
            rows_read: 0,
        }))
    }
}

impl RowSource for TiffSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn buffer_bytes(&self) -> usize {
        // One decoded strip.
        self.rows_per_strip.min(self.info.height) * self.info.row_bytes()
    }

    fn bytes_per_row(&self) -> usize {
        0
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        use tiff::decoder::DecodingResult;
        let rows = rows.min(self.info.height - self.rows_read);
        let (w, channels) = (self.info.width, self.info.channels());
        band.width = w;
        band.height = rows;
        for p in band.planes.iter_mut() {
            match p {
                Samples::U8(v) => v.resize(w * rows, 0),
                Samples::U16(v) => v.resize(w * rows, 0),
            }
        }
        let mut r = 0;
        while r < rows {
            let index = (self.rows_read + r) / self.rows_per_strip;
            if self.strip.as_ref().is_none_or(|(i, _)| *i != index as u32) {
                if index as u32 >= self.strips {
                    return Err(decode_err(&self.name, "truncated: strips missing".into()));
                }
                let chunk = self
                    .decoder
                    .read_chunk(index as u32)
                    .map_err(|e| decode_err(&self.name, format!("bad TIFF file: {e}")))?;
                self.strip = Some((index as u32, chunk));
            }
            let start = (self.rows_read + r) % self.rows_per_strip;
            let take = (self.rows_per_strip - start).min(rows - r);
            let (_, chunk) = self.strip.as_ref().expect("read above");
            let (from, to) = (start * w * channels, (start + take) * w * channels);
            for (c, p) in band.planes.iter_mut().enumerate() {
                let at = r * w;
                match (p, chunk) {
                    (Samples::U8(v), DecodingResult::U8(s)) if s.len() >= to => {
                        for (o, px) in v[at..at + take * w]
                            .iter_mut()
                            .zip(s[from..to].chunks_exact(channels))
                        {
                            *o = px[c];
                        }
                    }
                    (Samples::U16(v), DecodingResult::U16(s)) if s.len() >= to => {
                        for (o, px) in v[at..at + take * w]
                            .iter_mut()
                            .zip(s[from..to].chunks_exact(channels))
                        {
                            *o = px[c];
                        }
                    }
                    _ => {
                        return Err(decode_err(
                            &self.name,
                            "bad TIFF file: a strip holds fewer rows than it should".into(),
                        ))
                    }
                }
            }
            r += take;
        }
        self.rows_read += rows;
        Ok(())
    }
}
