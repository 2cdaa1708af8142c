//! A photo to a 1-bit PBM for a 300-dpi printer, 4 inches wide, with the library alone:
//! the options the command line's `convert` takes, as one struct.
//!
//! `cargo run --release --example file_to_file -- samples/raytrace.png out.pbm`

use halftone::{convert_to, MethodKind, Options};

fn main() -> Result<(), halftone::Error> {
    let mut args = std::env::args().skip(1);
    let (Some(input), Some(output)) = (args.next(), args.next()) else {
        eprintln!("usage: file_to_file INPUT OUTPUT.pbm");
        std::process::exit(2);
    };
    let opts = Options {
        method: MethodKind::Diffuse,
        kernel: "jarvis-judice-ninke".into(),
        dpi: Some(300.0),
        size: Some("4in".into()),
        ..Default::default()
    };
    let report = convert_to(input.as_str(), output.as_str(), &opts)?;
    println!(
        "{}x{} -> {}x{} pixels{}",
        report.input.0,
        report.input.1,
        report.output.0,
        report.output.1,
        if report.streamed { ", streamed" } else { "" }
    );
    Ok(())
}
