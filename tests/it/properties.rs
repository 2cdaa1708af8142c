//! Property tests across methods and options: any size from 1×1, any levels, any palette
//! and random valid options never panic and give a halftone of the promised shape; tone is
//! kept on flat greys; the output is the same for any thread count. The methods include
//! the whole-image searches (DBS, with and without a printer model), green noise,
//! tone-dependent diffusion and AM screens at any frequency, angle and spot.

use proptest::prelude::*;

use halftone::color::Palette;
use halftone::mask::screen::{Screen, ScreenSpec, Spot};
use halftone::method::dbs::{Dbs, DbsOptions};
use halftone::method::diffusion::hysteresis::Hysteresis;
use halftone::method::diffusion::tded::Tded;
use halftone::method::diffusion::{Diffuse, DiffuseOptions, KERNELS};
use halftone::method::ordered::Ordered;
use halftone::method::pattern::{Cell, Pattern};
use halftone::method::screen::ScreenMethod;
use halftone::method::threshold::Threshold;
use halftone::printer_model::PrinterModel;
use halftone::raster::ColorKind;
use halftone::tone::{srgb_to_linear, Encoding};
use halftone::{halftone_image, ColorMode, Halftone, Image, Mask, Method, ToneOptions};

/// Masks with distinct shapes: 2×2 to 16×16, square and not, dispersed and clustered.
const MASKS: &[&str] = &[
    "seed-2x2",
    "seed-3x3",
    "bayer-4",
    "bayer-8",
    "cluster-6",
    "dot45-8",
    "bayer-16",
];

/// A method from a few choices, as the CLI would build it.
#[derive(Clone, Debug)]
enum Choice {
    Threshold(f32),
    Ordered(usize),
    Pattern(usize, bool),
    Diffuse {
        kernel: usize,
        serpentine: bool,
        strength: f32,
        seed: u64,
    },
    /// DBS with a pass cap and, for bilevel output, optionally a dot-overlap printer model.
    Dbs {
        passes: u32,
        dot_ratio: Option<f64>,
    },
    Hysteresis(f32),
    Tded(bool),
    /// An AM screen: lpi, angle, spot (index into `Spot::ALL`), dpi.
    Screen(f64, f64, usize, f64),
}

fn choice() -> impl Strategy<Value = Choice> {
    prop_oneof![
        (0.0f32..=1.0).prop_map(Choice::Threshold),
        (0..MASKS.len()).prop_map(Choice::Ordered),
        (0..MASKS.len(), any::<bool>()).prop_map(|(m, e)| Choice::Pattern(m, e)),
        (0..KERNELS.len(), any::<bool>(), 0.0f32..=1.0, any::<u64>()).prop_map(
            |(kernel, serpentine, strength, seed)| Choice::Diffuse {
                kernel,
                serpentine,
                strength,
                seed
            }
        ),
        (1u32..=6, prop::option::of(1.0f64..=1.414))
            .prop_map(|(passes, dot_ratio)| Choice::Dbs { passes, dot_ratio }),
        (0.0f32..=3.0).prop_map(Choice::Hysteresis),
        any::<bool>().prop_map(Choice::Tded),
        (
            10.0f64..200.0,
            -360.0f64..360.0,
            0..Spot::ALL.len(),
            prop_oneof![Just(72.0), Just(300.0), Just(600.0)]
        )
            .prop_map(|(lpi, angle, spot, dpi)| Choice::Screen(lpi, angle, spot, dpi)),
    ]
}

