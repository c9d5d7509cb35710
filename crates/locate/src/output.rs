//! The `localize --json` object (FORMATS.md): one owner for its keys and
//! values, serialized by the command line and read back by whoever consumes
//! it (a ROS node, tests).

use serde::{Deserialize, Serialize};

use crate::{Candidate, FrameResult, FusedFit, Localization, Method, Prior, Status};

/// FORMATS.md's `localize --json` object for a scan naming several fruit
/// (scan.yaml's `targets`): one answer per fruit, in scan.yaml's order.
/// Build it with [`TargetsOutput::new`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetsOutput {
    /// One per fruit, in scan.yaml's order.
    pub targets: Vec<TargetOutput>,
    /// Fruit named.
    pub n_targets: usize,
    /// Fruit whose status is `ok`.
    pub n_found: usize,
}

/// One fruit of [`TargetsOutput`]: its prior, then the localize object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetOutput {
    /// 0-based index into scan.yaml's `targets`.
    pub target: usize,
    /// The rough position localization started from, mm.
    pub rough_position_mm: [f64; 3],
    /// The radius prior, mm.
    pub fruit_radius_mm: f64,
    /// The answer, as for a scan of this fruit alone.
    #[serde(flatten)]
    pub answer: LocalizeOutput,
}

impl TargetsOutput {
    /// The object for `answers`, one per prior of `priors`.
    pub fn new(answers: &[Localization], priors: &[Prior]) -> Self {
        let targets: Vec<TargetOutput> = answers
            .iter()
            .zip(priors)
            .enumerate()
            .map(|(target, (answer, prior))| TargetOutput {
                target,
                rough_position_mm: xyz(&prior.rough_position_mm),
                fruit_radius_mm: prior.fruit_radius_mm,
                answer: LocalizeOutput::from(answer),
            })
            .collect();
        let n_found = targets.iter().filter(|t| t.answer.status == Status::Ok).count();
        TargetsOutput { n_targets: targets.len(), n_found, targets }
    }
}

/// FORMATS.md's `localize --json` object: the answer, the method, the
/// holistic selection, the fused fit and each frame's stripe and fruit
/// point counts. Build it with `LocalizeOutput::from(&localization)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizeOutput {
    /// The fruit centre in the ALACS camera frame, mm (`null` when not found).
    pub position_mm: Option<[f64; 3]>,
    /// The fruit radius, mm (`null` when not found).
    pub radius_mm: Option<f64>,
    /// Covariance of `position_mm`, mm^2, rows of the 3 x 3 matrix (`null`
    /// when not found and for the holistic method).
    #[serde(default)]
    pub position_cov_mm2: Option<[[f64; 3]; 3]>,
    /// Every frame's candidate, in frame order.
    pub candidates: Vec<CandidateOutput>,
    /// Index into `candidates` of the answer (the holistic method only).
    pub selected: Option<usize>,
    /// `ok` or `not_found`.
    pub status: Status,
    /// Why not found, or how the answer was found.
    pub reason: String,
    /// `fused` or `holistic`.
    pub method: Method,
    /// Index into `candidates` of the holistic selection, whichever method answered.
    pub holistic_selection: Option<usize>,
    /// The fused fit, if it was trustworthy.
    pub fused: Option<FusedOutput>,
    /// Why the free fused fit was not trustworthy, if it was not.
    pub fused_rejected: Option<String>,
    /// What each frame gave, in frame order.
    pub frames: Vec<FrameOutput>,
}

/// One frame's candidate ([`Candidate`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateOutput {
    /// Index of the frame.
    pub frame: usize,
    /// Slide travel of the frame, mm.
    pub slide_mm: f64,
    /// The candidate fruit centre, camera frame, mm.
    pub position_mm: [f64; 3],
    /// Fruit points on the frame's circle.
    pub n_points: usize,
    /// The holistic score ([`Candidate::score`]).
    pub score: f64,
    /// Radius of the circle the laser plane cuts from the fruit, mm.
    pub circle_radius_mm: f64,
    /// Fraction of the rows between the arc's ends that hold a fruit point.
    pub continuity: f64,
    /// RMS distance of the fruit points from the circle, mm.
    pub fit_rms_mm: f64,
}

