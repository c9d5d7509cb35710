//! Camera model tests: the shared harness (Jacobians against finite
//! differences, round trips, finite outputs) for every distortion model,
//! parity with OpenCV, undistortion over whole images, and camera.yaml.

// Test helpers outside `#[test]` functions, where clippy.toml's
// allow-*-in-tests does not reach: failing loudly is their job.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use alacs_model::{Camera, Distortion, Error};
use nalgebra::{DMatrix, DVector, Point2, Point3};

use crate::harness::{Differentiable, assert_finite, assert_jacobian, assert_round_trip};

// ---------------------------------------------------------------------------
// Cameras under test
// ---------------------------------------------------------------------------

/// No distortion, fx != fy.
fn pinhole_camera() -> Camera {
    Camera {
        name: "pinhole".into(),
        width_px: 1280,
        height_px: 960,
        fx_px: 1000.0,
        fy_px: 1010.0,
        cx_px: 639.5,
        cy_px: 479.5,
        skew_px: 0.0,
        distortion: Distortion::None,
    }
}

/// Strong barrel distortion on a wide image: the corners lie at undistorted
/// normalized radius ~1.4 (54 deg off-axis), where OpenCV's fixed-point
/// undistortion fails.
fn strong_barrel_camera() -> Camera {
    Camera {
        name: "strong_barrel".into(),
        width_px: 1920,
        height_px: 1080,
        fx_px: 800.0,
        fy_px: 805.0,
        cx_px: 959.5,
        cy_px: 539.5,
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([-0.4, 0.2, 0.001, -0.0005, 0.0]),
    }
}

/// The strong-barrel camera with skew and an off-centre principal point.
fn skewed_strong_barrel_camera() -> Camera {
    Camera {
        name: "skewed".into(),
        skew_px: 2.5,
        cx_px: 940.0,
        cy_px: 560.25,
        ..strong_barrel_camera()
    }
}

/// A fisheye-ish `rational_polynomial` fit like a wide-angle depth camera's:
/// the corners lie ~74 deg off-axis (undistorted radius ~3.5).
fn rational_camera() -> Camera {
    Camera {
        name: "rational".into(),
        width_px: 1024,
        height_px: 768,
        fx_px: 504.0,
        fy_px: 504.0,
        cx_px: 511.5,
        cy_px: 383.5,
        skew_px: 0.0,
        distortion: Distortion::RationalPolynomial([3.3, 2.1, 2e-5, -4e-5, 0.11, 3.65, 3.2, 0.55]),
    }
}

/// Every camera of the harness tests: none / plumb_bob mild and strong /
/// rational_polynomial.
fn all_cameras() -> Vec<Camera> {
    vec![
        pinhole_camera(),
        Camera::blackfly_s_5mp(),
        strong_barrel_camera(),
        skewed_strong_barrel_camera(),
        rational_camera(),
    ]
}

/// Pixels every `step_px` across the image plus the four corner pixels and
/// the four outer corners of the image (-0.5, -0.5) .. (w - 0.5, h - 0.5).
fn image_grid(camera: &Camera, step_px: u32) -> Vec<Point2<f64>> {
    let (w, h) = (f64::from(camera.width_px), f64::from(camera.height_px));
    let mut grid = Vec::new();
    for v in (0..camera.height_px).step_by(step_px as usize) {
        for u in (0..camera.width_px).step_by(step_px as usize) {
            grid.push(Point2::new(f64::from(u), f64::from(v)));
        }
    }
    for (u, v) in [(0.0, 0.0), (w - 1.0, 0.0), (0.0, h - 1.0), (w - 1.0, h - 1.0)] {
        grid.push(Point2::new(u, v));
    }
    for (u, v) in [(-0.5, -0.5), (w - 0.5, -0.5), (-0.5, h - 0.5), (w - 0.5, h - 0.5)] {
        grid.push(Point2::new(u, v));
    }
    grid
}

fn vector2(p: &Point2<f64>) -> DVector<f64> {
    DVector::from_column_slice(&[p.x, p.y])
}

fn point2(x: &DVector<f64>) -> Point2<f64> {
    Point2::new(x[0], x[1])
}

// ---------------------------------------------------------------------------
// The camera's maps as harness `Differentiable`s
// ---------------------------------------------------------------------------

/// The camera's maps with analytic Jacobians.
#[derive(Debug, Clone, Copy)]
enum Map {
    /// Point in the camera frame (mm) -> pixel.
    Project,
    /// Undistorted normalized -> distorted normalized.
    Distort,
    /// Pixel -> undistorted normalized.
    Undistort,
}

/// One of the camera's maps as a harness `Differentiable`.
struct CameraMap(Camera, Map);

impl Differentiable for CameraMap {
    fn name(&self) -> String {
        format!("{}: {}", self.0.name, format!("{:?}", self.1).to_lowercase())
    }
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        let camera = &self.0;
        match self.1 {
            Map::Project => {
                camera.project(&Point3::new(x[0], x[1], x[2])).ok().map(|p| vector2(&p))
            }
            Map::Distort => Some(vector2(&camera.distort(&point2(x)))),
            Map::Undistort => camera.undistort_pixel(&point2(x)).ok().map(|p| vector2(&p)),
        }
    }
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let camera = &self.0;
        Some(match self.1 {
            Map::Project => {
                let jac = camera.project_jacobian(&Point3::new(x[0], x[1], x[2])).ok()?;
                DMatrix::from_column_slice(2, 3, jac.as_slice())
            }
            Map::Distort => {
                DMatrix::from_column_slice(2, 2, camera.distort_jacobian(&point2(x)).as_slice())
            }
            Map::Undistort => {
                let jac = camera.undistort_jacobian(&point2(x)).ok()?;
                DMatrix::from_column_slice(2, 2, jac.as_slice())
            }
        })
    }
}

