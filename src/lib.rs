//! halftone: turns continuous-tone images into halftones — the bitmaps a printer, an e-ink
//! panel or a thermal printer can reproduce.
//!
//! The data path is one straight road:
//! decode ([`io`]) → planes with a tone table ([`raster`], [`tone`]) → a [`method::Method`]
//! → a [`raster::Halftone`] of level indices → encode and write atomically ([`io`]).

#![warn(missing_docs)]

mod api;
#[cfg(feature = "batch")]
pub mod batch;
#[cfg(feature = "calibrate")]
pub mod calibrate;
pub mod color;
pub mod cpu;
pub mod error;
mod fmath;
pub mod in_memory;
pub mod io;
#[cfg(feature = "lab")]
pub mod lab;
pub mod mask;
pub mod method;
pub mod motion;
pub mod names;
pub mod options;
pub use options::preset;
pub mod pipeline;
pub mod press;
pub mod printer_model;
pub mod quality;
pub mod quantize;
pub mod raster;
#[cfg(feature = "render")]
pub mod render;
pub mod rendering;
pub mod resize;
pub mod scielab;
#[cfg(feature = "serve")]
pub mod serve;
pub mod tone;

pub use api::{
    compare, compare_device, convert, convert_to, convert_to_bytes, encode, methods, output_format,
    plates, read_whole, Book, CompareOptions, Converter, DeviceComparison, Input, Output, Plates,
};
pub use error::{Error, Result};
pub use io::panel;
pub use io::panel::Device;
pub use io::{Compression, Format};
#[cfg(feature = "lab")]
pub use lab::{bench, panel_stability, stability};
pub use mask::Mask;
pub use method::Method;
pub use options::{
    Color, ContentKind, InkColours, MethodKind, Options, PrinterModelKind, SeparationKind,
    Threshold,
};
pub use pipeline::halftone_image;
pub use pipeline::{MaxMemory, Report};
pub use quality::Quality;
pub use raster::{ColorMode, Halftone, Image, Planes};
pub use resize::FitMode;
pub use tone::{ToneOptions, ToneTable};
