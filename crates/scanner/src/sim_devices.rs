//! A rig backed by the simulator: the slide, camera and laser of a
//! [`SimulatedScan`]'s scene.
//!
//! The devices share one state (slide position, laser, a simulated clock).
//! Nothing sleeps unless asked ([`SimulatedRigOptions::realtime`]): the
//! clock adds what each operation would take on a real rig (the slide's
//! travel with its acceleration and top speed plus settling, the camera's
//! frame time, the laser's switching time, a position report's round
//! trip), and a timeout is reported when that would-be time exceeds it,
//! the same way on every run.
//!
//! The slide also sweeps ([`Slide::start_move`]): it moves on the clock
//! while the camera captures, the camera renders the laser smeared over
//! the slide's travel during the exposure
//! ([`SimulatedScan::render_moving`]), and time stamps are
//! `Instant`s: the rig's creation plus the simulated clock.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use alacs_model::SLIDE_STROKE_MM;
use alacs_sim::{Exposure, SimulatedScan};
use image::RgbImage;

use crate::hardware::{
    FrameCamera, LaserSwitch, Rig, ScanRig, Slide, SlideReport, TimedFrame, check_sweep_speed,
    check_target,
};
use crate::{Device, Error, Result};

/// How the simulated devices behave. `Default`: a 200 mm stroke, a top
/// speed of 50 mm/s reached at 500 mm/s^2 (GRBL's acceleration setting in
/// `devices/grbl_emulator.py`), 50 ms settling, starting at 0 mm; 30 ms per
/// frame; 2 ms to switch the laser; 5 ms per position report (a GRBL status
/// report's round trip at 115200 baud); no sleeping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedRigOptions {
    /// Slide stroke, mm.
    pub stroke_mm: f64,
    /// Slide top speed, mm/s.
    pub speed_mm_per_s: f64,
    /// Slide acceleration and deceleration, mm/s^2 (a trapezoidal profile).
    pub acceleration_mm_per_s2: f64,
    /// Time the slide needs to settle after a move.
    pub settle: Duration,
    /// Where the slide starts, mm.
    pub start_mm: f64,
    /// Exposure plus readout of one frame.
    pub frame_time: Duration,
    /// Time the laser needs to switch on or off.
    pub laser_switch: Duration,
    /// Time one position report takes ([`Slide::report`]).
    pub report_time: Duration,
    /// Sleep for the would-be times as well (a demonstration in real time).
    pub realtime: bool,
}

impl Default for SimulatedRigOptions {
    fn default() -> Self {
        Self {
            stroke_mm: SLIDE_STROKE_MM,
            speed_mm_per_s: DEFAULT_SPEED_MM_PER_S,
            acceleration_mm_per_s2: DEFAULT_ACCELERATION_MM_PER_S2,
            settle: Duration::from_millis(50),
            start_mm: 0.0,
            frame_time: Duration::from_millis(30),
            laser_switch: Duration::from_millis(2),
            report_time: Duration::from_millis(5),
            realtime: false,
        }
    }
}

/// A lead-screw slide's travel speed: a 200 mm stroke in 4 s.
const DEFAULT_SPEED_MM_PER_S: f64 = 50.0;

/// GRBL's acceleration in the emulator the rig's tests drive.
const DEFAULT_ACCELERATION_MM_PER_S2: f64 = 500.0;

/// A move on the simulated clock: a trapezoidal speed profile (or a
/// triangular one, where the top speed is not reached) from `from_mm` to
/// `to_mm`, begun at `start`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Motion {
    from_mm: f64,
    to_mm: f64,
    start: Duration,
    speed_mm_per_s: f64,
    acceleration_mm_per_s2: f64,
}

impl Motion {
    /// The peak speed and the time spent accelerating (as long as the time
    /// decelerating).
    fn ramp(&self) -> (f64, f64) {
        let distance = (self.to_mm - self.from_mm).abs();
        let (v, a) = (self.speed_mm_per_s, self.acceleration_mm_per_s2);
        let peak = v.min((distance * a).sqrt());
        (peak, peak / a)
    }

    /// How long the move takes, without settling.
    fn duration(&self) -> Duration {
        let distance = (self.to_mm - self.from_mm).abs();
        if distance == 0.0 {
            return Duration::ZERO;
        }
        let (peak, ramp) = self.ramp();
        // Two ramps cover peak * ramp; the rest runs at the peak speed.
        Duration::from_secs_f64(2.0 * ramp + (distance - peak * ramp) / peak)
    }

