//! OpenCV interop both ways (issue 17, item 4): a camera.yaml written with
//! `--format opencv` opens in `cv2.FileStorage` with the same numbers, and a
//! file OpenCV writes with its usual key names (`cameraMatrix`,
//! `distCoeffs`) reads in alacs. The reader is opencv-python-headless from
//! PyPI in `ALACS_PEER_PYTHON` (`.ci/run` installs it: `.ci/peers.txt`);
//! without it the alacs side still runs and the OpenCV side is skipped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

use alacs::model::{Camera, Distortion};

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn run(args: &[&str]) {
    let output = Command::new(ALACS).args(args).output().unwrap();
    assert!(output.status.success(), "{args:?}: {}", String::from_utf8_lossy(&output.stderr));
}

#[test]
fn opencv_reads_what_alacs_writes_and_alacs_reads_what_opencv_writes() {
    let dir = tempfile::tempdir().unwrap();
    let ros = dir.path().join("camera.yaml");
    let camera = Camera {
        distortion: Distortion::RationalPolynomial([
            -0.08, 0.125, 1.4e-4, -7.0e-5, -0.018, 0.002, -0.003, 0.0004,
        ]),
        ..Camera::blackfly_s_5mp()
    };
    camera.to_yaml_file(&ros).unwrap();
    let opencv = dir.path().join("camera_opencv.yaml");
    run(&["convert", "camera", "--input", ros.to_str().unwrap(), "-o", opencv.to_str().unwrap()]);
    assert_eq!(Camera::from_yaml_file(&opencv).unwrap(), camera, "alacs reads its OpenCV layout");

    let Ok(python) = std::env::var("ALACS_PEER_PYTHON") else {
        eprintln!("SKIPPED cv2.FileStorage: set ALACS_PEER_PYTHON (.ci/peers.txt)");
        return;
    };
    let from_opencv = dir.path().join("written_by_opencv.yaml");
    let script = r#"
import json, sys
import cv2
fs = cv2.FileStorage(sys.argv[1], cv2.FILE_STORAGE_READ)
assert fs.isOpened(), "cv2.FileStorage cannot open " + sys.argv[1]
k = fs.getNode("camera_matrix").mat()
d = fs.getNode("distortion_coefficients").mat()
size = [int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real())]
fs.release()
out = cv2.FileStorage(sys.argv[2], cv2.FILE_STORAGE_WRITE)
out.write("image_width", size[0])
out.write("image_height", size[1])
out.write("cameraMatrix", k)
out.write("distCoeffs", d.reshape(-1, 1))
out.release()
print(json.dumps({"k": k.flatten().tolist(), "d": d.flatten().tolist(), "size": size}))
"#;
    let output = Command::new(python)
        .args(["-c", script])
        .arg(&opencv)
        .arg(&from_opencv)
        .output()
        .expect("the peer Python runs");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let read: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let numbers = |key: &str| -> Vec<f64> {
        read[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let c = &camera;
    assert_eq!(numbers("k"), [c.fx_px, c.skew_px, c.cx_px, 0.0, c.fy_px, c.cy_px, 0.0, 0.0, 1.0]);
    assert_eq!(numbers("d"), camera.distortion.ros_model().1);
    assert_eq!(numbers("size"), [f64::from(c.width_px), f64::from(c.height_px)]);

    // OpenCV's file, with its key names, through alacs back to the ROS layout.
    let back = dir.path().join("back.yaml");
    run(&[
        "convert",
        "camera",
        "--input",
        from_opencv.to_str().unwrap(),
        "-o",
        back.to_str().unwrap(),
        "--format",
        "ros",
    ]);
    let back = Camera::from_yaml_file(&back).unwrap();
    assert_eq!(Camera { name: camera.name.clone(), ..back }, camera);
}
