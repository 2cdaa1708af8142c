//! Flags of AM screening, CMYK separation and calibration (`--method screen`,
//! `--color cmyk`, `--press`, `--transfer`).

use std::path::PathBuf;

use anyhow::bail;
use clap::{Args, ValueEnum};

use halftone::mask::screen::{Screen, ScreenSpec, Spot};

use halftone::options::DEFAULT_SCREEN_DPI;
use halftone::SeparationKind;

/// How sRGB becomes ink amounts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SeparationArg {
    /// Invert a model of the press (Yule–Nielsen Neugebauer) through a 3-D lookup table.
    Model,
    /// The plain complement (C = 1 − R …) with grey component replacement: fast, off-colour.
    Naive,
}

/// ICC rendering intent of `--intent`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum IntentArg {
    /// Compress the whole sRGB gamut into the press's.
    Perceptual,
    /// Media-relative colorimetric: in-gamut colours exact, paper (or the panel's white) as
    /// white, black-point compensated for a device.
    Relative,
    /// Vivid colours (business graphics).
    Saturation,
    /// Absolute colorimetric: simulates the paper's tint.
    Absolute,
}

impl IntentArg {
    /// The library's intent.
    pub fn intent(self) -> halftone::press::RenderingIntent {
        use halftone::press::RenderingIntent as R;
        match self {
            IntentArg::Perceptual => R::Perceptual,
            IntentArg::Relative => R::Relative,
            IntentArg::Saturation => R::Saturation,
            IntentArg::Absolute => R::Absolute,
        }
    }
}

/// AM screen, separation and calibration flags.
#[derive(Args, Debug, Clone)]
pub struct ScreenArgs {
    /// Screen frequency in lines per inch (`--method screen`, CMYK plates); with --color
    /// cmyk also per ink: `c=150,m=150,y=133,k=175`.
    #[arg(long, default_value = "106")]
    pub lpi: String,

    /// Screen angle in degrees, counter-clockwise from the x axis (PostScript's sense).
    #[arg(long, default_value_t = 45.0, allow_hyphen_values = true)]
    pub angle: f64,

    /// Spot function: a PDF name (Round, SimpleDot, Ellipse, Diamond, Line, …; any case,
    /// kebab-case too).
    #[arg(long, default_value = "Round")]
    pub spot: String,

    /// CMYK plate angles, e.g. `c=15,m=75,y=0,k=45` (the default).
    #[arg(long)]
    pub angles: Option<String>,

    /// Press to separate for: fogra39 (coated offset, the default), fogra29 (uncoated),
    /// tr002 (newsprint), gracol, or a characterisation file (.ti3, CGATS with CMYK and XYZ).
    #[arg(long, default_value = "fogra39")]
    pub press: String,

    /// Grey component replacement, percent: 0 builds greys from C, M, Y; 100 from black alone.
    #[arg(long, default_value_t = 50.0)]
    pub gcr: f64,

    /// Total area coverage limit, percent (sum of the four inks).
    #[arg(long, default_value_t = 300.0)]
    pub tac: f64,

    /// Separation: the press model (default) or the naive complement.
    #[arg(long, value_enum, default_value = "model")]
    pub separation: SeparationArg,

    /// Separate through a vendor's ICC output profile (CMYK, class 'prtr') instead of the
    /// press model; black generation and ink limit are the profile's (no --gcr, --tac).
    #[arg(long, value_name = "FILE.icc")]
    pub icc: Option<PathBuf>,

    /// Rendering intent: with --icc [default: relative]; with --device [default:
    /// perceptual] or --palette [default: absolute, the colours as given].
    #[arg(long, value_enum)]
    pub intent: Option<IntentArg>,

    /// Also write what the press would print (through the press model, paper as white), PNG.
    #[arg(long, value_name = "FILE.png")]
    pub preview: Option<PathBuf>,

    /// Device pixels averaged into one preview pixel [default: two screen periods; 1 shows
    /// every dot in the press's colours, a magnified rosette].
    #[arg(long, value_name = "N")]
    pub preview_block: Option<usize>,

    /// A measured step wedge (CSV: nominal %, measured %; one measured column per ink for
    /// CMYK; `#` comments): inverted into a compensation curve applied before halftoning.
    #[arg(long, value_name = "FILE.csv")]
    pub transfer: Option<PathBuf>,
}

impl SeparationArg {
    /// The library's name for it.
    pub fn kind(self) -> SeparationKind {
        match self {
            SeparationArg::Model => SeparationKind::Model,
            SeparationArg::Naive => SeparationKind::Naive,
        }
    }
}

/// `halftone patterns --screen` flags.
#[derive(Args, Debug, Clone)]
pub struct PatternScreenArgs {
    /// Show an AM screen's pattern table instead of a mask's: geometry, levels, thresholds.
    #[arg(long)]
    pub screen: bool,

    /// Screen frequency, lines per inch (with --screen).
    #[arg(long = "lpi", default_value_t = 106.0, requires = "screen")]
    pub screen_lpi: f64,

