//! The speed × accuracy runner: every registered method on a set of images, its median
//! throughput and its quality figures, and the chart that puts them side by side.

use std::path::Path;
use std::sync::OnceLock;
use std::time::Instant;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::method::Method;
use crate::printer_model::PrinterModel;
use crate::quality::{self, Quality, Viewing};
use crate::raster::{ColorKind, Image};
use crate::tone::{linear_to_srgb8, ToneOptions};

/// A registry entry: a short key (used by `--methods`) and the configured method.
pub type Entry = (String, Box<dyn Method>);

/// Every configured method of [`crate::options::registry`], built.
pub fn registry() -> Vec<Entry> {
    crate::options::registry()
        .into_iter()
        .map(|(key, o)| {
            // The registry's settings are fixed and valid; a failure here is a bug in it.
            let m = o
                .method()
                .unwrap_or_else(|e| panic!("registry entry {key}: {e}"));
            (key.to_string(), m)
        })
        .collect()
}

/// The registry entries whose key equals, or starts with, one of `wanted` followed by `-`
/// (`pattern` selects every pattern variant); an unknown name is an error listing the keys.
pub fn select(registry: Vec<Entry>, wanted: &[String]) -> Result<Vec<Entry>> {
    if wanted.is_empty() {
        return Ok(registry);
    }
    let matches = |key: &str, w: &str| key == w || key.starts_with(&format!("{w}-"));
    for w in wanted {
        if !registry.iter().any(|(k, _)| matches(k, w)) {
            let keys: Vec<&str> = registry.iter().map(|(k, _)| k.as_str()).collect();
            return Err(Error::Invalid(format!(
                "`methods`: no method '{w}'; known: {}",
                keys.join(", ")
            )));
        }
    }
    Ok(registry
        .into_iter()
        .filter(|(k, _)| wanted.iter().any(|w| matches(k, w)))
        .collect())
}

/// The chart font (DejaVu Sans, see assets/DejaVuSans.LICENSE), registered once for the
/// bitmap backend; SVG output names the family and leaves drawing to the viewer.
/// The font charts and sheets are drawn with (DejaVu Sans; its licence is in `assets/`).
pub const CHART_FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Registers [`CHART_FONT`] with plotters as "sans-serif".
pub fn register_chart_font() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, CHART_FONT)
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid("the built-in chart font is invalid".into()))
    }
}

/// An input of the benchmark.
#[derive(Clone, Debug)]
pub struct BenchImage {
    /// Name in reports (file name, or `ramp`).
    pub name: String,
    /// The decoded image.
    pub image: Image,
}

/// A grey ramp, black at the left to white at the right, even steps in sRGB code.
pub fn grey_ramp(width: usize, height: usize) -> Image {
    let row: Vec<u8> = (0..width)
        .map(|x| (x * 255 / width.saturating_sub(1).max(1)) as u8)
        .collect();
    Image::gray8(width, height, row.repeat(height))
}

/// A ramp even in light rather than in code: every reflectance equally often.
pub fn linear_ramp(width: usize, height: usize) -> Image {
    let row: Vec<u8> = (0..width)
        .map(|x| linear_to_srgb8(x as f64 / width.saturating_sub(1).max(1) as f64))
        .collect();
    Image::gray8(width, height, row.repeat(height))
}

/// The images in `dir` down to `max_depth` folder levels (1: the folder itself), by
/// extension, sorted by path.
pub fn images_in(
    dir: &Path,
    read: &crate::io::ReadOptions,
    max_depth: usize,
) -> Result<Vec<BenchImage>> {
    const EXT: &[&str] = crate::io::codec::IMAGE_EXTENSIONS;
    if !dir.is_dir() {
        return Err(Error::io(
            dir,
            std::io::Error::new(std::io::ErrorKind::NotFound, "not a directory"),
        ));
    }
    let mut paths: Vec<_> = walkdir::WalkDir::new(dir)
        .max_depth(max_depth)
        .into_iter()
        .filter_map(|e| e.ok())
        .map(|e| e.into_path())
        .filter(|p| {
            p.is_file()
                && p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| EXT.contains(&e.to_ascii_lowercase().as_str()))
        })
        .collect();
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            Ok(BenchImage {
                name: p
                    .strip_prefix(dir)
                    .unwrap_or(&p)
                    .to_string_lossy()
                    .into_owned(),
                image: crate::io::read_image(&p, read)?,
            })
        })
        .collect()
}

