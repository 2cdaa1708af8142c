//! Automatic palettes (`palette = "auto:N"`): N colours made from the image itself, for
//! displays that can show any colours but only a few at a time.
//!
//! The road, every step deterministic (the same pixels give the same bytes whatever the
//! thread count):
//!
//! 1. **Samples.** At most [`MAX_SAMPLES`] pixels: all of a small image; of a larger one, one
//!    pixel in every run of `stride` pixels, at a fixed pseudo-random place inside the run
//!    (a hash of the run's number), so a stride that divides the image's width does not
//!    sample the same columns on every row.
//! 2. **Bins.** Each sample's Oklab colour (Björn Ottosson, 2020, from linear light through
//!    [`crate::color::oklab_of_linear`]) falls into a cell of a grid (ΔL = 1/96, Δa = Δb =
//!    1/192, near Oklab's just-noticeable difference); a bin holds its samples' count and
//!    their exact mean (summed in `f64`). A photo gives some tens of thousands of bins, a
//!    graphic a handful: the later steps work on bins, weighted by their counts.
//! 3. **Median cut, variance-splitting** (after Wu, 1991): start with one box of all bins;
//!    repeatedly take the box of largest weighted squared error, and cut it across its axis
//!    of largest variance where the two halves' summed squared error is least; stop at N
//!    boxes or when no box holds two different bins. The boxes' means are the first
//!    centres.
//! 4. **k-means** (Lloyd) in Oklab on the weighted bins: every bin to its nearest centre
//!    (searched outward in L from the nearest centre by lightness, stopping when the
//!    lightness gap alone exceeds the best distance), every centre to its bins' mean, until
//!    no bin changes its centre or after [`MAX_ITERATIONS`] rounds. A centre that loses all
//!    its bins stays where it was.
//! 5. **Colours.** Each centre back to linear RGB, clipped to the gamut and encoded as sRGB
//!    8-bit; equal colours are merged; sorted by Oklab lightness, then a and b, then the
//!    colour value. An image of fewer than N distinct colours gives those colours (at least
//!    two: a one-colour image gets black or white beside its colour, whichever is farther).

use palette::{IntoColor, LinSrgb, Oklab};
use rayon::prelude::*;

use crate::color::oklab_of_linear;
use crate::error::{Error, Result};
use crate::tone::linear_to_srgb8;

/// The most pixels the palette is computed from; larger images are sampled (step 1).
pub const MAX_SAMPLES: usize = 1 << 18;

/// The most rounds of k-means.
pub const MAX_ITERATIONS: usize = 24;

/// Grid cells a unit of Oklab L, and of a and b (step 2).
const CELLS_L: f32 = 96.0;
const CELLS_AB: f32 = 192.0;

/// A palette of at most `n` (2..=256) sRGB 8-bit colours for `pixels` (linear-light RGB,
/// any order; values outside 0..1 are clipped), sorted by lightness. See the module's
/// documentation for the method. Errors name `palette`: `n` outside 2..=256, or no pixels.
pub fn auto_palette(pixels: &[[f32; 3]], n: usize) -> Result<Vec<[u8; 3]>> {
    let bad = |msg: String| Error::Option {
        field: "palette",
        value: format!("auto:{n}"),
        msg,
    };
    if !(2..=256).contains(&n) {
        return Err(bad("an automatic palette has 2 to 256 colours".into()));
    }
    if pixels.is_empty() {
        return Err(bad("the image has no pixels to make a palette from".into()));
    }
    let samples = sample_oklab(pixels);
    let bins = bin(samples);
    let mut centres = median_cut(&bins, n);
    kmeans(&bins, &mut centres);
    Ok(finish(&centres))
}

/// One grid cell's samples: their mean Oklab colour and their count.
#[derive(Clone, Copy, Debug)]
struct Bin {
    lab: [f64; 3],
    weight: f64,
}

