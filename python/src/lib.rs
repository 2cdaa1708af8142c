//! The native half of the `halftone` Python package: options from keyword arguments, inputs
//! from paths, bytes and numpy arrays, the halftone back as numpy arrays and encoded bytes.
//! The pure-Python half (`halftone/__init__.py`) normalises Pillow images and float arrays
//! and documents the API.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyList, PyTuple};

use halftone::options::table::{self, Form, OptionSpec, PRESET_NAMES};
use halftone::options::{Settings, Value};

use halftone::tone::Encoding;
use halftone::{Color, Converter, Error, Format, Halftone, Input, Options};

/// A library error as the Python exception that fits it. Option errors read
/// `field=value: message`, in the spelling of the keyword arguments.
fn py_err(e: Error) -> PyErr {
    match e {
        Error::Option { field, value, msg } => {
            PyValueError::new_err(format!("{field}={value}: {msg}"))
        }
        Error::Io { ref cause, .. } => {
            let errno = cause.raw_os_error();
            let text = e.to_string();
            match errno {
                Some(n) => PyOSError::new_err((n, text)),
                None => PyOSError::new_err(text),
            }
        }
        other => PyValueError::new_err(other.to_string()),
    }
}

/// Runs `f` without the GIL, turning a panic into a Python exception.
fn run<T: Send>(py: Python<'_>, f: impl FnOnce() -> halftone::Result<T> + Send) -> PyResult<T> {
    run_on(py, None, f)
}

