//! A rig built from rig.toml: its devices behind the scanner's traits, and
//! the rig check (`alacs rig check`).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use alacs_scanner::{
    Device, Error as DeviceError, FrameCamera, LaserSwitch, Rig, Slide, SlideReport, TimedFrame,
};
#[cfg(feature = "sim")]
use alacs_sim::SimulatedScan;
#[cfg(feature = "sim")]
use image::RgbImage;

use crate::config::{CameraDriver, LaserDriver, RigConfig, SlideDriver};
use crate::grbl::{self, GrblController, GrblLaser, GrblSlide};
use crate::{Error, Result};

/// The scene the simulated devices of a rig show (rig.toml's "sim"
/// drivers). Without the `sim` feature a rig has no simulated devices.
#[cfg(feature = "sim")]
pub type Scene = Arc<SimulatedScan>;
/// The scene the simulated devices of a rig show (none without the `sim`
/// feature).
#[cfg(not(feature = "sim"))]
pub type Scene = std::convert::Infallible;

/// What the devices did last, shared with a simulated camera so that it
/// renders the laser where the (possibly real) slide put it.
#[derive(Debug, Clone, Copy)]
struct Tracked {
    slide_mm: f64,
    /// When the slide reported `slide_mm` while moving (a sweep's report);
    /// `None` for a settled position.
    reported_at: Option<Instant>,
    laser_on: bool,
}

type Tracker = Arc<Mutex<Tracked>>;

fn lock(tracker: &Tracker) -> MutexGuard<'_, Tracked> {
    tracker.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A slide whose settled positions are tracked.
struct TrackedSlide {
    inner: Box<dyn Slide + Send>,
    tracker: Tracker,
}

impl TrackedSlide {
    /// Keeps where the slide was, and when if it was moving.
    fn track(&self, slide_mm: f64, reported_at: Option<Instant>) {
        let mut tracked = lock(&self.tracker);
        tracked.slide_mm = slide_mm;
        tracked.reported_at = reported_at;
    }
}

impl Slide for TrackedSlide {
    fn stroke_mm(&self) -> f64 {
        self.inner.stroke_mm()
    }

    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> alacs_scanner::Result<f64> {
        let at = self.inner.move_to(target_mm, timeout)?;
        self.track(at, None);
        Ok(at)
    }

    fn position_mm(&mut self) -> alacs_scanner::Result<f64> {
        let at = self.inner.position_mm()?;
        self.track(at, None);
        Ok(at)
    }

    fn start_move(&mut self, target_mm: f64, speed_mm_per_s: f64) -> alacs_scanner::Result<()> {
        self.inner.start_move(target_mm, speed_mm_per_s)
    }

    fn report(&mut self) -> alacs_scanner::Result<SlideReport> {
        let report = self.inner.report()?;
        self.track(report.position_mm, report.moving.then_some(report.at));
        Ok(report)
    }
}

/// A laser whose state is tracked (off after a failed switch: the scanner
/// switches it off whenever anything fails).
struct TrackedLaser {
    inner: Box<dyn LaserSwitch + Send>,
    tracker: Tracker,
}

impl LaserSwitch for TrackedLaser {
    fn set(&mut self, on: bool) -> alacs_scanner::Result<()> {
        let result = self.inner.set(on);
        lock(&self.tracker).laser_on = on && result.is_ok();
        result
    }
}

/// The simulator's camera on a rig: renders the scene with the laser where
/// the rig's slide reported it and as the rig's laser was switched.
#[cfg(feature = "sim")]
struct SceneCamera {
    scene: Scene,
    tracker: Tracker,
    captures_on: u64,
    captures_off: u64,
    exposure: alacs_scanner::ExposureSettings,
}

#[cfg(feature = "sim")]
impl FrameCamera for SceneCamera {
    fn capture(&mut self, timeout: Duration) -> alacs_scanner::Result<RgbImage> {
        Ok(self.capture_timed(timeout)?.image)
    }

    /// The frame shows the laser where the slide last reported it; its
    /// exposure is that report's moment, taken as instantaneous (the
    /// render cannot know where a real slide went while it rendered).
    fn capture_timed(&mut self, _timeout: Duration) -> alacs_scanner::Result<TimedFrame> {
        let Tracked { slide_mm, reported_at, laser_on } = *lock(&self.tracker);
        if !slide_mm.is_finite() {
            return Err(DeviceError::Device {
                device: Device::Camera,
                step: None,
                message: "the simulated camera renders the laser at the slide's position, and \
                          the slide has not reported one yet"
                    .into(),
            });
        }
        let exposure_start = reported_at.unwrap_or_else(Instant::now);
        let counter = if laser_on { &mut self.captures_on } else { &mut self.captures_off };
        let index = *counter;
        *counter += 1;
        let image =
            self.scene.render_exposed(slide_mm, laser_on, index, self.exposure.0).map_err(|e| {
                DeviceError::Device {
                    device: Device::Camera,
                    step: None,
                    message: format!("the simulated camera: {e}"),
                }
            })?;
        Ok(TimedFrame { image, exposure_start, exposure: Duration::ZERO })
    }

