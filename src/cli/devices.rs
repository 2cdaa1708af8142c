//! `halftone devices`: list and show the e-paper panel profiles.

use std::io::Write as _;
use std::process::ExitCode;

use clap::Subcommand;

use halftone::device::{Device, Measurement};

/// Examples shown by `halftone devices --help`.
pub const EXAMPLES: &str = "Examples:
  halftone devices list
  halftone devices show spectra6-7in3-v2
  halftone devices show spectra6-7in3-v2 > my-panel.toml   # edit, then --device my-panel.toml
  halftone convert photo.jpg -o frame.png --device spectra6-7in3-v2";

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
}

pub fn run(c: DevicesCommand) -> anyhow::Result<ExitCode> {
    // Built whole, then written once: a closed or broken stdout is an error.
    let text = match c {
        DevicesCommand::List => list(),
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
