//! Planes in, levels out: the decoded image, the views methods read, and the halftone they
//! write.
//!
//! Input planes keep the file's own codes (`u8` or `u16`); a [`ToneTable`] says what light
//! each code is. Output is a [`Halftone`]: a level index per sample, packed at the smallest
//! width that holds the levels (1 bit a pixel for bilevel), rows padded to whole bytes,
//! most significant bits first. Level 0 is the darkest (solid ink), level `levels − 1` paper.

use crate::tone::{Encoding, ToneOptions, ToneTable};

/// The codes of one plane, at the file's own depth.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// 8-bit codes.
    U8(Vec<u8>),
    /// 16-bit codes.
    U16(Vec<u16>),
}

impl Samples {
    /// Bits per code: 8 or 16.
    pub fn bits(&self) -> u32 {
        match self {
            Samples::U8(_) => 8,
            Samples::U16(_) => 16,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::U16(v) => v.len(),
        }
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A borrowed view.
    pub fn as_ref(&self) -> SamplesRef<'_> {
        match self {
            Samples::U8(v) => SamplesRef::U8(v),
            Samples::U16(v) => SamplesRef::U16(v),
        }
    }
}

/// A borrowed run of codes.
#[derive(Clone, Copy, Debug)]
pub enum SamplesRef<'a> {
    /// 8-bit codes.
    U8(&'a [u8]),
    /// 16-bit codes.
    U16(&'a [u16]),
}

/// Whether an image is grey or colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorKind {
    /// One plane.
    Gray,
    /// Three planes: red, green, blue.
    Rgb,
}

/// A decoded image: planar, alpha already composited over paper white, orientation applied.
#[derive(Clone, Debug)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Grey (one plane) or RGB (three planes).
    pub color: ColorKind,
    /// The planes, row-major, `width × height` samples each.
    pub planes: Vec<Samples>,
    /// How the codes relate to light.
    pub encoding: Encoding,
    /// Resolution stored in the file, if any (dots per inch, horizontal).
    pub dpi: Option<f64>,
}

impl Image {
    /// A grey 8-bit sRGB image from row-major codes.
    pub fn gray8(width: usize, height: usize, data: Vec<u8>) -> Image {
        assert_eq!(data.len(), width * height, "gray8: wrong sample count");
        Image {
            width,
            height,
            color: ColorKind::Gray,
            planes: vec![Samples::U8(data)],
            encoding: Encoding::Srgb,
            dpi: None,
        }
    }

    /// An RGB 8-bit sRGB image from interleaved `r g b` codes.
    pub fn rgb8(width: usize, height: usize, interleaved: &[u8]) -> Image {
        assert_eq!(
            interleaved.len(),
            width * height * 3,
            "rgb8: wrong sample count"
        );
        let planes = (0..3)
            .map(|c| Samples::U8(interleaved.iter().skip(c).step_by(3).copied().collect()))
            .collect();
        Image {
            width,
            height,
            color: ColorKind::Rgb,
            planes,
            encoding: Encoding::Srgb,
            dpi: None,
        }
    }

    /// Bits per code of the planes (8 or 16).
    pub fn bits(&self) -> u32 {
        self.planes.first().map_or(8, Samples::bits)
    }

    /// A single luminance plane computed in linear light (Rec. 709 / sRGB primaries:
    /// Y = 0.2126 R + 0.7152 G + 0.0722 B), stored as 16-bit linear codes so that no
    /// precision is lost. Grey images are returned unchanged.
    pub fn to_luminance(&self, opts: &ToneOptions) -> Image {
        if self.color == ColorKind::Gray {
            return self.clone();
        }
        // Decode each channel to linear (without the user's curves: those apply to Y later).
        let plain = ToneOptions {
            linearize: opts.linearize,
            ..ToneOptions::default()
        };
        let table = ToneTable::new(self.bits(), self.encoding, &plain);
        let t = table.as_slice();
        let n = self.width * self.height;
        let mut y = vec![0u16; n];
        let code = |p: &Samples, i: usize| match p {
            Samples::U8(v) => v[i] as usize,
            Samples::U16(v) => v[i] as usize,
        };
        let encoding = if opts.linearize {
            Encoding::Linear
        } else {
            self.encoding
        };
        // Bands of pixels on every core: each pixel's value depends on it alone.
        use rayon::prelude::*;
        const BAND: usize = 1 << 16;
        y.par_chunks_mut(BAND).enumerate().for_each(|(b, band)| {
            for (j, out) in band.iter_mut().enumerate() {
                let i = b * BAND + j;
                let l = 0.2126 * t[code(&self.planes[0], i)]
                    + 0.7152 * t[code(&self.planes[1], i)]
                    + 0.0722 * t[code(&self.planes[2], i)];
                *out = round_half_up(l.clamp(0.0, 1.0) * 65535.0);
            }
        });
        Image {
            width: self.width,
            height: self.height,
            color: ColorKind::Gray,
            planes: vec![Samples::U16(y)],
            encoding,
            dpi: self.dpi,
        }
    }

