//! The continuous sweep: the slide runs through the plan's positions at
//! constant speed while the camera captures on the way, instead of the
//! seed's stop-and-go (move, settle, capture, five times).
//!
//! 1. With the laser off, one time-stamped reference frame: it tells the
//!    exposure time (so the speed can keep the stripe's smear below
//!    [`Sweep::max_smear_px`]), and it is the laser-off frame of every
//!    frame when the scan differences (the camera and the scene stand
//!    still; only the laser moves).
//! 2. The speed: the smaller of [`Sweep::max_speed_mm_per_s`], the speed
//!    at which the stripe on the nearest fruit's front moves
//!    `max_smear_px` during the exposure, and the speed at which the slide
//!    covers half the plan's smallest step in one frame time (so that no
//!    position is passed while a frame is read out).
//! 3. The slide enters the plan from the end nearer to it (a slide inside
//!    the plan's span first moves to its nearer end) and runs to the other
//!    end without stopping; the laser is on.
//! 4. Per planned position: position reports until the slide is within
//!    half an exposure's travel of it, then a frame. The frame's slide
//!    position is the slide's position at mid-exposure, interpolated
//!    between the reports before and after it ([`SlideReport::position_at`]).
//!
//! The frames keep those positions: localization triangulates each frame
//! with where the laser was at the middle of its exposure. The stripe's
//! smear is symmetric about that position, so its centre is unbiased.

use std::time::{Duration, SystemTime};

use alacs_model::{Camera, LaserModel, ScanPlan};
use image::RgbImage;
use nalgebra::Point3;

use crate::hardware::{Rig, SlideReport, TimedFrame};
use crate::{Error, Result, Step};

/// The settings of a continuous sweep ([`crate::ScanMode::Continuous`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// The ALACS camera (camera.yaml): how fast the stripe moves in the
    /// image for a given slide speed.
    pub camera: Camera,
    /// The fastest sweep, mm/s (the slide may limit it further).
    pub max_speed_mm_per_s: f64,
    /// The most the stripe may move on the fruit during one exposure,
    /// pixels: well under its width, so that the smeared stripe is still
    /// one narrow line.
    pub max_smear_px: f64,
}

/// A stripe of the seed's laser is 3-5 px wide (its full width at half
/// maximum) on the 5 MP camera: a smear of 1 px widens it by a fraction.
pub const DEFAULT_MAX_SMEAR_PX: f64 = 1.0;

/// The top speed of a 200 mm ball-screw slide; slower slides limit it themselves.
pub const DEFAULT_MAX_SWEEP_SPEED_MM_PER_S: f64 = 200.0;

impl Sweep {
    /// A sweep for `camera` with the default speed and smear limits.
    pub fn new(camera: Camera) -> Self {
        Self {
            camera,
            max_speed_mm_per_s: DEFAULT_MAX_SWEEP_SPEED_MM_PER_S,
            max_smear_px: DEFAULT_MAX_SMEAR_PX,
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::InvalidInput(format!("continuous sweep: {m}")));
        self.camera.validate().map_err(|e| Error::InvalidInput(format!("sweep camera: {e}")))?;
        if !(self.max_speed_mm_per_s.is_finite() && self.max_speed_mm_per_s > 0.0) {
            return invalid(format!("speed {} mm/s must be positive", self.max_speed_mm_per_s));
        }
        if !(self.max_smear_px.is_finite() && self.max_smear_px > 0.0) {
            return invalid(format!("smear {} px must be positive", self.max_smear_px));
        }
        Ok(())
    }

    /// How many pixels the stripe moves per mm of slide travel on the
    /// front of a fruit at `centre_mm` with `radius_mm` (a surface facing
    /// the camera): the laser plane's shift along the image's x per mm of
    /// slide, over the depth, times the focal length.
    pub fn stripe_px_per_slide_mm(
        &self,
        laser: &LaserModel,
        centre_mm: &Point3<f64>,
        radius_mm: f64,
        slide_mm: f64,
    ) -> f64 {
        let plane = laser.plane_in_camera(slide_mm);
        let norm = plane.normal.norm();
        let shift_along_normal_mm =
            (laser.plane_in_camera(slide_mm + 1.0).offset_mm - plane.offset_mm).abs() / norm;
        // The plane's trace on a surface facing the camera moves along x
        // by the normal's shift over the normal's x part; a plane nearly
        // parallel to the image's x axis is capped (it does not occur in
        // an ALACS, whose plane stands across the image).
        let normal_x = (plane.normal.x / norm).abs().max(0.1);
        let depth_mm = (centre_mm.z - radius_mm).max(MIN_DEPTH_MM);
        self.camera.fx_px * shift_along_normal_mm / normal_x / depth_mm
    }
}

