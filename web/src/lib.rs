//! The halftone library in the browser: decode an image once, halftone it as the options
//! change, show it, measure it and encode it in every format the command line writes.
//!
//! Options arrive as JSON with the command line's names (`dot-gain` or `dot_gain`); every
//! conversion goes through the library's own [`halftone::Converter`], so the bytes of
//! [`Rendered::encode`] are the bytes `halftone convert` writes with the same flags.

use wasm_bindgen::prelude::*;

mod options;

use halftone::io::Format;
use halftone::raster::{ColorKind, Samples};
use halftone::tone::Encoding;
use halftone::{Color, Converter, Halftone, Image, InkColours, Input, Options};

pub use options::parse_options;

/// An error for JavaScript: the library's one-line message.
fn js(e: impl std::fmt::Display) -> JsError {
    JsError::new(&e.to_string())
}

/// A decoded image, kept while the options change.
#[wasm_bindgen]
pub struct Source {
    image: Image,
    /// The last options and the converter built from them: screens, masks and DBS tables
    /// are built once, not on every render with the same options.
    last: std::cell::RefCell<Option<(String, std::rc::Rc<Converter>)>>,
}

#[wasm_bindgen]
impl Source {
    /// Decodes an encoded image file (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM), refusing one
    /// of more than `max_pixels` pixels from its header, before decoding.
    #[wasm_bindgen(constructor)]
    pub fn new(bytes: &[u8], max_pixels: f64) -> Result<Source, JsError> {
        let opts = Options {
            max_pixels: max_pixels as u64,
            ..Options::default()
        };
        let image = halftone::read_whole(Input::Bytes(bytes.to_vec()), &opts).map_err(js)?;
        Ok(Source {
            image,
            last: Default::default(),
        })
    }

    /// Width in pixels.
    #[wasm_bindgen(getter)]
    pub fn width(&self) -> usize {
        self.image.width
    }

    /// Height in pixels.
    #[wasm_bindgen(getter)]
    pub fn height(&self) -> usize {
        self.image.height
    }

    /// True for a colour image.
    #[wasm_bindgen(getter)]
    pub fn color(&self) -> bool {
        self.image.color == ColorKind::Rgb
    }

    /// The image as 8-bit RGBA for a canvas.
    pub fn rgba(&self) -> Vec<u8> {
        image_rgba(&self.image)
    }

    /// Halftones the image with `options` (JSON, the command line's names).
    pub fn convert(&self, options: &str) -> Result<Rendered, JsError> {
        let cached = match &*self.last.borrow() {
            Some((json, conv)) if json == options => Some(conv.clone()),
            _ => None,
        };
        let conv = match cached {
            Some(c) => c,
            None => {
                let c = std::rc::Rc::new(converter(options)?);
                *self.last.borrow_mut() = Some((options.to_string(), c.clone()));
                c
            }
        };
        render(&self.image, &conv)
    }
}

/// Halftones one encoded image file with `options` (JSON): decode and convert in one call.
#[wasm_bindgen]
pub fn convert(bytes: &[u8], options: &str) -> Result<Rendered, JsError> {
    let conv = converter(options)?;
    let image = halftone::read_whole(Input::Bytes(bytes.to_vec()), conv.options()).map_err(js)?;
    render(&image, &conv)
}

fn converter(options: &str) -> Result<Converter, JsError> {
    let mut opts = parse_options(options).map_err(|e| JsError::new(&e))?;
    if opts.format.is_none() {
        // Encoding options (page, head width) do not depend on it; the library wants one
        // only to name a file's format.
        opts.format = Some(Format::Png);
    }
    Converter::new(&opts).map_err(js)
}

fn render(image: &Image, conv: &Converter) -> Result<Rendered, JsError> {
    let opts = conv.options().clone();
    let (halftone, preview) = if opts.color == Color::Cmyk {
        let p = conv.plates(Input::Image(image.clone())).map_err(js)?;
        (p.halftone, p.preview)
    } else {
        (conv.convert(Input::Image(image.clone())).map_err(js)?, None)
    };
    Ok(Rendered {
        halftone,
        preview,
        opts,
    })
}

/// A halftone made in the browser.
#[wasm_bindgen]
pub struct Rendered {
    halftone: Halftone,
    preview: Option<(usize, usize, Vec<u8>)>,
    opts: Options,
}

