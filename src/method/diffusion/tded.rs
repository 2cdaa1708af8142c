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
use crate::quality::{compare_halftone, filtered_mse, Viewing};
use crate::raster::{pack_row, Halftone, Image, PlaneRef, Planes};
use rayon::prelude::*;

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
                "--kernel tded works with bilevel output (--levels 2)".into(),
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
fn diffuse_rows<'p>(
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

/// The training loss of `params` on a flat of grey `g` (see the module documentation): the
/// flat is diffused over [`TRAIN_SIZE`] + `margin` pixels a side, the first `margin` rows
/// and columns (where error diffusion starts up) are dropped, and the
/// rest is scored exactly as `halftone compare` scores a photo ([`filtered_mse`]: the
/// Näsänen filter at 300 dpi and 12 inches, applied in the frequency domain over the patch
/// mirrored out at its edges).
pub fn flat_loss(params: &Params, g: f32, margin: usize) -> f64 {
    let (s, m) = (TRAIN_SIZE, margin);
    let n = s + m;
    let mut ht = vec![0f32; s * s];
    diffuse_rows(
        n,
        n,
        true,
        |_, buf| {
            buf.clear();
            buf.resize(n, 0);
        },
        |_| (g, params),
        |y, row| {
            if y >= m {
                for (o, &l) in ht[(y - m) * s..(y - m + 1) * s].iter_mut().zip(&row[m..]) {
                    *o = l as f32;
                }
            }
        },
    );
    let view = Viewing::default();
    filtered_mse(&vec![g; s * s], &ht, s, s, view.margin(), &|f| {
        view.hvs_gain(f)
    })
}

/// Trains row `k` (grey k/64) by coordinate search from `start` (module docs). The loss is
/// averaged over the greys k/64 and k/64 ± 1/256, so that a row also serves the greys
/// between rows and is not fitted to one patch's accidents.
pub fn train_row(k: usize, iterations: usize, start: Params, margin: usize) -> Params {
    if k == 0 {
        return FLOYD_STEINBERG;
    }
    let g = k as f32 / 64.0;
    let loss = |p: &Params| {
        // The three patches in parallel, summed in order: the same bits on any thread count.
        let l: Vec<f64> = (-1..=1)
            .into_par_iter()
            .map(|i| {
                let gg = (g + i as f32 / 256.0).clamp(1.0 / 256.0, 0.5);
                flat_loss(p, gg, margin)
            })
            .collect();
        l.iter().sum::<f64>()
    };
    let mut p = start;
    let mut best = loss(&p);
    let mut step = 0.04f32;
    for _ in 0..iterations {
        let mut improved = false;
        for j in 0..5 {
            for sign in [1.0f32, -1.0] {
                let mut q = p;
                q[j] += sign * step;
                if j < 4 {
                    if q[j] < 0.0 {
                        continue;
                    }
                    let s: f32 = q[..4].iter().sum();
                    for w in &mut q[..4] {
                        *w /= s;
                    }
                } else if !(0.3..=0.7).contains(&q[4]) {
                    continue;
                }
                let l = loss(&q);
                if l < best {
                    best = l;
                    p = q;
                    improved = true;
                    break;
                }
            }
        }
        if !improved {
            step *= 0.5;
            if step < 0.002 {
                break;
            }
        }
    }
    // Round to the digits the table file keeps, so retraining reproduces the file exactly.
    p.map(|v| (v * 1e6).round() / 1e6)
}

/// A training run's result: the smoothed table, the margin it was trained with, and its mean
/// HVS-PSNR on the validation images.
#[derive(Clone, Debug)]
pub struct Trained {
    /// The table, smoothed.
    pub rows: Vec<Params>,
    /// The run's [`TRAIN_MARGINS`] entry.
    pub margin: usize,
    /// Mean HVS-PSNR (dB) of the table on [`validation_images`].
    pub validation_db: f64,
}