/// The repository's sample pictures, built into the binary so that `bench` (and `sheet`)
/// measure the same pictures from any folder, not only a grey ramp.
pub const EMBEDDED_SAMPLES: &[(&str, &[u8])] = &[
    (
        "color-balls.png",
        include_bytes!("../../samples/color-balls.png"),
    ),
    (
        "ka-series.png",
        include_bytes!("../../samples/ka-series.png"),
    ),
    (
        "kd-series.png",
        include_bytes!("../../samples/kd-series.png"),
    ),
    (
        "ns-series.png",
        include_bytes!("../../samples/ns-series.png"),
    ),
    (
        "polyhedra.png",
        include_bytes!("../../samples/polyhedra.png"),
    ),
    ("raytrace.png", include_bytes!("../../samples/raytrace.png")),
    ("shading.png", include_bytes!("../../samples/shading.png")),
    (
        "warn-studio.png",
        include_bytes!("../../samples/warn-studio.png"),
    ),
];

/// The samples built into the binary ([`EMBEDDED_SAMPLES`]), decoded.
pub fn embedded_images(read: &crate::io::ReadOptions) -> Result<Vec<BenchImage>> {
    EMBEDDED_SAMPLES
        .iter()
        .map(|(name, bytes)| {
            Ok(BenchImage {
                name: name.to_string(),
                image: crate::io::read_image_bytes(bytes, Path::new(name), read)?,
            })
        })
        .collect()
}

/// The default set: the images in `samples` (when it exists, else the same pictures built
/// into the binary) and a grey ramp.
pub fn default_images(samples: &Path, read: &crate::io::ReadOptions) -> Result<Vec<BenchImage>> {
    // The pictures at the top of samples/, not their halftones in samples/halftones/.
    let mut v = if samples.is_dir() {
        images_in(samples, read, 1)?
    } else {
        embedded_images(read)?
    };
    v.push(BenchImage {
        name: "ramp".into(),
        image: grey_ramp(1024, 256),
    });
    Ok(v)
}

/// Shortest timed run, seconds: fast calls are repeated to fill it.
const MIN_RUN: f64 = 0.02;

/// Benchmark settings.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Timed runs per method and image; the median is kept.
    pub runs: usize,
    /// Viewing conditions for the quality figures.
    pub view: Viewing,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            runs: 5,
            view: Viewing::default(),
        }
    }
}

/// One method on one image.
#[derive(Clone, Debug, Serialize)]
pub struct Measurement {
    /// Registry key.
    pub key: String,
    /// The method's own name.
    pub method: String,
    /// Image name.
    pub image: String,
    /// Input megapixels.
    pub megapixels: f64,
    /// Median time of `Method::halftone`, seconds.
    pub median_seconds: f64,
    /// Input megapixels per second at the median.
    pub mp_per_s: f64,
    /// The quality figures.
    pub quality: Quality,
    /// The quality figures of the print under a printer model (`--printer-model`), when one
    /// was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub printed: Option<Quality>,
}

/// One method over all images.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Registry key.
    pub key: String,
    /// The method's own name.
    pub method: String,
    /// Total megapixels over total median time.
    pub mp_per_s: f64,
    /// Mean HVS-PSNR over the images, dB.
    pub hvs_psnr_db: f64,
    /// Mean tone bias.
    pub tone_bias: f64,
    /// Mean L* RMS.
    pub lstar_rms: f64,
    /// On the Pareto front: no other method is both faster and closer.
    pub pareto: bool,
    /// Mean HVS-PSNR as printed under the printer model, dB, when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub printed_hvs_psnr_db: Option<f64>,
    /// Mean tone bias as printed, when a printer model was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub printed_tone_bias: Option<f64>,
}