    /// The tone tables for this image's planes (one table serves every plane).
    pub fn tone_table(&self, opts: &ToneOptions) -> ToneTable {
        ToneTable::new(self.bits(), self.encoding, opts)
    }

    /// Views of the planes with their tone table, ready for a method.
    pub fn planes<'a>(&'a self, tone: &'a ToneTable) -> Planes<'a> {
        Planes {
            width: self.width,
            height: self.height,
            planes: self
                .planes
                .iter()
                .map(|s| PlaneRef {
                    width: self.width,
                    height: self.height,
                    samples: s.as_ref(),
                    tone: tone.as_slice(),
                })
                .collect(),
        }
    }
}

/// `x.round() as u16` for `x` in 0..=65535, without the `roundf` call the baseline x86-64
/// target makes of `round` (a quarter of a JPEG-to-PBM run went there): the truncation and
/// the fraction `x − ⌊x⌋` are exact in `f32` over this range, so comparing the fraction with
/// ½ rounds halves up exactly as `round` does for non-negative values.
#[inline(always)]
fn round_half_up(x: f32) -> u16 {
    let t = x as u16;
    t + (x - t as f32 >= 0.5) as u16
}

/// One plane as a method sees it: codes plus the table that says what light they are.
#[derive(Clone, Copy, Debug)]
pub struct PlaneRef<'a> {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major codes.
    pub samples: SamplesRef<'a>,
    /// Linear reflectance of every code (256 or 65536 entries).
    pub tone: &'a [f32],
}

impl<'a> PlaneRef<'a> {
    /// Rows `from..from + n` of the plane, as a plane of their own.
    pub fn rows(&self, from: usize, n: usize) -> PlaneRef<'a> {
        let r = from * self.width..(from + n) * self.width;
        PlaneRef {
            width: self.width,
            height: n,
            samples: match self.samples {
                SamplesRef::U8(v) => SamplesRef::U8(&v[r]),
                SamplesRef::U16(v) => SamplesRef::U16(&v[r]),
            },
            tone: self.tone,
        }
    }

    /// Linear reflectance of pixel (x, y).
    #[inline]
    pub fn value(&self, x: usize, y: usize) -> f32 {
        let i = y * self.width + x;
        match self.samples {
            SamplesRef::U8(v) => self.tone[v[i] as usize],
            SamplesRef::U16(v) => self.tone[v[i] as usize],
        }
    }

    /// Writes row `y` as linear reflectance into `out` (`out.len() == width`).
    pub fn row_linear(&self, y: usize, out: &mut [f32]) {
        let start = y * self.width;
        match self.samples {
            SamplesRef::U8(v) => {
                for (o, &c) in out.iter_mut().zip(&v[start..start + self.width]) {
                    *o = self.tone[c as usize];
                }
            }
            SamplesRef::U16(v) => {
                for (o, &c) in out.iter_mut().zip(&v[start..start + self.width]) {
                    *o = self.tone[c as usize];
                }
            }
        }
    }
}

/// The planes of one image, as a method receives them.
#[derive(Clone, Debug)]
pub struct Planes<'a> {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// One plane (grey) or three (red, green, blue).
    pub planes: Vec<PlaneRef<'a>>,
}

impl<'a> Planes<'a> {
    /// The red, green and blue planes: three planes as they are, one grey plane three times.
    /// `what` names the user in the error for any other count (`"a palette"`).
    pub fn rgb(&self, what: &str) -> crate::error::Result<[&PlaneRef<'a>; 3]> {
        match self.planes.len() {
            1 => Ok([&self.planes[0]; 3]),
            3 => Ok([&self.planes[0], &self.planes[1], &self.planes[2]]),
            n => Err(crate::error::Error::Invalid(format!(
                "{what} needs one or three input planes, not {n}"
            ))),
        }
    }
}

/// Storage bits per sample for `levels` output levels: 1, 2, 4 or 8.
pub fn bits_for_levels(levels: u16) -> u8 {
    match levels {
        0..=2 => 1,
        3..=4 => 2,
        5..=16 => 4,
        _ => 8,
    }
}

