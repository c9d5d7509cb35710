//! From the frames of a scan to the fruit's centre.
//!
//! Per frame (all frames in parallel):
//! 1. **Region of interest.** The fruit lies within a search ball around the
//!    rough position: the radius prior, enlarged by a quarter, plus the
//!    rough position's error (a fraction of its depth along the line of
//!    sight, a few millimetres across). The laser plane of the frame cuts
//!    the ball in a disk; its image is the region searched. Every pixel
//!    there triangulates (eqs. (7)-(8)) to a point inside the ball, so laser
//!    light on the background never enters.
//! 2. **Stripe.** One sub-pixel peak per row of the region
//!    ([`alacs_vision::extract_stripe_rgb`], [`StripeOptions::orchard`]).
//! 3. **Fruit points.** The stripe pixels, undistorted (eq. (3)) and
//!    triangulated, lie on the laser plane. The plane cuts a round fruit in
//!    a circle: a RANSAC circle fit in the plane keeps the points on one
//!    smooth, curved arc and drops leaves, branches and stray peaks. The arc
//!    must be curved beyond doubt (its points far from straight compared
//!    with their scatter about the circle): a flat leaf is not a fruit.
//! 4. **Candidate.** The fruit's centre lies on the circle's axis, at
//!    sqrt(R^2 - rho^2) from the plane for a fruit of radius R (the prior)
//!    and circle radius rho, on the side where the arc faces the camera.
//!
//! Across the frames, two answers:
//! - **Holistic selection** (the seed paper's): each candidate gets a score
//!   ([`Candidate::score`]) from its point count, stripe continuity, fit
//!   residual, agreement with the other frames' candidates and distance from
//!   the rough position; the best one is the answer.
//! - **Fused** (the default): one robust sphere fit (RANSAC, then least
//!   squares) over every frame's fruit points. Five parallel cuts 10 mm
//!   apart fix the sphere's centre and radius without the radius prior,
//!   which is what limits a single frame. Where an ellipsoid (roundness
//!   prior, Cauchy-weighted) fits clearly better, its centre is the answer:
//!   a sphere fitted to the front of an elongated fruit misplaces the
//!   centre by millimetres. When the free fit is not trustworthy (short
//!   arcs of a fruit mostly hidden), a sphere of the prior radius through
//!   the arcs may answer, under the same checks. The last resort, when the
//!   laser shows one short arc or arcs that fix no sphere, is the fruit's
//!   outline in the image ([`crate::outline`]): its rays touch the sphere,
//!   and the laser points that agree fix its depth. The README compares
//!   the methods on simulated scans.
//!
//! A fit that is not trustworthy (too few points, a large residual, a
//! radius or centre out of range, a surface facing away from the camera, a
//! flat patch) gives `not_found` with the reason, never a point.

use alacs_model::ransac::{RansacOptions, ransac_refit};
use alacs_model::{Camera, LaserModel, Scan};
use alacs_vision::{Region, StripeOptions, StripePoint, extract_stripe_rgb, read_image};
use image::RgbImage;
use nalgebra::{Point2, Point3, Unit, Vector3};
use rayon::prelude::*;

use crate::fit::{
    Circle, CircleEstimator, Ellipsoid, Sphere, SphereEstimator, fit_circle, fit_ellipsoid_robust,
    line_rms_mm, plane_rms_mm, rms_mm,
};
use crate::outline::{Outline, PixelBox, find_outline, fit_outline_sphere};
use crate::{Error, Result};

/// How the final position is chosen from the frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// One robust sphere fit over every frame's fruit points.
    #[default]
    Fused,
    /// The best-scoring single-frame candidate (the seed paper's holistic evaluation).
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

/// Settings of [`locate`]. `Default` is what the documentation measured.
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
    /// must hold fruit points for the free fit to count (a fruit behind
    /// leaves and in the laser's shadow shows part of them, a chance fit to
    /// clutter few).
    pub min_coverage: f64,
    /// When the laser alone cannot fix the fruit, fit a sphere to the
    /// fruit's outline in the image and the laser points together
    /// ([`crate::outline`]).
    pub use_outline: bool,
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

/// What localization knows before it looks at the frames.
#[derive(Debug, Clone, Copy)]
pub struct Prior {
    /// The rough fruit centre in the ALACS camera frame, mm.
    pub rough_position_mm: Point3<f64>,
    /// The fruit radius prior, mm.
    pub fruit_radius_mm: f64,
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
    /// The stripe points that triangulated: (index into `stripe`, point in
    /// the camera frame, mm).
    pub points_in_camera: Vec<(usize, Point3<f64>)>,
    /// Indices into `stripe` of the points on the fruit's circle.
    pub fruit: Vec<usize>,
    /// The frame's candidate, if its fruit points made one.
    pub candidate: Option<Candidate>,
    /// Why the frame gave no candidate.
    pub rejected: Option<String>,
}

/// The one sphere fitted to every frame's fruit points.
#[derive(Debug, Clone, PartialEq)]
pub struct FusedFit {
    /// The sphere, camera frame, mm.
    pub sphere: Sphere,
    /// The ellipsoid refined from the sphere (its centre is the answer).
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
    /// RMS distance of the points from the sphere, mm.
    pub rms_mm: f64,
    /// The fruit's outline in the image, when the sphere was fitted to it
    /// and the laser points together (the last resort).
    pub outline: Option<Outline>,
}