    /// Where the slide is at `clock` and whether it still moves.
    fn at(&self, clock: Duration) -> (f64, bool) {
        let total = self.duration().as_secs_f64();
        let t = clock.saturating_sub(self.start).as_secs_f64();
        if t >= total {
            return (self.to_mm, false);
        }
        let (peak, ramp) = self.ramp();
        let a = self.acceleration_mm_per_s2;
        let travelled = if t < ramp {
            0.5 * a * t * t
        } else if t <= total - ramp {
            0.5 * peak * ramp + peak * (t - ramp)
        } else {
            let left = total - t;
            (self.to_mm - self.from_mm).abs() - 0.5 * a * left * left
        };
        (self.from_mm + travelled.copysign(self.to_mm - self.from_mm), true)
    }
}

/// What the three devices share.
#[derive(Debug)]
struct RigState {
    /// Where the slide stands, or where its last move began.
    slide_mm: f64,
    /// The slide's move, until a device sees it ended.
    motion: Option<Motion>,
    laser_on: bool,
    clock: Duration,
    /// The `Instant` of clock 0, for time stamps.
    epoch: Instant,
    captures_on: u64,
    captures_off: u64,
}

type Shared = Arc<Mutex<RigState>>;

/// The shared state; a poisoned lock only means another device panicked
/// while holding it, and the state itself is always consistent.
fn lock(state: &Shared) -> MutexGuard<'_, RigState> {
    state.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Advances the simulated clock by `time` (and sleeps it, in real time).
fn spend(state: &mut RigState, time: Duration, realtime: bool) {
    state.clock += time;
    if realtime {
        std::thread::sleep(time);
    }
}

impl RigState {
    /// Where the slide is at the clock's time, and whether it moves; a move
    /// that has ended is put away.
    fn slide_now(&mut self) -> (f64, bool) {
        let Some(motion) = self.motion else { return (self.slide_mm, false) };
        let (at_mm, moving) = motion.at(self.clock);
        if !moving {
            self.slide_mm = at_mm;
            self.motion = None;
        }
        (at_mm, moving)
    }

    /// Waits (on the clock) until a move in progress has ended.
    fn finish_motion(&mut self, realtime: bool) {
        if let Some(motion) = self.motion {
            let end = motion.start + motion.duration();
            let wait = end.saturating_sub(self.clock);
            spend(self, wait, realtime);
            self.slide_now();
        }
    }

    /// The time stamp of the clock's time.
    fn instant(&self, clock: Duration) -> Instant {
        self.epoch + clock
    }
}

/// The simulated slide.
#[derive(Debug)]
pub struct SimulatedSlide {
    state: Shared,
    options: SimulatedRigOptions,
}

/// The simulated camera: renders the scene at the slide's position, with
/// the laser as it is switched, at its exposure and gain ([`ExposureSettings`]).
#[derive(Debug)]
pub struct SimulatedCamera {
    state: Shared,
    scan: Arc<SimulatedScan>,
    options: SimulatedRigOptions,
    exposure: ExposureSettings,
}

/// A simulated camera's exposure time and gain, set through the ranges a
/// machine-vision camera takes. The simulator renders each frame at these
/// settings ([`SimulatedScan::render_exposed`]): the light scales with the
/// exposure time, the full well clips, the gain amplifies signal and noise.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExposureSettings(pub Exposure);

impl ExposureSettings {
    /// The exposure times a simulated camera takes, microseconds.
    pub const EXPOSURE_RANGE_US: (f64, f64) = (1.0, 10.0e6);
    /// The gains a simulated camera takes, dB.
    pub const GAIN_RANGE_DB: (f64, f64) = (0.0, alacs_sim::MAX_GAIN_DB);

    /// Checks and sets the exposure time.
    pub fn set_exposure_us(&mut self, exposure_us: f64) -> Result<f64> {
        let (low, high) = Self::EXPOSURE_RANGE_US;
        if !(exposure_us.is_finite() && (low..=high).contains(&exposure_us)) {
            return Err(Error::Device {
                device: Device::Camera,
                step: None,
                message: format!("exposure {exposure_us} us is outside {low}-{high} us"),
            });
        }
        self.0.exposure_us = exposure_us;
        Ok(exposure_us)
    }

