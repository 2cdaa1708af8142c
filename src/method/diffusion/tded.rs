//! Tone-dependent error diffusion (`--kernel tded`), after Li and Allebach, "Tone-dependent
//! error diffusion", IEEE Trans. Image Processing 13(2), 2004: Floyd–Steinberg's four taps,
//! but the four weights and the threshold depend on the input tone, and are trained for each
//! grey so that the halftone of that grey scores as close as the search can get to what
//! direct binary search reaches.
//!
//! # The tables
//! `kernels/tded.txt` holds one row per trained grey `g = k/64`, k = 0..=32 (reflectance
//! 0..½): the weights of the pixel ahead, below-behind, below and below-ahead (summing to 1)
//! and the threshold. Greys above ½ use the row of `1 − g` with the threshold `1 − t` (a
//! halftone of `1 − g` is the negative of one of `g`). Between rows, linear interpolation.
//!
//! # Training (`halftone train tded`)
//! The training set is synthetic: for each grey, flat patches of [`TRAIN_SIZE`]² pixels at
//! the grey and ±1/256. The loss is the patches' error as `halftone compare` scores a photo
//! ([`flat_loss`]: the Näsänen filter at 300 dpi and 12 inches applied exactly, in the
//! frequency domain), measured past the patch's first rows and columns, where error
//! diffusion starts up. (An earlier loss, the error correlated with DBS's 13×13 tapered
//! filter autocorrelation, [`crate::method::dbs::cpp_table`], trained a table 0.35 dB worse
//! on photos: docs/accuracy.md.)
//! The greys are trained in order, each from the row before (the first from Floyd–Steinberg's
//! weights and a threshold of ½), by a deterministic coordinate search (each parameter up and
//! down by a step, the step halved when nothing helps); the table is then smoothed across
//! greys ([`smooth`]). The search is chaotic, so this is done once for each start-up margin
//! of [`TRAIN_MARGINS`], and the run kept is the one that scores best on synthetic
//! validation images ([`validation_images`]: a ramp and smooth random fields). The file names
//! the run it keeps. The result is bit-for-bit reproducible: `tests/it/accuracy.rs` retrains the
//! first rows of that run and checks them.

use super::DiffuseOptions;
use crate::error::{Error, Result};
use crate::method::{each_plane, Method, PlaneOut};
use crate::raster::{pack_row, Halftone, PlaneRef, Planes};

/// The shipped table (see the module documentation).
pub const TABLE_TEXT: &str = include_str!("../../../kernels/tded.txt");

/// Rows in the table: greys k/64, k = 0..=32.
pub const ROWS: usize = 33;
/// Side of a training patch, pixels.
pub const TRAIN_SIZE: usize = 96;
/// Rows and columns at the patch's start left out of the loss: one training run for each,
/// the run kept is the one that scores best on [`validation_images`] ([`train`]).
pub const TRAIN_MARGINS: [usize; 8] = [8, 12, 16, 20, 24, 28, 32, 36];
/// Side of a validation image, pixels (with the metric's mirror margin, a 512-point FFT).
pub const VALIDATION_SIZE: usize = 480;

/// One row: weights (ahead, below-behind, below, below-ahead) and threshold.
pub type Params = [f32; 5];

/// Floyd–Steinberg as a row: the start of training.
pub const FLOYD_STEINBERG: Params = [7.0 / 16.0, 3.0 / 16.0, 5.0 / 16.0, 1.0 / 16.0, 0.5];

/// Parses the table: `#` comments; rows of `k w_ahead w_below_behind w_below w_below_ahead t`.
pub fn parse_table(text: &str) -> Result<Vec<Params>> {
    let mut rows = vec![FLOYD_STEINBERG; ROWS];
    let mut seen = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let v: Vec<f32> = line
            .split_whitespace()
            .map(|w| w.parse::<f32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| Error::parse("tded table", i + 1, "not a number"))?;
        if v.len() != 6 || v[0] < 0.0 || v[0] as usize >= ROWS {
            return Err(Error::parse(
                "tded table",
                i + 1,
                "want: k w1 w2 w3 w4 threshold",
            ));
        }
        rows[v[0] as usize] = [v[1], v[2], v[3], v[4], v[5]];
        seen += 1;
    }
    if seen != ROWS {
        return Err(Error::parse(
            "tded table",
            0,
            format!("{seen} rows; want {ROWS}"),
        ));
    }
    Ok(rows)
}

/// The margin of the training run a table's text names (its `# margin N:` line).
pub fn table_margin(text: &str) -> Option<usize> {
    text.lines()
        .find_map(|l| l.strip_prefix("# margin ")?.split(':').next()?.parse().ok())
}

