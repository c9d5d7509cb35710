//! Laser model tests: the shared harness (Jacobians, round trips, finite
//! outputs) plus the model's own identities and its file.

use alacs_model::{Error, Fidelity, LaserModel, SLIDE_STROKE_MM};
use nalgebra::{DMatrix, DVector, Point2};

use crate::harness::{Differentiable, assert_finite, assert_jacobian, assert_round_trip};

/// The seed paper's Table 1, Method 4.
fn paper_laser() -> LaserModel {
    LaserModel::seed_paper()
}

fn low_fidelity_laser() -> LaserModel {
    LaserModel::from_degrees(Fidelity::Low, 19.03, 0.0, 382.83)
}

/// Normalized coordinates across a 2448 x 2048 image with f = 2320 px.
fn normalized_grid() -> Vec<Point2<f64>> {
    let mut grid = Vec::new();
    for i in 0..=8 {
        for j in 0..=8 {
            let u = -0.5 + 0.125 * f64::from(i) * 0.5;
            let v = -0.44 + 0.11 * f64::from(j);
            grid.push(Point2::new(u, v));
        }
    }
    grid
}

/// Triangulation as a map (u_n, v_n) -> (x, y, z) at a fixed slide travel.
struct Triangulation(LaserModel, f64);

impl Differentiable for Triangulation {
    fn name(&self) -> String {
        format!("triangulate {} at d = {} mm", self.0.fidelity, self.1)
    }
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        let p = self.0.triangulate(&Point2::new(x[0], x[1]), self.1).ok()?;
        Some(DVector::from_column_slice(p.coords.as_slice()))
    }
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let j = self.0.triangulate_jacobian(&Point2::new(x[0], x[1]), self.1).ok()?;
        Some(DMatrix::from_iterator(3, 2, j.iter().copied()))
    }
}

/// The modelled depth of eq. (9) as a map (alpha, L0, beta, k) -> z_hat.
struct DepthOfParams(Fidelity, Point2<f64>, f64);

impl Differentiable for DepthOfParams {
    fn name(&self) -> String {
        format!("z_hat(alpha, L0, beta, k) {} at {:?}, d = {} mm", self.0, self.1, self.2)
    }
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        let laser = LaserModel::new(self.0, x[0], x[2], x[1]).with_slide_scale(x[3]);
        Some(DVector::from_element(1, laser.depth_mm(&self.1, self.2).ok()?))
    }
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let laser = LaserModel::new(self.0, x[0], x[2], x[1]).with_slide_scale(x[3]);
        let mut g = laser.depth_gradient_params(&self.1, self.2).ok()?;
        if self.0 == Fidelity::Low {
            g[2] = 0.0; // beta is not a parameter of the low-fidelity model
        }
        Some(DMatrix::from_row_slice(1, 4, g.as_slice()))
    }
}

#[test]
fn triangulation_jacobian_matches_finite_differences() {
    for laser in [paper_laser(), low_fidelity_laser()] {
        for slide_mm in [0.0, 100.0, 200.0] {
            let f = Triangulation(laser, slide_mm);
            for n in normalized_grid() {
                let x = DVector::from_column_slice(&[n.x, n.y]);
                assert_finite(&f, &x);
                assert_jacobian(&f, &x, 1e-5);
            }
        }
    }
}

#[test]
fn depth_parameter_gradient_matches_finite_differences() {
    for fidelity in [Fidelity::High, Fidelity::Low] {
        let laser = paper_laser();
        let params =
            DVector::from_column_slice(&[laser.alpha_rad, laser.l0_mm, laser.beta_rad, 0.997]);
        for n in normalized_grid() {
            let f = DepthOfParams(fidelity, n, 150.0);
            assert_finite(&f, &params);
            assert_jacobian(&f, &params, 1e-5);
        }
    }
}

#[test]
fn triangulated_points_reproject_to_their_normalized_coordinates() {
    for laser in [paper_laser(), low_fidelity_laser()] {
        for slide_mm in [0.0, 37.5, 200.0] {
            for n in normalized_grid() {
                assert_round_trip(
                    "triangulate then x/z, y/z",
                    |x| {
                        let p = laser.triangulate(&Point2::new(x[0], x[1]), slide_mm).ok()?;
                        Some(DVector::from_column_slice(&[p.x, p.y, p.z]))
                    },
                    |p| Some(DVector::from_column_slice(&[p[0] / p[2], p[1] / p[2]])),
                    &DVector::from_column_slice(&[n.x, n.y]),
                    1e-12,
                );
            }
        }
    }
}

