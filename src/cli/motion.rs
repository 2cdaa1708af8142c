//! `halftone convert` for clips: an animated GIF, APNG or WebP, a YUV4MPEG2 stream or a
//! numbered series of files in; an animated GIF or PNG, a YUV4MPEG2 stream or a series out.
//! And `halftone compare --clip`: two clips, frame by frame in time.

use std::path::Path;
use std::process::ExitCode;

use halftone::io::Format;
use halftone::motion::{self, ClipFormat, ClipMethod};
use halftone::{Options, Output};

/// True when `input` or `output` is a clip (a series pattern, a clip format, a stream).
fn is_clip(input: &Path, output: &Path, format: Format) -> bool {
    ClipFormat::of(format).is_some() || motion::is_series(input) || motion::is_series(output)
}

/// Converts a clip when `input` or `output` is one; `None` leaves the still road to run.
pub fn run(input: &Path, output: &Path, opts: &Options) -> anyhow::Result<Option<ExitCode>> {
    let format = opts.format.expect("resolved before");
    if !is_clip(input, output, format) {
        return Ok(None);
    }
    let clip_format = if motion::is_series(output) {
        ClipFormat::Series(format)
    } else {
        match ClipFormat::of(format) {
            Some(f) => f,
            None => anyhow::bail!(
                "{}: a clip is written as gif, apng, y4m or a series such as frames/%04d.png",
                output.display()
            ),
        }
    };
    let gray = opts.color_mode() == halftone::ColorMode::Gray;
    let mut source = motion::open_source(input, &opts.read_options(), gray)?;
    let out = if output.as_os_str() == "-" {
        super::stdio::check_stdout()?;
        Output::Writer {
            writer: Box::new(std::io::BufWriter::with_capacity(
                1 << 20,
                std::io::stdout(),
            )),
            name: "-".into(),
        }
    } else {
        Output::Path(output.to_path_buf())
    };
    let mut sink = motion::open_sink(out, clip_format, opts)?;
    let mut method = ClipMethod::new(opts)?;
    motion::convert_clip(source.as_mut(), sink.as_mut(), &mut method)?;
    Ok(Some(ExitCode::SUCCESS))
}