/// Writes the table, naming the training run's margin, in the format [`parse_table`] reads.
pub fn table_text(rows: &[Params], margin: usize) -> String {
    let mut s = format!(
        "# Tone-dependent error diffusion: trained by `halftone train tded` (see\n\
         # src/method/diffusion/tded.rs). Columns: k (grey k/64), weights of the pixel ahead,\n\
         # below-behind, below, below-ahead, threshold.\n\
         # margin {margin}: the training run kept (the best on the validation images)\n",
    );
    for (k, p) in rows.iter().enumerate() {
        s.push_str(&format!(
            "{k:2} {:.6} {:.6} {:.6} {:.6} {:.6}\n",
            p[0], p[1], p[2], p[3], p[4]
        ));
    }
    s
}

/// The parameters for input reflectance `v`, interpolated between rows.
pub fn params_at(rows: &[Params], v: f32) -> Params {
    let v = v.clamp(0.0, 1.0);
    let (g, flip) = if v > 0.5 { (1.0 - v, true) } else { (v, false) };
    let t = (g * 64.0).min(32.0);
    let i = (t as usize).min(ROWS - 2);
    let f = t - i as f32;
    let mut p: Params = std::array::from_fn(|j| rows[i][j] + (rows[i + 1][j] - rows[i][j]) * f);
    if flip {
        p[4] = 1.0 - p[4];
    }
    p
}

/// The `diffuse --kernel tded` method (bilevel).
#[derive(Clone, Debug)]
pub struct Tded {
    /// Scan and strength.
    pub options: DiffuseOptions,
    rows: Vec<Params>,
}

impl Tded {
    /// Tone-dependent error diffusion with the shipped table.
    pub fn new(options: DiffuseOptions) -> Result<Tded> {
        Tded::with_table(options, parse_table(TABLE_TEXT)?)
    }

    /// With a table of [`ROWS`] rows.
    pub fn with_table(options: DiffuseOptions, rows: Vec<Params>) -> Result<Tded> {
        if options.levels != 2 {
            return Err(Error::Invalid(
                "`kernel` tded works with bilevel output (`levels` 2)".into(),
            ));
        }
        if rows.len() != ROWS {
            return Err(Error::Invalid(format!("tded table: want {ROWS} rows")));
        }
        Ok(Tded { options, rows })
    }

    fn plane(&self, plane: &PlaneRef<'_>, out: &mut PlaneOut<'_>) {
        let params: Vec<Params> = plane
            .tone
            .iter()
            .map(|&v| {
                let mut p = params_at(&self.rows, v);
                for w in &mut p[..4] {
                    *w *= self.options.strength;
                }
                p
            })
            .collect();
        let mut levels = vec![0u8; plane.width];
        diffuse_rows(
            plane.width,
            plane.height,
            self.options.serpentine,
            |y, codes: &mut Vec<u32>| {
                codes.clear();
                match plane.samples {
                    crate::raster::SamplesRef::U8(s) => codes.extend(
                        s[y * plane.width..(y + 1) * plane.width]
                            .iter()
                            .map(|&c| c as u32),
                    ),
                    crate::raster::SamplesRef::U16(s) => codes.extend(
                        s[y * plane.width..(y + 1) * plane.width]
                            .iter()
                            .map(|&c| c as u32),
                    ),
                }
            },
            |c| (plane.tone[c as usize], &params[c as usize]),
            |y, row| {
                levels.copy_from_slice(row);
                pack_row(
                    &levels,
                    out.bits,
                    &mut out.data[y * out.stride..(y + 1) * out.stride],
                );
            },
        );
    }
}

