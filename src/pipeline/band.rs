//! A band of rows and what yields it: the row source's interface that every streaming
//! decoder (PNM, PNG, TIFF strips in `source`, JPEG in `jpeg`) and the shrink-on-load
//! wrapper (`shrink`) implement, below all of them.

use crate::error::Result;
use crate::raster::{ColorKind, Image, Samples};
use crate::tone::Encoding;

/// What a streaming decoder knows from the header.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceInfo {
    /// Width in pixels.
    pub width: usize,
    /// Height in rows.
    pub height: usize,
    /// Grey or RGB (alpha is composited before a band is handed on).
    pub color: ColorKind,
    /// Bits per code of the planes handed on: 8 or 16.
    pub bits: u32,
    /// Resolution stored in the file, if known.
    pub dpi: Option<f64>,
}

impl SourceInfo {
    /// Planes per band: 1 or 3.
    pub fn channels(&self) -> usize {
        match self.color {
            ColorKind::Gray => 1,
            ColorKind::Rgb => 3,
        }
    }

    /// Bytes of planes one row takes.
    pub fn row_bytes(&self) -> usize {
        self.width * self.channels() * (self.bits as usize / 8)
    }
}

/// A decoder that hands on an image band by band.
pub trait RowSource: Send {
    /// The header's facts.
    fn info(&self) -> &SourceInfo;

    /// Bytes the decoder keeps whatever the band height (a TIFF strip).
    fn buffer_bytes(&self) -> usize {
        0
    }

    /// Bytes the decoder keeps per row of a band (the file's own bytes, when they need
    /// converting into planes).
    fn bytes_per_row(&self) -> usize;

    /// Reads the next `rows` rows into `band` (resized to `width × rows`; its buffers are
    /// reused from band to band).
    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()>;

    /// Before the first band: hands on a smaller image, still at least `min_w × min_h`,
    /// when the decoder can make one cheaply (JPEG's DCT scaling). Returns the factor `f`
    /// it will shrink by (1: not at all): the image is then `⌈w/f⌉ × ⌈h/f⌉`, each pixel
    /// standing for `f × f` of the full image's (the last row and column for what is left).
    fn shrink_to(&mut self, _min_w: usize, _min_h: usize) -> usize {
        1
    }

    /// Where the partial column and row of an image shrunk on load lie once it is handed
    /// on: (at the right, at the bottom). A decoder that turns the image (an EXIF
    /// orientation) moves them.
    fn remainder_at(&self) -> (bool, bool) {
        (true, true)
    }

    /// True when reading the whole image through this source is as fast as the
    /// whole-image reader (so the whole-image way uses it for files too).
    fn decodes_whole_well(&self) -> bool {
        false
    }

    /// Before the first band: hands on linear-light luminance, one 16-bit plane as
    /// [`Image::to_luminance`] makes it, in place of RGB; true when it will.
    fn to_luminance(&mut self, _tone: &crate::ToneOptions) -> bool {
        false
    }

    /// Before the first band: hands on the 16-bit codes the resize makes of the file's
    /// 8-bit ones before filtering (linear light, `Encoding::Linear`, or with
    /// `--no-linearize` the codes widened), so the resize filters them as they are; true
    /// when it will. The resize's output is the same, byte for byte.
    fn to_linear(&mut self, _tone: &crate::ToneOptions) -> bool {
        false
    }

    /// True when streaming is faster than the whole image even when the whole fits.
    fn prefers_streaming(&self) -> bool {
        false
    }
}

/// An empty band of the source's shape, to be filled by [`RowSource::read_rows`].
pub fn empty_band(info: &SourceInfo) -> Image {
    let plane = || {
        if info.bits == 16 {
            Samples::U16(Vec::new())
        } else {
            Samples::U8(Vec::new())
        }
    };
    Image {
        width: info.width,
        height: 0,
        color: info.color,
        planes: (0..info.channels()).map(|_| plane()).collect(),
        encoding: Encoding::Srgb,
        dpi: info.dpi,
    }
}