#[test]
fn triangulated_points_lie_on_the_laser_plane_and_invert_to_their_slide() {
    for laser in [paper_laser(), paper_laser().with_slide_scale(0.99)] {
        for slide_mm in [0.0, 10.0, 123.4, 200.0] {
            let plane = laser.plane_in_camera(slide_mm);
            assert!(plane.signed_distance_mm(&laser.origin_in_camera(slide_mm)).abs() < 1e-9);
            for n in normalized_grid() {
                let p = laser.triangulate(&n, slide_mm).unwrap();
                assert!(plane.signed_distance_mm(&p).abs() < 1e-9, "{p} off the plane");
                assert!((laser.slide_for_point(&p) - slide_mm).abs() < 1e-9);
                let target = laser.slide_target(&p, SLIDE_STROKE_MM);
                assert!(target.within_stroke);
                assert!((target.clamped_mm - target.slide_mm).abs() < 1e-9);
            }
        }
    }
}

#[test]
fn slide_target_reports_points_outside_the_stroke() {
    let laser = paper_laser();
    let beyond = laser.triangulate(&Point2::new(0.0, 0.0), 260.0).unwrap();
    let target = laser.slide_target(&beyond, SLIDE_STROKE_MM);
    assert!((target.slide_mm - 260.0).abs() < 1e-9);
    assert!(!target.within_stroke);
    assert_eq!(target.clamped_mm, SLIDE_STROKE_MM);
    let before = laser.triangulate(&Point2::new(0.1, 0.0), -5.0).unwrap();
    let target = laser.slide_target(&before, SLIDE_STROKE_MM);
    assert!(!target.within_stroke);
    assert_eq!(target.clamped_mm, 0.0);
}

#[test]
fn depth_follows_equation_7_at_a_hand_checked_point() {
    // u_n = 0, v_n = 0: z = L0 / sin(alpha).
    let laser = paper_laser();
    let z = laser.depth_mm(&Point2::new(0.0, 0.0), 0.0).unwrap();
    assert!((z - 381.98 / 19.07_f64.to_radians().sin()).abs() < 1e-9);
    // The low-fidelity model ignores beta whatever the field holds.
    let mut low = paper_laser();
    low.fidelity = Fidelity::Low;
    let n = Point2::new(-0.1, 0.3);
    let expected = 381.98 / (19.07_f64.to_radians().sin() + 0.1 * 19.07_f64.to_radians().cos());
    assert!((low.depth_mm(&n, 0.0).unwrap() - expected).abs() < 1e-9);
    assert_eq!(low.beta_deg(), 0.0);
}

#[test]
fn rays_that_miss_the_plane_in_front_are_errors_not_negative_depths() {
    let laser = paper_laser();
    // u_n = tan(alpha) makes D = 0; beyond it D < 0.
    for u_n in [19.07_f64.to_radians().tan(), 0.5, 2.0] {
        let err = laser.triangulate(&Point2::new(u_n, 0.0), 0.0).unwrap_err();
        assert!(matches!(err, Error::NoIntersection { .. }), "{err}");
    }
    let err = laser.depth_mm(&Point2::new(f64::NAN, 0.0), 0.0).unwrap_err();
    assert!(matches!(err, Error::NoIntersection { .. }));
    // A slide beyond L0 puts the laser behind the camera's baseline.
    assert!(laser.depth_mm(&Point2::new(0.0, 0.0), 400.0).is_err());
}

#[test]
fn laser_yaml_round_trips_exactly() {
    for laser in [
        paper_laser(),
        low_fidelity_laser(),
        LaserModel::new(Fidelity::High, 0.1234567890123, -0.01, 1.0 / 3.0)
            .with_slide_scale(1.0 - 1.0 / 3000.0),
    ] {
        let back = LaserModel::from_yaml_str(&laser.to_yaml_string()).unwrap();
        assert_eq!(back.fidelity, laser.fidelity);
        assert_eq!(back.slide_scale.to_bits(), laser.slide_scale.to_bits());
        assert_eq!(back.alpha_rad.to_bits(), laser.alpha_deg().to_radians().to_bits());
        assert_eq!(back.beta_deg().to_bits(), laser.beta_deg().to_bits());
        assert_eq!(back.l0_mm.to_bits(), laser.l0_mm.to_bits());
    }
}

