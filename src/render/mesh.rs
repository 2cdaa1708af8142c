//! Polygon meshes: the five regular polyhedra and a latitude–longitude sphere, with face
//! normals and Gouraud's vertex normals (lecture, Unit 5, "Gouraud Shading":
//! N_V = Σ N_k / |Σ N_k| over the faces sharing the vertex).

use super::geometry::Vec3;

/// A polygon mesh: shared vertex positions and convex faces listing vertex indices
/// counter-clockwise seen from outside.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Faces as vertex indices, counter-clockwise from outside.
    pub faces: Vec<Vec<usize>>,
}

/// The five regular polyhedra (lecture, Unit 5, "Regular Polyhedrons").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Solid {
    /// 4 triangles.
    Tetrahedron,
    /// 6 squares.
    Cube,
    /// 8 triangles.
    Octahedron,
    /// 12 pentagons.
    Dodecahedron,
    /// 20 triangles.
    Icosahedron,
}

impl Solid {
    /// All five, in order of face count.
    pub const ALL: [Solid; 5] = [
        Solid::Tetrahedron,
        Solid::Cube,
        Solid::Octahedron,
        Solid::Dodecahedron,
        Solid::Icosahedron,
    ];

    /// The solid's name in lower case.
    pub fn name(self) -> &'static str {
        match self {
            Solid::Tetrahedron => "tetrahedron",
            Solid::Cube => "cube",
            Solid::Octahedron => "octahedron",
            Solid::Dodecahedron => "dodecahedron",
            Solid::Icosahedron => "icosahedron",
        }
    }

    /// The solid named `name`.
    pub fn from_name(name: &str) -> Option<Solid> {
        Solid::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Its vertices, on the unit sphere.
    fn vertices(self) -> Vec<Vec3> {
        let phi = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v = Vec::new();
        let signs = [1.0, -1.0];
        match self {
            Solid::Tetrahedron => {
                for p in [
                    [1.0, 1.0, 1.0],
                    [1.0, -1.0, -1.0],
                    [-1.0, 1.0, -1.0],
                    [-1.0, -1.0, 1.0],
                ] {
                    v.push(Vec3::from_array(p));
                }
            }
            Solid::Cube => {
                for x in signs {
                    for y in signs {
                        for z in signs {
                            v.push(Vec3::new(x, y, z));
                        }
                    }
                }
            }
            Solid::Octahedron => {
                for s in signs {
                    v.push(Vec3::new(s, 0.0, 0.0));
                    v.push(Vec3::new(0.0, s, 0.0));
                    v.push(Vec3::new(0.0, 0.0, s));
                }
            }
            Solid::Icosahedron => {
                // Cyclic permutations of (0, ±1, ±φ).
                for a in signs {
                    for b in signs {
                        v.push(Vec3::new(0.0, a, b * phi));
                        v.push(Vec3::new(a, b * phi, 0.0));
                        v.push(Vec3::new(b * phi, 0.0, a));
                    }
                }
            }
            Solid::Dodecahedron => {
                // (±1, ±1, ±1) and cyclic permutations of (0, ±1/φ, ±φ).
                for x in signs {
                    for y in signs {
                        for z in signs {
                            v.push(Vec3::new(x, y, z));
                        }
                    }
                }
                for a in signs {
                    for b in signs {
                        v.push(Vec3::new(0.0, a / phi, b * phi));
                        v.push(Vec3::new(a / phi, b * phi, 0.0));
                        v.push(Vec3::new(b * phi, 0.0, a / phi));
                    }
                }
            }
        }
        v.into_iter().map(Vec3::normalized).collect()
    }
}

impl Mesh {
    /// The regular polyhedron `solid` with circumradius 1, centred on the origin.
    pub fn solid(solid: Solid) -> Mesh {
        let positions = solid.vertices();
        let faces = hull_faces(&positions);
        Mesh { positions, faces }
    }