/// Trains one table for each of [`TRAIN_MARGINS`] (every row in order of grey, each from
/// the row before, then smoothed across greys, ¼ ½ ¼) and returns every run, the one to
/// ship (the best on [`validation_images`]; the first of equals) first. The search on flats
/// is chaotic: the runs' scores on photos differ by up to 1.3 dB, and the validation images
/// rank them as the photos do (docs/accuracy.md).
pub fn train(iterations: usize) -> Vec<Trained> {
    let images = validation_images();
    let mut runs: Vec<Trained> = TRAIN_MARGINS
        .iter()
        .map(|&margin| {
            let rows = smooth(&train_first(ROWS, iterations, margin));
            let validation_db = validation_score(&rows, &images);
            Trained {
                rows,
                margin,
                validation_db,
            }
        })
        .collect();
    // A stable sort: of equal scores the earlier margin stays first.
    runs.sort_by(|a, b| b.validation_db.total_cmp(&a.validation_db));
    runs
}

/// The validation set, synthetic like the training set: a horizontal ramp from ink to
/// paper and four smooth random fields (each a sum of twelve plane waves of random
/// direction, period 25 pixels and up, phase and amplitude, from a fixed-seed xorshift
/// generator, stretched to the full tone range), [`VALIDATION_SIZE`]² 8-bit sRGB greys.
pub fn validation_images() -> Vec<Image> {
    let n = VALIDATION_SIZE;
    let mut images = vec![Image::gray8(
        n,
        n,
        (0..n * n)
            .map(|i| ((i % n) * 255 / (n - 1)) as u8)
            .collect(),
    )];
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..4 {
        let waves: Vec<[f64; 4]> = (0..12)
            .map(|_| {
                let tau = std::f64::consts::TAU;
                let (f, a) = (0.04 * uniform(), tau * uniform());
                [
                    f * a.cos(),
                    f * a.sin(),
                    tau * uniform(),
                    0.3 + 0.7 * uniform(),
                ]
            })
            .collect();
        let field: Vec<f64> = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                waves
                    .iter()
                    .map(|w| w[3] * (std::f64::consts::TAU * (w[0] * x + w[1] * y) + w[2]).sin())
                    .sum()
            })
            .collect();
        let lo = field.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = field.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        images.push(Image::gray8(
            n,
            n,
            field
                .iter()
                .map(|&v| ((v - lo) / (hi - lo) * 255.0).round() as u8)
                .collect(),
        ));
    }
    images
}

/// Mean HVS-PSNR (dB) of a table on `images`, scored as `halftone compare` scores.
pub fn validation_score(rows: &[Params], images: &[Image]) -> f64 {
    let m =
        Tded::with_table(DiffuseOptions::default(), rows.to_vec()).expect("a table of ROWS rows");
    let view = Viewing::default();
    images
        .iter()
        .map(|img| {
            let h = crate::halftone_image(img, &m, crate::ColorMode::Gray, &Default::default())
                .expect("a grey image halftones");
            compare_halftone(img, &h, &view)
                .expect("same sizes")
                .hvs_psnr_db
        })
        .sum::<f64>()
        / images.len() as f64
}

/// Smooths a table across greys (¼ ½ ¼, the end rows repeated), weights renormalised to
/// sum 1, rounded to the file's digits. Row k depends on rows k − 1..=k + 1 only.
pub fn smooth(rows: &[Params]) -> Vec<Params> {
    let n = rows.len();
    (0..n)
        .map(|k| {
            let (a, b, c) = (rows[k.saturating_sub(1)], rows[k], rows[(k + 1).min(n - 1)]);
            let mut q: Params = std::array::from_fn(|j| (a[j] + 2.0 * b[j] + c[j]) / 4.0);
            let s: f32 = q[..4].iter().sum();
            for w in &mut q[..4] {
                *w /= s;
            }
            q.map(|v| (v * 1e6).round() / 1e6)
        })
        .collect()
}

/// The first `n` rows of the run of [`train`] with `margin`, before smoothing: each grey
/// from the row before, the first from Floyd–Steinberg.
pub fn train_first(n: usize, iterations: usize, margin: usize) -> Vec<Params> {
    let mut rows: Vec<Params> = Vec::with_capacity(n);
    for k in 0..n.min(ROWS) {
        let start = rows.last().copied().unwrap_or(FLOYD_STEINBERG);
        rows.push(train_row(k, iterations, start, margin));
    }
    rows
}

/// Iterations of the shipped training run.
pub const TRAIN_ITERATIONS: usize = 40;

#[cfg(test)]
mod tests {
    use super::*;

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
                    (0.5 + 0.49 * ((x * 0.37 + y * 0.11).sin())).clamp(0.0, 1.0)
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