#[test]
fn laser_yaml_from_formats_md_reads() {
    let text = "model: high-fidelity        # or low-fidelity\nalpha_deg: 19.07\nbeta_deg: 0.69\nl0_mm: 381.98\nextra_key: kept out\n";
    let laser = LaserModel::from_yaml_str(text).unwrap();
    assert_eq!(laser.fidelity, Fidelity::High);
    assert!((laser.alpha_deg() - 19.07).abs() < 1e-12);
    assert!((laser.beta_deg() - 0.69).abs() < 1e-12);
    assert_eq!(laser.l0_mm, 381.98);
    // A file without `slide_scale` (every file before it existed) is the seed's slide.
    assert_eq!(laser.slide_scale, 1.0);
    let scaled = LaserModel::from_yaml_str(&format!("{text}slide_scale: 0.997\n")).unwrap();
    assert_eq!(scaled.slide_scale, 0.997);
    assert!((scaled.laser_distance_mm(200.0) - (381.98 - 0.997 * 200.0)).abs() < 1e-12);
    let low = LaserModel::from_yaml_str("model: low-fidelity\nalpha_deg: 19.03\nl0_mm: 382.83\n")
        .unwrap();
    assert_eq!(low.fidelity, Fidelity::Low);
    assert_eq!(low.beta_deg(), 0.0);
}

#[test]
fn laser_yaml_errors_name_the_problem() {
    let cases = [
        ("model: high-fidelity\nalpha_deg: 19.07\nl0_mm: 381.98\n", "beta_deg"),
        ("model: high-fidelity\nbeta_deg: 0.1\nl0_mm: 381.98\n", "alpha_deg"),
        ("model: medium\nalpha_deg: 19.07\nbeta_deg: 0.1\nl0_mm: 381.98\n", "medium"),
        ("model: high-fidelity\nalpha_deg: 19.07\nbeta_deg: 0.1\nl0_mm: -3\n", "l0_mm"),
        ("model: high-fidelity\nalpha_deg: .nan\nbeta_deg: 0.1\nl0_mm: 300\n", "finite"),
        ("model: low-fidelity\nalpha_deg: 19\nl0_mm: 300\nslide_scale: 0\n", "slide_scale"),
        ("model: low-fidelity\nalpha_deg: 19\nl0_mm: 300\nslide_scale: .inf\n", "slide_scale"),
        ("model: high-fidelity\nalpha_deg: [1, 2\n", ""),
    ];
    for (text, needle) in cases {
        let err = LaserModel::from_yaml_str(text).unwrap_err();
        assert!(matches!(err, Error::Parse { .. }), "{err}");
        assert!(err.to_string().contains(needle), "`{err}` should mention `{needle}`");
    }
    let missing =
        LaserModel::from_yaml_file(std::path::Path::new("/nonexistent/laser.yaml")).unwrap_err();
    assert!(missing.to_string().contains("/nonexistent/laser.yaml"), "{missing}");
}

#[test]
fn laser_origin_is_at_distance_l_from_the_camera() {
    let laser = paper_laser();
    for slide_mm in [0.0, 150.0] {
        let o = laser.origin_in_camera(slide_mm);
        assert!((o.coords.norm() - laser.laser_distance_mm(slide_mm)).abs() < 1e-9);
        assert_eq!(o.y, 0.0);
        // The origin sits to the left (-x) of the camera for 0 < alpha < 90 deg.
        assert!(o.x < 0.0);
    }
}

/// The geometric residual as a map (alpha, L0, beta, k) -> signed distance of a fixed point.
struct DistanceOfParams(Fidelity, nalgebra::Point3<f64>, f64);

