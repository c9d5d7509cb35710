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
//!    ([`alacs_vision::extract_stripe_rgb`], [`alacs_vision::StripeOptions::orchard`]).
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
//!   ([`crate::Candidate::score`]) from its point count, stripe continuity, fit
//!   residual, agreement with the other frames' candidates and distance from
//!   the rough position; the best one is the answer.
//! - **Fused** (the default): one estimator ([`crate::estimate`]). Spheres
//!   that might be the fruit are proposed from every source (robust spheres
//!   through all frames' points, each frame's arc at the prior radius on
//!   both sides of its plane, the free fit, the prior radius's fit, the
//!   outline's sphere, the rough position), refined and scored by one
//!   objective: the laser points each explains, the points it would hide (inside it, or seen or lit through it), the
//!   stripe rows it predicts and the image does not show, the outline's
//!   tangency, the radius prior and the rough position's prior. The best
//!   is the answer where it beats every other explanation (and the empty
//!   scene) by a stated margin and its position is known within the
//!   harvester's tolerance; the fruit's outline then refines it (to an
//!   ellipsoid, under a prior that apples are round to a few per cent). Per-frame steps only
//!   propose and prune. docs/ACCURACY.md judges it per family of scans.
//!
//! An answer that does not pass the acceptance test gives `not_found` with
//! the reason (the best sphere and the explanation it could not rule
//! out), never a point.

use alacs_model::{Camera, LaserModel};
use image::RgbImage;
use rayon::prelude::*;

use crate::frame::{self, FrameContext, SearchBall};
use crate::{
    Error, FrameImages, FrameResult, Localization, LocateOptions, Method, Prior, Result, Status,
    fusion, selection,
};

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
    let crops: Vec<frame::FrameCrop> = frames.par_iter().map(|f| context.crop(f)).collect();
    let unlit = frame::unlit_views(&crops);
    let results: Vec<FrameResult> = crops
        .par_iter()
        .zip(&unlit)
        .enumerate()
        .map(|(index, (crop, unlit))| context.frame(index, crop, unlit.as_ref()))
        .collect::<Result<_>>()?;
    let views: Vec<&RgbImage> =
        frames.iter().map(|f| f.image_laser_off.unwrap_or(f.image)).collect();
    Ok(conclude(results, &context, &views))
}

/// From every frame's result to the answer: the holistic selection, the
/// fused fit, and the answer of the chosen method. `views` are the frames'
/// images for the outline (the laser-off image where a frame has one), or
/// their per-pixel minimum: the outline needs no more.
pub(crate) fn conclude(
    mut results: Vec<FrameResult>,
    context: &FrameContext,
    views: &[&RgbImage],
) -> Localization {
    let contradiction = frame::slide_contradiction(&results);
    frame::drop_unlit_points(&mut results, context, views);
    let (candidates, holistic) = selection::select(&mut results, context);
    let (fused, accepted, fused_rejected) =
        match fusion::estimate_fruit(&results, context, &candidates, views) {
            Ok(fusion::Accepted { fit, note, covariance }) => {
                (Some(fit), Some((note, covariance)), None)
            }
            Err(reason) => (None, None, Some(reason)),
        };
    // The fused answer against the rough position: beyond its stated
    // error the slides, the laser or the calibration contradict it.
    let (fused, accepted, fused_rejected, mut contradicted) = match (fused, accepted) {
        (Some(fit), Some((note, covariance))) => {
            let centre = fit.ellipsoid.as_ref().map_or(fit.sphere.centre, |e| e.centre);
            match context.search.contradiction(&centre, covariance.as_ref()) {
                Some(reason) => (None, None, Some(reason), true),
                None => (Some(fit), Some((note, covariance)), fused_rejected, false),
            }
        }
        (fused, accepted) => (fused, accepted, fused_rejected, false),
    };
    let mut answer = Localization {
        status: Status::NotFound,
        position_mm: None,
        radius_mm: None,
        method: context.options.method,
        selected: None,
        reason: String::new(),
        candidates,
        holistic,
        fused,
        fused_rejected,
        frames: results,
        search_radius_mm: context.search.radius_mm,
        position_cov_mm2: None,
        contradicted: false,
    };
    match context.options.method {
        Method::Fused => match accepted {
            Some((note, covariance)) => fusion::answer_fused(&mut answer, note, covariance),
            None => answer.reason = answer.fused_rejected.clone().unwrap_or_default(),
        },
        Method::Holistic => selection::answer_holistic(&mut answer, context.prior),
    }
    if let Some(reason) = contradiction {
        contradicted = true;
        answer.status = Status::NotFound;
        answer.position_mm = None;
        answer.radius_mm = None;
        answer.position_cov_mm2 = None;
        answer.reason = reason;
    }
    answer.contradicted = contradicted && answer.status == Status::NotFound;
    answer
}

/// The checks of [`locate`]'s inputs, in its order: frames present, the
/// prior, each frame ([`check_frame`]), the options.
fn check_inputs(
    camera: &Camera,
    prior: &Prior,
    frames: &[FrameImages],
    options: &LocateOptions,
) -> Result<()> {
    if frames.is_empty() {
        return Err(Error::InvalidInput("the scan has no frames".into()));
    }
    check_prior(prior)?;
    for (i, frame) in frames.iter().enumerate() {
        check_frame(camera, i, frame)?;
    }
    check_options(options)
}

/// Frames present, a rough position in front of the camera and a positive
/// radius prior.
pub(crate) fn check_prior(prior: &Prior) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidInput(m));
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
    Ok(())
}

/// Frame `i`'s images fit the camera and its slide position is finite.
pub(crate) fn check_frame(camera: &Camera, i: usize, frame: &FrameImages) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidInput(m));
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
    Ok(())
}

/// Options within their ranges.
pub(crate) fn check_options(options: &LocateOptions) -> Result<()> {
    let (lo, hi) = options.radius_factors;
    let positive = [
        options.rough_depth_error,
        options.rough_lateral_error_mm,
        options.inlier_threshold_mm,
        options.max_fit_rms_mm,
        options.shape_std,
    ];
    if !(positive.iter().all(|v| v.is_finite() && *v >= 0.0) && lo > 0.0 && hi > lo) {
        return Err(Error::InvalidInput(format!("invalid localization options: {options:?}")));
    }
    Ok(())
}
