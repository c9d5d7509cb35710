//! What localization takes and gives: the options, a frame's images, the
//! prior, and the answer ([`Localization`]) with each frame's result, its
//! candidate and the fused fit.

use alacs_vision::{StripeOptions, StripePoint};
use image::RgbImage;
use nalgebra::{Matrix3, Point2, Point3};
use serde::{Deserialize, Serialize};

use crate::fit::{Ellipsoid, Sphere};
use crate::outline::Outline;

/// How the final position is chosen from the frames; serialized as
/// [`Method::as_str`] spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The one estimator over every frame's laser points ([`crate::locate()`]).
    #[default]
    Fused,
    /// The best-scoring single-frame candidate (the seed paper's holistic
    /// evaluation), answered only where it is the fruit the fused estimator
    /// accepts from all frames (the one acceptance test).
    Holistic,
}

impl Method {
    /// The name used in files and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Fused => "fused",
            Method::Holistic => "holistic",
        }
    }
}

/// Settings of [`locate`](crate::locate()). `Default` is what the documentation measured.
#[derive(Debug, Clone, PartialEq)]
pub struct LocateOptions {
    /// Stripe extraction ([`StripeOptions::orchard`]).
    pub stripe: StripeOptions,
    /// How the final position is chosen.
    pub method: Method,
    /// Largest error of the rough position along the line of sight, as a
    /// fraction of its depth (the RGB-D camera; the seed's D435i: 2 %).
    pub rough_depth_error: f64,
    /// Largest error of the rough position across the line of sight, mm.
    pub rough_lateral_error_mm: f64,
    /// Fruit radii accepted, as factors of the radius prior.
    pub radius_factors: (f64, f64),
    /// A point belongs to a circle or sphere when it lies within this of it, mm.
    pub inlier_threshold_mm: f64,
    /// Largest RMS distance of the fruit points from the fitted circle or sphere, mm.
    pub max_fit_rms_mm: f64,
    /// Fewest fruit points of a frame, as a fraction of the rows a fruit of
    /// the prior radius spans at the rough depth.
    pub min_points_fraction: f64,
    /// Smallest fraction of the stripe rows the fitted fruit predicts that
    /// must hold fruit points for the free fit to count, over all frames
    /// and in each of two of them (a fruit behind leaves and in the laser's
    /// shadow shows part of them, a chance fit to clutter few).
    pub min_coverage: f64,
    /// Use the fruit's outline in the image: a sphere fitted to it and the
    /// laser points together (for a fruit the laser alone cannot fix), and
    /// the silhouette that refines the accepted sphere to the fruit's
    /// ellipsoid ([`crate::outline`]).
    pub use_outline: bool,
    /// Relative standard deviation of a fruit's semi-axes about its mean
    /// radius (apples: about 5 %), for the position covariance: the depth
    /// semi-axis behind the centre is never seen ([`crate::uncertainty`]).
    pub shape_std: f64,
    /// Seed of the RANSAC samplers: same seed, same answer.
    pub seed: u64,
}

impl Default for LocateOptions {
    fn default() -> Self {
        LocateOptions {
            stripe: StripeOptions::orchard(),
            method: Method::Fused,
            rough_depth_error: 0.03,
            rough_lateral_error_mm: 10.0,
            radius_factors: (0.6, 1.5),
            inlier_threshold_mm: 2.0,
            max_fit_rms_mm: 1.2,
            min_points_fraction: 0.08,
            min_coverage: 0.2,
            use_outline: true,
            shape_std: 0.05,
            seed: 0,
        }
    }
}

/// The images of one frame and where the slide was.
#[derive(Debug, Clone, Copy)]
pub struct FrameImages<'a> {
    /// The frame with the laser on.
    pub image: &'a RgbImage,
    /// The same view with the laser off, if taken.
    pub image_laser_off: Option<&'a RgbImage>,
    /// Slide travel d, mm.
    pub slide_mm: f64,
}

impl<'a> From<(&'a RgbImage, f64)> for FrameImages<'a> {
    /// A frame with the laser on and no laser-off image, at slide travel mm.
    fn from((image, slide_mm): (&'a RgbImage, f64)) -> Self {
        Self { image, image_laser_off: None, slide_mm }
    }
}

/// What localization knows before it looks at the frames.
#[derive(Debug, Clone, Copy)]
pub struct Prior {
    /// The rough fruit centre in the ALACS camera frame, mm.
    pub rough_position_mm: Point3<f64>,
    /// The fruit radius prior, mm.
    pub fruit_radius_mm: f64,
}

impl From<&alacs_model::ScanTarget> for Prior {
    /// What scan.yaml says of one fruit.
    fn from(target: &alacs_model::ScanTarget) -> Self {
        Prior {
            rough_position_mm: target.rough_position_mm,
            fruit_radius_mm: target.fruit_radius_mm,
        }
    }
}