    /// A unit sphere approximated by `stacks` bands of latitude and `slices` of longitude:
    /// triangles at the poles, planar quadrilaterals elsewhere.
    pub fn sphere(stacks: usize, slices: usize) -> Mesh {
        let stacks = stacks.max(2);
        let slices = slices.max(3);
        let mut positions = vec![Vec3::new(0.0, 1.0, 0.0)];
        for i in 1..stacks {
            let theta = std::f64::consts::PI * i as f64 / stacks as f64;
            for j in 0..slices {
                let phi = std::f64::consts::TAU * j as f64 / slices as f64;
                positions.push(Vec3::new(
                    theta.sin() * phi.sin(),
                    theta.cos(),
                    theta.sin() * phi.cos(),
                ));
            }
        }
        positions.push(Vec3::new(0.0, -1.0, 0.0));
        let south = positions.len() - 1;
        let ring = |i: usize, j: usize| 1 + (i - 1) * slices + j % slices;
        let mut faces = Vec::new();
        for j in 0..slices {
            faces.push(vec![0, ring(1, j), ring(1, j + 1)]);
        }
        for i in 1..stacks - 1 {
            for j in 0..slices {
                faces.push(vec![
                    ring(i, j),
                    ring(i + 1, j),
                    ring(i + 1, j + 1),
                    ring(i, j + 1),
                ]);
            }
        }
        for j in 0..slices {
            faces.push(vec![ring(stacks - 1, j), south, ring(stacks - 1, j + 1)]);
        }
        Mesh { positions, faces }
    }

    /// The mesh scaled by `radius`, rotated by `rotate` (degrees about x, then y) and moved to
    /// `center`.
    pub fn placed(&self, center: Vec3, radius: f64, rotate: [f64; 2]) -> Mesh {
        let (a, b) = (rotate[0].to_radians(), rotate[1].to_radians());
        Mesh {
            positions: self
                .positions
                .iter()
                .map(|p| center + p.rotate_xy(a, b) * radius)
                .collect(),
            faces: self.faces.clone(),
        }
    }

    /// The unit normal of face `f` (Newell's method, exact for planar polygons).
    pub fn face_normal(&self, f: usize) -> Vec3 {
        let face = &self.faces[f];
        let mut n = Vec3::ZERO;
        for (k, &i) in face.iter().enumerate() {
            let a = self.positions[i];
            let b = self.positions[face[(k + 1) % face.len()]];
            n += a.cross(b);
        }
        n.normalized()
    }

    /// The centroid of face `f`.
    pub fn face_center(&self, f: usize) -> Vec3 {
        let face = &self.faces[f];
        let sum = face.iter().fold(Vec3::ZERO, |s, &i| s + self.positions[i]);
        sum / face.len() as f64
    }

    /// Gouraud's vertex normals: the normalised sum of the normals of the faces sharing each
    /// vertex.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut sums = vec![Vec3::ZERO; self.positions.len()];
        for f in 0..self.faces.len() {
            let n = self.face_normal(f);
            for &i in &self.faces[f] {
                sums[i] += n;
            }
        }
        sums.into_iter().map(Vec3::normalized).collect()
    }

    /// The faces split into triangles (fans from each face's first vertex), each with the
    /// index of the face it came from.
    pub fn triangles(&self) -> Vec<(usize, [usize; 3])> {
        let mut out = Vec::new();
        for (f, face) in self.faces.iter().enumerate() {
            for k in 1..face.len() - 1 {
                out.push((f, [face[0], face[k], face[k + 1]]));
            }
        }
        out
    }
}

