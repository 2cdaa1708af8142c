//! PDF: one page an image, the page exactly the image's physical size (or `--page`, with
//! the image centred), every pixel one image sample.
//!
//! Written by hand rather than through a PDF library so that a page streams: a grey or
//! bilevel image's rows are deflated straight into the output as they arrive, its
//! `/Length` given as an indirect object written after the stream (PDF 1.7 §7.3.10), so a
//! book of pages never sits in memory. Only what cannot stream is held: Group 4 data
//! (the `fax` encoder's output for one page) and the four plates of a CMYK page, which
//! follow one another in the file but arrive together.
//!
//! Images: bilevel grey is 1-bit `/DeviceGray` (bit 1 = paper = white, so no `/Decode`
//! is needed), with `/FlateDecode` or `/CCITTFaxDecode` (K −1, Group 4); few-level grey
//! is 2/4/8-bit `/DeviceGray` with `/Decode [0 d]` so that level L−1 is white; RGB planes
//! are interleaved `/DeviceRGB`; palettes are `/Indexed`. A 4-plane halftone (cyan,
//! magenta, yellow, black) is four `/Separation` images drawn with overprint, so a RIP
//! (or Ghostscript's `tiffsep1`) gets back exactly the plates.

use std::io::{Read, Write};

use flate2::write::ZlibEncoder;

use super::{fail, find, number, numbers, space, value, DecodeResult, ImageHead, Space};
use super::{Chunky, Language, PrintOptions};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{Compression, EncodeError, EncodeResult};
use crate::raster::Image;

/// The inks of a 4-plane halftone, in plane order.
const INKS: [&str; 4] = ["Cyan", "Magenta", "Yellow", "Black"];

/// Streaming PDF writer.
pub struct PdfEncoder {
    opts: PrintOptions,
    g4: bool,
    /// Bytes written so far (for the cross-reference table).
    pos: u64,
    /// Byte offset of every object, by number − 1 (0 until written).
    offsets: Vec<u64>,
    /// Object numbers of the pages.
    pages: Vec<usize>,
    page: Option<Page>,
    started: bool,
}

/// A page in progress.
struct Page {
    header: PageHeader,
    chunky: Chunky,
    body: Body,
    /// Object numbers: page, contents, images (one, or one a plate).
    page_obj: usize,
    images: Vec<usize>,
    rows: usize,
}

enum Body {
    /// One image deflated straight into the output; `start` is where its data began.
    Stream {
        z: ZlibEncoder<Vec<u8>>,
        start: u64,
        length_obj: usize,
    },
    /// Group 4 rows gathered for the page.
    G4(fax::encoder::Encoder<fax::VecWriter>),
    /// One deflated plate an ink.
    Plates(Vec<ZlibEncoder<Vec<u8>>>),
}

impl PdfEncoder {
    /// A PDF writer; `compression` `Some(G4)` asks for Group 4 (bilevel pages only).
    pub fn new(opts: PrintOptions, compression: Option<Compression>) -> PdfEncoder {
        PdfEncoder {
            opts,
            g4: compression == Some(Compression::G4),
            pos: 0,
            // 1 = catalog, 2 = page tree: written at the end.
            offsets: vec![0, 0],
            pages: Vec::new(),
            page: None,
            started: false,
        }
    }

