//! Ray tracing (lecture, Unit 5, "Ray-Tracing Methods"): a ray per sample, the nearest hit
//! is the visible surface, shadow rays to every light, a reflected ray R = u − (2u·N)N and a
//! refracted ray by Snell's law for transparent surfaces, down to a depth limit; each
//! secondary contribution is attenuated by the distance it travelled before it is added to
//! its parent's intensity (the ray-tracing tree).
//!
//! Meshes: flat shading applies the model at each hit with the face normal (a ray tracer
//! invokes the model per pixel, and shadows and spotlight edges then fall across a face);
//! Gouraud interpolates the vertex intensities (unshadowed); Phong interpolates normals.

use super::geometry::{reflect, refract, Ray, Vec3};
use super::illumination::{illuminate, Material, Rgb};
use super::scene::{Scene, Shading, View};
use super::shade::MeshShades;

/// Offset of secondary-ray origins from the surface, in scene units, so a ray does not hit
/// the surface it leaves.
const EPS: f64 = 1e-7;

/// A branch of the ray tree whose contribution to the pixel would be below this is not
/// traced: under half a code of 8-bit output even at full intensity.
const MIN_WEIGHT: f64 = 1.0 / 512.0;

struct Triangle {
    mesh: usize,
    v: [usize; 3],
    p0: Vec3,
    e1: Vec3,
    e2: Vec3,
}

struct Bound {
    center: Vec3,
    radius: f64,
    tris: std::ops::Range<usize>,
}

enum Surface {
    Sphere(usize),
    Plane(usize),
    Triangle(usize, f64, f64),
}

struct Hit {
    t: f64,
    surface: Surface,
}

/// A scene prepared for tracing: triangles listed, mesh bounds and precomputed flat and
/// Gouraud intensities.
pub struct Tracer<'a> {
    scene: &'a Scene,
    view: View,
    tris: Vec<Triangle>,
    bounds: Vec<Bound>,
    shades: Vec<MeshShades>,
    checkers: Vec<Option<Checker>>,
}

