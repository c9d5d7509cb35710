//! One frame, steps 1-4 of [`crate::locate()`]: the search region, the
//! stripe, the triangulated points, the circle fit and the frame's
//! candidate.

use std::collections::BTreeMap;

use alacs_model::ransac::{RansacOptions, ransac_refit};
use alacs_model::{Camera, LaserModel};
use alacs_vision::{Region, StripePoint, extract_stripe_rgb};
use image::RgbImage;
use nalgebra::{Point2, Point3, Unit, Vector3};

use crate::fit::{Circle, CircleEstimator, line_rms_mm, rms_mm};
use crate::outline::least_at_px;
use crate::{Candidate, FrameImages, FrameResult, LocateOptions, Prior, Result};

/// The ball around the rough position that holds the fruit, and the
/// tighter region its centre may lie in.
pub(crate) struct SearchBall {
    pub(crate) centre: Point3<f64>,
    pub(crate) radius_mm: f64,
    /// How far the fruit's centre may lie from the rough position along the
    /// line of sight (the RGB-D camera's depth error plus half the radius
    /// prior for the fruit's shape and the fit), mm.
    pub(crate) along_mm: f64,
    /// ... and across it (its lateral error plus half the radius prior), mm.
    pub(crate) across_mm: f64,
    /// The rough position's stated largest errors along and across the
    /// line of sight, mm (`rough_depth_error` of the depth, and
    /// `rough_lateral_error_mm`), plus the fruit's shape
    /// ([`SHAPE_MARGIN`]).
    pub(crate) stated_mm: (f64, f64),
}

/// How far a fruit's centre may lie from where a sphere of the prior
/// radius puts it, as a fraction of the radius: apples' semi-axes differ
/// by up to about a tenth (length/diameter 0.9-1.1 in common cultivars),
/// and the RGB-D camera's centre is its front's depth plus the radius.
const SHAPE_MARGIN: f64 = 0.1;

/// An answer whose centre lies more than this many of its own standard
/// deviations beyond the rough position's stated error contradicts the
/// RGB-D camera (three: one in 370 right answers refused where the
/// answer's error is Gaussian).
const CONTRADICTION_SIGMAS: f64 = 3.0;

/// The margin of the centre's region beyond the rough position's error, as
/// a fraction of the radius prior: a fitted centre errs by a few mm, a
/// touching neighbour lies a full diameter (70-90 mm) away.
const CENTRE_MARGIN: f64 = 0.5;

impl SearchBall {
    pub(crate) fn new(prior: &Prior, options: &LocateOptions) -> SearchBall {
        let depth = prior.rough_position_mm.coords.norm();
        let margin_mm = CENTRE_MARGIN * prior.fruit_radius_mm;
        SearchBall {
            centre: prior.rough_position_mm,
            radius_mm: 1.25 * prior.fruit_radius_mm
                + options.rough_depth_error * depth
                + options.rough_lateral_error_mm,
            along_mm: options.rough_depth_error * depth + margin_mm,
            across_mm: options.rough_lateral_error_mm + margin_mm,
            stated_mm: (
                options.rough_depth_error * depth + SHAPE_MARGIN * prior.fruit_radius_mm,
                options.rough_lateral_error_mm + SHAPE_MARGIN * prior.fruit_radius_mm,
            ),
        }
    }