/// Whether the fruit was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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

/// The answer of [`locate`].
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
}

/// The images of a scan's frames, in frame order: the laser-on image and
/// the laser-off one where the frame has it.
pub type ScanImages = Vec<(RgbImage, Option<RgbImage>)>;

/// Reads the images of a scan folder ([`Scan`]) in parallel;
/// `progress(done, total)` after each frame read.
pub fn read_scan_images(scan: &Scan, progress: impl Fn(usize, usize) + Sync) -> Result<ScanImages> {
    let total = scan.frames.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    scan.frames
        .par_iter()
        .map(|frame| {
            let on = read_image(&scan.path_of(&frame.image))?.to_rgb8();
            let off = match &frame.image_laser_off {
                Some(path) => Some(read_image(&scan.path_of(path))?.to_rgb8()),
                None => None,
            };
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, total);
            Ok((on, off))
        })
        .collect()
}

/// Locates the fruit from a scan folder ([`Scan`]): [`read_scan_images`],
/// then [`locate_scan_images`].
pub fn locate_scan(
    scan: &Scan,
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Localization> {
    let images = read_scan_images(scan, progress)?;
    locate_scan_images(scan, &images, camera, laser, options)
}

/// [`locate`] on a scan's images already read ([`read_scan_images`]), with
/// the prior and slide positions of its scan.yaml.
pub fn locate_scan_images(
    scan: &Scan,
    images: &[(RgbImage, Option<RgbImage>)],
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
) -> Result<Localization> {
    let frames: Vec<FrameImages> = scan
        .frames
        .iter()
        .zip(images)
        .map(|(frame, (on, off))| FrameImages {
            image: on,
            image_laser_off: off.as_ref(),
            slide_mm: frame.slide_mm,
        })
        .collect();
    let prior =
        Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: scan.fruit_radius_mm };
    locate(camera, laser, &prior, &frames, options).map_err(|error| match error {
        Error::InvalidInput(message) => {
            Error::InvalidInput(format!("{}: {message}", scan.dir.display()))
        }
        other => other,
    })
}

/// Locates the fruit from the frames of a scan (see the module docs).
pub fn locate(
    camera: &Camera,
    laser: &LaserModel,
    prior: &Prior,
    frames: &[FrameImages],
    options: &LocateOptions,
) -> Result<Localization> {
    camera.validate()?;
    laser.validate()?;
    check_inputs(camera, prior, frames, options)?;
    let search = SearchBall::new(prior, options);
    let context = FrameContext { camera, laser, prior, search: &search, options };
    let mut results: Vec<FrameResult> = frames
        .par_iter()
        .enumerate()
        .map(|(index, frame)| context.frame(index, frame))
        .collect::<Result<_>>()?;
    score_candidates(&mut results, &search, prior, options, context.expected_rows());
    let candidates: Vec<Candidate> = results.iter().filter_map(|r| r.candidate.clone()).collect();
    let holistic = candidates
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.score.total_cmp(&b.1.score))
        .map(|(i, _)| i);
    let candidate_positions: Vec<Point3<f64>> = candidates.iter().map(|c| c.position_mm).collect();
    let (fused, fused_rejected) = match fuse(&results, &context) {
        Ok(fit) => (Some(fit), None),
        Err(reason) => match fit_prior_radius(&results, &context, &candidate_positions) {
            Ok(fit) => (Some(fit), Some(reason)),
            Err(second) => {
                let reason = if candidate_positions.is_empty() {
                    reason
                } else {
                    format!("{reason}; with the radius prior: {second}")
                };
                match options.use_outline.then(|| fit_with_outline(&results, &context, frames)) {
                    Some(Ok(fit)) => (Some(fit), Some(reason)),
                    Some(Err(third)) => {
                        (None, Some(format!("{reason}; with the outline: {third}")))
                    }
                    None => (None, Some(reason)),
                }
            }
        },
    };

    let mut answer = Localization {
        status: Status::NotFound,
        position_mm: None,
        radius_mm: None,
        method: options.method,
        selected: None,
        reason: String::new(),
        candidates,
        holistic,
        fused,
        fused_rejected,
        frames: results,
        search_radius_mm: search.radius_mm,
    };
    match options.method {
        Method::Fused => match (&answer.fused, &answer.fused_rejected) {
            (Some(fit), _) => {
                answer.status = Status::Ok;
                let (centre, radius) = match &fit.ellipsoid {
                    Some(e) => (e.centre, e.equal_volume_radius_mm()),
                    None => (fit.sphere.centre, fit.sphere.radius_mm),
                };
                answer.position_mm = Some(centre);
                answer.radius_mm = Some(radius);
                answer.reason = if let Some(outline) = &fit.outline {
                    format!(
                        "sphere fitted to the fruit's outline ({:.0} % of it visible) and {} laser points from {} frames, RMS {:.2} mm (the laser alone did not fix the fruit: {})",
                        100.0 * outline.support,
                        fit.n_points,
                        fit.n_frames,
                        fit.rms_mm,
                        answer.fused_rejected.as_deref().unwrap_or_default()
                    )
                } else if fit.radius_from_prior {
                    format!(
                        "sphere of the prior radius fitted to {} points from {} frames, RMS {:.2} mm (the free fit failed: {})",
                        fit.n_points,
                        fit.n_frames,
                        fit.rms_mm,
                        answer.fused_rejected.as_deref().unwrap_or_default()
                    )
                } else {
                    format!(
                        "sphere fit over {} points from {} frames, RMS {:.2} mm",
                        fit.n_points, fit.n_frames, fit.rms_mm
                    )
                };
            }
            (None, reason) => {
                answer.reason = reason.clone().unwrap_or_default();
            }
        },
        Method::Holistic => match answer.holistic {
            Some(i) => {
                let best = &answer.candidates[i];
                answer.status = Status::Ok;
                answer.position_mm = Some(best.position_mm);
                answer.radius_mm = Some(prior.fruit_radius_mm);
                answer.selected = Some(i);
                answer.reason = format!(
                    "frame {} selected from {} candidates (score {:.2})",
                    best.frame,
                    answer.candidates.len(),
                    best.score
                );
            }
            None => answer.reason = no_candidate_reason(&answer.frames),
        },
    }
    Ok(answer)
}

