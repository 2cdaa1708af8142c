//! TIFF writer: the tiff crate's directory encoder with strips we compress ourselves, so
//! Group 4 data (fax crate) and the resolution tags go in one file of our own layout.
//!
//! Bilevel grey is 1 bit a pixel with Photometric WhiteIsZero (bit 1 = ink), for every
//! compression: that is what fax software expects of Group 4 (TIFF 6.0 §11), and using it
//! for the others too keeps one bit sense; the strip bytes are those of a PBM. Other grey
//! halftones are 8-bit BlackIsZero holding each level's reflectance as a display code
//! (sRGB-encoded unless the display is linear), so any viewer shows the right tone;
//! RGB and palette halftones are 8-bit RGB the same way.

use std::io::{Cursor, Seek, Write};

use rayon::prelude::*;
use tiff::encoder::compression::{CompressionAlgorithm, Deflate, Lzw, Packbits};
use tiff::encoder::{DirectoryEncoder, Rational, TiffEncoder as TiffFile, TiffKind};
use tiff::tags::{CompressionMethod, PhotometricInterpretation, ResolutionUnit, Tag};

use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{level_codes8, row8_of, Compression, EncodeError, EncodeResult, WriteOptions};

/// Default compression of bilevel halftones: Deflate.
///
/// Measured on A4 pages at 300 dpi (2480×3508, 1 087 694 bytes of raw bits), file sizes:
///
/// | page                                   | G4        | Deflate | LZW     | PackBits |
/// |----------------------------------------|-----------|---------|---------|----------|
/// | photo, Floyd–Steinberg (ImageMagick)   | 1 348 388 | 582 311 | 669 361 | 820 831  |
/// | photo, ordered 8×8 (ImageMagick)       | 3 437 498 | 222 378 | 263 204 | 449 878  |
/// | photo, `pattern --mask seed-3x3`       | 1 864 984 | 171 989 | 228 626 | 638 093  |
/// | text and rules, `threshold`            |    90 222 |  97 954 | 144 191 | 232 705  |
///
/// Group 4 codes runs, and dithered texture is nothing but short runs: it comes out larger
/// than the raw bits (up to 3×), while on text it beats Deflate by only 8%. Halftones are
/// mostly texture, so Deflate is the default; ask for G4 for fax and line art.
pub const DEFAULT_BILEVEL_COMPRESSION: Compression = Compression::Deflate;

/// Uncompressed bytes per strip (rows are grouped up to this size), except for Group 4,
/// which is written as one strip the way fax software writes it.
const STRIP_BYTES: usize = 256 * 1024;

/// Strips compressed together, on every core, once this many have filled.
const STRIPS_AT_ONCE: usize = 8;

/// The TIFF encoder. Rows are compressed into strips as they arrive, so only the compressed
/// strips stay until the end of the page: the file's header points at the directory, which
/// names every strip's offset and size, so it is written last, with the strips, in one go.
pub(in crate::io) struct TiffEncoder {
    opts: WriteOptions,
    page: Option<TiffPage>,
    pages: usize,
}

struct TiffPage {
    header: PageHeader,
    bilevel: bool,
    compression: Compression,
    spp: usize,
    row_bytes: usize,
    rows_per_strip: usize,
    table: [u8; 256],
    levels: Vec<u8>,
    /// Uncompressed rows of strips not yet compressed.
    raw: Vec<u8>,
    /// Group 4: one strip, coded row by row.
    g4: Option<fax::encoder::Encoder<fax::VecWriter>>,
    strips: Vec<Vec<u8>>,
    done: usize,
}

impl TiffEncoder {
    pub(in crate::io) fn new(opts: &WriteOptions) -> TiffEncoder {
        TiffEncoder {
            opts: opts.clone(),
            page: None,
            pages: 0,
        }
    }
}

impl TiffPage {
    /// Compresses the whole strips held in `raw` (and a last, short one when `last`).
    fn compress_raw(&mut self, last: bool) -> std::io::Result<()> {
        let strip = self.rows_per_strip * self.row_bytes;
        let whole = if last {
            self.raw.len()
        } else {
            self.raw.len() / strip * strip
        };
        if whole == 0 {
            return Ok(());
        }
        let (compression, width, row_bytes) = (self.compression, self.header.width, self.row_bytes);
        let strips: Vec<Vec<u8>> = self.raw[..whole]
            .par_chunks(strip)
            .map(|s| compress(s, compression, width, row_bytes))
            .collect::<std::io::Result<_>>()?;
        self.strips.extend(strips);
        self.raw.drain(..whole);
        Ok(())
    }
}

