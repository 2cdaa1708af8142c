//! `halftone devices`: list and show the e-paper panel profiles, write a calibration chart,
//! and measure a panel's inks from a photo of that chart.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context as _};
use clap::Subcommand;

use halftone::calibrate::{self, CalibrateOptions};
use halftone::io::{Format, WriteOptions};
use halftone::panel::{Device, Measurement};

use super::convert::FormatArg;

/// Examples shown by `halftone devices --help`.
pub const EXAMPLES: &str = "Examples:
  halftone devices list
  halftone devices show spectra6-7in3-v2
  halftone devices show spectra6-7in3-v2 > my-panel.toml   # edit, then --device my-panel.toml
  halftone convert photo.jpg -o frame.png --device spectra6-7in3-v2
  halftone devices chart bwry-4in2 -o chart.bin             # show it on the panel, photograph it
  halftone devices calibrate bwry-4in2 chart-photo.png -o my-panel.toml
  halftone convert photo.png -o frame.bin --device my-panel.toml";

/// `halftone devices` subcommands.
#[derive(Subcommand, Debug)]
pub enum DevicesCommand {
    /// List the built-in panels: name, size, ppi, inks, and whether their colours are
    /// measured, estimated or nominal.
    #[command(
        after_long_help = "Examples:\n  halftone devices list\n  halftone devices list | grep measured"
    )]
    List,
    /// Print a profile as TOML (a built-in's file as shipped, or a profile file checked and
    /// printed back).
    #[command(
        after_long_help = "Examples:\n  halftone devices show bwry-3in97\n  halftone devices show my-panel.toml"
    )]
    Show {
        /// A built-in name or a profile file.
        device: String,
    },
    /// Write a calibration chart for a panel, at its size and in the colours its driver
    /// expects: a white border, four corner markers (the top-left one with a larger white
    /// centre) and several patches of every ink. Show it on the panel, photograph the panel
    /// beside a sheet of white paper, and give the photo to `devices calibrate`.
    #[command(after_long_help = "Examples:
  halftone devices chart bwry-4in2 -o chart.png      # indexed PNG in the inks' nominal colours
  halftone devices chart bwry-4in2 -o chart.bin      # the panel's raw buffer
  halftone devices chart spectra6-7in3-v2 -o chart.h # as a C header for the firmware")]
    Chart {
        /// A built-in name or a profile file.
        device: String,
        /// The chart file; its extension names the format (png, raw/bin, h, planes,
        /// nibbles, bmp, tiff, pdf…) unless --format says.
        #[arg(short, long)]
        output: PathBuf,
        /// Output format; default from the output's extension.
        #[arg(long, short = 'f', value_enum)]
        format: Option<FormatArg>,
    },
    /// Measure a panel's inks from a photo (JPEG, PNG, …) of its chart beside a sheet of
    /// white paper, and write a profile with `colours = "measured"`. The chart is found by
    /// its corner markers (perspective corrected), the paper as the brightest large even
    /// region outside it (or --paper), vignetting corrected from the chart's white border and
    /// the paper; every ink is divided by the paper, channel by channel, in linear light.
    /// Assumes even, diffuse light, no glare, and a camera whose colours are sRGB (its white
    /// balance and exposure cancel).
    #[command(after_long_help = "Examples:
  halftone devices calibrate bwry-4in2 chart-photo.png -o my-panel.toml
  halftone devices calibrate bwry-4in2 chart-photo.png --paper 275,50,80,160 -o my-panel.toml
  halftone devices calibrate my-panel.toml chart-photo.png > my-panel-2.toml
  halftone convert photo.png -o frame.bin --device my-panel.toml")]
    Calibrate {
        /// The panel: a built-in name or a profile file (the chart was made from it).
        device: String,
        /// The photo of the panel showing its chart, beside white paper.
        photo: PathBuf,
        /// The profile to write; default: standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// The paper as a rectangle of the photo in pixels, X,Y,WIDTH,HEIGHT (default: the
        /// brightest large even region outside the chart).
        #[arg(long, value_name = "X,Y,W,H")]
        paper: Option<String>,
        /// The paper's reflectance as a fraction of sRGB white: 1 makes the paper the
        /// viewer's white, as the built-in measurements take it.
        #[arg(long, default_value_t = 1.0, value_name = "R")]
        paper_reflectance: f64,
        /// Do not correct vignetting and uneven light.
        #[arg(long)]
        no_vignetting: bool,
        /// The new profile's name [default: the output file's stem, else DEVICE-calibrated].
        #[arg(long)]
        name: Option<String>,
    },
}

