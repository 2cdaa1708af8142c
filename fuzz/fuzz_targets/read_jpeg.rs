//! The read path for JPEG files: sniffing, limits, decoding, alpha, orientation, resolution.
//! Inputs that do not start with the signature get it prepended, so every run reaches
//! the JPEG decoder.
#![no_main]

use libfuzzer_sys::fuzz_target;

mod read_common;

fuzz_target!(|data: &[u8]| {
    read_common::read_with_magic(data, b"\xff\xd8\xff", "fuzz.jpeg");
});
