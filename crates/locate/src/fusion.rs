//! The fused answer: the hypotheses of the one estimator
//! ([`crate::estimate`]) from today's fits (a robust sphere over every
//! frame's fruit points, a sphere of the prior radius, the sphere of the
//! fruit's outline, [`crate::outline`]), the acceptance, and the accepted
//! sphere's refinement by the outline. The fits' own checks only decide
//! whether they propose a sphere; the estimator decides the answer.

use alacs_model::ransac::{RansacOptions, ransac_refit};
use image::RgbImage;
use nalgebra::{Matrix3, Point2, Point3, Vector3};

use crate::fit::{
    Ellipsoid, Rays, Sphere, SphereEstimator, fit_circle, fit_ellipsoid_with_rays, line_rms_mm,
    plane_rms_mm, rms_mm,
};
use crate::frame::{
    CURVATURE_SIGNIFICANCE, FrameContext, MIN_NOISE_MM, MIN_POINTS, PlaneFrame, SearchBall,
    facing_fraction, no_candidate_reason,
};
use crate::outline::{
    FruitColours, LearnedColours, OUTLINE_WEIGHT, Outline, PixelBox, find_outline,
    fit_outline_sphere, is_fruit_coloured_at, outline_rays, rays_through, silhouette_edges,
};
use crate::{Candidate, FrameResult, FusedFit, Localization, LocateOptions, Status};

/// What the one estimator accepted: the fit, how it was found, and its
/// position covariance (mm^2, camera frame; `None` where the points do not
/// fix it), computed once for the acceptance test and the answer.
pub(crate) struct Accepted {
    pub(crate) fit: FusedFit,
    pub(crate) note: String,
    pub(crate) covariance: Option<Matrix3<f64>>,
}

