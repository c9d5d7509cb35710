//! One estimator for the fruit: generate hypotheses, score each with one
//! objective, accept the best only where it beats every other explanation
//! by a stated margin.
//!
//! **Generate.** Spheres that might be the fruit, from every source of
//! evidence: robust spheres through the laser points of all frames (each
//! one taken out in turn, so a neighbour's sphere does not hide the
//! target's); each frame's arc at the prior radius on both sides of its
//! laser plane (one arc fixes a circle; the sphere through it lies on
//! either side); the free fit, the sphere of the prior radius and the
//! outline's sphere ([`crate::fusion`]'s fits); the rough position itself.
//! Each is refined by the objective's own robust least squares.
//!
//! **Score** ([`score`], lower is better, in rows of stripe): every laser
//! point the sphere explains (within [`SURFACE_BAND_MM`]) earns up to one;
//! a point the fruit would have hidden costs one: a point inside it, or
//! one the camera sees through it or the laser lit through it (a sphere
//! occupies space, and a ray that reached a point crossed none); every
//! stripe row the sphere predicts (the part of its cut that faces both the
//! camera and the laser) where the image shows no line on it and nothing in
//! front costs [`MISSING_ROW_COST`]; the radius prior and the rough
//! position's prior (the RGB-D camera's error) add their negative log
//! likelihoods.
//!
//! **Accept** ([`accept`]): the best sphere must lie on the laser's cut in
//! one frame at least, and beat the best explanation
//! more than [`RIVAL_DISTANCE`] away, and the empty scene (score 0), by
//! [`ACCEPT_MARGIN`] rows, and its position's standard deviation must lie
//! within [`MAX_POSITION_STD_MM`]. Otherwise the fruit is not found, and
//! the reason names the rival and the scores.
//!
//! **Refine.** Where two frames or more show it, the accepted sphere then
//! becomes the fruit's ellipsoid by the laser points it explains and its
//! whole silhouette, under the roundness prior ([`crate::fusion`]'s
//! `refine_to_ellipsoid`): a sphere fitted to the front of a fruit a few
//! per cent from round misplaces its centre by the elongation.
//!
//! Per-frame steps (the frame's circle, the unlit points) only prune and
//! propose; no single frame decides.

use std::collections::BTreeMap;

use alacs_model::Camera;
use nalgebra::{Matrix4, Point3, Vector3, Vector4};

use crate::fit::Sphere;
use crate::frame::{FrameContext, PlaneFrame};
use crate::outline::OUTLINE_WEIGHT;
use crate::{FrameResult, Prior};

/// Half-width of the band around a sphere in which a laser point counts as
/// on it, mm: the stripe's triangulation noise at 1.6 m and half scale is
/// about 0.5 mm, and light scattered inside an apple moves the stripe's
/// centre by up to about 1 mm (apple flesh: reduced scattering about 1/mm,
/// ../shared/REFERENCES.md); a real apple departs from its sphere by a few
/// per cent of its radius.
pub(crate) const SURFACE_BAND_MM: f64 = 2.5;

/// How far inside a sphere a laser point, or the camera's or the laser's
/// ray to it, must pass to contradict it, mm: beyond the surface band, so
/// the stripe's scatter, the fruit's departure from a sphere and rays that
/// graze its limb never count against the right one.
const INSIDE_MM: f64 = 4.0;

/// Cost of a stripe row the sphere predicts where the image shows no line
/// on it and nothing in front, against one for a point it explains. A
/// twentieth: leaves beside the fruit shadow the laser (it comes from the
/// side, 30-40 cm away), a dark or specular patch of skin and a grazing
/// cut lose the line too, so even an unoccluded fruit shows only half to
/// three quarters of its predicted rows; absence is weak evidence, which
/// still tells a sphere that crosses empty space from one that does not.
///
/// A frame's missing rows count in proportion to the rows of its search
/// where it shows the line at all, on anything: a frame whose line the
/// leaves' shadow or a dark scene hides everywhere says nothing about
/// where the fruit is not.
const MISSING_ROW_COST: f64 = 0.05;

