//! `halftone convert`: one image in, one halftone out.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, ValueEnum};

use halftone::color::Palette;
use halftone::io::{Compression, Format, ReadOptions, WriteOptions};
use halftone::method::diffusion::{Diffuse, DiffuseOptions};
use halftone::method::ordered::Ordered;
use halftone::method::pattern::{Cell, Pattern};
use halftone::method::screen::ScreenMethod;
use halftone::method::threshold::Threshold;
use halftone::pipeline;
use halftone::preset::Presets;
use halftone::resize;
use halftone::tone::Encoding;
use halftone::{ColorMode, Mask, Method, ToneOptions};

use super::size_args::{DisplayArgs, SizeArgs};
use super::threshold_arg::ThresholdArg;

pub const EXAMPLES: &str = "Examples:
  halftone convert photo.jpg -o photo.pbm        # Floyd–Steinberg in linear light (the default)
  halftone convert photo.jpg -o photo-4.png --levels 4 --fit 800x480 --rotate auto
  halftone convert scan.png -o scan.pbm --method threshold --threshold 50%
  halftone convert photo.jpg -o out.png --method pattern --mask seed-3x3 --cell expand
  halftone convert photo.jpg -o out.pgm --method pattern --mask seed-2x2 --levels 4
  halftone convert photo.jpg -o out.png --method pattern --color rgb --mask seed-2x2
  halftone convert photo.jpg -o out.pbm --method ordered --mask blue-noise-64
  halftone convert photo.jpg -o out.pgm --method ordered --mask bayer-8 --levels 4
  halftone convert photo.jpg -o out.pbm --method diffuse --kernel floyd-steinberg
  halftone convert photo.jpg -o out.png --method diffuse --kernel ostromoukhov
  halftone convert photo.jpg -o out.png --method diffuse --palette epaper-7
  halftone convert photo.jpg -o out.escpos --preset thermal-203
  halftone convert photo.jpg --preset thermal-203 -o - | lp -o raw   # ESC/POS to a receipt printer
  halftone convert scan.png -o page.pdf --dpi 600 --page a4 --content auto
  halftone convert scan.png -o page.tif --compression g4 --dpi 300
  cat in.png | halftone convert - -o - --format pbm > out.pbm";

/// Halftoning methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodName {
    /// One fixed threshold (quantisation to the nearest level when --levels > 2).
    Threshold,
    /// The lecture's halftone patterns: an n×n cell of a mask of pixel position numbers.
    Pattern,
    /// Ordered dithering: one threshold a pixel from a tiled mask (Bayer, clustered dot,
    /// blue noise, or a file), placed in linear light.
    Ordered,
    /// Error diffusion in linear light (see --kernel), to levels or a palette.
    Diffuse,
    /// Direct binary search: the halftone that minimises the eye-filtered error (slow, best).
    Dbs,
    /// An AM screen at --lpi, --angle and --spot at the device --dpi (exact at any angle).
    Screen,
}

/// Colour handling.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ColorArg {
    /// Luminance in linear light, one output plane.
    Gray,
    /// Each of red, green and blue on its own.
    Rgb,
    /// Separation into cyan, magenta, yellow and black plates (see --press, --gcr, --tac).
    Cmyk,
}

/// Pattern cell placement.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CellArg {
    /// Each input pixel becomes an n×n cell: output n× larger (a device of n× the resolution).
    Expand,
    /// Output keeps the input's size; each n×n block is averaged and drawn as one pattern.
    Fit,
}

/// Output formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// Netpbm P4 bitmap (bilevel; 1 = black ink).
    Pbm,
    /// Netpbm P5 greymap (maxval levels−1 unless --maxval).
    Pgm,
    /// Netpbm P6 pixmap.
    Ppm,
    /// PNG: 1-bit grey for bilevel, 2/4-bit where the levels fit, 8-bit RGB for colour.
    Png,
    /// TIFF (bilevel: see --compression).
    Tiff,
    /// BMP (1-bit for bilevel).
    Bmp,
    /// PDF: one image a page at its physical size (see --page, --compression g4).
    Pdf,
    /// PostScript level 2: one image a page.
    Ps,
    /// PCL 5 raster for laser printers (75-600 dpi, see --dpi).
    Pcl,
    /// ESC/POS raster for receipt printers (see --paper-width, --cut).
    Escpos,
    /// ZPL II for label printers (see --zpl-encoding).
    Zpl,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Format {
        match f {
            FormatArg::Pbm => Format::Pbm,
            FormatArg::Pgm => Format::Pgm,
            FormatArg::Ppm => Format::Ppm,
            FormatArg::Png => Format::Png,
            FormatArg::Tiff => Format::Tiff,
            FormatArg::Bmp => Format::Bmp,
            FormatArg::Pdf => Format::Pdf,
            FormatArg::Ps => Format::Ps,
            FormatArg::Pcl => Format::Pcl,
            FormatArg::Escpos => Format::EscPos,
            FormatArg::Zpl => Format::Zpl,
        }
    }
}

