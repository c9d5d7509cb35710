//! Fruit localization for the Active LAser-Camera Scanner: from the frames
//! of an active scan (the laser line stepped across the target apple) to
//! the fruit's centre in the ALACS camera frame.
//!
//! See [`locate`](crate::locate()) for the method, step by step. The entry
//! points are [`locate_scan`] (a scan folder, FORMATS.md) and [`locate`]
//! (frames in memory, as the scan controller captures them).

mod error;
pub mod fit;
mod locate;
pub mod outline;

pub use error::{Error, Result};
pub use locate::{
    Candidate, FrameImages, FrameResult, FusedFit, Localization, LocateOptions, Method, Prior,
    ScanImages, Status, locate, locate_scan, locate_scan_images, read_scan_images,
};
