//! Circles and spheres through points: minimal solvers for RANSAC,
//! algebraic least squares (Kasa) for a start, and Gauss-Newton on the
//! geometric distance |‖p - c‖ - r| to finish.

use alacs_model::ransac::Estimator;
use nalgebra::{Matrix3, Matrix4, Point2, Point3, Vector2, Vector3, Vector4};

/// A circle in a plane's 2-D coordinates (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre.
    pub centre: Point2<f64>,
    /// Radius.
    pub radius_mm: f64,
}

/// A sphere in the camera frame (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub centre: Point3<f64>,
    /// Radius.
    pub radius_mm: f64,
}

impl Circle {
    /// Geometric distance of `p` from the circle.
    pub fn distance_mm(&self, p: &Point2<f64>) -> f64 {
        ((p - self.centre).norm() - self.radius_mm).abs()
    }
}

impl Sphere {
    /// Geometric distance of `p` from the sphere.
    pub fn distance_mm(&self, p: &Point3<f64>) -> f64 {
        ((p - self.centre).norm() - self.radius_mm).abs()
    }
}

/// The circle through three points, `None` when they are (nearly) collinear.
pub fn circle_through(a: &Point2<f64>, b: &Point2<f64>, c: &Point2<f64>) -> Option<Circle> {
    let (ab, ac) = (b - a, c - a);
    let cross = ab.x * ac.y - ab.y * ac.x;
    if cross.abs() <= 1e-9 * ab.norm_squared().max(ac.norm_squared()) {
        return None;
    }
    let (ab2, ac2) = (ab.norm_squared(), ac.norm_squared());
    let offset = Vector2::new(ac.y * ab2 - ab.y * ac2, ab.x * ac2 - ac.x * ab2) / (2.0 * cross);
    let circle = Circle { centre: a + offset, radius_mm: offset.norm() };
    circle.radius_mm.is_finite().then_some(circle)
}

/// The sphere through four points, `None` when they are (nearly) coplanar.
pub fn sphere_through(points: [&Point3<f64>; 4]) -> Option<Sphere> {
    let [a, b, c, d] = points;
    let rows = [b - a, c - a, d - a];
    let m = Matrix3::from_rows(&[rows[0].transpose(), rows[1].transpose(), rows[2].transpose()]);
    let rhs =
        Vector3::new(rows[0].norm_squared(), rows[1].norm_squared(), rows[2].norm_squared()) * 0.5;
    let scale = rows.iter().map(|r| r.norm()).fold(0.0, f64::max);
    if m.determinant().abs() <= 1e-9 * scale.powi(3) {
        return None;
    }
    let offset = m.lu().solve(&rhs)?;
    let sphere = Sphere { centre: a + offset, radius_mm: offset.norm() };
    sphere.radius_mm.is_finite().then_some(sphere)
}

