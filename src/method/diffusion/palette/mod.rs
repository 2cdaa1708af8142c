//! Palette diffusion, whole image or band by band: nearest colour in Oklab, error per channel
//! in linear RGB.
//!
//! The page is cut into fixed bands of [`BAND`] rows diffused independently, and so in
//! parallel: each band but the first starts from zero error [`WARM`] rows above its first row
//! (scanning them in the page rows' directions, their output dropped) and the error leaving
//! its last row is dropped, so the bytes depend on the page alone, not on the threads nor on
//! the rows each call is handed. [`PaletteRun`] holds what lives from one call to the next
//! (the error state of a band the call ended inside, the last input rows for a warm-up that
//! begins in an earlier call, the prepared palette), so a page streams through
//! [`PaletteRows`] with the bytes of the whole-image run.
//!
//! Kernels of Floyd–Steinberg's shape run the sliding-window loop of [`fs`];
//! other kernels (and variable coefficients) run the general loop here. The nearest colour
//! comes from [`FastNearest`] where it can prove the exact search's answer, and from the
//! exact search ([`PaletteMatcher::nearest`]) elsewhere; the scalar Floyd–Steinberg loop asks
//! the certified cell table ([`CellTable`]) first. On a CPU with AVX-512,
//! Floyd–Steinberg-shaped kernels with at most eight distinct colours run the vector loop
//! (`avx512`): the same answers, with a shorter chain from pixel to pixel.

#[cfg(target_arch = "x86_64")]
mod avx512;
pub(super) mod cells;
pub mod fast;
pub(super) mod fs;
pub(crate) mod inks;

use rayon::prelude::*;

use self::fs::{FsWeights, Input, Packed, Rows};
use super::{fs_shape, Algorithm, Diffuse, Engine, Weights, PAD};
use crate::color::{Palette, PaletteMatcher};
use crate::error::{Error, Result};
use crate::method::rows::RowMethod;
use crate::raster::{Halftone, PlaneRef, Planes, SamplesRef};
use cells::CellTable;
use fast::FastNearest;

/// Page rows a band: the page's bands (rows `k·BAND..`) are diffused independently.
pub(super) const BAND: usize = 128;

/// Rows diffused before each band but the first, from zero error, their output dropped.
pub(super) const WARM: usize = 16;

/// The nearest colour's lane: fast where proven, else the exact search's answer.
#[inline(always)]
fn nearest_of<const N: usize>(f: &FastNearest, m: &PaletteMatcher, v: [f32; 3]) -> usize {
    match f.nearest::<N>(v) {
        Some(lane) => lane,
        None => f.lane_of(m.nearest(v)),
    }
}

/// The error carried between rows within a band.
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

/// The part of one band that one call diffuses: page rows `own`, after the band's warm-up
/// (page rows `start..own.start`, none unless the band starts here).
struct Part<'o> {
    start: usize,
    own: std::ops::Range<usize>,
    /// The band's error state when it began in an earlier call (else a fresh one is made).
    state: Option<Carried>,
    out: &'o mut [u8],
}

/// What every part of one call shares.
struct Shared<'a, 'p> {
    planes: [&'a PlaneRef<'p>; 3],
    /// The page row of the planes' first row.
    y: usize,
    /// The rows kept from before `y` (the last `kept[0].height` of them).
    kept: [&'a PlaneRef<'p>; 3],
    grey: bool,
    serpentine: bool,
    engine: &'a Engine<'a>,
    /// The state of a band that begins in this call.
    fresh: &'a (dyn Fn() -> Carried + Sync),
    matcher: &'a PaletteMatcher,
    fast: Option<&'a FastNearest>,
    cells: Option<&'a CellTable>,
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    vector: bool,
    linear: &'a [[f32; 3]],
    entry: &'a [u8],
    stride: usize,
    bits: u8,
}

