//! The library's front: inputs, outputs, and one call for each job: an image to a halftone
//! in memory ([`convert`]), to an encoded file, writer or bytes ([`convert_to`],
//! [`convert_to_bytes`]), pages into one multi-page file ([`Book`]), CMYK plates
//! ([`plates`]), and a measure of a halftone against its original ([`compare`]).

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{self, EncodeResult, Format, WriteOptions};
use crate::options::{Color, MethodKind, Options};
use crate::pipeline::{self, Job, Report};
use crate::quality::{Quality, Viewing};
use crate::raster::{Halftone, Image};

/// Where an image comes from.
pub enum Input {
    /// A file (read as a stream when it is a pipe or a device).
    Path(PathBuf),
    /// The bytes of an encoded image file (PNG, JPEG, TIFF, PNM, …).
    Bytes(Vec<u8>),
    /// An encoded image arriving on a stream; `name` is used in error messages.
    Reader {
        /// The stream.
        reader: Box<dyn Read + Send>,
        /// What to call it in messages (`<stdin>`, a URL, …).
        name: String,
    },
    /// An image already decoded.
    Image(Image),
}

impl Input {
    /// The name used in messages.
    pub fn name(&self) -> PathBuf {
        match self {
            Input::Path(p) => p.clone(),
            Input::Bytes(_) => PathBuf::from("<bytes>"),
            Input::Reader { name, .. } => PathBuf::from(name),
            Input::Image(_) => PathBuf::from("<image>"),
        }
    }
}

impl From<&Path> for Input {
    fn from(p: &Path) -> Input {
        Input::Path(p.to_path_buf())
    }
}

impl From<PathBuf> for Input {
    fn from(p: PathBuf) -> Input {
        Input::Path(p)
    }
}

impl From<&str> for Input {
    /// A path.
    fn from(p: &str) -> Input {
        Input::Path(PathBuf::from(p))
    }
}

impl From<Vec<u8>> for Input {
    fn from(b: Vec<u8>) -> Input {
        Input::Bytes(b)
    }
}

impl From<&[u8]> for Input {
    fn from(b: &[u8]) -> Input {
        Input::Bytes(b.to_vec())
    }
}

impl From<Image> for Input {
    fn from(i: Image) -> Input {
        Input::Image(i)
    }
}

/// Where an encoded halftone goes.
pub enum Output {
    /// A file, replaced atomically (a temporary file in the same folder, then a rename); a
    /// failure leaves the old file, or nothing, behind. Devices and pipes are written
    /// straight.
    Path(PathBuf),
    /// A stream (standard output, a socket, a buffer); `name` is used in error messages.
    Writer {
        /// The stream.
        writer: Box<dyn Write + Send>,
        /// What to call it in messages.
        name: String,
    },
}

impl From<&Path> for Output {
    fn from(p: &Path) -> Output {
        Output::Path(p.to_path_buf())
    }
}

impl From<PathBuf> for Output {
    fn from(p: PathBuf) -> Output {
        Output::Path(p)
    }
}

impl From<&str> for Output {
    /// A path.
    fn from(p: &str) -> Output {
        Output::Path(PathBuf::from(p))
    }
}

/// Options made ready to run: the method built once (masks loaded, kernels parsed, DBS's
/// tables made), for any number of images, from any number of threads.
///
/// ```
/// use halftone::{Converter, Format, Image, Options};
/// let conv = Converter::new(&Options { levels: 4, ..Default::default() }).unwrap();
/// for shade in [32u8, 128, 224] {
///     let pgm = conv.convert_to_bytes(Image::gray8(16, 16, vec![shade; 256]), Format::Pgm).unwrap();
///     assert!(pgm.starts_with(b"P5\n16 16\n"));
/// }
/// ```
pub struct Converter {
    opts: Options,
    method: Box<dyn crate::Method>,
    tone: crate::ToneOptions,
    read: io::ReadOptions,
}

