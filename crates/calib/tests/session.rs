//! Calibration from simulated session images against the simulator's truth:
//! the camera, then the laser from dense stripe samples.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::PathBuf;

use alacs_calib::{
    Error, IntrinsicsFit, IntrinsicsOptions, LaserSessionOptions, calibrate_camera_session,
    calibrate_laser_session,
};
use alacs_model::{Camera, LaserModel, Session};
use alacs_sim::{SessionOptions, simulate_session};

mod volume;
use volume::max_depth_error_mm;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("alacs-calib-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn truth_laser() -> LaserModel {
    LaserModel::seed_paper()
}

/// The camera of `session`, default options, no progress.
fn calibrate_camera(session: &Session) -> alacs_calib::Result<IntrinsicsFit> {
    calibrate_camera_session(session, &IntrinsicsOptions::default(), &|| {})
}

/// A half-scale (1224 x 1024 px) session of `views` poses at slides 0, 100, 200 mm.
fn write_session(name: &str, views: usize, laser_off: bool, seed: u64) -> (PathBuf, Camera) {
    let options = SessionOptions {
        n_views: views,
        slides_mm: vec![0.0, 100.0, 200.0],
        laser_off,
        scale: 0.5,
        seed,
        ..SessionOptions::default()
    };
    let session = simulate_session(&Camera::blackfly_s_5mp(), &truth_laser(), &options).unwrap();
    let dir = temp_dir(name);
    session.write(&dir).unwrap();
    (dir, session.camera.clone())
}

