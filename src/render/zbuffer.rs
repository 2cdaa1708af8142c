//! Scan conversion with a z-buffer (lecture, Unit 5, "Polygon-Rendering Methods"): every
//! polygon is projected, split into triangles and filled sample by sample; a sample keeps
//! the nearest surface. Flat, Gouraud and Phong shading as the mesh asks. Spheres are
//! approximated by fine Phong-shaded meshes; shadows, mirrors and glass need the ray tracer.

use rayon::prelude::*;

use super::geometry::Vec3;
use super::illumination::{illuminate, Rgb};
use super::mesh::Mesh;
use super::scene::{MeshObject, Scene, Shading, View};
use super::shade::MeshShades;

/// Latitude bands of the mesh standing in for a sphere.
const SPHERE_DETAIL: usize = 48;

struct ScreenTri {
    obj: usize,
    face: usize,
    v: [usize; 3],
    /// Picture x, y and 1/depth of each corner.
    s: [(f64, f64, f64); 3],
    area: f64,
    y0: f64,
    y1: f64,
    x0: f64,
    x1: f64,
}

/// The samples of a picture as a grid: sample (i, j) lies at picture point
/// (i·step + offset, j·step + offset).
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    /// Samples across.
    pub width: usize,
    /// Samples down.
    pub height: usize,
    /// Distance between samples in pixels.
    pub step: f64,
    /// Position of sample 0 in pixels.
    pub offset: f64,
}

/// Renders the z-buffered polygons of `scene` as seen by `view` at the samples of `grid`,
/// returning one linear RGB triple per sample, row by row.
pub fn render_grid(scene: &Scene, view: &View, grid: Grid) -> Vec<Rgb> {
    let spheres: Vec<MeshObject> = scene
        .spheres
        .iter()
        .map(|s| MeshObject {
            mesh: Mesh::sphere(SPHERE_DETAIL, 2 * SPHERE_DETAIL).placed(
                s.center,
                s.radius,
                [0.0, 0.0],
            ),
            material: s.material,
            shading: Shading::Phong,
        })
        .collect();
    let objects: Vec<&MeshObject> = scene.meshes.iter().chain(&spheres).collect();
    let eye = view.eye();
    let shades: Vec<MeshShades> = objects
        .iter()
        .map(|o| MeshShades::new(scene, o, eye))
        .collect();
    let mut tris = Vec::new();
    for (oi, obj) in objects.iter().enumerate() {
        let proj: Vec<Option<(f64, f64, f64)>> = obj
            .mesh
            .positions
            .iter()
            .map(|p| view.project(*p))
            .collect();
        for (face, v) in obj.mesh.triangles() {
            // Back faces are hidden on closed meshes; skip them.
            let n = obj.mesh.face_normal(face);
            if n.dot(eye - obj.mesh.face_center(face)) <= 0.0 {
                continue;
            }
            let (Some(a), Some(b), Some(c)) = (proj[v[0]], proj[v[1]], proj[v[2]]) else {
                continue; // crosses behind the eye: not drawn
            };
            let s = [
                (a.0, a.1, 1.0 / a.2),
                (b.0, b.1, 1.0 / b.2),
                (c.0, c.1, 1.0 / c.2),
            ];
            let area = edge(s[0], s[1], s[2].0, s[2].1);
            if area.abs() < 1e-12 {
                continue;
            }
            tris.push(ScreenTri {
                obj: oi,
                face,
                v,
                s,
                area,
                y0: a.1.min(b.1).min(c.1),
                y1: a.1.max(b.1).max(c.1),
                x0: a.0.min(b.0).min(c.0),
                x1: a.0.max(b.0).max(c.0),
            });
        }
    }
    let mut out = vec![Rgb::ZERO; grid.width * grid.height];
    out.par_chunks_mut(grid.width)
        .enumerate()
        .for_each(|(j, row)| {
            let sy = j as f64 * grid.step + grid.offset;
            let mut depth = vec![f64::INFINITY; grid.width];
            let mut hit: Vec<Option<(usize, [f64; 3])>> = vec![None; grid.width];
            for (ti, t) in tris.iter().enumerate() {
                if sy < t.y0 || sy > t.y1 {
                    continue;
                }
                let i0 = ((t.x0 - grid.offset) / grid.step).ceil().max(0.0) as usize;
                let i1 = ((t.x1 - grid.offset) / grid.step).floor();
                if i1 < 0.0 {
                    continue;
                }
                let i1 = (i1 as usize).min(grid.width - 1);
                for i in i0..=i1 {
                    let sx = i as f64 * grid.step + grid.offset;
                    let w0 = edge(t.s[1], t.s[2], sx, sy) / t.area;
                    let w1 = edge(t.s[2], t.s[0], sx, sy) / t.area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    // Perspective-correct weights: screen weights scaled by 1/depth.
                    let inv_z = w0 * t.s[0].2 + w1 * t.s[1].2 + w2 * t.s[2].2;
                    let z = 1.0 / inv_z;
                    if z < depth[i] {
                        depth[i] = z;
                        let k = [w0 * t.s[0].2 * z, w1 * t.s[1].2 * z, w2 * t.s[2].2 * z];
                        hit[i] = Some((ti, k));
                    }
                }
            }
            for (i, px) in row.iter_mut().enumerate() {
                let sx = i as f64 * grid.step + grid.offset;
                *px = match hit[i] {
                    None => scene.background(view, view.ray(sx, sy).dir),
                    Some((ti, k)) => {
                        let t = &tris[ti];
                        let obj = objects[t.obj];
                        let sh = &shades[t.obj];
                        let lerp = |f: &dyn Fn(usize) -> Vec3| {
                            f(t.v[0]) * k[0] + f(t.v[1]) * k[1] + f(t.v[2]) * k[2]
                        };
                        match obj.shading {
                            Shading::Flat => sh.face[t.face],
                            Shading::Gouraud => lerp(&|v| sh.vertex[v]),
                            Shading::Phong => {
                                let n = lerp(&|v| sh.normal[v]).normalized();
                                let p = lerp(&|v| obj.mesh.positions[v]);
                                illuminate(
                                    &scene.materials[obj.material],
                                    p,
                                    n,
                                    (eye - p).normalized(),
                                    scene.ambient,
                                    &scene.lights,
                                    |_, _| 1.0,
                                )
                            }
                        }
                    }
                };
            }
        });
    out
}

/// Twice the signed area of (a, b, (x, y)).
fn edge(a: (f64, f64, f64), b: (f64, f64, f64), x: f64, y: f64) -> f64 {
    (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0)
}