/// The fused fit by the one estimator ([`crate::estimate`]): every fit
/// below proposes a sphere (whatever its own checks say), as do robust
/// spheres through all frames' points, each frame's arc at the prior
/// radius on both sides of its laser plane, and the rough position; all
/// are refined and scored by one objective, and the best is the answer
/// where it beats every other explanation by the stated margin and its
/// position is known within the harvester's tolerance. Returns what was
/// accepted, or why the fruit was not found.
pub(crate) fn estimate_fruit(
    results: &[FrameResult],
    context: &FrameContext,
    candidates: &[Candidate],
    views: &[&RgbImage],
) -> std::result::Result<Accepted, String> {
    use crate::estimate::{self, Decision, Evidence, Source};
    let scene_outline =
        if context.options.use_outline { find_scene_outline(context, views).ok() } else { None };
    let rays = scene_outline.as_ref().map(|o| outline_rays(context.camera, o)).unwrap_or_default();
    let evidence = Evidence::new(results, context, rays);
    let (prior, options) = (context.prior, context.options);
    let radius_range_mm = context.radius_range_mm();
    let mut starts = estimate::point_starts(&evidence, radius_range_mm, options.seed);
    for c in candidates {
        starts.extend(estimate::arc_starts(
            c.frame,
            &c.position_mm,
            &evidence,
            prior.fruit_radius_mm,
        ));
    }
    let positions: Vec<Point3<f64>> = candidates.iter().map(|c| c.position_mm).collect();
    let mut outline = None;
    if let Ok(fit) = fuse(results, context) {
        starts.push((fit.sphere, Source::FreeFit));
    }
    if let Ok(fit) = fit_prior_radius(results, context, &positions) {
        starts.push((fit.sphere, Source::PriorRadiusFit));
    }
    if let Some(found) = scene_outline.clone()
        && let Ok(fit) = fit_with_this_outline(results, context, views, found)
    {
        starts.push((fit.sphere, Source::Outline));
        outline = fit.outline;
    }
    starts.push((
        Sphere { centre: prior.rough_position_mm, radius_mm: prior.fruit_radius_mm },
        Source::Rough,
    ));
    // Prune what cannot be the target: a radius out of the options' range
    // or a centre beyond the rough position's error (a neighbour's).
    let can_be_target = |h: &estimate::Hypothesis| {
        (radius_range_mm.0..=radius_range_mm.1).contains(&h.sphere.radius_mm)
            && context.search.centre_rejection(&h.sphere.centre).is_none()
            && h.sphere.centre.z > 0.0
    };
    let all = estimate::rank(&starts, &evidence);
    let ranked: Vec<_> = all.iter().copied().filter(can_be_target).collect();
    if ranked.iter().all(|h| h.score.explained == 0) {
        return Err(no_candidate_reason(results));
    }
    // Neighbour fruit explain their own points: ranked again without the
    // points they explain better than the best target does.
    let neighbours = ranked.first().map(|b| estimate::neighbours(&b.sphere, &all));
    let (evidence, ranked) = match neighbours.filter(|n| !n.is_empty()) {
        Some(neighbours) => {
            let reduced = evidence.without_neighbours(&ranked[0].sphere, &neighbours);
            let again: Vec<_> =
                estimate::rank(&starts, &reduced).into_iter().filter(can_be_target).collect();
            (reduced, again)
        }
        None => (evidence, ranked),
    };
    let (best, margin) = match estimate::accept(&ranked, prior) {
        Decision::Accept { best, margin } => (best, margin),
        Decision::Refuse(reason) => return Err(reason),
    };
    let rms = best.score.rms_mm;
    let mut fit = FusedFit {
        sphere: best.sphere,
        ellipsoid: None,
        n_points: best.score.explained,
        n_frames: best.score.frames,
        rms_mm: rms,
        // One cut fixes a circle: the radius then rests on the prior.
        radius_from_prior: best.score.frames < 2,
        outline: if best.source == Source::Outline { outline } else { None },
        outline_refined: false,
    };
    // The accepted sphere refined to the fruit's ellipsoid by its outline
    // (two cuts or more: one fixes only a circle).
    if best.score.frames >= 2 {
        fit = refine_to_ellipsoid(fit, &evidence, context, views);
    }
    let covariance = crate::uncertainty::position_covariance(&fit, results, options);
    if let Some(cov) = &covariance {
        let worst = cov.symmetric_eigenvalues().max().max(0.0).sqrt();
        if worst > estimate::MAX_POSITION_STD_MM {
            return Err(format!(
                "the best sphere ({}) is uncertain by {worst:.1} mm along its worst direction, more than {:.1} mm",
                best.source.describe(),
                estimate::MAX_POSITION_STD_MM
            ));
        }
    }
    let note = format!(
        "{} over {} points from {} frames, RMS {:.2} mm, from {}; it beats the next explanation by {margin:.0} rows ({} of {} predicted rows missing)",
        if fit.ellipsoid.is_some() { "ellipsoid" } else { "sphere" },
        fit.n_points,
        fit.n_frames,
        fit.rms_mm,
        best.source.describe(),
        best.score.missing,
        best.score.predicted
    );
    Ok(Accepted { fit, note, covariance })
}

/// The fused method's answer from the accepted fit in `answer.fused`: its
/// centre (the ellipsoid's, where the outline refined the sphere to one),
/// how it was found (`note`) and its `covariance`.
pub(crate) fn answer_fused(
    answer: &mut Localization,
    note: String,
    covariance: Option<Matrix3<f64>>,
) {
    let Some(fit) = &answer.fused else { return };
    let (centre, radius) = match &fit.ellipsoid {
        Some(e) => (e.centre, e.equal_volume_radius_mm()),
        None => (fit.sphere.centre, fit.sphere.radius_mm),
    };
    answer.status = Status::Ok;
    answer.position_mm = Some(centre);
    answer.radius_mm = Some(radius);
    answer.reason = note;
    answer.position_cov_mm2 = covariance;
}