/// Colours of the process inks at full coverage, for the on-screen composite of plates
/// (approximate sRGB of coated-paper solids).
const INK_RGB: [[f32; 3]; 4] = [
    [0.0, 0.62, 0.88],
    [0.89, 0.0, 0.49],
    [1.0, 0.93, 0.0],
    [0.14, 0.12, 0.13],
];

#[wasm_bindgen]
impl Rendered {
    /// Width in pixels.
    #[wasm_bindgen(getter)]
    pub fn width(&self) -> usize {
        self.halftone.width
    }

    /// Height in pixels.
    #[wasm_bindgen(getter)]
    pub fn height(&self) -> usize {
        self.halftone.height
    }

    /// Levels a channel.
    #[wasm_bindgen(getter)]
    pub fn levels(&self) -> u16 {
        self.halftone.levels
    }

    /// Planes: 1 grey (or palette indices), 3 RGB, 4 CMYK plates.
    #[wasm_bindgen(getter)]
    pub fn planes(&self) -> usize {
        self.halftone.channels()
    }

    /// The level of every pixel of `plane`, one byte each, row-major (0 = darkest or full
    /// ink; palette indices with a palette).
    pub fn level_indices(&self, plane: usize) -> Result<Vec<u8>, JsError> {
        if plane >= self.halftone.channels() {
            return Err(JsError::new(&format!(
                "plane {plane}: the halftone has {}",
                self.halftone.channels()
            )));
        }
        Ok(self.halftone.levels_of(plane))
    }

    /// The palette as `[r, g, b, r, g, b, …]`, empty without one.
    pub fn palette(&self) -> Vec<u8> {
        self.halftone
            .palette
            .iter()
            .flatten()
            .flat_map(|c| c.iter().copied())
            .collect()
    }

    /// 8-bit RGBA for display. `view`: `""` or `composite` for the halftone itself (CMYK:
    /// the four plates printed over each other), `cyan`…`black` for one plate.
    pub fn rgba(&self, view: &str) -> Result<Vec<u8>, JsError> {
        let h = &self.halftone;
        let n = h.width * h.height;
        let mut out = vec![255u8; n * 4];
        let display = if self.opts.linearize {
            Encoding::Srgb
        } else {
            Encoding::Linear
        };
        let codes: Vec<u8> = (0..h.levels.min(256))
            .map(|k| halftone::io::level_code(k as u8, h.levels, 255, display) as u8)
            .collect();
        let mut row = vec![0u8; h.width];
        let plate = match view {
            "" | "composite" => None,
            name => Some(
                halftone::options::INKS
                    .iter()
                    .position(|i| *i == name)
                    .filter(|&i| i < h.channels() && h.channels() == 4)
                    .ok_or_else(|| JsError::new(&format!("no view '{name}' of this halftone")))?,
            ),
        };
        if let Some(c) = plate {
            for y in 0..h.height {
                h.unpack_row(c, y, &mut row);
                for (x, &k) in row.iter().enumerate() {
                    let v = codes[k as usize];
                    let o = &mut out[(y * h.width + x) * 4..][..3];
                    o.copy_from_slice(&[v, v, v]);
                }
            }
            return Ok(out);
        }
        // A device's inks are shown in the colours its PNG is written in: measured (what
        // the panel shows) or nominal (what the driver expects).
        let nominal = self
            .device()?
            .filter(|_| self.opts.ink_colours == InkColours::Nominal)
            .map(|d| d.nominal_colours());
        match (h.channels(), nominal.as_ref().or(h.palette.as_ref())) {
            (1, Some(pal)) => {
                for y in 0..h.height {
                    h.unpack_row(0, y, &mut row);
                    for (x, &k) in row.iter().enumerate() {
                        let c = pal.get(k as usize).copied().unwrap_or([255, 0, 255]);
                        out[(y * h.width + x) * 4..][..3].copy_from_slice(&c);
                    }
                }
            }
            (1, None) | (3, _) => {
                for c in 0..3 {
                    let p = if h.channels() == 1 { 0 } else { c };
                    for y in 0..h.height {
                        h.unpack_row(p, y, &mut row);
                        for (x, &k) in row.iter().enumerate() {
                            out[(y * h.width + x) * 4 + c] = codes[k as usize];
                        }
                    }
                }
            }
            (4, _) => {
                // Ink coverage of each plate, multiplied as transparent inks over paper.
                let mut acc = vec![[1.0f32; 3]; n];
                let top = (h.levels - 1).max(1) as f32;
                for (c, ink) in INK_RGB.iter().enumerate() {
                    for y in 0..h.height {
                        h.unpack_row(c, y, &mut row);
                        for (x, &k) in row.iter().enumerate() {
                            let cover = 1.0 - k as f32 / top;
                            let a = &mut acc[y * h.width + x];
                            for (v, i) in a.iter_mut().zip(ink) {
                                *v *= 1.0 - cover * (1.0 - i);
                            }
                        }
                    }
                }
                for (o, a) in out.chunks_exact_mut(4).zip(&acc) {
                    for (d, v) in o.iter_mut().zip(a) {
                        *d = (v * 255.0).round() as u8;
                    }
                }
            }
            (c, _) => return Err(JsError::new(&format!("cannot show {c} planes"))),
        }
        Ok(out)
    }