/// A predicted point counts only where the surface faces both the camera
/// and the laser by at least this cosine: at grazing angles the stripe
/// thins out on a real fruit and its absence says nothing.
const MIN_FACING_COS: f64 = 0.25;

/// Relative standard deviation of the radius prior: a detector's circle in
/// the RGB-D image and its depth give the radius to about 10 %, and apples
/// of one block vary by about as much (diameters 60-90 mm at harvest,
/// ../shared/REFERENCES.md).
pub(crate) const RADIUS_PRIOR_STD: f64 = 0.12;

/// The rough position's standard deviations are these fractions of the
/// largest errors the options state (`rough_depth_error`,
/// `rough_lateral_error_mm`): the options give bounds, about 2 sigma.
const ROUGH_STD_OF_BOUND: f64 = 0.5;

/// Two hypotheses are rival explanations when their centres lie farther
/// apart than this fraction of the radius prior (10 mm for a 40 mm fruit):
/// closer ones are the same fruit, fitted a little differently; a wrong
/// answer lies farther (a neighbour a diameter away, a mirror sphere
/// across a laser plane, a sphere through a leaf).
pub(crate) const RIVAL_DISTANCE: f64 = 0.25;

/// How much better, in rows of stripe, the best explanation must score
/// than its best rival and than the empty scene: a fixed part, ten rows
/// (the length of a leaf's edge at 1 m and half scale) ...
const ACCEPT_MARGIN: f64 = 10.0;

/// ... plus this fraction of the points the best sphere explains, so that
/// a rival must lose a tenth of the fruit's evidence at any resolution.
const ACCEPT_MARGIN_FRACTION: f64 = 0.1;

/// Largest standard deviation of the answer's position along its worst
/// direction, mm: two of them stay within the 15 mm by which a harvester's
/// gripper, closing around an apple of 70-90 mm, may miss its centre.
pub(crate) const MAX_POSITION_STD_MM: f64 = 7.5;

/// Robust sphere fits drawn from all frames' points, one after another
/// with the previous one's points taken out.
const SEQUENTIAL_SPHERES: usize = 3;

/// Gauss-Newton steps of a hypothesis's refinement.
const REFINE_STEPS: usize = 12;

/// One frame's evidence: its laser plane, the laser's origin, and the
/// laser points by image row.
#[derive(Clone)]
pub(crate) struct FrameEvidence {
    plane: PlaneFrame,
    laser_origin: Point3<f64>,
    /// The frame's points (camera frame, mm) in each image row.
    rows: BTreeMap<i64, Vec<Point3<f64>>>,
    /// Rows the frame's stripe search covered.
    searched: (i64, i64),
    /// The share of those rows where the frame shows the line at all, on
    /// anything: how far its absence from a row is evidence.
    shown: f64,
}

/// Everything the score looks at.
#[derive(Clone)]
pub(crate) struct Evidence<'a> {
    pub(crate) frames: Vec<FrameEvidence>,
    /// Every laser point with its frame.
    pub(crate) points: Vec<(usize, Point3<f64>)>,
    camera: &'a Camera,
    prior: &'a Prior,
    /// The rough position's inverse covariance (mm^-2).
    rough_information: nalgebra::Matrix3<f64>,
    /// Unit rays from the camera through the fruit's outline in the image,
    /// where it was found: a sphere that is the fruit touches them.
    outline_rays: Vec<Vector3<f64>>,
}

