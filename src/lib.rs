//! halftone: turns continuous-tone images into halftones — the bitmaps a printer, an e-ink
//! panel or a thermal printer can reproduce.
//!
//! The data path is one straight road:
//! decode ([`io`]) → planes with a tone table ([`raster`], [`tone`]) → a [`method::Method`]
//! → a [`raster::Halftone`] of level indices → encode and write atomically ([`io`]).

mod api;
pub mod batch;
#[cfg(feature = "lab")]
pub mod bench;
pub mod borrowed;
pub mod color;
pub mod error;
pub mod io;
pub mod mask;
pub mod method;
pub mod names;
pub mod options;
pub mod pipeline;
pub mod preset;
pub mod press;
pub mod printer_model;
pub mod quality;
pub mod raster;
pub mod render;
pub mod resize;
#[cfg(feature = "lab")]
pub mod stability;
pub mod tone;

pub use api::{
    compare, convert, convert_to, convert_to_bytes, encode, methods, output_format, plates,
    read_whole, Book, CompareOptions, Converter, Input, Output, Plates,
};
pub use error::{Error, Result};
pub use io::{Compression, Format};
pub use mask::Mask;
pub use method::Method;
pub use options::{
    Color, ContentKind, MethodKind, Options, PrinterModelKind, SeparationKind, Threshold,
};
pub use pipeline::{MaxMemory, Report};
pub use quality::Quality;
pub use raster::{Halftone, Image, Planes};
pub use tone::{ToneOptions, ToneTable};

/// How colour input is treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ColorMode {
    /// One plane: luminance computed in linear light.
    #[default]
    Gray,
    /// Three planes, each halftoned on its own (a grey input gives three equal planes).
    Rgb,
}

/// Halftones a decoded image: colour handling, tone table, then the method.
pub fn halftone_image(
    img: &Image,
    method: &dyn Method,
    color: ColorMode,
    tone: &ToneOptions,
) -> Result<Halftone> {
    let gray;
    let src = match (color, img.color) {
        (ColorMode::Gray, raster::ColorKind::Rgb) => {
            gray = img.to_luminance(tone);
            &gray
        }
        _ => img,
    };
    let table = src.tone_table(tone);
    let mut planes = src.planes(&table);
    if color == ColorMode::Rgb && planes.planes.len() == 1 {
        let p = planes.planes[0];
        planes.planes = vec![p, p, p];
    }
    method.halftone(&planes)
}
