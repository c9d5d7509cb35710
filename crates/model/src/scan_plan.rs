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
//!
//! Several fruit ([`ScanStrategy::plan_sweep`]): each fruit's five frames
//! as above, all in one sweep in ascending slide order, a frame shared
//! where two fruit's frames fall within [`SHARED_FRAME_MM`] of each other.
//!
//! 3. Extension ([`ScanStrategy::extension`]): where a fruit is not found
//!    in the sweep, a few more frames at the same step beyond each of its
//!    ends, so the line also crosses the fruit's outer thirds. A fruit half
//!    hidden by leaves may show only there, or only where the leaves do
//!    not shadow the laser (it comes from the side); a fruit found in the
//!    first sweep costs no extra frame.

use nalgebra::{Point3, Vector3};

use crate::{LaserModel, SLIDE_STROKE_MM};

/// Two planned frames of different fruit closer than this are taken once,
/// at the lower position: a quarter of the seed's 10 mm step, so each fruit
/// still gets its stripes about 10 mm apart, none moved by more than 2.5 mm
/// (localization triangulates with the slide position the frame was taken
/// at, so a moved frame costs no accuracy).
pub const SHARED_FRAME_MM: f64 = 2.5;

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
    /// Frames added where the sweep did not find the fruit, half beyond
    /// each end of it at the same step ([`ScanStrategy::extension`]); 0
    /// never extends. Four: with the paper's sweep from half a radius left
    /// of the centre, two 10 mm steps each side take the line across the
    /// whole of a 35-45 mm fruit.
    pub extension_frames: usize,
}

impl Default for ScanStrategy {
    fn default() -> Self {
        Self {
            frames: 5,
            step_mm: 10.0,
            start_left_of_centre: 0.5,
            stroke_mm: SLIDE_STROKE_MM,
            extension_frames: 4,
        }
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

impl ScanPlan {
    /// The first slide position outside `0..=stroke_mm` (or not finite),
    /// mm: a slide shorter than the strategy's cannot take it.
    pub fn first_beyond_stroke(&self, stroke_mm: f64) -> Option<f64> {
        self.slides_mm.iter().copied().find(|d| !(d.is_finite() && (0.0..=stroke_mm).contains(d)))
    }
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

    /// The slide positions that extend `plan`'s sweep where it did not
    /// find the fruit: [`ScanStrategy::extension_frames`] positions, half
    /// before its first frame and half after its last (the odd one after),
    /// at [`ScanStrategy::step_mm`], nearest first on each side (before,
    /// then after); those
    /// outside the stroke or within [`SHARED_FRAME_MM`] of a frame already
    /// taken are left out.
    pub fn extension(&self, plan: &ScanPlan) -> Vec<f64> {
        let first = plan.slides_mm.iter().copied().fold(f64::INFINITY, f64::min);
        let last = plan.slides_mm.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !(first.is_finite() && last.is_finite()) {
            return Vec::new();
        }
        let before = self.extension_frames / 2;
        let after = self.extension_frames - before;
        let within = |d: &f64| d.is_finite() && (0.0..=self.stroke_mm).contains(d);
        let below = (1..=before).map(|k| first - self.step_mm * k as f64).take_while(within);
        let above = (1..=after).map(|k| last + self.step_mm * k as f64).take_while(within);
        below
            .chain(above)
            .filter(|d| plan.slides_mm.iter().all(|taken| (d - taken).abs() >= SHARED_FRAME_MM))
            .collect()
    }

    /// One sweep for several fruit (rough centres and radius priors): each
    /// fruit's [`ScanStrategy::plan`], merged in ascending slide order, a
    /// frame within [`SHARED_FRAME_MM`] of the previous one taken once.
    /// `unclamped_start_mm` is the first fruit's, `shifted` whether any
    /// fruit's plan was shifted. With one fruit it is that fruit's plan.
    pub fn plan_sweep(&self, laser: &LaserModel, fruit: &[(Point3<f64>, f64)]) -> ScanPlan {
        let mut plans: Vec<ScanPlan> =
            fruit.iter().map(|(centre, radius_mm)| self.plan(laser, centre, *radius_mm)).collect();
        if plans.len() == 1 {
            return plans.remove(0);
        }
        let mut all: Vec<f64> = plans.iter().flat_map(|p| p.slides_mm.iter().copied()).collect();
        all.sort_by(f64::total_cmp);
        let mut slides_mm: Vec<f64> = Vec::with_capacity(all.len());
        for d in all {
            if slides_mm.last().is_none_or(|last| d - last >= SHARED_FRAME_MM) {
                slides_mm.push(d);
            }
        }
        ScanPlan {
            slides_mm,
            unclamped_start_mm: plans.first().map_or(f64::NAN, |p| p.unclamped_start_mm),
            shifted: plans.iter().any(|p| p.shifted),
        }
    }
}
