//! Helpers shared by alacs-locate's tests.

// Each test binary uses some of them.
#![allow(dead_code)]

use alacs_locate::{FrameImages, Localization, LocateOptions, Prior, locate};
use alacs_model::{Camera, Fidelity, LaserModel};
use nalgebra::Point3;

/// The seed paper's laser.
pub fn laser() -> LaserModel {
    LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98)
}

/// Locates a fruit 800 mm ahead in `n` black frames (the laser hits
/// nothing) of the 5 MP camera at a fifth of its resolution, the slide at
/// `first_slide_mm` and then every 10 mm.
pub fn locate_in_black_frames(n: usize, first_slide_mm: f64) -> Localization {
    let camera = Camera::blackfly_s_5mp().scaled(0.2);
    let black = image::RgbImage::new(camera.width_px, camera.height_px);
    let frames: Vec<_> =
        (0..n).map(|k| FrameImages::from((&black, first_slide_mm + 10.0 * k as f64))).collect();
    let prior = Prior { rough_position_mm: Point3::new(0.0, 0.0, 800.0), fruit_radius_mm: 40.0 };
    locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap()
}
