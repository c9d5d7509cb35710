//! Ground truth in the JSON shapes of FORMATS.md (truth.json).

use alacs_model::{Camera, LaserModel};
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