fn check_inputs(
    camera: &Camera,
    prior: &Prior,
    frames: &[FrameImages],
    options: &LocateOptions,
) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidInput(m));
    if frames.is_empty() {
        return invalid("the scan has no frames".into());
    }
    let r = &prior.rough_position_mm;
    if !(r.coords.iter().all(|c| c.is_finite()) && r.z > 0.0) {
        return invalid(format!(
            "the rough position ({}, {}, {}) mm must be finite and in front of the camera",
            r.x, r.y, r.z
        ));
    }
    if !(prior.fruit_radius_mm.is_finite() && prior.fruit_radius_mm > 0.0) {
        return invalid(format!(
            "the fruit radius prior {} mm must be positive",
            prior.fruit_radius_mm
        ));
    }
    for (i, frame) in frames.iter().enumerate() {
        if frame.image.dimensions() != (camera.width_px, camera.height_px) {
            return invalid(format!(
                "frame {i} is {} x {} px, the camera {} x {} px",
                frame.image.width(),
                frame.image.height(),
                camera.width_px,
                camera.height_px
            ));
        }
        if let Some(off) = frame.image_laser_off
            && off.dimensions() != frame.image.dimensions()
        {
            return invalid(format!(
                "frame {i}: the laser-off image is {} x {} px, the frame {} x {} px",
                off.width(),
                off.height(),
                frame.image.width(),
                frame.image.height()
            ));
        }
        if !frame.slide_mm.is_finite() {
            return invalid(format!("frame {i}: slide_mm {} is not finite", frame.slide_mm));
        }
    }
    let (lo, hi) = options.radius_factors;
    let positive = [
        options.rough_depth_error,
        options.rough_lateral_error_mm,
        options.inlier_threshold_mm,
        options.max_fit_rms_mm,
    ];
    if !(positive.iter().all(|v| v.is_finite() && *v >= 0.0) && lo > 0.0 && hi > lo) {
        return invalid(format!("invalid localization options: {options:?}"));
    }
    Ok(())
}

/// The ball around the rough position that holds the fruit.
struct SearchBall {
    centre: Point3<f64>,
    radius_mm: f64,
}

impl SearchBall {
    fn new(prior: &Prior, options: &LocateOptions) -> SearchBall {
        let depth = prior.rough_position_mm.coords.norm();
        SearchBall {
            centre: prior.rough_position_mm,
            radius_mm: 1.25 * prior.fruit_radius_mm
                + options.rough_depth_error * depth
                + options.rough_lateral_error_mm,
        }
    }
}

/// What every frame shares.
struct FrameContext<'a> {
    camera: &'a Camera,
    laser: &'a LaserModel,
    prior: &'a Prior,
    search: &'a SearchBall,
    options: &'a LocateOptions,
}

/// Points on the outline of the search region.
const OUTLINE_POINTS: usize = 48;

/// A laser plane with a unit normal and an orthonormal basis in it.
struct PlaneFrame {
    normal: Unit<Vector3<f64>>,
    origin: Point3<f64>,
    e1: Vector3<f64>,
    e2: Vector3<f64>,
}

impl PlaneFrame {
    fn new(laser: &LaserModel, slide_mm: f64) -> Option<PlaneFrame> {
        let plane = laser.plane_in_camera(slide_mm);
        let norm = plane.normal.norm();
        if norm.is_nan() || norm <= 0.0 {
            return None;
        }
        let normal = Unit::new_unchecked(plane.normal / norm);
        let origin = Point3::from(normal.into_inner() * (plane.offset_mm / norm));
        // e1 along the camera's y (the plane nearly contains it), e2 across.
        let y = Vector3::y();
        let e1 = (y - normal.into_inner() * normal.dot(&y)).try_normalize(1e-9)?;
        let e2 = normal.cross(&e1);
        Some(PlaneFrame { normal, origin, e1, e2 })
    }

    fn to_plane(&self, p: &Point3<f64>) -> Point2<f64> {
        let d = p - self.origin;
        Point2::new(d.dot(&self.e1), d.dot(&self.e2))
    }

