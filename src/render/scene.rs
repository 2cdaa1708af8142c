//! Scenes: camera, lights, materials and objects, read from a small TOML format (see
//! `scenes/*.toml`, which are also the built-in scenes).

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::geometry::{Ray, Vec3};
use super::illumination::{Highlight, Light, LightKind, Material, Rgb, WarnLight};
use super::mesh::{Mesh, Solid};
use crate::error::{Error, Result};

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Where the eye is.
    pub eye: Vec3,
    /// The point at the centre of the picture.
    pub look_at: Vec3,
    /// Which way is up (need not be perpendicular to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f64,
}

/// The camera set up for a picture of a given size: maps picture coordinates (x right,
/// y down, pixel (i, j) covering [i, i+1] × [j, j+1]) to rays and back.
#[derive(Clone, Copy, Debug)]
pub struct View {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    half_h: f64,
    half_w: f64,
    width: f64,
    height: f64,
}

impl View {
    /// The view of `camera` for a `width` × `height` picture.
    pub fn new(camera: &Camera, width: usize, height: usize) -> View {
        let forward = (camera.look_at - camera.eye).normalized();
        let right = forward.cross(camera.up).normalized();
        let up = right.cross(forward);
        let half_h = (camera.fov.to_radians() / 2.0).tan();
        View {
            eye: camera.eye,
            forward,
            right,
            up,
            half_h,
            half_w: half_h * width as f64 / height as f64,
            width: width as f64,
            height: height as f64,
        }
    }

    /// The eye ray through picture point (`sx`, `sy`).
    #[inline]
    pub fn ray(&self, sx: f64, sy: f64) -> Ray {
        let x = (2.0 * sx / self.width - 1.0) * self.half_w;
        let y = (1.0 - 2.0 * sy / self.height) * self.half_h;
        Ray {
            origin: self.eye,
            dir: (self.forward + self.right * x + self.up * y).normalized(),
        }
    }

    /// The picture point of scene point `p` and its depth along the view direction
    /// (`None` behind the eye).
    pub fn project(&self, p: Vec3) -> Option<(f64, f64, f64)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= 1e-6 {
            return None;
        }
        let x = d.dot(self.right) / z / self.half_w;
        let y = d.dot(self.up) / z / self.half_h;
        Some((
            (x + 1.0) * self.width / 2.0,
            (1.0 - y) * self.height / 2.0,
            z,
        ))
    }

    /// The eye position.
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// Where a direction lies between the bottom (0) and top (1) edges of the picture, by
    /// the tangent of its elevation, so that for eye rays it depends on the picture row
    /// alone; clamped beyond the edges (and for directions behind the camera).
    #[inline]
    pub fn elevation(&self, dir: Vec3) -> f64 {
        let (f, u) = (dir.dot(self.forward), dir.dot(self.up));
        let tan = if f > 0.0 {
            u / f / self.half_h
        } else if u > 0.0 {
            1.0
        } else {
            -1.0
        };
        0.5 * (1.0 + tan.clamp(-1.0, 1.0))
    }
}

/// How a polygon mesh is shaded (lecture, Unit 5, "Polygon-Rendering Methods").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// Constant intensity: the model applied once per polygon.
    Flat,
    /// The model applied at the vertices (averaged normals), intensities interpolated.
    Gouraud,
    /// Normals interpolated, the model applied at every pixel.
    #[default]
    Phong,
}

/// How a scene is turned into pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Renderer {
    /// A ray per sample, nearest hit, shadow rays, reflection and refraction.
    #[default]
    RayTrace,
    /// Polygons projected and scan-converted into a z-buffer; no shadows or mirrors.
    ZBuffer,
}

/// Antialiasing (lecture, Unit 5, "Antialiased Ray tracing").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Antialias {
    /// One ray through each pixel centre.
    None,
    /// Rays through the pixel corners, averaged (shared with the neighbours).
    Super,
    /// Corners first; where they differ, subdivide, up to 256 rays a pixel.
    #[default]
    Adaptive,
    /// 16 rays jittered on a 4×4 subpixel grid.
    Jitter,
}

/// A sphere.
#[derive(Clone, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f64,
    /// Index into [`Scene::materials`].
    pub material: usize,
}