    /// Why an answer at `centre` (its covariance `cov_mm2`, where known)
    /// contradicts the rough position, if it does: it lies farther from
    /// it, along or across the line of sight, than the rough position's
    /// stated error and [`CONTRADICTION_SIGMAS`] of its own uncertainty
    /// allow. Only an independent depth shows a calibration that scales
    /// the scene (every slide shifted by one amount, L0 or alpha off):
    /// the stripes stay consistent with each other under it.
    pub(crate) fn contradiction(
        &self,
        centre: &Point3<f64>,
        cov_mm2: Option<&nalgebra::Matrix3<f64>>,
    ) -> Option<String> {
        let sight = self.centre.coords.try_normalize(1e-9)?;
        let offset = centre - self.centre;
        let along = offset.dot(&sight);
        let across_vector = offset - sight * along;
        let across = across_vector.norm();
        let sigma = |direction: &Vector3<f64>| {
            cov_mm2.map_or(0.0, |c| direction.dot(&(c * direction)).max(0.0).sqrt())
        };
        let sigma_along = sigma(&sight);
        let sigma_across = across_vector.try_normalize(1e-9).map_or(0.0, |d| sigma(&d));
        let (stated_along, stated_across) = self.stated_mm;
        let allowed_along = stated_along + CONTRADICTION_SIGMAS * sigma_along;
        let allowed_across = stated_across + CONTRADICTION_SIGMAS * sigma_across;
        if along.abs() > allowed_along {
            return Some(format!(
                "the answer lies {:.0} mm {} the rough position along the line of sight, more than the RGB-D camera's stated error and the answer's own allow ({allowed_along:.0} mm): the slide positions, the laser or the camera's calibration contradict the RGB-D camera",
                along.abs(),
                if along > 0.0 { "behind" } else { "in front of" }
            ));
        }
        if across > allowed_across {
            return Some(format!(
                "the answer lies {across:.0} mm across the line of sight from the rough position, more than the RGB-D camera's stated error and the answer's own allow ({allowed_across:.0} mm): the slide positions, the laser or the camera's calibration contradict the RGB-D camera"
            ));
        }
        None
    }

    /// Why a fitted centre cannot be the target's, if it cannot: it lies
    /// outside the ellipsoid of the rough position's error (depth error
    /// along the line of sight, lateral error across it), where a
    /// neighbouring fruit of a cluster lies (its centre a diameter away,
    /// outside that ellipsoid in every direction).
    pub(crate) fn centre_rejection(&self, centre: &Point3<f64>) -> Option<String> {
        let sight = self.centre.coords.try_normalize(1e-9)?;
        let offset = centre - self.centre;
        let along = offset.dot(&sight);
        let across = (offset - sight * along).norm();
        let q = (along / self.along_mm).powi(2) + (across / self.across_mm).powi(2);
        (q > 1.0 || !q.is_finite()).then(|| {
            format!(
                "the fitted centre lies {:.0} mm along the line of sight and {across:.0} mm across it from the rough position, beyond the rough position's error ({:.0} mm along, {:.0} mm across): another fruit, not the target",
                along.abs(),
                self.along_mm,
                self.across_mm
            )
        })
    }
}

/// Frames whose slide positions differ by less than this claim one
/// position, mm: a tenth of a millimetre, the slide's stated repeatability
/// (a GRBL stepper slide repeats to a few hundredths).
const SAME_SLIDE_MM: f64 = 0.1;

/// Two frames at one slide position light the same pixels of a still
/// scene: their stripes may differ by the stripe's noise and a speckle's
/// shift (well under a pixel), not by this many pixels. A 10 mm step moves
/// the stripe tens of pixels at 1 m.
const MAX_SAME_SLIDE_SHIFT_PX: f64 = 3.0;

/// Rows two stripes must share to be compared.
const MIN_SHARED_ROWS: usize = 10;

