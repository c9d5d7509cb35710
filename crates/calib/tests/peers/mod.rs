//! The OpenCV peers of the calib tests: Python scripts beside this file run
//! by opencv-python-headless from PyPI in `ALACS_PEER_PYTHON` (`.ci/run`
//! installs it), one JSON request on standard input, one JSON answer out.

use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};

use alacs_calib::{BoardObservation, IntrinsicsFit};
use alacs_model::Camera;
use serde_json::{Value, json};

/// Runs `script` (in tests/peers) with `request`; `None` without the peer.
pub fn run(script: &str, request: &Value) -> Option<Value> {
    let python = std::env::var("ALACS_PEER_PYTHON").ok()?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers").join(script);
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

/// OpenCV's `calibrateCamera` on `views` (opencv_calibrate.py) with `flags`
/// (names of cv2.CALIB_* constants) from `initial`; `None` without the peer.
pub fn calibrate_camera(
    image_size: (u32, u32),
    views: &[BoardObservation],
    flags: &[&str],
    initial: Option<&Camera>,
) -> Option<Value> {
    let request = json!({
        "image_size": [image_size.0, image_size.1],
        "object_points": views.iter().map(|v| v.points_in_board.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "image_points": views.iter().map(|v| v.pixels.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        "flags": flags,
        "initial": initial.map(|c| json!({
            "K": [c.fx_px, c.skew_px, c.cx_px, 0.0, c.fy_px, c.cy_px, 0.0, 0.0, 1.0],
            "dist": c.distortion.coefficients(),
        })),
    });
    run("opencv_calibrate.py", &request)
}

/// Asserts that alacs's `fit` and OpenCV's answer `peer` are the same
/// minimum: the RMS to 1e-4 px (alacs never worse), fx, fy, cx and cy each
/// within a tenth of its standard deviation, and every distortion
/// coefficient too (OpenCV's extra ones, not fitted, 0). Prints both.
pub fn assert_same_minimum(name: &str, fit: &IntrinsicsFit, peer: &Value) {
    let get = |key: &str| peer[key].as_f64().unwrap();
    let c = &fit.camera;
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
    assert!(fit.rms_px <= get("rms_px") + 1e-4, "{name}: RMS {} vs {}", fit.rms_px, get("rms_px"));
    let std = fit.std_dev.clone().unwrap();
    for (k, key) in ["fx", "fy", "cx", "cy"].iter().enumerate() {
        let ours = [c.fx_px, c.fy_px, c.cx_px, c.cy_px][k];
        let bound = (0.1 * std[k]).max(1e-6);
        assert!((ours - get(key)).abs() <= bound, "{name}: {key} {ours} vs {}", get(key));
    }
    let coefficients = c.distortion.coefficients();
    let theirs: Vec<f64> =
        peer["dist"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    // OpenCV gives 14 coefficients for the rational model (thin prism and
    // tilt, not fitted: 0).
    assert!(theirs.len() >= coefficients.len(), "{name}: {theirs:?}");
    assert!(theirs[coefficients.len()..].iter().all(|&v| v == 0.0), "{name}: {theirs:?}");
    for (i, (ours, theirs)) in coefficients.iter().zip(&theirs).enumerate() {
        let bound = (0.1 * std[4 + i]).max(1e-9);
        assert!((ours - theirs).abs() <= bound, "{name}: coefficient {i}: {ours} vs {theirs}");
    }
}