    fn set_exposure_us(&mut self, exposure_us: f64) -> alacs_scanner::Result<f64> {
        self.exposure.set_exposure_us(exposure_us)
    }

    fn set_gain_db(&mut self, gain_db: f64) -> alacs_scanner::Result<f64> {
        self.exposure.set_gain_db(gain_db)
    }
}

/// The devices as they are connected, one at a time (the rig check reports
/// each step).
struct Parts<'a> {
    config: &'a RigConfig,
    #[cfg_attr(not(feature = "sim"), allow(dead_code))]
    scene: Option<Scene>,
    tracker: Tracker,
    controller: Option<Arc<Mutex<GrblController>>>,
    grbl_slide: Option<GrblSlide>,
    slide: Option<TrackedSlide>,
    laser: Option<TrackedLaser>,
    camera: Option<Box<dyn FrameCamera + Send>>,
}

impl<'a> Parts<'a> {
    fn new(config: &'a RigConfig, scene: Option<Scene>) -> Self {
        Self {
            config,
            scene,
            tracker: Arc::new(Mutex::new(Tracked {
                slide_mm: f64::NAN,
                reported_at: None,
                laser_on: false,
            })),
            controller: None,
            grbl_slide: None,
            slide: None,
            laser: None,
            camera: None,
        }
    }

    #[cfg(feature = "sim")]
    fn simulated(&self, device: Device) -> alacs_scanner::Result<alacs_scanner::SimulatedRig> {
        let Some(scene) = &self.scene else {
            return Err(DeviceError::Device {
                device,
                step: None,
                message: "a simulated device needs a simulated scene, and none was given".into(),
            });
        };
        let options = alacs_scanner::SimulatedRigOptions {
            stroke_mm: self.config.slide.stroke_mm,
            ..Default::default()
        };
        alacs_scanner::SimulatedRig::new(Arc::clone(scene), options)
    }

    #[cfg(feature = "sim")]
    fn simulated_slide(&self) -> alacs_scanner::Result<Box<dyn Slide + Send>> {
        Ok(Box::new(self.simulated(Device::Slide)?.slide))
    }

    #[cfg(feature = "sim")]
    fn simulated_laser(&self) -> alacs_scanner::Result<Box<dyn LaserSwitch + Send>> {
        Ok(Box::new(self.simulated(Device::Laser)?.laser))
    }

    #[cfg(feature = "sim")]
    fn simulated_camera(&self) -> alacs_scanner::Result<(Box<dyn FrameCamera + Send>, String)> {
        let Some(scene) = self.scene.clone() else {
            return Err(DeviceError::Device {
                device: Device::Camera,
                step: None,
                message: "the simulated camera needs a simulated scene".into(),
            });
        };
        let detail =
            format!("simulated camera, {} x {} px", scene.camera.width_px, scene.camera.height_px);
        let camera = SceneCamera {
            scene,
            tracker: Arc::clone(&self.tracker),
            captures_on: 0,
            captures_off: 0,
            exposure: alacs_scanner::ExposureSettings::default(),
        };
        Ok((Box::new(camera), detail))
    }

    #[cfg(not(feature = "sim"))]
    fn simulated_slide(&self) -> alacs_scanner::Result<Box<dyn Slide + Send>> {
        Err(without_simulator(Device::Slide))
    }

    #[cfg(not(feature = "sim"))]
    fn simulated_laser(&self) -> alacs_scanner::Result<Box<dyn LaserSwitch + Send>> {
        Err(without_simulator(Device::Laser))
    }

    #[cfg(not(feature = "sim"))]
    fn simulated_camera(&self) -> alacs_scanner::Result<(Box<dyn FrameCamera + Send>, String)> {
        Err(without_simulator(Device::Camera))
    }

    /// Connects the slide (for GRBL: opens the port, soft reset, banner).
    fn connect_slide(&mut self) -> alacs_scanner::Result<String> {
        let slide = &self.config.slide;
        let (inner, detail): (Box<dyn Slide + Send>, String) = match slide.driver {
            SlideDriver::Grbl => {
                let controller = grbl::connect(slide)?;
                let mut grbl_slide = GrblSlide::new(Arc::clone(&controller), slide.clone());
                grbl_slide.check_settings()?;
                let state = grbl_slide.state()?;
                let detail = format!(
                    "GRBL 1.1 on {} at {} baud, axis {}, state {state}",
                    slide.port, slide.baud, slide.axis
                );
                // One handle homes, the other scans; both on the one controller.
                self.grbl_slide = Some(GrblSlide::new(Arc::clone(&controller), slide.clone()));
                self.controller = Some(controller);
                (Box::new(grbl_slide), detail)
            }
            SlideDriver::Sim => (
                self.simulated_slide()?,
                format!("simulated slide, stroke {} mm", self.config.slide.stroke_mm),
            ),
        };
        self.slide = Some(TrackedSlide { inner, tracker: Arc::clone(&self.tracker) });
        Ok(detail)
    }

