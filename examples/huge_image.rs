//! A huge image under a memory budget: the input streams through in bands of rows and the
//! output is written as the bands come, so the budget holds whatever the image's size
//! (PNM, PNG and TIFF-strip input; most methods).
//!
//! `cargo run --release --example photo_pgm 20000 20000 > big.pgm`, then
//! `cargo run --release --example huge_image -- big.pgm big.pbm 64M`

use halftone::{convert_to, MaxMemory, Options};

fn main() -> Result<(), halftone::Error> {
    let mut args = std::env::args().skip(1);
    let (Some(input), Some(output)) = (args.next(), args.next()) else {
        eprintln!("usage: huge_image INPUT OUTPUT [BUDGET, e.g. 64M]");
        std::process::exit(2);
    };
    let budget = MaxMemory::parse(&args.next().unwrap_or_else(|| "64M".into()))?;
    let opts = Options {
        max_memory: budget,
        ..Default::default()
    };
    let r = convert_to(input.as_str(), output.as_str(), &opts)?;
    println!(
        "{} megapixels in {} bands of {} rows (estimated peak {} MiB)",
        r.pixels() / 1_000_000,
        r.bands,
        r.band_rows,
        r.estimate >> 20
    );
    Ok(())
}