/// Runs every method on every image: `runs` timed runs of [`Method::halftone`] (input
/// planes prepared beforehand, so only the method is timed; each run repeats the call to
/// last at least 20 ms), then the quality figures of the output. `tick` is called after each method × image.
pub fn run(
    methods: &[Entry],
    images: &[BenchImage],
    opts: &BenchOptions,
    tick: &dyn Fn(&str),
) -> Result<Vec<Measurement>> {
    run_printed(methods, images, opts, None, tick)
}

/// [`run`], and with a printer model also the quality figures of each bilevel halftone as
/// that printer would print it (multi-level and palette outputs get none).
pub fn run_printed(
    methods: &[Entry],
    images: &[BenchImage],
    opts: &BenchOptions,
    printer: Option<&PrinterModel>,
    tick: &dyn Fn(&str),
) -> Result<Vec<Measurement>> {
    let tone = ToneOptions::default();
    let mut out = Vec::new();
    for img in images {
        // Grey output, as `convert` does by default: luminance in linear light first.
        let gray = if img.image.color == ColorKind::Rgb {
            img.image.to_luminance(&tone)
        } else {
            img.image.clone()
        };
        let table = gray.tone_table(&tone);
        let planes = gray.planes(&table);
        let mp = (gray.width * gray.height) as f64 / 1e6;
        for (key, method) in methods {
            // One untimed call gives the output (and warms caches); then each timed run
            // repeats the call enough times to last MIN_RUN, so that a run of a fast method
            // on a small image is not lost in timer and scheduling noise.
            let h = method.halftone(&planes)?;
            let t = Instant::now();
            drop(method.halftone(&planes)?);
            let once = t.elapsed().as_secs_f64().max(1e-7);
            let reps = ((MIN_RUN / once).ceil() as usize).clamp(1, 10_000);
            let mut times = Vec::with_capacity(opts.runs.max(1));
            for _ in 0..opts.runs.max(1) {
                let t = Instant::now();
                for _ in 0..reps {
                    drop(method.halftone(&planes)?);
                }
                times.push(t.elapsed().as_secs_f64() / reps as f64);
            }
            times.sort_by(f64::total_cmp);
            let median = times[times.len() / 2];
            let q = quality::compare_halftone(&img.image, &h, &opts.view)?;
            let printed = match printer {
                Some(p) if h.levels == 2 && h.palette.is_none() => {
                    let mut orig = quality::image_reflectance(&img.image);
                    if img.image.color == ColorKind::Rgb && h.channels() == 1 {
                        orig = orig.luminance();
                    }
                    Some(quality::compare(&orig, &p.print_halftone(&h)?, &opts.view)?)
                }
                _ => None,
            };
            out.push(Measurement {
                key: key.clone(),
                method: method.name(),
                image: img.name.clone(),
                megapixels: mp,
                median_seconds: median,
                mp_per_s: mp / median.max(1e-9),
                quality: q,
                printed,
            });
            tick(&format!("{key} on {}", img.name));
        }
    }
    Ok(out)
}

/// Which points are on the Pareto front when both coordinates are better larger.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(x, y)| {
            !points
                .iter()
                .any(|&(a, b)| a >= x && b >= y && (a > x || b > y))
        })
        .collect()
}