impl Differentiable for DistanceOfParams {
    fn name(&self) -> String {
        format!("plane distance(alpha, L0, beta, k) {} at {}, d = {} mm", self.0, self.1, self.2)
    }
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        let laser = LaserModel::new(self.0, x[0], x[2], x[1]).with_slide_scale(x[3]);
        Some(DVector::from_element(1, laser.signed_distance_mm(&self.1, self.2)))
    }
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>> {
        let laser = LaserModel::new(self.0, x[0], x[2], x[1]).with_slide_scale(x[3]);
        let mut g = laser.signed_distance_gradient_params(&self.1, self.2);
        if self.0 == Fidelity::Low {
            g[2] = 0.0;
        }
        Some(DMatrix::from_row_slice(1, 4, g.as_slice()))
    }
}

#[test]
fn plane_distance_gradient_matches_finite_differences() {
    let laser = paper_laser();
    let params = DVector::from_column_slice(&[laser.alpha_rad, laser.l0_mm, laser.beta_rad, 0.997]);
    for fidelity in [Fidelity::High, Fidelity::Low] {
        for n in normalized_grid() {
            // A point 3 mm off the plane, so the distance is not trivially 0.
            let on_plane = laser.triangulate(&n, 20.0).unwrap();
            let point = on_plane + nalgebra::Vector3::new(1.0, -2.0, 2.0);
            let f = DistanceOfParams(fidelity, point, 20.0);
            assert_finite(&f, &params);
            assert_jacobian(&f, &params, 1e-5);
        }
    }
}

#[test]
fn camera_rays_meet_the_laser_plane_where_triangulation_puts_them() {
    use alacs_model::Ray;
    let laser = paper_laser();
    for slide_mm in [0.0, 80.0] {
        let plane = laser.plane_in_camera(slide_mm);
        for n in normalized_grid() {
            let hit = plane.intersect(&Ray::through_normalized(n.x, n.y)).unwrap();
            let point = laser.triangulate(&n, slide_mm).unwrap();
            assert!((hit - point).norm() < 1e-9, "{hit} vs {point}");
        }
    }
    // Rays that miss the plane in front of the camera have no intersection.
    let plane = laser.plane_in_camera(0.0);
    assert!(plane.intersect(&Ray::through_normalized(2.0, 0.0)).is_none());
    // A ray parallel to the plane has none either.
    let along = nalgebra::Vector3::new(laser.alpha_rad.sin(), 0.0, laser.alpha_rad.cos());
    assert!(
        plane.intersect(&Ray { origin: nalgebra::Point3::origin(), direction: along }).is_none()
    );
}

#[test]
fn the_scan_plan_starts_on_the_left_half_and_steps_right() {
    use alacs_model::ScanStrategy;
    let laser = paper_laser();
    let strategy = ScanStrategy::default();
    let fruit = nalgebra::Point3::new(30.0, -20.0, 900.0);
    let plan = strategy.plan(&laser, &fruit, 40.0);
    assert_eq!(plan.slides_mm.len(), 5);
    assert!(!plan.shifted);
    // The first plane passes 20 mm (half a radius) left of the centre, at the centre's depth and row.
    let start = fruit - nalgebra::Vector3::new(20.0, 0.0, 0.0);
    assert!(laser.signed_distance_mm(&start, plan.slides_mm[0]).abs() < 1e-9);
    for pair in plan.slides_mm.windows(2) {
        assert!((pair[1] - pair[0] - 10.0).abs() < 1e-12);
    }
    // Each step moves the plane right by 10 mm / cos(alpha) at that depth.
    let x_at = |slide_mm: f64| {
        let plane = laser.plane_in_camera(slide_mm);
        (plane.offset_mm - plane.normal.y * fruit.y - plane.normal.z * fruit.z) / plane.normal.x
    };
    let step = x_at(plan.slides_mm[1]) - x_at(plan.slides_mm[0]);
    assert!((step - 10.0 / laser.alpha_rad.cos()).abs() < 1e-9, "{step}");
}