/// Least-squares circle: Kasa's algebraic fit, then Gauss-Newton on the
/// geometric distances. `None` for fewer than 3 points or a degenerate set.
pub fn fit_circle(points: &[Point2<f64>]) -> Option<Circle> {
    if points.len() < 3 {
        return None;
    }
    // Kasa: x^2 + y^2 = 2 a x + 2 b y + c, centred for conditioning.
    let mean = points.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / points.len() as f64;
    let mut normal = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for p in points {
        let q = p.coords - mean;
        let row = Vector3::new(2.0 * q.x, 2.0 * q.y, 1.0);
        normal += row * row.transpose();
        rhs += row * q.norm_squared();
    }
    let solution = normal.lu().solve(&rhs)?;
    let centre = Vector2::new(solution.x, solution.y);
    let radius_squared = solution.z + centre.norm_squared();
    if radius_squared.is_nan() || radius_squared <= 0.0 {
        return None;
    }
    let mut circle =
        Circle { centre: Point2::from(centre + mean), radius_mm: radius_squared.sqrt() };
    for _ in 0..GAUSS_NEWTON_STEPS {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for p in points {
            let d = p - circle.centre;
            let n = d.norm();
            if n <= 0.0 {
                continue;
            }
            let j = Vector3::new(-d.x / n, -d.y / n, -1.0);
            let r = n - circle.radius_mm;
            jtj += j * j.transpose();
            jtr += j * r;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        circle.centre += Vector2::new(step.x, step.y);
        circle.radius_mm += step.z;
        if step.norm() < 1e-9 {
            break;
        }
    }
    (circle.radius_mm > 0.0 && circle.centre.coords.iter().all(|c| c.is_finite())).then_some(circle)
}

/// Least-squares sphere: the algebraic fit, then Gauss-Newton on the
/// geometric distances. `None` for fewer than 4 points or a degenerate set.
pub fn fit_sphere(points: &[Point3<f64>]) -> Option<Sphere> {
    if points.len() < 4 {
        return None;
    }
    let mean = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / points.len() as f64;
    let mut normal = Matrix4::zeros();
    let mut rhs = Vector4::zeros();
    for p in points {
        let q = p.coords - mean;
        let row = Vector4::new(2.0 * q.x, 2.0 * q.y, 2.0 * q.z, 1.0);
        normal += row * row.transpose();
        rhs += row * q.norm_squared();
    }
    let solution = normal.lu().solve(&rhs)?;
    let centre = Vector3::new(solution.x, solution.y, solution.z);
    let radius_squared = solution.w + centre.norm_squared();
    if radius_squared.is_nan() || radius_squared <= 0.0 {
        return None;
    }
    let mut sphere =
        Sphere { centre: Point3::from(centre + mean), radius_mm: radius_squared.sqrt() };
    for _ in 0..GAUSS_NEWTON_STEPS {
        let mut jtj = Matrix4::zeros();
        let mut jtr = Vector4::zeros();
        for p in points {
            let d = p - sphere.centre;
            let n = d.norm();
            if n <= 0.0 {
                continue;
            }
            let j = Vector4::new(-d.x / n, -d.y / n, -d.z / n, -1.0);
            let r = n - sphere.radius_mm;
            jtj += j * j.transpose();
            jtr += j * r;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        sphere.centre += Vector3::new(step.x, step.y, step.z);
        sphere.radius_mm += step.w;
        if step.norm() < 1e-9 {
            break;
        }
    }
    (sphere.radius_mm > 0.0 && sphere.centre.coords.iter().all(|c| c.is_finite())).then_some(sphere)
}

/// Gauss-Newton steps after the algebraic fit (it converges in 3-5 on
/// points that cover an arc of a few tens of degrees).
const GAUSS_NEWTON_STEPS: usize = 20;

/// RMS of the geometric distances.
pub fn rms_mm(distances: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = distances.fold((0.0, 0usize), |(s, n), d| (s + d * d, n + 1));
    if n == 0 { f64::INFINITY } else { (sum / n as f64).sqrt() }
}

/// RMS distance of points from their least-squares line (2-D) through the
/// principal axis: how far the points are from straight.
pub fn line_rms_mm(points: &[Point2<f64>]) -> f64 {
    if points.len() < 2 {
        return 0.0;
    }
    let mean = points.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / points.len() as f64;
    let mut scatter = nalgebra::Matrix2::zeros();
    for p in points {
        let q = p.coords - mean;
        scatter += q * q.transpose();
    }
    let smallest = scatter.symmetric_eigenvalues().min().max(0.0);
    (smallest / points.len() as f64).sqrt()
}

/// RMS distance of points from their least-squares plane: how far they are
/// from flat.
pub fn plane_rms_mm(points: &[Point3<f64>]) -> f64 {
    if points.len() < 3 {
        return 0.0;
    }
    let mean = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords) / points.len() as f64;
    let mut scatter = Matrix3::zeros();
    for p in points {
        let q = p.coords - mean;
        scatter += q * q.transpose();
    }
    let smallest = scatter.symmetric_eigenvalues().min().max(0.0);
    (smallest / points.len() as f64).sqrt()
}

/// Circles through 2-D points for [`alacs_model::ransac::ransac_refit`], with a
/// bound on the radius.
pub struct CircleEstimator<'a> {
    /// The points.
    pub points: &'a [Point2<f64>],
    /// Radii outside this range are no hypothesis.
    pub radius_range_mm: (f64, f64),
}