/// The fruit's outline around the accepted `sphere`'s image, in the colours
/// learned from the pixels its laser points (`points`, those on the
/// sphere) lie on against the surround's ([`LearnedColours`]), with those
/// colours; `None` where too few points lie on the sphere to learn them or
/// no outline is found.
fn outline_around(
    sphere: &Sphere,
    points: &[Point3<f64>],
    context: &FrameContext,
    views: &[&RgbImage],
) -> Option<(Outline, FruitColours)> {
    let camera = context.camera;
    let centre_px = camera.project(&sphere.centre).ok()?;
    let f_px = 0.5 * (camera.fx_px + camera.fy_px);
    let radius_px = f_px * sphere.radius_mm / sphere.centre.z;
    let area = PixelBox::around(&centre_px, 1.5 * radius_px + 5.0, camera);
    let on_fruit: Vec<Point2<f64>> = points.iter().filter_map(|p| camera.project(p).ok()).collect();
    let surround = area.pixels().filter(|&(u, v)| {
        (Point2::new(f64::from(u), f64::from(v)) - centre_px).norm() > SURROUND_FROM * radius_px
    });
    let colours = FruitColours::Learned(LearnedColours::learn(views, &on_fruit, surround)?);
    let outline = find_outline(
        views,
        area,
        &colours,
        (OUTLINE_RADIUS_RANGE.0 * radius_px, OUTLINE_RADIUS_RANGE.1 * radius_px),
        |c| (c - centre_px).norm() <= radius_px / 3.0,
        context.options.seed,
    )
    .ok()?;
    Some((outline, colours))
}

/// The accepted sphere refined to the fruit's ellipsoid (its MAP estimate
/// under the roundness prior, [`fit_ellipsoid_with_rays`]): the laser
/// points the sphere explains and, where the fruit's outline is found
/// around it, the outline's rays that touch the sphere within the fruit's
/// departure from round. The silhouette shows the semi-axes across the
/// line of sight and the front's curvature (a^2 / c) then the one along
/// it, which a sphere fitted to the front takes wrong by the fruit's
/// elongation. The ellipsoid replaces the sphere where it is an apple's
/// shape and the same explanation (its centre within the estimator's
/// rival distance, [`MIN_KEPT_SHARE`] of the sphere's points kept);
/// without the outline's rays the sphere stands, as the front alone does
/// not fix the depth semi-axis. The outline is the one the sphere came
/// from, or the one found around it ([`outline_around`]).
fn refine_to_ellipsoid(
    fit: FusedFit,
    evidence: &crate::estimate::Evidence,
    context: &FrameContext,
    views: &[&RgbImage],
) -> FusedFit {
    use crate::estimate::{RIVAL_DISTANCE, SURFACE_BAND_MM, ray_distance_mm};
    let (camera, options, sphere) = (context.camera, context.options, fit.sphere);
    // A sphere that came from the outline keeps it as its source: the
    // ellipsoid then refines it, but the laser saw too little of the fruit
    // for the outline to be a refinement of what it saw.
    let from_outline = fit.outline.is_some();
    // The laser points on the sphere: what its colours are learned from and
    // what the ellipsoid is fitted to.
    let near: Vec<(usize, Point3<f64>)> = evidence
        .points
        .iter()
        .copied()
        .filter(|(_, p)| sphere.distance_mm(p) < SURFACE_BAND_MM)
        .collect();
    let points: Vec<Point3<f64>> = near.iter().map(|(_, p)| *p).collect();
    let found = match fit.outline.clone() {
        Some(outline) => Some((outline, FruitColours::Apple)),
        None if options.use_outline => outline_around(&sphere, &points, context, views),
        None => None,
    };
    let Some((outline, colours)) = found else { return fit };
    // The fruit's departure from round: two standard deviations of a
    // semi-axis, beyond the surface band.
    let band = SURFACE_BAND_MM + 2.0 * options.shape_std * sphere.radius_mm;
    let band_px = band * 0.5 * (camera.fx_px + camera.fy_px) / sphere.centre.z.max(1.0);
    let directions: Vec<Vector3<f64>> =
        rays_through(camera, &silhouette_edges(views, &outline, &colours, band_px))
            .into_iter()
            .filter(|ray| (ray_distance_mm(&sphere.centre, ray) - sphere.radius_mm).abs() < band)
            .collect();
    if directions.len() < MIN_OUTLINE_RAYS {
        return fit;
    }
    let rays = Rays { directions, weight: OUTLINE_WEIGHT };
    let noise = fit.rms_mm.max(MIN_NOISE_MM);
    let start = Ellipsoid::from_sphere(&sphere);
    let Some(ellipsoid) =
        fit_ellipsoid_with_rays(&points, &rays, &start, noise, ELLIPSOID_PRIOR_POINTS)
    else {
        return fit;
    };
    // The same explanation: near the sphere, and on the laser points the
    // sphere was accepted for.
    let kept = points.iter().filter(|p| ellipsoid.distance_mm(p) < SURFACE_BAND_MM).count();
    let same = (ellipsoid.centre - sphere.centre).norm()
        <= RIVAL_DISTANCE * context.prior.fruit_radius_mm
        && kept as f64 >= MIN_KEPT_SHARE * points.len() as f64;
    if !(same && is_apple_shaped(&ellipsoid)) {
        return fit;
    }
    // The points on the ellipsoid: their frames and distances.
    let (frame_of, distances): (Vec<usize>, Vec<f64>) = near
        .iter()
        .map(|(k, p)| (*k, ellipsoid.distance_mm(p)))
        .filter(|(_, d)| *d < options.inlier_threshold_mm)
        .unzip();
    FusedFit {
        ellipsoid: Some(ellipsoid),
        n_points: distances.len(),
        n_frames: count_frames(&frame_of, 0..frame_of.len()),
        rms_mm: rms_mm(distances.into_iter()),
        outline: Some(outline),
        outline_refined: !from_outline,
        ..fit
    }
}

