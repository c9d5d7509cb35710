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

use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};

use alacs_calib::{
    BoardObservation, FixedIntrinsics, IntrinsicsFit, IntrinsicsOptions, calibrate_intrinsics,
};
use alacs_model::{Camera, Distortion, DistortionModel};
use nalgebra::{Point2, Point3};
use serde_json::{Value, json};

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

/// OpenCV's answer for `views` with `flags`, or `None` without the peer.
fn opencv(views: &[BoardObservation], flags: &[&str], initial: Option<&Camera>) -> Option<Value> {
    let python = std::env::var("ALACS_PEER_PYTHON").ok()?;
    let request = json!({
        "image_size": [640, 480],
        "object_points": views.iter().map(|v| v.points_in_board.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "image_points": views.iter().map(|v| v.pixels.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "flags": flags,
        "initial": initial.map(|c| json!({
            "K": [c.fx_px, c.skew_px, c.cx_px, 0.0, c.fy_px, c.cy_px, 0.0, 0.0, 1.0],
            "dist": c.distortion.coefficients(),
        })),
    });
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/opencv_calibrate.py");
    let mut child = Command::new(python)
        .arg(script)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(request.to_string().as_bytes()).unwrap();
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "peer: {}", String::from_utf8_lossy(&output.stderr));
    Some(serde_json::from_slice(&output.stdout).unwrap())
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
        let std = fit.std_dev.clone().unwrap();
        let Some(peer) = opencv(&views, &flags, options.initial.as_ref()) else {
            eprintln!(
                "{name}: alacs RMS {:.5} px; SKIPPED OpenCV: set ALACS_PEER_PYTHON",
                fit.rms_px
            );
            continue;
        };
        let get = |key: &str| peer[key].as_f64().unwrap();
        eprintln!(
            "{name}: RMS alacs {:.6} OpenCV {:.6} px; fx {:.4} / {:.4}, fy {:.4} / {:.4}, cx {:.4} / {:.4}, cy {:.4} / {:.4}",
            fit.rms_px,
            get("rms_px"),
            c.fx_px,
            get("fx"),
            c.fy_px,
            get("fy"),
            c.cx_px,
            get("cx"),
            c.cy_px,
            get("cy")
        );
        // The same minimum: RMS to 1e-4 px (alacs never worse), each
        // intrinsic within a tenth of its standard deviation.
        assert!(
            fit.rms_px <= get("rms_px") + 1e-4,
            "{name}: RMS {} vs {}",
            fit.rms_px,
            get("rms_px")
        );
        for (k, key) in ["fx", "fy", "cx", "cy"].iter().enumerate() {
            let ours = [c.fx_px, c.fy_px, c.cx_px, c.cy_px][k];
            let bound = (0.1 * std[k]).max(1e-6);
            assert!((ours - get(key)).abs() <= bound, "{name}: {key} {ours} vs {}", get(key));
        }
        let theirs: Vec<f64> =
            peer["dist"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        // OpenCV gives 14 coefficients for the rational model (thin prism
        // and tilt, not fitted: 0).
        assert!(theirs.len() >= coefficients.len(), "{name}: {theirs:?}");
        assert!(theirs[coefficients.len()..].iter().all(|&v| v == 0.0), "{name}: {theirs:?}");
        for (i, (ours, theirs)) in coefficients.iter().zip(&theirs).enumerate() {
            let bound = (0.1 * std[4 + i]).max(1e-9);
            assert!((ours - theirs).abs() <= bound, "{name}: coefficient {i}: {ours} vs {theirs}");
        }
        compared += 1;
    }
    eprintln!("{compared} controls compared with OpenCV");
}