/// The output of every method: the level index of every sample, packed.
#[derive(Clone, Debug, PartialEq)]
pub struct Halftone {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Levels per channel (2 = bilevel), at most 256.
    pub levels: u16,
    /// Storage bits per sample: 1, 2, 4 or 8 (see [`bits_for_levels`]).
    pub bits: u8,
    /// Bytes per packed row of one plane.
    pub stride: usize,
    /// One plane (grey, or palette indices) or three (red, green, blue), `stride × height` bytes each.
    pub planes: Vec<Vec<u8>>,
    /// When set, the single plane holds indices into these sRGB colours.
    pub palette: Option<Vec<[u8; 3]>>,
}

impl Halftone {
    /// An all-black (level 0) halftone with `channels` planes.
    pub fn new(width: usize, height: usize, channels: usize, levels: u16) -> Halftone {
        assert!((2..=256).contains(&levels), "levels must be 2..=256");
        let bits = bits_for_levels(levels);
        let stride = (width * bits as usize).div_ceil(8);
        Halftone {
            width,
            height,
            levels,
            bits,
            stride,
            planes: vec![vec![0u8; stride * height]; channels],
            palette: None,
        }
    }

    /// Number of planes.
    pub fn channels(&self) -> usize {
        self.planes.len()
    }

    /// Packed row `y` of plane `c`.
    pub fn row(&self, c: usize, y: usize) -> &[u8] {
        &self.planes[c][y * self.stride..(y + 1) * self.stride]
    }

    /// Level of sample (x, y) in plane `c`.
    #[inline]
    pub fn get(&self, c: usize, x: usize, y: usize) -> u8 {
        unpack(self.row(c, y), self.bits, x)
    }

    /// Sets the level of sample (x, y) in plane `c`.
    #[inline]
    pub fn set(&mut self, c: usize, x: usize, y: usize, level: u8) {
        let (bits, stride) = (self.bits, self.stride);
        pack(
            &mut self.planes[c][y * stride..(y + 1) * stride],
            bits,
            x,
            level,
        );
    }

    /// Unpacks row `y` of plane `c` to one level per byte.
    pub fn unpack_row(&self, c: usize, y: usize, out: &mut [u8]) {
        unpack_row(self.row(c, y), self.bits, out);
    }

    /// Every level of plane `c`, one per byte, row-major.
    pub fn levels_of(&self, c: usize) -> Vec<u8> {
        let mut out = vec![0u8; self.width * self.height];
        for (y, row) in out.chunks_exact_mut(self.width.max(1)).enumerate() {
            self.unpack_row(c, y, row);
        }
        out
    }

    /// Linear reflectance of level `k`: device levels are evenly spaced in light.
    pub fn reflectance(&self, level: u8) -> f64 {
        level as f64 / (self.levels - 1) as f64
    }
}

/// Reads sample `x` of a packed row.
#[inline]
pub fn unpack(row: &[u8], bits: u8, x: usize) -> u8 {
    let per_byte = 8 / bits as usize;
    let byte = row[x / per_byte];
    let shift = 8 - bits as usize * (x % per_byte + 1);
    (byte >> shift) & ((1u16 << bits) - 1) as u8
}

/// Writes sample `x` of a packed row.
#[inline]
pub fn pack(row: &mut [u8], bits: u8, x: usize, level: u8) {
    let per_byte = 8 / bits as usize;
    let shift = 8 - bits as usize * (x % per_byte + 1);
    let mask = (((1u16 << bits) - 1) as u8) << shift;
    let b = &mut row[x / per_byte];
    *b = (*b & !mask) | ((level << shift) & mask);
}

/// Packs one level per byte (`levels`) into a packed row (`row`, zero-padded at the end).
pub fn pack_row(levels: &[u8], bits: u8, row: &mut [u8]) {
    if bits == 8 {
        row[..levels.len()].copy_from_slice(levels);
        return;
    }
    if bits == 1 {
        // Eight 0/1 bytes to one byte with one multiply: the multiplier moves byte i's low
        // bit to bit 63 − i, so the top byte holds them MSB first.
        let mut chunks = levels.chunks_exact(8);
        for (out, c) in row.iter_mut().zip(&mut chunks) {
            let v = u64::from_le_bytes(c.try_into().expect("chunks of eight"));
            *out = (v.wrapping_mul(0x8040_2010_0804_0201) >> 56) as u8;
        }
        let tail = chunks.remainder();
        if let Some(out) = row.get_mut(levels.len() / 8).filter(|_| !tail.is_empty()) {
            *out = tail
                .iter()
                .enumerate()
                .fold(0, |b, (i, &l)| b | (l & 1) << (7 - i));
        }
        return;
    }
    match bits {
        2 => pack_small::<4>(levels, row),
        4 => pack_small::<2>(levels, row),
        _ => pack_small::<1>(levels, row),
    }
}

