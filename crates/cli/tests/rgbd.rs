//! `alacs calibrate rgbd` recovers the RGB-D camera's pose in the ALACS
//! camera frame from a simulated session where a second camera (1280 x 720)
//! saw every board pose from a known pose: within 1 mm and 0.1 deg.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

use nalgebra::{Isometry3, Matrix4, Rotation3, UnitQuaternion};
use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn matrix(value: &Value) -> Isometry3<f64> {
    let m = Matrix4::from_fn(|r, c| value[r][c].as_f64().unwrap());
    let rotation = Rotation3::from_matrix_unchecked(m.fixed_view::<3, 3>(0, 0).into_owned());
    Isometry3::from_parts(
        nalgebra::Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

#[test]
fn calibrate_rgbd_recovers_the_simulated_pose_within_1_mm_and_0_1_deg() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("session");
    let output = Command::new(ALACS)
        .args(["simulate", "session", "--seed", "5", "--views", "10", "--scale", "0.5"])
        .args(["--rgbd-pose", "65,-45,12,1.5,-2,3", "--laser-off", "--json", "--out"])
        .arg(&session)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(session.join("truth.json")).unwrap())
            .unwrap();
    let expected = matrix(&truth["rgbd"]["alacs_from_rgbd"]);
    let output = Command::new(ALACS)
        .args(["calibrate", "rgbd", "--json", "--session"])
        .arg(&session)
        .arg("--camera")
        .arg(session.join("camera.yaml"))
        .arg("--rgbd-camera")
        .arg(session.join("rgbd_camera.yaml"))
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let result: Value = serde_json::from_slice(&output.stdout).unwrap();
    let found = matrix(&result["alacs_from_rgbd"]["matrix"]);
    let delta = expected.inverse() * found;
    let translation_mm = (found.translation.vector - expected.translation.vector).norm();
    let rotation_deg = delta.rotation.angle().to_degrees();
    assert!(result["poses"].as_array().unwrap().len() >= 5, "{result}");
    assert!(translation_mm < 1.0, "{translation_mm:.3} mm off\n{result}");
    assert!(rotation_deg < 0.1, "{rotation_deg:.4} deg off\n{result}");

    // The ALACS camera's file given for the RGB-D camera (another image
    // size): bad input naming the image and both sizes, not "too degenerate".
    let output = Command::new(ALACS)
        .args(["calibrate", "rgbd", "--session"])
        .arg(&session)
        .arg("--camera")
        .arg(session.join("camera.yaml"))
        .arg("--rgbd-camera")
        .arg(session.join("camera.yaml"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("does not belong") && stderr.contains("1280 x 720"), "{stderr}");
}

#[test]
fn a_session_without_rgbd_images_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("session");
    let status = Command::new(ALACS)
        .args(["simulate", "session", "--seed", "1", "--views", "1", "--scale", "0.2", "--out"])
        .arg(&session)
        .output()
        .unwrap();
    assert!(status.status.success());
    let camera = session.join("camera.yaml");
    let output = Command::new(ALACS)
        .args(["calibrate", "rgbd", "--session"])
        .arg(&session)
        .arg("--camera")
        .arg(&camera)
        .arg("--rgbd-camera")
        .arg(&camera)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_ne!(output.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("image_rgbd") && stderr.contains("session.yaml"), "{stderr}");
}
