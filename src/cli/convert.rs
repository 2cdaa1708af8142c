//! `halftone convert`: one image in, one halftone out.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use clap::{Args, ValueEnum};

use halftone::io::Format;
use halftone::{Color, Converter, Input, Output};

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

pub use super::option_args::CommonArgs;

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

impl CommonArgs {
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
            if let (Some(path), Some(png)) = (&self.preview, plates.preview_png()?) {
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

pub fn run(a: ConvertArgs) -> anyhow::Result<ExitCode> {
    let mut opts = a.common.options()?;
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
    a.common.check_used(&opts, Some(format))?;
    if !stdout && a.input.as_os_str() != "-" && same_file(&a.input, &a.output) {
        bail!("{}: refusing to write over the input", a.output.display());
    }
    if let Some(code) = super::motion::run(&a.input, &a.output, &opts)? {
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