impl<'a, 'p> Shared<'a, 'p> {
    /// Two parts of the Floyd–Steinberg shape through the vector loop at once (their chains
    /// overlapping, [`avx512::run2`]); answers their error states after them.
    #[cfg(target_arch = "x86_64")]
    fn run_pair(&self, a: Part<'_>, b: Part<'_>) -> (Carried, Carried) {
        let (mut sa, ia, oa, ya, ka) = self.open(a);
        let (mut sb, ib, ob, yb, kb) = self.open(b);
        let f = self.fast.expect("the vector loop's search");
        match (&mut sa, &mut sb) {
            (
                Carried::Fs {
                    wt,
                    err: ea,
                    below: ba,
                },
                Carried::Fs {
                    err: eb, below: bb, ..
                },
            ) => {
                let band = |input, y0, skip, err, below, out| {
                    self.fs_band(*wt, input, y0, skip, err, below, out)
                };
                avx512::run2(
                    band(ia, ya, ka, ea, ba, oa),
                    band(ib, yb, kb, eb, bb, ob),
                    f,
                    self.matcher,
                );
            }
            _ => unreachable!("pairs are made of Floyd–Steinberg parts"),
        }
        (sa, sb)
    }

    /// A part's state (fresh unless carried), its input rows and output, its first page row
    /// and how many of its rows are warm-up.
    #[allow(clippy::type_complexity)]
    fn open<'o>(
        &self,
        part: Part<'o>,
    ) -> (Carried, fs::Input<'a, 'p>, fs::Packed<'o>, usize, usize) {
        let Part {
            start,
            own,
            state,
            out,
        } = part;
        let state = state.unwrap_or_else(self.fresh);
        let first = start.max(self.y);
        let (kept, at) = (self.y - start.min(self.y), self.kept[0].height);
        let input = fs::Input {
            kept: Rows {
                planes: self.kept,
                from: at - kept,
                n: kept,
            },
            planes: Rows {
                planes: self.planes,
                from: first - self.y,
                n: own.end - first,
            },
        };
        let out = fs::Packed {
            bytes: out,
            stride: self.stride,
            bits: self.bits,
        };
        (state, input, out, start, own.start - start)
    }

    /// What the Floyd–Steinberg loops take for a part opened by [`Self::open`].
    #[allow(clippy::too_many_arguments)]
    fn fs_band<'s>(
        &self,
        wt: FsWeights,
        input: fs::Input<'a, 'p>,
        y0: usize,
        skip: usize,
        err: &'s mut Vec<[f32; 3]>,
        below: &'s mut Vec<[f32; 3]>,
        out: fs::Packed<'s>,
    ) -> fs::FsBand<'s, 'p>
    where
        'a: 's,
    {
        fs::FsBand {
            input,
            y0,
            skip,
            grey: self.grey,
            wt,
            serpentine: self.serpentine,
            linear: self.linear,
            entry: self.entry,
            err,
            below,
            out,
        }
    }

    /// Diffuses one part into its output rows; answers the band's error state after it.
    fn run(&self, part: Part<'_>) -> Carried {
        let (mut state, input, out, start, skip) = self.open(part);
        let m = self.matcher;
        let (linear, entry) = (self.linear, self.entry);
        match &mut state {
            Carried::Fs { wt, err, below } => {
                let band = self.fs_band(*wt, input, start, skip, err, below, out);
                match self.fast {
                    #[cfg(target_arch = "x86_64")]
                    Some(f) if self.vector => avx512::run(band, f, m),
                    Some(f) => match f.lanes() {
                        8 => fs::run_fast::<8>(band, f, m, self.cells),
                        16 => fs::run_fast::<16>(band, f, m, self.cells),
                        32 => fs::run_fast::<32>(band, f, m, self.cells),
                        _ => fs::run_fast::<64>(band, f, m, self.cells),
                    },
                    None => fs::run(band, |v| m.nearest(v)),
                }
            }
            Carried::Rows { err } => {
                let fast = self.fast;
                let nearest = |v: [f32; 3]| match fast {
                    Some(f) => match f.lanes() {
                        8 => nearest_of::<8>(f, m, v),
                        16 => nearest_of::<16>(f, m, v),
                        32 => nearest_of::<32>(f, m, v),
                        _ => nearest_of::<64>(f, m, v),
                    },
                    None => m.nearest(v),
                };
                let page = Page {
                    input,
                    y0: start,
                    skip,
                    grey: self.grey,
                    serpentine: self.serpentine,
                };
                rows(page, self.engine, nearest, linear, entry, err, out);
            }
        }
        state
    }
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
    /// The page row the next call starts at.
    y: usize,
    /// Take the vector loop ([`avx512`]) where the CPU and palette allow.
    vector: bool,
    /// Let the scalar loop use the cell table.
    table: bool,
    /// Page rows a band ([`BAND`]) and warm-up rows ([`WARM`]).
    band_rows: usize,
    warm: usize,
    /// The error state of the band in progress when a call ends inside it.
    carried: Option<Carried>,
    /// The last input rows before `y` (at most `warm`), for a band whose warm-up begins in
    /// an earlier call.
    kept: Kept,
}