/// One frame's position candidate.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// Index of the frame.
    pub frame: usize,
    /// Slide travel of the frame, mm.
    pub slide_mm: f64,
    /// The candidate fruit centre, camera frame, mm.
    pub position_mm: Point3<f64>,
    /// Radius of the circle the laser plane cuts from the fruit, mm.
    pub circle_radius_mm: f64,
    /// Fruit points on the circle.
    pub n_points: usize,
    /// Fraction of the rows between the arc's ends that hold a fruit point.
    pub continuity: f64,
    /// RMS distance of the fruit points from the circle, mm.
    pub fit_rms_mm: f64,
    /// The holistic evaluation: coverage + continuity - residual/threshold -
    /// disagreement/radius - distance from the rough position/search radius,
    /// where coverage is the point count over the rows a fruit of the prior
    /// radius spans (at most 1), disagreement the median distance to the
    /// other frames' candidates. Higher is better.
    pub score: f64,
}

/// What one frame gave.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameResult {
    /// Slide travel, mm.
    pub slide_mm: f64,
    /// The search region's outline in the image (px), empty when the laser
    /// plane misses the search ball.
    pub region_outline_px: Vec<Point2<f64>>,
    /// The stripe found in the region.
    pub stripe: Vec<StripePoint>,
    /// The stripe points that triangulated inside the search ball, without
    /// those the laser did not light (see `stripe_red_dn`): (index into
    /// `stripe`, point in the camera frame, mm).
    pub points_in_camera: Vec<(usize, Point3<f64>)>,
    /// Indices into `stripe` of the points on the fruit's circle.
    pub fruit: Vec<usize>,
    /// The frame's candidate, if its fruit points made one.
    pub candidate: Option<Candidate>,
    /// Why the frame gave no candidate.
    pub rejected: Option<String>,
    /// The frame's red (DN) at each stripe point's pixel, where the frame
    /// has no laser-off image (empty where it has): to tell the laser from
    /// a red ridge that is there in every frame ([`crate::frame::drop_unlit_points`]).
    pub(crate) stripe_red_dn: Vec<u8>,
}

/// The one sphere fitted to every frame's fruit points.
#[derive(Debug, Clone, PartialEq)]
pub struct FusedFit {
    /// The sphere, camera frame, mm.
    pub sphere: Sphere,
    /// The ellipsoid the fruit's silhouette and the laser points refined
    /// the sphere to (its centre is the answer).
    pub ellipsoid: Option<Ellipsoid>,
    /// Points on it.
    pub n_points: usize,
    /// Frames that contribute points.
    pub n_frames: usize,
    /// Whether the radius was held at the prior: the fallback when the free
    /// fit is not trustworthy (a fruit mostly hidden or in the laser's
    /// shadow shows short arcs, which fix a centre for a known radius but
    /// not the radius itself).
    pub radius_from_prior: bool,
    /// RMS distance of the points from the fit (the ellipsoid where there
    /// is one), mm.
    pub rms_mm: f64,
    /// The fruit's outline in the image: the sphere's source, where it was
    /// fitted to the outline and the laser points together, or the
    /// accepted sphere's refinement (`outline_refined`).
    pub outline: Option<Outline>,
    /// Whether the outline refined the accepted sphere to the fruit's
    /// ellipsoid: the silhouette fixes the semi-axes across the line of
    /// sight, which the front of a fruit that is not quite round does not,
    /// and with the front's curvature the one along it
    /// (`fusion::refine_to_ellipsoid`).
    pub outline_refined: bool,
}

/// Whether the fruit was found; serialized as [`Status::as_str`] spells it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// `position_mm` holds the fruit centre.
    Ok,
    /// No frame gave a trustworthy fruit; `reason` says why.
    NotFound,
}

impl Status {
    /// FORMATS.md's spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::NotFound => "not_found",
        }
    }
}

/// The answer of [`locate`](crate::locate()).
#[derive(Debug, Clone, PartialEq)]
pub struct Localization {
    /// Found or not.
    pub status: Status,
    /// The fruit centre in the ALACS camera frame, mm (`None` when not found).
    pub position_mm: Option<Point3<f64>>,
    /// The fruit radius, mm: fitted by the fused method, the prior for a single frame.
    pub radius_mm: Option<f64>,
    /// The method that gave the answer.
    pub method: Method,
    /// Index into `candidates` of the holistic selection (`None` for the
    /// fused answer, which no single frame gives, and when not found).
    pub selected: Option<usize>,
    /// Why not found, or a remark on how the answer was found.
    pub reason: String,
    /// Every frame's candidate, in frame order.
    pub candidates: Vec<Candidate>,
    /// The holistic selection (index into `candidates`), whichever method answered.
    pub holistic: Option<usize>,
    /// The fused fit, if it was trustworthy.
    pub fused: Option<FusedFit>,
    /// Why the free fused fit was not trustworthy, if it was not (the
    /// fallback with the prior radius may still have answered).
    pub fused_rejected: Option<String>,
    /// What each frame gave.
    pub frames: Vec<FrameResult>,
    /// Radius of the search ball around the rough position, mm.
    pub search_radius_mm: f64,
    /// Covariance of `position_mm`, mm^2, camera frame: the fused answer's
    /// ([`crate::uncertainty`]); `None` when not found and for the holistic
    /// method.
    pub position_cov_mm2: Option<Matrix3<f64>>,
    /// Not found because the inputs contradict each other (frames that
    /// claim one slide position while their stripes moved, an answer the
    /// RGB-D camera's rough position rules out), not for want of evidence:
    /// more frames of the same rig cannot help.
    pub contradicted: bool,
}
