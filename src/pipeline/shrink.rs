//! Shrink-on-load for the sources that cannot shrink themselves (PNM, PNG, TIFF): boxes of
//! `f × f` pixels averaged in linear light while the rows are decoded, before the final
//! Lanczos step, so a large file made into a small output never holds the full-size image.
//!
//! The rule is JPEG's ([`shrink_factor`]): only images of at least [`SHRINK_MIN_PIXELS`],
//! by at most 1/4, leaving at least [`SHRINK_MARGIN`] times the output's size to the resize.
//! JPEG can only reduce by 1/2 or 1/4 (DCT scaling); a box can be any width, so 1/3 is used
//! too where 1/4 would leave too little.
//!
//! The box hands on what the resize would have made of the same pixels: the resize turns
//! every code into a 16-bit linear code (`round(table · 65535)`) before filtering; the box
//! averages the table's values (kept to 1/256 of such a code) and rounds the mean once to a
//! 16-bit linear code ([`Encoding::Linear`]), which the resize's own table maps back to the
//! same light. With `--no-linearize` the codes themselves are averaged, as the resize would.

use super::band::{RowSource, SourceInfo};
use crate::error::Result;
use crate::raster::{Image, Samples};
use crate::tone::{Encoding, ToneOptions, ToneTable};

/// Images smaller than this are decoded at full size whatever the output's size.
///
/// DCT scaling averages sRGB-encoded codes, not light, so a block with strong contrast
/// inside it comes out too dark (a 2×2 block of codes 50 and 200 averages to 125, 21% light,
/// where its light is 42%). In a camera-sized photo a block of 2–4 pixels rarely holds such
/// contrast; in a small one nearly every block does: on scikit-image's 512-pixel photos,
/// halftones made through 1/8 scaling lost up to 5.9 dB HVS-PSNR against the full decode,
/// and 0.3–1.2 dB even through 1/2 scaling with twice the output's size left (docs/photos.md).
/// The box shrink averages light and has no such loss, but small images decode quickly
/// anyway, so it keeps the same threshold: one rule for every format.
pub const SHRINK_MIN_PIXELS: usize = 4_000_000;

/// The part of the shrinking left to the resize after the decoder's, at least: the Lanczos
/// filter, in linear light, then averages every output pixel over several decoded ones.
pub const SHRINK_MARGIN: usize = 2;

/// The largest box: a box sum of 16-bit linear codes with 8 fractional bits must fit a
/// `u32` (`f² · 65535 · 256 < 2³²` for `f ≤ 15`); 4 is JPEG's limit and the rule's.
const MAX_FACTOR: usize = 4;

/// Input bytes a band of the wrapped source holds, about (a band is a whole number of boxes).
const INNER_BAND_BYTES: usize = 1 << 20;

/// The box side (4, 3, 2, else 1) for an image of `w × h` to be resized to `min_w × min_h`:
/// the largest whose output, `⌈w/f⌉ × ⌈h/f⌉`, is still at least [`SHRINK_MARGIN`] times
/// that size; 1 for images under [`SHRINK_MIN_PIXELS`].
pub fn shrink_factor(w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    largest_shrink(&[4, 3, 2], w, h, min_w, min_h)
}

/// The shrink rule, for JPEG's DCT scaling and for boxes alike: the first of `factors`
/// (largest first, none above [`MAX_FACTOR`]) whose output, `⌈w/f⌉ × ⌈h/f⌉`, is still at
/// least [`SHRINK_MARGIN`] times `min_w × min_h`; 1 when none is, or for images under
/// [`SHRINK_MIN_PIXELS`].
pub fn largest_shrink(factors: &[usize], w: usize, h: usize, min_w: usize, min_h: usize) -> usize {
    debug_assert!(factors.iter().all(|&f| f <= MAX_FACTOR));
    if w.saturating_mul(h) < SHRINK_MIN_PIXELS {
        return 1;
    }
    let (mw, mh) = (
        min_w.saturating_mul(SHRINK_MARGIN),
        min_h.saturating_mul(SHRINK_MARGIN),
    );
    factors
        .iter()
        .copied()
        .find(|&f| w.div_ceil(f) >= mw && h.div_ceil(f) >= mh)
        .unwrap_or(1)
}