/// The `threads=` keyword taken out of `kw`: a pool of that many worker threads for the
/// call's own parallel work, or None (every core, the process's shared pool).
fn take_threads(kw: Option<&Bound<'_, PyDict>>) -> PyResult<Option<rayon::ThreadPool>> {
    let Some(kw) = kw else { return Ok(None) };
    let Some(v) = kw.get_item("threads")? else {
        return Ok(None);
    };
    kw.del_item("threads")?;
    if v.is_none() {
        return Ok(None);
    }
    if v.extract::<bool>().is_ok() {
        return Err(PyTypeError::new_err(
            "threads: expected an integer, not a bool",
        ));
    }
    let n: i64 = v
        .extract()
        .map_err(|_| PyTypeError::new_err("threads: expected an integer"))?;
    if !(1..=1024).contains(&n) {
        return Err(PyValueError::new_err(format!(
            "threads={n}: expected a number of threads from 1 to 1024"
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n as usize)
        .build()
        .map(Some)
        .map_err(|e| PyRuntimeError::new_err(format!("threads={n}: cannot start them: {e}")))
}

/// [`run`] inside `pool` (the call's own threads) when there is one.
fn run_on<T: Send>(
    py: Python<'_>,
    pool: Option<&rayon::ThreadPool>,
    f: impl FnOnce() -> halftone::Result<T> + Send,
) -> PyResult<T> {
    let out = py.detach(|| {
        catch_unwind(AssertUnwindSafe(|| match pool {
            Some(p) => p.install(f),
            None => f(),
        }))
    });
    match out {
        Ok(r) => r.map_err(py_err),
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown".into());
            Err(PyRuntimeError::new_err(format!(
                "halftone: internal error: {msg}"
            )))
        }
    }
}

fn format_of(key: &str, s: &str) -> PyResult<Format> {
    Format::from_name(s.trim()).ok_or_else(|| {
        PyValueError::new_err(format!(
            "{key}={s}: not a format halftone writes; formats: {}",
            Format::WRITABLE.join(", ")
        ))
    })
}

/// A keyword argument's value as the option table takes it: Python's bool, int, float,
/// str, path or `(w, h)` pair, typed. A bool where an option wants a value, or anything but
/// a bool where it wants a switch, is a `TypeError`, as Python's own calls have it.
fn value_of(key: &str, spec: &OptionSpec, v: &Bound<'_, PyAny>) -> PyResult<Value<'static>> {
    let type_name = || {
        v.get_type()
            .name()
            .map(|n| n.to_string())
            .unwrap_or_default()
    };
    let switch = !matches!(spec.form, Form::Value | Form::Door);
    if let Ok(b) = v.cast::<PyBool>() {
        return if switch || spec.form == Form::Door {
            Ok(Value::Bool(b.is_true()))
        } else {
            Err(PyTypeError::new_err(format!(
                "{key}: expected a value, not a bool"
            )))
        };
    }
    if switch {
        return Err(PyTypeError::new_err(format!(
            "{key}: expected True or False, not {}",
            type_name()
        )));
    }
    if let Ok(i) = v.extract::<i64>() {
        return Ok(Value::Int(i));
    }
    if v.is_instance_of::<pyo3::types::PyInt>() {
        // An integer beyond 64 bits: its digits, so the option's message quotes the value
        // given (not a float's rounding of it) with its range.
        return Ok(Value::from(v.str()?.to_string()));
    }
    if let Ok(x) = v.extract::<f64>() {
        return Ok(Value::Float(x));
    }
    if let Ok(t) = v.extract::<String>() {
        return Ok(Value::from(t));
    }
    if let Ok((w, h)) = v.extract::<(u64, u64)>() {
        return Ok(Value::Pair(w, h));
    }
    if let Ok(p) = v.extract::<PathBuf>() {
        return Ok(Value::from(p.display().to_string()));
    }
    Err(PyTypeError::new_err(format!(
        "{key}: expected a string or a number, not {}",
        type_name()
    )))
}

/// The options of keyword arguments `kw` (values of None left out), through the library's
/// one option table ([`Settings`]): the same names and values as the command line's flags
/// and the page's keys, `preset` (from `presets`, a TOML file, or the built-ins) filling
/// what was not given, and an option the chosen method or format does not read refused.
fn options(kw: Option<&Bound<'_, PyDict>>) -> PyResult<Options> {
    let mut settings = Settings::new();
    let mut preset: Option<String> = None;
    if let Some(kw) = kw {
        for (k, v) in kw.iter() {
            let key: String = k.extract()?;
            if v.is_none() {
                continue;
            }
            if PRESET_NAMES.contains(&key.as_str()) {
                let t = if let Ok(t) = v.extract::<String>() {
                    t
                } else if let Ok(p) = v.extract::<PathBuf>() {
                    p.display().to_string()
                } else {
                    return Err(PyTypeError::new_err(format!("{key}: expected a string")));
                };
                if key == "preset" {
                    preset = Some(t.clone());
                }
                settings.set(&key, t).map_err(py_err)?;
                continue;
            }
            // Keyword arguments are the table's names as written, underscores only.
            let spec = match table::find(&key) {
                Some((spec, _)) if !key.contains('-') => spec,
                _ => {
                    return Err(PyTypeError::new_err(format!(
                        "unexpected keyword argument '{key}'"
                    )))
                }
            };
            let value = value_of(&key, spec, &v)?;
            settings.set_value(&key, &value).map_err(py_err)?;
        }
    }
    let given = settings.given();
    let o = settings.finish().map_err(|e| match (e, &preset) {
        (Error::Invalid(m), Some(name)) => {
            let m = m
                .strip_prefix(&format!("preset {name}: "))
                .map(str::to_string)
                .unwrap_or(m);
            PyValueError::new_err(format!("preset={name}: {m}"))
        }
        (e, _) => py_err(e),
    })?;
    o.check_used(&given, o.format).map_err(py_err)?;
    Ok(o)
}

/// An input as the library takes it.
enum Source<'py> {
    Input(Input),
    Gray8(PyReadonlyArrayDyn<'py, u8>, Encoding),
}

/// An array's interleaved samples split into the library's planes by `make`: read where
/// they lie when the array is C-contiguous, else gathered first (`as_slice` also takes
/// Fortran order, which is not row-major).
fn planes_of<T: numpy::Element + Copy + Sync>(
    a: &PyReadonlyArrayDyn<'_, T>,
    (h, w, c): (usize, usize, usize),
    linear: bool,
    make: fn(usize, usize, usize, &[T], Encoding) -> halftone::Result<halftone::Image>,
) -> PyResult<halftone::Image> {
    let gathered: Vec<T>;
    let data = match a.as_slice().ok().filter(|_| a.is_c_contiguous()) {
        Some(s) => s,
        None => {
            // A view (strided, transposed, zero strides): gathered into memory reserved
            // first, so memory that cannot be had is an error, never an abort. Its size
            // was held to the limits by `source`.
            let n = h * w * c;
            let mut v = Vec::new();
            v.try_reserve_exact(n).map_err(|_| {
                PyMemoryError::new_err(format!(
                    "cannot allocate {} bytes to gather the image array (shape {:?})",
                    n.saturating_mul(std::mem::size_of::<T>()),
                    a.shape()
                ))
            })?;
            v.extend(a.as_array().iter().copied());
            gathered = v;
            &gathered
        }
    };
    let enc = encoding(linear);
    run(a.py(), || make(w, h, c, data, enc))
}

fn encoding(linear: bool) -> Encoding {
    if linear {
        Encoding::Linear
    } else {
        Encoding::Srgb
    }
}

/// Height, width and channels of an array shape.
fn dims(shape: &[usize]) -> PyResult<(usize, usize, usize)> {
    let (h, w, c) = match *shape {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "an image array must be HxW (grey), HxWx3 (RGB) or HxWx4 (RGBA); this one has shape {shape:?}"
            )))
        }
    };
    if !(1..=4).contains(&c) {
        return Err(PyValueError::new_err(format!(
            "an image array must be HxW (grey), HxWx3 (RGB) or HxWx4 (RGBA); this one has {c} channels (shape {shape:?})"
        )));
    }
    if h == 0 || w == 0 {
        return Err(PyValueError::new_err(format!(
            "the image array is empty (shape {shape:?})"
        )));
    }
    Ok((h, w, c))
}

