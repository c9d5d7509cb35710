//! Geometry of the Active LAser-Camera Scanner (ALACS): the one camera model of
//! the project and the laser-triangulation model of the seed paper.
//!
//! The data's way through this crate reads straight:
//! pixel --[`Camera::undistort_pixel`], eq. (3)--> normalized (u_n, v_n)
//! --[`LaserModel::triangulate`], eqs. (7)-(8)--> point on the laser plane.
//!
//! # Conventions
//! - Camera frame: OpenCV optical frame, x right, y down, z forward, origin
//!   at the optical centre. Pixels (u, v) = (column, row), (0, 0) the centre
//!   of the top-left pixel.
//! - Lengths in millimetres, angles in radians inside the code; degrees only
//!   at the edges (files and printed output), and every such field says so
//!   (`alpha_deg`, `l0_mm`).
//! - Poses are named `target_from_source`: `point_in_camera =
//!   camera_from_board * point_in_board`.
//! - Equation numbers refer to the seed paper (Zhang et al., "Active
//!   Laser-Camera Scanning for High-Precision Fruit Localization in Robotic
//!   Harvesting: System Design and Calibration"): (1) normalized coordinates,
//!   (2) projection, (3) undistortion, (4)-(6) laser frame, (7)-(8) the
//!   high-fidelity model, (9) the calibration problem, (10) the low-fidelity
//!   model.
//!
//! # Example
//! ```
//! use alacs_model::{LaserModel, Fidelity};
//! use nalgebra::Point2;
//!
//! let laser = LaserModel::seed_paper();
//! let point = laser.triangulate(&Point2::new(0.0, 0.1), 0.0).unwrap();
//! // The point lies on the laser plane for slide travel 0.
//! assert!(laser.plane_in_camera(0.0).signed_distance_mm(&point).abs() < 1e-9);
//! ```

mod camera;
mod error;
mod geometry;
pub mod io;
mod laser;
mod pixels;
pub mod ransac;
mod samples;
mod scan;
mod scan_plan;
mod session;

pub use camera::*;
pub use error::{Error, ErrorClass, Num, PlusMinus, Result, yaml_message};
pub use geometry::{Plane, Ray};
pub use laser::{
    Fidelity, LaserFile, LaserModel, LaserStdDev, PreparedLaser, SLIDE_SCALE_RANGE,
    SLIDE_STROKE_MM, SlideTarget,
};
pub use pixels::{TriangulateJsonWriter, TriangulateOutput, for_each_pixel, read_pixels_csv};
pub use samples::{
    LaserSample, parse_samples_csv, read_samples_csv, samples_csv_string, validate_samples,
    write_samples, write_samples_csv,
};
pub use scan::{
    DEFAULT_FRUIT_RADIUS_MM, FRUIT_RADIUS_RANGE_MM, FrameExposure, MAX_ABS_SLIDE_MM,
    MAX_ROUGH_DISTANCE_MM, MAX_SCAN_TARGETS, SCAN_FILE, Scan, ScanFrameSpec, ScanTarget,
    checked_fruit_radius_mm, checked_rough_position_mm,
};
pub use scan_plan::{SHARED_FRAME_MM, ScanPlan, ScanStrategy};
pub use session::{
    ArucoDictionary, BoardSpec, CharucoMarkers, INNER_CORNERS_RANGE, MAX_SQUARE_MM, SESSION_FILE,
    Session, SessionView,
};