/// The fused fit ([`FusedFit`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FusedOutput {
    /// The sphere's centre, camera frame, mm.
    pub sphere_centre_mm: [f64; 3],
    /// The sphere's radius, mm.
    pub sphere_radius_mm: f64,
    /// The ellipsoid's semi-axes, mm, when it replaced the sphere.
    pub ellipsoid_semi_axes_mm: Option<[f64; 3]>,
    /// Points on the fit.
    pub n_points: usize,
    /// Frames that contribute points.
    pub n_frames: usize,
    /// RMS distance of the points from the sphere, mm.
    pub rms_mm: f64,
    /// Whether the radius was held at the prior.
    pub radius_from_prior: bool,
    /// The fruit's outline in the image, when the sphere was fitted to it.
    pub outline: Option<OutlineOutput>,
    /// Whether the laser alone fixed the sphere and the outline refined it
    /// (else the outline, where present, was the last resort).
    #[serde(default)]
    pub outline_refined: bool,
}

/// The fruit's outline in the image ([`crate::outline::Outline`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutlineOutput {
    /// Centre of the outline's circle, pixels.
    pub centre_px: [f64; 2],
    /// Radius of the outline's circle, pixels.
    pub radius_px: f64,
    /// Fraction of the circle's circumference the edges cover.
    pub support: f64,
    /// Fraction of the pixels inside the circle that are fruit-coloured.
    pub fill: f64,
}

/// What one frame gave ([`FrameResult`]), as counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameOutput {
    /// Slide travel, mm.
    pub slide_mm: f64,
    /// Stripe points found in the search region.
    pub stripe_points: usize,
    /// Of them, points on the fruit's circle.
    pub fruit_points: usize,
    /// Why the frame gave no candidate.
    pub rejected: Option<String>,
}

fn xyz(p: &nalgebra::Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

impl From<&Localization> for LocalizeOutput {
    fn from(answer: &Localization) -> Self {
        LocalizeOutput {
            position_mm: answer.position_mm.as_ref().map(xyz),
            radius_mm: answer.radius_mm,
            position_cov_mm2: answer
                .position_cov_mm2
                .map(|c| std::array::from_fn(|r| std::array::from_fn(|k| c[(r, k)]))),
            candidates: answer.candidates.iter().map(CandidateOutput::from).collect(),
            selected: answer.selected,
            status: answer.status,
            reason: answer.reason.clone(),
            method: answer.method,
            holistic_selection: answer.holistic,
            fused: answer.fused.as_ref().map(FusedOutput::from),
            fused_rejected: answer.fused_rejected.clone(),
            frames: answer.frames.iter().map(FrameOutput::from).collect(),
        }
    }
}

impl From<&Candidate> for CandidateOutput {
    fn from(c: &Candidate) -> Self {
        CandidateOutput {
            frame: c.frame,
            slide_mm: c.slide_mm,
            position_mm: xyz(&c.position_mm),
            n_points: c.n_points,
            score: c.score,
            circle_radius_mm: c.circle_radius_mm,
            continuity: c.continuity,
            fit_rms_mm: c.fit_rms_mm,
        }
    }
}

impl From<&FusedFit> for FusedOutput {
    fn from(f: &FusedFit) -> Self {
        FusedOutput {
            sphere_centre_mm: xyz(&f.sphere.centre),
            sphere_radius_mm: f.sphere.radius_mm,
            ellipsoid_semi_axes_mm: f.ellipsoid.map(|e| {
                let a = e.semi_axes_mm();
                [a.x, a.y, a.z]
            }),
            n_points: f.n_points,
            n_frames: f.n_frames,
            rms_mm: f.rms_mm,
            radius_from_prior: f.radius_from_prior,
            outline: f.outline.as_ref().map(|o| OutlineOutput {
                centre_px: [o.centre_px.x, o.centre_px.y],
                radius_px: o.radius_px,
                support: o.support,
                fill: o.fill,
            }),
            outline_refined: f.outline_refined,
        }
    }
}

impl From<&FrameResult> for FrameOutput {
    fn from(f: &FrameResult) -> Self {
        FrameOutput {
            slide_mm: f.slide_mm,
            stripe_points: f.stripe.len(),
            fruit_points: f.fruit.len(),
            rejected: f.rejected.clone(),
        }
    }
}
