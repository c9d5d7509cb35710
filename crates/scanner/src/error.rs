//! The one error type of `alacs-scanner`.

use std::fmt;
use std::time::Duration;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// One of the rig's devices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Device {
    /// The linear slide that carries the laser ([`crate::Slide`]).
    Slide,
    /// The ALACS camera ([`crate::FrameCamera`]).
    Camera,
    /// The line laser's switch ([`crate::LaserSwitch`]).
    Laser,
}

impl fmt::Display for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Device::Slide => "slide",
            Device::Camera => "camera",
            Device::Laser => "laser",
        })
    }
}

/// Where in a scan something happened. Frames are numbered from 0, as in
/// scan.yaml's `frame0.png`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Checking the plan against the slide's stroke, before anything moves.
    Planning,
    /// Moving the slide to a frame's position.
    Move {
        /// The frame.
        frame: usize,
        /// Where the plan puts the slide, mm.
        target_mm: f64,
    },
    /// Switching the laser for a frame.
    Laser {
        /// The frame.
        frame: usize,
        /// On or off.
        on: bool,
    },
    /// Capturing a frame's image.
    Capture {
        /// The frame.
        frame: usize,
        /// With the laser on or off.
        laser_on: bool,
    },
    /// Sweeping the slide past a frame's position (a continuous sweep).
    Sweep {
        /// The frame, in the order the sweep takes them.
        frame: usize,
        /// The position the frame is taken at, mm.
        target_mm: f64,
    },
    /// Metering the target with the laser off, before the first frame.
    Metering,
    /// Switching the laser off after the last frame.
    Finish,
}

fn on_off(on: bool) -> &'static str {
    if on { "on" } else { "off" }
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Step::Planning => f.write_str("planning"),
            Step::Move { frame, target_mm } => {
                write!(f, "frame {frame}, moving the slide to {target_mm:.3} mm")
            }
            Step::Laser { frame, on } => {
                write!(f, "frame {frame}, switching the laser {}", on_off(on))
            }
            Step::Capture { frame, laser_on } => {
                write!(f, "frame {frame}, capturing with the laser {}", on_off(laser_on))
            }
            Step::Sweep { frame, target_mm } => {
                write!(f, "frame {frame}, sweeping the slide past {target_mm:.3} mm")
            }
            Step::Metering => f.write_str("metering the target with the laser off"),
            Step::Finish => f.write_str("switching the laser off after the scan"),
        }
    }
}

/// " at <step>" or nothing, for the messages below.
fn at(step: &Option<Step>) -> String {
    step.map(|s| format!(" at {s}")).unwrap_or_default()
}

/// What can stop a scan. Device errors name the device and, once the
/// controller has seen them, the step of the scan ([`Error::at`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A slide target outside the stroke: refused, the slide did not move.
    #[error("slide error{}: target {target_mm} mm is outside the stroke 0..{stroke_mm} mm", at(.step))]
    OutOfStroke {
        /// The step of the scan, once known.
        step: Option<Step>,
        /// The refused target, mm.
        target_mm: f64,
        /// The stroke of the slide, mm.
        stroke_mm: f64,
    },
    /// A device did not finish within its timeout.
    #[error("{device} error{}: timed out after {:.3} s{}", at(.step), .timeout.as_secs_f64(), detail_suffix(.detail))]
    Timeout {
        /// The device.
        device: Device,
        /// The step of the scan, once known.
        step: Option<Step>,
        /// The timeout that passed.
        timeout: Duration,
        /// What the device knows about why (may be empty).
        detail: String,
    },
    /// The slide settled away from its target.
    #[error(
        "slide error{}: settled at {reached_mm:.3} mm, {:.3} mm from the target {target_mm:.3} mm (tolerance {tolerance_mm} mm)",
        at(.step),
        (.reached_mm - .target_mm).abs()
    )]
    PositionMismatch {
        /// The step of the scan, once known.
        step: Option<Step>,
        /// The commanded position, mm.
        target_mm: f64,
        /// The reported position, mm.
        reached_mm: f64,
        /// The largest difference accepted, mm.
        tolerance_mm: f64,
    },
    /// Any other failure a device driver reports.
    #[error("{device} error{}: {message}", at(.step))]
    Device {
        /// The device.
        device: Device,
        /// The step of the scan, once known.
        step: Option<Step>,
        /// What the driver said.
        message: String,
    },
    /// Metering found no exposure that shows the target unclipped and
    /// above the noise within the camera's range.
    #[error("metering failed after {frames} frames (last exposure {exposure_us:.0} us): {detail}")]
    Metering {
        /// Metering frames taken.
        frames: usize,
        /// The last exposure tried, microseconds.
        exposure_us: f64,
        /// Why.
        detail: String,
    },
    /// A configuration or rough position that cannot give a scan.
    #[error("invalid scan: {0}")]
    InvalidInput(String),
    /// Localization of the captured frames failed before giving an answer.
    #[error(transparent)]
    Locate(#[from] alacs_locate::Error),
    /// The simulated rig's simulator failed.
    #[cfg(feature = "sim")]
    #[error(transparent)]
    Sim(#[from] alacs_sim::Error),
    /// Writing a scan folder failed (or a file of the model's could not be used).
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
}

fn detail_suffix(detail: &str) -> String {
    if detail.is_empty() { String::new() } else { format!(" ({detail})") }
}

impl Error {
    /// Bad input (exit 2: a configuration or rough position that gives no
    /// scan, a scan folder that cannot be written) or a failed job (exit 1:
    /// a device failed).
    pub fn class(&self) -> alacs_model::ErrorClass {
        use alacs_model::ErrorClass::{BadInput, JobFailed};
        match self {
            Error::InvalidInput(_) => BadInput,
            Error::Model(e) => e.class(),
            Error::Locate(e) => e.class(),
            #[cfg(feature = "sim")]
            Error::Sim(e) => e.class(),
            Error::OutOfStroke { .. }
            | Error::Timeout { .. }
            | Error::PositionMismatch { .. }
            | Error::Metering { .. }
            | Error::Device { .. } => JobFailed,
        }
    }

    /// The same error, placed at `step` of the scan (a step already set is kept).
    pub fn at(mut self, step: Step) -> Self {
        match &mut self {
            Error::OutOfStroke { step: s, .. }
            | Error::Timeout { step: s, .. }
            | Error::PositionMismatch { step: s, .. }
            | Error::Device { step: s, .. } => {
                s.get_or_insert(step);
            }
            _ => {}
        }
        self
    }

    /// The device that failed, for device errors.
    pub fn device(&self) -> Option<Device> {
        match self {
            Error::OutOfStroke { .. } | Error::PositionMismatch { .. } => Some(Device::Slide),
            Error::Timeout { device, .. } | Error::Device { device, .. } => Some(*device),
            _ => None,
        }
    }

    /// The step of the scan where a device error happened, once known.
    pub fn step(&self) -> Option<Step> {
        match self {
            Error::OutOfStroke { step, .. }
            | Error::Timeout { step, .. }
            | Error::PositionMismatch { step, .. }
            | Error::Device { step, .. } => *step,
            _ => None,
        }
    }
}