/// [`dims`], then the limits a file meets ([`halftone::in_memory::check_array`]), before
/// anything is read or copied from the array.
fn checked_dims(
    shape: &[usize],
    sample_bytes: usize,
    max_pixels: u64,
) -> PyResult<(usize, usize, usize)> {
    let (h, w, c) = dims(shape)?;
    halftone::in_memory::check_array(w, h, c, sample_bytes, max_pixels).map_err(py_err)?;
    Ok((h, w, c))
}

fn source<'py>(image: &Bound<'py, PyAny>, linear: bool, max_pixels: u64) -> PyResult<Source<'py>> {
    if let Ok(b) = image.cast::<PyBytes>() {
        return Ok(Source::Input(Input::Bytes(b.as_bytes().to_vec())));
    }
    if let Ok(s) = image.extract::<PathBuf>() {
        return Ok(Source::Input(Input::Path(s)));
    }
    if let Ok(a) = image.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        let (h, w, c) = checked_dims(a.shape(), 1, max_pixels)?;
        if c == 1 && a.is_c_contiguous() {
            return Ok(Source::Gray8(a, encoding(linear)));
        }
        let img = planes_of(&a, (h, w, c), linear, halftone::in_memory::image_u8)?;
        return Ok(Source::Input(Input::Image(img)));
    }
    if let Ok(a) = image.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        let dims = checked_dims(a.shape(), 2, max_pixels)?;
        let img = planes_of(&a, dims, linear, halftone::in_memory::image_u16)?;
        return Ok(Source::Input(Input::Image(img)));
    }
    Err(PyTypeError::new_err(format!(
        "expected a path, bytes of an image file, a Pillow image or a numpy array of uint8, uint16 or float; got {}",
        image.get_type().name().map(|n| n.to_string()).unwrap_or_default()
    )))
}

/// The result of a conversion: the halftone, the options that made it and, for CMYK, the
/// preview.
#[pyclass(frozen, module = "halftone._halftone")]
struct Converted {
    h: Halftone,
    opts: Options,
    preview: Option<(usize, usize, Vec<u8>)>,
}

fn levels_array<'py>(py: Python<'py>, h: &Halftone) -> PyResult<Bound<'py, PyAny>> {
    let (w, ht, n) = (h.width, h.height, h.channels());
    // Rows on every worker thread, without the GIL: a 24 MP halftone took 70 ms on one.
    let out = py.detach(|| {
        use rayon::prelude::*;
        let mut out = vec![0u8; w * ht * n];
        if w > 0 {
            if n == 3 {
                out.par_chunks_mut(w * 3).enumerate().for_each(|(y, dst)| {
                    let mut row = vec![0u8; w];
                    for c in 0..3 {
                        h.unpack_row(c, y, &mut row);
                        for (px, &v) in dst.chunks_exact_mut(3).zip(&row) {
                            px[c] = v;
                        }
                    }
                });
            } else {
                out.par_chunks_mut(w).enumerate().for_each(|(i, dst)| {
                    h.unpack_row(i / ht, i % ht, dst);
                });
            }
        }
        out
    });
    let flat = PyArray1::from_vec(py, out);
    let shape: Vec<usize> = match n {
        1 => vec![ht, w],
        3 => vec![ht, w, 3],
        _ => vec![n, ht, w],
    };
    Ok(flat.reshape(shape)?.into_any())
}