    /// The press's view of CMYK plates (with the `preview` option): `[width, height]`.
    pub fn preview_size(&self) -> Vec<u32> {
        match &self.preview {
            Some((w, h, _)) => vec![*w as u32, *h as u32],
            None => vec![],
        }
    }

    /// The press's view as RGBA, empty without one.
    pub fn preview_rgba(&self) -> Vec<u8> {
        match &self.preview {
            Some((_, _, rgb)) => rgb
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            None => vec![],
        }
    }

    /// The press's view as a PNG file, as `--preview FILE.png` writes it.
    pub fn preview_png(&self) -> Result<Vec<u8>, JsError> {
        let Some(p) = &self.preview else {
            return Err(JsError::new(
                "no preview: set the preview option with color cmyk",
            ));
        };
        let plates = halftone::Plates {
            halftone: Halftone::new(1, 1, 1, 2),
            preview: Some(p.clone()),
            report: halftone::Report {
                input: (0, 0),
                output: (0, 0),
                streamed: false,
                band_rows: 0,
                bands: 0,
                estimate: 0,
                assumed_dpi: None,
            },
        };
        plates
            .preview_png()
            .map_err(js)?
            .ok_or_else(|| JsError::new("no preview"))
    }

    /// The files `halftone convert` writes for `format` (`png`, `pbm`, `tiff`, `pdf`,
    /// `ps`, `pcl`, `escpos`, `zpl`, …), as `[name suffix, bytes]` pairs: one file, or
    /// with CMYK plates one a plate (`-cyan` …), except PDF, which holds all four.
    pub fn encode_files(&self, format: &str) -> Result<js_sys_free::Files, JsError> {
        let f = Format::from_name(format).ok_or_else(|| {
            JsError::new(&format!(
                "'{format}' is not a format halftone writes; formats: {}",
                Format::WRITABLE.join(", ")
            ))
        })?;
        let opts = Options {
            format: Some(f),
            ..self.opts.clone()
        };
        let h = &self.halftone;
        let mut files = js_sys_free::Files::default();
        if opts.color != Color::Cmyk || f == Format::Pdf {
            files
                .items
                .push((String::new(), halftone::encode(h, f, &opts).map_err(js)?));
            return Ok(files);
        }
        for (c, ink) in halftone::options::INKS.iter().enumerate() {
            let bytes = if f == Format::Tiff {
                halftone::press::plates::plate_tiff(h, c, ink, opts.dpi).map_err(js)?
            } else {
                halftone::encode(&halftone::press::plates::plate(h, c), f, &opts).map_err(js)?
            };
            files.items.push((format!("-{ink}"), bytes));
        }
        Ok(files)
    }

    /// The one file `halftone convert` writes for `format` (an error for CMYK plates in
    /// any format but PDF: use [`Rendered::encode_files`]).
    pub fn encode(&self, format: &str) -> Result<Vec<u8>, JsError> {
        let mut files = self.encode_files(format)?;
        if files.items.len() != 1 {
            return Err(JsError::new(
                "CMYK plates are four files in this format: use encode_files",
            ));
        }
        Ok(files.items.pop().expect("one file").1)
    }

