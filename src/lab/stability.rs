//! Where methods fail: tone curve, start-up delay, regular texture and clumping, moiré,
//! flicker, and edge cases, measured on small synthetic inputs in memory.
//!
//! Every figure is in the halftone's own terms (output rows, output samples), so methods
//! that change size (pattern `expand`) and multi-level outputs are measured the same way as
//! the others.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::method::Method;
use crate::quality::{self, Reflectance, Viewing};
use crate::raster::{ColorKind, Halftone, Image, Samples};
use crate::tone::{linear_to_srgb8, Encoding, ToneOptions, ToneTable};

/// How big the test patches are and how they are viewed.
#[derive(Clone, Copy, Debug)]
pub struct StabilityOptions {
    /// Side of the square test patches, input pixels (start-up uses patches twice as tall).
    /// The default, 48, is a multiple of every common cell (2, 3, 4, 6, 8, 12, 16).
    pub size: usize,
    /// Viewing conditions for the texture figures.
    pub view: Viewing,
}

impl Default for StabilityOptions {
    fn default() -> Self {
        StabilityOptions {
            size: 48,
            view: Viewing::default(),
        }
    }
}

/// Output tone at each of the 256 constant 8-bit sRGB levels, against the input's tone.
#[derive(Clone, Debug, Serialize)]
pub struct ToneCurve {
    /// Mean output reflectance of a constant patch of each code.
    pub output: Vec<f64>,
    /// Linear reflectance of each code (the sRGB table).
    pub target: Vec<f64>,
    /// Largest |output − target|.
    pub max_error: f64,
    /// Mean |output − target| over the 256 codes.
    pub mean_error: f64,
    /// The code with the largest error.
    pub worst_code: u8,
}

impl ToneCurve {
    /// Signed error (output − target) of each code: negative prints too dark.
    pub fn errors(&self) -> Vec<f64> {
        self.output
            .iter()
            .zip(&self.target)
            .map(|(o, t)| o - t)
            .collect()
    }
}

/// Texture of a constant patch at a simple fraction of paper.
#[derive(Clone, Debug, Serialize)]
pub struct Texture {
    /// The fraction, as text ("1/2").
    pub fraction: String,
    /// Smallest horizontal and vertical period of the output's lower half, when it repeats
    /// within 16 samples: a regular texture.
    pub period: Option<[usize; 2]>,
    /// HVS-PSNR of the patch against the flat tone: how visible the texture is.
    pub hvs_psnr_db: f64,
}

/// One edge case's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct EdgeCase {
    /// What was tried.
    pub case: String,
    /// Whether the output was right.
    pub ok: bool,
    /// What was wrong (empty when ok).
    pub detail: String,
}

/// A method's stability figures.
#[derive(Clone, Debug, Serialize)]
pub struct Stability {
    /// Registry key.
    pub key: String,
    /// The method's own name.
    pub method: String,
    /// The tone curve.
    pub tone: ToneCurve,
    /// Output rows before the first ink dot at reflectance 63/64 (`None`: none in the patch).
    pub startup_white: Option<usize>,
    /// Output rows before the first paper dot at reflectance 1/64 (`None`: none in the patch).
    pub startup_black: Option<usize>,
    /// Texture at 1/2, 1/3 and 1/4 reflectance.
    pub texture: Vec<Texture>,
    /// Clumping (worms) at 1/8 ink: the share of minority pixels touching another (8-way);
    /// dispersed dots give 0, a random field 1 − (7/8)⁸ ≈ 0.66, clustered dots and worms more.
    pub clumping: f64,
    /// Moiré: PSNR (dB) of the error below 1/16 cycle per input pixel on a zone plate; low
    /// means strong low-frequency patterns that are not in the image.
    pub moire_lf_psnr_db: f64,
    /// Flicker: share of output samples that change when every input code rises by one.
    pub flicker: f64,
    /// Edge cases.
    pub edge_cases: Vec<EdgeCase>,
}