/// [`pack_row`] for `N` levels a byte of `8 / N` bits each: whole bytes from fixed-size
/// chunks (which the compiler turns into vector code), then the partial last byte.
fn pack_small<const N: usize>(levels: &[u8], row: &mut [u8]) {
    let bits = 8 / N;
    let byte = |chunk: &[u8]| {
        chunk
            .iter()
            .enumerate()
            .fold(0u8, |b, (i, &l)| b | l << (8 - bits * (i + 1)))
    };
    let mut chunks = levels.chunks_exact(N);
    for (out, c) in row.iter_mut().zip(&mut chunks) {
        let c: &[u8; N] = c.try_into().expect("chunks of N");
        *out = byte(c);
    }
    let tail = chunks.remainder();
    if !tail.is_empty() {
        row[levels.len() / N] = byte(tail);
    }
}

/// Unpacks a packed row into one level per byte (`out.len()` samples).
pub fn unpack_row(row: &[u8], bits: u8, out: &mut [u8]) {
    if bits == 8 {
        out.copy_from_slice(&row[..out.len()]);
        return;
    }
    let per_byte = 8 / bits as usize;
    let mask = ((1u16 << bits) - 1) as u8;
    for (chunk, &b) in out.chunks_mut(per_byte).zip(row) {
        for (i, o) in chunk.iter_mut().enumerate() {
            *o = (b >> (8 - bits as usize * (i + 1))) & mask;
        }
    }
}

/// How colour input is treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ColorMode {
    /// One plane: luminance computed in linear light.
    #[default]
    Gray,
    /// Three planes, each halftoned on its own (a grey input gives three equal planes).
    Rgb,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_half_up_is_round() {
        let mut x = 0.0f32;
        // Every f32 step near the halves and ends, and a sweep of the whole range.
        for v in [
            0.0f32, 0.49999997, 0.5, 0.50000006, 1.4999999, 1.5, 65534.5, 65535.0,
        ] {
            assert_eq!(round_half_up(v), v.round() as u16, "{v}");
        }
        while x <= 65535.0 {
            assert_eq!(round_half_up(x), x.round() as u16, "{x}");
            x += 0.013671875 + x * 1e-6;
        }
    }

    #[test]
    fn pack_unpack_all_widths() {
        for (&levels, w) in [2u16, 3, 4, 5, 16, 17, 256]
            .iter()
            .flat_map(|l| [0usize, 1, 2, 3, 5, 13, 1001].map(|w| (l, w)))
        {
            let bits = bits_for_levels(levels);
            let src: Vec<u8> = (0..w).map(|i| (i * 7 % levels as usize) as u8).collect();
            let mut row = vec![0u8; (w * bits as usize).div_ceil(8)];
            pack_row(&src, bits, &mut row);
            let mut back = vec![0u8; w];
            unpack_row(&row, bits, &mut back);
            assert_eq!(src, back, "levels {levels}");
            for (x, &l) in src.iter().enumerate() {
                assert_eq!(unpack(&row, bits, x), l);
            }
            let mut row2 = vec![0xFFu8; row.len()];
            for (x, &l) in src.iter().enumerate() {
                pack(&mut row2, bits, x, l);
            }
            let mut back2 = vec![0u8; w];
            unpack_row(&row2, bits, &mut back2);
            assert_eq!(src, back2);
        }
    }

    #[test]
    fn bilevel_is_msb_first() {
        let mut h = Halftone::new(10, 1, 1, 2);
        h.set(0, 0, 0, 1);
        h.set(0, 9, 0, 1);
        assert_eq!(h.row(0, 0), &[0b1000_0000, 0b0100_0000]);
        assert_eq!(h.stride, 2);
    }

    #[test]
    fn luminance_of_rgb_in_linear_light() {
        // Pure green at full intensity is 71.52% luminance.
        let img = Image::rgb8(1, 1, &[0, 255, 0]);
        let y = img.to_luminance(&ToneOptions::default());
        let t = y.tone_table(&ToneOptions::default());
        let p = y.planes(&t);
        assert!((p.planes[0].value(0, 0) - 0.7152).abs() < 1e-4);
    }
}