/// Normalized points of pixels every `step_px` across the image (the
/// Jacobian tests' sample points), by undistortion.
fn normalized_samples(camera: &Camera, step_px: u32) -> Vec<Point2<f64>> {
    image_grid(camera, step_px).iter().map(|p| camera.undistort_pixel(p).unwrap()).collect()
}

// ---------------------------------------------------------------------------
// Harness: Jacobians, finite outputs, round trips
// ---------------------------------------------------------------------------

#[test]
fn project_jacobian_matches_finite_differences() {
    for camera in all_cameras() {
        let map = CameraMap(camera.clone(), Map::Project);
        for normalized in normalized_samples(&camera, 97) {
            for z_mm in [150.0, 600.0, 2500.0] {
                let x =
                    DVector::from_column_slice(&[normalized.x * z_mm, normalized.y * z_mm, z_mm]);
                assert_jacobian(&map, &x, 1e-6);
            }
        }
    }
}

/// A distortion as a map of its own coefficients at a fixed point: what a
/// camera calibration differentiates.
struct DistortionOfCoefficients(Distortion, Point2<f64>);

impl DistortionOfCoefficients {
    fn with(&self, x: &DVector<f64>) -> Distortion {
        let mut distortion = self.0;
        distortion.coefficients_mut().copy_from_slice(x.as_slice());
        distortion
    }
}

impl Differentiable for DistortionOfCoefficients {
    fn name(&self) -> String {
        format!("distortion coefficients {:?} at {}", self.0, self.1)
    }
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        let camera = Camera { distortion: self.with(x), ..pinhole_camera() };
        Some(vector2(&camera.distort(&self.1)))
    }
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let columns = self.with(x).coefficient_jacobian(&self.1);
        Some(DMatrix::from_fn(2, columns.len(), |r, c| columns[c][r]))
    }
}

#[test]
fn distortion_coefficient_jacobian_matches_finite_differences() {
    let rational =
        Distortion::RationalPolynomial([-0.3, 0.1, 1e-3, -5e-4, -0.02, 0.05, -0.01, 0.002]);
    for distortion in [strong_barrel_camera().distortion, rational] {
        let x = DVector::from_column_slice(distortion.coefficients());
        for normalized in [Point2::new(0.1, -0.2), Point2::new(-0.6, 0.45), Point2::new(0.9, 0.7)] {
            let map = DistortionOfCoefficients(distortion, normalized);
            assert_finite(&map, &x);
            assert_jacobian(&map, &x, 1e-7);
        }
    }
}

#[test]
fn distort_jacobian_matches_finite_differences() {
    for camera in all_cameras() {
        let map = CameraMap(camera.clone(), Map::Distort);
        for normalized in normalized_samples(&camera, 61) {
            assert_jacobian(&map, &vector2(&normalized), 1e-7);
        }
    }
}

#[test]
fn undistort_jacobian_matches_finite_differences() {
    for camera in all_cameras() {
        let map = CameraMap(camera.clone(), Map::Undistort);
        // The outermost corners are left out: central differences need the
        // pixel +- h to be undistortable too (it is, but h steps outside).
        for pixel in image_grid(&camera, 61).iter().filter(|p| p.x >= 0.0 && p.y >= 0.0) {
            assert_jacobian(&map, &vector2(pixel), 1e-6);
        }
    }
}

#[test]
fn outputs_are_finite_across_the_image() {
    for camera in all_cameras() {
        for pixel in image_grid(&camera, 32) {
            assert_finite(&CameraMap(camera.clone(), Map::Undistort), &vector2(&pixel));
            let normalized = camera.undistort_pixel(&pixel).unwrap();
            assert_finite(&CameraMap(camera.clone(), Map::Distort), &vector2(&normalized));
            let point =
                DVector::from_column_slice(&[normalized.x * 500.0, normalized.y * 500.0, 500.0]);
            assert_finite(&CameraMap(camera.clone(), Map::Project), &point);
        }
    }
}

/// project(z * undistort(p)) == p within 1e-6 px at every 16th pixel and all
/// corners, for every model including strong barrel and rational.
#[test]
fn project_of_undistort_is_identity_over_the_whole_image() {
    for camera in all_cameras() {
        let name = format!("{}: pixel -> point -> pixel", camera.name);
        for pixel in image_grid(&camera, 16) {
            assert_round_trip(
                &name,
                |p| {
                    let ray = camera.pixel_ray(&point2(p)).ok()?;
                    Some(DVector::from_column_slice((ray * 750.0).as_slice()))
                },
                |x| camera.project(&Point3::new(x[0], x[1], x[2])).ok().map(|p| vector2(&p)),
                &vector2(&pixel),
                1e-6,
            );
        }
    }
}

