//! The sample-scene renderer: lit spheres, polyhedra and planes, shaded flat, Gouraud or
//! Phong with a z-buffer, or ray traced with shadows, mirrors and glass — the figure series
//! of the lecture's Unit 5 — producing continuous-tone pictures to halftone.
//!
//! It knows nothing of halftoning: it computes linear-light RGB and encodes it as an
//! sRGB PNG of 8 or 16 bits.
//!
//! ```
//! use halftone::render::{render, RenderOptions, Scene};
//! let scene = Scene::builtin("kd-series").unwrap();
//! let frame = render(&scene, &RenderOptions { size: Some((50, 12)), ..Default::default() });
//! assert_eq!(frame.pixels.len(), 50 * 12 * 3);
//! ```
// Not in the Python or WebAssembly builds: the standard library's transcendental functions
// are allowed here (clippy.toml; the rest of the library calls `crate::fmath`).
#![allow(clippy::disallowed_methods)]

pub mod geometry;
pub mod illumination;
pub mod mesh;
pub mod raytrace;
pub mod scene;
pub mod shade;
pub mod zbuffer;

use std::path::Path;

use rayon::prelude::*;

pub use illumination::{Highlight, Light, LightKind, Material, Rgb, WarnLight};
pub use scene::{parse_aa, Antialias, Camera, Renderer, Scene, Shading, BUILTIN};

use crate::error::{Error, Result};
use raytrace::Tracer;
use scene::View;
use zbuffer::Grid;

/// A rendered picture: linear-light RGB, row-major, three f32 per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear RGB, interleaved, `3 · width · height` values (may exceed 1 before output).
    pub pixels: Vec<f32>,
}

/// Choices that override a scene's defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderOptions {
    /// Picture size (width, height); `None` = the scene's.
    pub size: Option<(usize, usize)>,
    /// Antialiasing; `None` = the scene's.
    pub aa: Option<Antialias>,
}

/// Sample bits per channel of an encoded picture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Depth {
    /// 8-bit sRGB.
    #[default]
    Eight,
    /// 16-bit sRGB.
    Sixteen,
}

/// Renders `scene`.
pub fn render(scene: &Scene, opts: &RenderOptions) -> Frame {
    let (width, height) = opts.size.unwrap_or(scene.size);
    let aa = opts.aa.unwrap_or(scene.aa);
    let view = View::new(&scene.camera, width, height);
    let pixels = match scene.renderer {
        scene::Renderer::RayTrace => {
            let tracer = Tracer::new(scene, width, height);
            sample_picture(width, height, aa, &|x, y| tracer.sample(x, y))
        }
        scene::Renderer::ZBuffer => zbuffer_picture(scene, &view, width, height, aa),
    };
    Frame {
        width,
        height,
        pixels,
    }
}

/// Averages a z-buffered sample grid into pixels. Super samples the pixel corners (each
/// shared by four pixels); adaptive and jitter take a regular 4×4 grid of subpixel centres
/// (a scan converter samples on a grid; jitter and subdivision are for rays).
fn zbuffer_picture(scene: &Scene, view: &View, w: usize, h: usize, aa: Antialias) -> Vec<f32> {
    let (grid, k, stride) = match aa {
        Antialias::None => (
            Grid {
                width: w,
                height: h,
                step: 1.0,
                offset: 0.5,
            },
            1,
            1,
        ),
        Antialias::Super => (
            Grid {
                width: w + 1,
                height: h + 1,
                step: 1.0,
                offset: 0.0,
            },
            2,
            1,
        ),
        Antialias::Adaptive | Antialias::Jitter => (
            Grid {
                width: 4 * w,
                height: 4 * h,
                step: 0.25,
                offset: 0.125,
            },
            4,
            4,
        ),
    };
    let samples = zbuffer::render_grid(scene, view, grid);
    let mut out = vec![0f32; 3 * w * h];
    out.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            let mut sum = Rgb::ZERO;
            for dy in 0..k {
                for dx in 0..k {
                    sum += samples[(y * stride + dy) * grid.width + x * stride + dx];
                }
            }
            put(row, x, sum / (k * k) as f64);
        }
    });
    out
}

