//! The seed paper's holistic evaluation: every frame's candidate scored,
//! the best one selected.

use nalgebra::Point3;

use crate::frame::{FrameContext, SearchBall, no_candidate_reason};
use crate::{Candidate, FrameResult, Localization, LocateOptions, Prior, Status};

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

/// Every frame's candidate, scored, and the index of the best one.
pub(crate) fn select(
    results: &mut [FrameResult],
    context: &FrameContext,
) -> (Vec<Candidate>, Option<usize>) {
    score_candidates(
        results,
        context.search,
        context.prior,
        context.options,
        context.expected_rows(),
    );
    let candidates: Vec<Candidate> = results.iter().filter_map(|r| r.candidate.clone()).collect();
    let holistic = candidates
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.score.total_cmp(&b.1.score))
        .map(|(i, _)| i);
    (candidates, holistic)
}

/// The holistic method's answer: the selected candidate, at the prior radius.
pub(crate) fn answer_holistic(answer: &mut Localization, prior: &Prior) {
    let Some(i) = answer.holistic else {
        answer.reason = no_candidate_reason(&answer.frames);
        return;
    };
    let best = &answer.candidates[i];
    // The one acceptance test holds for every method: the selected frame's
    // candidate must be the fruit the estimator accepted from all frames
    // (within its rival distance), or the scan contradicts it.
    let agreed = answer.fused.as_ref().map(|fit| {
        let centre = fit.ellipsoid.as_ref().map_or(fit.sphere.centre, |e| e.centre);
        (best.position_mm - centre).norm()
    });
    let same_fruit = crate::estimate::RIVAL_DISTANCE * prior.fruit_radius_mm;
    match agreed {
        Some(apart) if apart <= same_fruit => {
            answer.status = Status::Ok;
            answer.position_mm = Some(best.position_mm);
            answer.radius_mm = Some(prior.fruit_radius_mm);
            answer.selected = Some(i);
            answer.reason = format!(
                "frame {} selected from {} candidates (score {:.2}); {apart:.1} mm from the fruit all frames support",
                best.frame,
                answer.candidates.len(),
                best.score
            );
        }
        Some(apart) => {
            answer.reason = format!(
                "frame {}'s candidate (score {:.2}) lies {apart:.0} mm from the fruit all frames support, more than {same_fruit:.0} mm: the frames contradict it",
                best.frame, best.score
            );
        }
        None => {
            answer.reason = format!(
                "frame {}'s candidate (score {:.2}) is not confirmed by the frames together: {}",
                best.frame,
                best.score,
                answer.fused_rejected.as_deref().unwrap_or("no fruit accepted")
            );
        }
    }
}
