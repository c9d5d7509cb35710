//! One goal's work, off the DDS event loop: the seed's scan on the rig and
//! the localization, with feedback per frame and cancellation between
//! device operations. Everything here is in the library's units (mm); the
//! conversion to ROS's metres happens at the edges ([`crate::node`]).

use std::cell::{Cell, RefCell};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use alacs_locate::{Localization, LocateOptions};
use alacs_model::{Camera, LaserModel};
use alacs_scanner::{
    CapturedScan, ControllerConfig, Device, Error as ScanError, FrameCamera, LaserSwitch, Rig,
    ScanController, Slide, SlideReport, TimedFrame,
};
use alacs_vision::{Region, StripeOptions, extract_stripe_rgb};
use image::RgbImage;
use nalgebra::Point3;

pub use alacs_scanner::ScanRig;

/// What a job reports while it runs.
#[derive(Debug)]
pub enum Progress {
    /// Frame `frame` (0-based) of `n_frames` was captured with the laser on
    /// at `slide_mm`, with `stripe_points` stripe points in it.
    Frame {
        /// 0-based frame index.
        frame: usize,
        /// Frames of the scan.
        n_frames: usize,
        /// Where the slide stood, mm.
        slide_mm: f64,
        /// Stripe points found in the frame.
        stripe_points: usize,
        /// The frame itself (published as sensor_msgs/Image).
        image: Arc<RgbImage>,
    },
}

/// How a job ended.
#[derive(Debug)]
pub enum Outcome {
    /// The scan ran and localization answered (found or not found).
    Localized {
        /// The answers, one per fruit scanned, in the order of the
        /// request's rough positions less those left out.
        localizations: Vec<Localization>,
        /// What the scan captured (its rough positions, frames, images).
        scan: Box<CapturedScan>,
        /// Rig and localization time.
        elapsed: Duration,
        /// Rough positions left out: the slide cannot reach their frames
        /// ([`JobRequest::leave_out_of_reach`]).
        out_of_reach: usize,
    },
    /// The goal was cancelled; the slide stopped where it was and the laser is off.
    Cancelled,
    /// A device or the localization failed; the laser is off.
    Failed(String),
}

/// A goal's inputs in the library's units.
#[derive(Debug, Clone)]
pub struct JobRequest {
    /// The rough fruit centres, mm, in the RGB-D frame when `in_rgbd`, else
    /// in the ALACS camera frame: one for a goal, up to
    /// [`alacs_model::MAX_SCAN_TARGETS`] scanned in one sweep.
    pub rough_positions_mm: Vec<Point3<f64>>,
    /// Whether the rough positions are in the RGB-D camera's frame.
    pub in_rgbd: bool,
    /// The fruit radius prior, mm.
    pub fruit_radius_mm: f64,
    /// Leave out fruit whose frames lie beyond the slide's stroke (a sweep
    /// over whatever the RGB-D camera detected) instead of failing the job
    /// (a goal names one fruit: out of reach is its answer).
    pub leave_out_of_reach: bool,
}

/// What a job needs besides the rig: the calibrated camera and laser and
/// the controller's configuration (alacs_from_rgbd among it).
#[derive(Debug, Clone)]
pub struct JobContext {
    /// The calibrated camera.
    pub camera: Camera,
    /// The calibrated laser.
    pub laser: LaserModel,
    /// The scan controller's settings; `fruit_radius_mm` is the goal's.
    pub config: ControllerConfig,
    /// Localization settings.
    pub locate: LocateOptions,
}

/// What the three watched devices share: the cancel flag, the laser's
/// state, the slide's last position, the frame count and the reporter.
struct Watch<'p> {
    cancel: &'p AtomicBool,
    laser_on: Cell<bool>,
    slide_mm: Cell<f64>,
    frame: Cell<usize>,
    n_frames: Cell<usize>,
    report: RefCell<&'p mut dyn FnMut(Progress)>,
}

/// The message of a device error that a cancel request caused.
pub const CANCELLED: &str = "the goal was cancelled";

impl Watch<'_> {
    /// A device error for `device` when a cancel request came.
    fn check(&self, device: Device) -> alacs_scanner::Result<()> {
        if self.cancel.load(Ordering::Relaxed) {
            Err(ScanError::Device { device, step: None, message: CANCELLED.into() })
        } else {
            Ok(())
        }
    }
}

