//! The real ALACS rig: rig.toml ([`RigConfig`]), a GRBL 1.1 controller on a
//! serial port for the slide and the laser ([`grbl`]), the simulator's
//! devices for what a rig lacks ("sim" in rig.toml: a bench test of a slide
//! with no camera), the connected rig behind the scanner's traits
//! ([`RealRig`]) and the rig check ([`check_rig`], `alacs rig check`).

mod config;
mod error;
#[cfg(feature = "genicam")]
pub mod genicam;
pub mod grbl;
pub mod relay;
mod rig;

pub use config::{
    CameraConfig, CameraDriver, LaserConfig, LaserDriver, RgbdConfig, RigConfig, ScanConfig,
    ScanModeName, SlideConfig, SlideDriver,
};
pub use error::{Error, Result};
pub use rig::{CheckStep, RealRig, Scene, check_rig};
