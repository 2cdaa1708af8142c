//! The lecture's halftone tables ("Halftone Approximations"), reproduced exactly, and tone
//! preserved at every grey level.

use std::collections::HashSet;

use halftone::method::pattern::{pattern_table, Cell, Pattern};
use halftone::tone::srgb_to_linear;
use halftone::{halftone_image, ColorMode, Image, Mask, Method, ToneOptions};

fn cells(rows: &[&str]) -> Vec<Vec<u8>> {
    rows.iter()
        .map(|r| {
            r.chars()
                .filter(|c| c.is_ascii_digit())
                .map(|c| c as u8 - b'0')
                .collect()
        })
        .collect()
}

#[test]
fn lecture_3x3_mask_gives_its_ten_patterns() {
    // Mask 8 3 7 / 5 1 2 / 4 9 6: level k lights every pixel numbered <= k.
    let expected = cells(&[
        "000 000 000",
        "000 010 000",
        "000 011 000",
        "010 011 000",
        "010 011 100",
        "010 111 100",
        "010 111 101",
        "011 111 101",
        "111 111 101",
        "111 111 111",
    ]);
    let table = pattern_table(&Mask::builtin("seed-3x3").unwrap(), 2);
    assert_eq!(table, expected);
}

#[test]
fn lecture_2x2_four_level_table_has_thirteen_patterns() {
    // The lecture's figure, levels 0..12, cells written "top row / bottom row".
    let expected = cells(&[
        "00/00", "01/00", "01/10", "11/10", "11/11", "12/11", "12/21", "22/21", "22/22", "23/22",
        "23/32", "33/32", "33/33",
    ]);
    let table = pattern_table(&Mask::builtin("seed-2x2").unwrap(), 4);
    assert_eq!(table.len(), 13);
    assert_eq!(table, expected);
}

fn constant(code: u8, w: usize, h: usize) -> Image {
    Image::gray8(w, h, vec![code; w * h])
}

fn mean_reflectance(h: &halftone::Halftone) -> f64 {
    let mut sum = 0.0;
    for c in 0..h.channels() {
        sum += h
            .levels_of(c)
            .iter()
            .map(|&l| h.reflectance(l))
            .sum::<f64>();
    }
    sum / (h.width * h.height * h.channels()) as f64
}

#[test]
fn every_grey_level_gets_the_nearest_representable_tone() {
    for (mask, levels) in [("seed-3x3", 2u16), ("seed-2x2", 2), ("seed-2x2", 4)] {
        let m = Mask::builtin(mask).unwrap();
        let tones = (m.len() * (levels as usize - 1)) as f64;
        for cell in [Cell::Expand, Cell::Fit] {
            let p = Pattern::new(m.clone(), levels, cell).unwrap();
            for code in 0..=255u8 {
                let img = constant(code, m.width * 2, m.height * 2);
                let h = halftone_image(&img, &p, ColorMode::Gray, &ToneOptions::default()).unwrap();
                let linear = srgb_to_linear(code as f64 / 255.0);
                let nearest = (linear * tones).round() / tones;
                let got = mean_reflectance(&h);
                assert!(
                    (got - nearest).abs() < 1e-9,
                    "{mask} L={levels} {cell:?} code {code}: mean {got}, nearest level {nearest}"
                );
            }
        }
    }
}

#[test]
fn code_128_is_about_22_percent_white_not_half() {
    let p = Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, Cell::Expand).unwrap();
    let h = halftone_image(
        &constant(128, 30, 30),
        &p,
        ColorMode::Gray,
        &ToneOptions::default(),
    )
    .unwrap();
    // 0.2158 linear → nearest of 10 levels is 2/9.
    assert!((mean_reflectance(&h) - 2.0 / 9.0).abs() < 1e-12);
    let naive = ToneOptions {
        linearize: false,
        ..Default::default()
    };
    let h = halftone_image(&constant(128, 30, 30), &p, ColorMode::Gray, &naive).unwrap();
    // 128/255 = 0.502 → nearest of 10 levels is 5/9.
    assert!((mean_reflectance(&h) - 5.0 / 9.0).abs() < 1e-12);
}

#[test]
fn three_bit_rgb_with_2x2_cells_shows_125_colours() {
    // Five linear tones a channel (0, 1/4, .., 1) in every combination: 125 input colours.
    let tones: Vec<u8> = (0..5)
        .map(|i| halftone::tone::linear_to_srgb8(i as f64 / 4.0))
        .collect();
    let mut px = Vec::new();
    for &r in &tones {
        for &g in &tones {
            for &b in &tones {
                px.extend([r, g, b]);
            }
        }
    }
    let img = Image::rgb8(125, 1, &px);
    let p = Pattern::new(Mask::builtin("seed-2x2").unwrap(), 2, Cell::Expand).unwrap();
    let h = halftone_image(&img, &p, ColorMode::Rgb, &ToneOptions::default()).unwrap();
    assert_eq!((h.width, h.height, h.channels(), h.levels), (250, 2, 3, 2));
    let mut colours = HashSet::new();
    for x in 0..125 {
        let lit = |c: usize| -> u8 {
            (0..2)
                .flat_map(|dy| (0..2).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| h.get(c, 2 * x + dx, dy))
                .sum()
        };
        colours.insert((lit(0), lit(1), lit(2)));
    }
    assert_eq!(colours.len(), 125);
}

#[test]
fn expand_output_is_n_times_larger() {
    let p = Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, Cell::Expand).unwrap();
    assert_eq!(p.output_size(7, 5), (21, 15));
    let h = halftone_image(
        &constant(200, 7, 5),
        &p,
        ColorMode::Gray,
        &ToneOptions::default(),
    )
    .unwrap();
    assert_eq!((h.width, h.height), (21, 15));
}

#[test]
fn fit_handles_sizes_not_a_multiple_of_the_cell() {
    let p = Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, Cell::Fit).unwrap();
    for (w, h) in [(1, 1), (1, 7), (7, 1), (4, 5), (10, 11)] {
        let out = halftone_image(
            &constant(255, w, h),
            &p,
            ColorMode::Gray,
            &ToneOptions::default(),
        )
        .unwrap();
        assert_eq!((out.width, out.height), (w, h));
        assert!(
            out.levels_of(0).iter().all(|&l| l == 1),
            "white stays white at {w}x{h}"
        );
        let out = halftone_image(
            &constant(0, w, h),
            &p,
            ColorMode::Gray,
            &ToneOptions::default(),
        )
        .unwrap();
        assert!(out.levels_of(0).iter().all(|&l| l == 0));
    }
}

#[test]
fn same_bytes_for_any_thread_count() {
    let px: Vec<u8> = (0..97 * 61).map(|i| ((i * 37) % 256) as u8).collect();
    let img = Image::gray8(97, 61, px);
    let run = |threads: usize, cell: Cell| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let p = Pattern::new(Mask::builtin("seed-3x3").unwrap(), 2, cell).unwrap();
        pool.install(|| halftone_image(&img, &p, ColorMode::Gray, &ToneOptions::default()))
            .unwrap()
    };
    for cell in [Cell::Expand, Cell::Fit] {
        assert_eq!(run(1, cell), run(2, cell));
        assert_eq!(run(1, cell), run(3, cell));
    }
}