/// Fewest silhouette rays that refine the sphere to an ellipsoid: the
/// edges of a few pixels of outline (a small fruit at 1.6 m and half scale
/// is about 20 px round, 160 edges), too few to show its shape below this.
const MIN_OUTLINE_RAYS: usize = 12;

/// The surround a fruit's colours are learned against
/// ([`LearnedColours`]) begins this many of the sphere's image radii from
/// its centre: beyond the largest outline searched for
/// ([`OUTLINE_RADIUS_RANGE`]), so no pixel of this fruit counts as its
/// surround.
const SURROUND_FROM: f64 = OUTLINE_RADIUS_RANGE.1;

/// Share of the sphere's laser points the ellipsoid must keep on its
/// surface: the refinement moves the surface by the fruit's departure from
/// round (a millimetre or two), which keeps nearly all of them; an
/// ellipsoid that pulled off a tenth followed a leaf's or a neighbour's
/// edge in the silhouette, not the fruit.
const MIN_KEPT_SHARE: f64 = 0.9;

/// The free fit: one robust sphere over every frame's fruit points. Its
/// checks decide whether it proposes a sphere to [`estimate_fruit`].
fn fuse(results: &[FrameResult], context: &FrameContext) -> std::result::Result<FusedFit, String> {
    let (search, prior, options) = (context.search, context.prior, context.options);
    let (mut points, mut frame_of) = fruit_points(results);
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
    let no_sphere = || "no sphere through the fruit points of the frames".to_string();
    let mut outcome = ransac_refit(&estimator, &ransac_options, 3).ok_or_else(no_sphere)?;
    // A frame whose arc the sphere crosses saw another surface (a
    // neighbour, a leaf) that meets the fruit's sphere by chance; its points
    // on the sphere pull it away from the fruit (in a cluster, to a larger
    // sphere off the fruit's centre). The sphere is fitted again without
    // those frames.
    let crossing = crossing_arcs(&points, &frame_of, results.len(), &outcome.model, threshold);
    if outcome.inliers.iter().any(|&i| crossing[frame_of[i]]) {
        let kept: Vec<usize> = (0..points.len()).filter(|&i| !crossing[frame_of[i]]).collect();
        points = kept.iter().map(|&i| points[i]).collect();
        frame_of = kept.iter().map(|&i| frame_of[i]).collect();
        let estimator = SphereEstimator { points: &points, radius_range_mm };
        outcome = ransac_refit(&estimator, &ransac_options, 3).ok_or_else(no_sphere)?;
    }
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
    let rows_per_frame: Vec<f64> = results
        .iter()
        .map(|r| {
            PlaneFrame::new(context.laser, r.slide_mm).map_or(0.0, |plane| {
                let d = plane.signed_distance_mm(&sphere.centre);
                let rho = (sphere.radius_mm.powi(2) - d * d).max(0.0).sqrt();
                2.0 * rho * context.camera.fy_px / sphere.centre.z
            })
        })
        .collect();
    let expected_rows: f64 = rows_per_frame.iter().sum();
    let coverage = inliers.len() as f64 / expected_rows.max(1.0);
    if coverage < options.min_coverage {
        return Err(format!(
            "the fitted fruit shows {:.0} % of the stripe rows it should ({} of {:.0}): too little to trust",
            100.0 * coverage,
            inliers.len(),
            expected_rows
        ));
    }
    // Two cuts, each a cut of this fruit: one frame's arc and a few points
    // of another surface (a neighbour's arc) in a second frame also lie on
    // a sphere, so the second-best frame must show its share of rows too.
    let held = points_per_frame(&frame_of, &inliers, results.len());
    let mut frame_coverage: Vec<f64> =
        held.iter().zip(&rows_per_frame).map(|(&n, rows)| n as f64 / rows.max(1.0)).collect();
    frame_coverage.sort_by(|a, b| b.total_cmp(a));
    let second = frame_coverage.get(1).copied().unwrap_or(0.0);
    if second < options.min_coverage {
        return Err(format!(
            "the fitted fruit shows {:.0} % of the stripe rows it should in its second-best frame, less than {:.0} %: a sphere needs two cuts",
            100.0 * second,
            100.0 * options.min_coverage
        ));
    }
    check_sphere_fit(&sphere, &on_sphere, rms, search, options)?;
    check_not_flat(&on_sphere, rms, CURVATURE_SIGNIFICANCE)?;
    Ok(FusedFit {
        sphere,
        ellipsoid: None,
        n_points: inliers.len(),
        n_frames,
        rms_mm: rms,
        radius_from_prior: false,
        outline: None,
        outline_refined: false,
    })
}

