//! Calibration from a photo file: the photo averaged down as it is decoded (the reading
//! pipeline's part), then measured by [`crate::calibrate`].

use std::path::Path;

use crate::calibrate::{calibrate, CalibrateOptions, Calibration, CALIBRATION_PIXELS};
use crate::error::{Error, Result};
use crate::io::panel::Device;
use crate::io::ReadOptions;

/// Reads the photo at `path` and measures the inks of `device` in it (see [`calibrate`]);
/// errors name the file.
pub fn calibrate_file(
    device: &Device,
    path: &Path,
    opts: &CalibrateOptions,
) -> Result<Calibration> {
    // Averaged down on load to at most CALIBRATION_PIXELS: the chart is found on a grid of
    // 1000 cells a side and its patches averaged, so a larger photo adds memory, not
    // accuracy (a 324-megapixel photo took 1.9 GB read whole).
    let (img, f) = super::reduce::read_reduced(path, &ReadOptions::default(), CALIBRATION_PIXELS)?;
    let s = f as f64;
    let mut o = opts.clone();
    o.paper = o.paper.map(|r| r.map(|v| v / s));
    let mut cal = calibrate(device, &img, &o).map_err(|e| match e {
        Error::Invalid(msg) if f > 1 => Error::Invalid(format!(
            "{}: {msg} (measured on the photo averaged down {f} times each way to {}x{}: \
             pixel figures are of that)",
            path.display(),
            img.width,
            img.height
        )),
        Error::Invalid(msg) => Error::Invalid(format!("{}: {msg}", path.display())),
        other => other,
    })?;
    // Back in the photo's own pixels.
    for m in &mut cal.markers {
        *m = m.map(|v| v * s);
    }
    cal.paper = cal.paper.map(|v| v * s);
    Ok(cal)
}