    /// Homes a GRBL slide (`$H`); `None` when there is nothing to home.
    fn home_slide(&mut self) -> Option<alacs_scanner::Result<String>> {
        let grbl_slide = self.grbl_slide.as_mut()?;
        if !self.config.slide.home {
            return None;
        }
        Some(grbl_slide.home().map(|()| "homed ($H), idle".to_string()))
    }

    fn connect_laser(&mut self) -> alacs_scanner::Result<String> {
        let laser = &self.config.laser;
        let (inner, detail): (Box<dyn LaserSwitch + Send>, String) = match laser.driver {
            LaserDriver::GrblSpindle => {
                let controller = self.controller.clone().ok_or_else(|| missing(Device::Laser))?;
                let detail = format!(
                    "on the GRBL controller's spindle output: `{}` / `{}`",
                    laser.on_line(),
                    laser.off_command
                );
                let timeout = self.config.slide.command_timeout();
                (Box::new(GrblLaser::new(controller, laser.clone(), timeout)?), detail)
            }
            LaserDriver::SerialRelay => (
                Box::new(crate::relay::SerialRelayLaser::open(laser)?),
                format!("on the serial relay {} at {} baud", laser.port, laser.baud),
            ),
            LaserDriver::Sim => (self.simulated_laser()?, "simulated laser".to_string()),
        };
        let mut laser = TrackedLaser { inner, tracker: Arc::clone(&self.tracker) };
        // Whatever the controller did before, the laser starts off.
        laser.set(false)?;
        self.laser = Some(laser);
        Ok(detail)
    }

    fn connect_camera(&mut self) -> alacs_scanner::Result<String> {
        match self.config.camera.driver {
            #[cfg(feature = "genicam")]
            CameraDriver::Genicam => {
                let camera = crate::genicam::GenicamCamera::open(&self.config.camera.device)?;
                let detail = format!("GenICam camera {}", camera.describe());
                self.set_camera(Box::new(camera), detail)
            }
            #[cfg(not(feature = "genicam"))]
            CameraDriver::Genicam => Err(DeviceError::Device {
                device: Device::Camera,
                step: None,
                message: "GenICam cameras need alacs built with the cargo feature `genicam` \
                          (aravis: Debian libaravis-dev libusb-1.0-0-dev)"
                    .into(),
            }),
            CameraDriver::Sim => {
                let (camera, detail) = self.simulated_camera()?;
                self.set_camera(camera, detail)
            }
        }
    }

    /// Sets rig.toml's exposure and gain on the connected `camera`.
    fn set_camera(
        &mut self,
        mut camera: Box<dyn FrameCamera + Send>,
        detail: String,
    ) -> alacs_scanner::Result<String> {
        let exposure_us = camera.set_exposure_us(self.config.camera.exposure_us)?;
        let gain_db = camera.set_gain_db(self.config.camera.gain_db)?;
        self.camera = Some(camera);
        Ok(format!("{detail}, exposure {exposure_us} us, gain {gain_db} dB"))
    }
}

#[cfg(not(feature = "sim"))]
fn without_simulator(device: Device) -> DeviceError {
    DeviceError::Device {
        device,
        step: None,
        message: "\"sim\" devices need the simulator, and this alacs was built without it \
                  (cargo feature `sim`)"
            .into(),
    }
}

fn missing(device: Device) -> DeviceError {
    DeviceError::Device {
        device,
        step: None,
        message: "\"grbl-spindle\" needs the slide's GRBL controller, which is not connected"
            .into(),
    }
}

/// A rig of rig.toml, connected: its slide (homed when rig.toml asks), its
/// laser (off) and its camera.
pub struct RealRig {
    slide: TrackedSlide,
    laser: TrackedLaser,
    camera: Box<dyn FrameCamera + Send>,
    description: String,
}

impl std::fmt::Debug for RealRig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RealRig").field("description", &self.description).finish_non_exhaustive()
    }
}

impl RealRig {
    /// Connects the devices of `config`; simulated devices show `scene`.
    pub fn open(config: &RigConfig, scene: Option<Scene>) -> Result<Self> {
        let mut parts = Parts::new(config, scene);
        let mut description = vec![parts.connect_slide()?];
        if let Some(homed) = parts.home_slide() {
            homed?;
        }
        description.push(parts.connect_laser()?);
        description.push(parts.connect_camera()?);
        match (parts.slide, parts.laser, parts.camera) {
            (Some(slide), Some(laser), Some(camera)) => {
                Ok(Self { slide, laser, camera, description: description.join("; ") })
            }
            _ => Err(Error::Device(missing(Device::Slide))),
        }
    }