/// Largest ratio of an ellipsoid's longest semi-axis to its shortest. Apples
/// are round to a few per cent (a tall variety's height is at most about 1.2
/// times its width); an ellipsoid beyond this has followed a neighbour, a
/// leaf's edge or an outline that is not the fruit's, and the sphere stands.
const MAX_SEMI_AXIS_RATIO: f64 = 1.25;

/// Whether an ellipsoid may be an apple ([`MAX_SEMI_AXIS_RATIO`]).
fn is_apple_shaped(ellipsoid: &Ellipsoid) -> bool {
    let axes = ellipsoid.semi_axes_mm();
    axes.max() <= MAX_SEMI_AXIS_RATIO * axes.min()
}

/// Weight of the ellipsoid's roundness prior, in points: the front of a
/// fruit does not fix its depth semi-axis, so the prior decides it; against
/// a fit's hundred or more laser points, a few tens leave the rest to them.
const ELLIPSOID_PRIOR_POINTS: f64 = 20.0;

/// Every frame's fruit points, with the frame each came from.
pub(crate) fn fruit_points(results: &[FrameResult]) -> (Vec<Point3<f64>>, Vec<usize>) {
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

/// A sphere of the prior radius through the frames' fruit points
/// (Gauss-Newton on the centre from each frame's candidate and the rough
/// position, each first with all the points and then with those the start's
/// sphere holds, keeping the fit with most points within the inlier
/// threshold). It proposes a sphere where it passes the free fit's checks
/// except the coverage, which a fruit mostly hidden cannot meet.
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
    // The points a sphere holds: within the inlier threshold.
    let held_by = |sphere: &Sphere| -> Vec<usize> {
        (0..points.len()).filter(|&i| sphere.distance_mm(&points[i]) <= threshold).collect()
    };
    // Gauss-Newton on the centre from `sphere` through `inliers`, then
    // through the points it holds, four times.
    let refine = |mut sphere: Sphere, mut inliers: Vec<usize>| {
        for _ in 0..4 {
            let chosen: Vec<Point3<f64>> = inliers.iter().map(|&i| points[i]).collect();
            let Some(centre) = fit_centre_for_radius(&chosen, &sphere.centre, radius) else {
                break;
            };
            sphere.centre = centre;
            inliers = held_by(&sphere);
            if inliers.len() < 4 {
                break;
            }
        }
        (sphere, inliers)
    };
    let mut best: Option<(Sphere, Vec<usize>, f64)> = None;
    for start in starts.iter().chain(std::iter::once(&search.centre)) {
        let start = Sphere { centre: *start, radius_mm: radius };
        // From all the points, and from those the start's sphere holds: a
        // frame's candidate near the fruit, pulled off by another frame's
        // arc on something else in the first step, would not come back.
        let all: Vec<usize> = (0..points.len()).collect();
        let held = held_by(&start);
        let first_sets = if held.len() >= 4 { vec![all, held] } else { vec![all] };
        for first in first_sets {
            let (sphere, inliers) = refine(start, first);
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
    }
    let Some((sphere, inliers, rms)) = best else {
        return Err("no sphere of the prior radius fits the fruit points".into());
    };
    if inliers.len() < min_points {
        return Err(format!("{} points on the sphere, fewer than {min_points}", inliers.len()));
    }
    // Without the coverage check, a sphere of the prior radius can pass
    // through parts of two surfaces (a fruit's edge and a branch in front
    // of it): it must explain most of the points the frames kept as fruit.
    let explained = inliers.len() as f64 / points.len() as f64;
    if explained < MIN_PRIOR_FIT_SHARE {
        return Err(format!(
            "the sphere holds {} of the {} fruit points ({:.0} %): they are not one fruit's",
            inliers.len(),
            points.len(),
            100.0 * explained
        ));
    }
    check_two_cuts(&frame_of, &inliers, results.len(), context.min_points())?;
    let on_sphere: Vec<Point3<f64>> = inliers.iter().map(|&i| points[i]).collect();
    check_sphere_fit(&sphere, &on_sphere, rms, search, options)?;
    check_not_flat(&on_sphere, rms, CURVATURE_SIGNIFICANCE)?;
    Ok(FusedFit {
        sphere,
        ellipsoid: None,
        n_points: inliers.len(),
        n_frames: count_frames(&frame_of, inliers.iter().copied()),
        rms_mm: rms,
        radius_from_prior: true,
        outline: None,
        outline_refined: false,
    })
}

/// A sphere of the prior radius needs two cuts of its fruit: at least
/// `min_points` of its `inliers` (indices into the points `frame_of`
/// describes) in each of two of the `n_frames` frames, as many as a frame
/// needs for a candidate of its own. One frame's arc is a circle in the
/// laser's plane, and two spheres of any radius hold it, mirrored across
/// that plane; a few points of another frame (a neighbour's arc, in a
/// cluster) cannot choose between them. Decides whether the fit proposes
/// a sphere.
fn check_two_cuts(
    frame_of: &[usize],
    inliers: &[usize],
    n_frames: usize,
    min_points: usize,
) -> std::result::Result<(), String> {
    let mut held = points_per_frame(frame_of, inliers, n_frames);
    held.sort_unstable_by(|a, b| b.cmp(a));
    let (first, second) = (held.first().copied().unwrap_or(0), held.get(1).copied().unwrap_or(0));
    if second < min_points {
        return Err(format!(
            "the sphere of the prior radius rests on one frame's arc ({first} points; the next frame holds {second}, fewer than {min_points}): its mirror across the laser's plane holds that arc as well"
        ));
    }
    Ok(())
}

/// Smallest share of the fruit points a sphere of the prior radius must hold
/// to be proposed: one fruit's sphere holds most of them, a sphere through a
/// fruit's edge and a branch in front of it holds a part of each.
const MIN_PRIOR_FIT_SHARE: f64 = 0.5;

/// The fruit's outline in the image of the search ball: a circle of the
/// radius range the options accept, its centre where the ball's may lie.
pub(crate) fn find_scene_outline(
    context: &FrameContext,
    views: &[&RgbImage],
) -> std::result::Result<Outline, String> {
    let (camera, search, options) = (context.camera, context.search, context.options);
    // The search ball's image: a box, the outline's radius range, and where
    // its centre may lie.
    let centre = search.centre;
    let near_mm = (centre.z - search.radius_mm).max(0.5 * centre.z);
    let centre_px = camera.project(&centre).map_err(|e| e.to_string())?;
    let ball_px = camera.fx_px.max(camera.fy_px) * search.radius_mm / near_mm;
    let area = PixelBox::around(&centre_px, ball_px, camera);
    let (lo_mm, hi_mm) = context.radius_range_mm();
    let f_px = 0.5 * (camera.fx_px + camera.fy_px);
    let radius_range_px = (f_px * lo_mm / (centre.z + search.radius_mm), f_px * hi_mm / near_mm);
    find_outline(
        views,
        area,
        &FruitColours::Apple,
        radius_range_px,
        |c| (c - centre_px).norm() <= ball_px,
        options.seed,
    )
}

/// A hypothesis from the fruit's outline ([`crate::outline`]) in the
/// frames, and a sphere fitted to it and to the laser points near the
/// fruit on fruit-coloured pixels, from every frame (not only the arcs the
/// frames kept). Enough of them must lie on the sphere besides the
/// frames' arcs that cross it ([`MIN_ARC_SHARE`]), in two frames or more,
/// the laser must confirm a curved surface, in one frame or across them,
/// and the sphere must pass the same checks as the others. These checks
/// decide whether the outline proposes a sphere.
fn fit_with_this_outline(
    results: &[FrameResult],
    context: &FrameContext,
    views: &[&RgbImage],
    outline: Outline,
) -> std::result::Result<FusedFit, String> {
    let (camera, search, options) = (context.camera, context.search, context.options);
    let (lo_mm, hi_mm) = context.radius_range_mm();
    // The laser points on the fruit: where the view is fruit-coloured (the
    // laser points on a leaf in front may lie on one sphere of the
    // outline's family and fix a wrong depth).
    let mut points = Vec::new();
    let mut frame_of = Vec::new();
    let mut on_arc = Vec::new();
    for (k, result) in results.iter().enumerate() {
        for (i, p) in &result.points_in_camera {
            let pixel = result.stripe.get(*i).map(|s| Point2::new(s.u_px, s.v_px));
            if pixel.is_some_and(|px| is_fruit_coloured_at(views, &px)) {
                points.push(*p);
                frame_of.push(k);
                on_arc.push(result.fruit.contains(i));
            }
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
    let (arcs, arc_frame_of) = fruit_points(results);
    let crossing = crossing_arcs(&arcs, &arc_frame_of, results.len(), &fit.sphere, threshold);
    let support = fit.inliers.iter().filter(|&&i| !(on_arc[i] && crossing[frame_of[i]])).count();
    if support < min_points {
        return Err(format!(
            "{support} laser points on the sphere of the fruit's outline besides the frames' arcs that cross it ({} in all), fewer than {min_points}",
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
    // their scatter about their own circle (the test of a frame's arc), or
    // the points of two or more frames together bend away from a plane
    // beyond their scatter about the sphere (`OUTLINE_CURVATURE_SIGNIFICANCE`
    // times it): a fruit whose lower part lies in a leaf's laser shadow
    // shows arcs of 20-40 rows per frame, each too short to bend beyond its
    // own noise, that together leave no doubt.
    let on_sphere: Vec<Point3<f64>> = fit.inliers.iter().map(|&i| points[i]).collect();
    let n_frames = count_frames(&frame_of, fit.inliers.iter().copied());
    // Two cuts, as for every other sphere: one frame's points fix a depth
    // for any outline they fall inside, a neighbour's too (the outline of a
    // neighbour behind the target takes its depth from the target's arc).
    if n_frames < 2 {
        return Err(format!(
            "the {} laser points on the outline's sphere lie in one frame: one cut does not tell the fruit's outline from a neighbour's",
            fit.inliers.len()
        ));
    }
    let bends_across_frames =
        check_not_flat(&on_sphere, fit.rms_mm, OUTLINE_CURVATURE_SIGNIFICANCE).is_ok();
    let curved = bends_across_frames
        || results.iter().enumerate().any(|(k, result)| {
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
        return Err("the laser points on the outline's sphere are nearly straight in every frame and nearly flat across them: not a fruit".into());
    }
    check_sphere_fit(&fit.sphere, &on_sphere, fit.rms_mm, search, options)?;
    Ok(FusedFit {
        sphere: fit.sphere,
        ellipsoid: None,
        n_points: fit.inliers.len(),
        n_frames,
        rms_mm: fit.rms_mm,
        radius_from_prior: false,
        outline: Some(outline),
        outline_refined: false,
    })
}

/// The radii, as factors of the accepted sphere's image radius, among which
/// the outline that refines it is searched: a sphere fitted to a fruit's
/// front takes its curvature radius a^2 / c (semi-axes a across the line of
/// sight, c along it), so for semi-axes within 8 % of their mean the
/// silhouette is 0.85-1.17 of the sphere, further with the stripe's noise.
const OUTLINE_RADIUS_RANGE: (f64, f64) = (0.7, 1.3);

/// Largest RMS distance of the outline's rays from the fitted sphere, mm: a
/// pixel is about 0.5 mm at 1.2 m, and a fruit 8 % from round departs a few
/// millimetres from any sphere.
const MAX_OUTLINE_RMS_MM: f64 = 3.0;

/// How far the laser points on the outline's sphere, across frames, must
/// bend away from a plane, in multiples of their scatter about the sphere,
/// for the outline to propose it (or one frame's arc must bend). The
/// free fit asks `CURVATURE_SIGNIFICANCE` (4) because its sphere is fitted
/// to those points alone and follows part of their noise; the outline's
/// sphere takes its size and its place across the line of sight from the
/// outline, so the laser points only fix its depth and cannot bend it
/// towards themselves, and a flat surface's points, which would lie on
/// any plane within their noise, give a ratio near 1; twice their scatter
/// lies clear of that.
const OUTLINE_CURVATURE_SIGNIFICANCE: f64 = 2.0;

/// The check a fit's sphere must pass after [`check_sphere_fit`] to be
/// proposed, free, of the prior radius or (across frames) the outline's: a
/// surface curved beyond its noise,
/// its points `significance` times `rms` (their scatter about the sphere)
/// from a plane.
fn check_not_flat(
    on_sphere: &[Point3<f64>],
    rms: f64,
    significance: f64,
) -> std::result::Result<(), String> {
    let flatness = plane_rms_mm(on_sphere);
    if flatness < significance * rms.max(MIN_NOISE_MM) {
        return Err(format!(
            "the points are nearly flat ({flatness:.2} mm RMS from a plane): not a fruit"
        ));
    }
    Ok(())
}

/// Share of a frame's arc (its points on one circle) a sphere must hold
/// for the arc to count as a cut of it ([`crossing_arcs`]): the free fit
/// is fitted again without frames whose arcs it crosses, and the outline's
/// fit counts no support from them. A cut of the sphere's own fruit lies on
/// it nearly whole; a surface that meets it by chance, over a short stretch.
const MIN_ARC_SHARE: f64 = 0.5;

/// For each of `n_frames` frames, whether its arc (its points on one
/// circle: one surface; `points` and `frame_of` as [`fruit_points`] gives
/// them) crosses `sphere`: the sphere holds less than [`MIN_ARC_SHARE`] of
/// it within `threshold_mm`, so where the two meet is chance, not support.
fn crossing_arcs(
    points: &[Point3<f64>],
    frame_of: &[usize],
    n_frames: usize,
    sphere: &Sphere,
    threshold_mm: f64,
) -> Vec<bool> {
    let mut held = vec![0usize; n_frames];
    let mut total = vec![0usize; n_frames];
    for (p, &k) in points.iter().zip(frame_of) {
        if let (Some(h), Some(t)) = (held.get_mut(k), total.get_mut(k)) {
            *t += 1;
            *h += usize::from(sphere.distance_mm(p) <= threshold_mm);
        }
    }
    held.iter().zip(&total).map(|(&h, &t)| (h as f64) < MIN_ARC_SHARE * t as f64).collect()
}

/// The checks of any fitted sphere: the points' scatter about it, its
/// centre within the search ball, and the points facing the camera from it.
/// They decide whether a fit proposes its sphere, and whether an outline's
/// refinement replaces the accepted one.
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
    if let Some(reason) = search.centre_rejection(&sphere.centre) {
        return Err(reason);
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

/// How many of the points `indices` (into the points `frame_of` describes)
/// each of `n_frames` frames holds.
fn points_per_frame(frame_of: &[usize], indices: &[usize], n_frames: usize) -> Vec<usize> {
    let mut held = vec![0usize; n_frames];
    for &i in indices {
        if let Some(h) = frame_of.get(i).and_then(|&k| held.get_mut(k)) {
            *h += 1;
        }
    }
    held
}

fn count_frames(frame_of: &[usize], indices: impl Iterator<Item = usize>) -> usize {
    let mut frames: Vec<usize> = indices.map(|i| frame_of[i]).collect();
    frames.sort_unstable();
    frames.dedup();
    frames.len()
}
