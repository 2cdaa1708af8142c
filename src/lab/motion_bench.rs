//! Methods over time (`halftone bench --motion CLIP`): each method halftones a clip frame
//! by frame as `halftone convert` does (masks that stay put, stable error diffusion or
//! diffusion frame by frame), and is measured against the clip as `compare --clip` measures
//! (per-frame HVS-PSNR, flicker in still areas: [`crate::motion::measure`]) with the time a
//! frame takes; a chart sets flicker against accuracy, each point labelled with its speed.

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::motion::measure::compare_clips;
use crate::motion::{ClipInfo, ClipMethod, Frame, FrameSource};
use crate::options::{Options, Settings};
use crate::quality::Viewing;
use crate::raster::{Halftone, Image};
use crate::tone::Encoding;

/// One method's figures on one clip.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotionRow {
    /// The method's key (see [`methods`]).
    pub key: String,
    /// The method as reports name it.
    pub method: String,
    /// Frames halftoned.
    pub frames: usize,
    /// Halftoning time a frame, milliseconds (the method alone: no decoding or writing).
    pub ms_per_frame: f64,
    /// Mean HVS-PSNR over the measured frames, dB.
    pub hvs_psnr_db: f64,
    /// Share of dots that changed where the input stayed within `noise` codes.
    pub flicker: f64,
}

/// The methods `bench --motion` measures: a key and the options that make it (grey, two
/// levels, every one a method a clip can take).
pub fn methods() -> Vec<(&'static str, Vec<(&'static str, &'static str)>)> {
    vec![
        ("threshold", vec![("method", "threshold")]),
        (
            "ordered-bayer-8",
            vec![("method", "ordered"), ("mask", "bayer-8")],
        ),
        (
            "ordered-blue-noise-64",
            vec![("method", "ordered"), ("mask", "blue-noise-64")],
        ),
        ("screen", vec![("method", "screen")]),
        ("diffuse-stable", vec![("method", "diffuse")]),
        (
            "diffuse-frame",
            vec![("method", "diffuse"), ("temporal", "frame")],
        ),
        (
            "diffuse-jarvis-stable",
            vec![("method", "diffuse"), ("kernel", "jarvis-judice-ninke")],
        ),
    ]
}

/// The options of a [`methods`] entry at `view`'s resolution.
pub fn options_of(pairs: &[(&str, &str)], view: &Viewing) -> Result<Options> {
    let mut s = Settings::new();
    for &(k, v) in pairs {
        s.set(k, v)?;
    }
    s.set("dpi", view.dpi.to_string().as_str())?;
    s.set("distance", view.distance_in.to_string().as_str())?;
    s.finish()
}

/// A clip's frames halftoned as they are read, shown as grey codes (what a GIF of the
/// halftone holds), with the halftoning time kept.
struct Halftoned<'a> {
    src: Box<dyn FrameSource>,
    method: &'a mut ClipMethod,
    spent: Duration,
    frames: usize,
    name: String,
}

impl FrameSource for Halftoned<'_> {
    fn info(&self) -> &ClipInfo {
        self.src.info()
    }

    fn name(&self) -> &Path {
        Path::new(&self.name)
    }

    fn next_frame(&mut self) -> Result<Option<Frame>> {
        let Some(f) = self.src.next_frame()? else {
            return Ok(None);
        };
        let t = Instant::now();
        let h = self.method.next(&f.image)?;
        self.spent += t.elapsed();
        self.frames += 1;
        Ok(Some(Frame {
            image: shown(&h)?,
            delay: f.delay,
        }))
    }
}

/// A one-channel halftone as the grey codes it shows (sRGB).
fn shown(h: &Halftone) -> Result<Image> {
    if h.channels() != 1 || h.palette.is_some() {
        return Err(Error::Invalid(
            "bench --motion measures grey halftones".into(),
        ));
    }
    let codes: Vec<u8> = (0..=255u16.min(h.levels.saturating_sub(1)))
        .map(|k| crate::io::level_code(k as u8, h.levels, 255, Encoding::Srgb) as u8)
        .collect();
    let mut px = Vec::with_capacity(h.width * h.height);
    for y in 0..h.height {
        for x in 0..h.width {
            px.push(codes[h.get(0, x, y) as usize]);
        }
    }
    Ok(Image::gray8(h.width, h.height, px))
}