    /// Checks and sets the gain.
    pub fn set_gain_db(&mut self, gain_db: f64) -> Result<f64> {
        let (low, high) = Self::GAIN_RANGE_DB;
        if !(gain_db.is_finite() && (low..=high).contains(&gain_db)) {
            return Err(Error::Device {
                device: Device::Camera,
                step: None,
                message: format!("gain {gain_db} dB is outside {low}-{high} dB"),
            });
        }
        self.0.gain_db = gain_db;
        Ok(gain_db)
    }
}

/// The simulated laser switch.
#[derive(Debug)]
pub struct SimulatedLaser {
    state: Shared,
    options: SimulatedRigOptions,
}

/// The three simulated devices of one scene.
#[derive(Debug)]
pub struct SimulatedRig {
    /// The slide.
    pub slide: SimulatedSlide,
    /// The camera.
    pub camera: SimulatedCamera,
    /// The laser.
    pub laser: SimulatedLaser,
    scan: Arc<SimulatedScan>,
    state: Shared,
}

impl SimulatedRig {
    /// A rig looking at `scan`'s scene (its camera, true laser and
    /// lighting); the slide at `options.start_mm`, the laser off, the clock at 0.
    pub fn new(scan: Arc<SimulatedScan>, options: SimulatedRigOptions) -> Result<Self> {
        let invalid = |m: String| Err(Error::InvalidInput(format!("simulated rig: {m}")));
        if !(options.stroke_mm.is_finite() && options.stroke_mm > 0.0) {
            return invalid(format!("stroke {} mm must be positive", options.stroke_mm));
        }
        if !(options.speed_mm_per_s.is_finite() && options.speed_mm_per_s > 0.0) {
            return invalid(format!("speed {} mm/s must be positive", options.speed_mm_per_s));
        }
        let acceleration = options.acceleration_mm_per_s2;
        if !(acceleration.is_finite() && acceleration > 0.0) {
            return invalid(format!("acceleration {acceleration} mm/s^2 must be positive"));
        }
        if !(0.0..=options.stroke_mm).contains(&options.start_mm) {
            return invalid(format!(
                "start {} mm is outside the stroke 0..{} mm",
                options.start_mm, options.stroke_mm
            ));
        }
        let state = Arc::new(Mutex::new(RigState {
            slide_mm: options.start_mm,
            motion: None,
            laser_on: false,
            clock: Duration::ZERO,
            epoch: Instant::now(),
            captures_on: 0,
            captures_off: 0,
        }));
        Ok(Self {
            slide: SimulatedSlide { state: state.clone(), options },
            camera: SimulatedCamera {
                state: state.clone(),
                scan: scan.clone(),
                options,
                exposure: ExposureSettings::default(),
            },
            laser: SimulatedLaser { state: state.clone(), options },
            scan,
            state,
        })
    }

    /// The devices, borrowed for a scan.
    pub fn rig(&mut self) -> Rig<'_> {
        Rig { slide: &mut self.slide, camera: &mut self.camera, laser: &mut self.laser }
    }

    /// The simulated scene: the truth behind the frames.
    pub fn scan(&self) -> &SimulatedScan {
        &self.scan
    }

    /// The time the operations so far would have taken on a real rig.
    pub fn elapsed(&self) -> Duration {
        lock(&self.state).clock
    }

    /// Whether the laser is on now.
    pub fn laser_on(&self) -> bool {
        lock(&self.state).laser_on
    }

    /// The slide's position now, mm.
    pub fn slide_mm(&self) -> f64 {
        lock(&self.state).slide_now().0
    }
}

impl Slide for SimulatedSlide {
    fn stroke_mm(&self) -> f64 {
        self.options.stroke_mm
    }

    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> Result<f64> {
        check_target(target_mm, self.options.stroke_mm)?;
        let mut state = lock(&self.state);
        state.finish_motion(self.options.realtime);
        let travel_mm = target_mm - state.slide_mm;
        if travel_mm == 0.0 {
            return Ok(target_mm);
        }
        let motion = self.motion(&state, target_mm, self.options.speed_mm_per_s);
        let needed = motion.duration() + self.options.settle;
        if needed > timeout {
            // The slide moves until the timeout and stops there.
            let (done_mm, _) = motion.at(state.clock + timeout);
            state.slide_mm = done_mm;
            spend(&mut state, timeout, self.options.realtime);
            return Err(Error::Timeout {
                device: Device::Slide,
                step: None,
                timeout,
                detail: format!(
                    "the move of {:.1} mm needs {:.3} s at {} mm/s with settling; stopped at {:.3} mm",
                    travel_mm.abs(),
                    needed.as_secs_f64(),
                    self.options.speed_mm_per_s,
                    state.slide_mm
                ),
            });
        }
        state.slide_mm = target_mm;
        spend(&mut state, needed, self.options.realtime);
        Ok(target_mm)
    }