impl Estimator for CircleEstimator<'_> {
    type Model = Circle;

    fn len(&self) -> usize {
        self.points.len()
    }

    fn sample_size(&self) -> usize {
        3
    }

    fn fit_minimal(&self, indices: &[usize]) -> Option<Circle> {
        let [a, b, c] = indices else { return None };
        let circle = circle_through(&self.points[*a], &self.points[*b], &self.points[*c])?;
        let (lo, hi) = self.radius_range_mm;
        (lo..=hi).contains(&circle.radius_mm).then_some(circle)
    }

    fn residual(&self, model: &Circle, index: usize) -> f64 {
        model.distance_mm(&self.points[index])
    }

    fn refit(&self, indices: &[usize]) -> Option<Circle> {
        fit_circle(&indices.iter().map(|&i| self.points[i]).collect::<Vec<_>>())
    }
}

/// Spheres through 3-D points for [`alacs_model::ransac::ransac_refit`], with a
/// bound on the radius.
pub struct SphereEstimator<'a> {
    /// The points.
    pub points: &'a [Point3<f64>],
    /// Radii outside this range are no hypothesis.
    pub radius_range_mm: (f64, f64),
}

impl Estimator for SphereEstimator<'_> {
    type Model = Sphere;

    fn len(&self) -> usize {
        self.points.len()
    }

    fn sample_size(&self) -> usize {
        4
    }

    fn fit_minimal(&self, indices: &[usize]) -> Option<Sphere> {
        let [a, b, c, d] = indices else { return None };
        let p = self.points;
        let sphere = sphere_through([&p[*a], &p[*b], &p[*c], &p[*d]])?;
        let (lo, hi) = self.radius_range_mm;
        (lo..=hi).contains(&sphere.radius_mm).then_some(sphere)
    }

    fn residual(&self, model: &Sphere, index: usize) -> f64 {
        model.distance_mm(&self.points[index])
    }

    fn refit(&self, indices: &[usize]) -> Option<Sphere> {
        fit_sphere(&indices.iter().map(|&i| self.points[i]).collect::<Vec<_>>())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn circles_and_spheres_through_exact_points() {
        let circle = Circle { centre: Point2::new(3.0, -2.0), radius_mm: 40.0 };
        let on = |t: f64| circle.centre + Vector2::new(t.cos(), t.sin()) * circle.radius_mm;
        let c = circle_through(&on(0.1), &on(0.7), &on(1.5)).unwrap();
        assert!((c.centre - circle.centre).norm() < 1e-9 && (c.radius_mm - 40.0).abs() < 1e-9);
        // A 60-degree arc with alternating +-0.1 mm noise.
        let arc: Vec<_> = (0..50)
            .map(|i| {
                let p = on(0.3 + i as f64 * 0.02);
                let noise = if i % 2 == 0 { 0.1 } else { -0.1 };
                p + (p - circle.centre).normalize() * noise
            })
            .collect();
        let fitted = fit_circle(&arc).unwrap();
        assert!((fitted.centre - circle.centre).norm() < 0.5, "{fitted:?}");
        assert!(circle_through(&on(0.0), &on(0.0), &on(1.0)).is_none());

        let sphere = Sphere { centre: Point3::new(10.0, 5.0, 900.0), radius_mm: 38.0 };
        let on = |t: f64, s: f64| {
            sphere.centre
                + Vector3::new(t.cos() * s.sin(), t.sin() * s.sin(), -s.cos()) * sphere.radius_mm
        };
        let s =
            sphere_through([&on(0.1, 0.3), &on(1.7, 0.9), &on(3.0, 0.5), &on(4.4, 1.2)]).unwrap();
        assert!((s.centre - sphere.centre).norm() < 1e-6, "{s:?}");
        // The front cap only, as the camera sees it.
        let cap: Vec<_> =
            (0..200).map(|i| on(i as f64 * 0.37, 0.1 + (i % 13) as f64 * 0.08)).collect();
        let fitted = fit_sphere(&cap).unwrap();
        assert!((fitted.centre - sphere.centre).norm() < 1e-6, "{fitted:?}");
        assert!(plane_rms_mm(&cap) > 2.0);
        assert!(
            line_rms_mm(&[Point2::new(0.0, 0.0), Point2::new(1.0, 1.0), Point2::new(2.0, 2.0)])
                < 1e-9
        );
    }

    /// The tangency residual: zero for a ray that touches, the centre's
    /// distance from the ray less the radius for a sphere.
    #[test]
    fn tangent_rays_touch_spheres_and_ellipsoids() {
        // A sphere: the centre's distance from the ray less the radius.
        let sphere = Ellipsoid {
            centre: Point3::new(30.0, -10.0, 800.0),
            shape: Matrix3::identity() / (40.0 * 40.0),
        };
        let ray = Vector3::new(0.02, 0.01, 1.0).normalize();
        let c = sphere.centre.coords;
        let distance = (c - ray * ray.dot(&c)).norm();
        assert!((sphere.tangency_residual(&ray, 40.0) - (distance - 40.0)).abs() < 1e-9);
        // An ellipsoid of semi-axes 30, 40, 50 on the optical axis: the ray
        // touching it at x = 30 (in the plane y = 0, from the origin) is
        // tangent; a ray through its middle misses touching by the radius.
        let ellipsoid = Ellipsoid {
            centre: Point3::new(0.0, 0.0, 1000.0),
            shape: Matrix3::from_diagonal(
                &Vector3::new(30.0f64, 40.0, 50.0).map(|a| 1.0 / (a * a)),
            ),
        };
        // Tangent from the origin to the ellipse x^2/30^2 + (z - 1000)^2/50^2 = 1:
        // slope x / z = 30 / sqrt(1000^2 - 50^2).
        let tangent =
            Vector3::new(30.0, 0.0, (1000.0f64 * 1000.0 - 50.0 * 50.0).sqrt()).normalize();
        assert!(ellipsoid.tangency_residual(&tangent, 40.0).abs() < 1e-9);
        assert!((ellipsoid.tangency_residual(&Vector3::z(), 40.0) + 40.0).abs() < 1e-9);
    }

    /// The ellipsoid of semi-axes `axes` turned by `rotation` about `centre`.
    fn rotated_ellipsoid(
        centre: Point3<f64>,
        rotation: &nalgebra::Rotation3<f64>,
        axes: &Vector3<f64>,
    ) -> Ellipsoid {
        let shape = rotation.matrix()
            * Matrix3::from_diagonal(&axes.map(|a| 1.0 / (a * a)))
            * rotation.matrix().transpose();
        Ellipsoid { centre, shape }
    }

    /// Points on `truth` (of semi-axes `axes` turned by `rotation`) on an
    /// `n` x `n` grid of polar and azimuth angles, numbered row by row.
    fn surface_grid<'a>(
        truth: &'a Ellipsoid,
        rotation: &'a nalgebra::Rotation3<f64>,
        axes: &'a Vector3<f64>,
        n: usize,
    ) -> impl Iterator<Item = (usize, Point3<f64>)> + 'a {
        (0..n * n).map(move |k| {
            let theta = std::f64::consts::PI * (k / n) as f64 / n as f64;
            let phi = std::f64::consts::TAU * (k % n) as f64 / n as f64;
            let body = Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            (k, truth.centre + rotation * body.component_mul(axes))
        })
    }

    /// An elongated fruit seen from the front only, its silhouette's rays
    /// with a tenth of them edges beside it (a leaf's, 3 mm out): with
    /// the rays the robust ellipsoid finds the centre the front alone
    /// leaves to the roundness prior.
    #[test]
    fn the_silhouettes_rays_fix_the_depth_semi_axis_despite_stray_edges() {
        let rotation = nalgebra::Rotation3::from_euler_angles(0.2, 0.6, -0.4);
        let axes = Vector3::new(43.0, 38.0, 36.0);
        let truth = rotated_ellipsoid(Point3::new(-30.0, 15.0, 900.0), &rotation, &axes);
        let radius = truth.equal_volume_radius_mm();
        // The front: points whose normal faces the camera well (the stripe
        // thins out towards the limb).
        let mut points = Vec::new();
        for (_, p) in surface_grid(&truth, &rotation, &axes, 30) {
            let normal = (truth.shape * (p - truth.centre)).normalize();
            if normal.dot(&(-p.coords).normalize()) > 0.5 {
                points.push(p);
            }
        }
        // The silhouette: for each azimuth, the ray that touches (bisection
        // on the tangency residual, negative through the fruit).
        let sight = truth.centre.coords.normalize();
        let e1 = sight.cross(&Vector3::y()).normalize();
        let e2 = sight.cross(&e1);
        let mut rays = Vec::new();
        for k in 0..120 {
            let phi = std::f64::consts::TAU * k as f64 / 120.0;
            let towards = e1 * phi.cos() + e2 * phi.sin();
            let ray = |t: f64| (sight + towards * t).normalize();
            let (mut lo, mut hi) = (0.0, 0.2);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if truth.tangency_residual(&ray(mid), radius) < 0.0 { lo = mid } else { hi = mid }
            }
            // Every tenth a stray edge 3 mm outside the silhouette.
            let t = if k % 10 == 0 { lo + 3.0 / truth.centre.coords.norm() } else { lo };
            rays.push(ray(t));
        }
        let sphere = fit_sphere(&points).unwrap();
        let start = Ellipsoid::from_sphere(&sphere);
        let rays = Rays { directions: rays, weight: 0.25 };
        let with_rays = fit_ellipsoid_with_rays(&points, &rays, &start, 0.3, 20.0).unwrap();
        let front_only = fit_ellipsoid_robust(&points, &sphere, 0.3, 20.0).unwrap();
        let error = (with_rays.centre - truth.centre).norm();
        let front_error = (front_only.centre - truth.centre).norm();
        assert!(error < 0.5, "with the rays {error:.2} mm, the front only {front_error:.2} mm");
        assert!(front_error > 2.0 * error, "the front only {front_error:.2} mm");
    }

    /// The front of an elongated fruit, as the camera sees it, with a few
    /// stray points 4 mm off: the robust ellipsoid finds the centre, the
    /// sphere does not.
    #[test]
    fn robust_ellipsoid_recovers_an_elongated_fruit_from_its_front() {
        let rotation = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.8);
        let axes = Vector3::new(41.0, 37.5, 39.0);
        let truth = rotated_ellipsoid(Point3::new(20.0, -10.0, 800.0), &rotation, &axes);
        let mut points = Vec::new();
        for (k, p) in surface_grid(&truth, &rotation, &axes, 40) {
            let normal = truth.shape * (p - truth.centre);
            if normal.dot(&(-p.coords)) > 0.0 {
                let stray = if k % 97 == 0 { 4.0 } else { 0.0 };
                points.push(p + normal.normalize() * stray);
            }
        }
        let sphere = fit_sphere(&points).unwrap();
        let robust = fit_ellipsoid_robust(&points, &sphere, 0.15, 20.0).unwrap();
        let sphere_error = (sphere.centre - truth.centre).norm();
        let robust_error = (robust.centre - truth.centre).norm();
        assert!(robust_error < 0.5, "ellipsoid {robust_error:.2} mm, sphere {sphere_error:.2} mm");
        assert!(sphere_error > 2.0 * robust_error, "sphere {sphere_error:.2} mm");
        let volume_radius = robust.equal_volume_radius_mm();
        assert!((volume_radius - axes.product().cbrt()).abs() < 0.5, "{volume_radius}");
    }
}