/// An infinite plane, optionally a checkerboard of its material and a second colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// A point on the plane.
    pub point: Vec3,
    /// Unit normal (the lit side).
    pub normal: Vec3,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Checkerboard: the other squares' colour and the square size.
    pub checker: Option<(Rgb, f64)>,
}

/// A polygon mesh placed in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshObject {
    /// The mesh in scene coordinates.
    pub mesh: Mesh,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// How it is shaded.
    pub shading: Shading,
}

/// Everything needed to render a picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Default picture size (width, height).
    pub size: (usize, usize),
    /// Ray tracing or z-buffer.
    pub renderer: Renderer,
    /// Default antialiasing.
    pub aa: Antialias,
    /// The camera.
    pub camera: Camera,
    /// Ambient light Ia.
    pub ambient: Rgb,
    /// Background at the top and bottom of the picture (a vertical gradient).
    pub background: [Rgb; 2],
    /// Light sources.
    pub lights: Vec<Light>,
    /// Materials, referred to by index.
    pub materials: Vec<Material>,
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// Planes (ray tracing only).
    pub planes: Vec<Plane>,
    /// Polygon meshes.
    pub meshes: Vec<MeshObject>,
    /// Ray tracing: the deepest ray tree (0 = eye rays only).
    pub max_depth: u32,
    /// Ray tracing: attenuation of a secondary ray's contribution with the distance it
    /// travelled, f(d) = 1 / (a0 + a1·d + a2·d²) capped at 1.
    pub tree_attenuation: [f64; 3],
    /// Ray tracing: cast shadow rays.
    pub shadows: bool,
}

impl Scene {
    /// The background seen along a ray: a vertical gradient from `background[1]` at the
    /// picture's bottom edge to `background[0]` at its top.
    #[inline]
    pub fn background(&self, view: &View, dir: Vec3) -> Rgb {
        let t = view.elevation(dir);
        self.background[1] * (1.0 - t) + self.background[0] * t
    }

    /// Parses a scene from TOML text; `path` names it in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Scene> {
        let raw: RawScene = toml::from_str(text).map_err(|e| {
            let line = e.span().map_or(0, |s| line_of(text, s.start));
            Error::parse(path, line, e.message().trim().to_string())
        })?;
        raw.build(text, path)
    }

    /// Reads a scene file.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = crate::io::read_text(path, 16 << 20)?;
        Scene::from_toml(&text, path)
    }

    /// A built-in scene by name (see [`BUILTIN`]).
    pub fn builtin(name: &str) -> Option<Scene> {
        let (_, _, text) = BUILTIN.iter().find(|(n, _, _)| *n == name)?;
        Some(Scene::from_toml(text, Path::new(name)).expect("built-in scene parses"))
    }
}

/// The built-in scenes: name, one-line description, TOML text (the files in `scenes/`).
pub const BUILTIN: &[(&str, &str, &str)] = &[
    (
        "kd-series",
        "spheres lit by diffuse reflection only, kd 0.4 to 1.0",
        include_str!("../../scenes/kd-series.toml"),
    ),
    (
        "ka-series",
        "ambient plus diffuse, kd 0.4, ka 0 to 0.6",
        include_str!("../../scenes/ka-series.toml"),
    ),
    (
        "ns-series",
        "Phong highlights from dull (ns 1) to shiny (ns 250)",
        include_str!("../../scenes/ns-series.toml"),
    ),
    (
        "shading",
        "one sphere mesh shaded flat, Gouraud and Phong, with a z-buffer",
        include_str!("../../scenes/shading.toml"),
    ),
    (
        "polyhedra",
        "the five regular polyhedra, flat shaded",
        include_str!("../../scenes/polyhedra.toml"),
    ),
    (
        "raytrace",
        "ray traced: shadow, mirror ball, glass ball, checkered floor",
        include_str!("../../scenes/raytrace.toml"),
    ),
    (
        "color-balls",
        "coloured balls under coloured lights, the lecture's table",
        include_str!("../../scenes/color-balls.toml"),
    ),
    (
        "warn-studio",
        "a Warn studio spotlight with a cone and barn doors",
        include_str!("../../scenes/warn-studio.toml"),
    ),
];

fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    renderer: Option<Spanned<String>>,
    size: Option<Spanned<[usize; 2]>>,
    aa: Option<Spanned<String>>,
    ambient: Option<[f64; 3]>,
    background: Option<[f64; 3]>,
    background_bottom: Option<[f64; 3]>,
    max_depth: Option<u32>,
    attenuation: Option<[f64; 3]>,
    shadows: Option<bool>,
    camera: Spanned<RawCamera>,
    #[serde(default)]
    material: BTreeMap<String, Spanned<RawMaterial>>,
    #[serde(default)]
    light: Vec<Spanned<RawLight>>,
    #[serde(default)]
    sphere: Vec<Spanned<RawSphere>>,
    #[serde(default)]
    plane: Vec<Spanned<RawPlane>>,
    #[serde(default)]
    mesh: Vec<Spanned<RawMesh>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    eye: [f64; 3],
    look_at: [f64; 3],
    up: Option<[f64; 3]>,
    fov: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    color: Option<[f64; 3]>,
    ka: Option<f64>,
    kd: Option<f64>,
    ks: Option<f64>,
    ns: Option<f64>,
    specular_color: Option<[f64; 3]>,
    highlight: Option<String>,
    reflect: Option<f64>,
    transmit: Option<f64>,
    ior: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    kind: String,
    position: Option<[f64; 3]>,
    direction: Option<[f64; 3]>,
    target: Option<[f64; 3]>,
    color: Option<[f64; 3]>,
    intensity: Option<f64>,
    attenuation: Option<[f64; 3]>,
    exponent: Option<f64>,
    cone: Option<f64>,
    flap_x: Option<[f64; 2]>,
    flap_y: Option<[f64; 2]>,
    flap_z: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSphere {
    center: [f64; 3],
    radius: f64,
    material: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlane {
    point: [f64; 3],
    normal: [f64; 3],
    material: Option<String>,
    checker: Option<[f64; 3]>,
    checker_size: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    shape: String,
    center: [f64; 3],
    radius: f64,
    rotate: Option<[f64; 2]>,
    detail: Option<usize>,
    shading: Option<String>,
    material: Option<String>,
}

impl RawScene {
    fn build(self, text: &str, path: &Path) -> Result<Scene> {
        let err = |span: std::ops::Range<usize>, msg: String| {
            Error::parse(path, line_of(text, span.start), msg)
        };
        let renderer = match &self.renderer {
            None => Renderer::RayTrace,
            Some(s) => match s.get_ref().as_str() {
                "raytrace" => Renderer::RayTrace,
                "zbuffer" => Renderer::ZBuffer,
                other => {
                    return Err(err(
                        s.span(),
                        format!("unknown renderer '{other}' (raytrace, zbuffer)"),
                    ))
                }
            },
        };
        let aa = match &self.aa {
            None => Antialias::default(),
            Some(s) => parse_aa(s.get_ref()).ok_or_else(|| {
                err(
                    s.span(),
                    format!(
                        "unknown aa '{}' (none, super, adaptive, jitter)",
                        s.get_ref()
                    ),
                )
            })?,
        };
        let size = self.size.as_ref().map_or([320, 240], |s| *s.get_ref());
        if size.iter().any(|&n| n == 0 || n > 16384) {
            let span = self.size.as_ref().map_or(0..0, |s| s.span());
            return Err(err(span, "size must be between 1 and 16384".into()));
        }
        let mut materials = vec![Material::default()];
        let mut names: BTreeMap<&str, usize> = BTreeMap::new();
        for (name, m) in &self.material {
            let span = m.span();
            materials.push(m.get_ref().build().map_err(|msg| err(span, msg))?);
            names.insert(name.as_str(), materials.len() - 1);
        }
        let material = |name: &Option<String>, span: std::ops::Range<usize>| match name {
            None => Ok(0),
            Some(n) => names
                .get(n.as_str())
                .copied()
                .ok_or_else(|| err(span, format!("no material named '{n}'"))),
        };
        let mut lights = Vec::new();
        for l in &self.light {
            lights.push(l.get_ref().build().map_err(|msg| err(l.span(), msg))?);
        }
        let mut spheres = Vec::new();
        for s in &self.sphere {
            let r = s.get_ref();
            if r.radius.is_nan() || r.radius <= 0.0 {
                return Err(err(s.span(), "sphere radius must be > 0".into()));
            }
            spheres.push(Sphere {
                center: Vec3::from_array(r.center),
                radius: r.radius,
                material: material(&r.material, s.span())?,
            });
        }
        let mut planes = Vec::new();
        for p in &self.plane {
            let r = p.get_ref();
            let normal = Vec3::from_array(r.normal);
            if normal.length() == 0.0 || normal.length().is_nan() {
                return Err(err(p.span(), "plane normal must not be zero".into()));
            }
            let size = r.checker_size.unwrap_or(1.0);
            if size.is_nan() || size <= 0.0 {
                return Err(err(p.span(), "checker_size must be > 0".into()));
            }
            let checker = r.checker.map(|c| (Vec3::from_array(c), size));
            planes.push(Plane {
                point: Vec3::from_array(r.point),
                normal: normal.normalized(),
                material: material(&r.material, p.span())?,
                checker,
            });
        }
        let mut meshes = Vec::new();
        for m in &self.mesh {
            let r = m.get_ref();
            let e = |msg: String| err(m.span(), msg);
            if r.radius.is_nan() || r.radius <= 0.0 {
                return Err(e("mesh radius must be > 0".into()));
            }
            let unit = match r.shape.as_str() {
                "sphere" => {
                    let d = r.detail.unwrap_or(8);
                    if !(2..=256).contains(&d) {
                        return Err(e("sphere detail must be 2 to 256".into()));
                    }
                    Mesh::sphere(d, 2 * d)
                }
                name => Mesh::solid(Solid::from_name(name).ok_or_else(|| {
                    e(format!(
                        "unknown shape '{name}' (tetrahedron, cube, octahedron, dodecahedron, icosahedron, sphere)"
                    ))
                })?),
            };
            let shading = match r.shading.as_deref() {
                None | Some("flat") => Shading::Flat,
                Some("gouraud") => Shading::Gouraud,
                Some("phong") => Shading::Phong,
                Some(other) => {
                    return Err(e(format!(
                        "unknown shading '{other}' (flat, gouraud, phong)"
                    )))
                }
            };
            meshes.push(MeshObject {
                mesh: unit.placed(
                    Vec3::from_array(r.center),
                    r.radius,
                    r.rotate.unwrap_or([0.0, 0.0]),
                ),
                material: material(&r.material, m.span())?,
                shading,
            });
        }
        if renderer == Renderer::ZBuffer && !planes.is_empty() {
            return Err(err(
                self.plane[0].span(),
                "planes need renderer = \"raytrace\"".into(),
            ));
        }
        let cam = self.camera.get_ref();
        let cam_span = self.camera.span();
        let camera = Camera {
            eye: Vec3::from_array(cam.eye),
            look_at: Vec3::from_array(cam.look_at),
            up: Vec3::from_array(cam.up.unwrap_or([0.0, 1.0, 0.0])),
            fov: cam.fov.unwrap_or(40.0),
        };
        let fwd = camera.look_at - camera.eye;
        if fwd.length() == 0.0 || fwd.cross(camera.up).length() < 1e-9 {
            return Err(err(
                cam_span,
                "camera: eye and look_at must differ, and up must not be along the view".into(),
            ));
        }
        if !(camera.fov > 0.0 && camera.fov < 179.0) {
            return Err(err(
                cam_span,
                "camera: fov must be between 0 and 179 degrees".into(),
            ));
        }
        let background = Vec3::from_array(self.background.unwrap_or([0.0; 3]));
        Ok(Scene {
            size: (size[0], size[1]),
            renderer,
            aa,
            camera,
            ambient: Vec3::from_array(self.ambient.unwrap_or([1.0; 3])),
            background: [
                background,
                self.background_bottom.map_or(background, Vec3::from_array),
            ],
            lights,
            materials,
            spheres,
            planes,
            meshes,
            max_depth: self.max_depth.unwrap_or(5).min(32),
            tree_attenuation: self.attenuation.unwrap_or([1.0, 0.0, 0.0]),
            shadows: self.shadows.unwrap_or(true),
        })
    }
}

/// Parses an antialiasing name: none, super, adaptive, jitter.
pub fn parse_aa(s: &str) -> Option<Antialias> {
    Some(match s {
        "none" => Antialias::None,
        "super" => Antialias::Super,
        "adaptive" => Antialias::Adaptive,
        "jitter" => Antialias::Jitter,
        _ => return None,
    })
}

fn unit_range(name: &str, v: Option<f64>, default: f64) -> Result<f64, String> {
    let v = v.unwrap_or(default);
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{name} must be between 0 and 1, not {v}"))
    }
}