/// TIFF compressions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CompressionArg {
    /// CCITT Group 4: what fax software and printers expect; best on text and line art.
    G4,
    /// Deflate: several times smaller than G4 on dithered photos.
    Deflate,
    /// LZW.
    Lzw,
    /// PackBits.
    Packbits,
    /// No compression.
    None,
}

impl From<CompressionArg> for Compression {
    fn from(c: CompressionArg) -> Compression {
        match c {
            CompressionArg::G4 => Compression::G4,
            CompressionArg::Deflate => Compression::Deflate,
            CompressionArg::Lzw => Compression::Lzw,
            CompressionArg::Packbits => Compression::PackBits,
            CompressionArg::None => Compression::None,
        }
    }
}

/// Options for reading, tone and writing shared by `convert` and `batch`.
#[derive(Args, Debug, Clone)]
pub struct CommonArgs {
    /// Halftoning method [default: diffuse, Floyd–Steinberg in linear light, serpentine].
    #[arg(
        long,
        short = 'm',
        value_enum,
        default_value = "diffuse",
        hide_default_value = true
    )]
    pub method: MethodName,

    /// Threshold for `--method threshold`; a pixel at or above it becomes paper: a fraction
    /// of reflectance (0.5 = half the light, linear unless --no-linearize), a percentage
    /// (50%, the same), or an 8-bit code of the input (128 = sRGB code 128, 21.6% of the
    /// light).
    #[arg(long, default_value = "0.5", value_name = "0.5|50%|128")]
    pub threshold: ThresholdArg,

    /// Mask: a built-in name (see `halftone masks list`) or a mask file
    /// [default: seed-3x3 for pattern, bayer-8 for ordered].
    #[arg(long)]
    pub mask: Option<String>,

    /// Error-diffusion kernel: floyd-steinberg, jarvis-judice-ninke, stucki, burkes, sierra,
    /// sierra-2, sierra-lite, atkinson, shiau-fan, shiau-fan-2, fan, ostromoukhov,
    /// zhou-fang, riemersma, or a kernel file (see kernels/README.md).
    #[arg(long, short = 'k', default_value = "floyd-steinberg")]
    pub kernel: String,

    /// Error diffusion: alternate direction every row (the default; reduces worms).
    #[arg(long, overrides_with = "no_serpentine")]
    pub serpentine: bool,

    /// Error diffusion: every row left to right (lets raster kernels use two cores).
    #[arg(long, overrides_with = "serpentine")]
    pub no_serpentine: bool,

    /// Error diffusion: share of the error passed on, 0..1.
    #[arg(long, default_value_t = 1.0)]
    pub strength: f32,

    /// Diffuse to a palette: a built-in (bw, eink-4, epaper-7, rgb-8, cga-16, pico-8,
    /// gameboy) or a file of hex colours or a GIMP .gpl. Implies --color rgb.
    #[arg(long)]
    pub palette: Option<String>,

    /// Seed for methods that draw noise (zhou-fang's threshold modulation).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Output levels a pixel per channel (2 = bilevel; 4 for a 4-level device).
    #[arg(long, short = 'l', default_value_t = 2)]
    pub levels: u16,

    /// Grey (luminance in linear light) or each RGB channel on its own.
    #[arg(long, value_enum, default_value = "gray")]
    pub color: ColorArg,

    /// Pattern cells: expand (output n× larger) or fit (same size, resolution reduced by n).
    #[arg(long, value_enum, default_value = "fit")]
    pub cell: CellArg,

    /// Treat codes as linear (the naive behaviour of most tools) instead of decoding sRGB.
    #[arg(long)]
    pub no_linearize: bool,

    /// Negative media: paper where the image is dark.
    #[arg(long)]
    pub invert: bool,

    /// Extra gamma on linear reflectance (r' = r^gamma); 1 = none.
    #[arg(long, default_value_t = 1.0)]
    pub gamma: f32,

    /// Pre-compensate this dot gain at 50% coverage, in percent (e.g. 15).
    #[arg(long, default_value_t = 0.0)]
    pub dot_gain: f32,

    /// Resolution recorded in the output (PNG pHYs, TIFF and BMP resolution), dots per inch.
    #[arg(long)]
    pub dpi: Option<f64>,

    /// PGM/PPM maxval [default: 255, display codes; levels−1 with --device-levels].
    #[arg(long)]
    pub maxval: Option<u16>,

    /// TIFF compression (bilevel); PDF takes deflate (the default) or g4.
    #[arg(long, value_enum)]
    pub compression: Option<CompressionArg>,

    /// Refuse images larger than this many pixels (checked from the header, before decoding).
    #[arg(long, default_value_t = 1_000_000_000)]
    pub max_pixels: u64,

    /// Resize to this width in pixels first (in linear light, Lanczos-3; aspect kept).
    #[arg(long)]
    pub width: Option<usize>,

    /// Resize to this physical width first (4in, 100mm, 10cm), with --dpi.
    #[arg(long)]
    pub size: Option<String>,

    /// A printer preset (built-in: thermal-203, thermal-80mm, label-203, label-300,
    /// laser-600, eink-4grey); flags given on the command line win over it.
    #[arg(long)]
    pub preset: Option<String>,

    /// A TOML file of presets adding to (or replacing) the built-ins.
    #[arg(long, value_name = "FILE")]
    pub presets: Option<PathBuf>,

    #[command(flatten)]
    pub sizing: SizeArgs,

    #[command(flatten)]
    pub display_codes: DisplayArgs,

    #[command(flatten)]
    pub memory: super::memory_args::MemoryArgs,

    #[command(flatten)]
    pub print: super::print_args::PrintArgs,

    #[command(flatten)]
    pub accuracy: super::accuracy_args::AccuracyArgs,

    #[command(flatten)]
    pub screen: super::screen_args::ScreenArgs,
}

