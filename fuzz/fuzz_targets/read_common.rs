//! The shared body of the `read_*` targets: one image format's whole read path.

/// Prepends `magic` unless the input starts with it (so every run reaches that format's
/// decoder), decodes under a 64-kilopixel limit (small enough for thousands of runs a second;
/// the limit checks themselves are the same code at any size), then
/// halftones what was decoded, so the planes and tone tables see every shape a decoder
/// returns.
pub fn read_with_magic(data: &[u8], magic: &[u8], name: &str) {
    let bytes: std::borrow::Cow<'_, [u8]> = if data.starts_with(magic) {
        data.into()
    } else {
        [magic, data].concat().into()
    };
    let opts = halftone::io::ReadOptions {
        max_pixels: 1 << 16,
    };
    if let Ok(img) = halftone::io::read_image_bytes(&bytes, std::path::Path::new(name), &opts) {
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
