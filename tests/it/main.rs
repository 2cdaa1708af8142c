//! The integration tests: one binary (one link instead of one per file), one module per
//! area, and the helpers every module shares in `tests/common`.
// The tests' own pictures and reference formulas: the standard library's functions are fine
// here (clippy.toml keeps them out of the library).
#![allow(clippy::disallowed_methods)]

#[path = "../common/mod.rs"]
mod common;

mod accuracy;
mod bad_input;
mod batch;
mod batch_resume;
mod blue_noise;
mod calibrate;
mod cpu_paths;
mod devices;
mod diffusion;
mod formats;
mod fuzz_regressions;
mod goldens;
mod hostile;
mod hues;
mod inks;
mod ipp_client;
mod library;
mod motion;
mod newcomer;
mod ordered;
mod palette;
mod panel_decode;
mod photos;
mod printers;
mod properties;
mod quality;
mod readme;
mod render;
mod screens;
mod screens_icc;
mod screens_presets;
mod seed_tables;
mod serve;
mod serve_dnssd;
mod serve_faults;
mod shrink;
mod stability;
mod streaming;
mod streams;

/// Without libjpeg (Debian: libjpeg-dev) build.rs leaves out the JPEG shim, and with it
/// the `photos` module and the JPEG unit tests: say so, and fail under CI.
#[cfg(not(halftone_libjpeg))]
#[test]
fn libjpeg_is_built_in() {
    common::skip(
        "photos (all of it) and the JPEG unit tests",
        "built without libjpeg (apt-get install libjpeg-dev, then rebuild)",
    );
}