/// Measures one method (`key`, `opts`) on the clip that `open` opens (twice: once to
/// halftone, once as the original): the frames must come at their own size (the options
/// ask for no resizing).
pub fn measure(
    open: &dyn Fn() -> Result<Box<dyn FrameSource>>,
    key: &str,
    opts: &Options,
    noise: u8,
    every: usize,
    view: &Viewing,
) -> Result<MotionRow> {
    let mut method = ClipMethod::new(opts)?;
    let name = method.name();
    let mut original = open()?;
    let mut halftoned = Halftoned {
        src: open()?,
        method: &mut method,
        spent: Duration::ZERO,
        frames: 0,
        name: format!("{key} of {}", original.name().display()),
    };
    let c = compare_clips(original.as_mut(), &mut halftoned, noise, every, view)?;
    let n = c.hvs_psnr_db.len().max(1) as f64;
    Ok(MotionRow {
        key: key.to_string(),
        method: name,
        frames: c.frames,
        ms_per_frame: halftoned.spent.as_secs_f64() * 1e3 / halftoned.frames.max(1) as f64,
        hvs_psnr_db: c.hvs_psnr_db.iter().sum::<f64>() / n,
        flicker: c.flicker,
    })
}

/// The rows as CSV.
pub fn to_csv(rows: &[MotionRow]) -> String {
    let mut s = String::from("key,method,frames,ms_per_frame,hvs_psnr_db,flicker\n");
    for r in rows {
        s += &format!(
            "{},\"{}\",{},{:.3},{:.3},{:.6}\n",
            r.key, r.method, r.frames, r.ms_per_frame, r.hvs_psnr_db, r.flicker
        );
    }
    s
}

/// The rows as a Markdown table.
pub fn to_markdown(clip: &str, rows: &[MotionRow]) -> String {
    let mut s = format!(
        "Methods over time on {clip} ({} frames)\n\n| method | HVS-PSNR dB | flicker | ms a frame |\n|---|---:|---:|---:|\n",
        rows.first().map_or(0, |r| r.frames)
    );
    for r in rows {
        s += &format!(
            "| {} | {:.2} | {:.4} | {:.2} |\n",
            r.key, r.hvs_psnr_db, r.flicker, r.ms_per_frame
        );
    }
    s
}

/// Writes the chart, flicker (log) against HVS-PSNR, as SVG and PNG.
pub fn write_chart(rows: &[MotionRow], view: &Viewing, svg: &Path, png: &Path) -> Result<()> {
    use plotters::prelude::*;
    super::bench::register_chart_font()?;
    let size = (900u32, 600u32);
    draw(SVGBackend::new(svg, size).into_drawing_area(), rows, view).map_err(|m| {
        Error::Encode {
            path: svg.into(),
            msg: m,
        }
    })?;
    let mut rgb = vec![0u8; (size.0 * size.1 * 3) as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        rows,
        view,
    )
    .map_err(|m| Error::Encode {
        path: png.into(),
        msg: m,
    })?;
    super::bench::write_rgb_png(png, size, &rgb)
}

/// The flicker axis: log10, with a floor for methods that do not flicker at all.
const FLOOR: f64 = 1e-5;

