//! Row streaming: the optional capability of a [`Method`] to halftone an image band by band,
//! top to bottom, so that the streaming pipeline ([`crate::pipeline`]) never holds the whole
//! image.
//!
//! A method that can stream returns a [`RowMethod`] from [`Method::rows`]; the pipeline makes
//! a fresh one for every page and feeds it bands of input rows in order. Each band's output
//! rows come back at once (error diffusion is causal: a row's levels depend only on the rows
//! above it, whose error the row method carries in its own state). The bytes are the same as
//! [`Method::halftone`] on the whole image, for any band height that is a multiple of
//! [`RowMethod::band_multiple`].
//!
//! Methods whose output rows depend only on the input rows of the same band (threshold,
//! ordered, pattern) stream through [`BandLocal`]: it runs the method's own whole-image code
//! on each band, which is exact as long as every band starts on a row where the method's
//! tiling restarts (a multiple of the mask's height).

use super::Method;
use crate::error::Result;
use crate::raster::{Halftone, Planes};

/// A method halftoning an image band by band, carrying whatever state crosses bands.
pub trait RowMethod: Send {
    /// Input bands must hold a multiple of this many rows (all but the last band of a page).
    fn band_multiple(&self) -> usize {
        1
    }

    /// Bytes of state this row method keeps for a page `width` pixels wide with `planes`
    /// planes (error rows, tiled threshold rows), for the pipeline's memory budget.
    fn state_bytes(&self, width: usize, planes: usize) -> usize {
        let _ = (width, planes);
        0
    }

    /// Halftones the next band of input rows (the page's rows in order, top to bottom) and
    /// returns its output rows: `Method::output_size` of the band.
    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone>;
}

/// Streams a method whose output rows depend only on the input rows of the same band, when
/// every band starts on a multiple of `period` rows: the method's own code runs on each band.
pub struct BandLocal<'a> {
    method: &'a dyn Method,
    period: usize,
    state: usize,
}

impl<'a> BandLocal<'a> {
    /// Streams `method`, whose tiling repeats every `period` rows (1 for per-pixel methods,
    /// the mask's height for ordered and pattern); `state` is bytes of tables it builds per
    /// band and plane row (for the budget).
    pub fn new(method: &'a dyn Method, period: usize, state: usize) -> BandLocal<'a> {
        BandLocal {
            method,
            period: period.max(1),
            state,
        }
    }
}

impl RowMethod for BandLocal<'_> {
    fn band_multiple(&self) -> usize {
        self.period
    }

    fn state_bytes(&self, width: usize, planes: usize) -> usize {
        self.state.saturating_mul(width).saturating_mul(planes)
    }

    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        self.method.halftone(input)
    }
}
