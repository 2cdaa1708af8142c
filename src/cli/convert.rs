//! `halftone convert`: one image in, one halftone out.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, ValueEnum};

use halftone::io::{Compression, Format};
use halftone::method::pattern::Cell;
use halftone::preset::Presets;
use halftone::{Color, Converter, Input, MethodKind, Options, Output, Threshold};

use super::size_args::{DisplayArgs, SizeArgs};

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
  halftone convert photo.jpg -o frame.png --device spectra6-7in3-v2   # what the panel shows
  halftone convert photo.jpg -o frame.bin --device spectra6-7in3-v2   # its 4-bit buffer
  halftone convert photo.jpg -o tag.planes --device hanshow-bwr       # black, then red plane
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

/// An output format on the command line: the library's one list of formats, with its
/// descriptions as help.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FormatArg(pub Format);

impl ValueEnum for FormatArg {
    fn value_variants<'a>() -> &'a [Self] {
        static ALL: std::sync::LazyLock<Vec<FormatArg>> =
            std::sync::LazyLock::new(|| Format::ALL.iter().map(|&f| FormatArg(f)).collect());
        &ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(
            clap::builder::PossibleValue::new(self.0.name())
                .help(super::flags_for_options(self.0.description())),
        )
    }
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Format {
        f.0
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
    pub threshold: Threshold,

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

    /// Diffuse (or, with --method ordered, pattern-dither) to a palette: a built-in (bw,
    /// eink-4, epaper-7, rgb-8, cga-16, pico-8, gameboy), a file of hex colours or a GIMP
    /// .gpl, or auto:N for N colours made from the image (2 to 256). Implies --color rgb.
    #[arg(long)]
    pub palette: Option<String>,

    /// An e-paper panel: a built-in profile (see `halftone devices list`) or a profile file.
    /// Its inks become the palette (in the panel's order), the picture is fitted into the
    /// panel (turned by its rotation) unless a size is given, and its ppi is recorded unless
    /// --dpi is. Panel buffers: --format raw, h, planes or nibbles.
    #[arg(long, value_name = "NAME|FILE")]
    pub device: Option<String>,

    /// With --device: write PNG (and the other colour formats) in the inks' measured
    /// colours (what the panel shows) or their nominal ones (what the driver expects).
    #[arg(long, value_name = "WHICH", default_value = "measured", value_parser = ["measured", "nominal"])]
    pub ink_colours: String,

    /// With --device or --palette: exposure in stops (+1 doubles the light).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        value_name = "STOPS"
    )]
    pub exposure: f32,

    /// With --device or --palette: chroma multiplier at constant lightness (0 grey, 1 as is).
    #[arg(long, default_value_t = 1.0, value_name = "FACTOR")]
    pub saturation: f32,

    /// With --device (perceptual intent): stretch the picture's tone range to the panel's:
    /// auto (from its histogram), off, or a strength 0..1.
    #[arg(long, default_value = "auto", value_name = "auto|off|STRENGTH")]
    pub tone: halftone::method::device::Amount,

    /// With --device (perceptual intent): compress colours the inks cannot show towards
    /// neutral, hue kept: auto (as far as the picture reaches), off (clip), or 0..1.
    #[arg(long, default_value = "auto", value_name = "auto|off|STRENGTH")]
    pub gamut: halftone::method::device::Amount,

    /// Seed for methods that draw noise (zhou-fang's threshold modulation).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Output levels a pixel per channel (2 = bilevel; 4 for a 4-level device).
    #[arg(long, short = 'l', default_value_t = 2, value_parser = super::size_args::parse_levels)]
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
    #[arg(long, allow_negative_numbers = true, value_parser = super::size_args::parse_dpi)]
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

    #[command(flatten)]
    pub motion: super::motion::MotionArgs,
}

impl From<MethodName> for MethodKind {
    fn from(m: MethodName) -> MethodKind {
        match m {
            MethodName::Threshold => MethodKind::Threshold,
            MethodName::Pattern => MethodKind::Pattern,
            MethodName::Ordered => MethodKind::Ordered,
            MethodName::Diffuse => MethodKind::Diffuse,
            MethodName::Dbs => MethodKind::Dbs,
            MethodName::Screen => MethodKind::Screen,
        }
    }
}

