//! Three-vectors, rays and the two vector formulas of ray tracing (reflection and Snell's
//! refraction), written as in the lecture (Unit 5, "Basic Ray-Tracing Algorithm").

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

/// A point or direction in scene space (right-handed: x right, y up, z towards the viewer).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3 {
    /// x coordinate.
    pub x: f64,
    /// y coordinate.
    pub y: f64,
    /// z coordinate.
    pub z: f64,
}

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3::new(0.0, 0.0, 0.0);

    /// A vector from its coordinates.
    pub const fn new(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3 { x, y, z }
    }

    /// A vector from an array `[x, y, z]`.
    pub const fn from_array(a: [f64; 3]) -> Vec3 {
        Vec3::new(a[0], a[1], a[2])
    }

    /// Dot product.
    pub fn dot(self, o: Vec3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product.
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    /// Euclidean length.
    pub fn length(self) -> f64 {
        self.dot(self).sqrt()
    }

    /// The unit vector in the same direction (the zero vector stays zero).
    pub fn normalized(self) -> Vec3 {
        let l = self.length();
        if l > 0.0 {
            self / l
        } else {
            self
        }
    }

    /// Component-wise product (a colour filtered by a colour).
    pub fn mul_elem(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }

    /// The largest component.
    pub fn max_elem(self) -> f64 {
        self.x.max(self.y).max(self.z)
    }

    /// Component `i` (0 = x).
    pub fn get(self, i: usize) -> f64 {
        match i {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }

    /// Rotates about the x axis by `a` radians, then about the y axis by `b` radians.
    pub fn rotate_xy(self, a: f64, b: f64) -> Vec3 {
        let (s, c) = a.sin_cos();
        let p = Vec3::new(self.x, c * self.y - s * self.z, s * self.y + c * self.z);
        let (s, c) = b.sin_cos();
        Vec3::new(c * p.x + s * p.z, p.y, -s * p.x + c * p.z)
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl AddAssign for Vec3 {
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    fn mul(self, k: f64) -> Vec3 {
        Vec3::new(self.x * k, self.y * k, self.z * k)
    }
}

impl Div<f64> for Vec3 {
    type Output = Vec3;
    fn div(self, k: f64) -> Vec3 {
        Vec3::new(self.x / k, self.y / k, self.z / k)
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

/// A half-line: `origin + t·dir` for t > 0; `dir` is a unit vector.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

impl Ray {
    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// The specular-reflection direction of an incoming unit direction `u` at a surface with
/// unit normal `n`: R = u − (2u·N)N (lecture, Unit 5).
pub fn reflect(u: Vec3, n: Vec3) -> Vec3 {
    u - n * (2.0 * u.dot(n))
}

/// The refracted direction of an incoming unit direction `u` at a surface with unit normal
/// `n` facing the incoming ray (u·N < 0), going from index `eta_i` into `eta_r`, by the
/// lecture's formula T = (ηi/ηr)u − (cos θr − (ηi/ηr) cos θi) N with
/// cos θr = sqrt(1 − (ηi/ηr)²(1 − cos²θi)). `None` on total internal reflection.
///
/// The lecture's θi is measured between −u and N, so cos θi = −u·N here; with that sign the
/// formula's second term becomes +(ηi/ηr)cos θi − cos θr, which is what is computed.
pub fn refract(u: Vec3, n: Vec3, eta_i: f64, eta_r: f64) -> Option<Vec3> {
    let eta = eta_i / eta_r;
    let cos_i = -u.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    if k < 0.0 {
        return None;
    }
    let cos_r = k.sqrt();
    Some((u * eta + n * (eta * cos_i - cos_r)).normalized())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflection_mirrors_about_the_normal() {
        let u = Vec3::new(1.0, -1.0, 0.0).normalized();
        let r = reflect(u, Vec3::new(0.0, 1.0, 0.0));
        assert!((r - Vec3::new(1.0, 1.0, 0.0).normalized()).length() < 1e-12);
    }

    #[test]
    fn refraction_obeys_snell() {
        // 30° incidence from air into glass: sin θr = sin 30° / 1.5.
        let n = Vec3::new(0.0, 1.0, 0.0);
        let a = 30f64.to_radians();
        let u = Vec3::new(a.sin(), -a.cos(), 0.0);
        let t = refract(u, n, 1.0, 1.5).unwrap();
        assert!((t.length() - 1.0).abs() < 1e-12);
        assert!((t.x - a.sin() / 1.5).abs() < 1e-12);
        assert!(t.y < 0.0);
        // Straight in goes straight through.
        let t = refract(-n, n, 1.0, 1.5).unwrap();
        assert!((t + n).length() < 1e-12);
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        // Glass to air: critical angle asin(1/1.5) ≈ 41.8°.
        let n = Vec3::new(0.0, 1.0, 0.0);
        let at = |deg: f64| {
            let a = deg.to_radians();
            refract(Vec3::new(a.sin(), -a.cos(), 0.0), n, 1.5, 1.0)
        };
        assert!(at(41.0).is_some());
        assert!(at(42.5).is_none());
    }
}
