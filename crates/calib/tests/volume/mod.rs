//! The depth error of a fitted camera and laser over the working volume,
//! shared by the session tests and the `session_floor` example.

use alacs_model::{Camera, LaserModel};

/// Largest |z_fit - z| over the working volume at slide travel `slide_mm`:
/// the true laser's points at depths 600-1200 mm (every 25 mm) on every
/// 32nd image row, seen through the true camera (points outside the image
/// left out), triangulated through the fitted camera and laser.
pub fn max_depth_error_mm(
    truth: (&Camera, &LaserModel),
    fit: (&Camera, &LaserModel),
    slide_mm: f64,
) -> f64 {
    let (true_camera, true_laser) = truth;
    let (camera, laser) = fit;
    let half_height_n = f64::from(true_camera.height_px) / 2.0 / true_camera.fy_px;
    let mut worst: f64 = 0.0;
    for i in 0..=24 {
        let z = 600.0 + 25.0 * f64::from(i);
        for row in (0..true_camera.height_px).step_by(32) {
            let v_n =
                (f64::from(row) / f64::from(true_camera.height_px) * 2.0 - 1.0) * half_height_n;
            // eq. (7): z = L / (sin a - u cos a - v tan b), solved for u.
            let u_n = (true_laser.alpha_rad.sin()
                - true_laser.laser_distance_mm(slide_mm) / z
                - v_n * true_laser.beta_rad.tan())
                / true_laser.alpha_rad.cos();
            let point = nalgebra::Point3::new(u_n * z, v_n * z, z);
            let Ok(pixel) = true_camera.project(&point) else { continue };
            let inside = (0.0..f64::from(true_camera.width_px)).contains(&pixel.x)
                && (0.0..f64::from(true_camera.height_px)).contains(&pixel.y);
            if !inside {
                continue;
            }
            let normalized = camera.undistort_pixel(&pixel).unwrap();
            let z_fit = laser.depth_mm(&normalized, slide_mm).unwrap();
            worst = worst.max((z_fit - z).abs());
        }
    }
    worst
}