fn put(row: &mut [f32], x: usize, c: Rgb) {
    row[3 * x] = c.x as f32;
    row[3 * x + 1] = c.y as f32;
    row[3 * x + 2] = c.z as f32;
}

/// Subdivision depth limit of adaptive sampling: cells down to 1/16 of a pixel side.
const ADAPTIVE_DEPTH: u32 = 4;
/// At most this many rays a pixel for adaptive sampling (lecture: "an upper bound, say, 256").
const ADAPTIVE_RAYS: u32 = 256;
/// Corner intensities "approximately equal": within this on a square-root (roughly
/// perceptual) scale in every channel.
const ADAPTIVE_CONTRAST: f64 = 0.02;

/// Samples a picture through `f(x, y)` (picture coordinates, pixel (i, j) covering
/// [i, i+1] × [j, j+1]) with the given antialiasing; rows run in parallel and every pixel
/// depends on its coordinates alone, so the result does not depend on the thread count.
pub fn sample_picture(
    w: usize,
    h: usize,
    aa: Antialias,
    f: &(dyn Fn(f64, f64) -> Rgb + Sync),
) -> Vec<f32> {
    let mut out = vec![0f32; 3 * w * h];
    match aa {
        Antialias::None => out.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                put(row, x, f(x as f64 + 0.5, y as f64 + 0.5));
            }
        }),
        Antialias::Jitter => out.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                put(row, x, jittered(x, y, f));
            }
        }),
        Antialias::Super | Antialias::Adaptive => {
            // Rays through the pixel corners, each shared by four pixels.
            let mut corners = vec![Rgb::ZERO; (w + 1) * (h + 1)];
            corners
                .par_chunks_mut(w + 1)
                .enumerate()
                .for_each(|(y, row)| {
                    for (x, c) in row.iter_mut().enumerate() {
                        *c = f(x as f64, y as f64);
                    }
                });
            let adaptive = aa == Antialias::Adaptive;
            out.par_chunks_mut(3 * w).enumerate().for_each(|(y, row)| {
                for x in 0..w {
                    let c = [
                        corners[y * (w + 1) + x],
                        corners[y * (w + 1) + x + 1],
                        corners[(y + 1) * (w + 1) + x],
                        corners[(y + 1) * (w + 1) + x + 1],
                    ];
                    let v = if adaptive {
                        let mut budget = ADAPTIVE_RAYS - 4;
                        subdivide(x as f64, y as f64, 1.0, c, 0, &mut budget, f)
                    } else {
                        (c[0] + c[1] + c[2] + c[3]) * 0.25
                    };
                    put(row, x, v);
                }
            });
        }
    }
    out
}

/// Adaptive subdivision (lecture: "If the intensities for the four rays are not
/// approximately equal ... we divide the pixel area into subpixels and repeat"): the cell
/// at (x, y) of side `size` with corner intensities `c` (top-left, top-right, bottom-left,
/// bottom-right). Each subdivision costs five new rays out of `budget`.
fn subdivide(
    x: f64,
    y: f64,
    size: f64,
    c: [Rgb; 4],
    depth: u32,
    budget: &mut u32,
    f: &(dyn Fn(f64, f64) -> Rgb + Sync),
) -> Rgb {
    let mean = (c[0] + c[1] + c[2] + c[3]) * 0.25;
    if depth >= ADAPTIVE_DEPTH || *budget < 5 || !differ(&c) {
        return mean;
    }
    *budget -= 5;
    let hs = size / 2.0;
    let top = f(x + hs, y);
    let left = f(x, y + hs);
    let mid = f(x + hs, y + hs);
    let right = f(x + size, y + hs);
    let bottom = f(x + hs, y + size);
    let d = depth + 1;
    let a = subdivide(x, y, hs, [c[0], top, left, mid], d, budget, f);
    let b = subdivide(x + hs, y, hs, [top, c[1], mid, right], d, budget, f);
    let e = subdivide(x, y + hs, hs, [left, mid, c[2], bottom], d, budget, f);
    let g = subdivide(x + hs, y + hs, hs, [mid, right, bottom, c[3]], d, budget, f);
    (a + b + e + g) * 0.25
}

