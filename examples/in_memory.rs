//! An image in memory to encoded bytes and back to level indices: what a server, a GUI or
//! another language's binding does. Nothing touches the file system.
//!
//! `cargo run --release --example in_memory`

use halftone::{convert, convert_to_bytes, Format, Image, MethodKind, Options};

fn main() -> Result<(), halftone::Error> {
    // A 256×64 grey ramp, sRGB codes, as a camera or a canvas would hand it over.
    let (w, h) = (256, 64);
    let ramp: Vec<u8> = (0..w * h).map(|i| (i % w) as u8).collect();
    let opts = Options {
        method: MethodKind::Ordered,
        mask: Some("bayer-8".into()),
        levels: 4,
        ..Default::default()
    };
    // The encoded file, as it would be written to disk or sent to a printer.
    let png = convert_to_bytes(Image::gray8(w, h, ramp.clone()), Format::Png, &opts)?;
    // The same halftone as level indices (0 = darkest), one row at a time.
    let ht = convert(Image::gray8(w, h, ramp), &opts)?;
    let mut row = vec![0u8; ht.width];
    ht.unpack_row(0, 0, &mut row);
    let mean = row.iter().map(|&l| l as f64).sum::<f64>() / (ht.width as f64 * 3.0);
    println!(
        "{} bytes of PNG; {} levels; first row's mean level {mean:.3} of 1",
        png.len(),
        ht.levels
    );
    Ok(())
}
