//! Checkerboard corners of ALACS calibration views: calib-targets' ChESS
//! detector, fitted to the board of session.yaml, labelled in OpenCV's order
//! and refined with the image gradients.
//!
//! Apart from `alacs-vision` (images and the laser stripe) so that fruit
//! localization, the scanner and the ROS node do not pull the detector.
//!
//! Pixels are (u, v) = (column, row) with (0, 0) the centre of the top-left
//! pixel, as everywhere in alacs.

mod checkerboard;
mod error;

pub use checkerboard::{
    BoardCorners, MAX_MISSING_FRACTION, board_gray, detect_checkerboard, refine_corners,
};
pub use error::{Error, Result};