    fn point_at(&self, q: &Point2<f64>) -> Point3<f64> {
        self.origin + self.e1 * q.x + self.e2 * q.y
    }

    fn signed_distance_mm(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&(p - self.origin))
    }
}

impl FrameContext<'_> {
    fn frame(&self, index: usize, frame: &FrameImages) -> Result<FrameResult> {
        let mut result = FrameResult {
            slide_mm: frame.slide_mm,
            region_outline_px: Vec::new(),
            stripe: Vec::new(),
            points_in_camera: Vec::new(),
            fruit: Vec::new(),
            candidate: None,
            rejected: None,
        };
        let Some(plane) = PlaneFrame::new(self.laser, frame.slide_mm) else {
            result.rejected = Some("the laser plane is degenerate".into());
            return Ok(result);
        };
        // 1. The search ball's disk on the laser plane, and its image.
        let offset = plane.signed_distance_mm(&self.search.centre);
        let disk_radius_squared = self.search.radius_mm.powi(2) - offset.powi(2);
        if disk_radius_squared <= 0.0 {
            result.rejected = Some(format!(
                "the laser plane passes {:.0} mm from the rough position, outside the {:.0} mm search ball",
                offset.abs(),
                self.search.radius_mm
            ));
            return Ok(result);
        }
        let disk_centre = self.search.centre - plane.normal.into_inner() * offset;
        let disk_radius = disk_radius_squared.sqrt();
        result.region_outline_px = (0..OUTLINE_POINTS)
            .filter_map(|k| {
                let t = std::f64::consts::TAU * k as f64 / OUTLINE_POINTS as f64;
                let p = disk_centre + (plane.e1 * t.cos() + plane.e2 * t.sin()) * disk_radius;
                self.camera.project(&p).ok()
            })
            .collect();
        let region = Region::convex_polygon(
            &result.region_outline_px,
            0.0,
            self.camera.width_px,
            self.camera.height_px,
        );
        // 2. The stripe.
        result.stripe =
            extract_stripe_rgb(frame.image, frame.image_laser_off, &region, &self.options.stripe)?;
        // 3. Triangulated points inside the ball.
        let prepared = self.laser.prepare();
        result.points_in_camera = result
            .stripe
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let normalized = self.camera.undistort_pixel(&Point2::new(s.u_px, s.v_px)).ok()?;
                let p = prepared.triangulate(&normalized, frame.slide_mm).ok()?;
                ((p - self.search.centre).norm() <= self.search.radius_mm).then_some((i, p))
            })
            .collect();
        match self.frame_candidate(index, frame.slide_mm, &plane, &result) {
            Ok((fruit, candidate)) => {
                result.fruit = fruit;
                result.candidate = Some(candidate);
            }
            Err(reason) => result.rejected = Some(reason),
        }
        Ok(result)
    }

    /// Rows a fruit of the prior radius spans at the rough depth.
    fn expected_rows(&self) -> f64 {
        2.0 * self.prior.fruit_radius_mm * self.camera.fy_px / self.prior.rough_position_mm.z
    }

    fn min_points(&self) -> usize {
        ((self.options.min_points_fraction * self.expected_rows()).ceil() as usize).max(MIN_POINTS)
    }

    fn radius_range_mm(&self) -> (f64, f64) {
        let (lo, hi) = self.options.radius_factors;
        (lo * self.prior.fruit_radius_mm, hi * self.prior.fruit_radius_mm)
    }

    /// Steps 3 and 4 of the module docs: the fruit's arc and the candidate.
    fn frame_candidate(
        &self,
        index: usize,
        slide_mm: f64,
        plane: &PlaneFrame,
        result: &FrameResult,
    ) -> std::result::Result<(Vec<usize>, Candidate), String> {
        let min_points = self.min_points();
        if result.points_in_camera.len() < min_points {
            return Err(format!(
                "{} stripe points near the fruit, fewer than {min_points}",
                result.points_in_camera.len()
            ));
        }
        let in_plane: Vec<Point2<f64>> =
            result.points_in_camera.iter().map(|(_, p)| plane.to_plane(p)).collect();
        let (_, hi) = self.radius_range_mm();
        let estimator = CircleEstimator {
            points: &in_plane,
            radius_range_mm: (CIRCLE_MIN_RADIUS_FACTOR * self.prior.fruit_radius_mm, hi),
        };
        let threshold = self.options.inlier_threshold_mm;
        let ransac_options = RansacOptions {
            threshold,
            confidence: 0.999,
            max_iterations: 500,
            seed: self.options.seed ^ index as u64,
        };
        let Some(outcome) = ransac_refit(&estimator, &ransac_options, 2) else {
            return Err("no circle through the stripe points".into());
        };
        let (circle, inliers) = (outcome.model, outcome.inliers);
        if inliers.len() < min_points {
            return Err(format!(
                "{} points on the best circle, fewer than {min_points}",
                inliers.len()
            ));
        }
        if !(estimator.radius_range_mm.0..=estimator.radius_range_mm.1).contains(&circle.radius_mm)
        {
            return Err(format!("the circle's radius {:.1} mm is out of range", circle.radius_mm));
        }
        let arc: Vec<Point2<f64>> = inliers.iter().map(|&i| in_plane[i]).collect();
        let fit_rms_mm = rms_mm(arc.iter().map(|p| circle.distance_mm(p)));
        if fit_rms_mm > self.options.max_fit_rms_mm {
            return Err(format!(
                "the arc's points scatter {fit_rms_mm:.2} mm RMS about the circle, more than {:.2} mm",
                self.options.max_fit_rms_mm
            ));
        }
        let straightness = line_rms_mm(&arc);
        if straightness < CURVATURE_SIGNIFICANCE * fit_rms_mm.max(MIN_NOISE_MM) {
            return Err(format!(
                "the points are nearly straight ({straightness:.2} mm RMS from a line): a flat surface, not a fruit"
            ));
        }
        let position_mm = self.centre_from_circle(plane, &circle, &arc);
        let rows: Vec<f64> =
            inliers.iter().map(|&i| result.stripe[result.points_in_camera[i].0].v_px).collect();
        let (first, last) = rows
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let continuity = inliers.len() as f64 / (last - first + 1.0).max(1.0);
        let fruit: Vec<usize> = inliers.iter().map(|&i| result.points_in_camera[i].0).collect();
        Ok((
            fruit,
            Candidate {
                frame: index,
                slide_mm,
                position_mm,
                circle_radius_mm: circle.radius_mm,
                n_points: inliers.len(),
                continuity: continuity.min(1.0),
                fit_rms_mm,
                score: 0.0,
            },
        ))
    }

    /// The fruit centre on the circle's axis, sqrt(R^2 - rho^2) off the
    /// plane (R the prior, at least rho), on the side from which the arc's
    /// points face the camera (ties: the side nearer the rough position).
    fn centre_from_circle(
        &self,
        plane: &PlaneFrame,
        circle: &Circle,
        arc: &[Point2<f64>],
    ) -> Point3<f64> {
        let centre_on_plane = plane.point_at(&circle.centre);
        let radius = self.prior.fruit_radius_mm.max(circle.radius_mm);
        let height = (radius * radius - circle.radius_mm * circle.radius_mm).max(0.0).sqrt();
        let points: Vec<Point3<f64>> = arc.iter().map(|q| plane.point_at(q)).collect();
        let option = |sign: f64| {
            let centre = centre_on_plane + plane.normal.into_inner() * (sign * height);
            let facing = facing_fraction(&centre, &points);
            let distance = (centre - self.prior.rough_position_mm).norm();
            (centre, facing, distance)
        };
        let (a, b) = (option(1.0), option(-1.0));
        let better_a = if (a.1 - b.1).abs() > 0.05 { a.1 > b.1 } else { a.2 <= b.2 };
        if better_a { a.0 } else { b.0 }
    }
}

