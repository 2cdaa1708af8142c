//! Training of the tone-dependent error diffusion table (`halftone train tded`): the
//! coordinate search on flat patches and the validation on synthetic photos that remade
//! `kernels/tded.txt` (see the module documentation of
//! [`crate::method::diffusion::tded`]).

use rayon::prelude::*;

use crate::method::diffusion::tded::{
    diffuse_rows, Params, Tded, FLOYD_STEINBERG, ROWS, TRAIN_MARGINS, TRAIN_SIZE, VALIDATION_SIZE,
};
use crate::method::diffusion::DiffuseOptions;
use crate::quality::{compare_halftone, filtered_mse, Viewing};
use crate::raster::Image;

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
            let h = crate::pipeline::halftone_image(
                img,
                &m,
                crate::raster::ColorMode::Gray,
                &Default::default(),
            )
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