/// The error-diffusion loop: `codes(y, buf)` fills a row's codes, `lookup(code)` gives the
/// reflectance and the parameters, `emit(y, levels)` takes each finished row (0 ink, 1 paper).
pub(crate) fn diffuse_rows<'p>(
    w: usize,
    h: usize,
    serpentine: bool,
    mut codes: impl FnMut(usize, &mut Vec<u32>),
    lookup: impl Fn(u32) -> (f32, &'p Params),
    mut emit: impl FnMut(usize, &[u8]),
) {
    if w == 0 {
        return;
    }
    let mut cur = vec![0f32; w + 2];
    let mut next = vec![0f32; w + 2];
    let mut row = Vec::with_capacity(w);
    let mut out = vec![0u8; w];
    for y in 0..h {
        codes(y, &mut row);
        let rtl = serpentine && y % 2 == 1;
        let dir: isize = if rtl { -1 } else { 1 };
        // The error passed ahead and the two partial sums of the next row still open (at the
        // pixel below and below-ahead) stay in registers: through memory, each pixel waited
        // for the store of the one before (store forwarding), which made this loop 3.3× as
        // slow as Floyd–Steinberg's. The sums are added in the same order as before, so the
        // output bits are the same.
        let mut ahead = 0f32;
        let (mut below, mut below_ahead) = (0f32, 0f32);
        for i in 0..w {
            let x = if rtl { w - 1 - i } else { i };
            let (v, p) = lookup(row[x]);
            let xi = x as isize + 1;
            let u = v + (cur[xi as usize] + ahead);
            let paper = u >= p[4];
            let e = if paper { u - 1.0 } else { u };
            ahead = e * p[0];
            // next[x − dir] is complete with this pixel's share.
            next[(xi - dir) as usize] = below + e * p[1];
            below = below_ahead + e * p[2];
            below_ahead = 0.0 + e * p[3];
            out[x] = paper as u8;
        }
        // The last pixel's below and below-ahead shares (the latter falls off the edge into
        // the padding column, as before).
        let last = (if rtl { 0 } else { w as isize - 1 }) + 1;
        next[last as usize] = below;
        next[(last + dir) as usize] = below_ahead;
        emit(y, &out);
        std::mem::swap(&mut cur, &mut next);
        next.fill(0.0);
    }
}

impl Method for Tded {
    fn name(&self) -> String {
        "diffuse(tded)".into()
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        Ok(each_plane(
            input,
            input.width,
            input.height,
            2,
            |_, plane, out| self.plane(plane, out),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmath as fm;

    /// The loop as first written, every share through memory: the register version must
    /// place the same dots.
    fn reference(w: usize, h: usize, tone: &[f32], rows: &[Params], serpentine: bool) -> Vec<u8> {
        let mut cur = vec![0f32; w + 2];
        let mut next = vec![0f32; w + 2];
        let mut out = vec![0u8; w * h];
        for y in 0..h {
            let rtl = serpentine && y % 2 == 1;
            let dir: isize = if rtl { -1 } else { 1 };
            for i in 0..w {
                let x = if rtl { w - 1 - i } else { i };
                let v = tone[y * w + x];
                let p = params_at(rows, v);
                let xi = x as isize + 1;
                let u = v + cur[xi as usize];
                let paper = u >= p[4];
                let e = u - if paper { 1.0 } else { 0.0 };
                cur[(xi + dir) as usize] += e * p[0];
                next[(xi - dir) as usize] += e * p[1];
                next[xi as usize] += e * p[2];
                next[(xi + dir) as usize] += e * p[3];
                out[y * w + x] = paper as u8;
            }
            std::mem::swap(&mut cur, &mut next);
            next.fill(0.0);
        }
        out
    }

    fn run(w: usize, h: usize, tone: &[f32], rows: &[Params], serpentine: bool) -> Vec<u8> {
        let params: Vec<Params> = tone.iter().map(|&v| params_at(rows, v)).collect();
        let mut out = Vec::with_capacity(w * h);
        diffuse_rows(
            w,
            h,
            serpentine,
            |y, buf| {
                buf.clear();
                buf.extend((y * w..(y + 1) * w).map(|i| i as u32));
            },
            |i| (tone[i as usize], &params[i as usize]),
            |_, row| out.extend_from_slice(row),
        );
        out
    }

    #[test]
    fn register_loop_places_the_reference_dots() {
        let rows = parse_table(TABLE_TEXT).unwrap();
        for (w, h) in [(1, 5), (2, 3), (61, 37)] {
            // A ramp with a ripple: every row of the table, both halves of the tone scale.
            let tone: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    (0.5 + 0.49 * (fm::sin(x * 0.37 + y * 0.11))).clamp(0.0, 1.0)
                })
                .collect();
            for serpentine in [true, false] {
                assert_eq!(
                    run(w, h, &tone, &rows, serpentine),
                    reference(w, h, &tone, &rows, serpentine),
                    "{w}x{h} serpentine {serpentine}"
                );
            }
        }
    }

    #[test]
    fn flats_keep_their_mean() {
        let rows = parse_table(TABLE_TEXT).unwrap();
        let n = 128;
        for k in 1..16 {
            let g = k as f32 / 16.0;
            let out = run(n, n, &vec![g; n * n], &rows, true);
            let mean = out.iter().map(|&l| l as f64).sum::<f64>() / (n * n) as f64;
            // What is left in the last row's error buffer is under one dot a row.
            assert!(
                (mean - g as f64).abs() < 1.0 / n as f64,
                "grey {g}: mean {mean}"
            );
        }
    }
}
