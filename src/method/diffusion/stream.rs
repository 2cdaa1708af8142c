//! Error diffusion band by band ([`RowMethod`]): the same loops as the whole-image paths,
//! with the error rows kept between bands, so a page of any height needs only a few rows of
//! state per plane.
//!
//! Floyd–Steinberg at full strength runs the two-pass rows of [`super::fs`]; every other
//! kernel (fixed, Ostromoukhov, Zhou–Fang, multi-level) runs the one-thread row loop of
//! [`Engine::sequential`]. Both give the whole-image bytes: the raster wavefront, which the
//! whole-image path may use on several cores, is itself byte-identical to the one-thread loop.
//! Riemersma (a Hilbert curve over the whole image) and palettes do not stream.

use std::cell::Cell;
use std::sync::mpsc;
use std::sync::Mutex;

use rayon::prelude::*;

use super::{fs, Diffuse, Engine, RowState, PAD, ROWS};
use crate::error::Result;
use crate::method::rows::RowMethod;
use crate::method::PlaneOut;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes, SamplesRef};

/// The error state of one plane between bands.
enum PlaneState {
    /// Two-pass Floyd–Steinberg: the fixed-point tone table, the error from the row above,
    /// and scratch rows.
    Fs {
        tone: Vec<i32>,
        err: Vec<i32>,
        x7: Vec<i32>,
        e: Vec<i32>,
        levels: Vec<u8>,
    },
    /// The general row loop: the tone table it was built for and the ring of error rows.
    Rows {
        tone: Vec<f32>,
        buf: Vec<f32>,
        levels: Vec<u8>,
    },
}

/// [`Diffuse`] as a [`RowMethod`].
pub(super) struct DiffuseRows<'a> {
    d: &'a Diffuse,
    /// The page row the next band starts at.
    y: usize,
    planes: Vec<PlaneState>,
}

impl<'a> DiffuseRows<'a> {
    pub(super) fn new(d: &'a Diffuse) -> DiffuseRows<'a> {
        DiffuseRows {
            d,
            y: 0,
            planes: Vec::new(),
        }
    }
}

impl PlaneState {
    /// The state for a page of planes like `plane` under `d`.
    fn start(d: &Diffuse, plane: &PlaneRef<'_>) -> PlaneState {
        let w = plane.width;
        let levels = d.options.levels;
        let engine = Engine::new(d, plane.tone, levels);
        if let Some(tone) = engine.fixed.as_ref().and_then(|f| f.floyd_steinberg_tone()) {
            return PlaneState::Fs {
                tone: tone.to_vec(),
                err: vec![0; w],
                x7: vec![0; w],
                e: vec![0; w + 2],
                levels: vec![0; w],
            };
        }
        PlaneState::Rows {
            tone: plane.tone.to_vec(),
            buf: vec![0.0; (engine.below + 1) * (w + 2 * PAD)],
            levels: vec![0; w],
        }
    }