/// `halftone convert` arguments.
#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// Input image (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM; 8 or 16 bits), or - for stdin.
    pub input: PathBuf,

    /// Output file, or - for stdout (then --format is required).
    #[arg(long, short = 'o')]
    pub output: PathBuf,

    /// Output format; default from the output's extension.
    #[arg(long, short = 'f', value_enum)]
    pub format: Option<FormatArg>,

    #[command(flatten)]
    pub common: CommonArgs,
}

/// Sets `$field` from the preset's `$value` unless the flag was given on the command line.
macro_rules! from_preset {
    ($matches:expr, $self:ident . $field:ident, $value:expr) => {
        if let Some(v) = $value {
            if $matches.value_source(stringify!($field)) != Some(ValueSource::CommandLine) {
                $self.$field = v;
            }
        }
    };
}

fn value_enum<T: ValueEnum>(what: &str, s: &str) -> anyhow::Result<T> {
    T::from_str(s, true).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
            .collect();
        anyhow::anyhow!("preset: unknown {what} '{s}' (known: {})", names.join(", "))
    })
}

impl CommonArgs {
    /// Fills in the options a preset names and the command line does not; returns the
    /// preset's output format, if it names one.
    pub fn apply_preset(&mut self, matches: &ArgMatches) -> anyhow::Result<Option<FormatArg>> {
        let Some(name) = self.preset.clone() else {
            return Ok(None);
        };
        let presets = Presets::load(self.presets.as_deref())?;
        let p = presets.get(&name)?.clone();
        self.print.apply_preset(&p, matches)?;
        self.screen.apply_preset(&name, &p, matches)?;
        let method = p
            .method
            .as_deref()
            .map(|m| value_enum("method", m))
            .transpose()?;
        let color = p
            .color
            .as_deref()
            .map(|c| value_enum("color", c))
            .transpose()?;
        let compression = p
            .compression
            .as_deref()
            .map(|c| value_enum("compression", c))
            .transpose()?;
        let format = p
            .format
            .as_deref()
            .map(|f| value_enum("format", f))
            .transpose()?;
        from_preset!(matches, self.method, method);
        from_preset!(matches, self.color, color);
        from_preset!(matches, self.mask, p.mask.map(Some));
        from_preset!(matches, self.kernel, p.kernel);
        from_preset!(matches, self.palette, p.palette.map(Some));
        from_preset!(matches, self.levels, p.levels);
        from_preset!(matches, self.dot_gain, p.dot_gain);
        from_preset!(matches, self.gamma, p.gamma);
        from_preset!(matches, self.dpi, p.dpi.map(Some));
        from_preset!(matches, self.compression, compression.map(Some));
        // A width or size on the command line replaces the preset's either way.
        let cli_sizes = [
            self.width.is_some(),
            self.size.is_some(),
            self.sizing.height.is_some(),
            self.sizing.fit.is_some(),
        ];
        if !cli_sizes.contains(&true) {
            self.width = p.width;
            self.size = p.size;
            self.sizing.fit = p.fit.as_deref().map(resize::parse_box).transpose()?;
        }
        Ok(format)
    }

