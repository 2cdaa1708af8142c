//! Time of palette error diffusion on a photo held in memory (no decoding, no encoding): the
//! best of RUNS, with the threads rayon has (`RAYON_NUM_THREADS`).
//!
//! `cargo run --release --example palette_speed PHOTO.ppm [PALETTE] [KERNEL] [RUNS]`

use std::time::Instant;

use halftone::{MethodKind, Options, ToneOptions};

fn main() -> Result<(), halftone::Error> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("PHOTO");
    let palette = args.get(2).map_or("epaper-7", String::as_str);
    let kernel = args.get(3).map_or("floyd-steinberg", String::as_str);
    let runs: usize = args.get(4).map_or(5, |s| s.parse().expect("RUNS"));
    let opts = Options {
        method: MethodKind::Diffuse,
        kernel: kernel.into(),
        palette: Some(palette.into()),
        ..Default::default()
    };
    let img = halftone::read_whole(path.as_str().into(), &opts)?;
    let ink = opts.method()?;
    let tone = img.tone_table(&ToneOptions::default());
    let planes = img.planes(&tone);
    let mut best = f64::INFINITY;
    let mut check = 0u64;
    for _ in 0..runs {
        let t = Instant::now();
        let h = ink.halftone(&planes)?;
        best = best.min(t.elapsed().as_secs_f64());
        check = h.planes[0].iter().map(|&k| k as u64).sum();
    }
    println!(
        "{}x{} {palette} {kernel}, {} threads: {:.1} ms (best of {runs}; checksum {check})",
        img.width,
        img.height,
        rayon::current_num_threads(),
        best * 1e3
    );
    Ok(())
}