impl<'a> Tracer<'a> {
    /// Prepares `scene` for a `width` × `height` picture.
    pub fn new(scene: &'a Scene, width: usize, height: usize) -> Tracer<'a> {
        let view = View::new(&scene.camera, width, height);
        let mut tris = Vec::new();
        let mut bounds = Vec::new();
        let mut shades = Vec::new();
        for (mi, obj) in scene.meshes.iter().enumerate() {
            let start = tris.len();
            for (_, v) in obj.mesh.triangles() {
                let p = |i: usize| obj.mesh.positions[v[i]];
                tris.push(Triangle {
                    mesh: mi,
                    v,
                    p0: p(0),
                    e1: p(1) - p(0),
                    e2: p(2) - p(0),
                });
            }
            let n = obj.mesh.positions.len().max(1) as f64;
            let center = obj.mesh.positions.iter().fold(Vec3::ZERO, |s, p| s + *p) / n;
            let radius = obj
                .mesh
                .positions
                .iter()
                .map(|p| (*p - center).length())
                .fold(0.0, f64::max);
            bounds.push(Bound {
                center,
                radius: radius * (1.0 + 1e-9),
                tris: start..tris.len(),
            });
            shades.push(MeshShades::new(scene, obj, view.eye()));
        }
        let checkers = scene
            .planes
            .iter()
            .map(|pl| Checker::new(pl, &scene.materials[pl.material]))
            .collect();
        Tracer {
            scene,
            view,
            tris,
            bounds,
            shades,
            checkers,
        }
    }

    /// The intensity seen through picture point (`sx`, `sy`).
    pub fn sample(&self, sx: f64, sy: f64) -> Rgb {
        let ray = self.view.ray(sx, sy);
        match self.nearest(&ray, f64::INFINITY) {
            None => self.scene.background(&self.view, ray.dir),
            Some(hit) => self.shade(&ray, &hit, 0, 1.0),
        }
    }

    /// A secondary ray's contribution, attenuated by the distance to what it hits; `weight`
    /// is the share of the pixel this branch of the tree carries.
    fn secondary(&self, ray: &Ray, depth: u32, weight: f64) -> Rgb {
        match self.nearest(ray, f64::INFINITY) {
            // The background is at infinity and is not attenuated: it is light arriving.
            None => self.scene.background(&self.view, ray.dir),
            Some(hit) => {
                let [a0, a1, a2] = self.scene.tree_attenuation;
                let f = (1.0 / (a0 + a1 * hit.t + a2 * hit.t * hit.t)).min(1.0);
                self.shade(ray, &hit, depth, weight * f) * f
            }
        }
    }

    #[inline]
    fn nearest(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        for (i, s) in self.scene.spheres.iter().enumerate() {
            if let Some(t) = hit_sphere(ray, s.center, s.radius) {
                if t < t_best {
                    t_best = t;
                    best = Some(Hit {
                        t,
                        surface: Surface::Sphere(i),
                    });
                }
            }
        }
        for (i, p) in self.scene.planes.iter().enumerate() {
            let denom = p.normal.dot(ray.dir);
            if denom.abs() > 1e-12 {
                let t = (p.point - ray.origin).dot(p.normal) / denom;
                if t > EPS && t < t_best {
                    t_best = t;
                    best = Some(Hit {
                        t,
                        surface: Surface::Plane(i),
                    });
                }
            }
        }
        for b in &self.bounds {
            if hit_sphere_any(ray, b.center, b.radius, t_best) {
                for i in b.tris.clone() {
                    if let Some((t, u, v)) = hit_triangle(ray, &self.tris[i]) {
                        if t < t_best {
                            t_best = t;
                            best = Some(Hit {
                                t,
                                surface: Surface::Triangle(i, u, v),
                            });
                        }
                    }
                }
            }
        }
        best
    }

    /// Fraction of light passing from `origin` along `dir` for `dist`: transparent
    /// surfaces on the way pass their `transmit`, opaque ones block.
    #[inline]
    fn transmittance(&self, origin: Vec3, dir: Vec3, dist: f64) -> f64 {
        let ray = Ray { origin, dir };
        let mats = &self.scene.materials;
        let mut pass = 1.0;
        for s in &self.scene.spheres {
            if matches!(hit_sphere(&ray, s.center, s.radius), Some(t) if t < dist) {
                pass *= mats[s.material].transmit;
                if pass == 0.0 {
                    return 0.0;
                }
            }
        }
        for p in &self.scene.planes {
            let denom = p.normal.dot(dir);
            if denom.abs() > 1e-12 {
                let t = (p.point - origin).dot(p.normal) / denom;
                if t > EPS && t < dist {
                    pass *= mats[p.material].transmit;
                    if pass == 0.0 {
                        return 0.0;
                    }
                }
            }
        }
        for b in &self.bounds {
            if hit_sphere_any(&ray, b.center, b.radius, dist) {
                for tri in &self.tris[b.tris.clone()] {
                    if matches!(hit_triangle(&ray, tri), Some((t, _, _)) if t < dist) {
                        pass *= mats[self.scene.meshes[tri.mesh].material].transmit;
                        if pass == 0.0 {
                            return 0.0;
                        }
                    }
                }
            }
        }
        pass
    }

    fn shade(&self, ray: &Ray, hit: &Hit, depth: u32, weight: f64) -> Rgb {
        let scene = self.scene;
        let p = ray.at(hit.t);
        let (geo, normal, material, local): (Vec3, Vec3, &Material, Option<Rgb>) = match hit.surface
        {
            Surface::Sphere(i) => {
                let s = &scene.spheres[i];
                let n = (p - s.center) / s.radius;
                (n, n, &scene.materials[s.material], None)
            }
            Surface::Plane(i) => {
                let pl = &scene.planes[i];
                (pl.normal, pl.normal, &scene.materials[pl.material], None)
            }
            Surface::Triangle(i, u, v) => {
                let tri = &self.tris[i];
                let obj = &scene.meshes[tri.mesh];
                let sh = &self.shades[tri.mesh];
                let w = [1.0 - u - v, u, v];
                let geo = tri.e1.cross(tri.e2).normalized();
                let m = &scene.materials[obj.material];
                match obj.shading {
                    Shading::Flat => (geo, geo, m, None),
                    Shading::Gouraud => {
                        let c = (0..3).fold(Rgb::ZERO, |s, k| s + sh.vertex[tri.v[k]] * w[k]);
                        (geo, geo, m, Some(c))
                    }
                    Shading::Phong => {
                        let n = (0..3)
                            .fold(Vec3::ZERO, |s, k| s + sh.normal[tri.v[k]] * w[k])
                            .normalized();
                        (geo, n, m, None)
                    }
                }
            }
        };
        let entering = ray.dir.dot(geo) < 0.0;
        // The normal on the side the ray arrives from.
        let n = if ray.dir.dot(normal) < 0.0 {
            normal
        } else {
            -normal
        };
        let facing_geo = if entering { geo } else { -geo };
        let mut c = match local {
            Some(c) => c,
            None => {
                let m = match hit.surface {
                    Surface::Plane(i) => match &self.checkers[i] {
                        Some(ch) if ch.odd(p) => &ch.material,
                        _ => material,
                    },
                    _ => material,
                };
                let lift = p + facing_geo * EPS;
                illuminate(m, p, n, -ray.dir, scene.ambient, &scene.lights, |_, inc| {
                    if scene.shadows {
                        self.transmittance(lift, inc.l, inc.distance)
                    } else {
                        1.0
                    }
                })
            }
        };
        if depth < scene.max_depth {
            let mirror = Ray {
                origin: p + facing_geo * EPS,
                dir: reflect(ray.dir, n),
            };
            let kr = material.reflect;
            if kr > 0.0 && weight * kr >= MIN_WEIGHT {
                c += self.secondary(&mirror, depth + 1, weight * kr) * kr;
            }
            let kt = material.transmit;
            if kt > 0.0 && weight * kt >= MIN_WEIGHT {
                let (eta_i, eta_r) = if entering {
                    (1.0, material.ior)
                } else {
                    (material.ior, 1.0)
                };
                let bent = match refract(ray.dir, n, eta_i, eta_r) {
                    Some(t) => Ray {
                        origin: p - facing_geo * EPS,
                        dir: t,
                    },
                    // Total internal reflection: the transmitted share goes into the mirror ray.
                    None => mirror,
                };
                c += self.secondary(&bent, depth + 1, weight * kt) * kt;
            }
        }
        c
    }
}

/// The odd squares of a checkered plane: their material and the plane's square grid.
struct Checker {
    material: Material,
    u: Vec3,
    v: Vec3,
    size: f64,
}

impl Checker {
    fn new(plane: &super::scene::Plane, material: &Material) -> Option<Checker> {
        let (other, size) = plane.checker?;
        let n = plane.normal;
        let a = if n.x.abs() < 0.9 {
            Vec3::new(1.0, 0.0, 0.0)
        } else {
            Vec3::new(0.0, 1.0, 0.0)
        };
        let u = n.cross(a).normalized();
        Some(Checker {
            material: Material {
                color: other,
                ..material.clone()
            },
            u,
            v: n.cross(u),
            size,
        })
    }

