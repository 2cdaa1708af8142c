//! `halftone sheet`: a contact sheet of the user's own image through the main methods, a
//! 1:1 crop each, labelled with the method, its HVS-PSNR and its time, so a method is picked
//! by looking rather than by reading tables.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use halftone::io::{self, level_code, ReadOptions};
use halftone::quality::{self, Viewing};
use halftone::raster::{Image, Samples};
use halftone::tone::{linear_to_srgb8, Encoding};
use halftone::{ColorMode, Method, ToneOptions};

use super::progress::Activity;

/// Examples shown by `halftone sheet --help`.
pub const EXAMPLES: &str = "Examples:
  halftone sheet photo.jpg -o sheet.png
  halftone sheet photo.jpg -o sheet-big.png --tile 384 --columns 3
  halftone render raytrace -o raytrace.png && halftone sheet raytrace.png -o raytrace-sheet.png";

/// `halftone sheet` arguments.
#[derive(Args, Debug)]
pub struct SheetArgs {
    /// The image (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM).
    pub input: PathBuf,

    /// The sheet to write (PNG).
    #[arg(long, short = 'o')]
    pub output: PathBuf,

    /// Side of each crop in pixels, shown 1:1 (one halftone pixel = one sheet pixel).
    #[arg(long, default_value_t = 256)]
    pub tile: usize,

    /// Crops a row.
    #[arg(long, default_value_t = 5)]
    pub columns: usize,

    /// Resolution of the print, for HVS-PSNR (pixels per inch).
    #[arg(long, default_value_t = 300.0)]
    pub dpi: f64,

    /// Viewing distance for HVS-PSNR, inches.
    #[arg(long, default_value_t = 12.0)]
    pub distance: f64,

    /// Refuse images larger than this many pixels (checked from the header, before decoding).
    #[arg(long, default_value_t = 1_000_000_000)]
    pub max_pixels: u64,
}

/// Largest side measured: bigger images are measured (and timed) on their centre crop of
/// this size, so the sheet takes seconds, not minutes, on a 24-megapixel photo.
const MEASURE: usize = 2048;

/// Height of the label strip under each crop.
const LABEL: usize = 40;
/// Space around and between crops.
const GAP: usize = 10;

/// The methods on the sheet, the main ones of each family: a label as `convert` names the
/// method, and the key of its configuration in the library's one registry
/// ([`halftone::options::registry`]).
const SHEET: &[(&str, &str)] = &[
    ("diffuse (default)", "diffuse-floyd-steinberg"),
    ("diffuse -k ostromoukhov", "diffuse-ostromoukhov"),
    ("diffuse -k atkinson", "diffuse-atkinson"),
    ("ordered bayer-8", "ordered-bayer-8"),
    ("ordered blue-noise-64", "ordered-blue-noise-64"),
    ("ordered cluster-8", "ordered-cluster-8"),
    ("pattern seed-3x3", "pattern-3x3-fit"),
    ("threshold", "threshold"),
    ("diffuse --levels 4", "diffuse-floyd-steinberg-4"),
];

/// The sheet's methods, each built by the registry's options.
fn methods() -> anyhow::Result<Vec<(String, Box<dyn Method>)>> {
    let registry = halftone::options::registry();
    SHEET
        .iter()
        .map(|&(label, key)| {
            let (_, opts) = registry
                .iter()
                .find(|(k, _)| *k == key)
                .with_context(|| format!("{key}: not in the method registry"))?;
            Ok((label.to_string(), opts.method()?))
        })
        .collect()
}

/// The `w × h` window of `img` at `(x0, y0)`.
fn crop(img: &Image, x0: usize, y0: usize, w: usize, h: usize) -> Image {
    fn window<T: Copy>(v: &[T], stride: usize, x0: usize, y0: usize, w: usize, h: usize) -> Vec<T> {
        (y0..y0 + h)
            .flat_map(|y| v[y * stride + x0..y * stride + x0 + w].iter().copied())
            .collect()
    }
    let planes = img
        .planes
        .iter()
        .map(|p| match p {
            Samples::U8(v) => Samples::U8(window(v, img.width, x0, y0, w, h)),
            Samples::U16(v) => Samples::U16(window(v, img.width, x0, y0, w, h)),
        })
        .collect();
    Image {
        width: w,
        height: h,
        color: img.color,
        planes,
        encoding: img.encoding,
        dpi: img.dpi,
    }
}

