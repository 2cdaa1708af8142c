//! The read path for TIFF files: sniffing, limits, decoding, alpha, orientation, resolution.
//! Inputs that do not start with the signature get it prepended, so every run reaches
//! the TIFF decoder.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    const MAGIC: &[u8] = b"II*\0";
    let bytes: std::borrow::Cow<'_, [u8]> = if data.starts_with(MAGIC) {
        data.into()
    } else {
        [MAGIC, data].concat().into()
    };
    halftone_fuzz_read(&bytes);
});

/// Decodes under a 4-megapixel limit (the decode budget is then 64 MiB), then halftones
/// what was decoded, so the planes and tone tables see every shape a decoder returns.
fn halftone_fuzz_read(bytes: &[u8]) {
    let opts = halftone::io::ReadOptions {
        max_pixels: 1 << 22,
    };
    let name = std::path::Path::new("fuzz.tiff");
    if let Ok(img) = halftone::io::read_image_bytes(bytes, name, &opts) {
        assert!(img.width > 0 && img.height > 0);
        assert!((img.width * img.height) as u64 <= opts.max_pixels);
        let method = halftone::method::threshold::Threshold::new(0.5, 2).unwrap();
        let h = halftone::halftone_image(
            &img,
            &method,
            halftone::ColorMode::Gray,
            &halftone::ToneOptions::default(),
        )
        .unwrap();
        assert_eq!((h.width, h.height), (img.width, img.height));
    }
}