impl PageEncoder for TiffEncoder {
    fn begin_page(&mut self, h: &PageHeader, _out: &mut dyn Write) -> EncodeResult {
        crate::io::sink::one_page_only(&mut self.pages)?;
        let opts = &self.opts;
        let bilevel = h.is_bilevel_grey();
        let compression = opts.compression.unwrap_or(if bilevel {
            DEFAULT_BILEVEL_COMPRESSION
        } else {
            Compression::Deflate
        });
        if compression == Compression::G4 && !bilevel {
            return Err(EncodeError::Other(
                "Group 4 compression is for black and white only".into(),
            ));
        }
        let spp = if h.channels == 1 && h.palette.is_none() {
            1
        } else {
            3
        };
        let row_bytes = if bilevel { h.stride } else { h.width * spp };
        let rows_per_strip = if compression == Compression::G4 {
            h.height
        } else {
            (STRIP_BYTES / row_bytes).clamp(1, h.height)
        };
        let g4 = (compression == Compression::G4)
            .then(|| fax::encoder::Encoder::new(fax::VecWriter::with_capacity(h.stride * 2)));
        self.page = Some(TiffPage {
            header: h.clone(),
            bilevel,
            compression,
            spp: if bilevel { 1 } else { spp },
            row_bytes,
            rows_per_strip,
            table: level_codes8(h.levels, opts.display),
            levels: vec![0u8; h.width],
            raw: Vec::new(),
            g4,
            strips: Vec::new(),
            done: 0,
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, _out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        for r in 0..band.rows {
            let rows = band.row(r, stride);
            // Uncompressed rows, in the file's bit sense and layout.
            let at = p.raw.len();
            p.raw.resize(at + p.row_bytes, 0);
            let dst = &mut p.raw[at..];
            if p.bilevel {
                crate::io::invert_bilevel_row(rows[0], p.header.width, dst);
            } else {
                row8_of(
                    &p.header,
                    &rows[..band.planes.len()],
                    &p.table,
                    &mut p.levels,
                    dst,
                );
            }
            if let Some(enc) = &mut p.g4 {
                g4_line(enc, &p.raw, p.header.width);
                p.raw.clear();
            }
        }
        p.done += band.rows;
        if p.raw.len() >= STRIPS_AT_ONCE * p.rows_per_strip * p.row_bytes {
            p.compress_raw(false)?;
        }
        Ok(())
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let mut p =
            crate::io::sink::take_complete_page(&mut self.page, |p| (p.done, p.header.height))?;
        if let Some(enc) = p.g4.take() {
            p.strips.push(match enc.finish() {
                Ok(w) => w.finish(),
                Err(never) => match never {},
            });
        } else {
            p.compress_raw(true)?;
        }
        write_file(&p, &self.opts, out)
    }
}

/// The file: header, the strips, then the directory.
fn write_file(p: &TiffPage, opts: &WriteOptions, out: &mut dyn Write) -> EncodeResult {
    let h = &p.header;
    let (compression, spp, strips) = (p.compression, p.spp, &p.strips);
    let tiff_err = |e: tiff::TiffError| match e {
        tiff::TiffError::IoError(e) => EncodeError::Io(e),
        e => EncodeError::Other(e.to_string()),
    };
    let mut file = Cursor::new(Vec::new());
    {
        let mut enc = TiffFile::new(&mut file).map_err(tiff_err)?;
        let mut dir = enc.image_directory().map_err(tiff_err)?;
        let mut offsets = Vec::with_capacity(strips.len());
        for s in strips {
            offsets.push(dir.write_data(s.as_slice()).map_err(tiff_err)? as u32);
        }
        let counts: Vec<u32> = strips.iter().map(|s| s.len() as u32).collect();
        let (bits, photometric): (&[u16], _) = match (p.bilevel, spp) {
            (true, _) => (&[1], PhotometricInterpretation::WhiteIsZero),
            (false, 1) => (&[8], PhotometricInterpretation::BlackIsZero),
            _ => (&[8, 8, 8], PhotometricInterpretation::RGB),
        };
        let method = match compression {
            Compression::G4 => CompressionMethod::Fax4,
            Compression::Deflate => CompressionMethod::Deflate,
            Compression::Lzw => CompressionMethod::LZW,
            Compression::PackBits => CompressionMethod::PackBits,
            Compression::None => CompressionMethod::None,
        };
        dir.write_tag(Tag::ImageWidth, h.width as u32)
            .map_err(tiff_err)?;
        dir.write_tag(Tag::ImageLength, h.height as u32)
            .map_err(tiff_err)?;
        dir.write_tag(Tag::BitsPerSample, bits).map_err(tiff_err)?;
        dir.write_tag(Tag::Compression, method).map_err(tiff_err)?;
        dir.write_tag(Tag::PhotometricInterpretation, photometric)
            .map_err(tiff_err)?;
        dir.write_tag(Tag::StripOffsets, offsets.as_slice())
            .map_err(tiff_err)?;
        dir.write_tag(Tag::SamplesPerPixel, spp as u16)
            .map_err(tiff_err)?;
        dir.write_tag(Tag::RowsPerStrip, p.rows_per_strip as u32)
            .map_err(tiff_err)?;
        dir.write_tag(Tag::StripByteCounts, counts.as_slice())
            .map_err(tiff_err)?;
        if let Some(dpi) = opts.dpi {
            write_resolution(&mut dir, dpi).map_err(tiff_err)?;
        }
        if spp == 3 {
            dir.write_tag(Tag::PlanarConfiguration, 1u16)
                .map_err(tiff_err)?;
        }
        if compression == Compression::G4 {
            // T6Options: no uncompressed mode.
            dir.write_tag(Tag::Unknown(293), 0u32).map_err(tiff_err)?;
        }
        dir.finish().map_err(tiff_err)?;
    }
    out.write_all(file.get_ref())?;
    Ok(())
}

/// Writes a directory's resolution: XResolution and YResolution as `dpi` (a rational, see
/// [`rational`]) and ResolutionUnit inch. The one writer of TIFF resolution tags (the
/// halftone files here and the press plates of `press::plates`).
pub(crate) fn write_resolution<W: Write + Seek, K: TiffKind>(
    dir: &mut DirectoryEncoder<'_, W, K>,
    dpi: f64,
) -> tiff::TiffResult<()> {
    let r = rational(dpi);
    dir.write_tag(Tag::XResolution, &r)?;
    dir.write_tag(Tag::YResolution, &r)?;
    dir.write_tag(Tag::ResolutionUnit, ResolutionUnit::Inch)
}

/// A resolution as a TIFF rational: whole dpi exactly, else to 1/1000 dpi.
fn rational(dpi: f64) -> Rational {
    if dpi.fract() == 0.0 && dpi <= u32::MAX as f64 {
        Rational {
            n: dpi as u32,
            d: 1,
        }
    } else {
        Rational {
            n: (dpi * 1000.0).round() as u32,
            d: 1000,
        }
    }
}

/// Compresses one strip of rows (`row_bytes` each).
fn compress(
    strip: &[u8],
    compression: Compression,
    width: usize,
    row_bytes: usize,
) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    match compression {
        Compression::None => out.extend_from_slice(strip),
        Compression::Deflate => {
            Deflate::default().write_to(&mut out, strip)?;
        }
        Compression::Lzw => {
            Lzw.write_to(&mut out, strip)?;
        }
        Compression::PackBits => {
            // PackBits runs must not cross rows (TIFF 6.0 §9).
            for row in strip.chunks_exact(row_bytes) {
                Packbits.write_to(&mut out, row)?;
            }
        }
        Compression::G4 => out = g4(strip, width, row_bytes),
    }
    Ok(out)
}

/// CCITT T.6 (Group 4) coding of WhiteIsZero rows: bit 1 = black pel.
pub(in crate::io) fn g4(rows: &[u8], width: usize, row_bytes: usize) -> Vec<u8> {
    let mut enc = fax::encoder::Encoder::new(fax::VecWriter::with_capacity(rows.len() * 2));
    for row in rows.chunks_exact(row_bytes) {
        g4_line(&mut enc, row, width);
    }
    match enc.finish() {
        Ok(w) => w.finish(),
        Err(never) => match never {},
    }
}

/// Codes one WhiteIsZero row (bit 1 = black pel) into a Group 4 stream.
fn g4_line(enc: &mut fax::encoder::Encoder<fax::VecWriter>, row: &[u8], width: usize) {
    use fax::Color;
    let pels = (0..width).map(|x| {
        if row[x / 8] & (0x80 >> (x % 8)) != 0 {
            Color::Black
        } else {
            Color::White
        }
    });
    // VecWriter never fails.
    let _ = enc.encode_line(pels, width as u32);
}