/// Fraction of surface points whose outward normal (from `centre`) faces
/// the camera at the origin.
fn facing_fraction(centre: &Point3<f64>, points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let facing = points.iter().filter(|p| (*p - centre).dot(&(-p.coords)) > 0.0).count();
    facing as f64 / points.len() as f64
}

/// Fewest fruit points of a frame at any resolution.
const MIN_POINTS: usize = 6;

/// Smallest circle, as a fraction of the radius prior: the plane grazing
/// the fruit's side.
const CIRCLE_MIN_RADIUS_FACTOR: f64 = 0.15;

/// An arc counts as curved when its points lie this many times farther from
/// a straight line than from the circle.
const CURVATURE_SIGNIFICANCE: f64 = 4.0;

/// The floor of the scatter used by the curvature test, mm (noise-free
/// points must still bend visibly).
const MIN_NOISE_MM: f64 = 0.15;

/// Fills in every candidate's holistic score ([`Candidate::score`]);
/// `expected_rows` is the rows a fruit of the prior radius spans.
fn score_candidates(
    results: &mut [FrameResult],
    search: &SearchBall,
    prior: &Prior,
    options: &LocateOptions,
    expected_rows: f64,
) {
    let positions: Vec<Point3<f64>> =
        results.iter().filter_map(|r| r.candidate.as_ref().map(|c| c.position_mm)).collect();
    for result in results.iter_mut() {
        let Some(candidate) = result.candidate.as_mut() else { continue };
        let mut distances: Vec<f64> = positions
            .iter()
            .map(|p| (p - candidate.position_mm).norm())
            .filter(|d| *d > 0.0)
            .collect();
        distances.sort_by(f64::total_cmp);
        let disagreement = distances.get(distances.len() / 2).copied().unwrap_or(0.0);
        let coverage = (candidate.n_points as f64 / expected_rows.max(1.0)).min(1.0);
        let rough = (candidate.position_mm - search.centre).norm() / search.radius_mm;
        candidate.score = coverage + candidate.continuity
            - candidate.fit_rms_mm / options.inlier_threshold_mm
            - disagreement / prior.fruit_radius_mm
            - rough;
    }
}