/// The method, or `None` where the combination is refused up front with an error (tded
/// and green noise take bilevel output only).
fn build(c: &Choice, levels: u16) -> Option<Box<dyn Method>> {
    Some(match *c {
        Choice::Threshold(t) => Box::new(Threshold::new(t, levels).unwrap()),
        Choice::Ordered(m) => {
            Box::new(Ordered::new(Mask::builtin(MASKS[m]).unwrap(), levels).unwrap())
        }
        Choice::Pattern(m, expand) => {
            let cell = if expand { Cell::Expand } else { Cell::Fit };
            Box::new(Pattern::new(Mask::builtin(MASKS[m]).unwrap(), levels, cell).unwrap())
        }
        Choice::Diffuse {
            kernel,
            serpentine,
            strength,
            seed,
        } => Box::new(
            Diffuse::new(
                KERNELS[kernel],
                DiffuseOptions {
                    levels,
                    serpentine,
                    strength,
                    seed,
                },
            )
            .unwrap(),
        ),
        Choice::Dbs { passes, dot_ratio } => {
            let options = match dot_ratio {
                Some(r) if levels == 2 => {
                    DbsOptions::for_printer(PrinterModel::dot_overlap(r).unwrap())
                }
                _ => DbsOptions::default(),
            };
            Box::new(
                Dbs::new(DbsOptions {
                    levels,
                    passes,
                    ..options
                })
                .unwrap(),
            )
        }
        Choice::Hysteresis(gain) => {
            let options = DiffuseOptions {
                levels,
                serpentine: true,
                strength: 1.0,
                seed: 0,
            };
            let h = Hysteresis::new("floyd-steinberg", options, gain);
            if levels != 2 {
                assert!(h.is_err());
                return None;
            }
            Box::new(h.unwrap())
        }
        Choice::Tded(serpentine) => {
            let t = Tded::new(DiffuseOptions {
                levels,
                serpentine,
                strength: 1.0,
                seed: 0,
            });
            if levels != 2 {
                assert!(t.is_err());
                return None;
            }
            Box::new(t.unwrap())
        }
        Choice::Screen(lpi, angle, spot, dpi) => {
            let lpi = lpi.min(dpi / 2.0);
            let spec = ScreenSpec {
                dpi,
                lpi,
                angle,
                spot: Spot::ALL[spot],
            };
            Box::new(ScreenMethod::new(Screen::new(spec).unwrap(), levels).unwrap())
        }
    })
}

/// A random image: grey or RGB, 8 or 16 bits, any size from 1×1.
fn image() -> impl Strategy<Value = Image> {
    sized_image(1..=33, 1..=29)
}

/// A random image as [`image`] makes, of a width and height in the ranges given.
fn sized_image(
    widths: std::ops::RangeInclusive<usize>,
    heights: std::ops::RangeInclusive<usize>,
) -> impl Strategy<Value = Image> {
    (widths, heights, any::<bool>(), any::<bool>(), any::<u64>()).prop_map(
        |(w, h, rgb, sixteen, seed)| {
            let channels = if rgb { 3 } else { 1 };
            let mut x = seed | 1;
            let mut next = move || {
                // xorshift64: any sequence will do, it only has to be reproducible.
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x
            };
            let planes = (0..channels)
                .map(|_| {
                    if sixteen {
                        halftone::raster::Samples::U16((0..w * h).map(|_| next() as u16).collect())
                    } else {
                        halftone::raster::Samples::U8((0..w * h).map(|_| next() as u8).collect())
                    }
                })
                .collect();
            Image {
                width: w,
                height: h,
                color: if rgb { ColorKind::Rgb } else { ColorKind::Gray },
                planes,
                encoding: Encoding::Srgb,
                dpi: None,
            }
        },
    )
}

fn tone() -> impl Strategy<Value = ToneOptions> {
    (any::<bool>(), 0.2f32..5.0, 0.0f32..0.49, any::<bool>()).prop_map(
        |(linearize, gamma, dot_gain, invert)| ToneOptions {
            linearize,
            gamma,
            dot_gain,
            invert,
        },
    )
}

