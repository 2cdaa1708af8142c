//! AM screening: each pixel compared with the threshold of an exact screen
//! ([`crate::mask::screen`]) at the printer's frequency, angle and dot shape.
//!
//! Thresholds are ink thresholds in linear light: a pixel of reflectance `v` on an L-level
//! device sits at `s = v·(L−1)` between levels `b = ⌊s⌋` and `b + 1`; its ink share toward
//! `b` is `a = 1 − (s − b)`, and it takes level `b` when `a` exceeds the pixel's threshold.
//! Bilevel: ink where `1 − v > t`, so a flat patch's ink coverage is `1 − v`.
//!
//! The method is row-local: each band of rows computes its own thresholds (a pixel's
//! threshold depends only on its absolute position on the page), so rows stream through
//! [`ScreenRows`], which tells each band where on the page its first row lies.

use rayon::prelude::*;

use super::rows::RowMethod;
use super::threshold::check_levels;
use super::Method;
use crate::error::Result;
use crate::mask::screen::Screen;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};

/// Fewest rows computed by one task.
const BAND: usize = 32;

/// Pixels a task screens, about: the screen locates a margin of pixels around each task's
/// band, which costs less the taller the band; its scratch is ~20 bytes a pixel.
const TASK_PIXELS: usize = 1 << 19;

/// Rows one task screens in a plane of `width × height`: about [`TASK_PIXELS`], at least
/// [`BAND`], and when several threads share the work at least four tasks a thread (when
/// the plane has the rows). The rows of a task never change its thresholds.
fn task_rows(width: usize, height: usize) -> usize {
    let rows = (TASK_PIXELS / width.max(1)).max(BAND);
    let threads = rayon::current_num_threads();
    if threads > 1 {
        rows.min(height.div_ceil(4 * threads).max(BAND))
    } else {
        rows
    }
}

/// AM screening with one screen per plane.
#[derive(Clone, Debug)]
pub struct ScreenMethod {
    screens: Vec<Screen>,
    levels: u16,
}

impl ScreenMethod {
    /// Screening with `screen` on every plane, to `levels` (2..=256) levels.
    pub fn new(screen: Screen, levels: u16) -> Result<ScreenMethod> {
        Self::per_plane(vec![screen], levels)
    }

    /// Plane `c` uses `screens[c % screens.len()]` (e.g. one angle per ink).
    pub fn per_plane(screens: Vec<Screen>, levels: u16) -> Result<ScreenMethod> {
        check_levels(levels)?;
        assert!(!screens.is_empty(), "at least one screen");
        Ok(ScreenMethod { screens, levels })
    }

    /// The screens in use.
    pub fn screens(&self) -> &[Screen] {
        &self.screens
    }

    /// Per code of the plane's table: `(lower level b, ink share a toward b in 1/65536)`.
    fn code_table(&self, tone: &[f32]) -> Vec<(u8, u32)> {
        let top = (self.levels - 1) as f64;
        tone.iter()
            .map(|&v| {
                let s = (v as f64 * top).clamp(0.0, top);
                let b = s.floor().min(top - 1.0);
                let a = 1.0 - (s - b);
                (b as u8, (a * 65536.0).round() as u32)
            })
            .collect()
    }

    /// Halftones one plane into a packed plane of `stride × height` bytes; the plane's first
    /// row is row `y0` of the page (the screen is fixed to the page, not to the band).
    pub fn plane(
        &self,
        c: usize,
        plane: &PlaneRef<'_>,
        bits: u8,
        stride: usize,
        data: &mut [u8],
        y0: usize,
    ) {
        self.plane_in_tasks(c, plane, bits, stride, data, y0, usize::MAX);
    }