    /// `compare`'s figures for this halftone against `source` (resized and turned as the
    /// options asked), viewed at `dpi` from `distance` inches, as JSON.
    pub fn compare(&self, source: &Source, dpi: f64, distance: f64) -> Result<String, JsError> {
        if self.halftone.channels() == 4 {
            return Err(JsError::new(
                "compare measures grey, RGB and palette halftones, not CMYK plates",
            ));
        }
        let original = self.resized_source(source)?;
        let view = halftone::quality::Viewing::new(dpi, distance).map_err(js)?;
        let q =
            halftone::quality::compare_halftone(&original, &self.halftone, &view).map_err(js)?;
        serde_json::to_string(&q).map_err(js)
    }

    /// `compare --device`'s figures for a halftone made for a device, against `source`
    /// resized and turned as the options asked, as JSON: `device`, `pixels_per_degree`,
    /// `de2000` (S-CIELAB mean CIEDE2000 for a viewer adapted to the panel's white and
    /// black), `de76` (ΔE*ab) and `lightness_ratio` (mean L*, displayed / original). The
    /// displayed pixels are the inks' measured colours, whatever `ink-colours` says, as in
    /// the PNG `convert --device` writes by default.
    pub fn compare_device(&self, source: &Source) -> Result<String, JsError> {
        let d = self.device()?.ok_or_else(|| {
            JsError::new("compare_device measures a halftone made for a device: set `device`")
        })?;
        let h = &self.halftone;
        if h.channels() != 1 || h.palette.is_none() {
            return Err(JsError::new(&format!(
                "compare_device: the halftone is not one of {}'s inks",
                d.name
            )));
        }
        let shown = d.shown_colours();
        let n = h.width * h.height;
        let mut planes = [vec![0u8; n], vec![0u8; n], vec![0u8; n]];
        let mut row = vec![0u8; h.width];
        for y in 0..h.height {
            h.unpack_row(0, y, &mut row);
            for (x, &k) in row.iter().enumerate() {
                let c = shown.get(k as usize).ok_or_else(|| {
                    JsError::new(&format!(
                        "ink index {k}: {} has {} inks",
                        d.name,
                        shown.len()
                    ))
                })?;
                for (p, v) in planes.iter_mut().zip(c) {
                    p[y * h.width + x] = *v;
                }
            }
        }
        let displayed = Image {
            width: h.width,
            height: h.height,
            color: ColorKind::Rgb,
            planes: planes.into_iter().map(Samples::U8).collect(),
            encoding: Encoding::Srgb,
            dpi: None,
        };
        let original = self.resized_source(source)?;
        let inks: Vec<[f64; 3]> = d.inks.iter().map(|i| i.shown_linear()).collect();
        let ppd = d.pixels_per_degree();
        let e = halftone::scielab::device_error(&original, &displayed, &inks, ppd).map_err(js)?;
        serde_json::to_string(&serde_json::json!({
            "device": d.name,
            "pixels_per_degree": ppd,
            "de2000": e.de2000,
            "de76": e.de76,
            "lightness_ratio": e.lightness_ratio,
        }))
        .map_err(js)
    }
}

impl Rendered {
    /// The device profile of the options, if any.
    fn device(&self) -> Result<Option<halftone::Device>, JsError> {
        self.opts.device_profile().map_err(js)
    }

    /// The source as the options resized and turned it: the picture the halftone is of.
    fn resized_source(&self, source: &Source) -> Result<Image, JsError> {
        let tone = self.opts.tone().map_err(js)?;
        let mut original = source.image.clone();
        if let Some(plan) =
            halftone::resize::plan(&self.opts.size_request(), original.width, original.height)
                .map_err(js)?
        {
            original = halftone::resize::apply(&original, &plan, &tone).map_err(js)?;
        }
        Ok(original)
    }
}

/// Files for JavaScript without pulling in js-sys: a list read by index.
pub mod js_sys_free {
    use wasm_bindgen::prelude::*;

    /// Encoded files: a name suffix and the bytes of each.
    #[wasm_bindgen]
    #[derive(Default)]
    pub struct Files {
        pub(crate) items: Vec<(String, Vec<u8>)>,
    }

    #[wasm_bindgen]
    impl Files {
        /// How many files.
        #[wasm_bindgen(getter)]
        pub fn length(&self) -> usize {
            self.items.len()
        }

        /// The suffix of file `i`'s name (`""`, or `-cyan` … for plates).
        pub fn suffix(&self, i: usize) -> String {
            self.items.get(i).map(|f| f.0.clone()).unwrap_or_default()
        }

