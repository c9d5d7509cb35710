//! The seed paper's scanning strategy (Section 3): put the laser line on
//! the left half of the target fruit, then step the slide to the right.
//!
//! 1. Initialization: the slide travel that puts the laser plane through a
//!    point half a fruit radius left of the rough fruit centre, from the
//!    inverse model ([`LaserModel::slide_for_point`]).
//! 2. Interval scanning: four more frames, 10 mm apart (the paper's 4 x 1 cm).
//!
//! Increasing the slide travel d shortens L = L0 - d, which moves the plane
//! to +x (right in the image) by d / cos(alpha) at a given depth, so five
//! frames sweep about 42 mm: from the left half across the centre of an
//! 80 mm apple. The sweep is shifted, not cut, to stay within the stroke.

use nalgebra::{Point3, Vector3};

use crate::{LaserModel, SLIDE_STROKE_MM};

/// The strategy's settings; `Default` is the seed paper's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanStrategy {
    /// Frames per scan (the paper: 5).
    pub frames: usize,
    /// Slide step between frames, mm (the paper: 10).
    pub step_mm: f64,
    /// Where the first frame's laser plane crosses the fruit, as a fraction
    /// of the radius left of the centre (the paper: "the left half"; 0.5).
    pub start_left_of_centre: f64,
    /// Slide stroke, mm (the paper: 200).
    pub stroke_mm: f64,
}

impl Default for ScanStrategy {
    fn default() -> Self {
        Self { frames: 5, step_mm: 10.0, start_left_of_centre: 0.5, stroke_mm: SLIDE_STROKE_MM }
    }
}

/// The slide positions of one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanPlan {
    /// Slide travel of each frame, mm, ascending, all within the stroke.
    pub slides_mm: Vec<f64>,
    /// The first frame's travel before any shift into the stroke.
    pub unclamped_start_mm: f64,
    /// Whether the sweep had to be shifted to fit the stroke (the first
    /// frame is then not on the left half of the fruit).
    pub shifted: bool,
}

impl ScanStrategy {
    /// The plan for a fruit roughly at `rough_centre_in_camera` with radius
    /// `radius_mm` (a prior: the paper's apples are 35-45 mm).
    pub fn plan(
        &self,
        laser: &LaserModel,
        rough_centre_in_camera: &Point3<f64>,
        radius_mm: f64,
    ) -> ScanPlan {
        let start_point =
            rough_centre_in_camera - Vector3::x() * (self.start_left_of_centre * radius_mm);
        let start_mm = laser.slide_for_point(&start_point);
        let sweep_mm = self.step_mm * self.frames.saturating_sub(1) as f64;
        // Shift the whole sweep into [0, stroke]; a sweep longer than the
        // stroke starts at 0 and its end is clamped.
        let latest_start = (self.stroke_mm - sweep_mm).max(0.0);
        let first_mm = if start_mm.is_finite() { start_mm.clamp(0.0, latest_start) } else { 0.0 };
        let slides_mm = (0..self.frames)
            .map(|k| (first_mm + self.step_mm * k as f64).min(self.stroke_mm))
            .collect();
        ScanPlan { slides_mm, unclamped_start_mm: start_mm, shifted: first_mm != start_mm }
    }
}
