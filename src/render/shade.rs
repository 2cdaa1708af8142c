//! What polygon shading precomputes per mesh (lecture, Unit 5, "Polygon-Rendering
//! Methods"): flat shading's one intensity per polygon, Gouraud's vertex normals and the
//! intensities at the vertices that it interpolates, and the vertex normals Phong shading
//! interpolates.

use super::geometry::Vec3;
use super::illumination::{illuminate, Rgb};
use super::scene::{MeshObject, Scene};

/// Per-mesh shading data.
pub struct MeshShades {
    /// Vertex normals: normalised sums of the adjacent faces' normals.
    pub normal: Vec<Vec3>,
    /// The model applied at each vertex with its vertex normal (Gouraud).
    pub vertex: Vec<Rgb>,
    /// The model applied once per face, at its centroid with its face normal (flat).
    pub face: Vec<Rgb>,
}

impl MeshShades {
    /// Computes the shading data of `obj` in `scene` seen from `eye`. Intensities here
    /// take no shadows: flat and Gouraud shading evaluate the model at a few points only.
    pub fn new(scene: &Scene, obj: &MeshObject, eye: Vec3) -> MeshShades {
        let m = &scene.materials[obj.material];
        let light = |p: Vec3, n: Vec3| {
            illuminate(
                m,
                p,
                n,
                (eye - p).normalized(),
                scene.ambient,
                &scene.lights,
                |_, _| 1.0,
            )
        };
        let normal = obj.mesh.vertex_normals();
        let vertex = obj
            .mesh
            .positions
            .iter()
            .zip(&normal)
            .map(|(p, n)| light(*p, *n))
            .collect();
        let face = (0..obj.mesh.faces.len())
            .map(|f| light(obj.mesh.face_center(f), obj.mesh.face_normal(f)))
            .collect();
        MeshShades {
            normal,
            vertex,
            face,
        }
    }
}