/// Depths nearer than this are treated as this for the smear (a rough
/// position that near is refused by the plan anyway).
const MIN_DEPTH_MM: f64 = 100.0;

/// One frame of the sweep, before the controller turns it into a
/// [`crate::CapturedFrame`].
pub(crate) struct SweptFrame {
    pub planned_slide_mm: f64,
    pub slide_mm: f64,
    pub image: RgbImage,
    /// When the frame arrived (the host's clock).
    pub captured_at: SystemTime,
}

/// What the sweep captured: its frames, the reference laser-off frame, the
/// fastest the slide went over a frame (measured from its reports; the
/// commanded speed where no frame saw it move).
pub(crate) struct SweepCapture {
    pub frames: Vec<SweptFrame>,
    pub reference_off: RgbImage,
    pub reference_at: SystemTime,
    pub speed_mm_per_s: f64,
}

/// Runs the sweep of `plan` (ascending positions) over `fruit` (centres
/// and radii in the ALACS camera frame). The metering (if any) is done;
/// the laser's state is whatever it was. `progress` is called after each
/// image.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_sweep(
    sweep: &Sweep,
    laser: &LaserModel,
    rig: &mut Rig<'_>,
    plan: &ScanPlan,
    fruit: &[(Point3<f64>, f64)],
    move_timeout: Duration,
    capture_timeout: Duration,
    progress: &mut dyn FnMut(),
) -> Result<SweepCapture> {
    let (Some(&first_mm), Some(&last_mm)) = (plan.slides_mm.first(), plan.slides_mm.last()) else {
        return Err(Error::InvalidInput("the plan has no frames".into()));
    };
    // 1. The reference frame, laser off.
    rig.laser.set(false).map_err(|e| e.at(Step::Laser { frame: 0, on: false }))?;
    let capture_step = |laser_on| Step::Capture { frame: 0, laser_on };
    let reference_step = Step::Sweep { frame: 0, target_mm: first_mm };
    let before = rig.slide.report().map_err(|e| e.at(reference_step))?;
    let reference =
        rig.camera.capture_timed(capture_timeout).map_err(|e| e.at(capture_step(false)))?;
    let reference_at = SystemTime::now();
    let after = rig.slide.report().map_err(|e| e.at(reference_step))?;
    progress();
    let frame_time = after.at.saturating_duration_since(before.at).max(reference.exposure);

    // 2. The speed.
    let exposure_s = reference.exposure.as_secs_f64();
    let px_per_mm = fruit
        .iter()
        .map(|(centre, radius)| {
            let at_mm = 0.5 * (first_mm + last_mm);
            sweep.stripe_px_per_slide_mm(laser, centre, *radius, at_mm)
        })
        .fold(0.0, f64::max);
    let mut speed = sweep.max_speed_mm_per_s;
    if px_per_mm > 0.0 && exposure_s > 0.0 {
        speed = speed.min(sweep.max_smear_px / (px_per_mm * exposure_s));
    }
    let smallest_step_mm = plan
        .slides_mm
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|s| *s > 0.0)
        .fold(f64::INFINITY, f64::min);
    if smallest_step_mm.is_finite() && !frame_time.is_zero() {
        speed = speed.min(0.5 * smallest_step_mm / frame_time.as_secs_f64());
    }

    // 3. The direction: in from the nearer end.
    let at_mm = after.position_mm;
    let ascending = (at_mm - first_mm).abs() <= (at_mm - last_mm).abs();
    let (entry_mm, exit_mm) = if ascending { (first_mm, last_mm) } else { (last_mm, first_mm) };
    let inside = if ascending { at_mm > first_mm } else { at_mm < last_mm };
    // A plan of one position is no sweep: the slide goes there and stands.
    if inside || entry_mm == exit_mm {
        let step = Step::Move { frame: 0, target_mm: entry_mm };
        rig.slide.move_to(entry_mm, move_timeout).map_err(|e| e.at(step))?;
    }
    let order: Vec<f64> = if ascending {
        plan.slides_mm.clone()
    } else {
        plan.slides_mm.iter().rev().copied().collect()
    };
    let direction = if ascending { 1.0 } else { -1.0 };
    rig.laser.set(true).map_err(|e| e.at(Step::Laser { frame: 0, on: true }))?;
    if entry_mm != exit_mm {
        let step = Step::Sweep { frame: 0, target_mm: entry_mm };
        rig.slide.start_move(exit_mm, speed).map_err(|e| e.at(step))?;
    }

    // 4. A frame as the slide passes each position.
    let lead_mm = 0.5 * speed * exposure_s;
    let mut frames = Vec::with_capacity(order.len());
    // The fastest the slide went over a frame (between the reports around
    // it): the speed that smeared the stripe most.
    let mut fastest_mm_per_s: f64 = 0.0;
    let mut started: Option<SlideReport> = None;
    for (k, &target_mm) in order.iter().enumerate() {
        let step = Step::Sweep { frame: k, target_mm };
        let before = loop {
            let report = rig.slide.report().map_err(|e| e.at(step))?;
            let start = *started.get_or_insert(report);
            if !report.position_mm.is_finite() {
                return Err(Error::Device {
                    device: crate::Device::Slide,
                    step: Some(step),
                    message: format!("reported position {}", report.position_mm),
                });
            }
            let to_go_mm = direction * (target_mm - report.position_mm);
            if to_go_mm <= lead_mm {
                break report;
            }
            if !report.moving {
                return Err(Error::PositionMismatch {
                    step: Some(step),
                    target_mm,
                    reached_mm: report.position_mm,
                    tolerance_mm: lead_mm,
                });
            }
            within(move_timeout, &start, &report, step, || {
                format!("sweeping at {speed:.1} mm/s, still at {:.3} mm", report.position_mm)
            })?;
        };
        let frame: TimedFrame = rig
            .camera
            .capture_timed(capture_timeout)
            .map_err(|e| e.at(Step::Capture { frame: k, laser_on: true }))?;
        let captured_at = SystemTime::now();
        let after = rig.slide.report().map_err(|e| e.at(step))?;
        let slide_mm = before.position_at(&after, frame.mid_exposure());
        let span_s = after.at.saturating_duration_since(before.at).as_secs_f64();
        if span_s > 0.0 {
            fastest_mm_per_s =
                fastest_mm_per_s.max((after.position_mm - before.position_mm).abs() / span_s);
        }
        progress();
        frames.push(SweptFrame {
            planned_slide_mm: target_mm,
            slide_mm,
            image: frame.image,
            captured_at,
        });
    }
    // The frames in the plan's (ascending) order.
    if !ascending {
        frames.reverse();
    }
    // The slide comes to rest at the plan's far end (it is decelerating
    // there already): wait for it, so that the rig stands when the scan
    // returns.
    let stop_step = Step::Sweep { frame: order.len().saturating_sub(1), target_mm: exit_mm };
    let start = rig.slide.report().map_err(|e| e.at(stop_step))?;
    let mut report = start;
    while report.moving {
        within(move_timeout, &start, &report, stop_step, || {
            format!("the slide did not stop; at {:.3} mm", report.position_mm)
        })?;
        report = rig.slide.report().map_err(|e| e.at(stop_step))?;
    }
    Ok(SweepCapture {
        frames,
        reference_off: reference.image,
        reference_at,
        speed_mm_per_s: if fastest_mm_per_s > 0.0 { fastest_mm_per_s } else { speed },
    })
}

/// The slide's timeout at `step` once `report` came more than `timeout`
/// after `start` (the reports' own clock), with `detail`.
fn within(
    timeout: Duration,
    start: &SlideReport,
    report: &SlideReport,
    step: Step,
    detail: impl FnOnce() -> String,
) -> Result<()> {
    if report.at.saturating_duration_since(start.at) > timeout {
        return Err(Error::Timeout {
            device: crate::Device::Slide,
            step: Some(step),
            timeout,
            detail: detail(),
        });
    }
    Ok(())
}
