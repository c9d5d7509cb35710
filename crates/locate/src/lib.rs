//! Fruit localization for the Active LAser-Camera Scanner: from the frames
//! of an active scan (the laser line stepped across the target apple) to
//! the fruit's centre in the ALACS camera frame.
//!
//! See [`locate`](crate::locate()) for the method, step by step. The entry
//! points are [`locate_scan`] (a scan folder, FORMATS.md) and [`locate`]
//! (frames in memory, as the scan controller captures them).
//!
//! The modules follow the steps:
//! - `types`: what localization takes and gives ([`LocateOptions`],
//!   [`FrameImages`], [`Prior`], [`Localization`] with its [`FrameResult`]s,
//!   [`Candidate`]s and [`FusedFit`]);
//! - `frame`: one frame, from the search region to its candidate;
//! - `selection`: the seed paper's holistic scoring and selection;
//! - `estimate`: the one estimator: hypotheses, one objective, the
//!   acceptance test;
//! - `fusion`: the fits that propose hypotheses (a free sphere, a sphere
//!   of the prior radius, the fruit's [`outline`]) and the accepted
//!   sphere's refinement;
//! - `folder`: reading a scan folder (scan.yaml and its images);
//! - `output`: the `localize --json` object ([`LocalizeOutput`]);
//! - [`fit`]: the geometric fits (circle, sphere, ellipsoid).

mod error;
mod estimate;
pub mod fit;
mod folder;
mod frame;
mod fusion;
mod locate;
pub mod outline;
mod output;
mod points;
mod selection;
mod types;
pub mod uncertainty;

pub use error::{Error, Result};
pub use folder::{
    FrameImagePair, MAX_FRAMES_IN_FLIGHT, MAX_SCAN_FRAMES, PendingFrame, ScanImages,
    check_camera_fits, locate_frames, locate_scan, locate_scan_images, locate_scan_targets,
    priors_of, read_scan_images,
};
pub use locate::locate;
pub use output::{
    CandidateOutput, FrameOutput, FusedOutput, LocalizeOutput, OutlineOutput, TargetOutput,
    TargetsOutput,
};
pub use points::{CloudFormat, target_cloud_path, write_points};
pub use types::{
    Candidate, FrameImages, FrameResult, FusedFit, Localization, LocateOptions, Method, Prior,
    Status,
};