/// An ellipsoid in the camera frame (mm): the fruit as the simulator and
/// nature make it, a sphere stretched a few per cent along three axes. The
/// points p on it satisfy (p - c)^T A (p - c) = 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid {
    /// Centre c.
    pub centre: Point3<f64>,
    /// The shape matrix A (symmetric positive definite, 1/mm^2).
    pub shape: Matrix3<f64>,
}

impl Ellipsoid {
    /// The sphere as an ellipsoid (A = I / r^2).
    pub fn from_sphere(sphere: &Sphere) -> Self {
        Self {
            centre: sphere.centre,
            shape: Matrix3::identity() / (sphere.radius_mm * sphere.radius_mm),
        }
    }

    /// The semi-axes, ascending, mm (1 / sqrt of A's eigenvalues).
    pub fn semi_axes_mm(&self) -> Vector3<f64> {
        let eigenvalues = self.shape.symmetric_eigenvalues();
        let mut axes: Vec<f64> = eigenvalues.iter().map(|l| 1.0 / l.max(1e-12).sqrt()).collect();
        axes.sort_by(f64::total_cmp);
        Vector3::new(axes[0], axes[1], axes[2])
    }

    /// The equal-volume radius, (a b c)^(1/3) = det(A)^(-1/6).
    pub fn equal_volume_radius_mm(&self) -> f64 {
        self.shape.determinant().max(1e-30).powf(-1.0 / 6.0)
    }