/// undistort(normalized_to_pixel(n)) == n within 1e-9 on a normalized grid
/// spanning the image (points whose pixel falls outside are skipped).
#[test]
fn undistort_of_normalized_to_pixel_is_identity() {
    for camera in all_cameras() {
        let name = format!("{}: normalized -> pixel -> normalized", camera.name);
        let corners = [
            Point2::new(-0.5, -0.5),
            Point2::new(f64::from(camera.width_px) - 0.5, f64::from(camera.height_px) - 0.5),
        ]
        .map(|p| camera.undistort_pixel(&p).unwrap());
        let mut checked = 0;
        for i in 0..=40 {
            for j in 0..=40 {
                let t = (f64::from(i) / 40.0, f64::from(j) / 40.0);
                let normalized = Point2::new(
                    corners[0].x + t.0 * (corners[1].x - corners[0].x),
                    corners[0].y + t.1 * (corners[1].y - corners[0].y),
                );
                if !camera.contains_pixel(&camera.normalized_to_pixel(&normalized)) {
                    continue;
                }
                checked += 1;
                assert_round_trip(
                    &name,
                    |n| Some(vector2(&camera.normalized_to_pixel(&point2(n)))),
                    |p| camera.undistort_pixel(&point2(p)).ok().map(|n| vector2(&n)),
                    &vector2(&normalized),
                    1e-9,
                );
            }
        }
        assert!(checked > 500, "{name}: only {checked} grid points inside the image");
    }
}

// ---------------------------------------------------------------------------
// Parity with OpenCV
// ---------------------------------------------------------------------------

/// Golden pixels from OpenCV 4.10.0 (opencv-python-headless, float64):
/// `cv2.projectPoints(points, rvec=0, tvec=0, K, dist)` with K = [[fx, 0, cx],
/// [0, fy, cy], [0, 0, 1]] and the cameras' coefficients; `repr()` of the
/// results. OpenCV 5.0.0 gives the same numbers.
#[test]
fn project_matches_opencv_project_points() {
    let points = [
        Point3::new(100.0, -200.0, 1000.0),
        Point3::new(-450.0, 320.0, 700.0),
        Point3::new(900.0, 650.0, 800.0),
        Point3::new(-2500.0, -1800.0, 800.0),
    ];
    let golden: [(Camera, [[f64; 2]; 4]); 3] = [
        (
            Camera::blackfly_s_5mp(),
            [
                [1454.61608, 561.25624],
                [-263.4540580900816, 2080.931256655441],
                [4592.330956787109, 3457.314036499023],
                [-188720.65955859376, -135730.3778671875],
            ],
        ),
        (
            strong_barrel_camera(),
            [
                [1037.88, 381.76025],
                [532.3441113821622, 845.4765760141606],
                [1833.4524536132812, 1176.7428752517699],
                [-96651.51425781252, -70163.44599853517],
            ],
        ),
        (
            rational_camera(),
            [
                [561.0386199512292, 284.4212480975416],
                [239.7841420015224, 576.7175174135206],
                [890.5139134798517, 657.2797220965596],
                [-26.19211471936751, -3.273621897944622],
            ],
        ),
    ];
    for (camera, pixels) in golden {
        for (point, expected) in points.iter().zip(pixels) {
            let pixel = camera.project(point).unwrap();
            for (got, want) in [(pixel.x, expected[0]), (pixel.y, expected[1])] {
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "{}: project({point}) = {pixel}, OpenCV {expected:?}",
                    camera.name
                );
            }
        }
    }
}

/// Golden values from OpenCV 4.10.0: `cv2.undistortPointsIter(pixels, K,
/// dist, None, None, (COUNT | EPS, 1000, 1e-16))` for the mild Blackfly
/// distortion, where OpenCV's fixed-point iteration converges.
#[test]
fn undistort_matches_opencv_where_opencv_converges() {
    let camera = Camera::blackfly_s_5mp();
    let golden = [
        ((0.0, 0.0), (-0.5329879068475532, -0.44595243757298914)),
        ((1523.5, 823.5), (0.1295605357184942, -0.08637450024378063)),
    ];
    for ((u, v), (x, y)) in golden {
        let normalized = camera.undistort_pixel(&Point2::new(u, v)).unwrap();
        assert!(
            (normalized.x - x).abs() < 1e-12 && (normalized.y - y).abs() < 1e-12,
            "{normalized}"
        );
    }
}

/// At the top-left corner of the strong-barrel image OpenCV's fixed-point
/// undistortion returns wrong points (`cv2.undistortPoints`: (-1.3731,
/// -0.7696); `cv2.undistortPointsIter` with 1000 iterations: (-0.7871,
/// -0.4423); neither projects back to the pixel). Newton finds the point that
/// does.
#[test]
fn undistort_succeeds_where_opencv_fixed_point_fails() {
    let camera = strong_barrel_camera();
    let pixel = Point2::new(0.0, 0.0);
    let normalized = camera.undistort_pixel(&pixel).unwrap();
    assert!((camera.normalized_to_pixel(&normalized) - pixel).norm() < 1e-9);
    for opencv in [
        Point2::new(-1.373108069369926, -0.7696161355261885),
        Point2::new(-0.7871384651017186, -0.4422747323743049),
    ] {
        assert!((camera.normalized_to_pixel(&opencv) - pixel).norm() > 10.0);
        assert!((normalized - opencv).norm() > 0.1);
    }
}

