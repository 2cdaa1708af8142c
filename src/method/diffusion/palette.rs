//! Palette diffusion, whole image or band by band: nearest colour in Oklab, error per channel
//! in linear RGB.
//!
//! [`PaletteRun`] holds everything that lives from one band to the next (the error rows and
//! the prepared palette), so a page streams through [`PaletteRows`] with the bytes of the
//! whole-image run: a band is just the next rows, and the run does not know where bands
//! begin. Kernels of Floyd–Steinberg's shape run the sliding-window loop of
//! [`super::palette_fs`]; other kernels (and variable coefficients) run the general loop
//! here. The nearest colour comes from [`FastNearest`] where it can prove the exact search's
//! answer, and from the exact search ([`PaletteMatcher::nearest`]) elsewhere; the scalar
//! Floyd–Steinberg loop asks the certified cell table ([`CellTable`]) first. On a CPU with
//! AVX-512, Floyd–Steinberg-shaped kernels with at most eight distinct colours run the
//! vector loop (`palette_avx512`): the same answers, with a shorter chain from pixel to pixel.

use super::palette_cells::CellTable;
use super::palette_fast::FastNearest;
use super::palette_fs::{self, FsWeights};
use super::{fs_shape, Algorithm, Diffuse, Engine, Weights, PAD};
use crate::color::{Palette, PaletteMatcher};
use crate::error::{Error, Result};
use crate::method::rows::RowMethod;
use crate::raster::{pack_row, Halftone, PlaneRef, Planes};

/// The nearest colour's lane: fast where proven, else the exact search's answer.
#[inline(always)]
fn nearest_of<const N: usize>(f: &FastNearest, m: &PaletteMatcher, v: [f32; 3]) -> usize {
    match f.nearest::<N>(v) {
        Some(lane) => lane,
        None => f.lane_of(m.nearest(v)),
    }
}

/// The error carried between rows.
enum Carried {
    /// Floyd–Steinberg's shape: the next row's error, three channels a pixel, and scratch.
    Fs {
        wt: FsWeights,
        err: Vec<[f32; 3]>,
        below: Vec<[f32; 3]>,
    },
    /// Any kernel: a ring of error rows per channel, `[channel][slot][x]` with padding.
    Rows { err: Vec<f32> },
}

/// One page of palette diffusion in progress.
pub(super) struct PaletteRun<'d> {
    d: &'d Diffuse,
    palette: &'d Palette,
    matcher: PaletteMatcher,
    fast: Option<FastNearest>,
    /// The cell table of the fast search's lanes, made when the scalar loop first runs.
    cells: Option<CellTable>,
    /// What the nearest-colour search answers (a palette index, or a lane of the fast
    /// search) in linear RGB, and as a palette index.
    linear: Vec<[f32; 3]>,
    entry: Vec<u8>,
    /// A palette of greys: diffuse luminance only.
    grey: bool,
    /// Kernels of Floyd–Steinberg's shape may take the sliding-window loop.
    fs_loop: bool,
    /// The page row the next band starts at.
    y: usize,
    /// Take the vector loop ([`super::palette_avx512`]) where the CPU and palette allow.
    vector: bool,
    /// Let the scalar loop use the cell table.
    table: bool,
    carried: Option<Carried>,
}