const INKS: [&str; 4] = ["cyan", "magenta", "yellow", "black"];

#[pymethods]
impl Converted {
    /// Width of the halftone in pixels.
    #[getter]
    fn width(&self) -> usize {
        self.h.width
    }

    /// Height of the halftone in pixels.
    #[getter]
    fn height(&self) -> usize {
        self.h.height
    }

    /// Output levels a pixel per channel.
    #[getter]
    fn levels(&self) -> u16 {
        self.h.levels
    }

    /// Number of planes: 1 (grey or palette), 3 (RGB) or 4 (CMYK plates).
    #[getter]
    fn channels(&self) -> usize {
        self.h.channels()
    }

    /// "gray", "rgb", "palette" or "cmyk".
    #[getter]
    fn kind(&self) -> &'static str {
        if self.opts.color == Color::Cmyk {
            "cmyk"
        } else if self.h.palette.is_some() {
            "palette"
        } else if self.h.channels() == 3 {
            "rgb"
        } else {
            "gray"
        }
    }

    /// The palette's colours as (r, g, b) tuples, or None.
    #[getter]
    fn palette(&self) -> Option<Vec<(u8, u8, u8)>> {
        self.h
            .palette
            .as_ref()
            .map(|p| p.iter().map(|c| (c[0], c[1], c[2])).collect())
    }

    /// Device resolution recorded in the output, or None: `dpi`, else a device's ppi.
    #[getter]
    fn dpi(&self) -> Option<f64> {
        self.opts.write_options(Format::Png).dpi
    }

    /// Level (or palette) indices, uint8: HxW for one plane, HxWx3 for RGB, 4xHxW for CMYK
    /// plates (cyan, magenta, yellow, black). Level 0 is the darkest (full ink).
    fn levels_array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        levels_array(py, &self.h)
    }

    /// The CMYK preview as an HxWx3 uint8 sRGB array, or None.
    fn preview_array<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some((w, h, rgb)) = &self.preview else {
            return Ok(None);
        };
        let flat = PyArray1::from_vec(py, rgb.clone());
        Ok(Some(flat.reshape(vec![*h, *w, 3])?.into_any()))
    }

    /// The halftone encoded as `format` (pbm, pgm, ppm, png, tiff, bmp, pdf, ps, pcl,
    /// escpos, zpl). CMYK plates: PDF holds all four; other formats take `plate`.
    #[pyo3(signature = (format, plate=None))]
    fn encode<'py>(
        &self,
        py: Python<'py>,
        format: &str,
        plate: Option<&str>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let f = format_of("format", format)?;
        let plate = match plate {
            None => None,
            Some(p) => Some(
                INKS.iter()
                    .position(|i| *i == p.trim().to_ascii_lowercase() || i[..1] == *p.trim())
                    .ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "plate={p}: expected cyan, magenta, yellow or black"
                        ))
                    })?,
            ),
        };
        let cmyk = self.opts.color == Color::Cmyk;
        if cmyk && plate.is_none() && f != Format::Pdf {
            return Err(PyValueError::new_err(format!(
                "format={format}: CMYK gives four plates; PDF holds them all, other formats take plate='cyan' (or magenta, yellow, black)"
            )));
        }
        if !cmyk && plate.is_some() {
            return Err(PyValueError::new_err(
                "plate: only CMYK conversions have plates",
            ));
        }
        let bytes = run(py, || match plate {
            Some(c) if f == Format::Tiff => {
                halftone::press::plates::plate_tiff(&self.h, c, INKS[c], self.opts.dpi)
            }
            Some(c) => halftone::encode(&halftone::press::plates::plate(&self.h, c), f, &self.opts),
            None => halftone::encode(&self.h, f, &self.opts),
        })?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Writes the halftone to `path` in `format` (default: from the extension), atomically.
    /// CMYK plates go to one PDF, or to NAME-cyan.EXT … NAME-black.EXT.
    #[pyo3(signature = (path, format=None))]
    fn save(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let f = match format {
            Some(s) => format_of("format", s)?,
            None => match Format::from_path(&path) {
                Some(f) => f,
                None => match self.opts.format {
                    Some(f) => f,
                    None => {
                        return Err(PyValueError::new_err(format!(
                            "{}: no format from the extension; name the file .pbm, .png, … or give format= ({})",
                            path.display(),
                            Format::WRITABLE.join(", ")
                        )))
                    }
                },
            },
        };
        run(py, || {
            if self.opts.color == Color::Cmyk {
                halftone::pipeline::plates::write(&self.h, &path, f, &self.opts)
            } else {
                let bytes = halftone::encode(&self.h, f, &self.opts)?;
                halftone::io::write_atomic(&path, |w| w.write_all(&bytes))
            }
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "<halftone result {}x{} {} levels={}>",
            self.h.width,
            self.h.height,
            self.kind(),
            self.h.levels
        )
    }
}

