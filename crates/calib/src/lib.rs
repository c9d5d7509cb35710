//! Robust calibration of the ALACS laser model from samples s_i = [u_n, v_n, z]:
//! the seed paper's eq. (9) and Algorithm 1, all four methods of its Table 1.
//!
//! - A closed-form estimate from the linear form of eq. (7)
//!   (`1/z` is linear in `sin a / L`, `cos a / L`, `tan b / L`),
//! - RANSAC (Algorithm 1) with that linear form as a 3-point minimal solver
//!   (2 for the low-fidelity model, one more when samples come from several
//!   slide positions), adaptive stopping at 99.9 % confidence, capped at k_max,
//! - Levenberg-Marquardt on the depth residual `z - z_hat` of eq. (9) (or,
//!   as an option, the distance to the laser plane), refitted on the inliers
//!   until the inlier set is stable,
//! - parameter standard deviations: a bootstrap over board poses where the
//!   samples name their poses (samples of one pose share its error), else
//!   the fit's covariance.
//!
//! Samples may carry `slide_mm`: L = L0 - k d per sample, L0 and the slide
//! scale k fitted jointly where the samples span two or more slide positions.
//!
//! # Example
//! ```
//! use alacs_calib::{calibrate, CalibrationOptions, LaserSample, Method};
//! use alacs_model::{Fidelity, LaserModel};
//! use nalgebra::Point2;
//!
//! // Exact samples from a known laser at several depths and image rows.
//! let truth = LaserModel::seed_paper();
//! let mut samples = Vec::new();
//! for i in 0..30 {
//!     let v_n = -0.4 + 0.8 * f64::from(i % 6) / 5.0;
//!     let u_n = -0.3 + 0.02 * f64::from(i);
//!     let z_mm = truth.depth_mm(&Point2::new(u_n, v_n), 0.0).unwrap();
//!     samples.push(LaserSample { u_n, v_n, z_mm, slide_mm: 0.0, pose: None });
//! }
//! let fit = calibrate(&samples, Method::HighFidelityRansac, &CalibrationOptions::default()).unwrap();
//! assert!((fit.laser.alpha_deg() - 19.07).abs() < 1e-6);
//! assert!((fit.laser.l0_mm - 381.98).abs() < 1e-6);
//! assert_eq!(fit.inliers.len(), 30);
//! ```

mod calibrate;
mod error;
mod intrinsics;
mod linear;
mod output;
mod refine;
mod rgbd;
mod session;
mod uncertainty;

/// The RANSAC driver is `alacs-model`'s (fruit localization uses it too).
pub use alacs_model::ransac;
/// Calibration samples and samples.csv are `alacs-model`'s (the simulator
/// writes them too).
pub use alacs_model::{
    LaserSample, parse_samples_csv, read_samples_csv, samples_csv_string, validate_samples,
    write_samples_csv,
};
pub use calibrate::{
    CalibrationOptions, Comparison, DEFAULT_THRESHOLD_MM, LaserCalibration, Method,
    ParameterStdDev, calibrate, compare, depth_error_mm,
};
pub use error::{Error, Result};
pub use intrinsics::{
    BoardObservation, FixedIntrinsics, IntrinsicsFit, IntrinsicsOptions, ViewFit, board_pose,
    calibrate_intrinsics, intrinsics_std_dev_at,
};
pub use output::CalibrationOutput;
pub use refine::Residual;
pub use rgbd::{RgbdCalibration, RgbdPose, calibrate_rgbd};
pub use session::{
    LaserSessionCalibration, LaserSessionOptions, ViewBoard, ViewSamples, board_pose_groups,
    calibrate_camera_session, calibrate_laser_session, detect_session_boards, pose_observations,
    rejection_note, session_view_samples, view_samples,
};
pub use uncertainty::{BOOTSTRAP_REPLICATES, MIN_BOOTSTRAP_POSES, StdSource, laser_std_dev_at};