#[test]
fn scan_plans_shift_into_the_stroke() {
    use alacs_model::ScanStrategy;
    let laser = paper_laser();
    let strategy = ScanStrategy::default();
    // Far right at close range needs travel beyond the stroke: the sweep ends at 200 mm.
    let right = laser.triangulate(&Point2::new(0.2, 0.0), 250.0).unwrap();
    let plan = strategy.plan(&laser, &right, 40.0);
    assert!(plan.shifted && plan.unclamped_start_mm > 200.0);
    assert_eq!(plan.slides_mm, vec![160.0, 170.0, 180.0, 190.0, 200.0]);
    // Far left needs negative travel: the sweep starts at 0.
    let left = laser.triangulate(&Point2::new(-0.3, 0.0), -80.0).unwrap();
    let plan = strategy.plan(&laser, &left, 40.0);
    assert!(plan.shifted);
    assert_eq!(plan.slides_mm, vec![0.0, 10.0, 20.0, 30.0, 40.0]);
    // A sweep longer than the stroke starts at 0 and is clamped at its end.
    let long = ScanStrategy { frames: 30, ..strategy };
    let plan = long.plan(&laser, &left, 40.0);
    assert_eq!(plan.slides_mm[0], 0.0);
    assert_eq!(*plan.slides_mm.last().unwrap(), 200.0);
}

#[test]
fn an_extension_steps_on_beyond_both_ends_of_the_sweep_within_the_stroke() {
    use alacs_model::{ScanPlan, ScanStrategy};
    let laser = paper_laser();
    let strategy = ScanStrategy::default();
    let plan = strategy.plan(&laser, &nalgebra::Point3::new(30.0, -20.0, 900.0), 40.0);
    let (first, last) = (plan.slides_mm[0], plan.slides_mm[4]);
    assert_eq!(
        strategy.extension(&plan),
        vec![first - 10.0, first - 20.0, last + 10.0, last + 20.0]
    );
    // At the stroke's end the frames beyond it are left out, not moved.
    let at_end = ScanPlan {
        slides_mm: vec![160.0, 170.0, 180.0, 190.0, 200.0],
        unclamped_start_mm: 170.0,
        shifted: true,
    };
    assert_eq!(strategy.extension(&at_end), vec![150.0, 140.0]);
    // An odd count puts the odd frame after the sweep; none extends nothing.
    let odd = ScanStrategy { extension_frames: 3, ..strategy };
    assert_eq!(odd.extension(&plan), vec![first - 10.0, last + 10.0, last + 20.0]);
    assert!(ScanStrategy { extension_frames: 0, ..strategy }.extension(&plan).is_empty());
}

#[test]
fn a_sweep_for_several_fruit_covers_each_with_its_own_five_frames() {
    use alacs_model::{SHARED_FRAME_MM, ScanStrategy};
    let laser = paper_laser();
    let strategy = ScanStrategy::default();
    let left = nalgebra::Point3::new(-60.0, 0.0, 900.0);
    let right = nalgebra::Point3::new(20.0, 10.0, 880.0);
    // Almost the left fruit's position: its frames fall on the left fruit's.
    let beside_left = nalgebra::Point3::new(-59.0, 5.0, 901.0);
    let sweep = strategy.plan_sweep(&laser, &[(left, 40.0), (right, 40.0), (beside_left, 40.0)]);
    assert!(sweep.slides_mm.windows(2).all(|w| w[1] - w[0] >= SHARED_FRAME_MM), "{sweep:?}");
    assert_eq!(sweep.slides_mm.len(), 10, "{sweep:?}");
    for fruit in [left, right, beside_left] {
        // Every frame of the fruit's own plan is in the sweep, within the shared tolerance.
        for d in strategy.plan(&laser, &fruit, 40.0).slides_mm {
            assert!(sweep.slides_mm.iter().any(|s| (s - d).abs() < SHARED_FRAME_MM), "{d}");
        }
    }
    assert_eq!(sweep.unclamped_start_mm, strategy.plan(&laser, &left, 40.0).unclamped_start_mm);
    // One fruit: its own plan.
    assert_eq!(strategy.plan_sweep(&laser, &[(right, 40.0)]), strategy.plan(&laser, &right, 40.0));
}

#[test]
fn an_l0_no_laser_beside_its_camera_has_is_refused() {
    // Issue 43 item 9: L0 1e300 was accepted.
    let laser = LaserModel { l0_mm: 1e300, ..paper_laser() };
    let message = laser.validate().unwrap_err().to_string();
    assert!(message.contains("l0_mm"), "{message}");
    assert!(LaserModel { l0_mm: 5000.0, ..paper_laser() }.validate().is_ok());
}