/// One summary per method, in registry order.
pub fn summarise(ms: &[Measurement]) -> Vec<Summary> {
    let mut keys: Vec<&str> = Vec::new();
    for m in ms {
        if !keys.contains(&m.key.as_str()) {
            keys.push(&m.key);
        }
    }
    let mut out: Vec<Summary> = keys
        .iter()
        .map(|k| {
            let mine: Vec<&Measurement> = ms.iter().filter(|m| m.key == *k).collect();
            let n = mine.len() as f64;
            let mean = |f: &dyn Fn(&Measurement) -> f64| mine.iter().map(|m| f(m)).sum::<f64>() / n;
            Summary {
                key: k.to_string(),
                method: mine[0].method.clone(),
                mp_per_s: mine.iter().map(|m| m.megapixels).sum::<f64>()
                    / mine
                        .iter()
                        .map(|m| m.median_seconds)
                        .sum::<f64>()
                        .max(1e-12),
                hvs_psnr_db: mean(&|m| m.quality.hvs_psnr_db),
                tone_bias: mean(&|m| m.quality.tone_bias),
                lstar_rms: mean(&|m| m.quality.lstar_rms),
                pareto: false,
                printed_hvs_psnr_db: mine
                    .iter()
                    .all(|m| m.printed.is_some())
                    .then(|| mean(&|m| m.printed.map_or(0.0, |q| q.hvs_psnr_db))),
                printed_tone_bias: mine
                    .iter()
                    .all(|m| m.printed.is_some())
                    .then(|| mean(&|m| m.printed.map_or(0.0, |q| q.tone_bias))),
            }
        })
        .collect();
    let pts: Vec<(f64, f64)> = out.iter().map(|s| (s.hvs_psnr_db, s.mp_per_s)).collect();
    for (s, p) in out.iter_mut().zip(pareto_front(&pts)) {
        s.pareto = p;
    }
    out
}

/// The measurements as CSV, one row per method × image.
pub fn to_csv(ms: &[Measurement]) -> String {
    let mut s = String::from(
        "key,method,image,megapixels,median_seconds,mp_per_s,hvs_psnr_db,tone_bias,lstar_rms,plain_psnr_db\n",
    );
    for m in ms {
        s.push_str(&format!(
            "{},\"{}\",\"{}\",{:.4},{:.6},{:.2},{:.3},{:.5},{:.3},{:.3}\n",
            m.key,
            m.method,
            m.image.replace('"', "\"\""),
            m.megapixels,
            m.median_seconds,
            m.mp_per_s,
            m.quality.hvs_psnr_db,
            m.quality.tone_bias,
            m.quality.lstar_rms,
            m.quality.plain_psnr_db
        ));
    }
    s
}

/// The summaries as a Markdown table.
pub fn to_markdown(sums: &[Summary]) -> String {
    let mut s = String::from(
        "| method | MP/s | HVS-PSNR dB | tone bias | L* RMS | Pareto |\n|---|---:|---:|---:|---:|:-:|\n",
    );
    for m in sums {
        s.push_str(&format!(
            "| {} | {:.1} | {:.2} | {:+.4} | {:.2} | {} |\n",
            m.key,
            m.mp_per_s,
            m.hvs_psnr_db,
            m.tone_bias,
            m.lstar_rms,
            if m.pareto { "●" } else { "" }
        ));
    }
    s
}

/// The summaries' figures ideal and as printed under `printer`, side by side, as a Markdown
/// table (methods without printed figures, i.e. multi-level ones, are left out).
pub fn to_markdown_printed(sums: &[Summary], printer: &str) -> String {
    let mut s = format!(
        "\nAs printed ({printer}):\n\n| method | HVS-PSNR ideal dB | HVS-PSNR printed dB | \
         tone bias printed |\n|---|---:|---:|---:|\n"
    );
    for m in sums {
        if let (Some(db), Some(bias)) = (m.printed_hvs_psnr_db, m.printed_tone_bias) {
            s.push_str(&format!(
                "| {} | {:.2} | {:.2} | {:+.4} |\n",
                m.key, m.hvs_psnr_db, db, bias
            ));
        }
    }
    s
}