fn differ(c: &[Rgb; 4]) -> bool {
    let root = |v: f64| v.max(0.0).sqrt();
    (0..3).any(|ch| {
        let vals = c.map(|p| root(p.get(ch)));
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        hi - lo > ADAPTIVE_CONTRAST
    })
}

/// Distributed sampling: 16 rays, one in each cell of a 4×4 subpixel grid, at the cell
/// centre moved by δx, δy in (−0.5, 0.5) cell (lecture, Unit 5, "Distributed Ray Tracing").
/// The jitter comes from a hash of (x, y, cell), so it is the same on every run.
fn jittered(x: usize, y: usize, f: &(dyn Fn(f64, f64) -> Rgb + Sync)) -> Rgb {
    let mut sum = Rgb::ZERO;
    for s in 0..16u64 {
        let (dx, dy) = jitter_offset(x as u64, y as u64, s);
        let cx = (s % 4) as f64 + 0.5 + dx;
        let cy = (s / 4) as f64 + 0.5 + dy;
        sum += f(x as f64 + cx / 4.0, y as f64 + cy / 4.0);
    }
    sum / 16.0
}

/// The jitter (δx, δy) of subpixel cell `s` of pixel (x, y): both in the open interval
/// (−0.5, 0.5), from SplitMix64 of the three numbers.
pub fn jitter_offset(x: u64, y: u64, s: u64) -> (f64, f64) {
    let h = splitmix(splitmix(splitmix(x) ^ y) ^ s);
    let unit = |bits: u64| ((bits >> 11) as f64 + 0.5) / (1u64 << 53) as f64 - 0.5;
    (unit(h), unit(splitmix(h)))
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Frame {
    /// The pixel at (x, y) as linear RGB.
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y * self.width + x);
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }

    /// The picture sRGB-encoded at 8 bits a channel, interleaved RGB; values outside 0..1
    /// are clipped.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .map(|&v| (srgb(v) * 255.0).round() as u8)
            .collect()
    }

    /// The picture sRGB-encoded at 16 bits a channel, interleaved RGB.
    pub fn to_srgb16(&self) -> Vec<u16> {
        self.pixels
            .iter()
            .map(|&v| (srgb(v) * 65535.0).round() as u16)
            .collect()
    }

    /// Encodes the picture as an sRGB PNG.
    pub fn encode_png(&self, depth: Depth) -> Result<Vec<u8>> {
        use image::{ImageBuffer, ImageFormat, Rgb as Px};
        let mut buf = std::io::Cursor::new(Vec::new());
        let (w, h) = (self.width as u32, self.height as u32);
        let res = match depth {
            Depth::Eight => ImageBuffer::<Px<u8>, _>::from_raw(w, h, self.to_srgb8())
                .expect("buffer size matches")
                .write_to(&mut buf, ImageFormat::Png),
            Depth::Sixteen => ImageBuffer::<Px<u16>, _>::from_raw(w, h, self.to_srgb16())
                .expect("buffer size matches")
                .write_to(&mut buf, ImageFormat::Png),
        };
        res.map_err(|e| Error::Encode {
            path: "png".into(),
            msg: e.to_string(),
        })?;
        Ok(buf.into_inner())
    }

    /// Writes the picture to `path` as an sRGB PNG, atomically.
    pub fn write_png(&self, path: &Path, depth: Depth) -> Result<()> {
        let bytes = self.encode_png(depth).map_err(|e| match e {
            Error::Encode { msg, .. } => Error::Encode {
                path: path.into(),
                msg,
            },
            other => other,
        })?;
        crate::io::write_atomic(path, |w| w.write_all(&bytes))
    }
}

/// Linear light to the sRGB transfer curve, clipped to 0..1.
fn srgb(v: f32) -> f64 {
    crate::tone::linear_to_srgb((v as f64).clamp(0.0, 1.0))
}