impl Converter {
    /// Checks the options and builds the method.
    pub fn new(opts: &Options) -> Result<Converter> {
        Ok(Converter {
            tone: opts.tone()?,
            method: opts.method()?,
            read: opts.read_options(),
            opts: opts.clone(),
        })
    }

    /// The options this converter was made from.
    pub fn options(&self) -> &Options {
        &self.opts
    }

    /// The method built from the options.
    pub fn method(&self) -> &dyn crate::Method {
        self.method.as_ref()
    }

    fn job<'a>(
        &'a self,
        write: &'a WriteOptions,
        size: &'a crate::resize::SizeRequest<'a>,
    ) -> Job<'a> {
        Job {
            method: self.method.as_ref(),
            color: self.opts.color_mode(),
            tone: &self.tone,
            read: &self.read,
            size,
            write,
            max_memory: self.opts.max_memory,
        }
    }

    /// See [`convert`].
    pub fn convert(&self, input: impl Into<Input>) -> Result<Halftone> {
        if self.opts.color == Color::Cmyk {
            return Ok(self.plates(input)?.halftone);
        }
        // PNG holds every kind of halftone (grey levels, RGB, palette): its checks pass for
        // whatever the method makes.
        let write = self.opts.write_options(Format::Png);
        let size = self.opts.size_request();
        let job = self.job(&write, &size);
        let mut collect = Collect::default();
        let output = Path::new("<memory>");
        run_input(
            input.into(),
            &job,
            &mut collect,
            &mut std::io::sink(),
            output,
        )?;
        collect
            .done
            .ok_or_else(|| Error::Invalid("the pipeline made no page".into()))
    }

    /// See [`convert_to`].
    pub fn convert_to(&self, input: impl Into<Input>, output: impl Into<Output>) -> Result<Report> {
        let input = input.into();
        let output = output.into();
        if self.opts.color == Color::Cmyk {
            let Output::Path(path) = &output else {
                return Err(Error::Option {
                    field: "color",
                    value: "cmyk".into(),
                    msg: "writes four plate files: give a file name, not a stream".into(),
                });
            };
            let format = output_format(Some(path), &self.opts)?;
            let p = self.plates(input)?;
            p.write(path, format, &self.opts)?;
            return Ok(p.report);
        }
        let format = match &output {
            Output::Path(p) => output_format(Some(p), &self.opts)?,
            Output::Writer { .. } => output_format(None, &self.opts)?,
        };
        self.encode_to(input, output, format)
    }

    /// Halftones `input` into `output` as `format`.
    fn encode_to(&self, input: Input, output: Output, format: Format) -> Result<Report> {
        let write = self.opts.write_options(format);
        let size = self.opts.size_request();
        let job = self.job(&write, &size);
        let mut enc = io::page_encoder(&write);
        match output {
            Output::Path(path) => {
                let mut report = None;
                io::write_atomic_with(&path, |out| {
                    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
                    report = Some(run_input(input, &job, enc.as_mut(), &mut out, &path)?);
                    enc.finish(&mut out).map_err(|e| e.named(&path))?;
                    out.flush().map_err(|e| Error::io(&path, e))
                })?;
                Ok(report.expect("set when the write succeeded"))
            }
            Output::Writer { writer, name } => {
                let name = PathBuf::from(name);
                let mut out = std::io::BufWriter::with_capacity(1 << 16, writer);
                let report = run_input(input, &job, enc.as_mut(), &mut out, &name)?;
                enc.finish(&mut out).map_err(|e| e.named(&name))?;
                out.flush().map_err(|e| Error::io(&name, e))?;
                Ok(report)
            }
        }
    }

    /// See [`convert_to_bytes`].
    pub fn convert_to_bytes(&self, input: impl Into<Input>, format: Format) -> Result<Vec<u8>> {
        let buf = SharedBuf::default();
        self.encode_to(
            input.into(),
            Output::Writer {
                writer: Box::new(buf.clone()),
                name: "<bytes>".into(),
            },
            format,
        )?;
        Ok(buf.take())
    }

    /// Runs `input` as the next page of a multi-page file: the encoder and writer of a
    /// [`Book`], or of a caller's own loop.
    pub fn add_page(
        &self,
        input: impl Into<Input>,
        format: Format,
        enc: &mut dyn PageEncoder,
        out: &mut dyn Write,
        output: &Path,
    ) -> Result<Report> {
        let write = self.opts.write_options(format);
        let size = self.opts.size_request();
        let job = self.job(&write, &size);
        run_input(input.into(), &job, enc, out, output)
    }

    /// See [`plates`].
    pub fn plates(&self, input: impl Into<Input>) -> Result<Plates> {
        let input = input.into();
        let name = input.name();
        let mut img = read_whole(input, &self.opts)?;
        let full = (img.width, img.height);
        if let Some(plan) = crate::resize::plan(&self.opts.size_request(), img.width, img.height)? {
            img = crate::resize::apply(&img, &plan, &self.tone)?;
        }
        crate::method::check_output_size(
            self.method.as_ref(),
            img.width,
            img.height,
            self.opts.max_pixels,
        )
        .map_err(|e| Error::Invalid(format!("{}: {e}", name.display())))?;
        let separated =
            crate::pipeline::plates::separate(&img, &self.opts, self.method.as_ref(), &self.tone)?;
        let report = Report {
            input: full,
            output: (separated.halftone.width, separated.halftone.height),
            streamed: false,
            band_rows: full.1,
            bands: 1,
            estimate: 0,
            assumed_dpi: None,
        };
        Ok(Plates {
            halftone: separated.halftone,
            preview: separated.preview,
            report,
        })
    }
}