impl Stability {
    /// True when every edge case passed.
    pub fn edge_cases_ok(&self) -> bool {
        self.edge_cases.iter().all(|e| e.ok)
    }
}

/// Halftones a grey image with default tone options.
fn run(method: &dyn Method, img: &Image) -> Result<Halftone> {
    crate::pipeline::halftone_image(
        img,
        method,
        crate::raster::ColorMode::Gray,
        &ToneOptions::default(),
    )
}

/// Runs `method`, turning a panic into an error so one broken method cannot stop a report.
fn run_guarded(method: &dyn Method, img: &Image) -> Result<Halftone> {
    match catch_unwind(AssertUnwindSafe(|| run(method, img))) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".into());
            Err(Error::Invalid(format!(
                "{}: panicked: {msg}",
                method.name()
            )))
        }
    }
}

/// A 16-bit image with codes proportional to light: tones like 1/3 stay exact.
fn linear16(width: usize, height: usize, f: impl Fn(usize, usize) -> f64) -> Image {
    let mut v = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            v.push((f(x, y).clamp(0.0, 1.0) * 65535.0).round() as u16);
        }
    }
    Image {
        width,
        height,
        color: ColorKind::Gray,
        planes: vec![Samples::U16(v)],
        encoding: Encoding::Linear,
        dpi: None,
    }
}

/// The zone plate cos(π r²/s): local frequency r/s cycles per pixel, reaching Nyquist at
/// r = s/2, so every frequency a halftone can alias is swept.
pub fn zone_plate(size: usize) -> Image {
    let c = size as f64 / 2.0;
    linear16(size, size, |x, y| {
        let (dx, dy) = (x as f64 + 0.5 - c, y as f64 + 0.5 - c);
        0.5 + 0.5 * (std::f64::consts::PI * (dx * dx + dy * dy) / size as f64).cos()
    })
}

/// The tone curve over the 256 8-bit sRGB codes.
pub fn tone_curve(method: &dyn Method, size: usize) -> Result<ToneCurve> {
    let table = ToneTable::new(8, Encoding::Srgb, &ToneOptions::default());
    let target: Vec<f64> = table.as_slice().iter().map(|&v| v as f64).collect();
    let output = (0..=255u8)
        .into_par_iter()
        .map(|c| {
            let h = run(method, &Image::gray8(size, size, vec![c; size * size]))?;
            Ok(quality::halftone_reflectance(&h).mean())
        })
        .collect::<Result<Vec<f64>>>()?;
    let errs: Vec<f64> = output
        .iter()
        .zip(&target)
        .map(|(o, t)| (o - t).abs())
        .collect();
    let (worst, max_error) =
        errs.iter().enumerate().fold(
            (0, 0.0),
            |(wi, wm), (i, &e)| if e > wm { (i, e) } else { (wi, wm) },
        );
    Ok(ToneCurve {
        mean_error: errs.iter().sum::<f64>() / 256.0,
        max_error,
        worst_code: worst as u8,
        output,
        target,
    })
}

/// Output rows before the first sample that is not the majority level: near white, any
/// level below paper; near black, any level above solid ink.
fn first_dot_row(h: &Halftone, near_white: bool) -> Option<usize> {
    let top = (h.levels - 1) as u8;
    let mut row = vec![0u8; h.width];
    (0..h.height).find(|&y| {
        (0..h.channels()).any(|c| {
            h.unpack_row(c, y, &mut row);
            row.iter()
                .any(|&l| if near_white { l < top } else { l > 0 })
        })
    })
}

/// Smallest period (≤ 16) of the lower half of plane 0 in x and y, if it repeats.
fn period(h: &Halftone) -> Option<[usize; 2]> {
    let lv = h.levels_of(0);
    let (w, y0) = (h.width, h.height / 2);
    let at = |x: usize, y: usize| lv[y * w + x];
    let px = (1..=16.min(w / 2))
        .find(|&p| (y0..h.height).all(|y| (0..w - p).all(|x| at(x, y) == at(x + p, y))))?;
    let py = (1..=16.min((h.height - y0) / 2))
        .find(|&p| (y0..h.height - p).all(|y| (0..w).all(|x| at(x, y) == at(x, y + p))))?;
    Some([px, py])
}