    /// Approximate distance of `p` from the surface: (sqrt((p - c)^T A (p - c)) - 1)
    /// times the equal-volume radius (exact for a sphere).
    pub fn distance_mm(&self, p: &Point3<f64>) -> f64 {
        self.scaled_residual(p, self.equal_volume_radius_mm()).abs()
    }

    /// How far the ray through the camera's centre along unit `direction`
    /// misses touching the ellipsoid, scaled like [`Ellipsoid::distance_mm`]
    /// with `radius_mm`: along the ray x = t r the form (x - c)^T A (x - c)
    /// is least, c^T A c - (r^T A c)^2 / r^T A r, where the ray comes
    /// closest; a tangent ray has it 1. For a sphere this is the centre's
    /// distance from the ray less the radius.
    pub fn tangency_residual(&self, direction: &Vector3<f64>, radius_mm: f64) -> f64 {
        let c = self.centre.coords;
        let ac = self.shape * c;
        let rar = direction.dot(&(self.shape * direction));
        if rar <= 0.0 {
            return f64::NAN;
        }
        let least = c.dot(&ac) - direction.dot(&ac).powi(2) / rar;
        (least.max(0.0).sqrt() - 1.0) * radius_mm
    }

    fn scaled_residual(&self, p: &Point3<f64>, radius_mm: f64) -> f64 {
        let d = p - self.centre;
        ((d.dot(&(self.shape * d))).max(0.0).sqrt() - 1.0) * radius_mm
    }
}