    fn position_mm(&mut self) -> Result<f64> {
        Ok(lock(&self.state).slide_now().0)
    }

    fn start_move(&mut self, target_mm: f64, speed_mm_per_s: f64) -> Result<()> {
        check_target(target_mm, self.options.stroke_mm)?;
        check_sweep_speed(speed_mm_per_s)?;
        let mut state = lock(&self.state);
        state.finish_motion(self.options.realtime);
        let speed = speed_mm_per_s.min(self.options.speed_mm_per_s);
        state.motion = Some(self.motion(&state, target_mm, speed));
        Ok(())
    }

    fn report(&mut self) -> Result<SlideReport> {
        let mut state = lock(&self.state);
        // The report holds the middle of the query's round trip.
        let half = self.options.report_time / 2;
        spend(&mut state, half, self.options.realtime);
        let (position_mm, moving) = state.slide_now();
        let at = state.instant(state.clock);
        spend(&mut state, self.options.report_time - half, self.options.realtime);
        Ok(SlideReport { position_mm, at, moving })
    }
}

impl SimulatedSlide {
    /// A move from where the slide stands to `target_mm`, beginning now.
    fn motion(&self, state: &RigState, target_mm: f64, speed_mm_per_s: f64) -> Motion {
        Motion {
            from_mm: state.slide_mm,
            to_mm: target_mm,
            start: state.clock,
            speed_mm_per_s,
            acceleration_mm_per_s2: self.options.acceleration_mm_per_s2,
        }
    }
}

impl FrameCamera for SimulatedCamera {
    fn capture(&mut self, timeout: Duration) -> Result<RgbImage> {
        Ok(self.capture_timed(timeout)?.image)
    }

    fn set_exposure_us(&mut self, exposure_us: f64) -> Result<f64> {
        self.exposure.set_exposure_us(exposure_us)
    }

    fn set_gain_db(&mut self, gain_db: f64) -> Result<f64> {
        self.exposure.set_gain_db(gain_db)
    }

    fn capture_timed(&mut self, timeout: Duration) -> Result<TimedFrame> {
        let exposure = Duration::from_secs_f64(self.exposure.0.exposure_us * 1e-6);
        let (slides_mm, laser_on, index, exposure_start) = {
            let mut state = lock(&self.state);
            // A frame takes its frame time, and at least its exposure.
            let frame_time = self.options.frame_time.max(exposure);
            if frame_time > timeout {
                spend(&mut state, timeout, self.options.realtime);
                return Err(Error::Timeout {
                    device: Device::Camera,
                    step: None,
                    timeout,
                    detail: format!("a frame takes {:.3} s", frame_time.as_secs_f64()),
                });
            }
            // The exposure begins now; where the slide is as it begins and ends.
            let start = state.clock;
            let (from_mm, _) = state.slide_now();
            let to_mm = state.motion.map_or(from_mm, |m| m.at(start + exposure).0);
            spend(&mut state, frame_time, self.options.realtime);
            state.slide_now();
            // Laser-on and laser-off captures are numbered apart, so that a
            // scan at the plan's positions renders the bytes of
            // `SimulatedScan::render_frame`.
            let counter =
                if state.laser_on { &mut state.captures_on } else { &mut state.captures_off };
            let index = *counter;
            *counter += 1;
            ([from_mm, to_mm], state.laser_on, index, state.instant(start))
        };
        let image = self.scan.render_moving(slides_mm, laser_on, index, self.exposure.0)?;
        Ok(TimedFrame { image, exposure_start, exposure })
    }
}

impl LaserSwitch for SimulatedLaser {
    fn set(&mut self, on: bool) -> Result<()> {
        let mut state = lock(&self.state);
        if state.laser_on != on {
            state.laser_on = on;
            spend(&mut state, self.options.laser_switch, self.options.realtime);
        }
        Ok(())
    }
}

impl ScanRig for SimulatedRig {
    fn rig(&mut self) -> Rig<'_> {
        SimulatedRig::rig(self)
    }

    fn describe(&self) -> String {
        "simulated rig".into()
    }

    fn simulated_time(&self) -> Option<Duration> {
        Some(self.elapsed())
    }
}