/// Share of minority samples (here: below paper) with a minority 8-neighbour.
fn clumping(h: &Halftone) -> f64 {
    let lv = h.levels_of(0);
    let top = (h.levels - 1) as u8;
    let (w, ht) = (h.width as isize, h.height as isize);
    let ink =
        |x: isize, y: isize| x >= 0 && y >= 0 && x < w && y < ht && lv[(y * w + x) as usize] < top;
    let (mut n, mut touching) = (0usize, 0usize);
    for y in 0..ht {
        for x in 0..w {
            if !ink(x, y) {
                continue;
            }
            n += 1;
            let near = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                .any(|(dx, dy)| (dx, dy) != (0, 0) && ink(x + dx, y + dy));
            touching += near as usize;
        }
    }
    if n == 0 {
        0.0
    } else {
        touching as f64 / n as f64
    }
}

fn same_size_check(
    method: &dyn Method,
    img: &Image,
    h: &Halftone,
) -> std::result::Result<(), String> {
    let want = method.output_size(img.width, img.height);
    if (h.width, h.height) != want {
        return Err(format!(
            "output {}x{}, expected {}x{}",
            h.width, h.height, want.0, want.1
        ));
    }
    let bytes = h.stride * h.height;
    if h.planes.iter().any(|p| p.len() != bytes) {
        return Err("plane storage does not match stride × height".into());
    }
    if h.stride * 8 < h.width * h.bits as usize {
        return Err("stride too short for the width".into());
    }
    Ok(())
}

fn ramp8(width: usize, height: usize) -> Image {
    let span = (width + height).saturating_sub(2).max(1);
    let px = (0..height)
        .flat_map(|y| (0..width).map(move |x| ((x + y) * 255 / span) as u8))
        .collect();
    Image::gray8(width, height, px)
}

/// Edge cases: tiny and odd sizes, all black, all white, 16-bit input, colour, thread count.
pub fn edge_cases(method: &dyn Method) -> Vec<EdgeCase> {
    let mut out = Vec::new();
    let mut case = |name: &str, r: std::result::Result<(), String>| {
        out.push(EdgeCase {
            case: name.into(),
            ok: r.is_ok(),
            detail: r.err().unwrap_or_default(),
        })
    };
    let sized = |img: Image| -> std::result::Result<Halftone, String> {
        let h = run_guarded(method, &img).map_err(|e| e.to_string())?;
        same_size_check(method, &img, &h)?;
        Ok(h)
    };
    case("1x1", sized(Image::gray8(1, 1, vec![128])).map(drop));
    case("1xN", sized(ramp8(1, 37)).map(drop));
    case("Nx1", sized(ramp8(37, 1)).map(drop));
    case(
        "7x5 (not a multiple of the mask)",
        sized(ramp8(7, 5)).map(drop),
    );
    for (name, code) in [("all black", 0u8), ("all white", 255u8)] {
        let r = sized(Image::gray8(19, 13, vec![code; 19 * 13])).and_then(|h| {
            let want = if code == 0 { 0 } else { (h.levels - 1) as u8 };
            match h.levels_of(0).iter().position(|&l| l != want) {
                None => Ok(()),
                Some(i) => Err(format!(
                    "sample {i} is level {}, expected {want}",
                    h.levels_of(0)[i]
                )),
            }
        });
        case(name, r);
    }
    // 16-bit codes c·257 mean exactly what 8-bit c means: the output must not change.
    let r = (|| {
        let img8 = ramp8(33, 17);
        let Samples::U8(c8) = &img8.planes[0] else {
            unreachable!()
        };
        let img16 = Image {
            planes: vec![Samples::U16(c8.iter().map(|&c| c as u16 * 257).collect())],
            ..img8.clone()
        };
        let (a, b) = (sized(img8)?, sized(img16)?);
        if a.planes == b.planes {
            Ok(())
        } else {
            Err("16-bit codes c·257 halftone differently from 8-bit c".to_string())
        }
    })();
    case("16-bit input", r);
    let r = (|| {
        let px: Vec<u8> = (0..12 * 9 * 3).map(|i| (i * 37 % 256) as u8).collect();
        let img = Image::rgb8(12, 9, &px);
        let tone = ToneOptions::default();
        let h = catch_unwind(AssertUnwindSafe(|| {
            crate::pipeline::halftone_image(&img, method, crate::raster::ColorMode::Rgb, &tone)
        }))
        .map_err(|_| "panicked".to_string())?
        .map_err(|e| e.to_string())?;
        same_size_check(method, &img, &h)?;
        if h.channels() != 3 {
            return Err(format!("{} planes for RGB, expected 3", h.channels()));
        }
        Ok(())
    })();
    case("RGB input", r);
    // The same bytes on one thread as on many.
    let r = (|| {
        let img = zone_plate(48);
        let many = sized(img.clone())?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .map_err(|e| e.to_string())?;
        let one = pool.install(|| sized(img))?;
        if one == many {
            Ok(())
        } else {
            Err("output depends on the thread count".to_string())
        }
    })();
    case("1 thread = many threads", r);
    out
}

