//! Board corners of ALACS calibration views: calib-targets' ChESS detector,
//! fitted to the checkerboard of session.yaml, or its ChArUco detector for a
//! ChArUco board (views cut by the image's border count), labelled in
//! OpenCV's order and refined with the image gradients ([`detect_board`]),
//! for calibration then fitted as X-junctions ([`detect_board_precise`]).
//!
//! Apart from `alacs-vision` (images and the laser stripe) so that fruit
//! localization, the scanner and the ROS node do not pull the detector.
//!
//! Pixels are (u, v) = (column, row) with (0, 0) the centre of the top-left
//! pixel, as everywhere in alacs.

mod charuco;
mod checkerboard;
mod chess;
mod error;
mod junction;

pub use charuco::{
    MIN_CHARUCO_CORNERS, charuco_spec, detect_board, detect_board_precise, detect_charuco,
};
pub use checkerboard::{
    BoardCorners, MAX_MISSING_FRACTION, board_gray, detect_checkerboard, refine_corners,
};
pub use error::{Error, Result};
pub use junction::{
    JUNCTION_RADIUS_PER_CELL, MAX_JUNCTION_RADIUS_PX, MIN_JUNCTION_RADIUS_PX, fit_board_junctions,
};