/// The distortion formulas by hand at one point: x = 0.3, y = -0.2, r2 = 0.13.
#[test]
fn distort_matches_the_formula_by_hand() {
    let camera = Camera {
        distortion: Distortion::RationalPolynomial([
            0.1, -0.05, 0.002, -0.003, 0.01, 0.2, 0.03, 0.004,
        ]),
        ..pinhole_camera()
    };
    let (x, y, r2): (f64, f64, f64) = (0.3, -0.2, 0.13);
    let radial = (1.0 + 0.1 * r2 - 0.05 * r2.powi(2) + 0.01 * r2.powi(3))
        / (1.0 + 0.2 * r2 + 0.03 * r2.powi(2) + 0.004 * r2.powi(3));
    let xd = x * radial + 2.0 * 0.002 * x * y - 0.003 * (r2 + 2.0 * x * x);
    let yd = y * radial + 0.002 * (r2 + 2.0 * y * y) + 2.0 * -0.003 * x * y;
    let distorted = camera.distort(&Point2::new(x, y));
    assert!((distorted.x - xd).abs() < 1e-15 && (distorted.y - yd).abs() < 1e-15);
    let pixel = camera.normalized_to_pixel(&Point2::new(x, y));
    assert!((pixel.x - (1000.0 * xd + 639.5)).abs() < 1e-12);
    assert!((pixel.y - (1010.0 * yd + 479.5)).abs() < 1e-12);
}

// ---------------------------------------------------------------------------
// Undistortion: failures are reported, never garbage
// ---------------------------------------------------------------------------

/// k1 = -0.4 alone folds over at undistorted radius 0.913 (distorted radius
/// 0.609); the image corners (distorted radius 1.10) lie beyond the fold.
fn folding_camera() -> Camera {
    Camera {
        name: "folding".into(),
        width_px: 1920,
        height_px: 1080,
        fx_px: 1000.0,
        fy_px: 1000.0,
        cx_px: 959.5,
        cy_px: 539.5,
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([-0.4, 0.0, 0.0, 0.0, 0.0]),
    }
}

#[test]
fn undistort_reports_pixels_beyond_a_fold() {
    let camera = folding_camera();
    // Distorted radius 0.5 is inside the fold: fine.
    let inside = Point2::new(959.5 + 500.0, 539.5);
    let normalized = camera.undistort_pixel(&inside).unwrap();
    assert!((camera.normalized_to_pixel(&normalized) - inside).norm() < 1e-9);
    assert!(normalized.x < 0.913);
    // Distorted radius 0.7 and the corner: no point inside the fold maps there.
    for pixel in
        [Point2::new(959.5 + 700.0, 539.5), Point2::new(0.0, 0.0), Point2::new(1919.0, 1079.0)]
    {
        match camera.undistort_pixel(&pixel) {
            Err(Error::UndistortNotConverged { u_px, v_px, residual, .. }) => {
                assert_eq!((u_px, v_px), (pixel.x, pixel.y));
                assert!(residual > 1e-12 || residual.is_nan(), "residual {residual}");
            }
            other => panic!("pixel {pixel}: expected UndistortNotConverged, got {other:?}"),
        }
        assert!(camera.pixel_ray(&pixel).is_err());
        assert!(camera.undistort_jacobian(&pixel).is_err());
    }
}

/// A point beyond the fold projects (OpenCV's formulas) onto a pixel that
/// belongs to a point inside it; undistortion returns the latter, and
/// `is_distortion_invertible_at` tells the two apart.
#[test]
fn points_beyond_a_fold_are_recognised() {
    let camera = folding_camera();
    let beyond = Point2::new(1.2, 0.0);
    assert!(!camera.is_distortion_invertible_at(&beyond));
    assert!(camera.is_distortion_invertible_at(&Point2::new(0.9, 0.0)));
    let pixel = camera.normalized_to_pixel(&beyond); // distorted radius 0.5088
    let normalized = camera.undistort_pixel(&pixel).unwrap();
    assert!(normalized.x < 0.913, "{normalized}");
    assert!((camera.normalized_to_pixel(&normalized) - pixel).norm() < 1e-9);
    for camera in all_cameras() {
        for pixel in image_grid(&camera, 128) {
            let normalized = camera.undistort_pixel(&pixel).unwrap();
            assert!(camera.is_distortion_invertible_at(&normalized), "{}: {pixel}", camera.name);
        }
    }
}

#[test]
fn non_finite_pixels_are_errors() {
    for camera in all_cameras() {
        for pixel in [
            Point2::new(f64::NAN, 10.0),
            Point2::new(10.0, f64::INFINITY),
            Point2::new(f64::NEG_INFINITY, f64::NAN),
        ] {
            assert!(matches!(
                camera.undistort_pixel(&pixel),
                Err(Error::UndistortNotConverged { .. })
            ));
            assert!(camera.pixel_ray(&pixel).is_err());
            assert!(camera.undistort_jacobian(&pixel).is_err());
        }
    }
}

#[test]
fn project_rejects_points_behind_the_camera_or_not_finite() {
    let camera = Camera::blackfly_s_5mp();
    for point in [
        Point3::new(10.0, 20.0, 0.0),
        Point3::new(10.0, 20.0, -100.0),
        Point3::new(f64::NAN, 20.0, 100.0),
        Point3::new(10.0, f64::INFINITY, 100.0),
    ] {
        assert!(matches!(camera.project(&point), Err(Error::NotProjectable { .. })), "{point}");
        assert!(camera.project_jacobian(&point).is_err());
    }
}

