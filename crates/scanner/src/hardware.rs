//! The rig's devices as the controller sees them: three small, object-safe
//! traits. A real rig implements them in its own crate (over a serial
//! stepper controller, a GenICam camera, a GPIO line); this crate has the
//! simulated ones ([`crate::SimulatedRig`]).
//!
//! Every method reports failures as this crate's [`Error`](crate::Error),
//! naming its device ([`Error::Timeout`](crate::Error::Timeout),
//! [`Error::Device`](crate::Error::Device), ...) and leaving the step empty:
//! the controller adds the step of the scan.

use std::time::{Duration, Instant};

use image::RgbImage;

use crate::{Device, Error, Result};

/// The linear slide that carries the laser.
///
/// Positions are the slide travel d of FORMATS.md, in mm: the laser's travel
/// from its calibration position towards the camera, so that the laser-camera
/// distance is L = L0 - d. A driver whose axis counts the other way or from
/// another origin converts, so that the positions it takes and reports are
/// the d that laser.yaml was calibrated with.
///
/// A driver must guarantee:
/// - [`Slide::move_to`] returns only after the slide has stopped and settled
///   (no vibration left that moves the laser line by more than the
///   controller's position tolerance), and returns the position the encoder
///   reports then, not the commanded one;
/// - a target outside `0 ..= stroke_mm()` (or not finite) is refused with
///   [`Error::OutOfStroke`](crate::Error::OutOfStroke) before anything
///   moves: never clamped, never moved to the nearest end;
/// - when the move does not settle within the timeout it returns
///   [`Error::Timeout`](crate::Error::Timeout), stops the slide, and the
///   position is whatever [`Slide::position_mm`] reports afterwards.
pub trait Slide {
    /// The stroke, mm: positions `0 ..= stroke_mm` are reachable.
    fn stroke_mm(&self) -> f64;

    /// Moves to `target_mm` and waits until the slide has settled there, at
    /// most `timeout`; returns the settled position, mm.
    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> Result<f64>;

    /// The current position, mm, as the encoder reports it.
    fn position_mm(&mut self) -> Result<f64>;

    /// Starts a move to `target_mm` at no more than `speed_mm_per_s` and
    /// returns at once, while the slide moves (a continuous sweep: the
    /// controller captures frames on the way and asks where the slide was
    /// with [`Slide::report`]).
    ///
    /// A driver must guarantee: the same refusal of targets outside the
    /// stroke as [`Slide::move_to`], before anything moves; a speed that is
    /// not finite and positive is refused; the slide accelerates, runs at
    /// constant speed (the smaller of `speed_mm_per_s` and its own limit)
    /// and stops at the target without overshoot. Called while an earlier
    /// move has not ended, it may wait for it or refuse. The default refuses:
    /// a slide that cannot report while moving cannot sweep.
    fn start_move(&mut self, target_mm: f64, speed_mm_per_s: f64) -> Result<()> {
        let _ = (target_mm, speed_mm_per_s);
        Err(cannot_sweep(Device::Slide, "cannot start a move without waiting for it"))
    }

    /// Where the slide is now, while it moves or stands: the position the
    /// encoder (or the controller's step count) reports, the moment it held
    /// on the host's monotonic clock (the clock of the camera's
    /// [`TimedFrame`]s), and whether the slide is still moving. A driver
    /// stamps the report with the middle of its query's round trip and says
    /// how long that is. The default refuses.
    fn report(&mut self) -> Result<SlideReport> {
        Err(cannot_sweep(Device::Slide, "does not report its position while moving"))
    }
}

/// The refusal a driver owes a target outside `0 ..= stroke_mm` (or not
/// finite), before anything moves: [`Slide::move_to`]'s and
/// [`Slide::start_move`]'s first check.
pub fn check_target(target_mm: f64, stroke_mm: f64) -> Result<()> {
    if !(target_mm.is_finite() && (0.0..=stroke_mm).contains(&target_mm)) {
        return Err(Error::OutOfStroke { step: None, target_mm, stroke_mm });
    }
    Ok(())
}

/// The refusal a driver owes a sweep speed that is not finite and
/// positive ([`Slide::start_move`]).
pub fn check_sweep_speed(speed_mm_per_s: f64) -> Result<()> {
    if !(speed_mm_per_s.is_finite() && speed_mm_per_s > 0.0) {
        return Err(Error::Device {
            device: Device::Slide,
            step: None,
            message: format!("sweep speed {speed_mm_per_s} mm/s must be positive"),
        });
    }
    Ok(())
}

/// One position report of a moving slide ([`Slide::report`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlideReport {
    /// The slide travel d, mm.
    pub position_mm: f64,
    /// When the slide was there, on the host's monotonic clock.
    pub at: Instant,
    /// Whether the slide is still moving.
    pub moving: bool,
}

