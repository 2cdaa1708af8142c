//! `halftone convert` for clips: an animated GIF, APNG or WebP, a YUV4MPEG2 stream or a
//! numbered series of files in; an animated GIF or PNG, a YUV4MPEG2 stream or a series out.
//! And `halftone compare --clip`: two clips, frame by frame in time.

use std::path::Path;
use std::process::ExitCode;

use clap::Args;

use halftone::io::Format;
use halftone::motion::{self, ClipFormat, ClipMethod, Temporal};
use halftone::{Options, Output};

/// How a clip is halftoned in time.
#[derive(Args, Debug, Clone)]
pub struct MotionArgs {
    /// Clips: `stable` re-decides an error-diffused dot only where the picture changed
    /// visibly (the default); `frame` halftones every frame on its own.
    #[arg(long, default_value = "stable", value_parser = ["stable", "frame"])]
    pub temporal: String,
}

/// True when `input` or `output` is a clip (a series pattern, a clip format, a stream).
fn is_clip(input: &Path, output: &Path, format: Format) -> bool {
    ClipFormat::of(format).is_some() || motion::is_series(input) || motion::is_series(output)
}

/// Converts a clip when `input` or `output` is one; `None` leaves the still road to run.
pub fn run(
    input: &Path,
    output: &Path,
    opts: &Options,
    args: &MotionArgs,
) -> anyhow::Result<Option<ExitCode>> {
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
    let mut method = ClipMethod::new(opts, Temporal::parse(&args.temporal)?)?;
    motion::convert_clip(source.as_mut(), sink.as_mut(), &mut method)?;
    Ok(Some(ExitCode::SUCCESS))
}

/// `halftone compare --clip ORIGINAL HALFTONE`: per-frame HVS-PSNR, the flicker rate in
/// the original's still areas, and the sizes of both files.
pub fn compare(a: &super::compare::CompareArgs) -> anyhow::Result<ExitCode> {
    use std::io::Write as _;
    let view = halftone::quality::Viewing::new(a.dpi, a.distance)?;
    let read = halftone::io::ReadOptions {
        max_pixels: a.max_pixels,
    };
    let mut original = motion::open_source(&a.original, &read, true)?;
    let mut halftoned = motion::open_source(&a.halftone, &read, true)?;
    let c = motion::measure::compare_clips(
        original.as_mut(),
        halftoned.as_mut(),
        a.noise,
        a.every,
        &view,
    )?;
    let size = |p: &Path| std::fs::metadata(p).ok().map(|m| m.len());
    let psnr = &c.hvs_psnr_db;
    let finite: Vec<f64> = psnr.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = (!finite.is_empty()).then(|| finite.iter().sum::<f64>() / finite.len() as f64);
    let min = finite.iter().copied().reduce(f64::min);
    let text = if a.json {
        let out = serde_json::json!({
            "original": a.original,
            "halftone": a.halftone,
            "frames": c.frames,
            "hvs_psnr_db_mean": mean,
            "hvs_psnr_db_min": min,
            "hvs_psnr_db": finite,
            "flicker": c.flicker,
            "still_pixels": c.still_pixels,
            "noise": a.noise,
            "original_bytes": size(&a.original),
            "halftone_bytes": size(&a.halftone),
        });
        format!("{}\n", serde_json::to_string_pretty(&out)?)
    } else {
        let bytes = |v: Option<u64>| v.map_or("-".to_string(), |b| b.to_string());
        format!(
            "frames     {:>10}\n\
             HVS-PSNR   {:>10} dB  (mean over {} frames; lowest {} dB)\n\
             flicker    {:>10.6}     (dots changed where the original moved at most {} codes, \
             over {} such pixels)\n\
             size       {:>10} bytes (original {} bytes)\n",
            c.frames,
            mean.map_or("-".into(), |m| format!("{m:.2}")),
            finite.len(),
            min.map_or("-".into(), |m| format!("{m:.2}")),
            c.flicker,
            a.noise,
            c.still_pixels,
            bytes(size(&a.halftone)),
            bytes(size(&a.original)),
        )
    };
    super::stdio::check_stdout()?;
    std::io::stdout().lock().write_all(text.as_bytes())?;
    Ok(ExitCode::SUCCESS)
}
