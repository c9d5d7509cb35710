//! Image processing for ALACS: the checkerboard corners of calibration views
//! and the laser stripe.
//!
//! Pixels are (u, v) = (column, row) with (0, 0) the centre of the top-left
//! pixel, as everywhere in alacs.

mod checkerboard;
mod error;
mod image_io;
mod stripe;

pub use checkerboard::{
    BoardCorners, MAX_MISSING_FRACTION, board_gray, detect_checkerboard, refine_corners,
};
pub use error::{Error, Result};
pub use image_io::read_image;
pub use stripe::{
    LocalBackground, PeakMethod, Region, ScoreImage, StripeOptions, StripePoint, extract_stripe,
    extract_stripe_rgb, laser_score,
};