impl<'a> Evidence<'a> {
    /// The evidence of every frame's laser points (those inside the search
    /// ball the laser lit).
    pub(crate) fn new(
        results: &[FrameResult],
        context: &FrameContext<'a>,
        outline_rays: Vec<Vector3<f64>>,
    ) -> Self {
        let mut frames = Vec::new();
        let mut points = Vec::new();
        for (k, result) in results.iter().enumerate() {
            let Some(plane) = PlaneFrame::new(context.laser, result.slide_mm) else { continue };
            let mut rows: BTreeMap<i64, Vec<Point3<f64>>> = BTreeMap::new();
            for (index, point) in &result.points_in_camera {
                if let Some(s) = result.stripe.get(*index) {
                    rows.entry(s.v_px.round() as i64).or_default().push(*point);
                }
                points.push((k, *point));
            }
            let searched =
                result.region_outline_px.iter().fold((i64::MAX, i64::MIN), |(lo, hi), p| {
                    (lo.min(p.y.floor() as i64), hi.max(p.y.ceil() as i64))
                });
            let searched =
                (searched.0.max(0), searched.1.min(i64::from(context.camera.height_px) - 1));
            let shown_rows: std::collections::BTreeSet<i64> =
                result.stripe.iter().map(|s| s.v_px.round() as i64).collect();
            let span = (searched.1 - searched.0 + 1).max(1);
            let shown = shown_rows.range(searched.0..=searched.1).count() as f64 / span as f64;
            frames.push(FrameEvidence {
                plane,
                laser_origin: context.laser.origin_in_camera(result.slide_mm),
                rows,
                searched,
                shown,
            });
        }
        let rough = context.prior.rough_position_mm;
        let depth = rough.coords.norm();
        let sight = rough.coords / depth.max(1e-9);
        let along = ROUGH_STD_OF_BOUND * context.options.rough_depth_error * depth;
        let across = ROUGH_STD_OF_BOUND * context.options.rough_lateral_error_mm;
        let (along, across) = (along.max(1.0), across.max(1.0));
        let projector = sight * sight.transpose();
        let rough_information = projector / (along * along)
            + (nalgebra::Matrix3::identity() - projector) / (across * across);
        Evidence {
            frames,
            points,
            camera: context.camera,
            prior: context.prior,
            rough_information,
            outline_rays,
        }
    }

    /// This evidence without the laser points that `neighbours` (other
    /// fruit: spheres apart from `target`, each explaining points of its
    /// own) explain better than `target` does: where apples touch, a
    /// neighbour's points near the contact lie within the band of the
    /// target's sphere and would lend it their surface. A point goes only
    /// where it lies within the band of a neighbour and nearer to it than
    /// to the target.
    pub(crate) fn without_neighbours(&self, target: &Sphere, neighbours: &[Sphere]) -> Self {
        let mut reduced = self.clone();
        reduced.points.retain(|(_, p)| {
            let own = target.distance_mm(p);
            !neighbours.iter().any(|n| {
                let d = n.distance_mm(p);
                d < SURFACE_BAND_MM && d < own
            })
        });
        reduced
    }
}

/// Two spheres are different fruit when their centres lie at least this
/// fraction of their radii's sum apart: touching apples sit at about the
/// sum (their skins give a little), while one fruit's rival fits (a mirror
/// across a laser plane, a larger or smaller sphere through the same
/// points) overlap it by far more.
pub(crate) const APART_FRACTION: f64 = 0.85;

/// The neighbour fruit among `ranked`: spheres apart from `target` (see
/// [`APART_FRACTION`]) that explain as many points as a frame must show
/// of a fruit ([`crate::frame::MIN_POINTS`]) and score better than the
/// empty scene.
pub(crate) fn neighbours(target: &Sphere, ranked: &[Hypothesis]) -> Vec<Sphere> {
    let mut found: Vec<Sphere> = Vec::new();
    for h in ranked {
        let s = h.sphere;
        let apart = |o: &Sphere| {
            (s.centre - o.centre).norm() >= APART_FRACTION * (s.radius_mm + o.radius_mm)
        };
        if h.score.total < 0.0
            && h.score.explained >= crate::frame::MIN_POINTS
            && apart(target)
            && found.iter().all(apart)
        {
            found.push(s);
        }
    }
    found
}

