//! The camera calibration's controls against OpenCV's `calibrateCamera` on
//! the same corners (issue 17, item 2): OpenCV's own corners of its 13
//! right-camera sample photographs (testdata/opencv_right/reference), each
//! control with its OpenCV flag. Both sides minimize the same reprojection
//! error, so they must reach the same minimum: the same RMS, and
//! intrinsics within a small fraction of their standard deviations. The
//! peer is opencv-python-headless from PyPI in `ALACS_PEER_PYTHON` (`.ci/run`
//! installs it); without it the alacs side still runs and the comparison is
//! skipped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::Path;

use alacs_calib::{
    BoardObservation, FixedIntrinsics, IntrinsicsFit, IntrinsicsOptions, calibrate_intrinsics,
};
use alacs_model::{Camera, Distortion, DistortionModel};
use nalgebra::{Point2, Point3};
use serde_json::Value;

mod peers;

/// OpenCV's classic corners of the 13 photographs, as board observations
/// (corner k at ((k % 9) * 25, (k / 9) * 25, 0) mm, OpenCV's order).
fn opencv_corners() -> Vec<BoardObservation> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/opencv_right/reference/opencv_right_corners_classic_win5.json");
    let reference: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let cols = reference["pattern_size"][0].as_u64().unwrap() as usize;
    reference["images"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|image| image["found"] == true)
        .map(|image| {
            let pixels: Vec<Point2<f64>> = image["corners"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| Point2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap()))
                .collect();
            let points_in_board = (0..pixels.len())
                .map(|k| Point3::new((k % cols) as f64 * 25.0, (k / cols) as f64 * 25.0, 0.0))
                .collect();
            BoardObservation { name: image["file"].to_string(), points_in_board, pixels }
        })
        .collect()
}

/// A starting camera near, not at, the answer.
fn starting_camera() -> Camera {
    Camera {
        name: "start".into(),
        width_px: 640,
        height_px: 480,
        fx_px: 520.0,
        fy_px: 525.0,
        cx_px: 322.0,
        cy_px: 242.0,
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([-0.2, 0.05, 0.0, 0.0, 0.01]),
    }
}

/// The controls compared: a name, alacs's options, OpenCV's flags.
fn controls() -> Vec<(&'static str, IntrinsicsOptions, Vec<&'static str>)> {
    let with = |distortion, fixed, initial| IntrinsicsOptions {
        distortion,
        fixed,
        initial,
        ..IntrinsicsOptions::default()
    };
    let fix = FixedIntrinsics::default();
    let plumb = DistortionModel::PlumbBob;
    vec![
        ("default", with(plumb, fix, None), vec![]),
        (
            "rational_polynomial",
            with(DistortionModel::RationalPolynomial, fix, None),
            vec!["RATIONAL_MODEL"],
        ),
        ("fix k3", with(plumb, FixedIntrinsics { k3: true, ..fix }, None), vec!["FIX_K3"]),
        (
            "zero tangential",
            with(plumb, FixedIntrinsics { tangential: true, ..fix }, None),
            vec!["ZERO_TANGENT_DIST"],
        ),
        (
            "fix aspect",
            with(plumb, FixedIntrinsics { aspect: true, ..fix }, Some(starting_camera())),
            vec!["FIX_ASPECT_RATIO", "USE_INTRINSIC_GUESS"],
        ),
        (
            "fix principal point",
            with(plumb, FixedIntrinsics { principal_point: true, ..fix }, None),
            vec!["FIX_PRINCIPAL_POINT"],
        ),
        (
            "starting camera, k3 held",
            with(plumb, FixedIntrinsics { k3: true, ..fix }, Some(starting_camera())),
            vec!["USE_INTRINSIC_GUESS", "FIX_K3"],
        ),
    ]
}

#[test]
fn every_camera_control_reaches_opencvs_minimum_on_the_same_corners() {
    let views = opencv_corners();
    assert_eq!(views.len(), 13);
    let mut compared = 0;
    for (name, options, flags) in controls() {
        let fit: IntrinsicsFit = calibrate_intrinsics(640, 480, &views, &options).unwrap();
        let c = &fit.camera;
        assert_eq!(fit.views_used(), 13, "{name}");
        assert_eq!(c.distortion.model(), options.distortion, "{name}");
        let coefficients = c.distortion.coefficients();
        // The held values are held.
        if options.fixed.k3 {
            let start = options.initial.as_ref().map_or(0.0, |s| s.distortion.coefficients()[4]);
            assert_eq!(coefficients[4], start, "{name}");
        }
        if options.fixed.tangential {
            assert_eq!((coefficients[2], coefficients[3]), (0.0, 0.0), "{name}");
        }
        if options.fixed.aspect {
            let start = options.initial.as_ref().unwrap();
            let ratio = c.fy_px / c.fx_px;
            assert!((ratio - start.fy_px / start.fx_px).abs() < 1e-12, "{name}: {ratio}");
        }
        if options.fixed.principal_point {
            assert_eq!((c.cx_px, c.cy_px), (319.5, 239.5), "{name}");
        }
        let Some(peer) =
            peers::calibrate_camera((640, 480), &views, &flags, options.initial.as_ref())
        else {
            eprintln!(
                "{name}: alacs RMS {:.5} px; SKIPPED OpenCV: set ALACS_PEER_PYTHON",
                fit.rms_px
            );
            continue;
        };
        peers::assert_same_minimum(name, &fit, &peer);
        compared += 1;
    }
    eprintln!("{compared} controls compared with OpenCV");
}
