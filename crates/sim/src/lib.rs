//! The ALACS simulator: seeded scenes with ground truth, the test oracle of
//! every accuracy claim in alacs.
//!
//! So far it generates calibration samples like the seed paper's (Section
//! 4.1): a checkerboard at several poses 0.6-1.2 m from the camera, a few
//! laser points per view, depth noise and gross outliers, with the truth
//! (camera, laser, which rows are outliers) beside them.
//!
//! # Example
//! ```
//! use alacs_sim::{SampleOptions, simulate_samples};
//! use alacs_model::{Camera, Fidelity, LaserModel};
//!
//! let laser = LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98);
//! let options = SampleOptions { outlier_fraction: 0.2, ..SampleOptions::default() };
//! let sim = simulate_samples(&Camera::blackfly_s_5mp(), &laser, &options).unwrap();
//! assert_eq!(sim.samples.len(), 30);
//! assert_eq!(sim.outliers.len(), 6);
//! ```

mod error;
mod samples;
mod truth;

pub use error::{Error, Result};
pub use samples::{SampleOptions, SimulatedSamples, simulate_samples};
pub use truth::{camera_to_json, laser_to_json};