/// A hypothesis's score and what it is made of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Score {
    /// The objective: lower is better; the empty scene scores 0.
    pub(crate) total: f64,
    /// Laser points on the sphere.
    pub(crate) explained: usize,
    /// Frames with points on the sphere.
    pub(crate) frames: usize,
    /// Laser points it would hide: inside it, or seen or lit through it.
    pub(crate) hidden: usize,
    /// Predicted rows with no line on the sphere and nothing in front.
    pub(crate) missing: usize,
    /// Rows the sphere predicts in all frames.
    pub(crate) predicted: usize,
    /// RMS distance of the explained points from the sphere, mm.
    pub(crate) rms_mm: f64,
}

/// The objective of a sphere (see the module docs).
pub(crate) fn score(sphere: &Sphere, evidence: &Evidence) -> Score {
    let (mut reward, mut explained, mut hidden, mut sum_sq) = (0.0, 0, 0, 0.0);
    let origin = Point3::origin();
    let mut frames_with = vec![0usize; evidence.frames.len()];
    for (k, p) in &evidence.points {
        // Unsigned: a point deep inside the sphere is hidden because the
        // camera's ray to it crosses the sphere.
        let d = sphere.distance_mm(p);
        if d < SURFACE_BAND_MM {
            reward += 1.0 - (d / SURFACE_BAND_MM).powi(2);
            explained += 1;
            sum_sq += d * d;
            if let Some(n) = frames_with.get_mut(*k) {
                *n += 1;
            }
        } else if crosses(sphere, &origin, p)
            || evidence.frames.get(*k).is_some_and(|f| crosses(sphere, &f.laser_origin, p))
        {
            hidden += 1;
        }
    }
    for ray in &evidence.outline_rays {
        let e = ray_distance_mm(&sphere.centre, ray) - sphere.radius_mm;
        if e.abs() < SURFACE_BAND_MM {
            reward += OUTLINE_WEIGHT * (1.0 - (e / SURFACE_BAND_MM).powi(2));
        }
    }
    let (mut missing, mut predicted, mut absence) = (0, 0, 0.0);
    for frame in &evidence.frames {
        let (m, p) = missing_rows(sphere, frame, evidence.camera);
        missing += m;
        predicted += p;
        absence += frame.shown * m as f64;
    }
    let r0 = evidence.prior.fruit_radius_mm;
    let radius_cost = 0.5 * ((sphere.radius_mm - r0) / (RADIUS_PRIOR_STD * r0)).powi(2);
    let offset = sphere.centre - evidence.prior.rough_position_mm;
    let rough_cost = 0.5 * offset.dot(&(evidence.rough_information * offset));
    let total = -reward + hidden as f64 + MISSING_ROW_COST * absence + radius_cost + rough_cost;
    Score {
        total,
        explained,
        frames: frames_with.iter().filter(|&&n| n >= crate::frame::MIN_POINTS).count(),
        hidden,
        missing,
        predicted,
        rms_mm: if explained > 0 { (sum_sq / explained as f64).sqrt() } else { f64::NAN },
    }
}

/// The rows of `frame` where the sphere's cut, facing the camera and the
/// laser, should show the line but the image shows nothing on it and
/// nothing in front; and the rows it predicts.
fn missing_rows(sphere: &Sphere, frame: &FrameEvidence, camera: &Camera) -> (usize, usize) {
    let plane = &frame.plane;
    let d = plane.signed_distance_mm(&sphere.centre);
    let rho2 = sphere.radius_mm.powi(2) - d * d;
    if rho2 <= 0.0 {
        return (0, 0);
    }
    let rho = rho2.sqrt();
    let centre = sphere.centre - plane.normal.into_inner() * d;
    // About two samples a row: the cut spans 2 rho fy / z rows.
    let rows_spanned = 2.0 * rho * camera.fy_px / sphere.centre.z.max(1.0);
    let samples = ((2.0 * std::f64::consts::PI * rows_spanned).ceil() as usize).clamp(16, 20_000);
    let mut predicted: BTreeMap<i64, Point3<f64>> = BTreeMap::new();
    for s in 0..samples {
        let t = 2.0 * std::f64::consts::PI * s as f64 / samples as f64;
        let q = centre + (plane.e1 * t.cos() + plane.e2 * t.sin()) * rho;
        let normal = (q - sphere.centre) / sphere.radius_mm;
        let to_camera = (-q.coords).normalize();
        let to_laser = (frame.laser_origin - q).normalize();
        if normal.dot(&to_camera) < MIN_FACING_COS || normal.dot(&to_laser) < MIN_FACING_COS {
            continue;
        }
        let Ok(px) = camera.project(&q) else { continue };
        if px.x < 0.0 || px.x >= f64::from(camera.width_px) {
            continue;
        }
        let row = px.y.round() as i64;
        if row < frame.searched.0 || row > frame.searched.1 {
            continue;
        }
        predicted.entry(row).or_insert(q);
    }
    let mut missing = 0;
    for (row, q) in &predicted {
        let seen = frame.rows.get(row).is_some_and(|points| {
            points.iter().any(|p| {
                // On the sphere, or in front of where it should be seen.
                sphere.distance_mm(p) < SURFACE_BAND_MM
                    || p.coords.norm() < q.coords.norm() - SURFACE_BAND_MM
            })
        });
        if !seen {
            missing += 1;
        }
    }
    (missing, predicted.len())
}