/// The format `opts` names, or the one of `path`'s extension.
pub fn output_format(path: Option<&Path>, opts: &Options) -> Result<Format> {
    if let Some(f) = opts.format {
        return Ok(f);
    }
    let guessed = path.and_then(Format::from_path);
    guessed.ok_or_else(|| {
        let name = path.map(|p| p.display().to_string()).unwrap_or_default();
        Error::Option {
            field: "format",
            value: name,
            msg: format!(
                "no format given and none from the name; formats: {}",
                Format::WRITABLE.join(", ")
            ),
        }
    })
}

/// Runs `input` through the pipeline into `enc` as one page.
fn run_input(
    input: Input,
    job: &Job<'_>,
    enc: &mut dyn PageEncoder,
    out: &mut dyn Write,
    output: &Path,
) -> Result<Report> {
    match input {
        Input::Path(p) => pipeline::run_page(&p, job, enc, out, output),
        Input::Bytes(b) => pipeline::run_reader(
            Path::new("<bytes>"),
            None,
            Box::new(std::io::Cursor::new(b)),
            job,
            enc,
            out,
            output,
        ),
        Input::Reader { reader, name } => pipeline::run_reader(
            Path::new(&name),
            None,
            Box::new(std::io::BufReader::with_capacity(1 << 16, reader)),
            job,
            enc,
            out,
            output,
        ),
        Input::Image(img) => pipeline::run_image(img, job, enc, out, output),
    }
}

/// Halftones `input` into a halftone in memory: the same levels, bit for bit, as the file
/// [`convert_to`] writes with the same options. With `color` CMYK, the four plates.
///
/// ```
/// use halftone::{convert, Image, Options};
/// // A 64×64 grey ramp, sRGB-encoded.
/// let ramp: Vec<u8> = (0..64 * 64).map(|i| (i % 64 * 4) as u8).collect();
/// let h = convert(Image::gray8(64, 64, ramp), &Options::default()).unwrap();
/// assert_eq!((h.width, h.height, h.levels), (64, 64, 2));
/// ```
pub fn convert(input: impl Into<Input>, opts: &Options) -> Result<Halftone> {
    Converter::new(opts)?.convert(input)
}

/// Halftones `input` and writes it to `output` in `opts.format` (or the format of the
/// output's extension), streaming bands of rows when the method and input allow. Returns
/// what was done.
///
/// ```no_run
/// use halftone::{convert_to, Options};
/// let report = convert_to("photo.jpg", "photo.pbm", &Options::default())?;
/// println!("{}x{} pixels", report.output.0, report.output.1);
/// # Ok::<(), halftone::Error>(())
/// ```
pub fn convert_to(
    input: impl Into<Input>,
    output: impl Into<Output>,
    opts: &Options,
) -> Result<Report> {
    Converter::new(opts)?.convert_to(input, output)
}

