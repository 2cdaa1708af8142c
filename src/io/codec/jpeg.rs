//! JPEG through the system's libjpeg-turbo (SIMD IDCT and colour conversion), row by row,
//! at full size or at 1/2, 1/4 or 1/8 by DCT scaling (shrink-on-load: an 8×8 block's
//! inverse DCT is computed only for its lowest 4×4, 2×2 or 1×1 frequencies, so a thumbnail
//! costs the entropy decoding and little else).
//!
//! Built only when libjpeg's header was found (`cfg(halftone_libjpeg)`, see build.rs); the
//! `image` crate decodes every JPEG otherwise, and the ones this module declines: CMYK and
//! YCCK files. An EXIF orientation is read here and applied by the caller
//! ([`crate::pipeline::jpeg::JpegSource`] turns the decoded image). The file is held in
//! memory (it is much smaller than its pixels).

use std::ffi::{c_char, c_int, c_long, c_uint, c_ulong, c_void};
use std::path::{Path, PathBuf};

use crate::error::Result;
use crate::io::{decode_err, ReadOptions};

extern "C" {
    fn hj_open(data: *const u8, len: c_ulong, msg: *mut c_char, msg_len: c_ulong) -> *mut c_void;
    fn hj_info(
        h: *mut c_void,
        w: *mut c_uint,
        hgt: *mut c_uint,
        components: *mut c_int,
        color_space: *mut c_int,
        progressive: *mut c_int,
    );
    fn hj_start(
        h: *mut c_void,
        denom: c_int,
        gray: c_int,
        out_w: *mut c_uint,
        out_h: *mut c_uint,
        msg: *mut c_char,
        msg_len: c_ulong,
    ) -> c_int;
    fn hj_read(
        h: *mut c_void,
        buf: *mut u8,
        rows: c_ulong,
        stride: c_ulong,
        eof: *mut c_int,
        msg: *mut c_char,
        msg_len: c_ulong,
    ) -> c_long;
    fn hj_close(h: *mut c_void);
}

/// libjpeg's `J_COLOR_SPACE` values this module decodes.
const JCS_GRAYSCALE: c_int = 1;
const JCS_RGB: c_int = 2;
const JCS_YCBCR: c_int = 3;

/// Room for libjpeg's messages (`JMSG_LENGTH_MAX` is 200).
const MSG_LEN: usize = 256;

/// An open JPEG: its bytes and libjpeg's decompressor.
pub struct Jpeg {
    name: PathBuf,
    /// The file; libjpeg reads from it, so it lives as long as the decompressor.
    data: Vec<u8>,
    handle: *mut c_void,
    /// Full size.
    pub width: usize,
    /// Full size.
    pub height: usize,
    /// True for one component (grey); false for YCbCr or RGB.
    pub gray: bool,
    /// Progressive files keep all their coefficients until the last scan.
    pub progressive: bool,
    /// Resolution from the JFIF header.
    pub dpi: Option<f64>,
    /// The EXIF orientation (1–8; 1 when there is none or it is not one of those), which
    /// the decoded rows do not apply.
    pub orientation: u16,
    /// Output size once started.
    out: Option<(usize, usize)>,
    rows_read: usize,
}

// The decompressor is used by one thread at a time (moved, never shared).
unsafe impl Send for Jpeg {}

impl Drop for Jpeg {
    fn drop(&mut self) {
        // SAFETY: `handle` came from hj_open and is freed once, here.
        unsafe { hj_close(self.handle) }
    }
}

