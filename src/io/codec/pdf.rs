//! PDF input (feature `pdf`): pages rasterised by `hayro` (pure Rust) at the output's
//! resolution, one page at a time, so a label PDF at 203 dpi becomes 812 × 1218 pixels of
//! the label's own lines rather than a resampled picture of them.
//!
//! A page is refused before it is rendered when its pixels would pass the pixel limit, and a
//! panic inside the renderer (a bug on a hostile file) becomes a one-line error.

use std::path::Path;

use hayro::hayro_interpret::InterpreterSettings;
use hayro::hayro_syntax::Pdf;
use hayro::vello_cpu::color::palette::css::WHITE;
use hayro::{PixmapSettings, RenderCache, RenderSettings};

use crate::error::Result;
use crate::io::{check_pixels, decode_err, ReadOptions};
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::Encoding;

/// The widest or tallest page rendered, in pixels (the renderer's own bound).
pub const MAX_SIDE: u32 = u16::MAX as u32;

/// True when `data` looks like a PDF file (`%PDF-` within its first kilobyte, as readers
/// allow leading junk).
pub fn is_pdf(data: &[u8]) -> bool {
    data[..data.len().min(1024)]
        .windows(5)
        .any(|w| w == b"%PDF-")
}

/// An opened PDF document.
pub struct Document {
    pdf: Pdf,
    name: std::path::PathBuf,
}

impl Document {
    /// Parses the document in `data` (`name` is for error messages).
    pub fn open(data: Vec<u8>, name: &Path) -> Result<Document> {
        let pdf = guarded(name, || {
            Pdf::new(data).map_err(|e| {
                let why = match e {
                    hayro::hayro_syntax::LoadPdfError::Decryption(_) => {
                        "is encrypted (not supported)"
                    }
                    hayro::hayro_syntax::LoadPdfError::Invalid => "is not a readable PDF",
                };
                decode_err(name, why.into())
            })
        })?;
        if pdf.pages().is_empty() {
            return Err(decode_err(name, "the PDF has no pages".into()));
        }
        Ok(Document {
            pdf,
            name: name.to_path_buf(),
        })
    }

    /// Number of pages.
    pub fn pages(&self) -> usize {
        self.pdf.pages().len()
    }

    /// A page's size in points (1/72 in), after its rotation.
    pub fn page_size(&self, index: usize) -> Option<(f64, f64)> {
        let p = self.pdf.pages().get(index)?;
        let (w, h) = p.render_dimensions();
        Some((f64::from(w), f64::from(h)))
    }

    /// Renders page `index` (from 0) at `dpi` on white: an RGB image, or a grey one when
    /// every pixel is neutral, with its resolution set.
    pub fn render(&self, index: usize, dpi: f64, opts: &ReadOptions) -> Result<Image> {
        let name = self.name.as_path();
        let n = self.pages();
        let err = |msg: String| decode_err(name, format!("page {}: {msg}", index + 1));
        let Some(page) = self.pdf.pages().get(index) else {
            return Err(decode_err(
                name,
                format!("no page {} (it has {n})", index + 1),
            ));
        };
        if !(dpi.is_finite() && dpi > 0.0 && dpi <= 10_000.0) {
            return Err(err(format!("cannot render at {dpi} dpi")));
        }
        let (w, h) = page.render_dimensions();
        let scale = dpi / 72.0;
        let (pw, ph) = (
            (f64::from(w) * scale).round(),
            (f64::from(h) * scale).round(),
        );
        if !(pw >= 1.0 && ph >= 1.0) {
            return Err(err(format!("a page of {w} x {h} points")));
        }
        if pw > f64::from(MAX_SIDE) || ph > f64::from(MAX_SIDE) {
            return Err(err(format!(
                "{pw} x {ph} pixels at {dpi} dpi; the renderer takes at most {MAX_SIDE} a side"
            )));
        }
        check_pixels(name, pw as u32, ph as u32, opts)?;
        // Scale so that the pixmap is exactly the rounded size.
        let settings = PixmapSettings {
            x_scale: (pw / f64::from(w)) as f32,
            y_scale: (ph / f64::from(h)) as f32,
            bg_color: WHITE,
        };
        let pixmap = guarded(name, || {
            let cache = RenderCache::new();
            Ok(hayro::render(
                page,
                &cache,
                &InterpreterSettings::default(),
                &RenderSettings::default(),
                &settings,
            ))
        })?;
        let (width, height) = (pixmap.width() as usize, pixmap.height() as usize);
        // Opaque white underneath: premultiplied RGBA is plain RGBA here.
        let rgba = pixmap.data_as_u8_slice();
        let neutral = rgba.chunks_exact(4).all(|p| p[0] == p[1] && p[1] == p[2]);
        let planes = if neutral {
            vec![Samples::U8(rgba.chunks_exact(4).map(|p| p[0]).collect())]
        } else {
            (0..3)
                .map(|c| Samples::U8(rgba.chunks_exact(4).map(|p| p[c]).collect()))
                .collect()
        };
        Ok(Image {
            width,
            height,
            color: if neutral {
                ColorKind::Gray
            } else {
                ColorKind::Rgb
            },
            planes,
            encoding: Encoding::Srgb,
            dpi: Some(dpi),
        })
    }
}