    /// Halftones the rows of `plane` (page rows `y0..`) into `out`.
    fn band(&mut self, d: &Diffuse, plane: &PlaneRef<'_>, y0: usize, out: &mut PlaneOut<'_>) {
        match self {
            PlaneState::Fs {
                tone,
                err,
                x7,
                e,
                levels,
            } => match plane.samples {
                SamplesRef::U8(s) => fs_band(tone, s, plane.width, y0, d, err, x7, e, levels, out),
                SamplesRef::U16(s) => fs_band(tone, s, plane.width, y0, d, err, x7, e, levels, out),
            },
            PlaneState::Rows { tone, buf, levels } => {
                let engine = Engine::new(d, tone, d.options.levels);
                match plane.samples {
                    SamplesRef::U8(s) => rows_band(&engine, s, plane.width, y0, buf, levels, out),
                    SamplesRef::U16(s) => rows_band(&engine, s, plane.width, y0, buf, levels, out),
                }
            }
        }
    }
}

/// Rows of a band through the two passes of [`fs::plane`], with the same row parity.
#[allow(clippy::too_many_arguments)]
fn fs_band<S: super::Code>(
    tone: &[i32],
    codes: &[S],
    w: usize,
    y0: usize,
    d: &Diffuse,
    err: &mut [i32],
    x7: &mut [i32],
    e: &mut [i32],
    levels: &mut [u8],
    out: &mut PlaneOut<'_>,
) {
    let (bits, stride) = (out.bits, out.stride);
    for r in 0..out.height {
        let y = y0 + r;
        let fwd = !d.options.serpentine || y.is_multiple_of(2);
        let row = &codes[r * w..(r + 1) * w];
        if fwd {
            fs::chain::<S, true>(tone, row, err, x7, levels);
        } else {
            fs::chain::<S, false>(tone, row, err, x7, levels);
        }
        pack_row(levels, bits, &mut out.data[r * stride..(r + 1) * stride]);
        // The whole-image loop skips this after the last row; here the next band may come.
        fs::spread(x7, e, err, fwd);
    }
}

/// Rows of a band through [`Engine::run_row`], as [`Engine::sequential`] runs them.
fn rows_band<S: super::Code>(
    engine: &Engine<'_>,
    codes: &[S],
    w: usize,
    y0: usize,
    buf: &mut [f32],
    levels: &mut [u8],
    out: &mut PlaneOut<'_>,
) {
    let n = engine.below + 1;
    let span = w + 2 * PAD;
    let cells = Cell::from_mut(buf).as_slice_of_cells();
    let slot = |r: usize| &cells[r * span..(r + 1) * span];
    let (bits, stride) = (out.bits, out.stride);
    for r in 0..out.height {
        let y = y0 + r;
        let dir = if engine.serpentine && y % 2 == 1 {
            -1
        } else {
            1
        };
        let rows: [&[Cell<f32>]; ROWS] =
            std::array::from_fn(|d| slot((y + d.min(engine.below)) % n));
        let mut state = RowState::default();
        engine.run_row(
            &codes[r * w..(r + 1) * w],
            &rows,
            levels,
            y,
            0,
            w,
            dir,
            &mut state,
        );
        for c in rows[0][..PAD].iter().chain(&rows[0][PAD + w..]) {
            c.set(0.0);
        }
        pack_row(levels, bits, &mut out.data[r * stride..(r + 1) * stride]);
    }
}

/// True when a band's three Floyd–Steinberg planes are better shared by two threads as
/// one and a half planes each (see [`split_third`]) than as whole planes (two on one thread,
/// one on the other, which leaves a core idle for a third of the band).
fn three_on_two(states: &[PlaneState], input: &Planes<'_>) -> bool {
    states.len() == 3
        && input.height >= 2
        && rayon::current_num_threads() == 2
        && states.iter().all(|s| matches!(s, PlaneState::Fs { .. }))
}

/// Halftones a band of three two-pass planes on two threads, one and a half planes each:
/// the first thread does the first half of the third plane's rows and then the first plane;
/// the second does the second plane and then the rest of the third, which by then is
/// (almost always) ready to go on. Each plane's rows are still halftoned in order, one after
/// the other, so the bytes are those of one thread.
fn split_third(
    d: &Diffuse,
    states: &mut [PlaneState],
    input: &Planes<'_>,
    y0: usize,
    h: &mut Halftone,
) {
    let (w, rows) = (input.width, input.height);
    let (bits, stride) = (h.bits, h.stride);
    let mid = rows / 2;
    let [s0, s1, s2] = states else {
        unreachable!("three planes")
    };
    let [o0, o1, o2] = &mut h.planes[..] else {
        unreachable!("three planes")
    };
    let (o2a, o2b) = o2.split_at_mut(mid * stride);
    let third = &Mutex::new(s2);
    let (done_tx, done_rx) = mpsc::channel::<()>();
    // Part of a plane: its rows `from..from + height` of the band, into `data`.
    let part =
        |s: &mut PlaneState, plane: &PlaneRef<'_>, from: usize, height: usize, data: &mut [u8]| {
            let mut o = PlaneOut {
                width: w,
                height,
                bits,
                stride,
                data,
            };
            s.band(d, &plane.rows(from, height), y0 + from, &mut o);
        };
    rayon::join(
        || {
            {
                let mut s2 = third.lock().expect("not poisoned");
                part(&mut s2, &input.planes[2], 0, mid, o2a);
            }
            // The receiver waits for this before it takes the third plane's state.
            let _ = done_tx.send(());
            part(s0, &input.planes[0], 0, rows, o0);
        },
        move || {
            part(s1, &input.planes[1], 0, rows, o1);
            done_rx
                .recv()
                .expect("the first half is sent before its sender is dropped");
            let mut s2 = third.lock().expect("not poisoned");
            part(&mut s2, &input.planes[2], mid, rows - mid, o2b);
        },
    );
}

impl RowMethod for DiffuseRows<'_> {
    fn state_bytes(&self, width: usize, planes: usize) -> usize {
        // Two-pass: three rows of i32 and a row of levels; else the ring of error rows.
        let below = match &self.d.algorithm {
            super::Algorithm::Kernel(k) => k.rows_below(),
            _ => 1,
        };
        let rows = (below + 1) * (width + 2 * PAD) * 4 + width;
        planes * rows.max(13 * width + 8)
    }

    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        if self.planes.is_empty() {
            self.planes = input
                .planes
                .iter()
                .map(|p| PlaneState::start(self.d, p))
                .collect();
        }
        let levels = self.d.options.levels;
        let mut h = Halftone::new(input.width, input.height, input.planes.len(), levels);
        let (bits, stride) = (h.bits, h.stride);
        let (d, y0) = (self.d, self.y);
        if three_on_two(&self.planes, input) {
            split_third(d, &mut self.planes, input, y0, &mut h);
            self.y += input.height;
            return Ok(h);
        }
        h.planes
            .par_iter_mut()
            .zip(self.planes.par_iter_mut())
            .zip(input.planes.par_iter())
            .for_each(|((data, state), plane)| {
                let mut out = PlaneOut {
                    width: input.width,
                    height: input.height,
                    bits,
                    stride,
                    data,
                };
                state.band(d, plane, y0, &mut out);
            });
        self.y += input.height;
        Ok(h)
    }
}