/// Standard deviation of the relative deviation of the semi-axes from
/// their mean in the ellipsoid fit's prior: apples are round to a few per cent.
pub const ELLIPTICITY_PRIOR: f64 = 0.05;

/// The ellipsoid of parameters x = [c (3), ln R, D (5)]:
/// A = exp(-2 ln R) (I + D) with D symmetric and traceless,
/// D = [[d0, d2, d3], [d2, d1, d4], [d3, d4, -d0 - d1]].
fn ellipsoid_of(x: &nalgebra::SVector<f64, 9>) -> Ellipsoid {
    let (d0, d1, d2, d3, d4) = (x[4], x[5], x[6], x[7], x[8]);
    let deviation = Matrix3::new(d0, d2, d3, d2, d1, d4, d3, d4, -d0 - d1);
    Ellipsoid {
        centre: Point3::new(x[0], x[1], x[2]),
        shape: (Matrix3::identity() + deviation) * (-2.0 * x[3]).exp(),
    }
}

/// [`fit_ellipsoid_from`] robust to stray points: iteratively reweighted least
/// squares with Cauchy weights 1 / (1 + (r / c)^2), c = 3 times the robust
/// scatter (1.4826 x the median absolute distance, at least `noise_mm` / 2),
/// from the sphere. A handful of points a few millimetres off the surface
/// (the stripe's ends at the silhouette, a leaf touching the fruit) would
/// otherwise pull an ellipsoid, with its extra freedom, far more than a
/// sphere.
pub fn fit_ellipsoid_robust(
    points: &[Point3<f64>],
    sphere: &Sphere,
    noise_mm: f64,
    prior_weight_points: f64,
) -> Option<Ellipsoid> {
    let start = Ellipsoid::from_sphere(sphere);
    fit_ellipsoid_with_rays(points, &Rays::default(), &start, noise_mm, prior_weight_points)
}

