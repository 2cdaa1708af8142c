//! Mask files: both parsers, then the pattern table, the warnings and the ordered method.
#![no_main]

use std::path::Path;

use halftone::Mask;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let src = Path::new("fuzz.mask");
    if let Ok(m) = Mask::parse(text, src) {
        assert_eq!(m.len(), m.width * m.height);
        let mut sorted = m.ranks.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(i, &r)| r as usize == i));
        if m.len() <= 256 {
            let t = halftone::method::pattern::pattern_table(&m, 3);
            assert_eq!(t.len(), 2 * m.len() + 1);
            let _ = halftone::mask::warnings::check(&m);
        }
        let back = Mask::parse(&m.to_text("round trip"), src).unwrap();
        assert_eq!(back.ranks, m.ranks);
    }
    if let Ok(m) = Mask::parse_ranks(text, src) {
        assert_eq!(m.len(), m.width * m.height);
        if let Ok(o) = halftone::method::ordered::Ordered::new(m, 2) {
            let img = halftone::Image::gray8(5, 3, (0..15).map(|i| i * 17).collect());
            let h = halftone::halftone_image(
                &img,
                &o,
                halftone::ColorMode::Gray,
                &halftone::ToneOptions::default(),
            )
            .unwrap();
            assert_eq!((h.width, h.height), (5, 3));
        }
    }
});