/// A centred window of at most `side × side` pixels of a `w × h` image: (x0, y0, w, h).
fn centre(w: usize, h: usize, side: usize) -> (usize, usize, usize, usize) {
    let (cw, ch) = (w.min(side), h.min(side));
    ((w - cw) / 2, (h - ch) / 2, cw, ch)
}

/// One tile of the sheet: 8-bit grey pixels and two lines of label.
struct Tile {
    pixels: Vec<u8>,
    width: usize,
    height: usize,
    title: String,
    figures: String,
}

/// Runs `halftone sheet`.
pub fn run(a: SheetArgs) -> anyhow::Result<ExitCode> {
    if a.tile < 16 || a.tile > 4096 {
        anyhow::bail!("--tile {}: choose 16 to 4096 pixels", a.tile);
    }
    if a.columns == 0 || a.columns > 32 {
        anyhow::bail!("--columns {}: choose 1 to 32", a.columns);
    }
    let ext = a
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if ext.as_deref() != Some("png") {
        anyhow::bail!("{}: the sheet is a PNG; name it .png", a.output.display());
    }
    let view = Viewing::new(a.dpi, a.distance)?;
    let activity = Activity::start(format!("sheet of {}", a.input.display()));
    let img = super::stdio::read_image(
        &a.input,
        &ReadOptions {
            max_pixels: a.max_pixels,
        },
    )?;
    let (mx, my, mw, mh) = centre(img.width, img.height, MEASURE);
    let region = crop(&img, mx, my, mw, mh);
    let tone = ToneOptions::default();
    // The original in linear light, as grey (every method here works on luminance).
    let original = quality::image_reflectance(&region).luminance();
    let (tx, ty, tw, th) = centre(mw, mh, a.tile);

    let mut tiles = vec![Tile {
        pixels: (ty..ty + th)
            .flat_map(|y| {
                original.planes[0][y * mw + tx..y * mw + tx + tw]
                    .iter()
                    .map(|&r| linear_to_srgb8(r as f64))
            })
            .collect(),
        width: tw,
        height: th,
        title: "original (grey)".into(),
        figures: format!("{}x{}", img.width, img.height),
    }];
    let methods = methods()?;
    activity.steps(methods.len() as u64);
    println!("{:<24} {:>9} {:>10}", "method", "HVS-PSNR", "time");
    for (name, method) in &methods {
        activity.set(format!("sheet: {name}"));
        // The best of three runs: the first run of the first method also pays for warming
        // the caches and starting the thread pool, which is not the method's cost.
        let mut secs = f64::INFINITY;
        let mut result = None;
        for _ in 0..3 {
            let start = Instant::now();
            let h = halftone::halftone_image(&region, method.as_ref(), ColorMode::Gray, &tone)?;
            secs = secs.min(start.elapsed().as_secs_f64());
            result = Some(h);
        }
        let h = result.expect("three runs");
        let q = quality::compare(&original, &quality::halftone_reflectance(&h), &view)?;
        let codes: Vec<u8> = (0..h.levels)
            .map(|k| level_code(k as u8, h.levels, 255, Encoding::Srgb) as u8)
            .collect();
        let mut levels = vec![0u8; h.width];
        let mut pixels = Vec::with_capacity(tw * th);
        for y in ty..ty + th {
            h.unpack_row(0, y, &mut levels);
            pixels.extend(levels[tx..tx + tw].iter().map(|&l| codes[l as usize]));
        }
        let ms = secs * 1e3;
        println!("{name:<24} {:>6.2} dB {ms:>7.1} ms", q.hvs_psnr_db);
        tiles.push(Tile {
            pixels,
            width: tw,
            height: th,
            title: name.clone(),
            figures: format!("{:.1} dB  {ms:.1} ms", q.hvs_psnr_db),
        });
        activity.inc();
    }
    if (mw, mh) != (img.width, img.height) {
        println!(
            "(measured and timed on the centre {mw}x{mh} of {}x{})",
            img.width, img.height
        );
    }
    let (w, h, rgb) = compose(&tiles, a.columns, a.tile, &view)?;
    io::write_atomic(&a.output, |out| write_png(out, w, h, &rgb))?;
    drop(activity);
    println!("wrote {} ({w}x{h})", a.output.display());
    Ok(ExitCode::SUCCESS)
}