    /// Reads `input`, resizes if asked, halftones with `method`, writes `output` atomically.
    /// Returns the number of input pixels.
    pub fn convert_file(
        &self,
        input: &Path,
        output: &Path,
        format: Format,
        method: &dyn Method,
        tone: &ToneOptions,
    ) -> anyhow::Result<u64> {
        if self.color == ColorArg::Cmyk {
            // Separation works on the whole image: four plates, one screen each.
            let mut img = halftone::io::read_image(
                input,
                &ReadOptions {
                    max_pixels: self.max_pixels,
                },
            )?;
            let pixels = (img.width * img.height) as u64;
            if let Some(plan) = resize::plan(&self.size_request(), img.width, img.height)? {
                img = resize::apply(&img, &plan, tone)?;
            }
            halftone::method::check_output_size(method, img.width, img.height, self.max_pixels)
                .map_err(|e| anyhow::anyhow!("{}: {e}", input.display()))?;
            super::plates::write_plates(self, &img, output, format, method, tone)?;
            return Ok(pixels);
        }
        let job = pipeline::Job {
            method,
            color: self.color_mode(),
            tone,
            read: &ReadOptions {
                max_pixels: self.max_pixels,
            },
            size: &self.size_request(),
            write: &self.write_options(format),
            max_memory: self.memory.max_memory(),
        };
        let report = pipeline::convert(input, output, &job)?;
        if let Some(d) = report.assumed_dpi {
            eprintln!("{}", assumed_dpi_note(output, d));
        }
        Ok(report.pixels())
    }

    /// The tone options these arguments ask for.
    pub fn tone(&self) -> anyhow::Result<ToneOptions> {
        if !(self.gamma > 0.0 && self.gamma.is_finite()) {
            bail!("--gamma {}: must be a positive number", self.gamma);
        }
        if !(0.0..50.0).contains(&self.dot_gain) {
            bail!(
                "--dot-gain {}: must be a percentage from 0 to 50",
                self.dot_gain
            );
        }
        Ok(ToneOptions {
            linearize: !self.no_linearize,
            gamma: self.gamma,
            dot_gain: self.dot_gain / 100.0,
            invert: self.invert,
        })
    }

    /// The method these arguments ask for: calibrated by --transfer, wrapped for `--content`.
    pub fn method(&self) -> anyhow::Result<Box<dyn Method>> {
        let calibrated = super::screen_args::with_transfer(self, self.plain_method()?)?;
        Ok(self.print.with_content(calibrated))
    }

    /// The method these arguments ask for.
    fn plain_method(&self) -> anyhow::Result<Box<dyn Method>> {
        if self.palette.is_some() && self.method != MethodName::Diffuse {
            bail!("--palette works with --method diffuse");
        }
        Ok(match self.method {
            MethodName::Threshold => Box::new(Threshold::new(
                self.threshold.reflectance(!self.no_linearize),
                self.levels,
            )?),
            MethodName::Pattern => {
                let cell = match self.cell {
                    CellArg::Expand => Cell::Expand,
                    CellArg::Fit => Cell::Fit,
                };
                let mask = Mask::load(self.mask.as_deref().unwrap_or("seed-3x3"), true)?;
                Box::new(Pattern::new(mask, self.levels, cell)?)
            }
            MethodName::Ordered => {
                let mask = Mask::load(self.mask.as_deref().unwrap_or("bayer-8"), false)?;
                Box::new(Ordered::new(mask, self.levels)?)
            }
            MethodName::Diffuse => {
                let options = DiffuseOptions {
                    levels: self.levels,
                    serpentine: !self.no_serpentine,
                    strength: self.strength,
                    seed: self.seed,
                };
                if self.kernel == "tded" || self.accuracy.hysteresis != 0.0 {
                    return self
                        .accuracy
                        .diffusion(&self.kernel, options, self.palette.is_some());
                }
                let d = Diffuse::new(&self.kernel, options)?;
                match &self.palette {
                    Some(p) => Box::new(d.with_palette(Palette::load(p)?)),
                    None => Box::new(d),
                }
            }
            MethodName::Dbs => self.accuracy.dbs(self.levels, self.dpi)?,
            MethodName::Screen => Box::new(ScreenMethod::new(
                self.screen.screen(self.dpi)?,
                self.levels,
            )?),
        })
    }

