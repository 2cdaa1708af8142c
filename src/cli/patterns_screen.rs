//! `halftone patterns --screen`: an AM screen's pattern table, or the screen of a halftone
//! measured.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;

use halftone::mask::screen::{Screen, ScreenSpec, Spot};

use halftone::options::DEFAULT_SCREEN_DPI;

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
