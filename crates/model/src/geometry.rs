//! Planes and rays in the camera frame.

use nalgebra::{Point3, Vector3};

/// A plane `normal · p = offset_mm` (the normal need not be unit length; the
/// distances below account for it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Normal vector.
    pub normal: Vector3<f64>,
    /// Right-hand side: `normal · p` for every point `p` on the plane, in mm.
    pub offset_mm: f64,
}

impl Plane {
    /// The plane through `point` with normal `normal`.
    pub fn from_point_normal(point: &Point3<f64>, normal: &Vector3<f64>) -> Self {
        Self { normal: *normal, offset_mm: normal.dot(&point.coords) }
    }

    /// Signed Euclidean distance of `point` from the plane, positive on the side the normal points to.
    pub fn signed_distance_mm(&self, point: &Point3<f64>) -> f64 {
        (self.normal.dot(&point.coords) - self.offset_mm) / self.normal.norm()
    }

    /// Where `ray` meets the plane, if it does at a positive ray parameter.
    pub fn intersect(&self, ray: &Ray) -> Option<Point3<f64>> {
        let along = self.normal.dot(&ray.direction);
        // A ray parallel to the plane (to rounding) has no single intersection.
        if along.abs() <= 1e-12 * self.normal.norm() * ray.direction.norm() {
            return None;
        }
        let t = (self.offset_mm - self.normal.dot(&ray.origin.coords)) / along;
        (t > 0.0 && t.is_finite()).then(|| ray.at(t))
    }
}

/// A half-line `origin + t * direction`, t > 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point, in mm.
    pub origin: Point3<f64>,
    /// Direction (any length).
    pub direction: Vector3<f64>,
}

impl Ray {
    /// The camera ray through normalized coordinates (u_n, v_n): from the optical
    /// centre along (u_n, v_n, 1), eq. (1).
    pub fn through_normalized(u_n: f64, v_n: f64) -> Self {
        Self { origin: Point3::origin(), direction: Vector3::new(u_n, v_n, 1.0) }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> Point3<f64> {
        self.origin + self.direction * t
    }
}