/// Measures one method.
pub fn measure(key: &str, method: &dyn Method, opts: &StabilityOptions) -> Result<Stability> {
    let s = opts.size.max(8);
    let tone = tone_curve(method, s)?;

    let near = |v: f64| linear_to_srgb8(v);
    let tall = |code: u8| Image::gray8(s, 2 * s, vec![code; 2 * s * s]);
    let startup_white = first_dot_row(&run(method, &tall(near(63.0 / 64.0)))?, true);
    let startup_black = first_dot_row(&run(method, &tall(near(1.0 / 64.0)))?, false);

    let texture = [(1usize, 2usize), (1, 3), (1, 4)]
        .iter()
        .map(|&(a, b)| {
            let v = a as f64 / b as f64;
            let h = run(method, &linear16(s, s, |_, _| v))?;
            let q = quality::compare(
                &Reflectance::constant(s, s, v as f32),
                &quality::halftone_reflectance(&h),
                &opts.view,
            )?;
            Ok(Texture {
                fraction: format!("{a}/{b}"),
                period: period(&h),
                hvs_psnr_db: q.hvs_psnr_db,
            })
        })
        .collect::<Result<Vec<_>>>()?;

    let clumping = clumping(&run(method, &linear16(s, s, |_, _| 7.0 / 8.0))?);

    let zp = zone_plate(s);
    let zh = run(method, &zp)?;
    let mut orig = quality::image_reflectance(&zp);
    let (kx, ky) = (zh.width / s, zh.height / s);
    if (kx, ky) != (1, 1) {
        orig = orig.enlarge(kx, ky);
    }
    let got = quality::halftone_reflectance(&zh).luminance();
    let cutoff = 1.0 / (16.0 * kx.max(ky) as f64);
    let lf = quality::filtered_mse(
        &orig.planes[0],
        &got.planes[0],
        zh.width,
        zh.height,
        16,
        &|f| if f < cutoff { 1.0 } else { 0.0 },
    );

    let grad = ramp8(s, s);
    let Samples::U8(codes) = &grad.planes[0] else {
        unreachable!()
    };
    let up = Image::gray8(s, s, codes.iter().map(|&c| c.saturating_add(1)).collect());
    let (a, b) = (run(method, &grad)?, run(method, &up)?);
    let changed: usize = (0..a.channels())
        .map(|c| {
            a.levels_of(c)
                .iter()
                .zip(b.levels_of(c))
                .filter(|(x, y)| **x != *y)
                .count()
        })
        .sum();
    let flicker = changed as f64 / (a.width * a.height * a.channels()).max(1) as f64;

    Ok(Stability {
        key: key.into(),
        method: method.name(),
        tone,
        startup_white,
        startup_black,
        texture,
        clumping,
        moire_lf_psnr_db: quality::psnr_db(lf),
        flicker,
        edge_cases: edge_cases(method),
    })
}