impl SlideReport {
    /// The position at `time` between `self` and a `later` report, by
    /// linear interpolation in time (exact at constant speed); a time
    /// outside the two reports takes the nearer one's position.
    pub fn position_at(&self, later: &SlideReport, time: Instant) -> f64 {
        let span = later.at.saturating_duration_since(self.at).as_secs_f64();
        if span <= 0.0 {
            return later.position_mm;
        }
        let t = (time.saturating_duration_since(self.at).as_secs_f64() / span).min(1.0);
        self.position_mm + t * (later.position_mm - self.position_mm)
    }
}

/// A frame with the time of its exposure ([`FrameCamera::capture_timed`]).
#[derive(Debug, Clone)]
pub struct TimedFrame {
    /// The frame, as [`FrameCamera::capture`] returns it.
    pub image: RgbImage,
    /// When the exposure began, on the host's monotonic clock (the clock
    /// of the slide's [`SlideReport`]s).
    pub exposure_start: Instant,
    /// The exposure time.
    pub exposure: Duration,
}

impl TimedFrame {
    /// The middle of the exposure: the moment a frame of a moving laser
    /// shows the laser at, on average.
    pub fn mid_exposure(&self) -> Instant {
        self.exposure_start + self.exposure / 2
    }
}

/// A device's refusal of a continuous sweep: the scan controller's
/// stop-and-go mode needs none of it.
fn cannot_sweep(device: Device, what: &str) -> Error {
    Error::Device {
        device,
        step: None,
        message: format!(
            "this {device} {what}, which a continuous sweep needs; scan in stop-and-go mode"
        ),
    }
}

/// The ALACS camera.
///
/// A driver must guarantee:
/// - the frame [`FrameCamera::capture`] returns was exposed entirely after
///   the call began: no frame buffered from before the slide moved or the
///   laser switched (flush the queue, or trigger in software);
/// - frames are RGB8 in the resolution and orientation of the calibrated
///   camera.yaml, not undistorted or rectified (localization undistorts
///   them with camera.yaml, eq. (3));
/// - exposure, gain and white balance stay fixed unless set through this
///   trait (the controller sets exposure and gain only while metering,
///   before the first frame), so that laser-off differencing compares like
///   with like; no auto-exposure of the camera's own;
/// - no frame within the timeout gives
///   [`Error::Timeout`](crate::Error::Timeout);
/// - exposure and gain set through [`FrameCamera::set_exposure_us`] and
///   [`FrameCamera::set_gain_db`] hold for every frame captured after the
///   call returns; a value the camera cannot take is refused with
///   [`Error::Device`](crate::Error::Device) naming its range, never
///   clamped silently; the returned value is the one the camera took
///   (rounded to its step).
pub trait FrameCamera {
    /// Captures one frame, waiting at most `timeout`.
    fn capture(&mut self, timeout: Duration) -> Result<RgbImage>;

    /// Sets the exposure time, microseconds; returns the one the camera took.
    fn set_exposure_us(&mut self, exposure_us: f64) -> Result<f64>;

    /// Sets the analogue gain, dB; returns the one the camera took.
    fn set_gain_db(&mut self, gain_db: f64) -> Result<f64>;

    /// Captures one frame as [`FrameCamera::capture`] does, with the start
    /// and length of its exposure on the host's monotonic clock (the
    /// clock of [`Slide::report`]): what a continuous sweep needs to know
    /// where the slide was. A driver says how its time stamp relates to the
    /// exposure (a trigger's latency, the camera's clock mapped to the
    /// host's). The default refuses.
    fn capture_timed(&mut self, timeout: Duration) -> Result<TimedFrame> {
        let _ = timeout;
        Err(cannot_sweep(Device::Camera, "does not time-stamp its exposures"))
    }
}

/// The line laser's on/off switch.
///
/// A driver must guarantee:
/// - when [`LaserSwitch::set`] returns, the laser emits steadily (on) or is
///   dark (off): any warm-up or switching time is waited out inside;
/// - switching to the state it is already in is harmless;
/// - `set(false)` may be called at any time, also after another device
///   failed: the controller switches the laser off whenever a scan stops.
pub trait LaserSwitch {
    /// Switches the laser on or off.
    fn set(&mut self, on: bool) -> Result<()>;
}

/// The three devices of a rig, borrowed for one scan.
pub struct Rig<'a> {
    /// The slide carrying the laser.
    pub slide: &'a mut dyn Slide,
    /// The camera.
    pub camera: &'a mut dyn FrameCamera,
    /// The laser's switch.
    pub laser: &'a mut dyn LaserSwitch,
}

/// A rig that owns its devices and lends them for one scan at a time: the
/// simulated rig, a rig of rig.toml (`alacs-rig`), the ROS node's rig.
pub trait ScanRig: Send {
    /// The devices, borrowed for one scan.
    fn rig(&mut self) -> Rig<'_>;
    /// A one-line description for logs and diagnostics ("simulated rig").
    fn describe(&self) -> String;
    /// For a simulated rig: the time its operations so far would have
    /// taken on a real rig (its simulated clock). `None` for real devices.
    fn simulated_time(&self) -> Option<Duration> {
        None
    }
}