/// Draws throughput (log scale) against HVS-PSNR, a labelled point per method, the Pareto
/// front joined, as SVG and PNG.
pub fn write_chart(sums: &[Summary], view: &Viewing, svg: &Path, png: &Path) -> Result<()> {
    use plotters::prelude::*;
    register_chart_font()?;
    let size = (900u32, 600u32);
    draw_chart(SVGBackend::new(svg, size).into_drawing_area(), sums, view).map_err(|m| {
        Error::Encode {
            path: svg.into(),
            msg: m,
        }
    })?;
    let mut rgb = vec![0u8; (size.0 * size.1 * 3) as usize];
    draw_chart(
        BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        sums,
        view,
    )
    .map_err(|m| Error::Encode {
        path: png.into(),
        msg: m,
    })?;
    write_rgb_png(png, size, &rgb)
}

/// Writes an 8-bit RGB buffer as PNG (the charts' bitmap form).
pub(crate) fn write_rgb_png(path: &Path, (w, h): (u32, u32), rgb: &[u8]) -> Result<()> {
    let enc_err = |e: png::EncodingError| Error::Encode {
        path: path.into(),
        msg: e.to_string(),
    };
    // Encoded first, then written atomically: a failure leaves no half chart.
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(enc_err)?;
    writer.write_image_data(rgb).map_err(enc_err)?;
    writer.finish().map_err(enc_err)?;
    crate::io::write_atomic(path, |out| out.write_all(&bytes))
}

