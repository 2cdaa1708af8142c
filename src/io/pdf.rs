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

use std::io::Write;

use flate2::write::ZlibEncoder;

use super::print::{self, Chunky, Language, PrintOptions};
use super::sink::{Band, PageEncoder, PageHeader};
use super::{Compression, EncodeError, EncodeResult};

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
        let dmax = print::num(print::decode_max(page.bits, page.levels));
        if let Some(c) = plate {
            // Tint 1 = full ink = level 0: the decode runs from 1 down.
            let lo = print::num(1.0 - print::decode_max(page.bits, page.levels));
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
        if let Some(msg) = print::check(Language::Pdf, page, &self.opts) {
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
        let mut p = super::sink::take_page_for_rows(&mut self.page)?;
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
        let p = super::sink::take_complete_page(&mut self.page, |p| (p.rows, p.header.height))?;
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
        let dpi = print::page_dpi(h);
        let (x, y, pw, ph) = print::placement(h, &self.opts, dpi);
        let (w, hh) = print::image_points(h, dpi);
        let names: Vec<String> = (0..p.images.len()).map(|i| format!("/Im{i}")).collect();
        let mut content = format!(
            "q {} 0 0 {} {} {} cm ",
            print::num(w),
            print::num(hh),
            print::num(x),
            print::num(y)
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
            print::num(pw),
            print::num(ph)
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