/// Rays from the camera's centre that touch the fruit (its outline in the
/// image, unit vectors in the camera frame), each weighted as `weight`
/// laser points.
#[derive(Debug, Clone, Default)]
pub struct Rays {
    /// The rays' unit directions.
    pub directions: Vec<Vector3<f64>>,
    /// Weight of one ray against one surface point.
    pub weight: f64,
}

/// [`fit_ellipsoid_robust`] from an ellipsoid `start`, with rays that touch
/// the fruit, robust on the rays too (Cauchy weights on their own scale:
/// an edge beside the silhouette is a stray): the outline fixes the
/// fruit's size across the line of sight,
/// and with it the laser's curvature of the front fixes the depth
/// semi-axis that neither sees alone (the front's curvature radius is
/// a^2 / c).
pub fn fit_ellipsoid_with_rays(
    points: &[Point3<f64>],
    rays: &Rays,
    start: &Ellipsoid,
    noise_mm: f64,
    prior_weight_points: f64,
) -> Option<Ellipsoid> {
    let mut ellipsoid = *start;
    for _ in 0..ROBUST_ROUNDS {
        let distances: Vec<f64> = points.iter().map(|p| ellipsoid.distance_mm(p)).collect();
        let mut weights = cauchy_weights(&distances, noise_mm);
        // The rays too, on a scale of their own (a sphere fitted to a fruit's
        // front misses its silhouette by millimetres, every ray alike): an
        // edge of a leaf beside the silhouette is a stray.
        let radius = ellipsoid.equal_volume_radius_mm();
        let misses: Vec<f64> =
            rays.directions.iter().map(|r| ellipsoid.tangency_residual(r, radius).abs()).collect();
        weights.extend(cauchy_weights(&misses, noise_mm));
        ellipsoid =
            fit_weighted(points, Some(&weights), rays, &ellipsoid, noise_mm, prior_weight_points)?;
    }
    Some(ellipsoid)
}

/// Cauchy weights 1 / (1 + (d / c)^2) of absolute residuals `d`, c = 3
/// times their robust scatter (1.4826 x the median, at least `noise_mm` / 2).
fn cauchy_weights(distances: &[f64], noise_mm: f64) -> Vec<f64> {
    let mut sorted = distances.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(noise_mm);
    let c = 3.0 * (1.4826 * median).max(0.5 * noise_mm);
    distances.iter().map(|d| 1.0 / (1.0 + (d / c).powi(2))).collect()
}

/// Reweighting rounds of [`fit_ellipsoid_robust`].
const ROBUST_ROUNDS: usize = 4;

/// Least-squares ellipsoid through surface points, started from `start`:
/// Levenberg-Marquardt over the centre, the size and the traceless
/// deviation D of the shape from a sphere, with a Gaussian prior on D that
/// keeps the semi-axes within a few per cent of each other
/// ([`ELLIPTICITY_PRIOR`]; a semi-axis deviates by about -1/2 of D's
/// eigenvalue), weighted as `prior_weight_points` points of `noise_mm`
/// scatter. The parametrization is smooth through the sphere, where an
/// axes-and-rotation one is not. A camera sees the fruit's front only, so
/// a sphere fitted to a slightly elongated fruit misplaces the centre by
/// the elongation; the ellipsoid takes it up. `None` when the fit fails.
pub fn fit_ellipsoid_from(
    points: &[Point3<f64>],
    start: &Ellipsoid,
    noise_mm: f64,
    prior_weight_points: f64,
) -> Option<Ellipsoid> {
    fit_weighted(points, None, &Rays::default(), start, noise_mm, prior_weight_points)
}