/// The fused estimate: one robust sphere fit over every frame's fruit
/// points, with the checks that make it trustworthy.
fn fuse(results: &[FrameResult], context: &FrameContext) -> std::result::Result<FusedFit, String> {
    let (search, prior, options) = (context.search, context.prior, context.options);
    let (points, frame_of) = fruit_points(results);
    let frames_with_points = count_frames(&frame_of, 0..points.len());
    if frames_with_points < 2 {
        return Err(match frames_with_points {
            0 => no_candidate_reason(results),
            _ => "the fruit was seen in one frame only; a sphere needs two cuts".into(),
        });
    }
    let (lo, hi) = options.radius_factors;
    let radius_range_mm = (lo * prior.fruit_radius_mm, hi * prior.fruit_radius_mm);
    let estimator = SphereEstimator { points: &points, radius_range_mm };
    let threshold = options.inlier_threshold_mm;
    let ransac_options =
        RansacOptions { threshold, confidence: 0.999, max_iterations: 1000, seed: options.seed };
    let outcome = ransac_refit(&estimator, &ransac_options, 3)
        .ok_or_else(|| "no sphere through the fruit points of the frames".to_string())?;
    let (sphere, inliers) = (outcome.model, outcome.inliers);
    let on_sphere: Vec<Point3<f64>> = inliers.iter().map(|&i| points[i]).collect();
    let n_frames = count_frames(&frame_of, inliers.iter().copied());
    if n_frames < 2 {
        return Err("the frames' fruit points do not lie on one sphere".into());
    }
    let rms = rms_mm(on_sphere.iter().map(|p| sphere.distance_mm(p)));
    if !(radius_range_mm.0..=radius_range_mm.1).contains(&sphere.radius_mm) {
        return Err(format!(
            "the fitted radius {:.1} mm is outside {:.0}-{:.0} mm",
            sphere.radius_mm, radius_range_mm.0, radius_range_mm.1
        ));
    }
    // The sphere predicts how many rows each frame's cut spans; a fruit
    // hidden behind leaves shows part of them, a chance fit to clutter few.
    let expected_rows: f64 = results
        .iter()
        .filter_map(|r| PlaneFrame::new(context.laser, r.slide_mm))
        .map(|plane| {
            let d = plane.signed_distance_mm(&sphere.centre);
            let rho = (sphere.radius_mm.powi(2) - d * d).max(0.0).sqrt();
            2.0 * rho * context.camera.fy_px / sphere.centre.z
        })
        .sum();
    let coverage = inliers.len() as f64 / expected_rows.max(1.0);
    if coverage < options.min_coverage {
        return Err(format!(
            "the fitted fruit shows {:.0} % of the stripe rows it should ({} of {:.0}): too little to trust",
            100.0 * coverage,
            inliers.len(),
            expected_rows
        ));
    }
    check_sphere(&sphere, &on_sphere, rms, search, options)?;
    // The ellipsoid replaces the sphere only where it fits clearly better:
    // on a round fruit its extra freedom only follows the noise.
    let ellipsoid =
        fit_ellipsoid_robust(&on_sphere, &sphere, rms.max(MIN_NOISE_MM), ELLIPSOID_PRIOR_POINTS)
            .filter(|e| {
                let ellipsoid_rms = rms_mm(on_sphere.iter().map(|p| e.distance_mm(p)));
                ellipsoid_rms * ellipsoid_rms < (1.0 - MIN_SSE_REDUCTION) * rms * rms
            });
    Ok(FusedFit {
        sphere,
        ellipsoid,
        n_points: inliers.len(),
        n_frames,
        rms_mm: rms,
        radius_from_prior: false,
        outline: None,
    })
}

/// Weight of the ellipsoid's roundness prior, in points. On 21 simulated
/// ellipsoidal fruit (semi-axes within 8 % of the mean) weights of 10 and
/// 50 gave the same mean 3-D error, 1.7 mm (the sphere alone: 2.6 mm); the
/// front of a fruit does not fix its depth semi-axis, so the prior decides
/// it, and the worst cases stay near 5 mm either way.
const ELLIPSOID_PRIOR_POINTS: f64 = 20.0;

/// The ellipsoid must cut the sum of squared distances by this fraction
/// (measured: on simulated spheres it cuts 1-25 %, on fruit with semi-axes
/// 8 % apart mostly 40-90 %).
const MIN_SSE_REDUCTION: f64 = 0.3;

/// Every frame's fruit points, with the frame each came from.
fn fruit_points(results: &[FrameResult]) -> (Vec<Point3<f64>>, Vec<usize>) {
    let mut points = Vec::new();
    let mut frame_of = Vec::new();
    for (k, result) in results.iter().enumerate() {
        for (i, p) in &result.points_in_camera {
            if result.fruit.contains(i) {
                points.push(*p);
                frame_of.push(k);
            }
        }
    }
    (points, frame_of)
}

