//! A real slide's own error: what the laser does for a commanded travel d.
//!
//! The seed paper's slide moves the laser by exactly d along its baseline
//! (eq. (4): the origin `(-L cos(alpha), 0, L sin(alpha))`, L = L0 - d). A
//! simulated slide here moves it by `scale d` (a lead screw's pitch error, a
//! belt's stretch, a steps-per-mm setting) along an axis turned by
//! `angle_deg` from the baseline, within the plane of the baseline and the
//! camera's optical axis. The stripe then shows the laser plane of
//! L = L0 - k d with `k = scale cos(angle)` (see `alacs_model::laser`): the
//! turned part of the motion lies in the laser plane, lights no other point
//! and only moves the laser's origin, which casts the shadows.

use alacs_model::LaserModel;
use nalgebra::{Point3, Vector3};
use serde_json::{Value, json};

use crate::{Error, Result};

/// The largest slide angle simulated, degrees: beyond, a mounting is not
/// "at an angle" but wrong.
pub const MAX_SLIDE_ANGLE_DEG: f64 = 30.0;

/// A slide's scale error and the angle of its axis to the laser's baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlideError {
    /// The laser's travel per commanded mm along the slide's axis (1: exact).
    pub scale: f64,
    /// The angle between the slide's axis and the baseline, degrees, in the
    /// plane of the baseline and the camera's optical axis.
    pub angle_deg: f64,
}

impl Default for SlideError {
    fn default() -> Self {
        Self { scale: 1.0, angle_deg: 0.0 }
    }
}

impl SlideError {
    /// Checks the ranges: the scale must give a k within
    /// [`alacs_model::SLIDE_SCALE_RANGE`], the angle within
    /// +-[`MAX_SLIDE_ANGLE_DEG`].
    pub fn validate(&self) -> Result<()> {
        if !(self.angle_deg.is_finite() && self.angle_deg.abs() <= MAX_SLIDE_ANGLE_DEG) {
            return Err(Error::InvalidOptions(format!(
                "the slide angle must lie within +-{MAX_SLIDE_ANGLE_DEG} deg, got {}",
                self.angle_deg
            )));
        }
        let (lo, hi) = alacs_model::SLIDE_SCALE_RANGE;
        let k = self.scale * self.angle_deg.to_radians().cos();
        if !(self.scale.is_finite() && (lo..=hi).contains(&k)) {
            return Err(Error::InvalidOptions(format!(
                "the slide scale {} at {} deg gives k = {k}, outside [{lo}, {hi}]",
                self.scale, self.angle_deg
            )));
        }
        Ok(())
    }

    /// The laser model the stripe shows on this slide: `nominal` with its
    /// slide scale k multiplied by `scale cos(angle)`.
    pub fn apply(&self, nominal: &LaserModel) -> LaserModel {
        nominal
            .with_slide_scale(nominal.slide_scale * self.scale * self.angle_deg.to_radians().cos())
    }

    /// The laser's origin at commanded travel `slide_mm` for `laser`, a model
    /// this slide gave ([`Self::apply`]): its origin at d = 0 moved along the
    /// slide's axis, by the travel its k implies.
    pub fn origin_in_camera(&self, laser: &LaserModel, slide_mm: f64) -> Point3<f64> {
        let (sin_a, cos_a) = laser.alpha_rad.sin_cos();
        let (sin_t, cos_t) = self.angle_deg.to_radians().sin_cos();
        // The baseline (where eq. (4)'s origin moves as d grows) and the
        // in-plane direction the axis turns towards.
        let baseline = Vector3::new(cos_a, 0.0, -sin_a);
        let in_plane = Vector3::new(sin_a, 0.0, cos_a);
        let travel_mm = slide_mm * laser.slide_scale / cos_t;
        laser.origin_in_camera(0.0) + travel_mm * (cos_t * baseline + sin_t * in_plane)
    }

    /// truth.json's `slide` object.
    pub fn to_json(&self) -> Value {
        json!({ "scale": self.scale, "angle_deg": self.angle_deg })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_origin_of_an_angled_slide_stays_on_the_plane_its_k_gives() {
        let slide = SlideError { scale: 1.004, angle_deg: 7.0 };
        let laser = slide.apply(&LaserModel::seed_paper());
        assert!((laser.slide_scale - 1.004 * 7.0_f64.to_radians().cos()).abs() < 1e-15);
        for slide_mm in [0.0, 50.0, 200.0] {
            let origin = slide.origin_in_camera(&laser, slide_mm);
            let plane = laser.plane_in_camera(slide_mm);
            assert!(plane.signed_distance_mm(&origin).abs() < 1e-9, "at {slide_mm} mm");
            // The origin travelled `scale d`.
            let travelled = (origin - laser.origin_in_camera(0.0)).norm();
            assert!((travelled - 1.004 * slide_mm).abs() < 1e-9);
        }
        assert!(SlideError { scale: 1.0, angle_deg: 45.0 }.validate().is_err());
        assert!(SlideError { scale: 0.5, angle_deg: 0.0 }.validate().is_err());
        assert!(SlideError::default().validate().is_ok());
    }
}