fn fmt_rows(r: Option<usize>) -> String {
    r.map_or("never".into(), |r| r.to_string())
}

/// The stability table as CSV, one row a method.
pub fn to_csv(results: &[Stability]) -> String {
    let mut s = String::from(
        "key,method,tone_max_error,tone_mean_error,worst_code,startup_white_rows,\
         startup_black_rows,period_1_2,period_1_3,period_1_4,texture_psnr_1_2,\
         texture_psnr_1_3,texture_psnr_1_4,clumping,moire_lf_psnr_db,flicker,edge_cases_failed\n",
    );
    for r in results {
        let per = |i: usize| {
            r.texture
                .get(i)
                .and_then(|t| t.period)
                .map_or("none".into(), |[x, y]| format!("{x}x{y}"))
        };
        let tp = |i: usize| r.texture.get(i).map_or(f64::NAN, |t| t.hvs_psnr_db);
        let failed: Vec<&str> = r
            .edge_cases
            .iter()
            .filter(|e| !e.ok)
            .map(|e| e.case.as_str())
            .collect();
        s.push_str(&format!(
            "{},\"{}\",{:.5},{:.5},{},{},{},{},{},{},{:.2},{:.2},{:.2},{:.3},{:.2},{:.4},\"{}\"\n",
            r.key,
            r.method,
            r.tone.max_error,
            r.tone.mean_error,
            r.tone.worst_code,
            fmt_rows(r.startup_white),
            fmt_rows(r.startup_black),
            per(0),
            per(1),
            per(2),
            tp(0),
            tp(1),
            tp(2),
            r.clumping,
            r.moire_lf_psnr_db,
            r.flicker,
            failed.join("; ")
        ));
    }
    s
}

/// The stability table as Markdown, for a terminal or the README.
pub fn to_markdown(results: &[Stability]) -> String {
    let mut s = String::from(
        "| method | tone max err (code) | mean err | start-up rows white/black | period 1/2, 1/3, 1/4 | clumping | moiré LF dB | flicker | edge cases |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for r in results {
        let periods: Vec<String> = r
            .texture
            .iter()
            .map(|t| t.period.map_or("–".into(), |[x, y]| format!("{x}×{y}")))
            .collect();
        let failed = r.edge_cases.iter().filter(|e| !e.ok).count();
        s.push_str(&format!(
            "| {} | {:.3} ({}) | {:.4} | {} / {} | {} | {:.2} | {:.1} | {:.1}% | {} |\n",
            r.key,
            r.tone.max_error,
            r.tone.worst_code,
            r.tone.mean_error,
            fmt_rows(r.startup_white),
            fmt_rows(r.startup_black),
            periods.join(", "),
            r.clumping,
            r.moire_lf_psnr_db,
            100.0 * r.flicker,
            if failed == 0 {
                "all pass".to_string()
            } else {
                format!("{failed} failed")
            }
        ));
    }
    s
}

/// Signed tone error to a colour: blue too dark, red too light, white right; saturates at
/// ±`scale`.
fn error_colour(e: f64, scale: f64) -> plotters::style::RGBColor {
    let t = (e / scale).clamp(-1.0, 1.0);
    let fade = |t: f64| (255.0 * (1.0 - t.abs())).round() as u8;
    if t < 0.0 {
        plotters::style::RGBColor(fade(t), fade(t), 255)
    } else {
        plotters::style::RGBColor(255, fade(t), fade(t))
    }
}

