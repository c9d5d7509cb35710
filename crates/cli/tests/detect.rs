//! `alacs simulate rgbd` then `alacs detect`: the files one writes are what
//! the other reads (a 16-bit depth PNG of millimetres, the colour camera),
//! the fruit is found within 15 mm of truth.json's, and bad inputs are
//! refused with exit 2 naming the file.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};

use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn alacs(args: &[&str]) -> Output {
    Command::new(ALACS).args(args).output().unwrap()
}

fn context(output: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

#[test]
fn detect_finds_the_simulated_rgbd_fruit_within_15_mm() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rgbd");
    let out_arg = out.to_str().unwrap();
    // 150 mm above the ALACS camera, looking down at its axis 0.9 m away.
    let o = alacs(&[
        "simulate",
        "rgbd",
        "--seed",
        "3",
        "--out",
        out_arg,
        "--alacs-from-rgbd=0,-150,0,-9.46,0,0",
    ]);
    assert!(o.status.success(), "{}", context(&o));
    let file = |name: &str| out.join(name).to_str().unwrap().to_owned();
    let o = alacs(&[
        "detect",
        "--image",
        &file("color.png"),
        "--depth",
        &file("depth.png"),
        "--camera",
        &file("camera.yaml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", context(&o));
    let found: Value = serde_json::from_slice(&o.stdout).unwrap();
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(file("truth.json")).unwrap()).unwrap();
    let target = truth["apples"].as_array().unwrap().iter().find(|a| a["target"] == true).unwrap();
    let xyz = |v: &Value| -> [f64; 3] { std::array::from_fn(|k| v[k].as_f64().unwrap()) };
    let t = xyz(&target["position_mm"]);
    let best = found["detections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            let p = xyz(&d["position_mm"]);
            assert_eq!(d["position_cov_mm2"].as_array().unwrap().len(), 3);
            ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    assert!(best <= 15.0, "nearest detection {best:.1} mm from the truth: {found}");
    // The colour image alone: circles, no 3-D keys.
    let o = alacs(&["detect", "--image", &file("color.png"), "--json"]);
    let plain: Value = serde_json::from_slice(&o.stdout).unwrap();
    let first = &plain["detections"][0];
    assert!(first["centre_px"].is_array() && first.get("position_mm").is_none(), "{plain}");
    // A colour image given as the depth: exit 2, naming it.
    let o = alacs(&[
        "detect",
        "--image",
        &file("color.png"),
        "--depth",
        &file("color.png"),
        "--camera",
        &file("camera.yaml"),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("color.png"), "{}", context(&o));
    // A depth without the camera that says where its pixels look: exit 2.
    let o = alacs(&["detect", "--image", &file("color.png"), "--depth", &file("depth.png")]);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
}

/// Without the `onnx` feature, `--model` says how to get it (exit 2),
/// naming the model, before anything is read.
#[cfg(not(feature = "onnx"))]
#[test]
fn a_model_without_the_onnx_feature_says_how_to_build_it() {
    let output =
        alacs(&["detect", "--image", "x.png", "--model", "yolo.onnx", "--classes", "apple"]);
    assert_eq!(output.status.code(), Some(2), "{}", context(&output));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("yolo.onnx") && stderr.contains("--features onnx"), "{stderr}");
}