/// The Levenberg-Marquardt core of the ellipsoid fits, with optional
/// weights on the squared residuals: the points' first, then the rays'.
fn fit_weighted(
    points: &[Point3<f64>],
    weights: Option<&[f64]>,
    rays: &Rays,
    start: &Ellipsoid,
    noise_mm: f64,
    prior_weight_points: f64,
) -> Option<Ellipsoid> {
    use nalgebra::{DMatrix, DVector, SVector};
    type Params = SVector<f64, 9>;
    let trace = start.shape.trace();
    if points.len() < 9 || trace.is_nan() || trace <= 0.0 {
        return None;
    }
    let radius = (3.0 / trace).sqrt();
    let deviation = start.shape * (radius * radius) - Matrix3::identity();
    let prior_scale = noise_mm * prior_weight_points.sqrt() / (2.0 * ELLIPTICITY_PRIOR);
    let residuals = |x: &Params| -> DVector<f64> {
        let e = ellipsoid_of(x);
        let n = points.len() + rays.directions.len();
        let mut r = DVector::zeros(n + 6);
        for (i, p) in points.iter().enumerate() {
            let weight = weights.and_then(|w| w.get(i)).map_or(1.0, |w| w.sqrt());
            r[i] = weight * e.scaled_residual(p, radius);
        }
        for (k, direction) in rays.directions.iter().enumerate() {
            let robust = weights.and_then(|w| w.get(points.len() + k)).map_or(1.0, |w| *w);
            let ray_weight = (rays.weight.max(0.0) * robust).sqrt();
            r[points.len() + k] = ray_weight * e.tangency_residual(direction, radius);
        }
        // |D|_F^2 = d0^2 + d1^2 + (d0 + d1)^2 + 2 (d2^2 + d3^2 + d4^2).
        let (d0, d1) = (x[4], x[5]);
        r[n] = prior_scale * d0;
        r[n + 1] = prior_scale * d1;
        r[n + 2] = prior_scale * (d0 + d1);
        for k in 0..3 {
            r[n + 3 + k] = prior_scale * std::f64::consts::SQRT_2 * x[6 + k];
        }
        r
    };
    let mut x = Params::zeros();
    x[0] = start.centre.x;
    x[1] = start.centre.y;
    x[2] = start.centre.z;
    x[3] = radius.ln();
    x[4] = deviation[(0, 0)];
    x[5] = deviation[(1, 1)];
    x[6] = deviation[(0, 1)];
    x[7] = deviation[(0, 2)];
    x[8] = deviation[(1, 2)];
    let mut r = residuals(&x);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-4;
    for _ in 0..100 {
        let mut jacobian = DMatrix::zeros(r.len(), 9);
        for k in 0..9 {
            let step = if k < 3 { 1e-5 * radius } else { 1e-7 };
            let mut forward = x;
            forward[k] += step;
            let mut backward = x;
            backward[k] -= step;
            let column = (residuals(&forward) - residuals(&backward)) / (2.0 * step);
            jacobian.set_column(k, &column);
        }
        let jtj = jacobian.transpose() * &jacobian;
        let jtr = jacobian.transpose() * &r;
        let mut improved = false;
        for _ in 0..12 {
            let mut damped = jtj.clone();
            for k in 0..9 {
                damped[(k, k)] += lambda * (jtj[(k, k)] + 1e-12);
            }
            let Some(delta) = damped.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let candidate = x + Params::from_column_slice(delta.as_slice());
            let r_new = residuals(&candidate);
            let cost_new = r_new.norm_squared();
            if cost_new.is_finite() && cost_new < cost {
                improved = cost - cost_new > 1e-12 * cost.max(1e-12);
                x = candidate;
                r = r_new;
                cost = cost_new;
                lambda = (lambda * 0.3).max(1e-12);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let e = ellipsoid_of(&x);
    let positive = e.shape.symmetric_eigenvalues().iter().all(|l| *l > 0.0);
    (positive && e.centre.coords.iter().all(|c| c.is_finite())).then_some(e)
}