/// The fallback when the free fit is not trustworthy: a sphere of the
/// prior radius through the frames' fruit points (Gauss-Newton on the
/// centre from each frame's candidate and the rough position, keeping the
/// start with most points within the inlier threshold), with the same
/// checks as the free fit except the coverage, which a fruit mostly hidden
/// cannot meet.
fn fit_prior_radius(
    results: &[FrameResult],
    context: &FrameContext,
    starts: &[Point3<f64>],
) -> std::result::Result<FusedFit, String> {
    let (search, prior, options) = (context.search, context.prior, context.options);
    let (points, frame_of) = fruit_points(results);
    let min_points = 2 * context.min_points();
    if points.len() < min_points {
        return Err(format!("{} fruit points, fewer than {min_points}", points.len()));
    }
    let radius = prior.fruit_radius_mm;
    let threshold = options.inlier_threshold_mm;
    let mut best: Option<(Sphere, Vec<usize>, f64)> = None;
    for start in starts.iter().chain(std::iter::once(&search.centre)) {
        let mut sphere = Sphere { centre: *start, radius_mm: radius };
        let mut inliers: Vec<usize> = (0..points.len()).collect();
        for _ in 0..4 {
            let chosen: Vec<Point3<f64>> = inliers.iter().map(|&i| points[i]).collect();
            let Some(centre) = fit_centre_for_radius(&chosen, &sphere.centre, radius) else {
                break;
            };
            sphere.centre = centre;
            inliers = (0..points.len())
                .filter(|&i| sphere.distance_mm(&points[i]) <= threshold)
                .collect();
            if inliers.len() < 4 {
                break;
            }
        }
        let rms = rms_mm(inliers.iter().map(|&i| sphere.distance_mm(&points[i])));
        let better = match &best {
            None => true,
            Some((_, b, b_rms)) => {
                inliers.len() > b.len() || (inliers.len() == b.len() && rms < *b_rms)
            }
        };
        if better {
            best = Some((sphere, inliers, rms));
        }
    }
    let Some((sphere, inliers, rms)) = best else {
        return Err("no sphere of the prior radius fits the fruit points".into());
    };
    if inliers.len() < min_points {
        return Err(format!("{} points on the sphere, fewer than {min_points}", inliers.len()));
    }
    let on_sphere: Vec<Point3<f64>> = inliers.iter().map(|&i| points[i]).collect();
    check_sphere(&sphere, &on_sphere, rms, search, options)?;
    Ok(FusedFit {
        sphere,
        ellipsoid: None,
        n_points: inliers.len(),
        n_frames: count_frames(&frame_of, inliers.iter().copied()),
        rms_mm: rms,
        radius_from_prior: true,
        outline: None,
    })
}

/// The last resort ([`crate::outline`]): the fruit's outline in the
/// frames, and a sphere fitted to it and to the laser points near the
/// fruit, from every frame (not only the arcs the frames kept). The laser
/// must confirm a curved surface in at least one frame, and the sphere
/// passes the same checks as the others.
fn fit_with_outline(
    results: &[FrameResult],
    context: &FrameContext,
    frames: &[FrameImages],
) -> std::result::Result<FusedFit, String> {
    let (camera, search, options) = (context.camera, context.search, context.options);
    // The search ball's image: a box, the outline's radius range, and where
    // its centre may lie.
    let centre = search.centre;
    let near_mm = (centre.z - search.radius_mm).max(0.5 * centre.z);
    let centre_px = camera.project(&centre).map_err(|e| e.to_string())?;
    let ball_px = camera.fx_px.max(camera.fy_px) * search.radius_mm / near_mm;
    let clip = |x: f64, size: u32| x.clamp(0.0, f64::from(size)) as u32;
    let area = PixelBox {
        u0: clip(centre_px.x - ball_px, camera.width_px),
        v0: clip(centre_px.y - ball_px, camera.height_px),
        u1: clip(centre_px.x + ball_px + 1.0, camera.width_px),
        v1: clip(centre_px.y + ball_px + 1.0, camera.height_px),
    };
    let (lo_mm, hi_mm) = context.radius_range_mm();
    let f_px = 0.5 * (camera.fx_px + camera.fy_px);
    let radius_range_px = (f_px * lo_mm / (centre.z + search.radius_mm), f_px * hi_mm / near_mm);
    let images: Vec<&RgbImage> =
        frames.iter().map(|f| f.image_laser_off.unwrap_or(f.image)).collect();
    let outline = find_outline(
        &images,
        area,
        radius_range_px,
        |c| (c - centre_px).norm() <= ball_px,
        options.seed,
    )?;
    let mut points = Vec::new();
    let mut frame_of = Vec::new();
    for (k, result) in results.iter().enumerate() {
        for (_, p) in &result.points_in_camera {
            points.push(*p);
            frame_of.push(k);
        }
    }
    let threshold = options.inlier_threshold_mm;
    let fit = fit_outline_sphere(camera, &outline, &points, threshold)?;
    let min_points = context.min_points();
    if fit.inliers.len() < min_points {
        return Err(format!(
            "{} laser points on the sphere of the fruit's outline, fewer than {min_points}",
            fit.inliers.len()
        ));
    }
    if fit.outline_rms_mm > MAX_OUTLINE_RMS_MM {
        return Err(format!(
            "the outline's rays miss the fitted sphere by {:.2} mm RMS, more than {MAX_OUTLINE_RMS_MM:.1} mm",
            fit.outline_rms_mm
        ));
    }
    if !(lo_mm..=hi_mm).contains(&fit.sphere.radius_mm) {
        return Err(format!(
            "the radius {:.1} mm from the outline is outside {lo_mm:.0}-{hi_mm:.0} mm",
            fit.sphere.radius_mm
        ));
    }
    // The laser must see a curved surface: some frame's points on the
    // sphere bend away from a straight line in the laser plane, beyond
    // their scatter about their own circle (the test of a frame's arc).
    let curved = results.iter().enumerate().any(|(k, result)| {
        let Some(plane) = PlaneFrame::new(context.laser, result.slide_mm) else { return false };
        let arc: Vec<Point2<f64>> = fit
            .inliers
            .iter()
            .filter(|&&i| frame_of[i] == k)
            .map(|&i| plane.to_plane(&points[i]))
            .collect();
        let Some(circle) = fit_circle(&arc).filter(|_| arc.len() >= MIN_POINTS) else {
            return false;
        };
        let scatter = rms_mm(arc.iter().map(|p| circle.distance_mm(p)));
        line_rms_mm(&arc) >= CURVATURE_SIGNIFICANCE * scatter.max(MIN_NOISE_MM)
    });
    if !curved {
        return Err("the laser points on the outline's sphere are nearly straight in every frame: not a fruit".into());
    }
    let on_sphere: Vec<Point3<f64>> = fit.inliers.iter().map(|&i| points[i]).collect();
    check_sphere_fit(&fit.sphere, &on_sphere, fit.rms_mm, search, options)?;
    Ok(FusedFit {
        sphere: fit.sphere,
        ellipsoid: None,
        n_points: fit.inliers.len(),
        n_frames: count_frames(&frame_of, fit.inliers.iter().copied()),
        rms_mm: fit.rms_mm,
        radius_from_prior: false,
        outline: Some(outline),
    })
}