/// A source shrunk by boxes of `factor × factor` pixels averaged in linear light: bands of
/// `⌈w/f⌉`-wide 16-bit linear codes, one row for every `f` rows of the wrapped source (the
/// last box of a row or column holds what is left). Reads the wrapped source a band of
/// whole boxes at a time, so memory is the shrunk image and one such band.
pub struct BoxShrink {
    inner: Box<dyn RowSource>,
    factor: usize,
    info: SourceInfo,
    linearize: bool,
    /// Linear light of every code of the wrapped source, in 1/256 of a 16-bit code; built
    /// from the first band, whose depth and encoding it follows.
    lut: Vec<u32>,
    /// The encoding of the bands handed on.
    encoding: Encoding,
    /// A band of the wrapped source.
    band: Image,
    /// Box sums of one shrunk row.
    acc: Vec<u32>,
    /// Rows of the wrapped source per band: a whole number of boxes.
    inner_rows: usize,
    /// Rows handed on, and rows of the wrapped source read.
    rows_read: usize,
    inner_read: usize,
}

impl BoxShrink {
    /// Wraps `inner` to shrink it by `factor` (2 to 4); `tone.linearize` says whether codes
    /// are averaged as light (the default) or as codes (`--no-linearize`, as the resize).
    pub fn new(inner: Box<dyn RowSource>, factor: usize, tone: &ToneOptions) -> BoxShrink {
        assert!(
            (2..=MAX_FACTOR).contains(&factor),
            "box factor {factor} out of range"
        );
        let i = inner.info().clone();
        let info = SourceInfo {
            width: i.width.div_ceil(factor),
            height: i.height.div_ceil(factor),
            color: i.color,
            bits: 16,
            dpi: i.dpi,
        };
        let boxes = (INNER_BAND_BYTES / (factor * i.row_bytes()).max(1)).max(1);
        let band = super::band::empty_band(&i);
        BoxShrink {
            inner,
            factor,
            info,
            linearize: tone.linearize,
            lut: Vec::new(),
            encoding: Encoding::Linear,
            band,
            acc: Vec::new(),
            inner_rows: boxes * factor,
            rows_read: 0,
            inner_read: 0,
        }
    }

    /// The table for the wrapped source's codes, as [`crate::resize::resize`] reads them:
    /// the tone table of `linearize` alone, scaled to 16-bit codes with 8 bits more.
    fn build_lut(&mut self) {
        let plain = ToneOptions {
            linearize: self.linearize,
            ..ToneOptions::default()
        };
        let table = ToneTable::new(self.band.bits(), self.band.encoding, &plain);
        self.lut = table
            .as_slice()
            .iter()
            .map(|&v| (v as f64 * 65535.0 * 256.0).round() as u32)
            .collect();
        // Light in linear codes; without linearising, codes on the wrapped source's scale.
        self.encoding = if self.linearize {
            Encoding::Linear
        } else {
            self.band.encoding
        };
    }
}

impl RowSource for BoxShrink {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn buffer_bytes(&self) -> usize {
        let i = self.inner.info();
        self.inner.buffer_bytes()
            + self.inner_rows.min(i.height) * (i.row_bytes() + self.inner.bytes_per_row())
            + self.info.width * 4
            + self.lut.capacity().max(1 << i.bits) * 4
    }

    fn bytes_per_row(&self) -> usize {
        0
    }

    fn decodes_whole_well(&self) -> bool {
        true
    }

    fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
        let rows = rows.min(self.info.height - self.rows_read);
        let (sw, f) = (self.info.width, self.factor);
        let (iw, ih) = (self.inner.info().width, self.inner.info().height);
        band.width = sw;
        band.height = rows;
        band.color = self.info.color;
        band.planes
            .resize(self.info.channels(), Samples::U16(Vec::new()));
        for p in band.planes.iter_mut() {
            if !matches!(p, Samples::U16(_)) {
                *p = Samples::U16(Vec::new());
            }
            let Samples::U16(v) = p else {
                unreachable!("set above")
            };
            v.resize(sw * rows, 0);
        }
        self.acc.resize(sw, 0);
        let mut done = 0;
        while done < rows {
            let n = self
                .inner_rows
                .min(ih - self.inner_read)
                .min((rows - done) * f);
            self.inner.read_rows(n, &mut self.band)?;
            if self.lut.is_empty() {
                self.build_lut();
            }
            let made = n.div_ceil(f);
            for (src, dst) in self.band.planes.iter().zip(band.planes.iter_mut()) {
                let Samples::U16(dst) = dst else {
                    unreachable!("16-bit planes")
                };
                let out = &mut dst[done * sw..(done + made) * sw];
                match src {
                    Samples::U8(codes) => {
                        box_plane(&codes[..iw * n], iw, f, &self.lut, &mut self.acc, out)
                    }
                    Samples::U16(codes) => {
                        box_plane(&codes[..iw * n], iw, f, &self.lut, &mut self.acc, out)
                    }
                }
            }
            self.inner_read += n;
            done += made;
        }
        band.encoding = self.encoding;
        self.rows_read += rows;
        Ok(())
    }
}

/// Box means of one plane: `codes` holds whole rows `w` wide, every `f` of them (the last
/// group may be shorter) made into one row of `out`, `⌈w/f⌉` wide, each sample the mean
/// of its box's `lut` values rounded to a 16-bit code.
pub fn box_plane<T: Copy>(
    codes: &[T],
    w: usize,
    f: usize,
    lut: &[u32],
    acc: &mut [u32],
    out: &mut [u16],
) where
    usize: From<T>,
{
    let sw = w.div_ceil(f);
    debug_assert_eq!(acc.len(), sw);
    debug_assert_eq!(out.len(), codes.len().div_ceil(w * f) * sw);
    for (group, o) in codes.chunks(w * f).zip(out.chunks_exact_mut(sw)) {
        acc.fill(0);
        for row in group.chunks_exact(w) {
            match f {
                2 => add_row::<2, T>(row, lut, acc),
                3 => add_row::<3, T>(row, lut, acc),
                4 => add_row::<4, T>(row, lut, acc),
                _ => unreachable!("factor checked in BoxShrink::new"),
            }
        }
        let rows = (group.len() / w) as u32;
        let full = f as u32 * rows;
        let (body, last) = o.split_at_mut(sw - 1);
        for (o, &a) in body.iter_mut().zip(acc.iter()) {
            *o = mean(a, full);
        }
        // The last box of the row holds the columns left over.
        let left = (w - (sw - 1) * f) as u32;
        last[0] = mean(acc[sw - 1], left * rows);
    }
}

/// The sum `a` of `n` values in 1/256 of a code, as the nearest code.
#[inline]
fn mean(a: u32, n: u32) -> u16 {
    // Exact in u64: a < 2³², n · 256 < 2¹⁴.
    ((a as u64 + n as u64 * 128) / (n as u64 * 256)) as u16
}