/// Draws the heatmap (method × grey level, colour = tone error) as SVG and PNG.
pub fn write_heatmap(results: &[Stability], svg: &Path, png: &Path) -> Result<()> {
    use plotters::prelude::*;
    crate::lab::bench::register_chart_font()?;
    let size = (1040u32, 120 + 28 * results.len().max(1) as u32);
    draw_heatmap(SVGBackend::new(svg, size).into_drawing_area(), results).map_err(|m| {
        Error::Encode {
            path: svg.into(),
            msg: m,
        }
    })?;
    let mut rgb = vec![0u8; (size.0 * size.1 * 3) as usize];
    draw_heatmap(
        BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        results,
    )
    .map_err(|m| Error::Encode {
        path: png.into(),
        msg: m,
    })?;
    crate::lab::bench::write_rgb_png(png, size, &rgb)
}

fn draw_heatmap<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    results: &[Stability],
) -> std::result::Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    let rows = results.len().max(1);
    let height = root.dim_in_pixel().1 as i32;
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let (main, legend) = root.split_horizontally(880);
    let mut chart = ChartBuilder::on(&main)
        .caption(
            "Tone error by grey level (output − input reflectance)",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(170)
        .build_cartesian_2d(0i32..256, (0..rows as i32 - 1).into_segmented())
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("input level (8-bit sRGB code)")
        .y_labels(rows)
        .y_label_formatter(&|v| match v {
            // First method on top.
            SegmentValue::CenterOf(i) => results
                .get(rows - 1 - *i as usize)
                .map_or(String::new(), |r| r.key.clone()),
            _ => String::new(),
        })
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(|x| e(&x))?;
    for (i, r) in results.iter().enumerate() {
        let i = (rows - 1 - i) as i32;
        chart
            .draw_series(r.tone.errors().iter().enumerate().map(|(c, &err)| {
                Rectangle::new(
                    [
                        (c as i32, SegmentValue::Exact(i)),
                        (c as i32 + 1, SegmentValue::Exact(i + 1)),
                    ],
                    error_colour(err, HEATMAP_SCALE).filled(),
                )
            }))
            .map_err(|x| e(&x))?;
    }
    // The colour scale.
    let steps = 40;
    let top = 40;
    let bar_h = (height - 100).max(60);
    for k in 0..steps {
        let v = HEATMAP_SCALE * (1.0 - 2.0 * k as f64 / (steps - 1) as f64);
        let y0 = top + bar_h * k / steps;
        let y1 = top + bar_h * (k + 1) / steps;
        legend
            .draw(&Rectangle::new(
                [(10, y0), (34, y1)],
                error_colour(v, HEATMAP_SCALE).filled(),
            ))
            .map_err(|x| e(&x))?;
    }
    let style = ("sans-serif", 12).into_font();
    for (txt, y) in [
        (format!("+{HEATMAP_SCALE} too light"), top),
        ("0".to_string(), top + bar_h / 2),
        (format!("−{HEATMAP_SCALE} too dark"), top + bar_h),
    ] {
        legend
            .draw(&Text::new(txt, (40, y - 6), style.clone()))
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// Tone error at which the heatmap's colours saturate.
const HEATMAP_SCALE: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn period_of_a_checkerboard() {
        let mut h = Halftone::new(16, 16, 1, 2);
        for y in 0..16 {
            for x in 0..16 {
                h.set(0, x, y, ((x + y) % 2) as u8);
            }
        }
        assert_eq!(period(&h), Some([2, 2]));
        assert_eq!(clumping(&h), 1.0); // diagonal neighbours touch
        assert_eq!(first_dot_row(&h, true), Some(0));
    }

    #[test]
    fn isolated_dots_do_not_clump() {
        let mut h = Halftone::new(16, 16, 1, 2);
        for y in 0..16 {
            for x in 0..16 {
                h.set(0, x, y, !(x % 4 == 0 && y % 4 == 0) as u8);
            }
        }
        assert_eq!(clumping(&h), 0.0);
        assert_eq!(period(&h), Some([4, 4]));
    }
}