#[test]
fn pinhole_undistort_is_the_inverse_intrinsic_matrix() {
    let camera = Camera { skew_px: 1.5, ..pinhole_camera() };
    let pixel = Point2::new(100.0, 900.0);
    let normalized = camera.undistort_pixel(&pixel).unwrap();
    let y = (900.0 - 479.5) / 1010.0;
    let x = (100.0 - 639.5 - 1.5 * y) / 1000.0;
    assert_eq!(normalized, Point2::new(x, y));
    assert_eq!(camera.pixel_ray(&pixel).unwrap(), nalgebra::Vector3::new(x, y, 1.0));
}

// ---------------------------------------------------------------------------
// Construction, validation, scaling, image bounds
// ---------------------------------------------------------------------------

#[test]
fn blackfly_is_the_documented_camera() {
    let camera = Camera::blackfly_s_5mp();
    assert_eq!((camera.width_px, camera.height_px), (2448, 2048));
    assert_eq!((camera.fx_px, camera.fy_px, camera.skew_px), (2320.0, 2320.0, 0.0));
    assert_eq!((camera.cx_px, camera.cy_px), (1223.5, 1023.5));
    assert!(matches!(camera.distortion, Distortion::PlumbBob([k1, ..]) if k1 < 0.0));
    camera.validate().unwrap();
    // The optical axis hits the image centre.
    assert_eq!(camera.project(&Point3::new(0.0, 0.0, 1.0)).unwrap(), Point2::new(1223.5, 1023.5));
}

#[test]
fn validate_rejects_unusable_parameters() {
    for camera in all_cameras() {
        camera.validate().unwrap();
    }
    let good = Camera::blackfly_s_5mp();
    let bad = [
        Camera { fx_px: 0.0, ..good.clone() },
        Camera { fy_px: -1.0, ..good.clone() },
        Camera { cx_px: f64::NAN, ..good.clone() },
        Camera { skew_px: f64::INFINITY, ..good.clone() },
        Camera { width_px: 0, ..good.clone() },
        Camera { height_px: 0, ..good.clone() },
        Camera { distortion: Distortion::PlumbBob([f64::NAN, 0.0, 0.0, 0.0, 0.0]), ..good.clone() },
    ];
    for camera in bad {
        assert!(
            matches!(camera.validate(), Err(Error::InvalidParameters { what: "camera", .. })),
            "{camera:?}"
        );
    }
}

#[test]
fn scaled_keeps_the_pixel_centre_convention() {
    for camera in all_cameras() {
        for scale in [0.5, 0.25, 2.0] {
            let small = camera.scaled(scale);
            small.validate().unwrap();
            assert_eq!(small.width_px, (f64::from(camera.width_px) * scale).round() as u32);
            assert_eq!(small.distortion, camera.distortion);
            for point in [Point3::new(30.0, -20.0, 500.0), Point3::new(-80.0, 60.0, 400.0)] {
                let pixel = camera.project(&point).unwrap();
                let expected = (pixel.coords.add_scalar(0.5) * scale).add_scalar(-0.5);
                assert!((small.project(&point).unwrap().coords - expected).norm() < 1e-9);
            }
        }
    }
    // The Blackfly's centred principal point stays centred.
    let half = Camera::blackfly_s_5mp().scaled(0.5);
    assert_eq!((half.width_px, half.height_px, half.cx_px, half.cy_px), (1224, 1024, 611.5, 511.5));
    assert!(Camera::blackfly_s_5mp().scaled(0.0).validate().is_err());
    assert!(Camera::blackfly_s_5mp().scaled(f64::NAN).validate().is_err());
}

#[test]
fn contains_pixel_uses_pixel_edges() {
    let camera = pinhole_camera();
    for (u, v, inside) in [
        (-0.5, -0.5, true),
        (1279.5, 959.5, true),
        (0.0, 0.0, true),
        (-0.51, 10.0, false),
        (10.0, 959.51, false),
        (1279.6, 10.0, false),
        (f64::NAN, 10.0, false),
    ] {
        assert_eq!(camera.contains_pixel(&Point2::new(u, v)), inside, "({u}, {v})");
    }
}

// ---------------------------------------------------------------------------
// camera.yaml
// ---------------------------------------------------------------------------

/// A unique scratch path for this test process.
fn scratch_path(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("alacs-model-camera-{}-{name}", std::process::id()))
}