    /// Screen angle, degrees counter-clockwise (with --screen).
    #[arg(
        long = "angle",
        default_value_t = 45.0,
        allow_hyphen_values = true,
        requires = "screen"
    )]
    pub screen_angle: f64,

    /// Spot function (with --screen).
    #[arg(long = "spot", default_value = "Round", requires = "screen")]
    pub screen_spot: String,

    /// Device resolution, dots per inch (with --screen).
    #[arg(long = "dpi", default_value_t = DEFAULT_SCREEN_DPI, requires = "screen")]
    pub screen_dpi: f64,

    /// Side of the threshold tile written with -o when the screen has no repeat that fits
    /// (with --screen).
    #[arg(long, default_value_t = 256, requires = "screen")]
    pub tile: usize,

    /// Measure the screen of a halftone image (a flat patch, e.g. from another RIP) at
    /// --dpi instead: its frequency and angle from the 2-D spectrum (with --screen).
    #[arg(long, value_name = "IMAGE", requires = "screen")]
    pub measure: Option<PathBuf>,
}

/// `halftone patterns --screen`: prints the screen's numbers; with `output`, writes its
/// threshold array (the repeat if it has one of at most 1024 pixels a side, else a tile).
pub fn patterns(
    a: &PatternScreenArgs,
    output: Option<&std::path::Path>,
) -> anyhow::Result<std::process::ExitCode> {
    use halftone::mask::screen::{measure, CellCache};
    use std::io::Write;
    if let Some(path) = &a.measure {
        let img = super::stdio::read_image(path, &Default::default())?;
        let table = img.tone_table(&halftone::ToneOptions {
            linearize: false,
            ..Default::default()
        });
        let planes = img.planes(&table);
        let p = &planes.planes[0];
        let mut ink = vec![0u8; img.width * img.height];
        for y in 0..img.height {
            for x in 0..img.width {
                ink[y * img.width + x] = (p.value(x, y) < 0.5) as u8;
            }
        }
        if img.width.min(img.height) < 16 {
            bail!("{}: needs at least 16x16 pixels to measure", path.display());
        }
        let m = measure(&ink, img.width, img.height);
        // 89.9999° and −0° are 0° (angles are modulo 90).
        let angle = if m.angle > 89.9995 {
            0.0
        } else {
            m.angle + 0.0
        };
        println!(
            "{}: {:.3} lpi at {:.3}° at {} dpi (period {:.4} pixels)",
            path.display(),
            a.screen_dpi / m.period,
            angle,
            a.screen_dpi,
            m.period
        );
        return Ok(std::process::ExitCode::SUCCESS);
    }
    let screen = Screen::new(ScreenSpec {
        dpi: a.screen_dpi,
        lpi: a.screen_lpi,
        angle: a.screen_angle,
        spot: Spot::from_name(&a.screen_spot)?,
    })?;
    if a.tile == 0 || a.tile > 8192 {
        bail!("--tile {}: must be 1 to 8192", a.tile);
    }
    let repeat = screen.supercell(1024);
    let (w, h) = repeat.unwrap_or((a.tile, a.tile));
    let mut th = vec![0u16; w * h];
    let mut cache = CellCache::new();
    for (y, row) in th.chunks_exact_mut(w).enumerate() {
        screen.threshold_row(y as i64, 0, row, &mut cache);
    }
    // Measure the geometry from a 50% patch of the screen itself.
    let n = 256usize;
    let mut patch = vec![0u8; n * n];
    let mut row = vec![0u16; n];
    for y in 0..n {
        screen.threshold_row(y as i64, 0, &mut row, &mut cache);
        for x in 0..n {
            patch[y * n + x] = (32768 > row[x] as u32) as u8;
        }
    }
    let m = measure(&patch, n, n);
    let s = screen.spec();
    let [v1, v2] = screen.cell_vectors();
    let mut out = String::new();
    out += &format!(
        "screen: {} lpi at {}° at {} dpi, spot {}\n",
        s.lpi,
        s.angle,
        s.dpi,
        s.spot.name()
    );
    out += &format!(
        "achieved (2-D FFT of a 50% patch): {:.3} lpi at {:.3}°\n",
        s.dpi / m.period,
        m.angle
    );
    out += &format!(
        "cell vectors (pixels, x right, y down): ({:.4}, {:.4}) and ({:.4}, {:.4})\n",
        v1.0, v1.1, v2.0, v2.1
    );
    out += &format!("pixels a cell: {:.3}\n", screen.pixels_per_cell());
    match repeat {
        Some((w, h)) => out += &format!("repeat on the pixel grid: {w}x{h}\n"),
        None => out += "repeat on the pixel grid: none within 1024 pixels (irrational screen)\n",
    }
    out += &format!(
        "distinct threshold levels in the {}x{} array: {}\n",
        w,
        h,
        Screen::distinct_levels(&th)
    );
    if let Some(path) = output {
        let is_pgm = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("pgm"));
        let bytes = if is_pgm {
            // 16-bit PGM: the ink threshold, 0 = first to take ink.
            let mut b = format!("P5\n{w} {h}\n65535\n").into_bytes();
            for &t in &th {
                b.extend_from_slice(&t.to_be_bytes());
            }
            b
        } else {
            // A mask file: the lowest number lights (paper) first, as in every mask.
            let mut t = format!(
                "# {} lpi, {} deg, {} at {} dpi: {}x{} thresholds (65535 - ink threshold).\n",
                s.lpi,
                s.angle,
                s.spot.name(),
                s.dpi,
                w,
                h
            );
            for row in th.chunks_exact(w) {
                let r: Vec<String> = row.iter().map(|&v| (65535 - v).to_string()).collect();
                t += &r.join(" ");
                t.push('\n');
            }
            t.into_bytes()
        };
        halftone::io::write_atomic(path, |f| f.write_all(&bytes))?;
        out += &format!("wrote {}\n", path.display());
    }
    std::io::stdout().lock().write_all(out.as_bytes())?;
    Ok(std::process::ExitCode::SUCCESS)
}