    /// Colour mode.
    pub fn color_mode(&self) -> ColorMode {
        if self.palette.is_some() {
            return ColorMode::Rgb;
        }
        match self.color {
            ColorArg::Gray => ColorMode::Gray,
            ColorArg::Rgb | ColorArg::Cmyk => ColorMode::Rgb,
        }
    }

    /// Write options for `format`.
    pub fn write_options(&self, format: Format) -> WriteOptions {
        WriteOptions {
            format,
            dpi: self.dpi,
            maxval: self.maxval,
            compression: self.compression.map(Into::into),
            print: self.print.options(),
            display: if self.no_linearize {
                Encoding::Linear
            } else {
                Encoding::Srgb
            },
            device_levels: self.display_codes.device_levels,
        }
    }
}

/// True when `a` and `b` name the same file (b need not exist).
pub fn same_file(a: &Path, b: &Path) -> bool {
    let Ok(a) = a.canonicalize() else {
        return false;
    };
    if let Ok(b) = b.canonicalize() {
        return a == b;
    }
    match (b.parent(), b.file_name()) {
        (Some(dir), Some(name)) => {
            let dir = if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            };
            dir.canonicalize()
                .map(|d| d.join(name) == a)
                .unwrap_or(false)
        }
        _ => false,
    }
}

pub fn run(mut a: ConvertArgs, matches: &ArgMatches) -> anyhow::Result<ExitCode> {
    let preset_format = a.common.apply_preset(matches)?;
    let stdout = a.output.as_os_str() == "-";
    let format: Format = match a.format.or(if stdout { preset_format } else { None }) {
        Some(f) => f.into(),
        None if stdout => bail!(
            "writing to stdout (-o -) needs --format ({})",
            Format::WRITABLE.join(", ")
        ),
        None => output_format(&a.output, preset_format)?,
    };
    super::flag_check::check_used(matches, a.common.method, Some(format))?;
    if !stdout && a.input.as_os_str() != "-" && same_file(&a.input, &a.output) {
        bail!("{}: refusing to write over the input", a.output.display());
    }
    let tone = a.common.tone()?;
    let method = a.common.method()?;
    let _activity = super::progress::Activity::start(format!(
        "halftoning {} to {}",
        a.input.display(),
        a.output.display()
    ));
    a.common
        .convert_file(&a.input, &a.output, format, method.as_ref(), &tone)?;
    Ok(ExitCode::SUCCESS)
}

/// The format for `output` from its extension; an unknown extension, or one that disagrees
/// with the preset's format, is an error that lists what can be written.
fn output_format(output: &Path, preset_format: Option<FormatArg>) -> anyhow::Result<Format> {
    let ext = output
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    let Some(format) = Format::from_name(&ext) else {
        let what = if ext.is_empty() {
            "has no extension".to_string()
        } else {
            format!("'.{ext}' is not a format halftone writes")
        };
        // An image format halftone only reads (GIF, JPEG…) is not a typo of one it writes:
        // `.gif` is one letter from `.tif`, but suggesting TIFF would mislead.
        let read_only = [
            "gif", "jpg", "jpeg", "webp", "avif", "heic", "tga", "ico", "exr", "svg",
        ]
        .contains(&ext.to_ascii_lowercase().as_str());
        let hint = halftone::names::closest(&ext, Format::WRITABLE)
            .filter(|_| !ext.is_empty() && !read_only)
            .map(|c| format!("did you mean '.{c}'? "))
            .unwrap_or_default();
        bail!(
            "{}: {what}; {hint}halftone writes {} (name the file so, or give --format)",
            output.display(),
            Format::WRITABLE.join(", ")
        );
    };
    if let Some(p) = preset_format {
        let p: Format = p.into();
        if p != format {
            bail!(
                "{}: the preset writes {} but the extension says {}; name the output .{} or give \
                 --format {}",
                output.display(),
                format!("{p:?}").to_ascii_uppercase(),
                format!("{format:?}").to_ascii_uppercase(),
                format!("{p:?}").to_ascii_lowercase(),
                format!("{format:?}").to_ascii_lowercase()
            );
        }
    }
    Ok(format)
}

/// The one line that says which resolution a printed page got when `--dpi` was not given.
pub fn assumed_dpi_note(output: &Path, d: pipeline::AssumedDpi) -> String {
    let why = match d {
        pipeline::AssumedDpi::Recorded(_) => "the resolution the image records",
        pipeline::AssumedDpi::Default(_) => "the image records no usable resolution",
    };
    format!(
        "halftone: {}: no --dpi given; printed at {} dpi ({why})",
        output.display(),
        d.dpi()
    )
}
