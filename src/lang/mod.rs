//! Printer raster formats read as input: what IPP Everywhere and AirPrint clients send.
//!
//! - [`pwg`]: PWG raster (`image/pwg-raster`, PWG 5102.4).
//! - [`urf`]: Apple raster (`image/urf`).
//! - `pdf` (feature `pdf`): PDF pages rasterised at the output's resolution.

#[cfg(feature = "pdf")]
pub mod pdf;
pub mod pwg;
pub mod urf;