impl<'d> PaletteRun<'d> {
    /// A page of `d` to `palette`. `fast` takes the nearest colour from [`FastNearest`]
    /// where it is proven; `fs_loop` runs Floyd–Steinberg-shaped kernels in
    /// [`palette_fs`]. With both false this is the reference the fast paths are tested
    /// against; all four give the same bytes.
    pub(super) fn new(
        d: &'d Diffuse,
        palette: &'d Palette,
        fast: bool,
        fs_loop: bool,
    ) -> Result<PaletteRun<'d>> {
        if d.algorithm == Algorithm::Riemersma {
            return Err(Error::Invalid(
                "`palette` works with the kernels, Ostromoukhov and Zhou-Fang, not riemersma"
                    .into(),
            ));
        }
        let matcher = PaletteMatcher::new(palette);
        let fast = FastNearest::new(palette, &matcher).filter(|_| fast);
        let entry: Vec<u8> = match &fast {
            Some(f) => (0..f.lanes()).map(|lane| f.entry(lane) as u8).collect(),
            None => (0..palette.len()).map(|i| i as u8).collect(),
        };
        let linear = entry.iter().map(|&i| matcher.linear(i as usize)).collect();
        Ok(PaletteRun {
            d,
            palette,
            matcher,
            fast,
            cells: None,
            linear,
            entry,
            grey: palette.colours.iter().all(|c| c[0] == c[1] && c[1] == c[2]),
            fs_loop,
            y: 0,
            vector: true,
            table: true,
            carried: None,
        })
    }

    /// The same run without the vector loop (to test the loops against each other).
    #[cfg(test)]
    pub(super) fn without_vector(mut self) -> Self {
        self.vector = false;
        self
    }

    /// The same run without the cell table (to test the loops against each other).
    #[cfg(test)]
    pub(super) fn without_table(mut self) -> Self {
        self.table = false;
        self
    }

    /// Whether a Floyd–Steinberg-shaped band runs the vector loop.
    fn vector_loop(&self, f: &FastNearest) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            self.vector && f.lanes() == 8 && super::palette_avx512::available()
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = (f, self.vector);
            false
        }
    }

    /// Halftones the next band of rows of the page (one or three planes) to palette indices.
    pub(super) fn band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        let (w, h) = (input.width, input.height);
        let planes = input.rgb("a palette")?;
        let mut out = Halftone::new(w, h, 1, self.palette.len() as u16);
        out.palette = Some(self.palette.colours.clone());
        // The weights come from the luminance plane's engine for variable kernels: index the
        // tables by the pixel's luminance level.
        let engine = Engine::new(self.d, planes[0].tone, 2);
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
        let vector = self.fast.as_ref().is_some_and(|f| self.vector_loop(f));
        let carried = self.carried.get_or_insert_with(|| {
            match fs_shape(&engine.weights).filter(|_| self.fs_loop) {
                Some(wt) => Carried::Fs {
                    wt,
                    err: vec![[0.0; 3]; w],
                    below: vec![[0.0; 3]; w],
                },
                None => Carried::Rows {
                    err: vec![0.0; 3 * (engine.below + 1) * (w + 2 * PAD)],
                },
            }
        });
        let (y0, grey, serpentine) = (self.y, self.grey, self.d.options.serpentine);
        let (m, linear, entry) = (&self.matcher, &self.linear[..], &self.entry[..]);
        match carried {
            Carried::Fs { wt, err, below } => {
                let band = palette_fs::FsBand {
                    planes,
                    y0,
                    grey,
                    wt: *wt,
                    serpentine,
                    linear,
                    entry,
                    err,
                    below,
                };
                match &self.fast {
                    #[cfg(target_arch = "x86_64")]
                    Some(f) if vector => super::palette_avx512::run(band, f, m, &mut out),
                    Some(f) => {
                        // The cell table serves this loop only: made when it first runs.
                        let cells = if self.table {
                            Some(self.cells.get_or_insert_with(|| CellTable::new(f, m)))
                        } else {
                            None
                        };
                        match f.lanes() {
                            8 => palette_fs::run_fast::<8>(band, f, m, cells, &mut out),
                            16 => palette_fs::run_fast::<16>(band, f, m, cells, &mut out),
                            32 => palette_fs::run_fast::<32>(band, f, m, cells, &mut out),
                            _ => palette_fs::run_fast::<64>(band, f, m, cells, &mut out),
                        }
                    }
                    None => palette_fs::run(band, |v| m.nearest(v), &mut out),
                }
            }
            Carried::Rows { err } => {
                let fast = self.fast.as_ref();
                let nearest = |v: [f32; 3]| match fast {
                    Some(f) => match f.lanes() {
                        8 => nearest_of::<8>(f, m, v),
                        16 => nearest_of::<16>(f, m, v),
                        32 => nearest_of::<32>(f, m, v),
                        _ => nearest_of::<64>(f, m, v),
                    },
                    None => m.nearest(v),
                };
                rows(
                    planes, y0, grey, serpentine, &engine, nearest, linear, entry, err, &mut out,
                );
            }
        }
        self.y += h;
        Ok(out)
    }

    /// Bytes of error state for a page `width` pixels wide.
    fn state_bytes(&self, width: usize) -> usize {
        let below = match &self.d.algorithm {
            Algorithm::Kernel(k) => k.rows_below(),
            _ => 1,
        };
        3 * 4 * (below + 1) * (width + 2 * PAD) + 3 * 4 * width
    }
}