/// A 64-bit mix of `x` (splitmix64's finaliser).
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Step 1 and the colour conversion: the sampled pixels in Oklab, in sample order.
fn sample_oklab(pixels: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let len = pixels.len();
    let stride = len.div_ceil(MAX_SAMPLES).max(1);
    let count = len.div_ceil(stride);
    let lab = |p: [f32; 3]| oklab_of_linear(p.map(|v| if v > 0.0 { v.min(1.0) } else { 0.0 }));
    (0..count)
        .into_par_iter()
        .with_min_len(4096)
        .map(|j| {
            let start = j * stride;
            let run = stride.min(len - start);
            let at = if run > 1 {
                start + (mix(j as u64) % run as u64) as usize
            } else {
                start
            };
            lab(pixels[at])
        })
        .collect()
}

/// Step 2: samples into grid cells, in the order of the cells.
fn bin(samples: Vec<[f32; 3]>) -> Vec<Bin> {
    let cell =
        |v: f32, lo: f32, cells: f32, max: u32| ((v - lo) * cells).clamp(0.0, max as f32) as u32;
    let mut keyed: Vec<(u32, [f32; 3])> = samples
        .into_iter()
        .map(|s| {
            let l = cell(s[0], 0.0, CELLS_L, 96);
            let a = cell(s[1], -0.5, CELLS_AB, 192);
            let b = cell(s[2], -0.5, CELLS_AB, 192);
            ((l * 193 + a) * 193 + b, s)
        })
        .collect();
    // Stable: equal keys keep the sample order, so every sum is made in one order.
    keyed.sort_by_key(|&(k, _)| k);
    let mut bins: Vec<Bin> = Vec::new();
    let mut i = 0;
    while i < keyed.len() {
        let key = keyed[i].0;
        let mut sum = [0f64; 3];
        let mut n = 0usize;
        while i < keyed.len() && keyed[i].0 == key {
            for (sc, &v) in sum.iter_mut().zip(&keyed[i].1) {
                *sc += v as f64;
            }
            n += 1;
            i += 1;
        }
        bins.push(Bin {
            lab: sum.map(|s| s / n as f64),
            weight: n as f64,
        });
    }
    bins
}

/// Adds a bin's weighted colour to `s` and its weighted squared colour to `q`.
#[inline]
fn accumulate(b: &Bin, s: &mut [f64; 3], q: &mut f64) {
    for (sc, &v) in s.iter_mut().zip(&b.lab) {
        *sc += b.weight * v;
        *q += b.weight * v * v;
    }
}

/// The weighted mean and the weighted squared error about it of `items`' bins.
fn moments(bins: &[Bin], items: &[u32]) -> ([f64; 3], f64) {
    let mut w = 0.0;
    let mut s = [0f64; 3];
    let mut q = 0.0;
    for &i in items {
        let b = &bins[i as usize];
        w += b.weight;
        accumulate(b, &mut s, &mut q);
    }
    if w == 0.0 {
        return ([0.0; 3], 0.0);
    }
    let mean = s.map(|v| v / w);
    let sse = q - (s[0] * mean[0] + s[1] * mean[1] + s[2] * mean[2]);
    (mean, sse.max(0.0))
}