/// The faces of the convex hull of points on a sphere whose faces are regular polygons:
/// every plane through three vertices with all others on one side is a face; its vertices
/// are ordered counter-clockwise seen from outside.
fn hull_faces(p: &[Vec3]) -> Vec<Vec<usize>> {
    const EPS: f64 = 1e-9;
    let mut faces: Vec<Vec<usize>> = Vec::new();
    let n = p.len();
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                let mut normal = (p[j] - p[i]).cross(p[k] - p[i]);
                if normal.length() < EPS {
                    continue;
                }
                normal = normal.normalized();
                let d = normal.dot(p[i]);
                let (mut above, mut below) = (false, false);
                let mut on = Vec::new();
                for (m, q) in p.iter().enumerate() {
                    let s = normal.dot(*q) - d;
                    if s > EPS {
                        above = true;
                    } else if s < -EPS {
                        below = true;
                    } else {
                        on.push(m);
                    }
                }
                if above && below {
                    continue;
                }
                if above {
                    normal = -normal;
                }
                if faces
                    .iter()
                    .any(|f| f.iter().all(|v| on.contains(v)) && f.len() == on.len())
                {
                    continue;
                }
                // Order counter-clockwise about the outward normal.
                let c = on.iter().fold(Vec3::ZERO, |s, &m| s + p[m]) / on.len() as f64;
                let u = (p[on[0]] - c).normalized();
                let w = normal.cross(u);
                on.sort_by(|&a, &b| {
                    let ang = |m: usize| {
                        let r = p[m] - c;
                        r.dot(w).atan2(r.dot(u))
                    };
                    ang(a).total_cmp(&ang(b))
                });
                faces.push(on);
            }
        }
    }
    faces
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_polyhedra_have_the_right_faces_and_euler_characteristic() {
        // (vertices, faces, edges per face)
        let expect = [(4, 4, 3), (8, 6, 4), (6, 8, 3), (20, 12, 5), (12, 20, 3)];
        for (solid, (v, f, k)) in Solid::ALL.into_iter().zip(expect) {
            let m = Mesh::solid(solid);
            assert_eq!(m.positions.len(), v, "{solid:?}");
            assert_eq!(m.faces.len(), f, "{solid:?}");
            assert!(m.faces.iter().all(|face| face.len() == k), "{solid:?}");
            let edges = f * k / 2;
            assert_eq!(v + f - edges, 2, "{solid:?}");
            // Outward, counter-clockwise: the normal points away from the centre, and all
            // faces are congruent (same distance from the centre).
            let d0 = m.face_normal(0).dot(m.face_center(0));
            for i in 0..f {
                let n = m.face_normal(i);
                assert!(n.dot(m.face_center(i)) > 0.0, "{solid:?} face {i}");
                assert!((n.dot(m.face_center(i)) - d0).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn vertex_normals_average_adjacent_faces() {
        // On a regular solid the average of adjacent face normals points at the vertex.
        for solid in Solid::ALL {
            let m = Mesh::solid(solid);
            for (p, n) in m.positions.iter().zip(m.vertex_normals()) {
                assert!((n - *p).length() < 1e-9, "{solid:?}");
            }
        }
        // A cube corner by hand: (x + y + z)/√3.
        let m = Mesh::solid(Solid::Cube);
        let i = m
            .positions
            .iter()
            .position(|p| p.x > 0.0 && p.y > 0.0 && p.z > 0.0)
            .unwrap();
        let n = m.vertex_normals()[i];
        assert!((n - Vec3::new(1.0, 1.0, 1.0).normalized()).length() < 1e-12);
    }

    #[test]
    fn sphere_mesh_is_closed_and_outward() {
        let m = Mesh::sphere(6, 8);
        assert_eq!(m.positions.len(), 2 + 5 * 8);
        assert_eq!(m.faces.len(), 6 * 8);
        let edges: usize = m.faces.iter().map(Vec::len).sum::<usize>() / 2;
        assert_eq!(m.positions.len() + m.faces.len() - edges, 2);
        for f in 0..m.faces.len() {
            assert!(m.face_normal(f).dot(m.face_center(f)) > 0.0);
        }
        assert_eq!(m.triangles().len(), 2 * 8 + 2 * 4 * 8);
    }
}