impl CommonArgs {
    /// The resolved step: the library's options from these flags, then the preset's
    /// values for every option the command line did not give. A preset's format, if it
    /// names one, is in `format`.
    pub fn options(&self, matches: &ArgMatches) -> anyhow::Result<Options> {
        let mut o = Options {
            method: self.method.into(),
            threshold: self.threshold,
            mask: self.mask.clone(),
            kernel: self.kernel.clone(),
            serpentine: !self.no_serpentine,
            strength: self.strength,
            palette: self.palette.clone(),
            device: self.device.clone(),
            ink_colours: self.ink_colours.parse()?,
            seed: self.seed,
            levels: self.levels,
            color: match self.color {
                ColorArg::Gray => Color::Gray,
                ColorArg::Rgb => Color::Rgb,
                ColorArg::Cmyk => Color::Cmyk,
            },
            cell: match self.cell {
                CellArg::Expand => Cell::Expand,
                CellArg::Fit => Cell::Fit,
            },
            linearize: !self.no_linearize,
            invert: self.invert,
            gamma: self.gamma,
            dot_gain: self.dot_gain,
            transfer: self.screen.transfer.clone(),
            preset_transfer: None,
            format: None,
            dpi: self.dpi,
            maxval: self.maxval,
            compression: self.compression.map(Into::into),
            device_levels: self.display_codes.device_levels,
            print: self.print.options(),
            content: self.print.content(),
            max_pixels: self.max_pixels,
            width: self.width,
            height: self.sizing.height,
            fit: self.sizing.fit,
            fit_mode: self.sizing.fit_mode,
            size: self.size.clone(),
            rotate: self.sizing.rotate.unwrap_or_default(),
            max_memory: self.memory.max_memory(),
            passes: self.accuracy.passes,
            distance: self.accuracy.distance,
            tone_correction: !self.accuracy.no_tone_correction,
            hysteresis: self.accuracy.hysteresis,
            printer_model: self.accuracy.printer.kind(),
            dot_ratio: self.accuracy.printer.dot_ratio,
            printer_table: self.accuracy.printer.printer_table.clone(),
            lpi: self.screen.lpi.clone(),
            angle: self.screen.angle,
            spot: self.screen.spot.clone(),
            angles: self.screen.angles.clone(),
            press: self.screen.press.clone(),
            gcr: self.screen.gcr,
            tac: self.screen.tac,
            separation: self.screen.separation.kind(),
            icc: self.screen.icc.clone(),
            intent: self.screen.intent.map(|i| i.intent()),
            exposure: self.exposure,
            saturation: self.saturation,
            tone: self.tone,
            gamut: self.gamut,
            preview: self.screen.preview.is_some(),
            preview_block: self.screen.preview_block,
        };
        if let Some(name) = &self.preset {
            let presets = Presets::load(self.presets.as_deref())?;
            let given = |id: &str| matches.value_source(id) == Some(ValueSource::CommandLine);
            presets
                .get(name)?
                .apply(name, &mut o, &given)
                .map_err(|e| anyhow::anyhow!("preset {name}: {e}"))?;
        }
        Ok(o)
    }

    /// Halftones `input` to `output` (`-`: standard input and output) with `conv`,
    /// writing the file atomically (CMYK: the plates and the preview). Returns the number
    /// of input pixels.
    pub fn convert_file(
        &self,
        conv: &Converter,
        input: &Path,
        output: &Path,
    ) -> anyhow::Result<u64> {
        let input = if input.as_os_str() == "-" {
            Input::Reader {
                reader: Box::new(std::io::stdin()),
                name: "<stdin>".into(),
            }
        } else {
            Input::Path(input.to_path_buf())
        };
        let opts = conv.options();
        if opts.color == Color::Cmyk {
            if output.as_os_str() == "-" {
                bail!("--color cmyk writes four plate files: give -o NAME.EXT, not stdout");
            }
            // Separation works on the whole image: four plates, one screen each.
            let plates = conv.plates(input)?;
            let format = opts.format.expect("resolved before");
            plates.write(output, format, opts)?;
            if let (Some(path), Some(png)) = (&self.screen.preview, plates.preview_png()?) {
                halftone::io::write_atomic(path, |w| w.write_all(&png))?;
            }
            return Ok(plates.report.pixels());
        }
        let output = if output.as_os_str() == "-" {
            super::stdio::check_stdout()?;
            Output::Writer {
                writer: Box::new(std::io::stdout()),
                name: "-".into(),
            }
        } else {
            Output::Path(output.to_path_buf())
        };
        let shown = match &output {
            Output::Path(p) => p.clone(),
            Output::Writer { .. } => PathBuf::from("-"),
        };
        let report = conv.convert_to(input, output)?;
        if let Some(d) = report.assumed_dpi {
            eprintln!("{}", assumed_dpi_note(&shown, d));
        }
        Ok(report.pixels())
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

pub fn run(a: ConvertArgs, matches: &ArgMatches) -> anyhow::Result<ExitCode> {
    let mut opts = a.common.options(matches)?;
    let preset_format = opts.format;
    let stdout = a.output.as_os_str() == "-";
    let format: Format =
        match a
            .format
            .map(Format::from)
            .or(if stdout { preset_format } else { None })
        {
            Some(f) => f,
            None if stdout => bail!(
                "writing to stdout (-o -) needs --format ({})",
                Format::WRITABLE.join(", ")
            ),
            None => output_format(&a.output, preset_format)?,
        };
    opts.format = Some(format);
    super::flag_check::check_used(matches, opts.method, Some(format))?;
    if !stdout && a.input.as_os_str() != "-" && same_file(&a.input, &a.output) {
        bail!("{}: refusing to write over the input", a.output.display());
    }
    if let Some(code) = super::motion::run(&a.input, &a.output, &opts, &a.motion)? {
        return Ok(code);
    }
    let conv = Converter::new(&opts)?;
    let _activity = super::progress::Activity::start(format!(
        "halftoning {} to {}",
        a.input.display(),
        a.output.display()
    ));
    a.common.convert_file(&conv, &a.input, &a.output)?;
    Ok(ExitCode::SUCCESS)
}

/// The format for `output` from its extension; an unknown extension, or one that disagrees
/// with the preset's format, is an error that lists what can be written.
fn output_format(output: &Path, preset_format: Option<Format>) -> anyhow::Result<Format> {
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
pub fn assumed_dpi_note(output: &Path, d: halftone::pipeline::AssumedDpi) -> String {
    let why = match d {
        halftone::pipeline::AssumedDpi::Recorded(_) => "the resolution the image records",
        halftone::pipeline::AssumedDpi::Default(_) => "the image records no usable resolution",
    };
    format!(
        "halftone: {}: no --dpi given; printed at {} dpi ({why})",
        output.display(),
        d.dpi()
    )
}