    fn put(&mut self, out: &mut dyn Write, bytes: &[u8]) -> EncodeResult {
        out.write_all(bytes)?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    fn alloc(&mut self) -> usize {
        self.offsets.push(0);
        self.offsets.len()
    }

    fn begin_obj(&mut self, out: &mut dyn Write, n: usize) -> EncodeResult {
        self.offsets[n - 1] = self.pos;
        self.put(out, format!("{n} 0 obj\n").as_bytes())
    }

    /// Writes a whole object `n` whose body is `body`.
    fn obj(&mut self, out: &mut dyn Write, n: usize, body: &str) -> EncodeResult {
        self.begin_obj(out, n)?;
        self.put(out, body.as_bytes())?;
        self.put(out, b"\nendobj\n")
    }

    /// Writes stream object `n` with dictionary entries `dict` and data `data`.
    fn stream_obj(
        &mut self,
        out: &mut dyn Write,
        n: usize,
        dict: &str,
        data: &[u8],
    ) -> EncodeResult {
        self.begin_obj(out, n)?;
        self.put(
            out,
            format!("<< {dict} /Length {} >>\nstream\n", data.len()).as_bytes(),
        )?;
        self.put(out, data)?;
        self.put(out, b"\nendstream\nendobj\n")
    }

    /// The image dictionary entries (without filter and length) of plane `plate` (or the
    /// whole image when `None`).
    fn image_dict(page: &PageHeader, plate: Option<usize>) -> String {
        let mut d = format!(
            "/Type /XObject /Subtype /Image /Width {} /Height {} /BitsPerComponent {}",
            page.width, page.height, page.bits
        );
        let dmax = super::num(super::decode_max(page.bits, page.levels));
        if let Some(c) = plate {
            // Tint 1 = full ink = level 0: the decode runs from 1 down.
            let lo = super::num(1.0 - super::decode_max(page.bits, page.levels));
            let c1 = match c {
                0 => "1 0 0 0",
                1 => "0 1 0 0",
                2 => "0 0 1 0",
                _ => "0 0 0 1",
            };
            d += &format!(
                " /ColorSpace [/Separation /{} /DeviceCMYK << /FunctionType 2 /Domain [0 1] /C0 [0 0 0 0] /C1 [{c1}] /N 1 >>] /Decode [1 {lo}]",
                INKS[c]
            );
        } else if let Some(p) = &page.palette {
            let hex: String = p.iter().flatten().map(|b| format!("{b:02X}")).collect();
            d += &format!(" /ColorSpace [/Indexed /DeviceRGB {} <{hex}>]", p.len() - 1);
        } else if page.channels == 3 {
            d += &format!(" /ColorSpace /DeviceRGB /Decode [0 {dmax} 0 {dmax} 0 {dmax}]");
        } else if page.levels == 2 {
            d += " /ColorSpace /DeviceGray";
        } else {
            d += &format!(" /ColorSpace /DeviceGray /Decode [0 {dmax}]");
        }
        d
    }
}

impl PageEncoder for PdfEncoder {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = super::check(Language::Pdf, page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        if self.g4 && !page.is_bilevel_grey() {
            return Err(EncodeError::Other(
                "Group 4 compression is for black and white only; use `compression` deflate".into(),
            ));
        }
        if self.page.is_some() {
            return Err(EncodeError::Other("a page began inside another".into()));
        }
        if !self.started {
            self.started = true;
            // A binary comment line so that transfer programs treat the file as binary.
            self.put(out, b"%PDF-1.4\n%\xE2\xE3\xCF\xD3\n")?;
        }
        let page_obj = self.alloc();
        let plates = if page.channels == 4 { 4 } else { 1 };
        let images: Vec<usize> = (0..plates).map(|_| self.alloc()).collect();
        let level = flate2::Compression::default();
        let body = if plates == 4 {
            Body::Plates(
                (0..4)
                    .map(|_| ZlibEncoder::new(Vec::new(), level))
                    .collect(),
            )
        } else if self.g4 {
            Body::G4(fax::encoder::Encoder::new(fax::VecWriter::new()))
        } else {
            let length_obj = self.alloc();
            let dict = Self::image_dict(page, None);
            self.begin_obj(out, images[0])?;
            self.put(
                out,
                format!("<< {dict} /Filter /FlateDecode /Length {length_obj} 0 R >>\nstream\n")
                    .as_bytes(),
            )?;
            Body::Stream {
                z: ZlibEncoder::new(Vec::new(), level),
                start: self.pos,
                length_obj,
            }
        };
        self.page = Some(Page {
            header: page.clone(),
            chunky: Chunky::new(page),
            body,
            page_obj,
            images,
            rows: 0,
        });
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let mut p = crate::io::sink::take_page_for_rows(&mut self.page)?;
        let stride = p.header.stride;
        let result = (|| -> EncodeResult {
            match &mut p.body {
                Body::Stream { z, .. } => {
                    for r in 0..band.rows {
                        z.write_all(p.chunky.build(band.planes, stride, r))?;
                    }
                    let pending = std::mem::take(z.get_mut());
                    self.put(out, &pending)?;
                }
                Body::G4(enc) => {
                    use fax::Color;
                    let w = p.header.width;
                    for r in 0..band.rows {
                        let row = &band.planes[0][r * stride..(r + 1) * stride];
                        let pels = (0..w).map(|x| {
                            if row[x / 8] & (0x80 >> (x % 8)) == 0 {
                                Color::Black
                            } else {
                                Color::White
                            }
                        });
                        // VecWriter never fails.
                        let _ = enc.encode_line(pels, w as u32);
                    }
                }
                Body::Plates(zs) => {
                    for (z, plane) in zs.iter_mut().zip(band.planes) {
                        z.write_all(&plane[..band.rows * stride])?;
                    }
                }
            }
            Ok(())
        })();
        p.rows += band.rows;
        self.page = Some(p);
        result
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let p = crate::io::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
        let h = &p.header;
        match p.body {
            Body::Stream {
                z,
                start,
                length_obj,
            } => {
                let rest = z.finish()?;
                self.put(out, &rest)?;
                let len = self.pos - start;
                self.put(out, b"\nendstream\nendobj\n")?;
                self.obj(out, length_obj, &len.to_string())?;
            }
            Body::G4(enc) => {
                let data = match enc.finish() {
                    Ok(w) => w.finish(),
                    Err(never) => match never {},
                };
                let dict = format!(
                    "{} /Filter /CCITTFaxDecode /DecodeParms << /K -1 /Columns {} /Rows {} >>",
                    Self::image_dict(h, None),
                    h.width,
                    h.height
                );
                self.stream_obj(out, p.images[0], &dict, &data)?;
            }
            Body::Plates(zs) => {
                for (c, z) in zs.into_iter().enumerate() {
                    let data = z.finish()?;
                    let dict = format!("{} /Filter /FlateDecode", Self::image_dict(h, Some(c)));
                    self.stream_obj(out, p.images[c], &dict, &data)?;
                }
            }
        }
        let dpi = super::page_dpi(h);
        let (x, y, pw, ph) = super::placement(h, &self.opts, dpi);
        let (w, hh) = super::image_points(h, dpi);
        let names: Vec<String> = (0..p.images.len()).map(|i| format!("/Im{i}")).collect();
        let mut content = format!(
            "q {} 0 0 {} {} {} cm ",
            super::num(w),
            super::num(hh),
            super::num(x),
            super::num(y)
        );
        if p.images.len() == 4 {
            content += "/OP gs ";
        }
        for n in &names {
            content += &format!("{n} Do ");
        }
        content += "Q";
        let contents_obj = self.alloc();
        self.stream_obj(out, contents_obj, "", content.as_bytes())?;
        let xobjects: String = names
            .iter()
            .zip(&p.images)
            .map(|(n, i)| format!("{n} {i} 0 R "))
            .collect();
        let gstate = if p.images.len() == 4 {
            " /ExtGState << /OP << /Type /ExtGState /OP true /op true /OPM 1 >> >>"
        } else {
            ""
        };
        let page = format!(
            "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {} {}] /Resources << /XObject << {xobjects}>>{gstate} >> /Contents {contents_obj} 0 R >>",
            super::num(pw),
            super::num(ph)
        );
        self.obj(out, p.page_obj, &page)?;
        self.pages.push(p.page_obj);
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        if self.page.is_some() {
            return Err(EncodeError::Other("the last page was not ended".into()));
        }
        if self.pages.is_empty() {
            return Err(EncodeError::Other("no pages to write".into()));
        }
        self.obj(out, 1, "<< /Type /Catalog /Pages 2 0 R >>")?;
        let kids: Vec<String> = self.pages.iter().map(|n| format!("{n} 0 R")).collect();
        let tree = format!(
            "<< /Type /Pages /Kids [{}] /Count {} >>",
            kids.join(" "),
            self.pages.len()
        );
        self.obj(out, 2, &tree)?;
        let xref = self.pos;
        let mut t = format!("xref\n0 {}\n0000000000 65535 f \n", self.offsets.len() + 1);
        for off in &self.offsets {
            t += &format!("{off:010} 00000 n \n");
        }
        t += &format!(
            "trailer\n<< /Size {} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n",
            self.offsets.len() + 1
        );
        self.put(out, t.as_bytes())?;
        out.flush()?;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// Decoding

/// The byte offset of every object's body (`N 0 obj` at the start of a line), by number.
fn pdf_objects(data: &[u8]) -> std::collections::HashMap<usize, usize> {
    let mut objs = std::collections::HashMap::new();
    let mut at = 0;
    while let Some(p) = find(data, b" 0 obj\n", at) {
        let start = data[..p]
            .iter()
            .rposition(|b| !b.is_ascii_digit())
            .map_or(0, |i| i + 1);
        if (start == 0 || data[start - 1] == b'\n') && start < p {
            if let Some(n) = std::str::from_utf8(&data[start..p])
                .ok()
                .and_then(|s| s.parse().ok())
            {
                objs.insert(n, p + 7);
            }
        }
        at = p + 7;
    }
    objs
}

/// Decodes the pages of a PDF that halftone wrote: each page's image (one a page), as
/// 8-bit codes. A page of four `/Separation` plates (CMYK) is refused.
pub fn decode(data: &[u8]) -> DecodeResult<Vec<Image>> {
    let objs = pdf_objects(data);
    let text = |n: usize| -> DecodeResult<&str> {
        let Some(&at) = objs.get(&n) else {
            return fail(format!("object {n} is missing"));
        };
        let end = find(data, b"endobj", at).unwrap_or(data.len());
        let end = find(&data[..end], b"stream\n", at).unwrap_or(end);
        std::str::from_utf8(&data[at..end])
            .map_or_else(|_| fail(format!("object {n} is not text")), Ok)
    };
    let refs = |s: &str| -> Vec<usize> {
        let t: Vec<&str> = s.split_whitespace().collect();
        t.windows(3)
            .filter(|w| w[1] == "0" && w[2].starts_with('R'))
            .filter_map(|w| w[0].trim_start_matches('[').parse().ok())
            .collect()
    };
    // Catalog → page tree → kids, in order.
    let catalog = text(1)?;
    let tree = value(catalog, "/Pages")
        .map(refs)
        .and_then(|r| r.first().copied());
    let Some(tree) = tree else {
        return fail("no page tree");
    };
    let kids = value(text(tree)?, "/Kids").map(refs).unwrap_or_default();
    let mut pages = Vec::new();
    for page in kids {
        let page_text = text(page)?;
        let Some(xo) = page_text.find("/XObject") else {
            return fail(format!("page object {page} has no image"));
        };
        let images = refs(&page_text[xo..]);
        // The contents stream is listed after the resources; the images are in /XObject.
        let images: Vec<usize> = images
            .into_iter()
            .take_while(|&n| text(n).is_ok_and(|t| t.contains("/Subtype /Image")))
            .collect();
        match images.len() {
            0 => return fail(format!("page object {page} has no image")),
            1 => {}
            n => {
                return fail(format!(
                    "a page of {n} images (CMYK separations); compare reads grey, RGB and palette pages"
                ))
            }
        }
        pages.push(pdf_image(data, &objs, images[0], &text)?);
    }
    if pages.is_empty() {
        return fail("no pages");
    }
    Ok(pages)
}

fn pdf_image<'a>(
    data: &'a [u8],
    objs: &std::collections::HashMap<usize, usize>,
    n: usize,
    text: &dyn Fn(usize) -> DecodeResult<&'a str>,
) -> DecodeResult<Image> {
    let dict = text(n)?;
    let cs_at = dict.find("/ColorSpace").map_or("", |i| &dict[i + 11..]);
    let cs = cs_at.trim_start();
    let head = ImageHead {
        width: number(dict, "/Width")?,
        height: number(dict, "/Height")?,
        bits: number(dict, "/BitsPerComponent")? as u32,
        space: space(cs, cs)?,
        decode: value(dict, "/Decode").map(numbers).unwrap_or_default(),
    };
    head.check()?;
    // The stream: its length direct, or an indirect object written after it.
    let len_text = value(dict, "/Length").unwrap_or("");
    let len_words: Vec<&str> = len_text.split_whitespace().collect();
    let length: usize = match len_words.as_slice() {
        [v] => v.parse().ok(),
        [r, "0", "R", ..] => r
            .parse()
            .ok()
            .and_then(|r: usize| text(r).ok())
            .and_then(|t| t.trim().parse().ok()),
        _ => None,
    }
    .map_or_else(|| fail(format!("image object {n} without a /Length")), Ok)?;
    let at = objs[&n];
    let Some(s) = find(data, b"stream\n", at) else {
        return fail(format!("image object {n} without a stream"));
    };
    let Some(stream) = data.get(s + 7..s + 7 + length) else {
        return fail(format!("image object {n}: stream cut short"));
    };
    let expected = head.stride() * head.height;
    let raw = if dict.contains("/FlateDecode") {
        inflate(stream, expected)?
    } else if dict.contains("/CCITTFaxDecode") {
        if head.bits != 1 || head.space != Space::Gray {
            return fail("Group 4 data for an image that is not black and white");
        }
        g4(stream, head.width, head.height)?
    } else {
        return fail(format!(
            "image object {n}: a filter halftone does not write"
        ));
    };
    head.image(&raw)
}

/// Inflates zlib data, up to `expected` bytes.
fn inflate(z: &[u8], expected: usize) -> DecodeResult<Vec<u8>> {
    let mut out = Vec::with_capacity(expected);
    flate2::read::ZlibDecoder::new(z)
        .take(expected as u64)
        .read_to_end(&mut out)
        .map_or_else(|e| fail(format!("Flate data: {e}")), |_| Ok(out))
}

/// Decodes Group 4 (K −1) data of `width` × `height` into packed rows, bit 1 = white.
fn g4(data: &[u8], width: usize, height: usize) -> DecodeResult<Vec<u8>> {
    let stride = width.div_ceil(8);
    let mut out = vec![0u8; stride * height];
    let mut y = 0;
    let (w32, h32) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => return fail("Group 4 image too large"),
    };
    let done = fax::decoder::decode_g4(data.iter().copied(), w32, Some(h32), |line| {
        if y < height {
            let row = &mut out[y * stride..(y + 1) * stride];
            for (x, c) in fax::decoder::pels(line, w32).enumerate() {
                if c == fax::Color::White {
                    row[x / 8] |= 0x80 >> (x % 8);
                }
            }
        }
        y += 1;
    });
    if done.is_none() || y < height {
        return fail("Group 4 data could not be decoded");
    }
    Ok(out)
}