/// Step 3: at most `n` boxes of bins cut by variance; their means.
fn median_cut(bins: &[Bin], n: usize) -> Vec<[f64; 3]> {
    struct Cut {
        items: Vec<u32>,
        sse: f64,
    }
    let all: Vec<u32> = (0..bins.len() as u32).collect();
    let sse = moments(bins, &all).1;
    let mut boxes = vec![Cut { items: all, sse }];
    while boxes.len() < n {
        // The box of largest squared error that can be cut (the first of equals).
        let Some(k) = (0..boxes.len())
            .filter(|&k| boxes[k].items.len() >= 2 && boxes[k].sse > 0.0)
            .max_by(|&a, &b| boxes[a].sse.total_cmp(&boxes[b].sse).then(b.cmp(&a)))
        else {
            break;
        };
        let mut items = std::mem::take(&mut boxes[k].items);
        // The axis of largest variance.
        let (mean, _) = moments(bins, &items);
        let mut var = [0f64; 3];
        for &i in &items {
            let b = &bins[i as usize];
            for c in 0..3 {
                var[c] += b.weight * (b.lab[c] - mean[c]).powi(2);
            }
        }
        let axis = (0..3)
            .max_by(|&a, &b| var[a].total_cmp(&var[b]).then(b.cmp(&a)))
            .unwrap_or(0);
        items.sort_by(|&a, &b| {
            bins[a as usize].lab[axis]
                .total_cmp(&bins[b as usize].lab[axis])
                .then(a.cmp(&b))
        });
        // The cut that leaves the least squared error: prefix sums along the sorted bins.
        let len = items.len();
        let (mut tw, mut ts, mut tq) = (0.0, [0f64; 3], 0.0);
        for &i in &items {
            let b = &bins[i as usize];
            tw += b.weight;
            accumulate(b, &mut ts, &mut tq);
        }
        let sse_of = |w: f64, s: [f64; 3], q: f64| {
            if w > 0.0 {
                (q - (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) / w).max(0.0)
            } else {
                0.0
            }
        };
        let (mut lw, mut ls, mut lq) = (0.0, [0f64; 3], 0.0);
        let (mut best, mut best_sse) = (1, f64::INFINITY);
        for (cut, &i) in items.iter().enumerate().take(len - 1) {
            let b = &bins[i as usize];
            lw += b.weight;
            accumulate(b, &mut ls, &mut lq);
            // Bins with the same value on the axis stay together when they can.
            if bins[items[cut + 1] as usize].lab[axis] == b.lab[axis] {
                continue;
            }
            let rs = [ts[0] - ls[0], ts[1] - ls[1], ts[2] - ls[2]];
            let e = sse_of(lw, ls, lq) + sse_of(tw - lw, rs, tq - lq);
            if e < best_sse {
                best_sse = e;
                best = cut + 1;
            }
        }
        let right = items.split_off(best);
        let (left_sse, right_sse) = (moments(bins, &items).1, moments(bins, &right).1);
        boxes[k] = Cut {
            items,
            sse: left_sse,
        };
        boxes.push(Cut {
            items: right,
            sse: right_sse,
        });
    }
    boxes.iter().map(|b| moments(bins, &b.items).0).collect()
}

/// The index of the centre nearest to `p`; `order` lists the centres by lightness and
/// `ls` their lightness in that order. Equal distances go to the earlier centre in `order`.
fn nearest(p: [f64; 3], centres: &[[f64; 3]], order: &[usize], ls: &[f64]) -> usize {
    let d2 = |c: &[f64; 3]| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2);
    let start = ls.partition_point(|&l| l < p[0]).min(order.len() - 1);
    let (mut best, mut best_d) = (order[start], d2(&centres[order[start]]));
    let consider = |k: usize, best: &mut usize, best_d: &mut f64| -> bool {
        let gap = (ls[k] - p[0]).powi(2);
        if gap > *best_d {
            return false;
        }
        let d = d2(&centres[order[k]]);
        if d < *best_d || (d == *best_d && order[k] < *best) {
            *best = order[k];
            *best_d = d;
        }
        true
    };
    for k in (start + 1)..order.len() {
        if !consider(k, &mut best, &mut best_d) {
            break;
        }
    }
    for k in (0..start).rev() {
        if !consider(k, &mut best, &mut best_d) {
            break;
        }
    }
    best
}

/// Step 4: Lloyd's iterations on the weighted bins.
fn kmeans(bins: &[Bin], centres: &mut [[f64; 3]]) {
    let mut assigned: Vec<u32> = vec![u32::MAX; bins.len()];
    for _ in 0..MAX_ITERATIONS {
        let mut order: Vec<usize> = (0..centres.len()).collect();
        order.sort_by(|&a, &b| centres[a][0].total_cmp(&centres[b][0]).then(a.cmp(&b)));
        let ls: Vec<f64> = order.iter().map(|&k| centres[k][0]).collect();
        let next: Vec<u32> = bins
            .par_iter()
            .with_min_len(1024)
            .map(|b| nearest(b.lab, centres, &order, &ls) as u32)
            .collect();
        if next == assigned {
            break;
        }
        assigned = next;
        // Sums in bin order, one thread: the same every run.
        let mut sum = vec![([0f64; 3], 0f64); centres.len()];
        for (b, &k) in bins.iter().zip(&assigned) {
            let s = &mut sum[k as usize];
            for c in 0..3 {
                s.0[c] += b.weight * b.lab[c];
            }
            s.1 += b.weight;
        }
        for (c, (s, w)) in centres.iter_mut().zip(sum) {
            if w > 0.0 {
                *c = s.map(|v| v / w);
            }
        }
    }
}