/// convert(image, linear, **options) -> Converted. See `halftone.convert`.
#[pyfunction]
#[pyo3(signature = (image, linear=false, **kw))]
fn convert(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    linear: bool,
    kw: Option<&Bound<'_, PyDict>>,
) -> PyResult<Converted> {
    let pool = take_threads(kw)?;
    let opts = options(kw)?;
    let src = source(image, linear, opts.max_pixels)?;
    let conv = run(py, || Converter::new(&opts))?;
    let (h, preview) = match src {
        Source::Gray8(a, enc) => {
            let (ht, w, _) = dims(a.shape())?;
            let data = a
                .as_slice()
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            let borrowed = run_on(py, pool.as_ref(), || {
                halftone::in_memory::halftone_gray8(&conv, w, ht, data, enc)
            })?;
            match borrowed {
                Some(h) => (h, None),
                None => {
                    let img = halftone::in_memory::image_u8(w, ht, 1, data, enc).map_err(py_err)?;
                    convert_input(py, pool.as_ref(), &conv, Input::Image(img))?
                }
            }
        }
        Source::Input(input) => convert_input(py, pool.as_ref(), &conv, input)?,
    };
    Ok(Converted { h, opts, preview })
}

/// A clip halftoned a frame at a time, as `halftone convert` halftones a clip: masks that
/// stay put, stable error diffusion for `method="diffuse"` (`temporal="frame"` for frame by
/// frame). The same frames give the command line's bytes.
#[pyclass(module = "halftone._halftone")]
struct Clip {
    method: halftone::motion::ClipMethod,
    opts: Options,
}

#[pymethods]
impl Clip {
    #[new]
    #[pyo3(signature = (**kw))]
    fn new(kw: Option<&Bound<'_, PyDict>>) -> PyResult<Clip> {
        let opts = options(kw)?;
        let method = halftone::motion::ClipMethod::new(&opts).map_err(py_err)?;
        Ok(Clip { method, opts })
    }

    /// next(frame, linear=False): the next frame's halftone. `frame` is a numpy array
    /// (HxW grey, HxWx3 RGB or HxWx4 RGBA), every frame the same size.
    #[pyo3(signature = (frame, linear=false))]
    fn next(
        &mut self,
        py: Python<'_>,
        frame: &Bound<'_, PyAny>,
        linear: bool,
    ) -> PyResult<Converted> {
        let img = match whole_input(frame, linear)? {
            Input::Image(img) => img,
            _ => {
                return Err(PyTypeError::new_err(
                    "Clip.next: a frame is a numpy array (HxW grey, HxWx3 RGB or HxWx4 RGBA)",
                ))
            }
        };
        let method = &mut self.method;
        let h = run(py, || method.next(&img))?;
        Ok(Converted {
            h,
            opts: self.opts.clone(),
            preview: None,
        })
    }
}

type Made = (Halftone, Option<(usize, usize, Vec<u8>)>);

fn convert_input(
    py: Python<'_>,
    pool: Option<&rayon::ThreadPool>,
    conv: &Converter,
    input: Input,
) -> PyResult<Made> {
    run_on(py, pool, || {
        if conv.options().color == Color::Cmyk {
            let p = conv.plates(input)?;
            Ok((p.halftone, p.preview))
        } else {
            Ok((conv.convert(input)?, None))
        }
    })
}