#[test]
fn simulated_session_calibrates_camera_and_laser_to_the_truth() {
    let truth = truth_laser();
    for (seed, laser_off) in [(1, false), (2, true)] {
        let (dir, true_camera) = write_session(&format!("truth{seed}"), 10, laser_off, seed);
        let session = Session::read(&dir).unwrap();
        let fit = calibrate_camera(&session).unwrap();
        let c = &fit.camera;
        let relative = |a: f64, b: f64| (a - b).abs() / b;
        eprintln!(
            "seed {seed}: rms {:.3} px, fx {:.2} fy {:.2} cx {:.2} cy {:.2} (truth f {:.1}, c {:.1}, {:.1})",
            fit.rms_px,
            c.fx_px,
            c.fy_px,
            c.cx_px,
            c.cy_px,
            true_camera.fx_px,
            true_camera.cx_px,
            true_camera.cy_px
        );
        assert_eq!(fit.views_used(), fit.views.len());
        // The bound: intrinsics within 0.5 %.
        assert!(relative(c.fx_px, true_camera.fx_px) < 0.005);
        assert!(relative(c.fy_px, true_camera.fy_px) < 0.005);
        assert!(relative(c.cx_px, true_camera.cx_px) < 0.005);
        assert!(relative(c.cy_px, true_camera.cy_px) < 0.005);
        assert!(fit.rms_px < 0.1, "rms {}", fit.rms_px);

        let laser =
            calibrate_laser_session(&session, c, &LaserSessionOptions::default(), &|| {}).unwrap();
        let l = &laser.calibration.laser;
        eprintln!(
            "seed {seed}: {} samples from {} views, alpha {:.4} beta {:.4} L0 {:.3}, warnings {:?}",
            laser.samples.len(),
            laser.views.iter().filter(|v| v.n_samples > 0).count(),
            l.alpha_deg(),
            l.beta_deg(),
            l.l0_mm,
            laser.warnings
        );
        // The bounds: a, b within 0.05 deg, L0 within 0.3 mm.
        assert!((l.alpha_deg() - truth.alpha_deg()).abs() < 0.05);
        assert!((l.beta_deg() - truth.beta_deg()).abs() < 0.05);
        assert!((l.l0_mm - truth.l0_mm).abs() < 0.3);
        // Every view gives samples; half-scale boards 4-213 per view once the
        // points with a square's edge under the stripe are dropped (a stripe
        // along a column of squares loses most), 9 in 10 views over 30.
        assert!(laser.views.iter().all(|v| v.n_samples > 0), "{:?}", laser.views);
        let many = laser.views.iter().filter(|v| v.n_samples > 30).count();
        assert!(10 * many >= 9 * laser.views.len(), "{:?}", laser.views);
        assert!(laser.warnings.is_empty(), "{:?}", laser.warnings);
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Issue 17: a slide whose travel is k d instead of d (a pitch error, a
/// steps-per-mm setting, an axis at an angle to the baseline). Half-scale
/// sessions of 8 poses at slides 0, 100, 200 mm: k within 0.02 % and the
/// depth error over the working volume (0.6-1.2 m, the whole image) within
/// 0.5 mm at every slide position (issue 17 asks 1 mm; 0.06-0.21 mm
/// measured); held at 1 (the seed's model) the same sessions are up to 5 mm
/// off at 200 mm (k 0.99 and 1.02).
#[test]
fn a_slide_scale_error_is_fitted_to_the_noise_floor() {
    use alacs_sim::SlideError;
    // (scale, angle, seed): k = scale cos(angle) = 0.99, 0.997, 1.02, 0.997
    // from an axis turned by 4.44 deg, and the perfect slide, whose errors
    // are the noise floor (the fitted camera and laser of one session
    // together: 0.19 mm on seed 15; 0.5-0.75 mm on seeds 15 and 16 before
    // the corners were fitted as X-junctions, where the true camera with
    // the fitted laser was 0.8-4 mm off at the image's corners).
    let cases =
        [(0.99, 0.0, 11), (0.997, 0.0, 12), (1.02, 0.0, 13), (1.0, 4.44, 14), (1.0, 0.0, 15)];
    for (scale, angle_deg, seed) in cases {
        let options = SessionOptions {
            n_views: 8,
            slides_mm: vec![0.0, 100.0, 200.0],
            scale: 0.5,
            seed,
            slide: SlideError { scale, angle_deg },
            ..SessionOptions::default()
        };
        let simulated =
            simulate_session(&Camera::blackfly_s_5mp(), &truth_laser(), &options).unwrap();
        let dir = temp_dir(&format!("slide{seed}"));
        simulated.write(&dir).unwrap();
        let true_k = simulated.laser.slide_scale;
        let session = Session::read(&dir).unwrap();
        let camera = calibrate_camera(&session).unwrap().camera;
        let fit = |fit_slide_scale: bool| {
            let mut options = LaserSessionOptions::default();
            options.calibration.fit_slide_scale = fit_slide_scale;
            calibrate_laser_session(&session, &camera, &options, &|| {}).unwrap().calibration
        };
        let (fitted, held) = (fit(true), fit(false));
        let truth = (&simulated.camera, &simulated.laser);
        let errors: Vec<f64> = [0.0, 100.0, 200.0]
            .iter()
            .map(|&d| max_depth_error_mm(truth, (&camera, &fitted.laser), d))
            .collect();
        let held_error = max_depth_error_mm(truth, (&camera, &held.laser), 200.0);
        let k = fitted.laser.slide_scale;
        let k_std = fitted.std_dev.and_then(|s| s.slide_scale).unwrap();
        eprintln!(
            "k {true_k:.5}: fitted {k:.6} +- {k_std:.6} ({:+.4} %), max depth error {errors:.3?} mm at 0/100/200 mm; k held at 1: {held_error:.2} mm at 200 mm, {} of {} inliers",
            100.0 * (k - true_k) / true_k,
            held.inliers.len(),
            held.n_samples
        );
        assert!(fitted.slide_scale_fitted && !held.slide_scale_fitted);
        assert!(((k - true_k) / true_k).abs() < 2e-4, "k {k} for {true_k}");
        assert!(errors.iter().all(|&e| e <= 0.5), "{errors:?}");
        // The fitted k's standard deviation covers its error.
        assert!((k - true_k).abs() < 3.0 * k_std, "k {k} +- {k_std} for {true_k}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// Issue 17: a ChArUco board may be cut by the image's border, so its
/// corners reach the image's edges, where a checkerboard seen whole cannot
/// go. Half-scale sessions of 8 poses at slides 0, 100, 200 mm (k = 0.99,
/// seeds 100 and 101), boards cut by the border: every pose is used (one
/// pose's images at several slides merged, though each shows a different
/// part of the board), and k is fitted.
///
/// Not claimed: that such sessions calibrate better than a checkerboard
/// seen whole: poses that show 10-20 % of the board fix the focal length
/// poorly, and the reported standard deviations say so.
#[test]
fn a_charuco_session_cut_by_the_border_uses_every_pose() {
    use alacs_model::ArucoDictionary;
    use alacs_sim::{Checkerboard, SlideError};
    for seed in [100, 101] {
        let options = SessionOptions {
            n_views: 8,
            slides_mm: vec![0.0, 100.0, 200.0],
            scale: 0.5,
            seed,
            slide: SlideError { scale: 0.99, angle_deg: 0.0 },
            board: Checkerboard::charuco(ArucoDictionary::Dict5x5_100),
            cut_by_border: true,
            ..SessionOptions::default()
        };
        let simulated =
            simulate_session(&Camera::blackfly_s_5mp(), &truth_laser(), &options).unwrap();
        let dir = temp_dir(&format!("charuco{seed}"));
        simulated.write(&dir).unwrap();
        let true_k = simulated.laser.slide_scale;
        let session = Session::read(&dir).unwrap();
        assert!(session.board.markers.is_some(), "session.yaml names the markers");
        let intrinsics = calibrate_camera(&session).unwrap();
        let camera = intrinsics.camera.clone();
        let laser =
            calibrate_laser_session(&session, &camera, &LaserSessionOptions::default(), &|| {})
                .unwrap()
                .calibration;
        let truth = (&simulated.camera, &simulated.laser);
        let errors: Vec<f64> = [0.0, 100.0, 200.0]
            .iter()
            .map(|&d| max_depth_error_mm(truth, (&camera, &laser.laser), d))
            .collect();
        let k = laser.laser.slide_scale;
        eprintln!(
            "seed {seed} k {true_k:.5}: {} poses, fx {:.2} (truth {:.2}), fitted k {k:.6} ({:+.4} %), {} samples, max depth error {errors:.3?} mm at 0/100/200 mm",
            intrinsics.views_used(),
            camera.fx_px,
            simulated.camera.fx_px,
            100.0 * (k - true_k) / true_k,
            laser.n_samples,
        );
        assert_eq!(intrinsics.views_used(), 8, "every pose, those cut by the border too");
        assert!(((k - true_k) / true_k).abs() < 5e-4, "k {k} for {true_k}");
        // A mislabelled corner would be tens of mm.
        assert!(errors.iter().all(|&e| e <= 15.0), "{errors:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// A session of `views` poses without laser-off images ([`write_session`]),
/// read back, and the image of its view `index`, to be spoiled.
fn session_with_victim(
    name: &str,
    views: usize,
    seed: u64,
    index: usize,
) -> (PathBuf, Session, PathBuf) {
    let (dir, _) = write_session(name, views, false, seed);
    let session = Session::read(&dir).unwrap();
    let victim = session.path_of(&session.views[index].image);
    (dir, session, victim)
}

#[test]
fn a_view_without_a_board_is_rejected_with_its_reason() {
    let (dir, session, victim) = session_with_victim("noboard", 4, 3, 1);
    // Replace one view by a plain grey image of the same size.
    image::RgbImage::from_pixel(1224, 1024, image::Rgb([90, 90, 90])).save(&victim).unwrap();
    let fit = calibrate_camera(&session).unwrap();
    let rejected: Vec<_> = fit.views.iter().filter(|v| v.rejected.is_some()).collect();
    assert_eq!(rejected.len(), 1);
    assert_eq!(rejected[0].name, session.views[1].image.display().to_string());
    assert!(rejected[0].rejected.as_ref().unwrap().contains("no 11 x 8 checkerboard"));
    let laser =
        calibrate_laser_session(&session, &fit.camera, &LaserSessionOptions::default(), &|| {})
            .unwrap();
    assert_eq!(laser.views[1].n_samples, 0);
    assert!(laser.views[1].rejected.is_some());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unreadable_images_are_bad_input_naming_the_file() {
    let (dir, session, victim) = session_with_victim("corrupt", 3, 4, 0);
    std::fs::write(&victim, b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let error = calibrate_camera(&session).unwrap_err();
    assert!(error.is_bad_input(), "{error}");
    assert!(error.to_string().contains(&victim.display().to_string()), "{error}");
    std::fs::remove_file(&victim).unwrap();
    let error = calibrate_camera(&session).unwrap_err();
    assert!(matches!(error, Error::Vision(_)) && error.is_bad_input(), "{error}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn one_board_pose_is_too_degenerate_for_the_laser() {
    let (dir, _) = write_session("onepose", 3, false, 5);
    let session = Session::read(&dir).unwrap();
    let camera = calibrate_camera(&session).unwrap().camera;
    let mut single = session.clone();
    single.views.truncate(1);
    let error = calibrate_laser_session(&single, &camera, &LaserSessionOptions::default(), &|| {})
        .unwrap_err();
    assert!(!error.is_bad_input());
    assert!(error.to_string().contains("at least 2 board views"), "{error}");
    let _ = std::fs::remove_dir_all(&dir);
}