/// Whether the segment from `from` to `point` passes more than
/// [`INSIDE_MM`] deep into the sphere: a ray that reached `point` from
/// there (the camera's, the laser's) would have met the fruit first.
fn crosses(sphere: &Sphere, from: &Point3<f64>, point: &Point3<f64>) -> bool {
    let along = point - from;
    let length2 = along.norm_squared();
    if length2 <= 0.0 {
        return false;
    }
    let t = ((sphere.centre - from).dot(&along) / length2).clamp(0.0, 1.0);
    let closest = from + along * t;
    (sphere.centre - closest).norm() < sphere.radius_mm - INSIDE_MM
}

/// The distance of `centre` from the line through the camera along `ray`
/// (a unit vector), mm.
pub(crate) fn ray_distance_mm(centre: &Point3<f64>, ray: &Vector3<f64>) -> f64 {
    (centre.coords - ray * ray.dot(&centre.coords)).norm()
}

/// Refines `start` by robust least squares of the objective's smooth part:
/// the points near its surface (a Tukey weight over twice the surface
/// band, then the band), the radius prior and the rough position's prior.
pub(crate) fn refine(start: &Sphere, evidence: &Evidence) -> Sphere {
    let mut x = Vector4::new(start.centre.x, start.centre.y, start.centre.z, start.radius_mm);
    let r0 = evidence.prior.fruit_radius_mm;
    let radius_weight = 1.0 / (RADIUS_PRIOR_STD * r0).powi(2);
    // The points' own scatter: a fraction of the band (noise about 0.7 mm).
    let point_weight = 1.0 / (0.3 * SURFACE_BAND_MM).powi(2);
    for step in 0..REFINE_STEPS {
        let band = if step < REFINE_STEPS / 2 { 2.0 * SURFACE_BAND_MM } else { SURFACE_BAND_MM };
        let centre = Point3::new(x[0], x[1], x[2]);
        let mut h = Matrix4::<f64>::zeros();
        let mut g = Vector4::<f64>::zeros();
        for (_, p) in &evidence.points {
            let v = p - centre;
            let dist = v.norm();
            let r = dist - x[3];
            if r.abs() >= band || dist < 1e-9 {
                continue;
            }
            let w = point_weight * (1.0 - (r / band).powi(2)).powi(2);
            let u = -v / dist;
            let j = Vector4::new(u.x, u.y, u.z, -1.0);
            h += j * j.transpose() * w;
            g += j * (w * r);
        }
        for ray in &evidence.outline_rays {
            let off = centre.coords - ray * ray.dot(&centre.coords);
            let dist = off.norm();
            let r = dist - x[3];
            if r.abs() >= band || dist < 1e-9 {
                continue;
            }
            let w = OUTLINE_WEIGHT * point_weight * (1.0 - (r / band).powi(2)).powi(2);
            let u = off / dist;
            let j = Vector4::new(u.x, u.y, u.z, -1.0);
            h += j * j.transpose() * w;
            g += j * (w * r);
        }
        // Radius prior.
        h[(3, 3)] += radius_weight;
        g[3] += radius_weight * (x[3] - r0);
        // Rough position prior.
        let offset = centre - evidence.prior.rough_position_mm;
        let info = evidence.rough_information;
        for a in 0..3 {
            for b in 0..3 {
                h[(a, b)] += info[(a, b)];
            }
        }
        let pull = info * offset;
        g[0] += pull.x;
        g[1] += pull.y;
        g[2] += pull.z;
        let Some(delta) = h.cholesky().map(|c| c.solve(&(-g))) else { break };
        x += delta;
        if !x.iter().all(|v| v.is_finite()) || x[3] <= 0.0 {
            return *start;
        }
        if delta.norm() < 1e-4 {
            break;
        }
    }
    Sphere { centre: Point3::new(x[0], x[1], x[2]), radius_mm: x[3] }
}

