//! The read path for TIFF files: sniffing, limits, decoding, alpha, orientation, resolution.
//! Inputs that do not start with the signature get it prepended, so every run reaches
//! the TIFF decoder.
#![no_main]

use libfuzzer_sys::fuzz_target;

mod read_common;

fuzz_target!(|data: &[u8]| {
    read_common::read_with_magic(data, b"II*\0", "fuzz.tiff");
});
