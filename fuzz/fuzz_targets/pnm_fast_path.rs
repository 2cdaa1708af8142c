//! The P4/P5 fast path on its own: header parse, then the pixel data read into a plane,
//! from a stream (the same code reads files and standard input).
#![no_main]

use halftone::io::codec::pnm::{self, HeaderParse};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let HeaderParse::Ok(h) = pnm::parse_header(data) {
        assert!(h.data_offset <= data.len());
        // The limit the reader applies before allocating.
        if h.width as u64 * h.height as u64 > 1 << 22 {
            return;
        }
        let mut rest = &data[h.data_offset..];
        if let Ok(samples) = pnm::read_data(&h, &mut rest) {
            let n = h.width as usize * h.height as usize;
            match samples {
                halftone::raster::Samples::U8(v) => assert_eq!(v.len(), n),
                halftone::raster::Samples::U16(v) => assert_eq!(v.len(), n),
            }
        }
    }
});
