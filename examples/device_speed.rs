//! Time of rendering a photo for an e-paper device held in memory (no decoding, no
//! encoding): the tone and gamut map and the dithering, the best of RUNS.
//!
//! `cargo run --release --example device_speed PHOTO.ppm [DEVICE] [METHOD] [RUNS] [keep]`
//! (the photo fitted to the panel, as `--device` does; `keep`: at its own size).

use std::time::Instant;

use halftone::{Options, ToneOptions};

fn main() -> Result<(), halftone::Error> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("PHOTO");
    let device = args.get(2).map_or("spectra6-7in3-v2", String::as_str);
    let method = args.get(3).map_or("diffuse", String::as_str);
    let runs: usize = args.get(4).map_or(9, |s| s.parse().expect("RUNS"));
    let keep = args.get(5).is_some_and(|a| a == "keep");
    let mut opts = Options {
        device: Some(device.into()),
        method: method.parse()?,
        ..Default::default()
    };
    if keep {
        let probe = halftone::read_whole(path.as_str().into(), &Options::default())?;
        opts.width = Some(probe.width);
    }
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
        "{}x{} {device} {method}: {:.2} ms (best of {runs}; checksum {check})",
        img.width,
        img.height,
        best * 1e3
    );
    Ok(())
}