    /// Whether `p` lies on an odd square.
    fn odd(&self, p: Vec3) -> bool {
        let i =
            (p.dot(self.u) / self.size).floor() as i64 + (p.dot(self.v) / self.size).floor() as i64;
        i.rem_euclid(2) == 1
    }
}

/// Nearest t > EPS where `ray` meets the sphere.
#[inline]
fn hit_sphere(ray: &Ray, center: Vec3, radius: f64) -> Option<f64> {
    let oc = ray.origin - center;
    let b = oc.dot(ray.dir);
    let c = oc.dot(oc) - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    let t0 = -b - sq;
    if t0 > EPS {
        return Some(t0);
    }
    let t1 = -b + sq;
    (t1 > EPS).then_some(t1)
}

/// Whether `ray` meets the sphere before `t_max` (or starts inside it).
#[inline]
fn hit_sphere_any(ray: &Ray, center: Vec3, radius: f64, t_max: f64) -> bool {
    let oc = ray.origin - center;
    let c = oc.dot(oc) - radius * radius;
    if c <= 0.0 {
        return true;
    }
    let b = oc.dot(ray.dir);
    let disc = b * b - c;
    disc >= 0.0 && -b + disc.sqrt() > 0.0 && -b - disc.sqrt() < t_max
}

/// Möller–Trumbore: t and barycentrics (u, v) of the hit with a triangle.
#[inline]
fn hit_triangle(ray: &Ray, tri: &Triangle) -> Option<(f64, f64, f64)> {
    let p = ray.dir.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - tri.p0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = ray.dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(q) * inv;
    (t > EPS).then_some((t, u, v))
}
