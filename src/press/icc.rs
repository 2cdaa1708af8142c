//! Separation through a vendor's ICC output profile (`--icc FILE`) instead of the press
//! model, with Little CMS (the `lcms2` crate, built from its bundled C source).
//!
//! The profile's B2A table (sRGB → PCS → CMYK at the chosen rendering intent) is sampled at
//! the nodes of the same 17³ lookup table the press model fills ([`Separation`]), so the
//! plates are made exactly as with `--press`: one trilinear lookup a colour. Black
//! generation and the ink limit are built into the profile's table; the profile's A2B
//! table (CMYK → PCS) prints the preview.

use std::path::{Path, PathBuf};

use lcms2::{ColorSpaceSignature, Intent, PixelFormat, Profile, ProfileClassSignature, Transform};

use super::separation::{Separation, SeparationOptions, GRID};
use super::{lab, D50};
use crate::error::{Error, Result};

/// Largest profile read (vendor output profiles are a few MB; their CLUTs 33⁴ at most).
const MAX_PROFILE_BYTES: u64 = 64 << 20;

pub use super::RenderingIntent;

/// Little CMS's name for an intent.
fn lcms(intent: RenderingIntent) -> Intent {
    match intent {
        RenderingIntent::Perceptual => Intent::Perceptual,
        RenderingIntent::Relative => Intent::RelativeColorimetric,
        RenderingIntent::Saturation => Intent::Saturation,
        RenderingIntent::Absolute => Intent::AbsoluteColorimetric,
    }
}

/// A CMYK output profile, checked and ready to build transforms from.
#[derive(Clone, Debug)]
pub struct IccProfile {
    path: PathBuf,
    bytes: Vec<u8>,
    description: String,
}

fn bad(path: &Path, msg: impl Into<String>) -> Error {
    Error::Decode {
        path: path.to_path_buf(),
        msg: msg.into(),
    }
}

/// The four letters of an ICC signature, e.g. `prtr`, `CMYK`.
fn sig4(v: u32) -> String {
    v.to_be_bytes()
        .iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect::<String>()
        .trim_end()
        .to_string()
}

impl IccProfile {
    /// Reads and checks an ICC profile: it must be an output (`prtr`) profile for CMYK data.
    /// Errors are one line naming the file.
    pub fn load(path: &Path) -> Result<IccProfile> {
        use std::io::Read;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut bytes = Vec::new();
        file.take(MAX_PROFILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| Error::io(path, e))?;
        if bytes.len() as u64 > MAX_PROFILE_BYTES {
            return Err(bad(path, "larger than 64 MiB: not an ICC profile"));
        }
        IccProfile::from_bytes(path, bytes)
    }

    /// Checks profile bytes; `path` names them in errors.
    pub fn from_bytes(path: &Path, bytes: Vec<u8>) -> Result<IccProfile> {
        if bytes.len() < 132 || &bytes[36..40] != b"acsp" {
            return Err(bad(path, "not an ICC profile (no 'acsp' signature)"));
        }
        let profile = Profile::new_icc(&bytes)
            .map_err(|e| bad(path, format!("not a readable ICC profile ({e})")))?;
        let class = profile.device_class();
        let space = profile.color_space();
        if space != ColorSpaceSignature::CmykData || class != ProfileClassSignature::OutputClass {
            return Err(bad(
                path,
                format!(
                    "not a CMYK output profile (it is a '{}' profile for '{}' data; `icc` needs \
                     class 'prtr', colour space 'CMYK')",
                    sig4(class as u32),
                    sig4(space as u32)
                ),
            ));
        }
        let description = profile
            .info(lcms2::InfoType::Description, lcms2::Locale::none())
            .unwrap_or_default();
        Ok(IccProfile {
            path: path.to_path_buf(),
            bytes,
            description,
        })
    }

    /// The profile's description tag (empty when it has none).
    pub fn description(&self) -> &str {
        &self.description
    }

    fn open(&self) -> Result<Profile> {
        Profile::new_icc(&self.bytes).map_err(|e| bad(&self.path, e.to_string()))
    }

    /// sRGB → CMYK through the profile at `intent`, sampled into the separation's 17³ table
    /// (nodes at exact sRGB values `k/16`, as the table interpolates them).
    pub fn separation(&self, intent: RenderingIntent) -> Result<Separation> {
        let out = self.open()?;
        let srgb = Profile::new_srgb();
        let t: Transform<[f64; 3], [f64; 4]> = Transform::new(
            &srgb,
            PixelFormat::RGB_DBL,
            &out,
            PixelFormat::CMYK_DBL,
            lcms(intent),
        )
        .map_err(|e| {
            bad(
                &self.path,
                format!("no sRGB to CMYK transform at {intent:?} intent ({e})"),
            )
        })?;
        let node = |k: usize| k as f64 / (GRID - 1) as f64;
        let rgb: Vec<[f64; 3]> = (0..GRID * GRID * GRID)
            .map(|i| {
                [
                    node(i % GRID),
                    node((i / GRID) % GRID),
                    node(i / (GRID * GRID)),
                ]
            })
            .collect();
        let mut cmyk = vec![[0.0f64; 4]; rgb.len()];
        t.transform_pixels(&rgb, &mut cmyk);
        // Little CMS gives CMYK in percent.
        let lut = cmyk
            .iter()
            .map(|c| c.map(|v| (v / 100.0).clamp(0.0, 1.0) as f32))
            .collect();
        Ok(Separation::from_table(lut, SeparationOptions::default()))
    }

    /// CMYK coverages (0..1) printed through the profile (A2B, relative colorimetric):
    /// CIELAB D50, paper as white.
    pub fn lab(&self, cmyk: &[[f64; 4]]) -> Result<Vec<[f64; 3]>> {
        let xyz = self.to_pcs_xyz(cmyk)?;
        Ok(xyz.iter().map(|&x| lab(x, D50)).collect())
    }

    /// Media-relative XYZ (D50, Y = 100 for paper) of CMYK coverages (0..1).
    fn to_pcs_xyz(&self, cmyk: &[[f64; 4]]) -> Result<Vec<[f64; 3]>> {
        let prof = self.open()?;
        let xyz = Profile::new_xyz();
        let t: Transform<[f64; 4], [f64; 3]> = Transform::new(
            &prof,
            PixelFormat::CMYK_DBL,
            &xyz,
            PixelFormat::XYZ_DBL,
            Intent::RelativeColorimetric,
        )
        .map_err(|e| bad(&self.path, format!("no CMYK to PCS transform ({e})")))?;
        let src: Vec<[f64; 4]> = cmyk.iter().map(|c| c.map(|v| v * 100.0)).collect();
        let mut out = vec![[0.0f64; 3]; src.len()];
        t.transform_pixels(&src, &mut out);
        // XYZ_DBL is 1.0 for the white; the crate's colorimetry is on Y = 100.
        Ok(out.iter().map(|x| x.map(|v| v * 100.0)).collect())
    }

    /// 8-bit sRGB a screen shows for CMYK coverages (0..1): the print, paper as white.
    pub fn preview_srgb8(&self, cmyk: &[[f64; 4]]) -> Result<Vec<[u8; 3]>> {
        Ok(self
            .to_pcs_xyz(cmyk)?
            .iter()
            .map(|&x| super::xyz_to_srgb_linear(x).map(crate::tone::linear_to_srgb8))
            .collect())
    }
}
