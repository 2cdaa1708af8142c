//! CMYK plates for a press: the separation through the FOGRA39 press model, one AM screen a
//! plate at the classic angles, the four plates written as TIFFs with their ink names and a
//! preview of the printed result.
//!
//! `cargo run --release --example cmyk_plates -- samples/color-balls.png poster.tif`

use halftone::{plates, Color, MethodKind, Options};

fn main() -> Result<(), halftone::Error> {
    let mut args = std::env::args().skip(1);
    let (Some(input), Some(output)) = (args.next(), args.next()) else {
        eprintln!("usage: cmyk_plates INPUT OUTPUT.tif");
        std::process::exit(2);
    };
    let opts = Options {
        color: Color::Cmyk,
        method: MethodKind::Screen,
        lpi: "150".into(),
        dpi: Some(1200.0),
        size: Some("3in".into()),
        preview: true,
        ..Default::default()
    };
    let p = plates(input.as_str(), &opts)?;
    let output = std::path::Path::new(&output);
    p.write(output, halftone::Format::Tiff, &opts)?;
    if let Some(png) = p.preview_png()? {
        let preview = output.with_extension("preview.png");
        halftone::io::write_atomic(&preview, |w| w.write_all(&png))?;
        println!("preview: {}", preview.display());
    }
    println!(
        "{}x{} plates: {}-cyan.tif … -black.tif",
        p.halftone.width,
        p.halftone.height,
        output.with_extension("").display()
    );
    Ok(())
}