/// Halftones `input` and returns the encoded file's bytes in `format`.
///
/// ```
/// use halftone::{convert_to_bytes, Format, Image, Options};
/// let grey = Image::gray8(8, 2, vec![128; 16]);
/// let pbm = convert_to_bytes(grey, Format::Pbm, &Options::default()).unwrap();
/// assert!(pbm.starts_with(b"P4\n8 2\n"));
/// ```
pub fn convert_to_bytes(
    input: impl Into<Input>,
    format: Format,
    opts: &Options,
) -> Result<Vec<u8>> {
    let opts = Options {
        format: Some(format),
        ..opts.clone()
    };
    Converter::new(&opts)?.convert_to_bytes(input, format)
}

/// Encodes a halftone in `format` with the output options of `opts` (resolution, page,
/// printer-language settings).
pub fn encode(h: &Halftone, format: Format, opts: &Options) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    io::encode(
        h,
        &opts.write_options(format),
        Path::new("<bytes>"),
        &mut out,
    )?;
    Ok(out)
}

/// A multi-page file (PDF, PostScript, PCL, ESC/POS, ZPL): one page an input.
///
/// ```no_run
/// use halftone::{Book, Format, Options};
/// let opts = Options { format: Some(Format::Pdf), dpi: Some(300.0), ..Default::default() };
/// let mut book = Book::new(Vec::new(), &opts)?;
/// book.add_page("page1.png")?;
/// book.add_page("page2.png")?;
/// let pdf: Vec<u8> = book.finish()?;
/// # Ok::<(), halftone::Error>(())
/// ```
pub struct Book<W: Write> {
    out: W,
    conv: Converter,
    format: Format,
    enc: Box<dyn PageEncoder>,
    pages: usize,
}

impl<W: Write> Book<W> {
    /// Starts a book writing into `out`; `opts.format` must be a multi-page format.
    pub fn new(out: W, opts: &Options) -> Result<Book<W>> {
        let format = opts.format.unwrap_or(Format::Pdf);
        if !format.is_multi_page() {
            return Err(Error::Option {
                field: "format",
                value: format!("{format:?}").to_ascii_lowercase(),
                msg: format!(
                    "holds one image; a book needs one of {}",
                    Format::ALL
                        .iter()
                        .filter(|f| f.is_multi_page())
                        .map(|f| f.name())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            });
        }
        let enc = io::page_encoder(&opts.write_options(format));
        Ok(Book {
            out,
            conv: Converter::new(opts)?,
            format,
            enc,
            pages: 0,
        })
    }

    /// Halftones `input` as the next page.
    pub fn add_page(&mut self, input: impl Into<Input>) -> Result<Report> {
        let name = Path::new("<book>");
        let report =
            self.conv
                .add_page(input, self.format, self.enc.as_mut(), &mut self.out, name)?;
        self.pages += 1;
        Ok(report)
    }

    /// Pages added so far.
    pub fn pages(&self) -> usize {
        self.pages
    }

    /// Ends the file (trailers, cross-references) and gives the writer back.
    pub fn finish(mut self) -> Result<W> {
        let name = Path::new("<book>");
        self.enc.finish(&mut self.out).map_err(|e| e.named(name))?;
        self.out.flush().map_err(|e| Error::io(name, e))?;
        Ok(self.out)
    }
}

/// CMYK plates of one image: the separation halftoned plate by plate.
pub struct Plates {
    /// Four planes: cyan, magenta, yellow, black (level 0 = full ink).
    pub halftone: Halftone,
    /// How the printed plates look (sRGB, 8 bits, interleaved), from the press model or
    /// the ICC profile: `(width, height, pixels)`.
    pub preview: Option<(usize, usize, Vec<u8>)>,
    /// What the conversion did.
    pub report: Report,
}

/// Separates `input` into CMYK with the press model (or the ICC profile) of `opts` and
/// halftones each plate: with the screen method, each plate at its own angle.
pub fn plates(input: impl Into<Input>, opts: &Options) -> Result<Plates> {
    Converter::new(opts)?.plates(input)
}

impl Plates {
    /// Writes the plates next to `output`: one PDF with a separation image a plate, or
    /// `NAME-cyan.EXT` … `NAME-black.EXT` (TIFF plates carry their ink's name).
    pub fn write(&self, output: &Path, format: Format, opts: &Options) -> Result<()> {
        crate::pipeline::plates::write(&self.halftone, output, format, opts)
    }

