//! Image processing for ALACS: reading images, and the laser stripe.
//! (Checkerboard corners are `alacs-board`'s.)
//!
//! Pixels are (u, v) = (column, row) with (0, 0) the centre of the top-left
//! pixel, as everywhere in alacs.

mod error;
mod image_io;
mod stripe;

pub use error::{Error, Result};
pub use image_io::{
    MAX_IMAGE_FILE_BYTES, read_colour_image, read_depth_png, read_image, read_laser_off_image,
};
pub use stripe::{
    LocalBackground, PeakMethod, Region, ScoreImage, StripeOptions, StripePoint, extract_stripe,
    extract_stripe_rgb, laser_score,
};