/// Where a hypothesis came from, for the answer's reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Source {
    /// A robust sphere through the laser points of all frames.
    Points,
    /// A frame's arc at the prior radius, on the camera's side of its plane
    /// or the far side.
    Arc { frame: usize, mirrored: bool },
    /// The free sphere fit over the frames' fruit points.
    FreeFit,
    /// The sphere of the prior radius through the frames' fruit points.
    PriorRadiusFit,
    /// The sphere of the fruit's outline and the laser points.
    Outline,
    /// The rough position.
    Rough,
}

impl Source {
    pub(crate) fn describe(self) -> String {
        match self {
            Source::Points => "a sphere through the laser points".into(),
            Source::Arc { frame, mirrored: false } => format!("frame {frame}'s arc"),
            Source::Arc { frame, mirrored: true } => {
                format!("frame {frame}'s arc mirrored across its laser plane")
            }
            Source::FreeFit => "the free sphere fit".into(),
            Source::PriorRadiusFit => "the sphere of the prior radius".into(),
            Source::Outline => "the fruit's outline".into(),
            Source::Rough => "the rough position".into(),
        }
    }
}

/// A scored hypothesis.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hypothesis {
    pub(crate) sphere: Sphere,
    pub(crate) score: Score,
    pub(crate) source: Source,
}

/// Refines and scores every start, best first.
pub(crate) fn rank(starts: &[(Sphere, Source)], evidence: &Evidence) -> Vec<Hypothesis> {
    let mut hypotheses: Vec<Hypothesis> = starts
        .iter()
        .filter(|(s, _)| s.radius_mm.is_finite() && s.centre.coords.iter().all(|c| c.is_finite()))
        .map(|(start, source)| {
            let sphere = refine(start, evidence);
            Hypothesis { sphere, score: score(&sphere, evidence), source: *source }
        })
        .collect();
    hypotheses.sort_by(|a, b| a.score.total.total_cmp(&b.score.total));
    hypotheses
}

/// The spheres of the prior radius through a frame's arc: its circle's
/// centre `candidate` on the camera's side, and its mirror image across
/// the frame's laser plane.
pub(crate) fn arc_starts(
    frame: usize,
    candidate: &Point3<f64>,
    evidence: &Evidence,
    radius_mm: f64,
) -> Vec<(Sphere, Source)> {
    let Some(plane) = evidence.frames.get(frame).map(|f| &f.plane) else { return Vec::new() };
    let d = plane.signed_distance_mm(candidate);
    let mirror = candidate - plane.normal.into_inner() * (2.0 * d);
    vec![
        (Sphere { centre: *candidate, radius_mm }, Source::Arc { frame, mirrored: false }),
        (Sphere { centre: mirror, radius_mm }, Source::Arc { frame, mirrored: true }),
    ]
}