/// The sRGB 8-bit colour of an Oklab centre, clipped to the gamut.
fn srgb_of(lab: [f64; 3]) -> [u8; 3] {
    let lin: LinSrgb<f32> = Oklab::new(lab[0] as f32, lab[1] as f32, lab[2] as f32).into_color();
    [lin.red, lin.green, lin.blue].map(|v| linear_to_srgb8(v.clamp(0.0, 1.0) as f64))
}

/// Step 5: colours, merged, sorted; at least two.
fn finish(centres: &[[f64; 3]]) -> Vec<[u8; 3]> {
    let mut colours: Vec<[u8; 3]> = centres.iter().map(|&c| srgb_of(c)).collect();
    colours.sort_unstable();
    colours.dedup();
    if colours.len() == 1 {
        let c = colours[0];
        let light = lightness(c) > 0.5;
        colours.push(if light { [0; 3] } else { [255; 3] });
        colours.dedup();
    }
    let key = |c: &[u8; 3]| {
        oklab_of_linear(c.map(|v| crate::tone::srgb_to_linear(v as f64 / 255.0) as f32))
    };
    colours.sort_by(|a, b| {
        let (ka, kb) = (key(a), key(b));
        ka[0]
            .total_cmp(&kb[0])
            .then(ka[1].total_cmp(&kb[1]))
            .then(ka[2].total_cmp(&kb[2]))
            .then(a.cmp(b))
    });
    colours
}

