//! Ground truth in the JSON shapes of FORMATS.md (truth.json).

use alacs_model::{Camera, LaserModel};
use nalgebra::Isometry3;
use serde_json::{Value, json};

use crate::board::Checkerboard;

/// The camera as camera.yaml holds it, in JSON.
pub fn camera_to_json(camera: &Camera) -> Value {
    // Camera serializes with exactly the camera.yaml keys; it cannot fail.
    serde_json::to_value(camera).unwrap_or_default()
}

/// The laser as laser.yaml holds it, in JSON.
pub fn laser_to_json(laser: &LaserModel) -> Value {
    // LaserFile serializes with exactly the laser.yaml keys; it cannot fail.
    serde_json::to_value(laser.to_file()).unwrap_or_default()
}

/// A board as truth.json holds it (`board`, `second_board`): its inner
/// corners, squares, border, reflectances and ChArUco markers if it has them.
pub fn checkerboard_to_json(board: &Checkerboard) -> Value {
    json!({
        "inner_corners": [board.inner_corners.0, board.inner_corners.1],
        "square_mm": [board.square_mm.0, board.square_mm.1],
        "border_mm": board.border_mm,
        "black_reflectance": board.black_reflectance,
        "white_reflectance": board.white_reflectance,
        "marker_mm": board.markers.map(|m| m.marker_mm),
        "dictionary": board.markers.map(|m| m.dictionary.as_str()),
    })
}

/// A pose as truth.json holds it: 4 x 4, row-major, translation in mm.
pub(crate) fn matrix_rows(pose: &Isometry3<f64>) -> Vec<Vec<f64>> {
    let matrix = pose.to_homogeneous();
    (0..4).map(|r| (0..4).map(|c| matrix[(r, c)]).collect()).collect()
}