#[test]
fn yaml_round_trip_is_exact() {
    let awkward_name = Camera { name: "left: \"cam\" #1".into(), ..rational_camera() };
    let odd_values = Camera {
        name: "yes".into(),
        fx_px: 1234.5678901234567,
        cx_px: 1e-7,
        skew_px: -3.25e-9,
        distortion: Distortion::PlumbBob([9.5e3, -2.5e-17, 0.1, 1.0 / 3.0, -0.0]),
        ..strong_barrel_camera()
    };
    for camera in all_cameras().into_iter().chain([awkward_name, odd_values]) {
        let text = camera.to_yaml_string();
        let back = Camera::from_yaml_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back, camera, "\n{text}");
    }
    // Files, too.
    let path = scratch_path("round-trip.yaml");
    let camera = skewed_strong_barrel_camera();
    camera.to_yaml_file(&path).unwrap();
    assert_eq!(Camera::from_yaml_file(&path).unwrap(), camera);
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn written_yaml_has_every_ros_key() {
    let text = Camera::blackfly_s_5mp().to_yaml_string();
    let expected = "\
image_width: 2448
image_height: 2048
camera_name: blackfly_s_5mp
camera_matrix:
  rows: 3
  cols: 3
  data: [2320.0, 0.0, 1223.5, 0.0, 2320.0, 1023.5, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.08, 0.12, 0.0001, -0.0001, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [2320.0, 0.0, 1223.5, 0.0, 0.0, 2320.0, 1023.5, 0.0, 0.0, 0.0, 1.0, 0.0]
";
    assert_eq!(text, expected);
    // Exponents carry a '.' and a sign, so YAML 1.1 readers (PyYAML) see floats.
    let tiny = Camera {
        distortion: Distortion::PlumbBob([1e-7, 2e20, 0.0, 0.0, 0.0]),
        ..pinhole_camera()
    };
    assert!(tiny.to_yaml_string().contains("data: [1.0e-7, 2.0e+20, 0.0, 0.0, 0.0]"));
    // No distortion is written as ROS writes it, and read back as none.
    let text = pinhole_camera().to_yaml_string();
    assert!(text.contains("distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0.0, 0.0, 0.0, 0.0, 0.0]"));
}

/// The layout ROS `camera_calibration` writes (ost.yaml): padded numbers
/// such as `0.     `, and a projection matrix for the rectified image that
/// differs from the camera matrix (it must be ignored).
#[test]
fn reads_a_ros_calibration_file() {
    let text = "\
image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [423.85420,   0.     , 319.33760,
           0.     , 425.60394, 242.44457,
           0.     ,   0.     ,   1.     ]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.009236, 0.011853, -0.001156, -0.000567, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1., 0., 0.,
         0., 1., 0.,
         0., 0., 1.]
projection_matrix:
  rows: 3
  cols: 4
  data: [421.00000,   0.     , 318.00000,   0.     ,
           0.     , 424.00000, 241.00000,   0.     ,
           0.     ,   0.     ,   1.     ,   0.     ]
";
    let camera = Camera::from_yaml_str(text).unwrap();
    let expected = Camera {
        name: "narrow_stereo".into(),
        width_px: 640,
        height_px: 480,
        fx_px: 423.8542,
        fy_px: 425.60394,
        cx_px: 319.3376,
        cy_px: 242.44457,
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([-0.009236, 0.011853, -0.001156, -0.000567, 0.0]),
    };
    assert_eq!(camera, expected);
}

/// What OpenCV's calibration sample (`samples/cpp/calibration.cpp`,
/// `cv::FileStorage`) writes: a `%YAML:1.0` directive, `!!opencv-matrix`
/// tags, a 5 x 1 coefficient matrix, no `distortion_model`, no camera name,
/// extra keys.
#[test]
#[allow(clippy::excessive_precision)] // the file's 17 significant digits, verbatim
fn reads_an_opencv_filestorage_file() {
    let text = "\
%YAML:1.0
---
calibration_time: \"Mon 01 Jan 2024 12:00:00 PM UTC\"
nframes: 25
image_width: 1280
image_height: 720
board_width: 9
board_height: 6
square_size: 25.
flags: 0
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 9.1234567890123457e+02, 0., 6.4012345678901235e+02, 0.,
       9.1876543210987656e+02, 3.6045678901234567e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 1.2345678901234567e-01, -2.3456789012345678e-01,
       1.0000000000000000e-03, -2.0000000000000000e-03,
       8.7654321098765432e-02 ]
avg_reprojection_error: 2.3456789012345678e-01
image_points: !!opencv-nd-matrix
   sizes: [ 2, 1 ]
   dt: \"2f\"
   data: [ 1., 2., 3., 4. ]
";
    let camera = Camera::from_yaml_str(text).unwrap();
    let expected = Camera {
        name: "camera".into(),
        width_px: 1280,
        height_px: 720,
        fx_px: 912.34567890123457,
        fy_px: 918.76543210987656,
        cx_px: 640.12345678901235,
        cy_px: 360.45678901234567,
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([
            0.12345678901234567,
            -0.23456789012345678,
            0.001,
            -0.002,
            0.087654321098765432,
        ]),
    };
    assert_eq!(camera, expected);
}

/// A minimal file: no name, no rectification or projection matrix,
/// `rows`/`cols` omitted for the coefficients.
fn minimal_yaml(distortion: &str) -> String {
    format!(
        "image_width: 800\nimage_height: 600\n\
         camera_matrix: {{rows: 3, cols: 3, data: [500, 0, 399.5, 0, 500, 299.5, 0, 0, 1]}}\n\
         {distortion}\n"
    )
}