fn draw_chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    sums: &[Summary],
    view: &Viewing,
) -> std::result::Result<(), String> {
    use plotters::prelude::*;
    let e = |x: &dyn std::fmt::Display| x.to_string();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let finite: Vec<&Summary> = sums
        .iter()
        .filter(|s| s.hvs_psnr_db.is_finite() && s.mp_per_s > 0.0)
        .collect();
    // The "as printed" figure of a method, when it has a finite one.
    let printed = |s: &Summary| s.printed_hvs_psnr_db.filter(|v| v.is_finite());
    let (mut x0, mut x1) = finite.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
        let p = printed(s).unwrap_or(s.hvs_psnr_db);
        (a.min(s.hvs_psnr_db).min(p), b.max(s.hvs_psnr_db).max(p))
    });
    let (mut y0, mut y1) = finite.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
        (a.min(s.mp_per_s), b.max(s.mp_per_s))
    });
    if finite.is_empty() {
        (x0, x1, y0, y1) = (0.0, 1.0, 1.0, 10.0);
    }
    let pad = ((x1 - x0) * 0.12).max(1.0);
    (x0, x1) = (x0 - pad, x1 + pad * 1.6);
    // Throughput in log10 on a plain axis, whole decades at the ends: labels land on
    // 1, 10, 100… and the minor lines at 2…9 are drawn by hand.
    let (d0, d1) = ((y0 / 1.5).log10().floor(), (y1 * 1.5).log10().ceil());
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Speed against visual accuracy (up and right is better)",
            ("sans-serif", 20),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, d0..d1)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(format!(
            "HVS-PSNR, dB (Näsänen filter, {} dpi at {} in)",
            view.dpi, view.distance_in
        ))
        .y_desc("throughput, megapixels per second (log)")
        .y_labels((d1 - d0) as usize + 1)
        .y_max_light_lines(0)
        .y_label_formatter(&|v| {
            let p = 10f64.powf(*v);
            if p >= 1.0 {
                format!("{p:.0}")
            } else {
                format!("{p}")
            }
        })
        .x_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|x| e(&x))?;
    let minor = RGBColor(225, 225, 225);
    for d in d0 as i32..d1 as i32 {
        for m in 2..=9 {
            let y = (m as f64).log10() + d as f64;
            chart
                .draw_series(LineSeries::new([(x0, y), (x1, y)], minor))
                .map_err(|x| e(&x))?;
        }
    }
    let mut front: Vec<(f64, f64)> = finite
        .iter()
        .filter(|s| s.pareto)
        .map(|s| (s.hvs_psnr_db, s.mp_per_s.log10()))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    let front_colour = RGBColor(214, 96, 77);
    chart
        .draw_series(LineSeries::new(front, front_colour.stroke_width(2)))
        .map_err(|x| e(&x))?
        .label("Pareto front")
        .legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], front_colour.stroke_width(2))
        });
    let blue = RGBColor(33, 102, 172);
    // As printed: a hollow triangle at the printed HVS-PSNR, the same speed, joined to the
    // method's ideal point by a thin line.
    let grey = RGBColor(150, 150, 150);
    let printed_colour = RGBColor(118, 42, 131);
    let mut any_printed = false;
    for s in &finite {
        if let Some(p) = printed(s) {
            let y = s.mp_per_s.log10();
            chart
                .draw_series(LineSeries::new([(s.hvs_psnr_db, y), (p, y)], grey))
                .map_err(|x| e(&x))?;
            let series = chart
                .draw_series(std::iter::once(TriangleMarker::new(
                    (p, y),
                    6,
                    printed_colour.stroke_width(2),
                )))
                .map_err(|x| e(&x))?;
            if !any_printed {
                series.label("as printed").legend(move |(x, y)| {
                    TriangleMarker::new((x + 10, y), 6, printed_colour.stroke_width(2))
                });
                any_printed = true;
            }
        }
    }
    if any_printed {
        chart
            .draw_series(std::iter::once(Circle::new((x0, d0 - 1.0), 0, blue)))
            .map_err(|x| e(&x))?
            .label("ideal printer")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, blue.filled()));
    }
    // Labels placed greedily, top to bottom: each takes the first offset (right of its point,
    // then left, stepping up and down) whose box overlaps no label placed before and stays
    // inside the plot.
    let (plot_w, _) = chart.plotting_area().dim_in_pixel();
    let plot_left = chart.backend_coord(&(x0, d1)).0;
    let mut placed: Vec<(i32, i32, i32, i32)> = Vec::new();
    let mut order: Vec<&&Summary> = finite.iter().collect();
    order.sort_by(|a, b| b.mp_per_s.total_cmp(&a.mp_per_s));
    for s in order {
        let colour = if s.pareto { front_colour } else { blue };
        let at = (s.hvs_psnr_db, s.mp_per_s.log10());
        let (px, py) = chart.backend_coord(&at);
        let (lw, lh) = (s.key.chars().count() as i32 * 7, 14);
        let candidates = [0, -12, 12, -24, 24, -36, 36, 48]
            .into_iter()
            .flat_map(|dy| [(8, dy - 6), (-8 - lw, dy - 6)]);
        let mut offset = (8, -6);
        for (dx, dy) in candidates {
            let b = (px + dx, py + dy, px + dx + lw, py + dy + lh);
            let inside = b.0 >= plot_left && b.2 <= plot_left + plot_w as i32;
            let free = placed
                .iter()
                .all(|p| b.2 <= p.0 || b.0 >= p.2 || b.3 <= p.1 || b.1 >= p.3);
            if inside && free {
                offset = (dx, dy);
                break;
            }
        }
        placed.push((
            px + offset.0,
            py + offset.1,
            px + offset.0 + lw,
            py + offset.1 + lh,
        ));
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 5, colour.filled())
                    + Text::new(s.key.clone(), offset, ("sans-serif", 13).into_font()),
            ))
            .map_err(|x| e(&x))?;
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.9))
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_the_undominated() {
        let pts = [
            (10.0, 100.0),
            (20.0, 50.0),
            (15.0, 40.0),
            (20.0, 10.0),
            (5.0, 100.0),
        ];
        assert_eq!(pareto_front(&pts), vec![true, true, false, false, false]);
    }

    #[test]
    fn registry_keys_are_unique_and_selectable() {
        let r = registry();
        let mut keys: Vec<&str> = r.iter().map(|(k, _)| k.as_str()).collect();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), r.len());
        let sel = select(registry(), &["pattern".into()]).unwrap();
        assert!(sel.len() >= 2 && sel.iter().all(|(k, _)| k.starts_with("pattern-")));
        let one = select(registry(), &["threshold".into()]).unwrap();
        assert_eq!(one.len(), 2);
        assert!(select(registry(), &["nope".into()]).is_err());
    }
}