    /// [`Self::plane`] with tasks of at most `max_task_rows` rows (a streamed band keeps
    /// its scratch within the memory budget it was planned for).
    #[allow(clippy::too_many_arguments)]
    fn plane_in_tasks(
        &self,
        c: usize,
        plane: &PlaneRef<'_>,
        bits: u8,
        stride: usize,
        data: &mut [u8],
        y0: usize,
        max_task_rows: usize,
    ) {
        let screen = &self.screens[c % self.screens.len()];
        let table = self.code_table(plane.tone);
        let w = plane.width;
        if stride == 0 {
            return;
        }
        let band_rows = task_rows(w, data.len() / stride).min(max_task_rows.max(1));
        data.par_chunks_mut(stride * band_rows)
            .enumerate()
            .for_each(|(band, rows)| {
                let n = rows.len() / stride;
                let first = band * band_rows;
                let mut th = vec![0u16; w * n];
                screen.threshold_band((y0 + first) as i64, n, w, &mut th);
                let mut levels = vec![0u8; w];
                for (k, row) in rows.chunks_mut(stride).enumerate() {
                    let start = (first + k) * w;
                    let th = &th[k * w..(k + 1) * w];
                    let level = |code: usize, t: u16| {
                        let (b, a) = table[code];
                        b + (a <= t as u32) as u8
                    };
                    match plane.samples {
                        SamplesRef::U8(s) => {
                            for ((l, &code), &t) in
                                levels.iter_mut().zip(&s[start..start + w]).zip(th)
                            {
                                *l = level(code as usize, t);
                            }
                        }
                        SamplesRef::U16(s) => {
                            for ((l, &code), &t) in
                                levels.iter_mut().zip(&s[start..start + w]).zip(th)
                            {
                                *l = level(code as usize, t);
                            }
                        }
                    }
                    pack_row(&levels, bits, row);
                }
            });
    }
}

impl Method for ScreenMethod {
    fn name(&self) -> String {
        let s = self.screens[0].spec();
        format!(
            "screen({} lpi, {}°, {}, {} dpi)",
            s.lpi,
            s.angle,
            s.spot.name(),
            s.dpi
        )
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        self.band(input, 0, usize::MAX)
    }

    fn rows(&self) -> Option<Box<dyn RowMethod + '_>> {
        Some(Box::new(ScreenRows { method: self, y: 0 }))
    }
}

impl ScreenMethod {
    /// Halftones `input` as the rows of the page starting at row `y0`, in tasks of at most
    /// `max_task_rows` rows.
    fn band(&self, input: &Planes<'_>, y0: usize, max_task_rows: usize) -> Result<Halftone> {
        let mut h = Halftone::new(input.width, input.height, input.planes.len(), self.levels);
        let (bits, stride) = (h.bits, h.stride);
        for (c, data) in h.planes.iter_mut().enumerate() {
            self.plane_in_tasks(c, &input.planes[c], bits, stride, data, y0, max_task_rows);
        }
        Ok(h)
    }
}

/// The screen streamed: any band height, since each band is screened at its own rows of the
/// page (the same thresholds as the whole image, so the same bytes).
pub struct ScreenRows<'a> {
    method: &'a ScreenMethod,
    /// Page row of the next band's first row.
    y: usize,
}

impl RowMethod for ScreenRows<'_> {
    fn state_bytes(&self, width: usize, planes: usize) -> usize {
        // A threshold row (16-bit) and a level row, and each running task's scratch: its
        // thresholds and the located pixels of its band and margin.
        let _ = planes;
        // Streamed bands run in tasks of BAND rows (`next_band`), so the scratch does not
        // grow with the band the budget allows.
        let rows = BAND;
        let scratch = self
            .method
            .screens
            .iter()
            .map(|s| s.band_scratch_bytes(rows, width) + rows * width * 2)
            .max()
            .unwrap_or(0);
        width
            .saturating_mul(3)
            .saturating_add(scratch.saturating_mul(rayon::current_num_threads()))
    }

    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        let h = self.method.band(input, self.y, BAND)?;
        self.y += input.height;
        Ok(h)
    }
}
