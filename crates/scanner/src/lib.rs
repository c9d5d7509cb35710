//! The scan controller of the Active LAser-Camera Scanner: the seed paper's
//! active scan, run on a rig of three devices.
//!
//! - [`hardware`]: the devices as small, object-safe traits ([`Slide`],
//!   [`FrameCamera`], [`LaserSwitch`]) with what a real driver must
//!   guarantee. Real drivers implement them in their own crates.
//! - `SimulatedRig` (cargo feature `sim`, on by default): the devices
//!   backed by the simulator (`alacs_sim`), with a simulated clock for the
//!   slide's travel, settling and timeouts.
//! - [`ScanController`]: the rough position from the RGB-D camera, carried
//!   into the ALACS camera frame, the seed's plan ([`ScanStrategy`]), then
//!   per frame: move, settle, laser on, capture (and laser off, capture).
//!   Or, in [`ScanMode::Continuous`] ([`sweep`]), one run of the slide
//!   through the plan's positions with frames captured on the way, each at
//!   the slide's position at mid-exposure.
//!   The [`CapturedScan`] it returns writes a scan folder (FORMATS.md) and
//!   localizes the fruit ([`alacs_locate::locate`]).
//!
//! # Conventions
//! Millimetres and the ALACS camera's OpenCV optical frame, as in
//! [`alacs_model`]; the slide position is the travel d of FORMATS.md
//! (L = L0 - d). Errors name the device and the step of the scan.
//!
//! # Example
//! (With the default feature `sim`.)
//! A scan of a simulated apple (at a tenth of the 5 MP camera's resolution,
//! to keep the example quick):
//! ```
//! # #[cfg(feature = "sim")] {
//! use std::sync::Arc;
//! use alacs_model::{Camera, Fidelity, LaserModel};
//! use alacs_scanner::{ControllerConfig, ScanController, SimulatedRig, SimulatedRigOptions};
//! use alacs_sim::{ScanOptions, simulate_scan};
//!
//! let laser = LaserModel::seed_paper();
//! let options = ScanOptions { scale: 0.1, seed: 1, ..ScanOptions::default() };
//! let scene = Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &laser, &options)?);
//! let rough_in_rgbd = scene.rough_position_mm; // the RGB-D camera is the ALACS camera here
//! let mut rig = SimulatedRig::new(scene, SimulatedRigOptions::default())?;
//! let controller = ScanController::new(laser, ControllerConfig::default())?;
//! let scan = controller.run(&mut rig.rig(), &rough_in_rgbd)?;
//! assert_eq!(scan.frames.len(), 5);
//! assert!(!rig.laser_on()); // switched off after the scan
//! // scan.write(dir) writes scan.yaml and the frames;
//! // scan.localize(&camera, &laser, &LocateOptions::default()) finds the fruit.
//! # }
//! # Ok::<(), alacs_scanner::Error>(())
//! ```
//!
//! [`ScanStrategy`]: alacs_model::ScanStrategy

mod controller;
mod error;
pub mod hardware;
pub mod metering;
#[cfg(feature = "sim")]
mod sim_devices;
pub mod sweep;

pub use controller::{
    CapturedFrame, CapturedScan, ControllerConfig, Localized, ScanController, ScanMode,
};
pub use error::{Device, Error, Result, Step};
pub use hardware::{FrameCamera, LaserSwitch, Rig, ScanRig, Slide, SlideReport, TimedFrame};
pub use metering::{MeteredExposure, Metering};
#[cfg(feature = "sim")]
pub use sim_devices::{
    ExposureSettings, SimulatedCamera, SimulatedLaser, SimulatedRig, SimulatedRigOptions,
    SimulatedSlide,
};
pub use sweep::Sweep;