/// Oklab lightness of an sRGB 8-bit colour.
fn lightness(c: [u8; 3]) -> f32 {
    oklab_of_linear(c.map(|v| crate::tone::srgb_to_linear(v as f64 / 255.0) as f32))[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tone::srgb_to_linear;

    fn lin(c: [u8; 3]) -> [f32; 3] {
        c.map(|v| srgb_to_linear(v as f64 / 255.0) as f32)
    }

    /// A deterministic generator for test images.
    fn xorshift(mut s: u64) -> impl FnMut() -> u64 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    /// A photo-like image: smooth hue and lightness ramps with grain.
    fn photo(w: usize, h: usize) -> Vec<[f32; 3]> {
        let mut r = xorshift(7);
        let mut px = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let hue = x as f64 / w as f64 * 6.0;
                let light = y as f64 / h as f64;
                let f = |k: f64| (((hue + k) % 6.0 - 3.0).abs() - 1.0).clamp(0.0, 1.0);
                let c = [f(0.0), f(4.0), f(2.0)].map(|c| {
                    let v = c * (0.2 + 0.8 * light);
                    ((v * 255.0) + (r() % 9) as f64 - 4.0).clamp(0.0, 255.0) as u8
                });
                px.push(lin(c));
            }
        }
        px
    }

    #[test]
    fn four_colours_come_back_within_one_code() {
        let want = [[200, 30, 40], [20, 90, 200], [240, 230, 60], [15, 15, 20]];
        let mut r = xorshift(3);
        // Unequal shares, shuffled.
        let px: Vec<[f32; 3]> = (0..5000)
            .map(|_| lin(want[[0, 0, 1, 2, 2, 2, 3][(r() % 7) as usize]]))
            .collect();
        for n in [4, 5, 16, 256] {
            let got = auto_palette(&px, n).unwrap();
            // More colours asked for than there are: the four, no more.
            assert_eq!(got.len(), 4, "auto:{n}: {got:?}");
            for w in want {
                assert!(
                    got.iter()
                        .any(|g| (0..3).all(|c| (g[c] as i32 - w[c] as i32).abs() <= 1)),
                    "auto:{n}: {w:?} missing from {got:?}"
                );
            }
            // Sorted by lightness: the near-black first, the yellow last.
            assert!(got[0][0] < 30 && got[3][1] > 200, "{got:?}");
        }
    }

    #[test]
    fn one_colour_gets_a_partner_and_two_colours_stay_two() {
        let px = vec![lin([90, 90, 90]); 100];
        let got = auto_palette(&px, 8).unwrap();
        assert_eq!(got, [[90, 90, 90], [255, 255, 255]]);
        let px = vec![lin([230, 230, 230]); 100];
        assert_eq!(auto_palette(&px, 2).unwrap(), [[0, 0, 0], [230, 230, 230]]);
    }

    #[test]
    fn deterministic_across_runs_and_thread_counts() {
        // Larger than MAX_SAMPLES: the sampled path.
        let px = photo(700, 400);
        assert!(px.len() > MAX_SAMPLES);
        let run = |threads: usize, n: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| auto_palette(&px, n).unwrap())
        };
        for n in [2, 16, 64] {
            let a = run(1, n);
            assert_eq!(a.len(), n, "a photo has more than {n} colours");
            assert_eq!(a, run(3, n), "auto:{n}");
            assert_eq!(a, run(1, n), "auto:{n}");
            let l: Vec<f32> = a.iter().map(|&c| lightness(c)).collect();
            assert!(l.windows(2).all(|w| w[0] <= w[1]), "sorted: {l:?}");
        }
    }

    #[test]
    fn a_palette_fits_the_image_better_than_a_fixed_one() {
        // k-means' error (mean squared Oklab distance to the nearest colour) falls with N
        // and is below that of the median cut it starts from.
        let px = photo(300, 200);
        let samples = sample_oklab(&px);
        let bins = bin(samples.clone());
        let err = |centres: &[[f64; 3]]| {
            let mut order: Vec<usize> = (0..centres.len()).collect();
            order.sort_by(|&a, &b| centres[a][0].total_cmp(&centres[b][0]));
            let ls: Vec<f64> = order.iter().map(|&k| centres[k][0]).collect();
            samples
                .iter()
                .map(|s| {
                    let p = s.map(|v| v as f64);
                    let c = centres[nearest(p, centres, &order, &ls)];
                    (0..3).map(|i| (p[i] - c[i]).powi(2)).sum::<f64>()
                })
                .sum::<f64>()
                / samples.len() as f64
        };
        let mut last = f64::INFINITY;
        for n in [4, 8, 16, 32] {
            let start = median_cut(&bins, n);
            let mut tuned = start.clone();
            kmeans(&bins, &mut tuned);
            let (e0, e1) = (err(&start), err(&tuned));
            assert!(
                e1 <= e0 * 1.0001,
                "auto:{n}: k-means {e1} > median cut {e0}"
            );
            assert!(e1 < last, "auto:{n}: {e1} not below {last}");
            last = e1;
        }
    }

    #[test]
    fn nearest_with_pruning_is_the_exhaustive_nearest() {
        let mut r = xorshift(11);
        let mut f = || (r() % 10_000) as f64 / 10_000.0 - 0.3;
        let centres: Vec<[f64; 3]> = (0..40).map(|_| [f() + 0.3, f(), f()]).collect();
        let mut order: Vec<usize> = (0..centres.len()).collect();
        order.sort_by(|&a, &b| centres[a][0].total_cmp(&centres[b][0]).then(a.cmp(&b)));
        let ls: Vec<f64> = order.iter().map(|&k| centres[k][0]).collect();
        for _ in 0..2000 {
            let p = [f() + 0.3, f(), f()];
            let d2 = |c: &[f64; 3]| (0..3).map(|i| (p[i] - c[i]).powi(2)).sum::<f64>();
            let want = (0..centres.len())
                .min_by(|&a, &b| d2(&centres[a]).total_cmp(&d2(&centres[b])))
                .unwrap();
            let got = nearest(p, &centres, &order, &ls);
            assert_eq!(d2(&centres[got]), d2(&centres[want]));
        }
    }

    #[test]
    fn bad_sizes_name_the_palette_field() {
        let px = vec![[0.5f32; 3]; 10];
        for n in [0, 1, 257] {
            let e = auto_palette(&px, n).unwrap_err();
            assert!(
                matches!(
                    e,
                    Error::Option {
                        field: "palette",
                        ..
                    }
                ),
                "{n}: {e}"
            );
        }
        let e = auto_palette(&[], 4).unwrap_err().to_string();
        assert_eq!(
            e,
            "palette auto:4: the image has no pixels to make a palette from"
        );
    }
}
