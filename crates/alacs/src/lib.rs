//! `alacs`: the Active LAser-Camera Scanner, a perception module that gives a
//! robotic fruit harvester millimetre fruit positions from a red line laser
//! on a linear slide and a fixed RGB camera.
//!
//! This facade re-exports the domain crates:
//! - [`model`]: the camera model and the ALACS laser model (eqs. (1)-(10) of the seed paper),
//! - [`calib`]: robust laser calibration (eq. (9), Algorithm 1, the four methods of Table 1),
//! - [`sim`]: the seeded simulator with ground truth,
//! - [`scanner`]: the scan controller (slide, camera and laser behind small traits; a simulated rig),
//! - [`eval`]: the seed paper's experiments as reports (Table 1, the accuracy box plots),
//! - [`ros`]: the ROS 2 node (the LocalizeFruit action and its topics, pure Rust).
//!
//! # Example
//! ```
//! use alacs::{CalibrationOptions, Method, calibrate};
//! use alacs::sim::{SampleOptions, simulate_samples};
//! use alacs::{Camera, Fidelity, LaserModel};
//!
//! let truth = LaserModel::seed_paper();
//! let options = SampleOptions { outlier_fraction: 0.3, ..SampleOptions::default() };
//! let sim = simulate_samples(&Camera::blackfly_s_5mp(), &truth, &options).unwrap();
//! let fit = calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default()).unwrap();
//! assert!((fit.laser.alpha_deg() - 19.07).abs() < 0.1);
//! ```

pub use alacs_board as board;
pub use alacs_calib as calib;
pub use alacs_detect as detect;
pub use alacs_eval as eval;
pub use alacs_locate as locate;
pub use alacs_model as model;
pub use alacs_rig as rig;
pub use alacs_ros as ros;
pub use alacs_scanner as scanner;
pub use alacs_sim as sim;
pub use alacs_vision as vision;

pub use alacs_calib::{
    CalibrationOptions, Comparison, LaserCalibration, LaserSample, Method, calibrate, compare,
};
pub use alacs_model::{Camera, Distortion, Fidelity, LaserModel, Scan, Session};