    /// The preview as PNG bytes, when there is one.
    pub fn preview_png(&self) -> Result<Option<Vec<u8>>> {
        let Some((w, h, rgb)) = &self.preview else {
            return Ok(None);
        };
        let mut buf = Vec::new();
        image::RgbImage::from_raw(*w as u32, *h as u32, rgb.clone())
            .ok_or_else(|| Error::Invalid("preview size".into()))?
            .write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
            .map_err(|e| Error::Invalid(format!("cannot encode the preview: {e}")))?;
        Ok(Some(buf))
    }
}

/// Decodes a whole image from any input.
pub fn read_whole(input: Input, opts: &Options) -> Result<Image> {
    let read = opts.read_options();
    match input {
        Input::Path(p) => io::read_image(&p, &read),
        Input::Bytes(b) => io::read_image_bytes(&b, Path::new("<bytes>"), &read),
        Input::Reader { mut reader, name } => {
            // Under the bound the stream's own header sets (an endless stream stops there).
            let bytes = io::read_stream(&mut reader, Path::new(&name), &read)?;
            io::read_image_bytes(&bytes, Path::new(&name), &read)
        }
        Input::Image(img) => Ok(img),
    }
}

/// How to measure a halftone against its original.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Resolution of the printed halftone, pixels per inch.
    pub dpi: f64,
    /// Viewing distance, inches.
    pub distance: f64,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            dpi: 300.0,
            distance: 12.0,
        }
    }
}

/// Measures `halftone` against the image it was made from, as an eye sees both at the
/// viewing distance: HVS-filtered PSNR, tone bias, L* error.
pub fn compare(
    original: impl Into<Input>,
    halftone: &Halftone,
    opts: &CompareOptions,
) -> Result<Quality> {
    let original = read_whole(original.into(), &Options::default())?;
    let view = Viewing::new(opts.dpi, opts.distance)?;
    crate::quality::compare_halftone(&original, halftone, &view)
}

/// What [`compare_device`] measured: the colour error of a halftone shown on an e-paper
/// panel, as a viewer adapted to the panel's white and black sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceComparison {
    /// The panel's name.
    pub device: String,
    /// The panel's pixels a degree at its viewing distance (the S-CIELAB filters' scale).
    pub pixels_per_degree: f64,
    /// Mean CIEDE2000, ΔE*ab and the lightness ratio.
    pub error: crate::scielab::ColourError,
    /// Whether the original was fitted to the panel first (turned and fitted inside it on
    /// white, as `convert --device` fits it), because it was not the panel's size and the
    /// halftone was.
    pub fitted: bool,
    /// How many inks the panel has.
    pub inks: usize,
    /// `Some(inks + 1)` when the halftone has more distinct colours than the panel has inks:
    /// it is not a halftone made for this panel, so the figures are not the panel's.
    pub extra_colours: Option<usize>,
}

impl DeviceComparison {
    /// The warning a front door shows when the halftone given is not one made for the
    /// panel (`None` when it is), naming it as `halftone`.
    pub fn warning(&self, halftone: &str) -> Option<String> {
        let n = self.extra_colours?;
        Some(format!(
            "{halftone} has {n} or more colours, more than the {} inks of {}: not a halftone \
             made for this panel (`convert --device {}` makes one), so the figures are not the \
             panel's",
            self.inks, self.device, self.device
        ))
    }
}

