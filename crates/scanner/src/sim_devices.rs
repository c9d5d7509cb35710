//! A rig backed by the simulator: the slide, camera and laser of a
//! [`SimulatedScan`]'s scene.
//!
//! The devices share one state (slide position, laser, a simulated clock).
//! Nothing sleeps unless asked ([`SimulatedRigOptions::realtime`]): the
//! clock adds what each operation would take on a real rig (the slide's
//! travel at its speed plus settling, the camera's frame time, the laser's
//! switching time), and a timeout is reported when that would-be time
//! exceeds it, the same way on every run.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use alacs_model::SLIDE_STROKE_MM;
use alacs_sim::{Exposure, SimulatedScan};
use image::RgbImage;

use crate::hardware::{FrameCamera, LaserSwitch, Rig, ScanRig, Slide};
use crate::{Device, Error, Result};

/// How the simulated devices behave. `Default`: a 200 mm stroke at
/// 50 mm/s with 50 ms settling, starting at 0 mm; 30 ms per frame; 2 ms to
/// switch the laser; no sleeping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedRigOptions {
    /// Slide stroke, mm.
    pub stroke_mm: f64,
    /// Slide speed, mm/s.
    pub speed_mm_per_s: f64,
    /// Time the slide needs to settle after a move.
    pub settle: Duration,
    /// Where the slide starts, mm.
    pub start_mm: f64,
    /// Exposure plus readout of one frame.
    pub frame_time: Duration,
    /// Time the laser needs to switch on or off.
    pub laser_switch: Duration,
    /// Sleep for the would-be times as well (a demonstration in real time).
    pub realtime: bool,
}

impl Default for SimulatedRigOptions {
    fn default() -> Self {
        Self {
            stroke_mm: SLIDE_STROKE_MM,
            speed_mm_per_s: DEFAULT_SPEED_MM_PER_S,
            settle: Duration::from_millis(50),
            start_mm: 0.0,
            frame_time: Duration::from_millis(30),
            laser_switch: Duration::from_millis(2),
            realtime: false,
        }
    }
}

/// A lead-screw slide's travel speed: a 200 mm stroke in 4 s.
const DEFAULT_SPEED_MM_PER_S: f64 = 50.0;

/// What the three devices share.
#[derive(Debug)]
struct RigState {
    slide_mm: f64,
    laser_on: bool,
    clock: Duration,
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
        if !(0.0..=options.stroke_mm).contains(&options.start_mm) {
            return invalid(format!(
                "start {} mm is outside the stroke 0..{} mm",
                options.start_mm, options.stroke_mm
            ));
        }
        let state = Arc::new(Mutex::new(RigState {
            slide_mm: options.start_mm,
            laser_on: false,
            clock: Duration::ZERO,
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
        lock(&self.state).slide_mm
    }
}

impl Slide for SimulatedSlide {
    fn stroke_mm(&self) -> f64 {
        self.options.stroke_mm
    }

    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> Result<f64> {
        let stroke_mm = self.options.stroke_mm;
        if !(target_mm.is_finite() && (0.0..=stroke_mm).contains(&target_mm)) {
            return Err(Error::OutOfStroke { step: None, target_mm, stroke_mm });
        }
        let mut state = lock(&self.state);
        let travel_mm = target_mm - state.slide_mm;
        if travel_mm == 0.0 {
            return Ok(target_mm);
        }
        let speed = self.options.speed_mm_per_s;
        let moving = Duration::from_secs_f64(travel_mm.abs() / speed);
        let needed = moving + self.options.settle;
        if needed > timeout {
            // The slide moves until the timeout and stops there.
            let done_mm = (speed * timeout.as_secs_f64()).min(travel_mm.abs());
            state.slide_mm += done_mm.copysign(travel_mm);
            spend(&mut state, timeout, self.options.realtime);
            return Err(Error::Timeout {
                device: Device::Slide,
                step: None,
                timeout,
                detail: format!(
                    "the move of {:.1} mm needs {:.3} s at {speed} mm/s with settling; stopped at {:.3} mm",
                    travel_mm.abs(),
                    needed.as_secs_f64(),
                    state.slide_mm
                ),
            });
        }
        state.slide_mm = target_mm;
        spend(&mut state, needed, self.options.realtime);
        Ok(target_mm)
    }

    fn position_mm(&mut self) -> Result<f64> {
        Ok(lock(&self.state).slide_mm)
    }
}

impl FrameCamera for SimulatedCamera {
    fn capture(&mut self, timeout: Duration) -> Result<RgbImage> {
        let (slide_mm, laser_on, index) = {
            let mut state = lock(&self.state);
            if self.options.frame_time > timeout {
                spend(&mut state, timeout, self.options.realtime);
                return Err(Error::Timeout {
                    device: Device::Camera,
                    step: None,
                    timeout,
                    detail: format!("a frame takes {:.3} s", self.options.frame_time.as_secs_f64()),
                });
            }
            spend(&mut state, self.options.frame_time, self.options.realtime);
            // Laser-on and laser-off captures are numbered apart, so that a
            // scan at the plan's positions renders the bytes of
            // `SimulatedScan::render_frame`.
            let counter =
                if state.laser_on { &mut state.captures_on } else { &mut state.captures_off };
            let index = *counter;
            *counter += 1;
            (state.slide_mm, state.laser_on, index)
        };
        Ok(self.scan.render_exposed(slide_mm, laser_on, index, self.exposure.0)?)
    }

    fn set_exposure_us(&mut self, exposure_us: f64) -> Result<f64> {
        self.exposure.set_exposure_us(exposure_us)
    }

    fn set_gain_db(&mut self, gain_db: f64) -> Result<f64> {
        self.exposure.set_gain_db(gain_db)
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