#[test]
fn reads_lenient_files() {
    let read = |distortion: &str| Camera::from_yaml_str(&minimal_yaml(distortion)).unwrap();
    let camera = read(
        "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 4, data: [0.1, -0.2, 0.001, 0.002]}",
    );
    assert_eq!(camera.name, "camera");
    assert_eq!((camera.fx_px, camera.cx_px, camera.cy_px), (500.0, 399.5, 299.5));
    assert_eq!(camera.distortion, Distortion::PlumbBob([0.1, -0.2, 0.001, 0.002, 0.0]));
    // No distortion_model: inferred from the number of coefficients.
    let camera = read("distortion_coefficients: {data: [0.1, -0.2, 0.001, 0.002]}");
    assert_eq!(camera.distortion, Distortion::PlumbBob([0.1, -0.2, 0.001, 0.002, 0.0]));
    let camera =
        read("distortion_coefficients: {rows: 1, cols: 5, data: [0.1, -0.2, 0.001, 0.002, 0.01]}");
    assert_eq!(camera.distortion, Distortion::PlumbBob([0.1, -0.2, 0.001, 0.002, 0.01]));
    let camera =
        read("distortion_coefficients: {rows: 8, cols: 1, data: [1, 2, 3, 4, 5, 6, 7, 8]}");
    assert_eq!(
        camera.distortion,
        Distortion::RationalPolynomial([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    );
    let camera = read(
        "distortion_model: rational_polynomial\ndistortion_coefficients: {rows: 1, cols: 8, data: [1, 2, 3, 4, 5, 6, 7, 8]}",
    );
    assert_eq!(
        camera.distortion,
        Distortion::RationalPolynomial([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    );
    // All zeros, or none at all: no distortion.
    let camera = read(
        "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}",
    );
    assert_eq!(camera.distortion, Distortion::None);
    let camera =
        read("distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 0, data: []}");
    assert_eq!(camera.distortion, Distortion::None);
}

/// Reads a file that must fail and returns the message, which must name `key`.
fn parse_error_naming(text: &str, key: &str) -> String {
    match Camera::from_yaml_str(text) {
        Err(Error::Parse { path, message }) => {
            assert_eq!(path, PathBuf::from("<string>"));
            assert!(message.contains(key), "message {message:?} does not name {key:?}");
            message
        }
        other => panic!("expected a parse error naming {key}, got {other:?}\n{text}"),
    }
}

#[test]
fn bad_files_are_errors_that_name_the_key() {
    let plumb_bob = "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [0.1, 0, 0, 0, 0]}";
    let good = minimal_yaml(plumb_bob);
    Camera::from_yaml_str(&good).unwrap();

    // Missing keys.
    parse_error_naming(&good.replace("camera_matrix", "kamera_matrix"), "camera_matrix");
    parse_error_naming(&good.replace("image_width: 800\n", ""), "image_width");
    parse_error_naming(&minimal_yaml("distortion_model: plumb_bob"), "distortion_coefficients");
    // Bad values.
    parse_error_naming(&good.replace("500, 0, 399.5", ".nan, 0, 399.5"), "camera_matrix");
    parse_error_naming(&good.replace("[0.1, 0,", "[.inf, 0,"), "distortion_coefficients");
    parse_error_naming(&good.replace("500, 0, 399.5", "-500, 0, 399.5"), "camera_matrix");
    parse_error_naming(&good.replace("0, 0, 1]", "0, 0, 2]"), "camera_matrix");
    parse_error_naming(&good.replace("image_width: 800", "image_width: 0"), "image_width");
    // Shapes.
    let message =
        parse_error_naming(&good.replace("rows: 3, cols: 3", "rows: 3, cols: 4"), "camera_matrix");
    assert!(message.contains("rows 3 x cols 4"), "{message}");
    parse_error_naming(&good.replace("rows: 3, cols: 3", "rows: 1, cols: 9"), "camera_matrix");
    parse_error_naming(&good.replace("cols: 5", "cols: 6"), "distortion_coefficients");
    parse_error_naming(
        &minimal_yaml(
            "distortion_model: plumb_bob\ndistortion_coefficients: {data: [1, 2, 3, 4, 5, 6, 7, 8]}",
        ),
        "distortion_coefficients",
    );
    parse_error_naming(
        &minimal_yaml(
            "distortion_model: rational_polynomial\ndistortion_coefficients: {data: [1, 2, 3, 4, 5]}",
        ),
        "distortion_coefficients",
    );
    parse_error_naming(
        &minimal_yaml("distortion_coefficients: {data: [1, 2, 3]}"),
        "distortion_model",
    );
    parse_error_naming(
        &(good.clone() + "projection_matrix: {rows: 3, cols: 4, data: [1, 2, 3]}\n"),
        "projection_matrix",
    );
    // Unsupported models.
    for model in ["equidistant", "fisheye"] {
        let message = parse_error_naming(
            &minimal_yaml(&format!(
                "distortion_model: {model}\ndistortion_coefficients: {{data: [0.1, 0.01, 0, 0]}}"
            )),
            "distortion_model",
        );
        assert!(message.contains(model) && message.contains("not supported"), "{message}");
    }
    // Not YAML, or not a mapping.
    for text in ["camera_matrix: [1, 2", "image_width: -5\n", "image_width: wide\n"] {
        match Camera::from_yaml_str(text) {
            // One line naming the position, for a one-line CLI error.
            Err(Error::Parse { message, .. }) => {
                assert!(message.contains("line 1") && !message.contains('\n'), "{message:?}");
            }
            other => panic!("expected a parse error, got {other:?}"),
        }
    }
    assert!(matches!(Camera::from_yaml_str("- 1\n- 2\n"), Err(Error::Parse { .. })));
    assert!(matches!(Camera::from_yaml_str(""), Err(Error::Parse { .. })));
}

#[test]
fn file_errors_name_the_path() {
    let missing = scratch_path("does-not-exist.yaml");
    match Camera::from_yaml_file(&missing) {
        Err(Error::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected Io, got {other:?}"),
    }
    let bad = scratch_path("bad.yaml");
    std::fs::write(&bad, "image_width: 10\n").unwrap();
    let result = Camera::from_yaml_file(&bad);
    std::fs::remove_file(&bad).unwrap();
    match result {
        Err(error @ Error::Parse { .. }) => {
            let message = error.to_string();
            assert!(
                message.contains(&bad.display().to_string()) && message.contains("image_height"),
                "{message}"
            );
        }
        other => panic!("expected Parse, got {other:?}"),
    }
    let unwritable = scratch_path("no-such-dir").join("camera.yaml");
    assert!(matches!(Camera::blackfly_s_5mp().to_yaml_file(&unwritable), Err(Error::Io { .. })));
}

/// serde gives camera.yaml's keys, so truth.json can hold the camera as JSON.
#[test]
fn json_has_the_camera_yaml_keys() {
    let camera = rational_camera();
    let json = serde_json::to_value(&camera).unwrap();
    assert_eq!(json["image_width"], 1024);
    assert_eq!(json["distortion_model"], "rational_polynomial");
    assert_eq!(json["camera_matrix"]["data"][0], 504.0);
    assert_eq!(json["projection_matrix"]["cols"], 4);
    let back: Camera = serde_json::from_value(json).unwrap();
    assert_eq!(back, camera);
}

#[test]
fn absurd_distortion_coefficients_in_camera_yaml_are_refused_naming_the_key() {
    // Regression: `data: [1e308, ...]` was read, and triangulate then
    // printed "undistortion did not converge" per pixel with exit 0.
    for data in ["[1e308, 0, 0, 0, 0]", "[0, 0, 0, 0, -2e4]"] {
        let text = minimal_yaml(&format!("distortion_coefficients: {{data: {data}}}"));
        let message = Camera::from_yaml_str(&text).unwrap_err().to_string();
        assert!(
            message.contains("distortion_coefficients") && message.contains("beyond"),
            "{message}"
        );
    }
    let text = minimal_yaml("distortion_coefficients: {data: [0.1, 0, 0, 0, 9000]}");
    assert!(Camera::from_yaml_str(&text).is_ok(), "large but possible coefficients are read");
}

#[test]
fn the_opencv_layout_reads_back_as_the_same_camera() {
    let base = Camera::blackfly_s_5mp();
    let cameras = [
        Camera { name: "rig left".into(), ..base.clone() },
        Camera { distortion: Distortion::None, ..base.clone() },
        Camera {
            distortion: Distortion::RationalPolynomial([
                0.1, -0.2, 1e-3, -2e-3, 0.05, 0.01, -0.02, 0.003,
            ]),
            skew_px: 0.25,
            ..base
        },
    ];
    for camera in cameras {
        let text = camera.to_opencv_yaml_string();
        assert!(text.starts_with("%YAML:1.0\n---\n"), "{text}");
        assert!(
            text.contains("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n")
        );
        assert!(text.contains("distortion_coefficients: !!opencv-matrix\n"), "{text}");
        let back = Camera::from_yaml_str(&text).unwrap();
        let expected = match camera.distortion {
            d if d.is_identity() => Camera { distortion: Distortion::None, ..camera.clone() },
            _ => camera.clone(),
        };
        assert_eq!(back, expected, "{text}");
    }
}

#[test]
fn opencv_and_ros_key_names_are_read() {
    let expected = Camera::from_yaml_str(
        "image_width: 640\nimage_height: 480\n\
         camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 510, 240, 0, 0, 1]}\n\
         distortion_coefficients: {rows: 1, cols: 5, data: [0.1, -0.2, 0.001, 0.002, 0.03]}\n",
    )
    .unwrap();
    let k = "[500, 0, 320, 0, 510, 240, 0, 0, 1]";
    let d = "[0.1, -0.2, 0.001, 0.002, 0.03]";
    for text in [
        // OpenCV's usual names (calibrateCamera's outputs).
        format!(
            "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n\
             cameraMatrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: {k}\n\
             distCoeffs: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: {d}\n"
        ),
        format!("image_width: 640\nimage_height: 480\nK: {{data: {k}}}\nD: {{data: {d}}}\n"),
        // A ROS 2 CameraInfo message as `ros2 topic echo` prints it.
        format!(
            "header:\n  frame_id: camera\nheight: 480\nwidth: 640\n\
             distortion_model: plumb_bob\nd: {d}\nk: {k}\n\
             r: [1, 0, 0, 0, 1, 0, 0, 0, 1]\np: [500, 0, 320, 0, 0, 510, 240, 0, 0, 0, 1, 0]\n\
             binning_x: 0\nbinning_y: 0\n"
        ),
    ] {
        let camera = Camera::from_yaml_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(camera, expected, "{text}");
    }
    // Two names for one key are refused, not silently merged.
    let both = format!(
        "image_width: 640\nimage_height: 480\nK: {{data: {k}}}\ncamera_matrix: {{data: {k}}}\nD: {{data: {d}}}\n"
    );
    assert!(Camera::from_yaml_str(&both).is_err());
}

#[test]
fn absurd_focal_lengths_principal_points_and_skews_are_refused() {
    // Issue 43 item 9: fx 1e300 and cx -1e9 were accepted.
    let base = Camera::blackfly_s_5mp();
    for (camera, expected) in [
        (Camera { fx_px: 1e300, ..base.clone() }, "focal length"),
        (Camera { cx_px: -1e9, ..base.clone() }, "principal point"),
        (Camera { cy_px: 5e4, ..base.clone() }, "principal point"),
        (Camera { skew_px: 1e6, ..base.clone() }, "skew"),
    ] {
        let message = camera.validate().unwrap_err().to_string();
        assert!(message.contains(expected), "{message}");
    }
    // A long lens and a principal point off a cropped sensor's centre are fine.
    let long = Camera { fx_px: 40.0 * 2448.0, fy_px: 40.0 * 2448.0, cx_px: -100.0, ..base };
    assert!(long.validate().is_ok());
}