/// Every sample of `h` is a level below `h.levels`.
fn levels_in_range(h: &Halftone) -> bool {
    let mut row = vec![0u8; h.width];
    (0..h.channels()).all(|c| {
        (0..h.height).all(|y| {
            h.unpack_row(c, y, &mut row);
            row.iter().all(|&l| (l as u16) < h.levels)
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 192, ..ProptestConfig::default() })]

    #[test]
    fn any_method_size_levels_and_options_give_a_valid_halftone(
        img in image(),
        c in choice(),
        levels in prop_oneof![Just(2u16), 3u16..=16, Just(256u16)],
        rgb in any::<bool>(),
        tone in tone(),
    ) {
        let Some(method) = build(&c, levels) else {
            return Ok(());
        };
        let mode = if rgb { ColorMode::Rgb } else { ColorMode::Gray };
        let h = halftone_image(&img, method.as_ref(), mode, &tone).unwrap();
        prop_assert_eq!((h.width, h.height), method.output_size(img.width, img.height));
        prop_assert_eq!(h.channels(), if rgb { 3 } else { 1 });
        prop_assert_eq!(h.levels, levels);
        prop_assert!(levels_in_range(&h));
        for p in &h.planes {
            prop_assert_eq!(p.len(), h.stride * h.height);
        }
    }

    #[test]
    fn any_palette_gives_indices_into_it(
        img in image(),
        colours in prop::collection::vec(any::<[u8; 3]>(), 2..=16),
        kernel in 0..KERNELS.len(),
        serpentine in any::<bool>(),
    ) {
        let Ok(palette) = Palette::new("random", colours.clone()) else {
            // Refused (e.g. repeated colours): an error is a valid answer, not a panic.
            return Ok(());
        };
        let n = palette.len();
        let options = DiffuseOptions { levels: 2, serpentine, strength: 1.0, seed: 7 };
        let d = Diffuse::new(KERNELS[kernel], options).unwrap().with_palette(palette);
        let h = match halftone_image(&img, &d, ColorMode::Rgb, &ToneOptions::default()) {
            Ok(h) => h,
            // The one documented refusal: Riemersma's curve takes levels, not palettes.
            Err(e) => {
                prop_assert_eq!(KERNELS[kernel], "riemersma", "{}", e);
                return Ok(());
            }
        };
        prop_assert_eq!(h.channels(), 1);
        prop_assert_eq!(h.palette.as_ref().map(|p| p.len()), Some(n));
        let mut row = vec![0u8; h.width];
        for y in 0..h.height {
            h.unpack_row(0, y, &mut row);
            prop_assert!(row.iter().all(|&i| (i as usize) < n));
        }
    }

    #[test]
    fn flat_grey_keeps_its_tone(
        code in 0u8..=255,
        kernel in prop_oneof![Just("floyd-steinberg"), Just("jarvis-judice-ninke"), Just("stucki"), Just("sierra")],
        levels in prop_oneof![Just(2u16), Just(3u16), Just(4u16)],
    ) {
        // 96×96 of one sRGB code; the mean output reflectance (levels spaced evenly in
        // light) must match the code's linear reflectance. Ordered dithering with an 8×8
        // mask places exactly round(r·64) of each 64 dots at two levels; error diffusion
        // keeps the mean within the edge effects of the first rows.
        let img = Image::gray8(96, 96, vec![code; 96 * 96]);
        let r = srgb_to_linear(code as f64 / 255.0);
        let mean = |h: &Halftone| {
            let sum: f64 = h.levels_of(0).iter().map(|&l| h.reflectance(l)).sum();
            sum / (h.width * h.height) as f64
        };
        let d = Diffuse::new(kernel, DiffuseOptions { levels, serpentine: true, strength: 1.0, seed: 0 }).unwrap();
        let h = halftone_image(&img, &d, ColorMode::Gray, &ToneOptions::default()).unwrap();
        prop_assert!((mean(&h) - r).abs() < 0.01, "{kernel}: {} against {r}", mean(&h));
        let o = Ordered::new(Mask::builtin("bayer-8").unwrap(), levels).unwrap();
        let h = halftone_image(&img, &o, ColorMode::Gray, &ToneOptions::default()).unwrap();
        let step = 1.0 / (levels - 1) as f64;
        prop_assert!((mean(&h) - r).abs() <= step / 64.0 + 1e-6, "ordered: {} against {r}", mean(&h));
    }

    #[test]
    fn output_is_the_same_for_any_thread_count(
        img in image(),
        c in choice(),
        levels in prop_oneof![Just(2u16), Just(4u16), Just(17u16)],
        rgb in any::<bool>(),
    ) {
        let Some(method) = build(&c, levels) else {
            return Ok(());
        };
        let mode = if rgb { ColorMode::Rgb } else { ColorMode::Gray };
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| halftone_image(&img, method.as_ref(), mode, &ToneOptions::default()).unwrap())
        };
        let one = run(1);
        prop_assert_eq!(&one, &run(2));
        prop_assert_eq!(&one, &run(5));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, ..ProptestConfig::default() })]

    /// DBS (plain and through a printer model) splits the image into 64-pixel tiles that
    /// run side by side: on images of more than one tile in each direction the bytes do not
    /// depend on the thread count either.
    #[test]
    fn dbs_is_the_same_for_any_thread_count_across_its_tiles(
        img in sized_image(130..=200, 129..=150),
        passes in 1u32..=3,
        dot_ratio in prop::option::of(1.0f64..=1.414),
        levels in prop_oneof![Just(2u16), Just(3u16)],
        rgb in any::<bool>(),
    ) {
        let method = build(&Choice::Dbs { passes, dot_ratio }, levels).unwrap();
        let mode = if rgb { ColorMode::Rgb } else { ColorMode::Gray };
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| halftone_image(&img, method.as_ref(), mode, &ToneOptions::default()).unwrap())
        };
        let one = run(1);
        prop_assert_eq!(&one, &run(2));
        prop_assert_eq!(&one, &run(5));
    }
}