/// The slide, stopped before its next move by a cancel request.
struct WatchedSlide<'a, 'p> {
    inner: &'a mut dyn Slide,
    watch: &'a Watch<'p>,
}

/// The camera, stopped before its next capture by a cancel request; every
/// laser frame is reported with its stripe points.
struct WatchedCamera<'a, 'p> {
    inner: &'a mut dyn FrameCamera,
    watch: &'a Watch<'p>,
}

/// The laser: switching on is refused after a cancel request, switching
/// off never.
struct WatchedLaser<'a, 'p> {
    inner: &'a mut dyn LaserSwitch,
    watch: &'a Watch<'p>,
}

impl Slide for WatchedSlide<'_, '_> {
    fn stroke_mm(&self) -> f64 {
        self.inner.stroke_mm()
    }

    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> alacs_scanner::Result<f64> {
        self.watch.check(Device::Slide)?;
        let reached = self.inner.move_to(target_mm, timeout)?;
        self.watch.slide_mm.set(reached);
        Ok(reached)
    }

    fn position_mm(&mut self) -> alacs_scanner::Result<f64> {
        self.inner.position_mm()
    }

    fn start_move(&mut self, target_mm: f64, speed_mm_per_s: f64) -> alacs_scanner::Result<()> {
        self.watch.check(Device::Slide)?;
        self.inner.start_move(target_mm, speed_mm_per_s)
    }

    fn report(&mut self) -> alacs_scanner::Result<SlideReport> {
        // A cancel stops a sweep at its next report (the controller then
        // switches the laser off; the slide ends its move).
        self.watch.check(Device::Slide)?;
        let report = self.inner.report()?;
        self.watch.slide_mm.set(report.position_mm);
        Ok(report)
    }
}

impl WatchedCamera<'_, '_> {
    /// Reports a laser frame as feedback (its stripe's points counted).
    fn observe(&self, image: RgbImage) -> RgbImage {
        if !self.watch.laser_on.get() {
            return image;
        }
        let region = Region::full(image.width(), image.height());
        let stripe_points = extract_stripe_rgb(&image, None, &region, &StripeOptions::orchard())
            .map(|points| points.len())
            .unwrap_or(0);
        let image = Arc::new(image);
        let frame = self.watch.frame.get();
        (self.watch.report.borrow_mut())(Progress::Frame {
            frame,
            n_frames: self.watch.n_frames.get(),
            slide_mm: self.watch.slide_mm.get(),
            stripe_points,
            image: Arc::clone(&image),
        });
        self.watch.frame.set(frame + 1);
        // The reporter keeps its copy only as long as it publishes it.
        Arc::try_unwrap(image).unwrap_or_else(|shared| (*shared).clone())
    }
}

impl FrameCamera for WatchedCamera<'_, '_> {
    fn capture(&mut self, timeout: Duration) -> alacs_scanner::Result<RgbImage> {
        self.watch.check(Device::Camera)?;
        let image = self.inner.capture(timeout)?;
        Ok(self.observe(image))
    }

    fn set_exposure_us(&mut self, exposure_us: f64) -> alacs_scanner::Result<f64> {
        self.inner.set_exposure_us(exposure_us)
    }

    fn set_gain_db(&mut self, gain_db: f64) -> alacs_scanner::Result<f64> {
        self.inner.set_gain_db(gain_db)
    }

    fn capture_timed(&mut self, timeout: Duration) -> alacs_scanner::Result<TimedFrame> {
        self.watch.check(Device::Camera)?;
        let frame = self.inner.capture_timed(timeout)?;
        Ok(TimedFrame { image: self.observe(frame.image), ..frame })
    }
}

impl LaserSwitch for WatchedLaser<'_, '_> {
    fn set(&mut self, on: bool) -> alacs_scanner::Result<()> {
        if on {
            self.watch.check(Device::Laser)?;
        }
        self.inner.set(on)?;
        self.watch.laser_on.set(on);
        Ok(())
    }
}