/// Adds one row's boxes of `F` samples to `acc` (the row's last box may be shorter).
#[inline]
fn add_row<const F: usize, T: Copy>(row: &[T], lut: &[u32], acc: &mut [u32])
where
    usize: From<T>,
{
    let chunks = row.chunks_exact(F);
    let rest = chunks.remainder();
    let (whole, last) = acc.split_at_mut(row.len() / F);
    for (a, px) in whole.iter_mut().zip(chunks) {
        let mut s = 0;
        for &c in px {
            s += lut[usize::from(c)];
        }
        *a += s;
    }
    if !rest.is_empty() {
        for &c in rest {
            last[0] += lut[usize::from(c)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source of given planes, handed on in bands of whatever size is asked.
    struct Planes {
        info: SourceInfo,
        img: Image,
        y: usize,
    }

    impl RowSource for Planes {
        fn info(&self) -> &SourceInfo {
            &self.info
        }
        fn bytes_per_row(&self) -> usize {
            0
        }
        fn read_rows(&mut self, rows: usize, band: &mut Image) -> Result<()> {
            let w = self.info.width;
            let rows = rows.min(self.info.height - self.y);
            band.width = w;
            band.height = rows;
            band.encoding = self.img.encoding;
            band.planes = self
                .img
                .planes
                .iter()
                .map(|p| match p {
                    Samples::U8(v) => Samples::U8(v[self.y * w..(self.y + rows) * w].to_vec()),
                    Samples::U16(v) => Samples::U16(v[self.y * w..(self.y + rows) * w].to_vec()),
                })
                .collect();
            self.y += rows;
            Ok(())
        }
    }

    fn source(img: &Image) -> Box<dyn RowSource> {
        Box::new(Planes {
            info: SourceInfo {
                width: img.width,
                height: img.height,
                color: img.color,
                bits: img.bits(),
                dpi: None,
            },
            img: img.clone(),
            y: 0,
        })
    }

    fn random_image(w: usize, h: usize, rgb: bool, bits: u32, seed: u64) -> Image {
        let mut s = seed;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let planes = (0..if rgb { 3 } else { 1 })
            .map(|_| {
                if bits == 16 {
                    Samples::U16((0..w * h).map(|_| next() as u16).collect())
                } else {
                    Samples::U8((0..w * h).map(|_| next() as u8).collect())
                }
            })
            .collect();
        Image {
            width: w,
            height: h,
            color: if rgb {
                crate::raster::ColorKind::Rgb
            } else {
                crate::raster::ColorKind::Gray
            },
            planes,
            encoding: Encoding::Srgb,
            dpi: None,
        }
    }

    /// The mean of the light over each box, straight from the definition, in `f64`.
    fn reference(img: &Image, f: usize, linearize: bool) -> Vec<Vec<f64>> {
        let (w, h) = (img.width, img.height);
        let (sw, sh) = (w.div_ceil(f), h.div_ceil(f));
        let max = ((1u32 << img.bits()) - 1) as f64;
        let light = |c: usize| {
            let v = c as f64 / max;
            if linearize {
                crate::tone::srgb_to_linear(v)
            } else {
                v
            }
        };
        img.planes
            .iter()
            .map(|p| {
                let code = |x: usize, y: usize| match p {
                    Samples::U8(v) => v[y * w + x] as usize,
                    Samples::U16(v) => v[y * w + x] as usize,
                };
                let mut out = vec![0.0; sw * sh];
                for by in 0..sh {
                    for bx in 0..sw {
                        let (mut sum, mut n) = (0.0, 0);
                        for y in by * f..((by + 1) * f).min(h) {
                            for x in bx * f..((bx + 1) * f).min(w) {
                                sum += light(code(x, y));
                                n += 1;
                            }
                        }
                        out[by * sw + bx] = sum / n as f64;
                    }
                }
                out
            })
            .collect()
    }

    fn shrink_all(img: &Image, f: usize, tone: &ToneOptions, band_rows: &[usize]) -> Image {
        let mut s = BoxShrink::new(source(img), f, tone);
        let h = s.info().height;
        let mut out = super::super::band::empty_band(s.info());
        let mut planes: Vec<Vec<u16>> = vec![Vec::new(); img.planes.len()];
        let mut y = 0;
        let mut k = 0;
        while y < h {
            let n = band_rows[k % band_rows.len()].min(h - y);
            k += 1;
            s.read_rows(n, &mut out).unwrap();
            assert_eq!((out.width, out.height), (img.width.div_ceil(f), n));
            for (p, o) in planes.iter_mut().zip(&out.planes) {
                let Samples::U16(v) = o else { panic!("16-bit") };
                p.extend_from_slice(v);
            }
            y += n;
        }
        Image {
            width: out.width,
            height: h,
            color: img.color,
            planes: planes.into_iter().map(Samples::U16).collect(),
            encoding: out.encoding,
            dpi: None,
        }
    }

    #[test]
    fn box_mean_is_the_mean_of_the_light() {
        // Sizes that are and are not multiples of every factor; grey and RGB; 8 and 16 bits;
        // with and without linearising.
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for (w, h) in [(24, 12), (31, 17), (5, 3), (1, 1), (7, 9)] {
            for rgb in [false, true] {
                for bits in [8, 16] {
                    seed = seed.wrapping_add(0x1234_5678_9abc_def1);
                    let img = random_image(w, h, rgb, bits, seed);
                    for f in 2..=4 {
                        for linearize in [true, false] {
                            let tone = ToneOptions {
                                linearize,
                                ..ToneOptions::default()
                            };
                            let got = shrink_all(&img, f, &tone, &[1]);
                            let want = reference(&img, f, linearize);
                            let enc = if linearize {
                                Encoding::Linear
                            } else {
                                Encoding::Srgb
                            };
                            assert_eq!(got.encoding, enc);
                            for (g, r) in got.planes.iter().zip(&want) {
                                let Samples::U16(g) = g else { panic!() };
                                assert_eq!(g.len(), r.len());
                                for (i, (&g, &r)) in g.iter().zip(r).enumerate() {
                                    // One rounding of the mean, and the tables' f32.
                                    let err = (g as f64 - r * 65535.0).abs();
                                    assert!(
                                        err <= 0.51,
                                        "{w}x{h} rgb {rgb} {bits}-bit f {f} lin {linearize} at {i}: {g} vs {}",
                                        r * 65535.0
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_resize_reads_the_codes_back_as_the_same_light() {
        // The resize's table for 16-bit linear codes gives every code back exactly.
        let t = ToneTable::new(16, Encoding::Linear, &ToneOptions::default());
        for (c, &v) in t.as_slice().iter().enumerate() {
            assert_eq!((v * 65535.0).round() as usize, c);
        }
    }

    #[test]
    fn bands_of_any_height_give_the_same_rows() {
        let img = random_image(37, 29, true, 8, 7);
        let tone = ToneOptions::default();
        for f in 2..=4 {
            let one = shrink_all(&img, f, &tone, &[1]);
            for bands in [&[2usize][..], &[3, 1, 5], &[100]] {
                let other = shrink_all(&img, f, &tone, bands);
                assert_eq!(one.planes, other.planes, "f {f} bands {bands:?}");
            }
        }
    }

    #[test]
    fn flat_grey_keeps_its_tone() {
        for code in [0u8, 1, 50, 128, 200, 254, 255] {
            let img = Image::gray8(13, 11, vec![code; 13 * 11]);
            let t = ToneTable::new(8, Encoding::Srgb, &ToneOptions::default());
            let want = (t.as_slice()[code as usize] as f64 * 65535.0).round() as u16;
            for f in 2..=4 {
                let got = shrink_all(&img, f, &ToneOptions::default(), &[2]);
                let Samples::U16(v) = &got.planes[0] else {
                    panic!()
                };
                // The code the resize itself gives this grey.
                assert!(v.iter().all(|&c| c == want), "code {code} f {f}");
            }
        }
    }

    #[test]
    fn factor_follows_the_jpeg_rule() {
        assert_eq!(shrink_factor(6000, 4000, 384, 256), 4);
        assert_eq!(shrink_factor(6000, 4000, 750, 500), 4);
        assert_eq!(shrink_factor(6000, 4000, 751, 10), 3);
        assert_eq!(shrink_factor(6000, 4000, 1000, 10), 3);
        assert_eq!(shrink_factor(6000, 4000, 1001, 10), 2);
        assert_eq!(shrink_factor(6000, 4000, 1501, 1000), 1);
        assert_eq!(shrink_factor(1999, 2000, 10, 10), 1);
    }
}