/// Input rows kept from call to call: each plane's codes, row after row. They are read with
/// the tone tables of the call that reads them (a page's bands share theirs).
#[derive(Default)]
struct Kept {
    rows: usize,
    codes: [Codes; 3],
}

/// The codes of one plane's kept rows.
enum Codes {
    U8(Vec<u8>),
    U16(Vec<u16>),
}

impl Default for Codes {
    fn default() -> Codes {
        Codes::U8(Vec::new())
    }
}

impl Codes {
    /// The codes of `plane`'s rows `from..from + n` after the last `keep` rows of these
    /// (`width` codes a row); starts afresh if the sample type changed.
    fn then(&self, keep: usize, plane: &PlaneRef<'_>, from: usize, n: usize) -> Codes {
        fn join<T: Copy>(old: &[T], keep: usize, new: &[T]) -> Vec<T> {
            let mut v = Vec::with_capacity(keep + new.len());
            v.extend_from_slice(&old[old.len() - keep..]);
            v.extend_from_slice(new);
            v
        }
        let (w, new) = (plane.width, from * plane.width..(from + n) * plane.width);
        match (self, plane.samples) {
            (Codes::U8(old), SamplesRef::U8(s)) => Codes::U8(join(old, keep * w, &s[new])),
            (Codes::U16(old), SamplesRef::U16(s)) => Codes::U16(join(old, keep * w, &s[new])),
            (_, SamplesRef::U8(s)) => Codes::U8(s[new].to_vec()),
            (_, SamplesRef::U16(s)) => Codes::U16(s[new].to_vec()),
        }
    }

    /// The codes as `rows` rows of a plane read through `like`'s tone table.
    fn plane<'a>(&'a self, like: &PlaneRef<'a>, rows: usize) -> PlaneRef<'a> {
        PlaneRef {
            width: like.width,
            height: rows,
            samples: match self {
                Codes::U8(v) => SamplesRef::U8(v),
                Codes::U16(v) => SamplesRef::U16(v),
            },
            tone: like.tone,
        }
    }

    fn is_u8(&self) -> bool {
        matches!(self, Codes::U8(_))
    }
}

impl Kept {
    /// The rows kept that can be read with `planes`' tone tables: all of them, or none if the
    /// sample type changed from call to call (it does not within a page).
    fn usable(&self, planes: [&PlaneRef<'_>; 3]) -> usize {
        let same =
            |c: usize| self.codes[c].is_u8() == matches!(planes[c].samples, SamplesRef::U8(_));
        if (0..3).all(same) {
            self.rows
        } else {
            0
        }
    }
}

impl<'d> PaletteRun<'d> {
    /// A page of `d` to `palette`. `fast` takes the nearest colour from [`FastNearest`]
    /// where it is proven; `fs_loop` runs Floyd–Steinberg-shaped kernels in
    /// [`fs`]. With both false this is the reference the fast paths are tested
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
            band_rows: BAND,
            warm: WARM,
            carried: None,
            kept: Kept::default(),
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