fn message(buf: &[c_char]) -> String {
    let bytes: Vec<u8> = buf
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

impl Jpeg {
    /// Opens a JPEG held in `data` and reads its header: `Ok(None)` when this module declines
    /// it (the caller decodes it with the `image` crate), an error for a file that is
    /// truncated, corrupt or over the pixel limit.
    pub fn open(name: &Path, data: Vec<u8>, opts: &ReadOptions) -> Result<Option<Jpeg>> {
        super::read::check_jpeg_data(&data, name)?;
        // As the whole-image reader takes it: a value outside 1–8 is no orientation.
        let orientation = exif_orientation(&data)
            .filter(|o| (1..=8).contains(o))
            .unwrap_or(1);
        let mut msg = [0 as c_char; MSG_LEN];
        // SAFETY: data outlives the handle (both owned by the returned Jpeg, the handle
        // dropped first in Drop); msg is MSG_LEN long.
        let handle = unsafe {
            hj_open(
                data.as_ptr(),
                data.len() as c_ulong,
                msg.as_mut_ptr(),
                MSG_LEN as c_ulong,
            )
        };
        if handle.is_null() {
            return Err(decode_err(
                name,
                format!("bad JPEG file: {}", message(&msg)),
            ));
        }
        let (mut w, mut h, mut comps, mut cs, mut prog) = (0, 0, 0, 0, 0);
        // SAFETY: a valid handle and pointers to locals.
        unsafe { hj_info(handle, &mut w, &mut h, &mut comps, &mut cs, &mut prog) };
        let dpi = super::read::jfif_density(&data);
        let jpeg = Jpeg {
            name: name.to_path_buf(),
            data,
            handle,
            width: w as usize,
            height: h as usize,
            gray: cs == JCS_GRAYSCALE,
            progressive: prog != 0,
            dpi,
            orientation,
            out: None,
            rows_read: 0,
        };
        let ok = match cs {
            JCS_GRAYSCALE => comps == 1,
            JCS_RGB | JCS_YCBCR => comps == 3,
            _ => false,
        };
        if !ok {
            return Ok(None);
        }
        crate::io::check_pixels(name, w, h, opts)?;
        if w == 0 || h == 0 {
            return Err(decode_err(name, format!("image is {w}x{h}: no pixels")));
        }
        Ok(Some(jpeg))
    }

    /// The size a decode at 1/`denom` gives: libjpeg rounds up (`jdiv_round_up`).
    pub fn scaled_size(&self, denom: usize) -> (usize, usize) {
        (self.width.div_ceil(denom), self.height.div_ceil(denom))
    }

    /// The bytes of the file.
    pub fn file_bytes(&self) -> usize {
        self.data.len()
    }

    /// Starts decoding at 1/`denom` (1, 2, 4 or 8); returns the output size.
    pub fn start(&mut self, denom: usize) -> Result<(usize, usize)> {
        assert!(matches!(denom, 1 | 2 | 4 | 8), "DCT scaling is 1/1 to 1/8");
        assert!(self.out.is_none(), "started twice");
        let (mut w, mut h) = (0, 0);
        let mut msg = [0 as c_char; MSG_LEN];
        // SAFETY: a valid handle, locals, msg MSG_LEN long.
        let r = unsafe {
            hj_start(
                self.handle,
                denom as c_int,
                self.gray as c_int,
                &mut w,
                &mut h,
                msg.as_mut_ptr(),
                MSG_LEN as c_ulong,
            )
        };
        if r != 0 {
            return Err(self.err(&msg));
        }
        let size = (w as usize, h as usize);
        debug_assert_eq!(size, self.scaled_size(denom));
        self.out = Some(size);
        Ok(size)
    }

    fn err(&self, msg: &[c_char]) -> crate::error::Error {
        decode_err(&self.name, format!("bad JPEG file: {}", message(msg)))
    }

    /// Samples a pixel of output: 1 (grey) or 3 (RGB, interleaved).
    pub fn channels(&self) -> usize {
        if self.gray {
            1
        } else {
            3
        }
    }

    /// Decodes the next `rows` rows (all there are, at most) into `buf`, interleaved,
    /// `width × channels` bytes a row. Data that ends early is an error.
    pub fn read_rows(&mut self, rows: usize, buf: &mut Vec<u8>) -> Result<usize> {
        let (w, h) = self.out.expect("start first");
        let rows = rows.min(h - self.rows_read);
        let stride = w * self.channels();
        buf.resize(rows * stride, 0);
        let mut eof = 0;
        let mut msg = [0 as c_char; MSG_LEN];
        // SAFETY: buf holds rows × stride bytes; libjpeg writes at most that.
        let got = unsafe {
            hj_read(
                self.handle,
                buf.as_mut_ptr(),
                rows as c_ulong,
                stride as c_ulong,
                &mut eof,
                msg.as_mut_ptr(),
                MSG_LEN as c_ulong,
            )
        };
        if got < 0 {
            return Err(self.err(&msg));
        }
        if eof != 0 || (got as usize) < rows {
            return Err(decode_err(
                &self.name,
                "truncated: the JPEG data ends early (image data is missing)".into(),
            ));
        }
        self.rows_read += rows;
        Ok(rows)
    }
}

/// The EXIF orientation (1–8) from an APP1 `Exif` segment before the image data, if any.
pub fn exif_orientation(bytes: &[u8]) -> Option<u16> {
    let mut pos = 2;
    while pos + 4 <= bytes.len() {
        if bytes[pos] != 0xFF {
            return None;
        }
        let marker = bytes[pos + 1];
        if marker == 0xFF {
            pos += 1;
            continue;
        }
        if marker == 0xDA || marker == 0xD9 {
            return None;
        }
        let len = u16::from_be_bytes([bytes[pos + 2], bytes[pos + 3]]) as usize;
        let seg = bytes.get(pos + 4..(pos + 2 + len).min(bytes.len()))?;
        if marker == 0xE1 && seg.starts_with(b"Exif\0\0") {
            return tiff_orientation(&seg[6..]);
        }
        pos += 2 + len;
    }
    None
}

/// Tag 0x0112 of IFD0 of a TIFF structure (EXIF's container).
fn tiff_orientation(t: &[u8]) -> Option<u16> {
    let le = match t.get(..2)? {
        b"II" => true,
        b"MM" => false,
        _ => return None,
    };
    let u16_at = |i: usize| -> Option<u16> {
        let b = t.get(i..i + 2)?;
        Some(if le {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        })
    };
    let u32_at = |i: usize| -> Option<u32> {
        let b = t.get(i..i + 4)?;
        let a = [b[0], b[1], b[2], b[3]];
        Some(if le {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        })
    };
    let ifd = u32_at(4)? as usize;
    let n = u16_at(ifd)? as usize;
    (0..n).find_map(|k| {
        let e = ifd + 2 + 12 * k;
        (u16_at(e)? == 0x0112).then(|| u16_at(e + 8))?
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u32, h: u32, rgb: bool) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90);
        let px: Vec<u8> = (0..w * h * if rgb { 3 } else { 1 })
            .map(|i| ((i * 37) % 251) as u8)
            .collect();
        let ct = if rgb {
            image::ExtendedColorType::Rgb8
        } else {
            image::ExtendedColorType::L8
        };
        enc.encode(&px, w, h, ct).unwrap();
        out
    }

    #[test]
    fn decodes_full_and_scaled_sizes() {
        for rgb in [false, true] {
            let bytes = jpeg(37, 21, rgb);
            for denom in [1, 2, 4, 8] {
                let mut j = Jpeg::open(Path::new("t.jpg"), bytes.clone(), &ReadOptions::default())
                    .unwrap()
                    .unwrap();
                assert_eq!(j.gray, !rgb);
                let (w, h) = j.start(denom).unwrap();
                assert_eq!((w, h), (37usize.div_ceil(denom), 21usize.div_ceil(denom)));
                let mut buf = Vec::new();
                let mut rows = 0;
                while rows < h {
                    rows += j.read_rows(5, &mut buf).unwrap();
                    assert_eq!(buf.len() % (w * j.channels()), 0);
                }
                assert_eq!(rows, h);
            }
        }
    }

    #[test]
    fn full_size_is_close_to_the_image_crate() {
        // Two decoders of one file differ only in rounding (IDCT, upsampling).
        let bytes = jpeg(64, 48, true);
        let mut j = Jpeg::open(Path::new("t.jpg"), bytes.clone(), &ReadOptions::default())
            .unwrap()
            .unwrap();
        j.start(1).unwrap();
        let mut buf = Vec::new();
        j.read_rows(48, &mut buf).unwrap();
        let theirs = image::load_from_memory(&bytes)
            .unwrap()
            .to_rgb8()
            .into_raw();
        let worst = buf
            .iter()
            .zip(&theirs)
            .map(|(&a, &b)| (a as i32 - b as i32).abs())
            .max()
            .unwrap();
        assert!(worst <= 3, "largest difference {worst}");
    }

    #[test]
    fn truncated_and_garbage_are_errors() {
        let bytes = jpeg(64, 64, true);
        let cut = bytes[..bytes.len() * 2 / 3].to_vec();
        let e = Jpeg::open(Path::new("cut.jpg"), cut, &ReadOptions::default());
        assert!(e.is_err());
        let mut junk = bytes[..200].to_vec();
        junk.extend_from_slice(&[0x12; 400]);
        junk.extend_from_slice(&[0xFF, 0xD9]);
        let r = Jpeg::open(Path::new("junk.jpg"), junk, &ReadOptions::default());
        // Scan data that stops at a marker is missing data, not a grey picture.
        if let Ok(Some(mut j)) = r {
            let mut buf = Vec::new();
            assert!(j.start(1).is_err() || j.read_rows(64, &mut buf).is_err());
        }
    }

    #[test]
    fn orientation_is_read_from_exif() {
        // APP1: Exif, big-endian TIFF, one IFD0 entry: orientation 6.
        let mut tiff = b"MM\0\x2a\0\0\0\x08\0\x01".to_vec();
        tiff.extend_from_slice(&[0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0]);
        tiff.extend_from_slice(&[0, 0, 0, 0]);
        let mut seg = b"Exif\0\0".to_vec();
        seg.extend_from_slice(&tiff);
        let mut bytes = vec![0xFF, 0xD8, 0xFF, 0xE1];
        bytes.extend_from_slice(&((seg.len() + 2) as u16).to_be_bytes());
        bytes.extend_from_slice(&seg);
        bytes.extend_from_slice(&[0xFF, 0xDA, 0, 2]);
        assert_eq!(exif_orientation(&bytes), Some(6));
        assert_eq!(exif_orientation(&jpeg(8, 8, false)), None);
    }
}