/// Largest RMS distance of the outline's rays from the fitted sphere, mm: a
/// pixel is about 0.5 mm at 1.2 m, and a fruit 8 % from round departs a few
/// millimetres from any sphere.
const MAX_OUTLINE_RMS_MM: f64 = 3.0;

/// The checks every fused sphere must pass, free or of the prior radius:
/// those of [`check_sphere_fit`], and a surface curved beyond its noise.
fn check_sphere(
    sphere: &Sphere,
    on_sphere: &[Point3<f64>],
    rms: f64,
    search: &SearchBall,
    options: &LocateOptions,
) -> std::result::Result<(), String> {
    check_sphere_fit(sphere, on_sphere, rms, search, options)?;
    let flatness = plane_rms_mm(on_sphere);
    if flatness < CURVATURE_SIGNIFICANCE * rms.max(MIN_NOISE_MM) {
        return Err(format!(
            "the points are nearly flat ({flatness:.2} mm RMS from a plane): not a fruit"
        ));
    }
    Ok(())
}

/// The checks of any fitted sphere: the points' scatter about it, its
/// centre within the search ball, and the points facing the camera from it.
fn check_sphere_fit(
    sphere: &Sphere,
    on_sphere: &[Point3<f64>],
    rms: f64,
    search: &SearchBall,
    options: &LocateOptions,
) -> std::result::Result<(), String> {
    if rms > options.max_fit_rms_mm {
        return Err(format!(
            "the fruit points scatter {rms:.2} mm RMS about the fitted sphere, more than {:.2} mm",
            options.max_fit_rms_mm
        ));
    }
    let offset = (sphere.centre - search.centre).norm();
    if offset > search.radius_mm {
        return Err(format!(
            "the fitted centre lies {offset:.0} mm from the rough position, beyond the {:.0} mm search ball",
            search.radius_mm
        ));
    }
    let facing = facing_fraction(&sphere.centre, on_sphere);
    if facing < MIN_FACING_FRACTION {
        return Err(format!(
            "only {:.0} % of the points face the camera on the fitted sphere",
            100.0 * facing
        ));
    }
    Ok(())
}

/// Gauss-Newton on the centre of a sphere of known radius, from `start`.
fn fit_centre_for_radius(
    points: &[Point3<f64>],
    start: &Point3<f64>,
    radius_mm: f64,
) -> Option<Point3<f64>> {
    let mut centre = *start;
    for _ in 0..20 {
        let mut jtj = nalgebra::Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for p in points {
            let d = p - centre;
            let n = d.norm();
            if n <= 0.0 {
                continue;
            }
            let j = -d / n;
            jtj += j * j.transpose();
            jtr += j * (n - radius_mm);
        }
        let step = jtj.lu().solve(&(-jtr))?;
        centre += step;
        if step.norm() < 1e-6 {
            break;
        }
    }
    centre.coords.iter().all(|c| c.is_finite()).then_some(centre)
}

/// Every point on a fruit's surface that the camera sees faces it; a few
/// may not, from noise at the silhouette.
const MIN_FACING_FRACTION: f64 = 0.9;

fn count_frames(frame_of: &[usize], indices: impl Iterator<Item = usize>) -> usize {
    let mut frames: Vec<usize> = indices.map(|i| frame_of[i]).collect();
    frames.sort_unstable();
    frames.dedup();
    frames.len()
}

/// Why no frame gave a candidate, from the frames' own reasons.
fn no_candidate_reason(results: &[FrameResult]) -> String {
    let reasons: Vec<String> = results
        .iter()
        .enumerate()
        .filter_map(|(k, r)| r.rejected.as_ref().map(|why| format!("frame {k}: {why}")))
        .collect();
    if reasons.is_empty() {
        "no frame shows the fruit".into()
    } else {
        format!("no frame shows the fruit ({})", reasons.join("; "))
    }
}
