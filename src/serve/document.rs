//! A job's document as pages: an image is one page; PWG raster, Apple raster and (feature
//! `pdf`) PDF are every page they hold, decoded one at a time and halftoned in order, so a
//! job's memory is one page's, whatever its page count.

use std::path::Path;
use std::rc::Rc;

use crate::api::{Converter, Input};
use crate::io::lang::{pwg, urf};
use crate::io::{self, Format, ReadOptions};

/// What the bytes of a document are, by their signature (a MIME type).
pub fn sniff(doc: &[u8]) -> Option<&'static str> {
    if doc.starts_with(&[0xff, 0xd8, 0xff]) {
        Some("image/jpeg")
    } else if doc.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if pwg::is_pwg(doc) {
        Some("image/pwg-raster")
    } else if urf::is_urf(doc) {
        Some("image/urf")
    } else if doc.starts_with(b"II*\0") || doc.starts_with(b"MM\0*") {
        Some("image/tiff")
    } else if doc.starts_with(b"GIF8") {
        Some("image/gif")
    } else if doc.starts_with(b"BM") {
        Some("image/bmp")
    } else if doc.len() > 12 && &doc[..4] == b"RIFF" && &doc[8..12] == b"WEBP" {
        Some("image/webp")
    } else if doc.len() > 2 && doc[0] == b'P' && (b'1'..=b'6').contains(&doc[1]) {
        Some("image/x-portable-anymap")
    } else if is_pdf(doc) {
        Some("application/pdf")
    } else {
        None
    }
}

#[cfg(feature = "pdf")]
fn is_pdf(doc: &[u8]) -> bool {
    crate::io::codec::pdf::is_pdf(doc)
}

#[cfg(not(feature = "pdf"))]
fn is_pdf(doc: &[u8]) -> bool {
    doc.starts_with(b"%PDF-")
}

/// The converter for one page and the resolution a PDF page is rendered at.
pub type PageJob = (Rc<Converter>, f64);

/// A job's output files, as (bytes, file name), and the pages printed.
pub type Files = (Vec<(Vec<u8>, String)>, usize);

/// The files a job makes: in a multi-page language (ESC/POS, ZPL, PCL, PostScript, PDF)
/// one file holding every page; in an image format one file a page (`job-N.EXT` for one
/// page, `job-N-pP.EXT` for several). Returns (bytes, file name) pairs and the pages
/// printed.
///
/// `pick(page)` (pages from 1) gives each page's converter and resolution, or `None` for a
/// page left out (page-ranges); `canceled` is asked between pages. Raster pages are
/// decoded under `max_pixels` (the job's pixel limit).
pub fn halftone(
    doc: Vec<u8>,
    format: Format,
    id: i32,
    max_pixels: u64,
    pick: &mut dyn FnMut(usize) -> Result<Option<PageJob>, String>,
    canceled: &dyn Fn() -> bool,
) -> Result<Files, String> {
    let name = format!("job-{id}");
    let ext = format.extension();
    let label = Path::new(&name);
    let mut book = Pages::new(format);
    let mut read = ReadOptions::default();
    // Each page: asked for, decoded only if printed, halftoned.
    let mut page = |n: usize,
                    input: &mut dyn FnMut(f64, &ReadOptions) -> Result<Input, String>|
     -> Result<(), String> {
        if canceled() {
            return Err("canceled".into());
        }
        let Some((conv, dpi)) = pick(n)? else {
            return Ok(());
        };
        read.max_pixels = conv.options().max_pixels;
        let input = input(dpi, &read)?;
        book.add(&conv, input)
    };
    let text = |e: crate::Error| e.to_string();
    match sniff(&doc) {
        Some("image/pwg-raster") => {
            let all = ReadOptions { max_pixels };
            for (i, p) in pwg::pages(&doc, label, &all).map_err(text)?.enumerate() {
                let mut p = Some(p);
                page(i + 1, &mut |_, _| {
                    p.take()
                        .unwrap_or_else(unreachable_page)
                        .map(Input::Image)
                        .map_err(text)
                })?;
            }
        }
        Some("image/urf") => {
            let all = ReadOptions { max_pixels };
            for (i, p) in urf::pages(&doc, label, &all).map_err(text)?.enumerate() {
                let mut p = Some(p);
                page(i + 1, &mut |_, _| {
                    p.take()
                        .unwrap_or_else(unreachable_page)
                        .map(Input::Image)
                        .map_err(text)
                })?;
            }
        }
        #[cfg(feature = "pdf")]
        Some("application/pdf") => {
            let pdf = crate::io::codec::pdf::Document::open(doc, label).map_err(text)?;
            for i in 0..pdf.pages() {
                page(i + 1, &mut |dpi, read| {
                    pdf.render(i, dpi, read).map(Input::Image).map_err(text)
                })?;
            }
        }
        _ => {
            let mut doc = Some(doc);
            page(1, &mut |_, _| {
                Ok(Input::Bytes(doc.take().unwrap_or_default()))
            })?;
        }
    }
    let pages = book.count;
    if pages == 0 {
        return Err("page-ranges select no page of the document".into());
    }
    let files = book.finish(&name, ext)?;
    Ok((files, pages))
}

/// A page's decoder is called once; a second call is a bug, reported rather than panicked.
fn unreachable_page() -> crate::Result<crate::raster::Image> {
    Err(crate::Error::Invalid("a page was decoded twice".into()))
}

/// Pages going into one multi-page file, or one file each.
struct Pages {
    format: Format,
    enc: Option<Box<dyn io::sink::PageEncoder>>,
    out: Vec<u8>,
    singles: Vec<Vec<u8>>,
    count: usize,
}

impl Pages {
    fn new(format: Format) -> Pages {
        Pages {
            format,
            enc: None,
            out: Vec::new(),
            singles: Vec::new(),
            count: 0,
        }
    }

    fn add(&mut self, conv: &Converter, input: Input) -> Result<(), String> {
        self.count += 1;
        if self.format.is_multi_page() {
            let enc = self.enc.get_or_insert_with(|| {
                io::page_encoder(&conv.options().write_options(self.format))
            });
            conv.add_page(
                input,
                self.format,
                enc.as_mut(),
                &mut self.out,
                Path::new("<job>"),
            )
            .map_err(|e| e.to_string())?;
        } else {
            let bytes = conv
                .convert_to_bytes(input, self.format)
                .map_err(|e| e.to_string())?;
            self.singles.push(bytes);
        }
        Ok(())
    }

    fn finish(mut self, name: &str, ext: &str) -> Result<Vec<(Vec<u8>, String)>, String> {
        if let Some(mut enc) = self.enc.take() {
            enc.finish(&mut self.out)
                .map_err(|e| e.named(Path::new("<job>")).to_string())?;
            return Ok(vec![(self.out, format!("{name}.{ext}"))]);
        }
        if self.singles.len() == 1 {
            let one = self.singles.pop().unwrap_or_default();
            return Ok(vec![(one, format!("{name}.{ext}"))]);
        }
        Ok(self
            .singles
            .into_iter()
            .enumerate()
            .map(|(i, b)| (b, format!("{name}-p{}.{ext}", i + 1)))
            .collect())
    }
}