        /// The bytes of file `i`.
        pub fn bytes(&self, i: usize) -> Vec<u8> {
            self.items.get(i).map(|f| f.1.clone()).unwrap_or_default()
        }
    }
}

/// The names the page offers, as JSON: methods, kernels, palettes, masks, presets, spots,
/// formats, colours, contents, and the built-in e-paper devices (size, ppi, rotation, inks
/// in index order with their shown and nominal colours, the panel encodings each takes)
/// with the methods, intents, ink colours and panel formats that go with them; `lists`, the
/// library's lists as every door shows them (`halftone options --json`).
#[wasm_bindgen]
pub fn listings() -> String {
    let lists = halftone::options::Lists::get();
    // The buffers panels take go with a device; clips (GIF, Y4M, APNG) are the command line's; the
    // rest are offered as downloads, by their one name each.
    let panel_formats: Vec<&str> = Format::ALL
        .iter()
        .filter(|f| f.is_panel_buffer())
        .map(|f| f.name())
        .collect();
    // PNG first: the page's first download is the picture as it looks.
    let formats: Vec<&str> = std::iter::once(Format::Png)
        .chain(Format::ALL.iter().copied().filter(|&f| f != Format::Png))
        .filter(|f| !f.is_panel_buffer() && !f.is_clip())
        .map(|f| f.name())
        .collect();
    let presets = halftone::preset::Presets::builtin();
    let presets: Vec<serde_json::Value> = presets
        .by_name
        .iter()
        .map(|(name, p)| {
            serde_json::json!({
                "name": name,
                "description": p.description,
                "format": p.format().map(|f| f.name()),
            })
        })
        .collect();
    let devices: Vec<serde_json::Value> = halftone::Device::builtin_names()
        .filter_map(halftone::Device::builtin)
        .map(|d| {
            let hex = |c: [u8; 3]| format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2]);
            serde_json::json!({
                "name": d.name,
                "description": d.description,
                "width": d.width,
                "height": d.height,
                "ppi": d.ppi,
                "rotation": d.rotation,
                "viewing_distance_cm": d.viewing_distance_cm,
                "colours": d.colours.name(),
                "encodings": d.encodings.iter().map(|f| f.name()).collect::<Vec<_>>(),
                "inks": d.inks.iter().map(|i| serde_json::json!({
                    "name": i.name,
                    "code": i.code,
                    "shown": hex(i.shown()),
                    "nominal": hex(i.nominal),
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    serde_json::json!({
        "methods": lists.methods,
        "devices": devices,
        "device_methods": ["diffuse", "dbs", "ordered"],
        "intents": lists.intents,
        "ink_colours": InkColours::NAMES,
        "panel_formats": panel_formats,
        "kernels": lists.kernels,
        "palettes": lists.palettes,
        "masks": lists.masks,
        "presets": presets,
        "spots": lists.spots,
        "formats": formats,
        "colors": lists.colors,
        "contents": lists.contents,
        "lists": lists,
        "version": env!("CARGO_PKG_VERSION"),
    })
    .to_string()
}

/// An image's planes as 8-bit RGBA.
fn image_rgba(img: &Image) -> Vec<u8> {
    let n = img.width * img.height;
    let mut out = vec![255u8; n * 4];
    // Linear-light codes are shown through the sRGB curve, as a viewer would.
    let to8 = |v: f64| -> u8 {
        let v = match img.encoding {
            Encoding::Srgb => v,
            Encoding::Linear => halftone::tone::linear_to_srgb(v),
        };
        (v * 255.0).round().clamp(0.0, 255.0) as u8
    };
    let lut8: Vec<u8> = (0..256).map(|c| to8(c as f64 / 255.0)).collect();
    let lut16: Vec<u8> = match img.planes.first() {
        Some(Samples::U16(_)) => (0..65536).map(|c| to8(c as f64 / 65535.0)).collect(),
        _ => Vec::new(),
    };
    let chans = img.planes.len();
    for c in 0..3 {
        let p = &img.planes[if chans == 1 { 0 } else { c.min(chans - 1) }];
        match p {
            Samples::U8(v) => {
                for (i, &s) in v.iter().enumerate() {
                    out[i * 4 + c] = lut8[s as usize];
                }
            }
            Samples::U16(v) => {
                for (i, &s) in v.iter().enumerate() {
                    out[i * 4 + c] = lut16[s as usize];
                }
            }
        }
    }
    out
}