/// The general loop: any kernel, error rows per channel in a ring, for the rows of one band
/// (page rows `y0..`). `nearest` answers a code: `linear[code]` in linear RGB, `entry[code]`
/// the palette index.
#[allow(clippy::too_many_arguments)]
fn rows(
    planes: [&PlaneRef<'_>; 3],
    y0: usize,
    grey: bool,
    serpentine: bool,
    engine: &Engine<'_>,
    mut nearest: impl FnMut([f32; 3]) -> usize,
    linear: &[[f32; 3]],
    entry: &[u8],
    err: &mut [f32],
    out: &mut Halftone,
) {
    let (w, h) = (out.width, out.height);
    let (bits, stride) = (out.bits, out.stride);
    let n = engine.below + 1;
    let span = w + 2 * PAD;
    let mut lin = [vec![0f32; w], vec![0f32; w], vec![0f32; w]];
    let mut idx = vec![0u8; w];
    let at = |c: usize, slot: usize, x: usize| (c * n + slot) * span + x;
    for r in 0..h {
        let y = y0 + r;
        palette_fs::linear_row(planes, r, grey, &mut lin);
        let dir: isize = if serpentine && y % 2 == 1 { -1 } else { 1 };
        let mut carry = [0f32; 3];
        for i in 0..w {
            let x = if dir > 0 { i } else { w - 1 - i };
            let mut v = [0f32; 3];
            for c in 0..3 {
                let cell = at(c, y % n, PAD + x);
                v[c] = (lin[c][x] + err[cell] + carry[c]).clamp(-1.0, 2.0);
                err[cell] = 0.0;
            }
            let k = nearest(v);
            idx[x] = entry[k];
            let q = linear[k];
            let e = [v[0] - q[0], v[1] - q[1], v[2] - q[2]];
            let base = (PAD + x) as isize;
            match &engine.weights {
                Weights::Fixed { right, taps } => {
                    for c in 0..3 {
                        carry[c] = e[c] * right;
                        for &(dx, dy, wt) in taps {
                            let xx = (base + dir * dx) as usize;
                            err[at(c, (y + dy) % n, xx)] += wt * e[c];
                        }
                    }
                }
                Weights::Variable {
                    table,
                    modulation: _,
                    ..
                } => {
                    // Level of the input's luminance (Rec. 709 weights in linear light).
                    let lum = 0.2126 * lin[0][x] + 0.7152 * lin[1][x] + 0.0722 * lin[2][x];
                    let [r, dl, d] = table[(lum.clamp(0.0, 1.0) * 255.0).round() as usize];
                    for c in 0..3 {
                        carry[c] = e[c] * r;
                        err[at(c, (y + 1) % n, (base - dir) as usize)] += e[c] * dl;
                        err[at(c, (y + 1) % n, base as usize)] += e[c] * d;
                    }
                }
            }
        }
        for c in 0..3 {
            for x in (0..PAD).chain(PAD + w..span) {
                err[at(c, y % n, x)] = 0.0;
            }
        }
        pack_row(&idx, bits, &mut out.planes[0][r * stride..(r + 1) * stride]);
    }
}

/// Palette diffusion as a [`RowMethod`]: one [`PaletteRun`] over the page's bands.
pub(super) struct PaletteRows<'d> {
    run: PaletteRun<'d>,
}

impl<'d> PaletteRows<'d> {
    pub(super) fn new(d: &'d Diffuse, palette: &'d Palette) -> Result<PaletteRows<'d>> {
        Ok(PaletteRows {
            run: PaletteRun::new(d, palette, true, true)?,
        })
    }
}

impl RowMethod for PaletteRows<'_> {
    fn state_bytes(&self, width: usize, _planes: usize) -> usize {
        self.run.state_bytes(width)
    }

    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        self.run.band(input)
    }
}