impl RawMaterial {
    fn build(&self) -> Result<Material, String> {
        let d = Material::default();
        let ns = self.ns.unwrap_or(d.ns);
        if ns.is_nan() || ns < 0.0 {
            return Err(format!("ns must be >= 0, not {ns}"));
        }
        let ior = self.ior.unwrap_or(1.5);
        if ior.is_nan() || ior <= 0.0 {
            return Err(format!("ior must be > 0, not {ior}"));
        }
        Ok(Material {
            color: self.color.map_or(d.color, Vec3::from_array),
            ka: unit_range("ka", self.ka, d.ka)?,
            kd: unit_range("kd", self.kd, d.kd)?,
            ks: unit_range("ks", self.ks, d.ks)?,
            ns,
            specular_color: self
                .specular_color
                .map_or(d.specular_color, Vec3::from_array),
            highlight: match self.highlight.as_deref() {
                None | Some("halfway") => Highlight::Halfway,
                Some("reflection") => Highlight::Reflection,
                Some(o) => return Err(format!("unknown highlight '{o}' (halfway, reflection)")),
            },
            reflect: unit_range("reflect", self.reflect, 0.0)?,
            transmit: unit_range("transmit", self.transmit, 0.0)?,
            ior,
        })
    }
}

impl RawLight {
    fn build(&self) -> Result<Light, String> {
        let need = |v: Option<[f64; 3]>, what: &str| {
            v.map(Vec3::from_array)
                .ok_or_else(|| format!("a {} light needs '{what}'", self.kind))
        };
        let color =
            Vec3::from_array(self.color.unwrap_or([1.0; 3])) * self.intensity.unwrap_or(1.0);
        let kind = match self.kind.as_str() {
            "point" => LightKind::Point {
                position: need(self.position, "position")?,
            },
            "directional" => {
                let d = need(self.direction, "direction")?;
                if d.length() == 0.0 {
                    return Err("light direction must not be zero".into());
                }
                LightKind::Directional {
                    direction: d.normalized(),
                }
            }
            "warn" => {
                let position = need(self.position, "position")?;
                let direction = match (self.direction, self.target) {
                    (Some(d), _) => Vec3::from_array(d),
                    (None, Some(t)) => Vec3::from_array(t) - position,
                    (None, None) => return Err("a warn light needs 'direction' or 'target'".into()),
                };
                if direction.length() == 0.0 {
                    return Err("light direction must not be zero".into());
                }
                let cone = match self.cone {
                    None => None,
                    Some(c) if c > 0.0 && c < 90.0 => Some(c.to_radians()),
                    Some(c) => {
                        return Err(format!("cone must be between 0 and 90 degrees, not {c}"))
                    }
                };
                LightKind::Warn(WarnLight {
                    position,
                    direction: direction.normalized(),
                    exponent: self.exponent.unwrap_or(1.0).max(0.0),
                    cone,
                    flaps: [self.flap_x, self.flap_y, self.flap_z],
                })
            }
            other => {
                return Err(format!(
                    "unknown light kind '{other}' (point, directional, warn)"
                ))
            }
        };
        let attenuation = self.attenuation.unwrap_or([1.0, 0.0, 0.0]);
        if attenuation.iter().any(|a| a.is_nan() || *a < 0.0)
            || attenuation.iter().all(|a| *a == 0.0)
        {
            return Err("attenuation must be three coefficients >= 0, not all zero".into());
        }
        Ok(Light {
            kind,
            color,
            attenuation,
        })
    }
}