/// convert_to_bytes(image, format, linear, **options) -> bytes: the file the command line
/// writes, streamed when the input is a file.
#[pyfunction]
#[pyo3(signature = (image, format, linear=false, **kw))]
fn convert_to_bytes<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    format: &str,
    linear: bool,
    kw: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let pool = take_threads(kw)?;
    let mut opts = options(kw)?;
    let f = format_of("format", format)?;
    opts.format = Some(f);
    if opts.color == Color::Cmyk {
        return Err(PyValueError::new_err(
            "color=cmyk: gives four plates; use convert(...).encode(...) or .save(...)",
        ));
    }
    let input = match source(image, linear, opts.max_pixels)? {
        Source::Input(i) => i,
        Source::Gray8(a, enc) => {
            let (h, w, _) = dims(a.shape())?;
            let data = a
                .as_slice()
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            Input::Image(halftone::in_memory::image_u8(w, h, 1, data, enc).map_err(py_err)?)
        }
    };
    let bytes = run_on(py, pool.as_ref(), || {
        halftone::convert_to_bytes(input, f, &opts)
    })?;
    Ok(PyBytes::new(py, &bytes))
}

fn quality_dict<'py>(py: Python<'py>, q: &halftone::Quality) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("hvs_psnr_db", q.hvs_psnr_db)?;
    d.set_item("hvs_mse", q.hvs_mse)?;
    d.set_item("tone_bias", q.tone_bias)?;
    d.set_item("lstar_rms", q.lstar_rms)?;
    d.set_item("plain_psnr_db", q.plain_psnr_db)?;
    d.set_item("scale", PyTuple::new(py, q.scale)?)?;
    Ok(d)
}

fn whole_input(image: &Bound<'_, PyAny>, linear: bool) -> PyResult<Input> {
    let max_pixels = halftone::io::ReadOptions::default().max_pixels;
    Ok(match source(image, linear, max_pixels)? {
        Source::Input(i) => i,
        Source::Gray8(a, enc) => {
            let (h, w, _) = dims(a.shape())?;
            let data = a
                .as_slice()
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            Input::Image(halftone::in_memory::image_u8(w, h, 1, data, enc).map_err(py_err)?)
        }
    })
}

/// compare(original, halftone, dpi, distance, linear, device) -> dict. `halftone` is a
/// result of `convert`, or an image (path, bytes, array) read as the command line reads one.
/// With `device` (a built-in name or a profile file), the figures of `compare --device`.
#[pyfunction]
#[pyo3(signature = (original, halftone, dpi=300.0, distance=12.0, linear=false, device=None))]
fn compare<'py>(
    py: Python<'py>,
    original: &Bound<'py, PyAny>,
    halftone: &Bound<'py, PyAny>,
    dpi: f64,
    distance: f64,
    linear: bool,
    device: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let orig = whole_input(original, linear)?;
    if let Some(device) = device {
        return compare_device(py, orig, halftone, &device);
    }
    let q = if let Ok(c) = halftone.cast::<Converted>() {
        let c = c.get();
        let opts = halftone::CompareOptions { dpi, distance };
        run(py, || halftone::compare(orig, &c.h, &opts))?
    } else {
        let ht = whole_input(halftone, false)?;
        run(py, || {
            use halftone::quality;
            let view = quality::Viewing::new(dpi, distance)?;
            let original = halftone::read_whole(orig, &Options::default())?;
            let mut h = halftone::read_whole(ht, &Options::default())?;
            // A grey halftone stored as colour (an indexed PNG with grey entries) is grey.
            if h.planes.len() == 3 && h.planes[0] == h.planes[1] && h.planes[1] == h.planes[2] {
                h.planes.truncate(1);
                h.color = halftone::raster::ColorKind::Gray;
            }
            let ht = quality::decoded_halftone_reflectance(&h, Encoding::Srgb);
            quality::compare(&quality::image_reflectance(&original), &ht, &view)
        })?
    };
    quality_dict(py, &q)
}