/// Why the frames' slide positions contradict their images, if they do:
/// frames that claim one slide position but whose stripes moved between
/// them (a slide that did not report, or reported one position for every
/// frame). Whatever the method, such a scan has no answer.
pub(crate) fn slide_contradiction(results: &[FrameResult]) -> Option<String> {
    // A row may hold several peaks (the fruit, a leaf behind it).
    let rows = |r: &FrameResult| -> BTreeMap<i64, Vec<f64>> {
        let mut rows: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
        for s in &r.stripe {
            rows.entry(s.v_px.round() as i64).or_default().push(s.u_px);
        }
        rows
    };
    for (i, a) in results.iter().enumerate() {
        let rows_a = rows(a);
        for (j, b) in results.iter().enumerate().skip(i + 1) {
            if (a.slide_mm - b.slide_mm).abs() >= SAME_SLIDE_MM {
                continue;
            }
            let rows_b = rows(b);
            let mut shifts: Vec<f64> = rows_a
                .iter()
                .filter_map(|(v, us)| {
                    let ws = rows_b.get(v)?;
                    // Each peak of A's row against the nearest of B's.
                    us.iter()
                        .map(|u| ws.iter().map(|w| (u - w).abs()).fold(f64::INFINITY, f64::min))
                        .reduce(f64::max)
                })
                .collect();
            let fewer = rows_a.len().min(rows_b.len());
            if fewer < MIN_SHARED_ROWS {
                continue;
            }
            let moved = if shifts.len() * 2 < fewer {
                // Most rows of one stripe are not in the other: it moved away.
                None
            } else {
                shifts.sort_by(f64::total_cmp);
                let median = shifts[shifts.len() / 2];
                if median <= MAX_SAME_SLIDE_SHIFT_PX {
                    continue;
                }
                Some(median)
            };
            return Some(format!(
                "frames {} and {} claim one slide position ({:.1} mm) but the stripe moved between them ({}): the slide positions contradict the images",
                i,
                j,
                a.slide_mm,
                match moved {
                    Some(px) => format!("{px:.0} px along its rows"),
                    None => format!("{} of {fewer} rows lit in both", shifts.len()),
                }
            ));
        }
    }
    None
}

/// What every frame shares.
pub(crate) struct FrameContext<'a> {
    pub(crate) camera: &'a Camera,
    pub(crate) laser: &'a LaserModel,
    pub(crate) prior: &'a Prior,
    pub(crate) search: &'a SearchBall,
    pub(crate) options: &'a LocateOptions,
}

/// Points on the outline of the search region.
const OUTLINE_POINTS: usize = 48;

/// A laser plane with a unit normal and an orthonormal basis in it.
#[derive(Clone)]
pub(crate) struct PlaneFrame {
    pub(crate) normal: Unit<Vector3<f64>>,
    pub(crate) origin: Point3<f64>,
    pub(crate) e1: Vector3<f64>,
    pub(crate) e2: Vector3<f64>,
}

