//! The print server's raster input: PWG raster (`RaS2`) and Apple raster (`UNIRAST`), every
//! page of a file, under a 64-kilopixel limit. The first byte picks the format (its
//! signature is prepended to the rest), so both decoders get half the runs. Every page is
//! either an image within the limit or an error: never a panic, never more than the limit.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let magic: &[u8] = if pick & 1 == 0 { b"RaS2" } else { b"UNIRAST\0" };
    let bytes = [magic, rest].concat();
    let opts = halftone::io::ReadOptions {
        max_pixels: 1 << 16,
    };
    let name = std::path::Path::new("fuzz.raster");
    let check = |img: halftone::raster::Image| {
        assert!(img.width > 0 && img.height > 0);
        assert!((img.width * img.height) as u64 <= opts.max_pixels);
    };
    if pick & 1 == 0 {
        if let Ok(pages) = halftone::io::lang::pwg::pages(&bytes, name, &opts) {
            for img in pages.take(64).flatten() {
                check(img);
            }
        }
    } else if let Ok(pages) = halftone::io::lang::urf::pages(&bytes, name, &opts) {
        for img in pages.take(64).flatten() {
            check(img);
        }
    }
});