/// Robust spheres through all frames' points, one after another, each
/// without the points the previous ones explained.
pub(crate) fn point_starts(
    evidence: &Evidence,
    radius_range_mm: (f64, f64),
    seed: u64,
) -> Vec<(Sphere, Source)> {
    use alacs_model::ransac::{RansacOptions, ransac_refit};
    let mut remaining: Vec<Point3<f64>> = evidence.points.iter().map(|(_, p)| *p).collect();
    let mut starts = Vec::new();
    for round in 0..SEQUENTIAL_SPHERES {
        if remaining.len() < 2 * crate::frame::MIN_POINTS {
            break;
        }
        let estimator = crate::fit::SphereEstimator { points: &remaining, radius_range_mm };
        let options = RansacOptions {
            threshold: SURFACE_BAND_MM,
            confidence: 0.999,
            max_iterations: 1000,
            seed: seed.wrapping_add(round as u64),
        };
        let Some(outcome) = ransac_refit(&estimator, &options, 3) else { break };
        starts.push((outcome.model, Source::Points));
        let on: std::collections::BTreeSet<usize> = outcome.inliers.into_iter().collect();
        remaining = remaining
            .iter()
            .enumerate()
            .filter(|(i, _)| !on.contains(i))
            .map(|(_, p)| *p)
            .collect();
    }
    starts
}

/// What the acceptance test decided.
pub(crate) enum Decision {
    /// The best hypothesis, and by how much it beat its best rival.
    Accept { best: Hypothesis, margin: f64 },
    /// Why not, naming the competing explanation.
    Refuse(String),
}