impl PlaneFrame {
    pub(crate) fn new(laser: &LaserModel, slide_mm: f64) -> Option<PlaneFrame> {
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

    pub(crate) fn to_plane(&self, p: &Point3<f64>) -> Point2<f64> {
        let d = p - self.origin;
        Point2::new(d.dot(&self.e1), d.dot(&self.e2))
    }

    pub(crate) fn point_at(&self, q: &Point2<f64>) -> Point3<f64> {
        self.origin + self.e1 * q.x + self.e2 * q.y
    }

    pub(crate) fn signed_distance_mm(&self, p: &Point3<f64>) -> f64 {
        self.normal.dot(&(p - self.origin))
    }
}

/// A frame's pixels around the search ball's image: all its stripe search
/// reads, and what another frame's search needs of it as a view without
/// that frame's laser ([`unlit_views`]).
pub(crate) struct FrameCrop {
    /// Column and row of the crop's first pixel in the frame.
    origin: (u32, u32),
    /// The frame (laser on).
    on: RgbImage,
    /// The frame's own laser-off image, where it has one.
    off: Option<RgbImage>,
    /// Slide travel, mm.
    slide_mm: f64,
}

impl FrameCrop {
    /// The crop's view without the laser: its laser-off image, or itself
    /// where it has none (the laser then lights one line of it).
    fn view(&self) -> &RgbImage {
        self.off.as_ref().unwrap_or(&self.on)
    }
}

/// Pixels the crop around the search ball's image keeps beyond it on
/// each side: more than the line detector reads beyond a search region's
/// span (`LocalBackground`'s gap and window, 9 px for the orchard's).
const CROP_MARGIN_PX: f64 = 24.0;

/// Points on the search ball's silhouette projected to find its image.
const SILHOUETTE_POINTS: usize = 64;

/// Per frame, the scan's other frames as its view without the laser: the
/// per-pixel minimum of the frames at least [`MIN_SLIDES_APART_MM`] from
/// it, where the laser lit other lines of a scene that stood still (their
/// laser-off images where they have them). `None` for a frame with its own
/// laser-off image, or with no such other frame. Its stripe is then
/// searched on its difference to that view, the laser's own light, as a
/// frame with a laser-off image is: the fruit's and the leaves' colours
/// cancel, so a line on green or sunlit red skin, or spread by the flesh
/// to a few DN, stands out where the colour score loses it.
pub(crate) fn unlit_views(crops: &[FrameCrop]) -> Vec<Option<RgbImage>> {
    crops
        .iter()
        .map(|crop| {
            if crop.off.is_some() {
                return None;
            }
            let mut others = crops
                .iter()
                .filter(|o| (o.slide_mm - crop.slide_mm).abs() >= MIN_SLIDES_APART_MM)
                .filter(|o| o.origin == crop.origin && o.on.dimensions() == crop.on.dimensions());
            let mut least = others.next()?.view().clone();
            for other in others {
                for (l, v) in least.iter_mut().zip(other.view().iter()) {
                    *l = (*l).min(*v);
                }
            }
            Some(least)
        })
        .collect()
}

impl FrameContext<'_> {
    /// The pixel box (first column, first row, columns, rows) around the
    /// search ball's image, with [`CROP_MARGIN_PX`]: the ball's silhouette
    /// projected, or the whole image where the ball reaches behind the
    /// camera.
    fn ball_box(&self) -> (u32, u32, u32, u32) {
        let (width, height) = (self.camera.width_px, self.camera.height_px);
        let whole = (0, 0, width, height);
        let (centre, radius) = (self.search.centre.coords, self.search.radius_mm);
        let distance = centre.norm();
        if !(distance > radius && radius > 0.0) {
            return whole;
        }
        // The silhouette: the circle where the camera's rays touch the ball.
        let sight = centre / distance;
        let along = (distance * distance - radius * radius) / distance;
        let rho = radius * (distance * distance - radius * radius).sqrt() / distance;
        let Some(e1) = sight.cross(&Vector3::x()).try_normalize(1e-9) else { return whole };
        let e2 = sight.cross(&e1);
        let (mut lo, mut hi) = (
            Point2::new(f64::INFINITY, f64::INFINITY),
            Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for k in 0..SILHOUETTE_POINTS {
            let t = std::f64::consts::TAU * k as f64 / SILHOUETTE_POINTS as f64;
            let p = Point3::from(sight * along + (e1 * t.cos() + e2 * t.sin()) * rho);
            let Some(px) = self.camera.project(&p).ok().filter(|_| p.z > 0.0) else {
                return whole;
            };
            (lo.x, lo.y, hi.x, hi.y) =
                (lo.x.min(px.x), lo.y.min(px.y), hi.x.max(px.x), hi.y.max(px.y));
        }
        let clamp = |x: f64, limit: u32| x.clamp(0.0, f64::from(limit)) as u32;
        let (u0, v0) = (clamp(lo.x - CROP_MARGIN_PX, width), clamp(lo.y - CROP_MARGIN_PX, height));
        let (u1, v1) =
            (clamp(hi.x + CROP_MARGIN_PX + 1.0, width), clamp(hi.y + CROP_MARGIN_PX + 1.0, height));
        (u0, v0, u1.saturating_sub(u0), v1.saturating_sub(v0))
    }

    /// The frame's pixels around the search ball's image.
    pub(crate) fn crop(&self, frame: &FrameImages) -> FrameCrop {
        let (u0, v0, w, h) = self.ball_box();
        let cut = |image: &RgbImage| image::imageops::crop_imm(image, u0, v0, w, h).to_image();
        FrameCrop {
            origin: (u0, v0),
            on: cut(frame.image),
            off: frame.image_laser_off.map(cut),
            slide_mm: frame.slide_mm,
        }
    }

    /// Steps 1-4 for one frame: its crop ([`FrameContext::crop`]) and,
    /// where it has no laser-off image, the scan's other frames as one
    /// ([`unlit_views`]).
    pub(crate) fn frame(
        &self,
        index: usize,
        crop: &FrameCrop,
        unlit: Option<&RgbImage>,
    ) -> Result<FrameResult> {
        let mut result = FrameResult {
            slide_mm: crop.slide_mm,
            region_outline_px: Vec::new(),
            stripe: Vec::new(),
            points_in_camera: Vec::new(),
            fruit: Vec::new(),
            candidate: None,
            rejected: None,
            stripe_red_dn: Vec::new(),
        };
        let Some(plane) = PlaneFrame::new(self.laser, crop.slide_mm) else {
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
        // 2. The stripe, searched in the crop.
        let (u0, v0) = (f64::from(crop.origin.0), f64::from(crop.origin.1));
        let in_crop: Vec<Point2<f64>> =
            result.region_outline_px.iter().map(|p| Point2::new(p.x - u0, p.y - v0)).collect();
        let region = Region::convex_polygon(&in_crop, 0.0, crop.on.width(), crop.on.height());
        let off = crop.off.as_ref().or(unlit);
        result.stripe = extract_stripe_rgb(&crop.on, off, &region, &self.options.stripe)?;
        if off.is_none() {
            // The pixel's red: the per-pixel minimum of this one image.
            let red_at = |s: &StripePoint| {
                least_at_px(&[&crop.on], s.u_px.round(), s.v_px.round()).map_or(0, |rgb| rgb[0])
            };
            result.stripe_red_dn = result.stripe.iter().map(red_at).collect();
        }
        for point in &mut result.stripe {
            point.u_px += u0;
            point.v_px += v0;
        }
        // 3. Triangulated points inside the ball.
        let prepared = self.laser.prepare();
        result.points_in_camera = result
            .stripe
            .iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let normalized = self.camera.undistort_pixel(&Point2::new(s.u_px, s.v_px)).ok()?;
                let p = prepared.triangulate(&normalized, crop.slide_mm).ok()?;
                ((p - self.search.centre).norm() <= self.search.radius_mm).then_some((i, p))
            })
            .collect();
        self.find_candidate(index, &plane, &mut result);
        Ok(result)
    }

