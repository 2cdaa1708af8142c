//! The calibration walk-through's pictures: a device's chart (as the driver gets it) and a
//! synthetic photograph of it beside white paper (a colour cast, vignetting, tilt, blur and
//! noise), then the inks `calibrate` recovers from that photo against the truth.
//!
//! `cargo run --release --example calibration_photo -- [DEVICE] [DIR]`
//! (default: bwry-4in2 into docs/calibration)

use std::path::Path;

use halftone::calibrate::{calibrate, chart, synthetic_photo, CalibrateOptions, Scene};
use halftone::io::{write_halftone, Format, WriteOptions};
use halftone::raster::Samples;
use halftone::Device;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let name = args.next().unwrap_or_else(|| "bwry-4in2".into());
    let dir = args.next().unwrap_or_else(|| "docs/calibration".into());
    std::fs::create_dir_all(&dir)?;
    let device = Device::load(&name)?;
    let mut opts = WriteOptions::new(Format::Png);
    opts.device = Some(std::sync::Arc::new(device.clone()));
    opts.nominal_colours = true;
    let chart_path = Path::new(&dir).join(format!("{name}-chart.png"));
    write_halftone(&chart(&device)?, &chart_path, &opts)?;
    let truth: Vec<[f64; 3]> = device.inks.iter().map(|i| i.shown_linear()).collect();
    let scene = Scene {
        width: 400,
        height: 260,
        ..Scene::default()
    };
    let photo = synthetic_photo(&device, &truth, &scene)?;
    let mut rgb = Vec::with_capacity(photo.width * photo.height * 3);
    for i in 0..photo.width * photo.height {
        for p in &photo.planes {
            if let Samples::U8(v) = p {
                rgb.push(v[i]);
            }
        }
    }
    let photo_path = Path::new(&dir).join(format!("{name}-photo.png"));
    image::save_buffer(
        &photo_path,
        &rgb,
        photo.width as u32,
        photo.height as u32,
        image::ColorType::Rgb8,
    )?;
    let cal = calibrate(&device, &photo, &CalibrateOptions::default())?;
    println!("{} and {}", chart_path.display(), photo_path.display());
    println!(
        "markers {:?}\npaper {:?}\nfield {:?}",
        cal.markers, cal.paper, cal.field
    );
    for (m, ink) in cal.inks.iter().zip(&device.inks) {
        println!(
            "{:<8} truth {:?} measured {:?} ({} patches, spread {:.3})",
            m.name,
            ink.shown(),
            m.srgb,
            m.patches,
            m.spread
        );
    }
    Ok(())
}
