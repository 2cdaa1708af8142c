//! `halftone render`: draws a built-in or TOML scene into an sRGB PNG (continuous tone,
//! for halftoning).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use clap::{Args, ValueEnum};

use halftone::render::{self, Antialias, Depth, RenderOptions, Scene};

/// Examples shown under `halftone render --help`.
pub const EXAMPLES: &str = "Examples:
  halftone render --list
  halftone render kd-series -o kd.png
  halftone render raytrace -o rt.png --size 512x512 --aa jitter
  halftone render scenes/raytrace.toml -o rt16.png --depth 16
  halftone render my-scene.toml -o out.png --aa none";

/// Antialiasing choices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum AaArg {
    /// One ray through each pixel centre.
    None,
    /// Rays through the pixel corners, averaged.
    Super,
    /// Corners, subdivided where they differ (up to 256 rays a pixel).
    Adaptive,
    /// 16 rays jittered on a 4×4 subpixel grid.
    Jitter,
}

impl From<AaArg> for Antialias {
    fn from(a: AaArg) -> Antialias {
        match a {
            AaArg::None => Antialias::None,
            AaArg::Super => Antialias::Super,
            AaArg::Adaptive => Antialias::Adaptive,
            AaArg::Jitter => Antialias::Jitter,
        }
    }
}

/// PNG sample depths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DepthArg {
    /// 8 bits a channel.
    #[value(name = "8")]
    Eight,
    /// 16 bits a channel.
    #[value(name = "16")]
    Sixteen,
}

/// Arguments of `halftone render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A built-in scene name (see --list) or a TOML scene file.
    #[arg(required_unless_present = "list")]
    pub scene: Option<String>,
    /// Output PNG file.
    #[arg(short, long, required_unless_present = "list")]
    pub output: Option<PathBuf>,
    /// Picture size, WIDTHxHEIGHT (default: the scene's).
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(usize, usize)>,
    /// Antialiasing (default: the scene's).
    #[arg(long, value_enum)]
    pub aa: Option<AaArg>,
    /// Bits per channel of the PNG.
    #[arg(long, value_enum, default_value = "8")]
    pub depth: DepthArg,
    /// List the built-in scenes and exit.
    #[arg(long)]
    pub list: bool,
}

fn parse_size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("'{s}': sizes are 1 to 16384"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// Writes the picture as a binary PPM (P6), sRGB, maxval 255 or 65535 (big-endian).
fn write_ppm(frame: &render::Frame, path: &Path, depth: Depth) -> anyhow::Result<()> {
    let (w, h) = (frame.width, frame.height);
    let (maxval, bytes) = match depth {
        Depth::Eight => (255, frame.to_srgb8()),
        Depth::Sixteen => (
            65535,
            frame
                .to_srgb16()
                .iter()
                .flat_map(|v| v.to_be_bytes())
                .collect(),
        ),
    };
    halftone::io::write_atomic(path, |out| {
        write!(out, "P6\n{w} {h}\n{maxval}\n")?;
        out.write_all(&bytes)
    })?;
    Ok(())
}

/// Runs `halftone render`.
pub fn run(a: RenderArgs) -> anyhow::Result<ExitCode> {
    if a.list {
        for (name, about, _) in render::BUILTIN {
            println!("{name:<12} {about}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    let (Some(name), Some(output)) = (a.scene, a.output) else {
        bail!("render: a scene and -o OUTPUT are needed");
    };
    // The picture is continuous-tone colour: PNG, or PPM for Netpbm pipelines. Anything
    // else is refused before rendering, rather than PNG bytes under another name.
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let ppm = match ext.as_deref() {
        Some("png") => false,
        Some("ppm") | Some("pnm") => true,
        _ => bail!(
            "{}: render writes PNG (.png) or PPM (.ppm) pictures; to get a halftone, render \
             to PNG and run `halftone convert` on it",
            output.display()
        ),
    };
    let path = Path::new(&name);
    let scene = if path.is_file() {
        Scene::load(path)?
    } else if let Some(s) = Scene::builtin(&name) {
        s
    } else {
        bail!("{name}: no such file or built-in scene (see halftone render --list)");
    };
    let frame = render::render(
        &scene,
        &RenderOptions {
            size: a.size,
            aa: a.aa.map(Antialias::from),
        },
    );
    let depth = match a.depth {
        DepthArg::Eight => Depth::Eight,
        DepthArg::Sixteen => Depth::Sixteen,
    };
    if ppm {
        write_ppm(&frame, &output, depth)?;
    } else {
        frame.write_png(&output, depth)?;
    }
    Ok(ExitCode::SUCCESS)
}