/// Lays the tiles out on a white sheet with their labels; returns width, height, RGB.
fn compose(
    tiles: &[Tile],
    columns: usize,
    tile: usize,
    view: &Viewing,
) -> anyhow::Result<(usize, usize, Vec<u8>)> {
    let columns = columns.min(tiles.len());
    let rows = tiles.len().div_ceil(columns);
    let cell_w = tile.max(200);
    let footer = 24;
    let width = GAP + columns * (cell_w + GAP);
    let height = GAP + rows * (tile + LABEL + GAP) + footer;
    let mut rgb = vec![255u8; width * height * 3];
    for (i, t) in tiles.iter().enumerate() {
        let (x0, y0) = (
            GAP + (i % columns) * (cell_w + GAP),
            GAP + (i / columns) * (tile + LABEL + GAP),
        );
        for y in 0..t.height {
            for x in 0..t.width {
                let v = t.pixels[y * t.width + x];
                let o = ((y0 + y) * width + x0 + x) * 3;
                rgb[o..o + 3].fill(v);
            }
        }
    }
    let font = ab_glyph::FontRef::try_from_slice(halftone::bench::CHART_FONT)
        .map_err(|e| anyhow::anyhow!("the built-in font: {e}"))?;
    let mut canvas = Canvas {
        rgb: &mut rgb,
        width,
        height,
    };
    for (i, t) in tiles.iter().enumerate() {
        let (x0, y0) = (
            (GAP + (i % columns) * (cell_w + GAP)) as f32,
            (GAP + (i / columns) * (tile + LABEL + GAP) + tile + 3) as f32,
        );
        canvas.text(&font, 15.0, (x0, y0), &t.title, [0, 0, 0]);
        canvas.text(&font, 13.0, (x0, y0 + 18.0), &t.figures, [60, 60, 60]);
    }
    canvas.text(
        &font,
        13.0,
        (GAP as f32, (height - footer + 4) as f32),
        &format!(
            "1:1 crops. HVS-PSNR: error seen at {} dpi from {} in (higher is better); time: halftoning alone.",
            view.dpi, view.distance_in
        ),
        [60, 60, 60],
    );
    Ok((width, height, rgb))
}

/// An RGB buffer that text is drawn on.
struct Canvas<'a> {
    rgb: &'a mut [u8],
    width: usize,
    height: usize,
}

impl Canvas<'_> {
    /// Draws `text` at `size` pixels with its top-left corner at `top_left`: glyphs on one
    /// baseline (the font's ascent below the top), with side bearings and kerning, blended
    /// by coverage. (plotters' bitmap text drops the side bearings and lifts small glyphs
    /// such as "." off the baseline, so the sheet draws its own.)
    fn text(
        &mut self,
        font: &ab_glyph::FontRef<'_>,
        size: f32,
        top_left: (f32, f32),
        text: &str,
        color: [u8; 3],
    ) {
        use ab_glyph::{Font, ScaleFont};
        let scaled = font.as_scaled(size);
        let baseline = top_left.1 + scaled.ascent();
        let mut x = top_left.0;
        let mut prev = None;
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = prev {
                x += scaled.kern(p, id);
            }
            prev = Some(id);
            let glyph = id.with_scale_and_position(size, ab_glyph::point(x, baseline));
            x += scaled.h_advance(id);
            let Some(outline) = font.outline_glyph(glyph) else {
                continue;
            };
            let b = outline.px_bounds();
            outline.draw(|gx, gy, cover| {
                let (px, py) = (b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64);
                if px < 0 || py < 0 || px >= self.width as i64 || py >= self.height as i64 {
                    return;
                }
                let o = (py as usize * self.width + px as usize) * 3;
                let a = cover.clamp(0.0, 1.0);
                for (dst, &c) in self.rgb[o..o + 3].iter_mut().zip(&color) {
                    *dst = (*dst as f32 * (1.0 - a) + c as f32 * a).round() as u8;
                }
            });
        }
    }
}

/// Writes 8-bit RGB as PNG.
fn write_png(out: &mut dyn std::io::Write, w: usize, h: usize, rgb: &[u8]) -> std::io::Result<()> {
    let mut enc = png::Encoder::new(out, w as u32, h as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer
        .write_image_data(rgb)
        .map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)
}