    /// The same run with bands of `rows` rows and `warm` warm-up rows (`warm <= rows`), to
    /// test banding on small pages (`usize::MAX` rows: one band, the page diffused whole).
    #[cfg(test)]
    pub(super) fn with_bands(mut self, rows: usize, warm: usize) -> Self {
        assert!(warm <= rows);
        self.band_rows = rows;
        self.warm = warm;
        self
    }

    /// Whether a Floyd–Steinberg-shaped band runs the vector loop.
    fn vector_loop(&self, f: &FastNearest) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            self.vector && f.lanes() == 8 && avx512::available()
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = (f, self.vector);
            false
        }
    }

    /// Halftones the next rows of the page (one or three planes) to palette indices. The rows
    /// are cut where the page's bands begin; the bands run in parallel, each with its own
    /// error rows, and a band begun in an earlier call goes on from its error state.
    pub(super) fn band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        let (w, h) = (input.width, input.height);
        let planes = input.rgb("a palette")?;
        let mut out = Halftone::new(w, h, 1, self.palette.len() as u16);
        out.palette = Some(self.palette.colours.clone());
        // The weights come from the luminance plane's engine for variable kernels: index the
        // tables by the pixel's luminance level.
        let engine = Engine::new(self.d, planes[0].tone, 2);
        let vector = self.fast.as_ref().is_some_and(|f| self.vector_loop(f));
        let shape = fs_shape(&engine.weights).filter(|_| self.fs_loop);
        if let (Some(f), Some(_), false, true) = (&self.fast, shape, vector, self.table) {
            // The cell table serves the scalar Floyd–Steinberg loop only: made when it first
            // runs.
            let m = &self.matcher;
            self.cells.get_or_insert_with(|| CellTable::new(f, m));
        }
        let fresh = || match shape {
            Some(wt) => Carried::Fs {
                wt,
                err: vec![[0.0; 3]; w],
                below: vec![[0.0; 3]; w],
            },
            None => Carried::Rows {
                err: vec![0.0; 3 * (engine.below + 1) * (w + 2 * PAD)],
            },
        };
        // The kept rows, read as the planes are.
        let rows = self.kept.usable(planes);
        let kept: [PlaneRef<'_>; 3] =
            std::array::from_fn(|c| self.kept.codes[c].plane(planes[c], rows));
        // The call's rows cut where bands begin: a band begun earlier goes on; a band that
        // begins here starts from zero error `warm` rows above (none for the page's first).
        let (y, b, stride) = (self.y, self.band_rows, out.stride);
        let mut parts = Vec::new();
        let mut rest: &mut [u8] = &mut out.planes[0];
        let mut a = y;
        while a < y + h {
            let e = (a - a % b).saturating_add(b).min(y + h);
            let (mine, tail) = std::mem::take(&mut rest).split_at_mut((e - a) * stride);
            rest = tail;
            let (start, state) = if a.is_multiple_of(b) {
                (a.saturating_sub(self.warm).max(y - rows), None)
            } else {
                let state = self
                    .carried
                    .take()
                    .expect("the state of the band in progress");
                (a, Some(state))
            };
            parts.push(Part {
                start,
                own: a..e,
                state,
                out: mine,
            });
            a = e;
        }
        let shared = Shared {
            planes,
            y,
            kept: [&kept[0], &kept[1], &kept[2]],
            fresh: &fresh,
            grey: self.grey,
            serpentine: self.d.options.serpentine,
            engine: &engine,
            matcher: &self.matcher,
            fast: self.fast.as_ref(),
            cells: self.cells.as_ref().filter(|_| self.table),
            vector,
            linear: &self.linear,
            entry: &self.entry,
            stride,
            bits: out.bits,
        };
        // The error leaving a band's last row is dropped (each part's state is dropped as it
        // ends, so only the parts running hold one); a band the call ends inside goes on in
        // the next call.
        let run = |p: Part<'_>| {
            let goes_on = !p.own.end.is_multiple_of(b);
            let state = shared.run(p);
            goes_on.then_some(state)
        };
        // The vector loop takes two parts a task, their chains overlapping on one thread.
        #[cfg(target_arch = "x86_64")]
        let paired = vector && shape.is_some() && parts.len() >= 2;
        #[cfg(not(target_arch = "x86_64"))]
        let paired = false;
        let mut states: Vec<Option<Carried>> = if paired {
            #[cfg(target_arch = "x86_64")]
            {
                let mut pairs: Vec<Vec<Part<'_>>> = Vec::new();
                for p in parts {
                    match pairs.last_mut() {
                        Some(last) if last.len() == 1 => last.push(p),
                        _ => pairs.push(vec![p]),
                    }
                }
                let done: Vec<Vec<Option<Carried>>> = pairs
                    .into_par_iter()
                    .map(|mut pair| {
                        if pair.len() == 1 {
                            return vec![run(pair.pop().expect("one part"))];
                        }
                        let second = pair.pop().expect("two parts");
                        let first = pair.pop().expect("two parts");
                        let on = [first.own.end, second.own.end].map(|e| !e.is_multiple_of(b));
                        let (sa, sb) = shared.run_pair(first, second);
                        vec![on[0].then_some(sa), on[1].then_some(sb)]
                    })
                    .collect();
                done.into_iter().flatten().collect()
            }
            #[cfg(not(target_arch = "x86_64"))]
            unreachable!()
        } else if parts.len() == 1 {
            parts.into_iter().map(run).collect()
        } else {
            parts.into_par_iter().map(run).collect()
        };
        self.carried = states.pop().flatten();
        self.keep(planes, h);
        self.y += h;
        Ok(out)
    }

    /// Keeps the last input rows before the next call (at most `warm`), after a call of `h`
    /// rows.
    fn keep(&mut self, planes: [&PlaneRef<'_>; 3], h: usize) {
        let take = h.min(self.warm);
        let keep = self.kept.usable(planes).min(self.warm - take);
        let codes =
            std::array::from_fn(|c| self.kept.codes[c].then(keep, planes[c], h - take, take));
        self.kept = Kept {
            rows: keep + take,
            codes,
        };
    }

    /// Bytes of state for a page `width` pixels wide: the error rows and scratch of each band
    /// running at once and of one carried between calls, and the rows kept for warm-up (16-bit
    /// codes at most).
    fn state_bytes(&self, width: usize) -> usize {
        let below = match &self.d.algorithm {
            Algorithm::Kernel(k) => k.rows_below(),
            _ => 1,
        };
        let band = 3 * 4 * (below + 1) * (width + 2 * PAD) + 3 * 4 * width + width;
        band * (rayon::current_num_threads() + 1) + self.warm * 3 * 2 * width
    }
}