/// Runs the renderer, turning a panic inside it into a one-line error naming the file.
fn guarded<T>(name: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|p| {
        let why = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown cause".into());
        Err(decode_err(name, format!("the PDF renderer failed: {why}")))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-page PDF of `w` x `h` points with a black rectangle in its lower-left quarter.
    pub(crate) fn tiny_pdf(w: u32, h: u32) -> Vec<u8> {
        let content = format!("0 g 0 0 {} {} re f", w / 2, h / 2);
        let objs = [
            "<< /Type /Catalog /Pages 2 0 R >>".to_string(),
            "<< /Type /Pages /Kids [3 0 R] /Count 1 >>".to_string(),
            format!("<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {w} {h}] /Contents 4 0 R >>"),
            format!(
                "<< /Length {} >>\nstream\n{content}\nendstream",
                content.len()
            ),
        ];
        let mut out = b"%PDF-1.4\n".to_vec();
        let mut offsets = Vec::new();
        for (i, o) in objs.iter().enumerate() {
            offsets.push(out.len());
            out.extend(format!("{} 0 obj\n{o}\nendobj\n", i + 1).bytes());
        }
        let xref = out.len();
        out.extend(format!("xref\n0 {}\n0000000000 65535 f \n", objs.len() + 1).bytes());
        for o in offsets {
            out.extend(format!("{o:010} 00000 n \n").bytes());
        }
        out.extend(
            format!(
                "trailer\n<< /Size {} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n",
                objs.len() + 1
            )
            .bytes(),
        );
        out
    }

    #[test]
    fn renders_at_the_asked_resolution() {
        let name = Path::new("t.pdf");
        let d = Document::open(tiny_pdf(288, 432), name).unwrap();
        assert_eq!(d.pages(), 1);
        let img = d.render(0, 203.0, &ReadOptions::default()).unwrap();
        assert_eq!((img.width, img.height), (812, 1218));
        assert_eq!(img.planes.len(), 1);
        let Samples::U8(v) = &img.planes[0] else {
            panic!()
        };
        // Lower-left quarter black, upper-right white (rows run top to bottom).
        assert_eq!(v[(1218 - 10) * 812 + 10], 0);
        assert_eq!(v[10 * 812 + 800], 255);
        let e = d.render(1, 203.0, &ReadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("no page 2 (it has 1)"), "{e}");
        let small = ReadOptions { max_pixels: 1000 };
        assert!(d.render(0, 203.0, &small).is_err());
        let e = d.render(0, 20_000.0, &ReadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("20000 dpi"), "{e}");
    }

    #[test]
    fn bad_pdfs_are_one_line_errors() {
        let name = Path::new("bad.pdf");
        let good = tiny_pdf(100, 100);
        for n in [0, 5, 20, good.len() / 2] {
            if let Err(e) = Document::open(good[..n].to_vec(), name) {
                assert!(!e.to_string().contains('\n'));
            }
        }
        let mut seed = 11u64;
        for _ in 0..200 {
            let mut g = good.clone();
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let at = (seed >> 33) as usize % g.len();
            g[at] = (seed >> 20) as u8;
            if let Ok(d) = Document::open(g, name) {
                let _ = d.render(0, 72.0, &ReadOptions::default());
            }
        }
        assert!(is_pdf(&good) && !is_pdf(b"RaS2"));
    }
}
