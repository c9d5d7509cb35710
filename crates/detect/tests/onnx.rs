//! The learned detector (feature `onnx`) on small YOLO-style models the
//! test builds with the onnx Python package (ALACS_PEER_PYTHON, as CI
//! installs it): nothing is downloaded. The models' outputs are fixed
//! boxes, so the test pins what alacs does with a model's output: the
//! letterbox back to image pixels, both layouts, the fruit classes, the
//! score threshold and non-maximum suppression.
#![cfg(feature = "onnx")]
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::process::Command;

use alacs_detect::{OnnxDetector, OnnxOptions};

/// Writes yolov8.onnx ([1, 6, 5]) and yolov5.onnx ([1, 5, 7]) into `dir`:
/// input `images` [1, 3, 64, 64], classes apple and leaf; five boxes in
/// input pixels: apple A (20, 30, 16 x 16, 0.9), the same apple again
/// (0.6), apple B (48, 40, 10 x 12, 0.5), a leaf (0.95), a faint apple
/// (0.1).
const BUILD_MODELS: &str = r#"
import sys, numpy as np, onnx
from onnx import helper, numpy_helper, TensorProto
rows = np.array([
    [20, 30, 16, 16, 0.9, 0.1],
    [21, 31, 16, 16, 0.6, 0.1],
    [48, 40, 10, 12, 0.5, 0.2],
    [40, 20, 10, 10, 0.1, 0.95],
    [10, 50, 8, 8, 0.1, 0.05],
], dtype=np.float32)
def save(name, out):
    graph = helper.make_graph(
        [helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
         helper.make_node("Mul", ["m", "zero"], ["z"]),
         helper.make_node("Add", ["boxes", "z"], ["output0"])],
        "yolo", [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 64, 64])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(out.shape))],
        [numpy_helper.from_array(out, "boxes"),
         numpy_helper.from_array(np.array(0.0, dtype=np.float32), "zero")])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    onnx.checker.check_model(model)
    onnx.save(model, f"{sys.argv[1]}/{name}")
save("yolov8.onnx", rows.T[None].copy())
v5 = np.concatenate([rows[:, :4], np.ones((5, 1), np.float32), rows[:, 4:]], axis=1)
save("yolov5.onnx", v5[None].copy())
"#;

fn build_models(dir: &Path) -> bool {
    let Ok(python) = std::env::var("ALACS_PEER_PYTHON") else {
        eprintln!("ALACS_PEER_PYTHON unset: the ONNX models are not built (CI sets it)");
        return false;
    };
    let status = Command::new(python).arg("-c").arg(BUILD_MODELS).arg(dir).status().unwrap();
    assert!(status.success(), "building the models (pip install onnx)");
    true
}

#[test]
fn a_yolo_models_boxes_become_fruit_in_image_pixels_in_both_layouts() {
    let dir = tempfile::tempdir().unwrap();
    if !build_models(dir.path()) {
        return;
    }
    // 128 x 64: the letterbox halves it and pads 16 rows above and below.
    let image = image::RgbImage::from_pixel(128, 64, image::Rgb([90, 120, 60]));
    let names = vec!["apple".to_string(), "leaf".to_string()];
    for model in ["yolov8.onnx", "yolov5.onnx"] {
        let detector =
            OnnxDetector::load(&dir.path().join(model), OnnxOptions::new(names.clone())).unwrap();
        let found = detector.detect(&image).unwrap();
        assert_eq!(found.len(), 2, "{model}: A once (NMS), B; no leaf, no faint box: {found:?}");
        let (a, b) = (&found[0], &found[1]);
        assert!(
            (a.centre_px.x - 40.0).abs() < 1e-4 && (a.centre_px.y - 28.0).abs() < 1e-4,
            "{a:?}"
        );
        assert!((a.radius_px - 16.0).abs() < 1e-4 && (a.score - 0.9).abs() < 1e-6, "{a:?}");
        assert!(
            (b.centre_px.x - 96.0).abs() < 1e-4 && (b.centre_px.y - 48.0).abs() < 1e-4,
            "{b:?}"
        );
        assert!((b.radius_px - 12.0).abs() < 1e-4, "the longer side: {b:?}");
    }
}

#[test]
fn models_and_classes_that_do_not_fit_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    if !build_models(dir.path()) {
        return;
    }
    let path = dir.path().join("yolov8.onnx");
    let image = image::RgbImage::new(64, 64);
    // Three class names for a model of two: the output does not fit.
    let three = OnnxOptions::new(vec!["apple".into(), "leaf".into(), "sky".into()]);
    let error = OnnxDetector::load(&path, three).unwrap().detect(&image).unwrap_err();
    assert!(error.is_bad_input() && error.to_string().contains("[1, 7, N]"), "{error}");
    let no_fruit = OnnxOptions::new(vec!["pear".into(), "leaf".into()]);
    let error = OnnxDetector::load(&path, no_fruit).unwrap_err();
    assert!(error.to_string().contains("yolov8.onnx"), "{error}");
    let not_onnx = dir.path().join("model.onnx");
    std::fs::write(&not_onnx, "not a model").unwrap();
    let error = OnnxDetector::load(&not_onnx, OnnxOptions::new(vec!["apple".into()])).unwrap_err();
    assert!(error.is_bad_input() && error.to_string().contains("model.onnx"), "{error}");
}

#[test]
fn a_fifo_given_as_the_model_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("model.onnx");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return;
    }
    let error = OnnxDetector::load(&fifo, OnnxOptions::new(vec!["apple".into()])).unwrap_err();
    assert!(error.is_bad_input() && error.to_string().contains("model.onnx"), "{error}");
}