/// Where the general loop's rows come from and how they are scanned.
struct Page<'a, 'p> {
    input: Input<'a, 'p>,
    /// The page row of the input's first row.
    y0: usize,
    /// The input's first rows whose output is dropped (a band's warm-up).
    skip: usize,
    grey: bool,
    serpentine: bool,
}

/// The general loop: any kernel, error rows per channel in a ring, for the rows of `page`.
/// `nearest` answers a code: `linear[code]` in linear RGB, `entry[code]` the palette index.
fn rows(
    page: Page<'_, '_>,
    engine: &Engine<'_>,
    mut nearest: impl FnMut([f32; 3]) -> usize,
    linear: &[[f32; 3]],
    entry: &[u8],
    err: &mut [f32],
    mut out: Packed<'_>,
) {
    let (w, h) = (page.input.width(), page.input.rows());
    let n = engine.below + 1;
    let span = w + 2 * PAD;
    let mut lin = [vec![0f32; w], vec![0f32; w], vec![0f32; w]];
    let mut idx = vec![0u8; w];
    let at = |c: usize, slot: usize, x: usize| (c * n + slot) * span + x;
    for r in 0..h {
        let y = page.y0 + r;
        page.input.row(r, page.grey, &mut lin);
        let dir: isize = if page.serpentine && y % 2 == 1 { -1 } else { 1 };
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
        if r >= page.skip {
            out.put(r - page.skip, &idx);
        }
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