    /// The frame's fruit points and candidate, or why it has none, from its
    /// `points_in_camera` (again after [`drop_unlit_points`] took some).
    fn find_candidate(&self, index: usize, plane: &PlaneFrame, result: &mut FrameResult) {
        (result.fruit, result.candidate, result.rejected) =
            match self.frame_candidate(index, result.slide_mm, plane, result) {
                Ok((fruit, candidate)) => (fruit, Some(candidate), None),
                Err(reason) => (Vec::new(), None, Some(reason)),
            };
    }

    /// Rows a fruit of the prior radius spans at the rough depth.
    pub(crate) fn expected_rows(&self) -> f64 {
        2.0 * self.prior.fruit_radius_mm * self.camera.fy_px / self.prior.rough_position_mm.z
    }

    pub(crate) fn min_points(&self) -> usize {
        ((self.options.min_points_fraction * self.expected_rows()).ceil() as usize).max(MIN_POINTS)
    }

    pub(crate) fn radius_range_mm(&self) -> (f64, f64) {
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
pub(crate) fn facing_fraction(centre: &Point3<f64>, points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let facing = points.iter().filter(|p| (*p - centre).dot(&(-p.coords)) > 0.0).count();
    facing as f64 / points.len() as f64
}

/// Fewest fruit points of a frame at any resolution.
pub(crate) const MIN_POINTS: usize = 6;

/// Smallest circle, as a fraction of the radius prior: the plane grazing
/// the fruit's side.
const CIRCLE_MIN_RADIUS_FACTOR: f64 = 0.15;

/// An arc counts as curved when its points lie this many times farther from
/// a straight line than from the circle.
pub(crate) const CURVATURE_SIGNIFICANCE: f64 = 4.0;

/// The floor of the scatter used by the curvature test, mm (noise-free
/// points must still bend visibly).
pub(crate) const MIN_NOISE_MM: f64 = 0.15;

/// Why no frame gave a candidate, from the frames' own reasons.
pub(crate) fn no_candidate_reason(results: &[FrameResult]) -> String {
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

/// Slide positions closer than this may light the same pixels (the
/// stripe, a few pixels wide, moves about 2 px per mm at 1 m): frames
/// this close do not show each other's unlit view.
const MIN_SLIDES_APART_MM: f64 = 2.5;

/// Drops the triangulated stripe points the laser did not light, in frames
/// without a laser-off image, and finds those frames' fruit points and
/// candidates again. The laser only adds light, so the per-pixel minimum
/// over frames at slides apart (`views`, [`crate::outline::least_at_px`])
/// is the scene without it. A stripe point whose pixel's red is not higher
/// in its frame by the stripe's least strength
/// (`StripeOptions::min_strength`, the least the laser must show; where
/// the red clips, what the clipping leaves room for) is a red ridge of the
/// scene itself (a sunlit fruit's rim against a leaf), found where the
/// laser lies in a leaf's shadow; triangulated on the frame's laser plane,
/// its points lie centimetres behind the fruit's front and would fix a
/// wrong depth for the outline's sphere. (The points' strength, their
/// colour's contrast with the neighbours, is no measure: a ridge beside a
/// dark branch scores 100 where the laser adds 40 DN.) A frame with no
/// other frame beyond [`MIN_SLIDES_APART_MM`] of it has no unlit view:
/// nothing is dropped there.
pub(crate) fn drop_unlit_points(
    results: &mut [FrameResult],
    context: &FrameContext,
    views: &[&RgbImage],
) {
    if views.is_empty() {
        return;
    }
    let (lowest, highest) = results
        .iter()
        .map(|r| r.slide_mm)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| (lo.min(s), hi.max(s)));
    for (index, result) in results.iter_mut().enumerate() {
        let farthest_mm = (result.slide_mm - lowest).max(highest - result.slide_mm);
        if farthest_mm < MIN_SLIDES_APART_MM || result.stripe_red_dn.len() != result.stripe.len() {
            continue;
        }
        let before = result.points_in_camera.len();
        let (stripe, red) = (&result.stripe, &result.stripe_red_dn);
        let min_strength = context.options.stripe.min_strength;
        result.points_in_camera.retain(|(i, _)| {
            let point = &stripe[*i];
            let (u, v) = (point.u_px.round(), point.v_px.round());
            let unlit = least_at_px(views, u, v).map_or(0, |rgb| rgb[0]);
            // Where the red clips, the laser shows no more than the
            // clipping leaves room for.
            let least_added = min_strength.min(f32::from(u8::MAX - unlit)).max(1.0);
            f32::from(red[*i].saturating_sub(unlit)) >= least_added
        });
        if let Some(plane) = PlaneFrame::new(context.laser, result.slide_mm)
            .filter(|_| result.points_in_camera.len() < before)
        {
            context.find_candidate(index, &plane, result);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rough position at 1 m with the default stated errors (3 %, 10 mm)
    /// and a 40 mm radius prior: 34 mm along the line of sight, 14 mm across.
    fn ball() -> SearchBall {
        let prior =
            Prior { rough_position_mm: Point3::new(0.0, 0.0, 1000.0), fruit_radius_mm: 40.0 };
        SearchBall::new(&prior, &LocateOptions::default())
    }

    #[test]
    fn an_answer_beyond_the_rough_positions_stated_error_contradicts_it() {
        let ball = ball();
        assert!(ball.contradiction(&Point3::new(0.0, 0.0, 1030.0), None).is_none());
        let reason = ball.contradiction(&Point3::new(0.0, 0.0, 1040.0), None).unwrap();
        assert!(reason.contains("40 mm behind") && reason.contains("contradict"), "{reason}");
        assert!(ball.contradiction(&Point3::new(0.0, 0.0, 960.0), None).is_some());
        assert!(ball.contradiction(&Point3::new(16.0, 0.0, 1000.0), None).is_some());
        // The answer's own uncertainty widens what is allowed: 3 sigma of 3 mm.
        let cov = nalgebra::Matrix3::from_diagonal_element(9.0);
        assert!(ball.contradiction(&Point3::new(0.0, 0.0, 1040.0), Some(&cov)).is_none());
        assert!(ball.contradiction(&Point3::new(0.0, 0.0, 1045.0), Some(&cov)).is_some());
    }

    /// A bicolour fruit's rows: greenish-yellow skin with a red streak at
    /// column 30 (skin colour, 120 DN of colour contrast), and the laser at
    /// `line_px` adding 20 DN of red with a sigma of 2.5 px (a line spread
    /// by the flesh).
    fn bicolour_rows(line_px: f64) -> RgbImage {
        RgbImage::from_fn(120, 12, |u, _| {
            let u = f64::from(u);
            let streak = 120.0 * (-0.5 * ((u - 30.0) / 1.5).powi(2)).exp();
            let laser = 20.0 * (-0.5 * ((u - line_px) / 2.5).powi(2)).exp();
            image::Rgb([(110.0 + streak + laser) as u8, 130, 40])
        })
    }

    fn crop(on: RgbImage, off: Option<RgbImage>, slide_mm: f64) -> FrameCrop {
        FrameCrop { origin: (0, 0), on, off, slide_mm }
    }

    #[test]
    fn the_other_frames_are_a_frames_view_without_its_laser() {
        let crops = [
            crop(bicolour_rows(60.0), None, 0.0),
            crop(bicolour_rows(75.0), None, 10.0),
            crop(bicolour_rows(90.0), None, 20.0),
            crop(bicolour_rows(91.0), None, 21.0),
            crop(bicolour_rows(60.0), Some(bicolour_rows(-100.0)), 30.0),
        ];
        let unlit = unlit_views(&crops);
        // The first frame's view: the skin without any line at 60 px.
        let view = unlit[0].as_ref().unwrap();
        assert_eq!(view.get_pixel(60, 5), bicolour_rows(-100.0).get_pixel(60, 5));
        assert_eq!(view.get_pixel(30, 5), bicolour_rows(-100.0).get_pixel(30, 5));
        // A frame with its own laser-off image keeps it.
        assert!(unlit[4].is_none());
        // Only frames at other slides count: none for a lone frame.
        assert!(unlit_views(&crops[..1])[0].is_none());
        assert!(
            unlit_views(&[
                crop(bicolour_rows(60.0), None, 0.0),
                crop(bicolour_rows(61.0), None, 1.0)
            ])[0]
                .is_none()
        );
    }

    #[test]
    fn a_weak_line_beside_a_skin_streak_is_found_against_the_other_frames() {
        let options = LocateOptions::default().stripe;
        let region = Region::full(120, 12);
        let on = bicolour_rows(60.0);
        // On the colour score the streak outshines the line six to one (the
        // orchard search drops peaks under a fifth of the row's strongest).
        let by_colour = extract_stripe_rgb(&on, None, &region, &options).unwrap();
        assert!(by_colour.iter().all(|p| (p.u_px - 60.0).abs() > 3.0), "{by_colour:?}");
        // Against the other frames the streak cancels and the line is found.
        let crops = [
            crop(on.clone(), None, 0.0),
            crop(bicolour_rows(75.0), None, 10.0),
            crop(bicolour_rows(90.0), None, 20.0),
        ];
        let unlit = unlit_views(&crops);
        let found = extract_stripe_rgb(&on, unlit[0].as_ref(), &region, &options).unwrap();
        assert_eq!(found.len(), 12, "{found:?}");
        assert!(found.iter().all(|p| (p.u_px - 60.0).abs() < 0.1), "{found:?}");
    }
}