fn draw<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    rows: &[MotionRow],
    view: &Viewing,
) -> std::result::Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let fx = |r: &MotionRow| r.flicker.max(FLOOR).log10();
    let finite: Vec<&MotionRow> = rows.iter().filter(|r| r.hvs_psnr_db.is_finite()).collect();
    let (y0, y1) = finite.iter().fold((f64::MAX, f64::MIN), |(a, b), r| {
        (a.min(r.hvs_psnr_db), b.max(r.hvs_psnr_db))
    });
    let (y0, y1) = if finite.is_empty() {
        (0.0, 1.0)
    } else {
        (y0 - 1.0, y1 + 1.0)
    };
    let (x0, x1) = (FLOOR.log10(), 0.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Flicker against visual accuracy over a clip (up and left is better)",
            ("sans-serif", 20),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1 + 0.9, y0..y1)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(format!(
            "flicker in still areas (log; {FLOOR} and below at the left edge)"
        ))
        .y_desc(format!(
            "HVS-PSNR, dB ({} dpi at {} in)",
            view.dpi, view.distance_in
        ))
        .x_labels(7)
        .x_label_formatter(&|v| format!("{:.0e}", 10f64.powf(*v)))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|x| e(&x))?;
    // Labels from the top down, each moved below the last one it would overlap.
    let mut order = finite.clone();
    order.sort_by(|a, b| b.hvs_psnr_db.total_cmp(&a.hvs_psnr_db));
    let line = (y1 - y0) / 28.0;
    let mut placed: Vec<(f64, f64)> = Vec::new();
    for r in order {
        let p = (fx(r), r.hvs_psnr_db);
        chart
            .draw_series([Circle::new(p, 5, BLUE.filled())])
            .map_err(|x| e(&x))?;
        let mut ly = p.1;
        // At most one move a label placed (each move goes below the one it met).
        for _ in 0..placed.len() {
            match placed
                .iter()
                .find(|&&(x, y)| (x - p.0).abs() < 1.5 && (y - ly).abs() < line * 0.999)
            {
                Some(&(_, y)) => ly = y - line,
                None => break,
            }
        }
        placed.push((p.0, ly));
        chart
            .draw_series([Text::new(
                format!("{} ({:.1} ms)", r.key, r.ms_per_frame),
                (p.0 + 0.06, ly),
                ("sans-serif", 13),
            )])
            .map_err(|x| e(&x))?;
    }
    root.present().map_err(|x| e(&x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::{Delay, Loops};

    /// A clip in memory: a ramp with a patch that moves 3 px a frame.
    struct Moving {
        info: ClipInfo,
        n: usize,
    }

    impl FrameSource for Moving {
        fn info(&self) -> &ClipInfo {
            &self.info
        }
        fn name(&self) -> &Path {
            Path::new("moving")
        }
        fn next_frame(&mut self) -> Result<Option<Frame>> {
            if self.n == 6 {
                return Ok(None);
            }
            let (w, h) = (self.info.width, self.info.height);
            let mut px: Vec<u8> = (0..w * h).map(|i| (i % w * 255 / w) as u8).collect();
            for y in 10..20 {
                for x in 5 + 3 * self.n..20 + 3 * self.n {
                    px[y * w + x] = 240;
                }
            }
            self.n += 1;
            Ok(Some(Frame {
                image: Image::gray8(w, h, px),
                delay: Delay::ms(40),
            }))
        }
    }

    #[test]
    fn stable_methods_flicker_less_than_diffusion_frame_by_frame() {
        let open = || -> Result<Box<dyn FrameSource>> {
            Ok(Box::new(Moving {
                info: ClipInfo {
                    width: 80,
                    height: 60,
                    loops: Loops::Forever,
                    rate: None,
                },
                n: 0,
            }))
        };
        let view = Viewing::default();
        let mut rows = Vec::new();
        for (key, pairs) in methods() {
            let opts = options_of(&pairs, &view).unwrap();
            rows.push(measure(&open, key, &opts, 2, 1, &view).unwrap());
        }
        let row = |k: &str| rows.iter().find(|r| r.key == k).unwrap();
        // Every frame measured; threshold is the poorest (15 dB here), the others above 30.
        assert!(rows.iter().all(|r| r.frames == 6 && r.hvs_psnr_db > 10.0));
        assert!(rows
            .iter()
            .all(|r| r.key == "threshold" || r.hvs_psnr_db > 30.0));
        // Masks: a dot depends on its pixel alone, and the still pixels keep their input.
        for k in ["threshold", "ordered-bayer-8", "ordered-blue-noise-64"] {
            assert_eq!(row(k).flicker, 0.0, "{k}");
        }
        assert!(row("diffuse-stable").flicker < row("diffuse-frame").flicker / 2.0);
        let csv = to_csv(&rows);
        assert_eq!(csv.lines().count(), methods().len() + 1);
        assert!(to_markdown("moving", &rows).contains("| diffuse-stable |"));
    }
}
