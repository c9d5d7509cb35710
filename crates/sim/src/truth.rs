//! Ground truth in the JSON shapes of FORMATS.md (truth.json).

use alacs_model::{Camera, LaserModel};
use nalgebra::Isometry3;
use serde_json::Value;

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

/// A pose as truth.json holds it: 4 x 4, row-major, translation in mm.
pub(crate) fn matrix_rows(pose: &Isometry3<f64>) -> Vec<Vec<f64>> {
    let matrix = pose.to_homogeneous();
    (0..4).map(|r| (0..4).map(|c| matrix[(r, c)]).collect()).collect()
}