/// Measures `displayed` (a halftone for the panel `device`, a built-in name or a profile
/// file, holding the inks' colours as `convert --device` writes them) against `original`:
/// S-CIELAB at the panel's pixels a degree, for a viewer adapted to the panel's white and
/// black. When the halftone is the panel's size and the original is not, the original is
/// first fitted to the panel as `convert --device` fits it (under `max_pixels`), so it is
/// compared with what was made of it. Every front door's `compare --device` is this.
pub fn compare_device(
    original: Image,
    displayed: &Image,
    device: &str,
    max_pixels: u64,
) -> Result<DeviceComparison> {
    let d = crate::panel::Device::load(device)?;
    let panel = (d.width, d.height);
    let fitted =
        (displayed.width, displayed.height) == panel && (original.width, original.height) != panel;
    let original = if fitted {
        let o = Options {
            device: Some(device.to_string()),
            max_pixels,
            ..Default::default()
        };
        match crate::resize::plan(&o.size_request(), original.width, original.height)? {
            Some(plan) => {
                crate::resize::apply(&original, &plan, &crate::tone::ToneOptions::default())?
            }
            None => original,
        }
    } else {
        original
    };
    let inks: Vec<[f64; 3]> = d.inks.iter().map(|i| i.shown_linear()).collect();
    let ppd = d.pixels_per_degree();
    let error = crate::scielab::device_error(&original, displayed, &inks, ppd)?;
    Ok(DeviceComparison {
        device: d.name.clone(),
        pixels_per_degree: ppd,
        error,
        fitted,
        inks: inks.len(),
        extra_colours: more_colours_than(displayed, inks.len()),
    })
}

/// `Some(limit + 1)` when `img` has more than `limit` distinct colours (counting stops there).
fn more_colours_than(img: &Image, limit: usize) -> Option<usize> {
    use crate::raster::Samples;
    let mut seen = std::collections::HashSet::new();
    let code = |s: &Samples, i: usize| -> u16 {
        match s {
            Samples::U8(v) => v[i] as u16,
            Samples::U16(v) => v[i],
        }
    };
    for i in 0..img.width * img.height {
        let mut c = [0u16; 4];
        for (v, p) in c.iter_mut().zip(&img.planes) {
            *v = code(p, i);
        }
        seen.insert(c);
        if seen.len() > limit {
            return Some(limit + 1);
        }
    }
    None
}

/// A page encoder that keeps the halftone instead of encoding it.
#[derive(Default)]
struct Collect {
    page: Option<(Halftone, usize)>,
    done: Option<Halftone>,
}

impl PageEncoder for Collect {
    fn begin_page(&mut self, page: &PageHeader, _out: &mut dyn Write) -> EncodeResult {
        let h = Halftone {
            width: page.width,
            height: page.height,
            levels: page.levels,
            bits: page.bits,
            stride: page.stride,
            planes: vec![Vec::with_capacity(page.stride * page.height); page.channels],
            palette: page.palette.clone(),
        };
        self.page = Some((h, 0));
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, _out: &mut dyn Write) -> EncodeResult {
        let (h, rows) = crate::io::sink::page_for_rows(&mut self.page)?;
        for (plane, data) in h.planes.iter_mut().zip(band.planes) {
            plane.extend_from_slice(&data[..band.rows * h.stride]);
        }
        *rows += band.rows;
        Ok(())
    }

    fn end_page(&mut self, _out: &mut dyn Write) -> EncodeResult {
        let (h, _) =
            crate::io::sink::take_complete_page(&mut self.page, |(h, rows)| (*rows, h.height))?;
        self.done = Some(h);
        Ok(())
    }
}

/// A growable buffer shared between a writer handed to the pipeline and its owner.
#[derive(Clone, Default)]
struct SharedBuf(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl SharedBuf {
    fn take(&self) -> Vec<u8> {
        std::mem::take(&mut self.0.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

impl Write for SharedBuf {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The names of the halftoning methods.
pub fn methods() -> &'static [&'static str] {
    MethodKind::NAMES
}
