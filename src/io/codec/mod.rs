//! Image codecs: the readers of the image files halftone takes (through the `image` crate,
//! with fast paths of our own for binary greymaps, bitmaps and pixmaps, and JPEG through
//! libjpeg-turbo with shrink-on-load) and the writers of the image files it makes (PNG,
//! TIFF with Group 4, BMP, PBM/PGM/PPM). PDF pages are read as images by rasterising them
//! at the output's resolution (`pdf`, feature `pdf`). The printer languages are in
//! [`super::lang`].

pub(crate) mod bmp;
#[cfg(halftone_libjpeg)]
pub mod jpeg;
#[cfg(feature = "pdf")]
pub mod pdf;
#[cfg(unix)]
pub(crate) mod pixmap;
pub(crate) mod png;
pub mod pnm;
pub(crate) mod read;
pub(crate) mod tiff;

/// The extensions of the image files the readers take, which a folder walk picks up (files
/// named explicitly are taken whatever their extension).
pub const IMAGE_EXTENSIONS: &[&str] = &[
    "png", "jpg", "jpeg", "tif", "tiff", "bmp", "gif", "webp", "pbm", "pgm", "ppm", "pnm",
];