/// Runs one goal on `rig`: plans the seed's scan from the rough position,
/// scans (reporting each laser frame), switches the laser off and
/// localizes; where a fruit is not found for want of evidence, extends the
/// sweep beyond both ends ([`ScanController::localize_extending`]) and
/// localizes it again. `cancel` stops it between device operations; the laser is
/// off whenever this returns.
pub fn run_job(
    rig: &mut dyn ScanRig,
    context: &JobContext,
    request: &JobRequest,
    cancel: &AtomicBool,
    report: &mut dyn FnMut(Progress),
) -> Outcome {
    let start = Instant::now();
    let mut config = context.config.clone();
    config.fruit_radius_mm = request.fruit_radius_mm;
    if !request.in_rgbd {
        config.alacs_from_rgbd = nalgebra::Isometry3::identity();
    }
    let controller = match ScanController::new(context.laser, config) {
        Ok(controller) => controller,
        Err(e) => return Outcome::Failed(e.to_string()),
    };
    let roughs_mm = if request.leave_out_of_reach {
        let stroke_mm = rig.rig().slide.stroke_mm();
        within_reach(&controller, &request.rough_positions_mm, stroke_mm)
    } else {
        request.rough_positions_mm.clone()
    };
    let out_of_reach = request.rough_positions_mm.len() - roughs_mm.len();
    if roughs_mm.is_empty() {
        return Outcome::Failed(format!(
            "none of the {} fruit is within the slide's reach",
            request.rough_positions_mm.len()
        ));
    }
    let plan = controller.plan_targets(&roughs_mm).map(|(plan, _)| plan);
    let watch = Watch {
        cancel,
        laser_on: Cell::new(false),
        slide_mm: Cell::new(f64::NAN),
        frame: Cell::new(0),
        n_frames: Cell::new(
            plan.map_or(controller.config().strategy.frames, |p| p.slides_mm.len()),
        ),
        report: RefCell::new(report),
    };
    let scanned = {
        let devices = rig.rig();
        let mut slide = WatchedSlide { inner: devices.slide, watch: &watch };
        let mut camera = WatchedCamera { inner: devices.camera, watch: &watch };
        let mut laser = WatchedLaser { inner: devices.laser, watch: &watch };
        let mut watched = Rig { slide: &mut slide, camera: &mut camera, laser: &mut laser };
        controller.run_targets_with_progress(&mut watched, &roughs_mm, |_, _| {}).map(
            |mut captured| {
                // Not found in the sweep for want of evidence: frames
                // beyond both ends of it, then localization again.
                let localized = controller.localize_extending(
                    &mut watched,
                    &mut captured,
                    &context.camera,
                    &context.laser,
                    &context.locate,
                    |slides| watch.n_frames.set(watch.frame.get() + slides.len()),
                    |_, _| {},
                );
                (captured, localized)
            },
        )
    };
    // Whatever happened, the laser is off (the controller switched it off;
    // this covers a driver that failed to).
    let _ = rig.rig().laser.set(false);
    let (captured, answers) = match scanned {
        Ok(scanned) => scanned,
        Err(_) if cancel.load(Ordering::Relaxed) => return Outcome::Cancelled,
        Err(e) => return Outcome::Failed(e.to_string()),
    };
    match answers {
        // A device that failed during the extension fails the goal, as it
        // would have failed the sweep.
        Ok(localized) if localized.extension_error.is_some() => {
            if cancel.load(Ordering::Relaxed) {
                return Outcome::Cancelled;
            }
            Outcome::Failed(localized.extension_error.map(|e| e.to_string()).unwrap_or_default())
        }
        Ok(localized) => Outcome::Localized {
            localizations: localized.answers,
            elapsed: start.elapsed(),
            scan: Box::new(captured),
            out_of_reach,
        },
        Err(e) => Outcome::Failed(e.to_string()),
    }
}

/// The rough positions (RGB-D frame, mm) whose frames the slide can reach:
/// the scan of each alone lies within `stroke_mm` (a sweep's frames are
/// the union of its fruit's, so together they fit too).
fn within_reach(
    controller: &ScanController,
    roughs_mm: &[Point3<f64>],
    stroke_mm: f64,
) -> Vec<Point3<f64>> {
    roughs_mm
        .iter()
        .filter(|rough| {
            controller.plan(rough).is_ok_and(|plan| plan.first_beyond_stroke(stroke_mm).is_none())
        })
        .copied()
        .collect()
}
