//! Size and display flags shared by `convert` and `batch`: `--height`, `--fit`, `--fit-mode`,
//! `--rotate` and `--device-levels`.

use clap::Args;

use halftone::resize::{self, FitMode, Rotate};

/// Sizing beyond `--width`/`--size`.
#[derive(Args, Debug, Clone, Default)]
pub struct SizeArgs {
    /// Resize to this height in pixels first (aspect kept unless --width is given too; both
    /// together set an exact size).
    #[arg(long)]
    pub height: Option<usize>,

    /// Resize to the largest size inside this box with the aspect ratio kept, e.g. 800x480
    /// for a panel (enlarges small images too).
    #[arg(long, value_name = "WxH", value_parser = parse_fit)]
    pub fit: Option<(usize, usize)>,

    /// How the picture goes into the --fit box or a --device's panel: inside (aspect kept,
    /// one side may fall short), pad (as inside, centred on white to exactly the box) or
    /// cover (aspect kept, the overflow cropped about the centre) [default: pad for a
    /// --device with no size given, inside for --fit].
    #[arg(long, value_name = "inside|pad|cover", value_parser = parse_fit_mode)]
    pub fit_mode: Option<FitMode>,

    /// Turn the image first: auto (a portrait photo turned a quarter clockwise for a
    /// landscape --fit box, and the other way round), or 90, 180, 270 degrees clockwise.
    #[arg(long, value_name = "auto|90|180|270", value_parser = parse_rotate)]
    pub rotate: Option<Rotate>,
}

/// What the codes of a multi-level grey file hold.
#[derive(Args, Debug, Clone, Default)]
pub struct DisplayArgs {
    /// Store device level numbers (0..L−1) in multi-level PGM/PPM and 2/4-bit PNG instead of
    /// display codes (sRGB-encoded reflectance, which every viewer shows at the right tone).
    #[arg(long)]
    pub device_levels: bool,
}

/// `--levels`: 2 to 256 levels a channel, the range every method and format takes.
pub(super) fn parse_levels(s: &str) -> Result<u16, String> {
    match s.trim().parse::<u64>() {
        Ok(n @ 2..=256) => Ok(n as u16),
        Ok(_) => Err("levels must be from 2 to 256 (2 is bilevel)".into()),
        Err(_) => Err("expected a whole number of levels from 2 to 256".into()),
    }
}

/// `--dpi`: a positive, finite number of dots per inch. Negative numbers reach this
/// parser (not clap's "unexpected argument"), so `--dpi -5` and `--dpi=-5` get the same
/// answer.
pub(super) fn parse_dpi(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        Ok(_) => Err("a resolution must be a positive number of dots per inch (e.g. 300)".into()),
        Err(_) => Err("expected a number of dots per inch (e.g. 300)".into()),
    }
}

fn parse_fit(s: &str) -> Result<(usize, usize), String> {
    resize::parse_box(s).map_err(|e| super::flags_for_options(&e.to_string()))
}

fn parse_fit_mode(s: &str) -> Result<FitMode, String> {
    s.parse()
        .map_err(|_| format!("'{s}': expected inside, pad or cover"))
}

fn parse_rotate(s: &str) -> Result<Rotate, String> {
    Ok(match s.trim().to_ascii_lowercase().as_str() {
        "auto" => Rotate::Auto,
        "0" | "none" => Rotate::None,
        "90" => Rotate::Clockwise(1),
        "180" => Rotate::Clockwise(2),
        "270" | "-90" => Rotate::Clockwise(3),
        _ => return Err(format!("'{s}': expected auto, 90, 180 or 270")),
    })
}
