//! A method to a palette made from the image (`palette = "auto:N"`): the planes' linear
//! light is sampled, [`crate::quantize::auto_palette`] makes the palette, and error
//! diffusion or ordered (pattern) dithering runs with it. The halftone carries the palette
//! it computed, so a PNG shows it.
//!
//! The palette depends on the whole image, so this method does not stream: `rows()` is
//! `None` and the pipeline gives it the whole image.

use super::diffusion::Diffuse;
use super::ordered_palette::OrderedPalette;
use super::Method;
use crate::color::Palette;
use crate::error::{Error, Result};
use crate::mask::Mask;
use crate::quantize::{auto_palette, MAX_SAMPLES};
use crate::raster::{Halftone, Planes};

/// The pixels read from the planes for the palette: a grid of at most about this many
/// (the palette then samples [`MAX_SAMPLES`] of them), so a 24-megapixel page is not
/// copied whole into linear RGB.
const GRID_PIXELS: usize = 4 * MAX_SAMPLES;

/// What runs once the palette is made.
#[derive(Clone, Debug)]
enum Then {
    /// Error diffusion (its palette is set per image).
    Diffuse(Diffuse),
    /// Ordered dithering to the palette with this mask.
    Ordered(Mask),
}

/// A method to an automatic palette of at most `n` colours.
#[derive(Clone, Debug)]
pub struct AutoPalette {
    n: usize,
    then: Then,
}

/// Checks N of `auto:N`.
fn check(n: usize) -> Result<()> {
    if !(2..=256).contains(&n) {
        return Err(Error::Option {
            field: "palette",
            value: format!("auto:{n}"),
            msg: "an automatic palette has 2 to 256 colours".into(),
        });
    }
    Ok(())
}

impl AutoPalette {
    /// Error diffusion `d` (its own palette, if any, is replaced) to `n` colours of the image.
    pub fn diffuse(d: Diffuse, n: usize) -> Result<AutoPalette> {
        check(n)?;
        Ok(AutoPalette {
            n,
            then: Then::Diffuse(d),
        })
    }

    /// Ordered dithering with `mask` to `n` colours of the image.
    pub fn ordered(mask: Mask, n: usize) -> Result<AutoPalette> {
        check(n)?;
        if mask.is_empty() || mask.len() != mask.width * mask.height {
            return Err(Error::Invalid(format!("mask {}: no cells", mask.name)));
        }
        Ok(AutoPalette {
            n,
            then: Then::Ordered(mask),
        })
    }

    /// The palette this method makes for `input` (one grey or three RGB planes).
    pub fn palette_of(&self, input: &Planes<'_>) -> Result<Palette> {
        let (w, h) = (input.width, input.height);
        let planes = input.rgb("a palette")?;
        // A grid of every `step`-th pixel in both directions, centred in its cells.
        let mut step = 1;
        while (w.div_ceil(step)) * (h.div_ceil(step)) > GRID_PIXELS {
            step += 1;
        }
        let mut pixels = Vec::with_capacity(w.div_ceil(step) * h.div_ceil(step));
        for y in (step / 2..h).step_by(step) {
            for x in (step / 2..w).step_by(step) {
                pixels.push([0, 1, 2].map(|c| planes[c].value(x, y)));
            }
        }
        let colours = auto_palette(&pixels, self.n)?;
        Palette::new(&format!("auto:{}", self.n), colours)
    }
}

impl Method for AutoPalette {
    fn name(&self) -> String {
        match &self.then {
            Then::Diffuse(d) => format!("{} to palette auto:{}", d.name(), self.n),
            Then::Ordered(m) => format!("ordered({}, palette auto:{})", m.name, self.n),
        }
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        let palette = self.palette_of(input)?;
        match &self.then {
            Then::Diffuse(d) => d.clone().with_palette(palette).halftone(input),
            Then::Ordered(mask) => OrderedPalette::new(mask.clone(), palette)?.halftone(input),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::diffusion::DiffuseOptions;
    use crate::raster::Image;
    use crate::tone::ToneOptions;

    #[test]
    fn the_halftone_carries_the_palette_it_made() {
        // Four flat quarters: the palette is their four colours.
        let (w, h) = (40, 30);
        let quarters = [[250, 20, 20], [20, 20, 250], [20, 200, 20], [240, 240, 240]];
        let mut px = Vec::new();
        for y in 0..h {
            for x in 0..w {
                px.extend(quarters[(y >= h / 2) as usize * 2 + (x >= w / 2) as usize]);
            }
        }
        let img = Image::rgb8(w, h, &px);
        let tone = img.tone_table(&ToneOptions::default());
        let planes = img.planes(&tone);
        let d = Diffuse::new("floyd-steinberg", DiffuseOptions::default()).unwrap();
        for m in [
            AutoPalette::diffuse(d.clone(), 8).unwrap(),
            AutoPalette::ordered(Mask::builtin("bayer-8").unwrap(), 8).unwrap(),
        ] {
            let ht = m.halftone(&planes).unwrap();
            let pal = ht.palette.clone().unwrap();
            assert_eq!(pal.len(), 4, "{}: {pal:?}", m.name());
            assert_eq!(ht.levels, 4);
            // Each flat quarter is its own colour exactly.
            for y in 0..h {
                for x in 0..w {
                    let want = quarters[(y >= h / 2) as usize * 2 + (x >= w / 2) as usize];
                    let got = pal[ht.get(0, x, y) as usize];
                    assert!(
                        (0..3).all(|c| (got[c] as i32 - want[c] as i32).abs() <= 1),
                        "{} at {x},{y}: {got:?} for {want:?}",
                        m.name()
                    );
                }
            }
        }
        assert!(AutoPalette::diffuse(d, 1).is_err());
    }
}