pub fn run(c: DevicesCommand) -> anyhow::Result<ExitCode> {
    // Built whole, then written once: a closed or broken stdout is an error.
    let text = match c {
        DevicesCommand::List => list(),
        DevicesCommand::Chart {
            device,
            output,
            format,
        } => return chart(&device, &output, format.map(Format::from)),
        DevicesCommand::Calibrate {
            device,
            photo,
            output,
            paper,
            paper_reflectance,
            no_vignetting,
            name,
        } => {
            let opts = CalibrateOptions {
                paper: paper.as_deref().map(parse_rect).transpose()?,
                paper_reflectance,
                vignetting: !no_vignetting,
            };
            let text = calibrate(&device, &photo, &opts, name, output.as_deref())?;
            match output {
                Some(path) => {
                    halftone::io::write_atomic(&path, |out| out.write_all(text.as_bytes()))?;
                    eprintln!("wrote {}", path.display());
                    return Ok(ExitCode::SUCCESS);
                }
                None => text,
            }
        }
        DevicesCommand::Show { device } => match Device::builtin_text(&device) {
            Some(text) => text.to_string(),
            None => {
                // A file: parsed first, so a bad profile is the usual one-line error.
                Device::load(&device)?;
                std::fs::read_to_string(&device)?
            }
        },
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(ExitCode::SUCCESS)
}

/// One line a built-in device.
fn list() -> String {
    let devices: Vec<Device> = Device::builtin_names()
        .map(|n| Device::builtin(n).expect("built-in"))
        .collect();
    let width = devices.iter().map(|d| d.name.len()).max().unwrap_or(4);
    let mut s = String::new();
    for d in &devices {
        let inks: Vec<&str> = d.inks.iter().map(|i| i.name.as_str()).collect();
        let inks = if inks.len() > 7 {
            format!("{} greys", inks.len())
        } else {
            inks.join(",")
        };
        let colours = match d.colours {
            Measurement::Measured => "measured",
            Measurement::Estimated => "estimated",
            Measurement::Nominal => "nominal",
        };
        s.push_str(&format!(
            "{:<width$}  {:>9}  {:>3} ppi  {:<9}  {}\n",
            d.name,
            format!("{}x{}", d.width, d.height),
            d.ppi.round(),
            colours,
            inks
        ));
    }
    s
}

/// Writes the chart of `device` to `output`.
fn chart(device: &str, output: &Path, format: Option<Format>) -> anyhow::Result<ExitCode> {
    let d = Device::load(device)?;
    let Some(format) = format.or_else(|| Format::from_path(output)) else {
        bail!(
            "{}: the extension names no format halftone writes; name the file .png, .bin, .h… \
             or give --format",
            output.display()
        );
    };
    let h = calibrate::chart(&d)?;
    let mut opts = WriteOptions::new(format);
    opts.dpi = Some(d.ppi);
    opts.nominal_colours = true;
    opts.device = Some(std::sync::Arc::new(d));
    halftone::io::write_halftone(&h, output, &opts)?;
    Ok(ExitCode::SUCCESS)
}

/// `X,Y,W,H` as four numbers.
fn parse_rect(s: &str) -> anyhow::Result<[f64; 4]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 4)
        .with_context(|| format!("--paper {s}: give X,Y,WIDTH,HEIGHT in pixels"))?;
    Ok([v[0], v[1], v[2], v[3]])
}

/// Measures the photo and returns the profile's text; a summary goes to standard error.
fn calibrate(
    device: &str,
    photo: &Path,
    opts: &CalibrateOptions,
    name: Option<String>,
    output: Option<&Path>,
) -> anyhow::Result<String> {
    let d = Device::load(device)?;
    let cal = halftone::pipeline::calibrate::calibrate_file(&d, photo, opts)?;
    let name = name.unwrap_or_else(|| {
        output
            .and_then(|o| o.file_stem())
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty() && !s.chars().any(char::is_whitespace))
            .unwrap_or_else(|| format!("{}-calibrated", d.name))
    });
    let photo_name = photo.file_name().map_or_else(
        || photo.display().to_string(),
        |f| f.to_string_lossy().into_owned(),
    );
    let source = format!(
        "calibrated from the photo {photo_name} on {} with `halftone devices calibrate` \
         (profile {}; paper at {:.0},{:.0},{:.0},{:.0} taken as {} of sRGB white; {})",
        today(),
        d.name,
        cal.paper[0],
        cal.paper[1],
        cal.paper[2],
        cal.paper[3],
        opts.paper_reflectance,
        if opts.vignetting {
            "vignetting corrected"
        } else {
            "no vignetting correction"
        }
    );
    let text = calibrate::profile(&d, &cal, &name, &source)?;
    let mut e = std::io::stderr().lock();
    writeln!(
        e,
        "chart found (markers at {}); paper {:.0},{:.0} {:.0}x{:.0}; light over the chart {:.2} to 1",
        cal.markers
            .iter()
            .map(|m| format!("{:.0},{:.0}", m[0], m[1]))
            .collect::<Vec<_>>()
            .join(" "),
        cal.paper[0],
        cal.paper[1],
        cal.paper[2],
        cal.paper[3],
        cal.field[0]
    )?;
    for (ink, m) in d.inks.iter().zip(&cal.inks) {
        let [r, g, b] = m.srgb;
        let [nr, ng, nb] = ink.nominal;
        writeln!(
            e,
            "  {:<12} #{r:02x}{g:02x}{b:02x}  (nominal #{nr:02x}{ng:02x}{nb:02x}; {} patches, spread {:.3})",
            ink.name, m.patches, m.spread
        )?;
    }
    Ok(text)
}

/// Today's date (UTC) as YYYY-MM-DD.
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Days to a civil date (Howard Hinnant's algorithm).
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}