/// `compare(..., device=)`: the colour error a viewer adapted to the panel's white and
/// black sees (S-CIELAB at the panel's pixels a degree), by the library function the
/// command line's `compare --device` calls ([`halftone::compare_device`]): an original not
/// of the panel's size is fitted to it as `convert` fits it, and a "halftone" with more
/// colours than the panel has inks is measured with a `UserWarning`. A result of `convert`
/// is measured as the PNG `convert` writes of it, in the inks' measured colours.
fn compare_device<'py>(
    py: Python<'py>,
    orig: Input,
    halftone: &Bound<'py, PyAny>,
    device: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let (ht, ht_name) = if let Ok(c) = halftone.cast::<Converted>() {
        let c = c.get();
        let png = run(py, || {
            halftone::encode(&c.h, Format::Png, &Options::default())
        })?;
        (Input::Bytes(png), "the result".to_string())
    } else {
        let is_path = halftone.is_instance_of::<pyo3::types::PyString>()
            || halftone.hasattr("__fspath__").unwrap_or(false);
        let name = match halftone.extract::<PathBuf>() {
            Ok(p) if is_path => p.display().to_string(),
            _ => "the halftone".to_string(),
        };
        (whole_input(halftone, false)?, name)
    };
    let c = run(py, || {
        halftone::Device::load(device)?;
        let opts = Options::default();
        let original = halftone::read_whole(orig, &opts)?;
        let displayed = halftone::read_whole(ht, &opts)?;
        halftone::compare_device(original, &displayed, device, opts.max_pixels)
    })?;
    if let Some(w) = c.warning(&ht_name) {
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &std::ffi::CString::new(w).unwrap_or_default(),
            1,
        )?;
    }
    let (name, ppd, e) = (c.device, c.pixels_per_degree, c.error);
    let out = PyDict::new(py);
    out.set_item("device", name)?;
    out.set_item("pixels_per_degree", ppd)?;
    out.set_item("de2000", e.de2000)?;
    out.set_item("de76", e.de76)?;
    out.set_item("lightness_ratio", e.lightness_ratio)?;
    Ok(out)
}

/// Every list of names the library accepts (methods, kernels, palettes, masks, spots,
/// formats, intents, devices, presses, colours, contents, presets), as JSON: the lists the
/// command line's `halftone options --json` and the page's `listings()` show.
#[pyfunction]
fn lists_json() -> PyResult<String> {
    serde_json::to_string(&halftone::options::Lists::get())
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Every option of the library's one table as JSON (name, kind, values, default, help, …):
/// what ``halftone options --json`` prints under ``options``. ``convert``'s docstring is
/// made from it.
#[pyfunction]
fn options_json() -> PyResult<String> {
    serde_json::to_string(&halftone::options::describe_json())
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The built-in e-paper panel profiles (``device=``): name → description.
#[pyfunction]
fn devices(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for name in halftone::Device::builtin_names() {
        let dev = halftone::Device::builtin(name)
            .ok_or_else(|| PyValueError::new_err(format!("{name}: no such device")))?;
        d.set_item(name, dev.description.clone())?;
    }
    Ok(d)
}

/// One e-paper panel profile (a built-in name or a profile file) as a dict: what
/// `halftone devices list` shows of it (size, ppi, how its colours are known, inks) and the
/// rest of the profile.
#[pyfunction]
fn device<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
    let d = run(py, || halftone::Device::load(name))?;
    let out = PyDict::new(py);
    out.set_item("name", &d.name)?;
    out.set_item("description", &d.description)?;
    out.set_item("width", d.width)?;
    out.set_item("height", d.height)?;
    out.set_item("ppi", d.ppi)?;
    out.set_item("viewing_distance_cm", d.viewing_distance_cm)?;
    out.set_item("rotation", d.rotation)?;
    out.set_item("colours", d.colours.name())?;
    out.set_item("source", &d.source)?;
    let encodings: Vec<&str> = d.encodings.iter().map(|f| f.name()).collect();
    out.set_item("encodings", encodings)?;
    out.set_item("bits", d.packed_bits())?;
    let inks = PyList::empty(py);
    for ink in &d.inks {
        let i = PyDict::new(py);
        i.set_item("name", &ink.name)?;
        i.set_item("code", ink.code)?;
        i.set_item("nominal", PyTuple::new(py, ink.nominal)?)?;
        i.set_item("shown", PyTuple::new(py, ink.shown())?)?;
        inks.append(i)?;
    }
    out.set_item("inks", inks)?;
    Ok(out)
}

#[pymodule]
fn _halftone(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Converted>()?;
    m.add_class::<Clip>()?;
    m.add_function(wrap_pyfunction!(convert, m)?)?;
    m.add_function(wrap_pyfunction!(convert_to_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(lists_json, m)?)?;
    m.add_function(wrap_pyfunction!(options_json, m)?)?;
    m.add_function(wrap_pyfunction!(devices, m)?)?;
    m.add_function(wrap_pyfunction!(device, m)?)?;
    // The default pixel limit, which the Python half holds arrays to before converting
    // them (float and bool arrays are converted there).
    m.add(
        "MAX_PIXELS",
        halftone::io::ReadOptions::default().max_pixels,
    )?;
    Ok(())
}