/// The acceptance test (see the module docs) over hypotheses ranked best
/// first.
pub(crate) fn accept(ranked: &[Hypothesis], prior: &Prior) -> Decision {
    let Some(best) = ranked.first().copied() else {
        return Decision::Refuse("no hypothesis of the fruit".into());
    };
    // The laser must show the fruit: without a frame's cut on the sphere
    // its depth is the rough position's (the RGB-D camera's, 2 % of the
    // depth), which the laser points' covariance does not know.
    if best.score.frames == 0 {
        return Decision::Refuse(format!(
            "the laser shows the best sphere ({}: radius {:.1} mm) in no frame ({} points on it, fewer than {} in any frame): its depth would be the rough position's",
            best.source.describe(),
            best.sphere.radius_mm,
            best.score.explained,
            crate::frame::MIN_POINTS
        ));
    }
    let required = ACCEPT_MARGIN + ACCEPT_MARGIN_FRACTION * best.score.explained as f64;
    let rival_distance = RIVAL_DISTANCE * prior.fruit_radius_mm;
    let rival =
        ranked.iter().find(|h| (h.sphere.centre - best.sphere.centre).norm() > rival_distance);
    // The empty scene (nothing explained, nothing predicted) scores 0.
    let (rival_total, rival_name) = match rival {
        Some(r) if r.score.total < 0.0 => (
            r.score.total,
            format!(
                "{} ({:.0} mm away, radius {:.1} mm: {} points on it in {} frames, {} rows missing)",
                r.source.describe(),
                (r.sphere.centre - best.sphere.centre).norm(),
                r.sphere.radius_mm,
                r.score.explained,
                r.score.frames,
                r.score.missing
            ),
        ),
        _ => (0.0, "no fruit at all".to_string()),
    };
    let margin = rival_total - best.score.total;
    if margin < required {
        return Decision::Refuse(format!(
            "the best sphere ({}: radius {:.1} mm, {} points on it in {} frames, {} of {} predicted rows missing) does not beat {rival_name} by the margin: {margin:.1} < {required:.1} rows",
            best.source.describe(),
            best.sphere.radius_mm,
            best.score.explained,
            best.score.frames,
            best.score.missing,
            best.score.predicted,
        ));
    }
    Decision::Accept { best, margin }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_margin_grows_with_the_evidence_the_best_sphere_predicts() {
        let prior =
            Prior { rough_position_mm: Point3::new(0.0, 0.0, 800.0), fruit_radius_mm: 40.0 };
        let h = |x: f64, total: f64, predicted: usize| Hypothesis {
            sphere: Sphere { centre: Point3::new(x, 0.0, 800.0), radius_mm: 40.0 },
            score: Score {
                total,
                explained: predicted,
                frames: 2,
                hidden: 0,
                missing: 0,
                predicted,
                rms_mm: 0.5,
            },
            source: Source::Points,
        };
        // Beats the empty scene and a rival 20 mm away by 10 + 10 % of 100.
        assert!(matches!(
            accept(&[h(0.0, -100.0, 100), h(20.0, -79.0, 100)], &prior),
            Decision::Accept { .. }
        ));
        assert!(matches!(
            accept(&[h(0.0, -100.0, 100), h(20.0, -81.0, 100)], &prior),
            Decision::Refuse(_)
        ));
        // A hypothesis 5 mm away is the same fruit, not a rival.
        assert!(matches!(
            accept(&[h(0.0, -100.0, 100), h(5.0, -99.0, 100)], &prior),
            Decision::Accept { .. }
        ));
        // Too little evidence against the empty scene.
        let Decision::Refuse(reason) = accept(&[h(0.0, -11.0, 20)], &prior) else { panic!() };
        assert!(reason.contains("no fruit at all"), "{reason}");
        // However well it scores, a sphere no frame's cut lies on (its score
        // from the outline and a few stray points) is refused.
        let mut unseen = h(0.0, -100.0, 3);
        unseen.score.frames = 0;
        let Decision::Refuse(reason) = accept(&[unseen], &prior) else { panic!() };
        assert!(reason.contains("in no frame"), "{reason}");
    }

    /// Points on the camera's side of a sphere, none inside `other`.
    fn front_points(sphere: &Sphere, other: &Sphere) -> Vec<(usize, Point3<f64>)> {
        let mut points = Vec::new();
        for i in 1..=16 {
            let theta = f64::from(i) * 80f64.to_radians() / 16.0;
            for j in 0..32 {
                let phi = f64::from(j) * std::f64::consts::TAU / 32.0;
                let direction =
                    Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), -theta.cos());
                let p = sphere.centre + direction * sphere.radius_mm;
                if (p - other.centre).norm() > other.radius_mm {
                    points.push((0, p));
                }
            }
        }
        points
    }

    #[test]
    fn a_touching_neighbour_explains_its_own_points_and_no_longer_pulls_the_target() {
        let camera = Camera::blackfly_s_5mp();
        let target = Sphere { centre: Point3::new(0.0, 0.0, 800.0), radius_mm: 40.0 };
        let neighbour = Sphere { centre: Point3::new(78.0, 0.0, 800.0), radius_mm: 40.0 };
        let prior = Prior { rough_position_mm: target.centre, fruit_radius_mm: 40.0 };
        let mut points = front_points(&target, &neighbour);
        points.extend(front_points(&neighbour, &target));
        let evidence = Evidence {
            frames: Vec::new(),
            points,
            camera: &camera,
            prior: &prior,
            rough_information: nalgebra::Matrix3::identity() * 1e-6,
            outline_rays: Vec::new(),
        };
        let error = |s: Sphere| (s.centre - target.centre).norm() + (s.radius_mm - 40.0).abs();
        let pulled = error(refine(&target, &evidence));
        // The neighbour is found among the hypotheses; a sphere overlapping
        // the target (the same fruit fitted otherwise) is not a neighbour.
        let hypothesis = |sphere: Sphere| Hypothesis {
            sphere,
            score: score(&sphere, &evidence),
            source: Source::Points,
        };
        let overlapping = Sphere { centre: Point3::new(10.0, 0.0, 805.0), radius_mm: 44.0 };
        let found = neighbours(&target, &[hypothesis(overlapping), hypothesis(neighbour)]);
        assert_eq!(found, vec![neighbour]);
        let reduced = evidence.without_neighbours(&target, &found);
        let kept = error(refine(&target, &reduced));
        // Noise-free points: the contact's points pull the target by about
        // 0.2 mm (centre and radius); without them nothing does.
        assert!(pulled > 0.1 && kept < 0.01, "{pulled} mm pulled, {kept} mm kept");
    }
}