    /// The devices, borrowed for one scan.
    pub fn rig(&mut self) -> Rig<'_> {
        Rig { slide: &mut self.slide, camera: self.camera.as_mut(), laser: &mut self.laser }
    }

    /// The devices in one line.
    pub fn describe(&self) -> &str {
        &self.description
    }
}

impl Drop for RealRig {
    fn drop(&mut self) {
        // The laser is off on exit, whatever happened.
        let _ = self.laser.set(false);
    }
}

/// One step of the rig check.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckStep {
    /// What the step does ("move to 100 mm").
    pub name: String,
    /// The device it uses.
    pub device: Device,
    /// How long it took, s.
    pub seconds: f64,
    /// What it found, or why it failed.
    pub outcome: std::result::Result<String, String>,
}

/// Runs the rig check of `config`: connects the slide (and homes it when
/// rig.toml asks), the laser and the camera, moves the slide to 0, half
/// the stroke and the stroke, switches the laser on and off, and captures
/// a frame. `on_step` sees each step as it ends; the check stops at the
/// first failure and then switches the laser off (a last step). Returns
/// every step.
pub fn check_rig(
    config: &RigConfig,
    scene: Option<Scene>,
    on_step: &mut dyn FnMut(&CheckStep),
) -> Vec<CheckStep> {
    let mut steps: Vec<CheckStep> = Vec::new();
    let mut parts = Parts::new(config, scene);
    let mut run = |steps: &mut Vec<CheckStep>,
                   name: String,
                   device: Device,
                   action: &mut dyn FnMut() -> alacs_scanner::Result<String>|
     -> bool {
        let start = Instant::now();
        let outcome = action().map_err(|e| e.to_string());
        let step = CheckStep { name, device, seconds: start.elapsed().as_secs_f64(), outcome };
        on_step(&step);
        let ok = step.outcome.is_ok();
        steps.push(step);
        ok
    };
    let stroke = config.slide.stroke_mm;
    // A whole stroke at the feed rate, twice over, or the scan's move timeout.
    let move_timeout = Duration::from_secs_f64(
        (stroke / config.slide.feed_mm_per_min * 60.0 * 2.0).max(config.slide.move_timeout_s),
    );
    let passed = 'check: {
        if !run(&mut steps, "connect".into(), Device::Slide, &mut || parts.connect_slide()) {
            break 'check false;
        }
        if config.slide.home && parts.grbl_slide.is_some() {
            let ok = run(&mut steps, "home".into(), Device::Slide, &mut || {
                parts.home_slide().unwrap_or_else(|| Ok("nothing to home".into()))
            });
            if !ok {
                break 'check false;
            }
        }
        if !run(&mut steps, "connect".into(), Device::Laser, &mut || parts.connect_laser()) {
            break 'check false;
        }
        if !run(&mut steps, "connect".into(), Device::Camera, &mut || parts.connect_camera()) {
            break 'check false;
        }
        for target in [0.0, stroke / 2.0, stroke] {
            let ok = run(&mut steps, format!("move to {target} mm"), Device::Slide, &mut || {
                let slide = parts.slide.as_mut().ok_or_else(|| missing(Device::Slide))?;
                let at = slide.move_to(target, move_timeout)?;
                Ok(format!("stands at {at:.3} mm"))
            });
            if !ok {
                break 'check false;
            }
        }
        for on in [true, false] {
            let name = if on { "switch on" } else { "switch off" };
            let ok = run(&mut steps, name.into(), Device::Laser, &mut || {
                let laser = parts.laser.as_mut().ok_or_else(|| missing(Device::Laser))?;
                laser.set(on)?;
                Ok(if on { "on".into() } else { "off".into() })
            });
            if !ok {
                break 'check false;
            }
        }
        run(&mut steps, "capture a frame".into(), Device::Camera, &mut || {
            let camera = parts.camera.as_mut().ok_or_else(|| missing(Device::Camera))?;
            let frame = camera.capture(Duration::from_secs(5))?;
            Ok(format!("{} x {} px RGB", frame.width(), frame.height()))
        })
    };
    if !passed && let Some(laser) = parts.laser.as_mut() {
        run(&mut steps, "switch off after the failure".into(), Device::Laser, &mut || {
            laser.set(false).map(|()| "off".into())
        });
    }
    steps
}

impl alacs_scanner::ScanRig for RealRig {
    fn rig(&mut self) -> Rig<'_> {
        RealRig::rig(self)
    }

    fn describe(&self) -> String {
        self.description.clone()
    }
}
