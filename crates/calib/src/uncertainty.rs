//! Standard deviations that hold when samples are not independent.
//!
//! Every laser sample of one board pose inherits that pose's error (the
//! board plane from PnP is a little off, for all of its pixels at once), and
//! every pose inherits the camera's. The covariance of the least-squares
//! fit, sigma^2 (J^T J)^-1, takes thousands of dense samples as thousands
//! of independent measurements and so reports a spread far too small: on a
//! rendered session it printed alpha +- 0.0001 deg for an error of
//! 0.0074 deg. A bootstrap over board poses (Efron's cluster bootstrap)
//! resamples what is independent, the poses: each replicate draws as many
//! poses as there are, with replacement, and repeats the fit on their
//! samples; with the session's images at hand it repeats the camera
//! calibration on the drawn poses' corners too, so the camera's error
//! reaches the laser's (`bootstrap_session`). The reported standard
//! deviation is the larger of the bootstrap's (scaled by sqrt(G / (G - 1))
//! for G poses, the usual small-cluster correction) and the covariance's.

use alacs_model::{Camera, LaserModel};
use nalgebra::{DMatrix, DVector, Isometry3, Point2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::intrinsics::CameraLinearization;
use crate::refine::{Layout, normal_equations, refine};
use crate::{BoardObservation, LaserSample, Residual};

/// Bootstrap replicates drawn: the standard deviation of a standard
/// deviation from B replicates is about 1 / sqrt(2 B), 5 % at 200.
pub const BOOTSTRAP_REPLICATES: usize = 200;

/// Inliers beyond which a bootstrap replicate is one Gauss-Newton step from
/// the fit instead of a refit. A refit reads every drawn sample several
/// times (200 refits of 1.4 million samples took half a minute, of 70,000
/// samples 0.8 s); one step from the fit on the drawn poses' summed normal
/// equations is the linearized (one-step) bootstrap, which on sets this
/// large agrees with the refits within a few per cent of the spread (test
/// `the_linearized_bootstrap_agrees_with_the_refits`: 12,000 samples).
const LINEARIZED_BOOTSTRAP_SAMPLES: usize = 20_000;

/// Fewest board poses a bootstrap is run on; with fewer, the spread over
/// poses says little, the covariance's would understate the error, and a
/// calibration gives no standard deviations (and warns).
pub const MIN_BOOTSTRAP_POSES: usize = 5;

/// Fewest distinct poses a replicate re-calibrates the camera from (Zhang's
/// minimum for the intrinsics); a draw with fewer is drawn again, which
/// with 5 or more poses is rarer than 1 in 40.
const MIN_CAMERA_POSES: usize = 3;

/// Fraction of replicates that must give a fit for the bootstrap to count.
const MIN_GOOD_REPLICATES: f64 = 0.8;

/// Where a calibration's standard deviations come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StdSource {
    /// The fit's covariance, sigma^2 (J^T J)^-1: the samples taken as
    /// independent (samples that do not name their board poses).
    Covariance,
    /// A bootstrap over board poses, never below the covariance's.
    PoseBootstrap {
        /// Board poses resampled.
        poses: usize,
        /// Replicates that gave a fit.
        replicates: usize,
        /// Whether each replicate re-calibrated the camera from its poses.
        camera: bool,
    },
}

impl StdSource {
    /// A short description for reports and the JSON's `std_source`.
    pub fn describe(&self) -> String {
        match self {
            StdSource::Covariance => "covariance of the fit (samples taken as independent)".into(),
            StdSource::PoseBootstrap { poses, replicates, camera } => format!(
                "bootstrap over {poses} board poses ({replicates} replicates{})",
                if *camera { ", camera re-calibrated in each" } else { "" }
            ),
        }
    }
}

/// Standard deviations over `replicates` draws of `groups` groups with
/// replacement; `fit` gets each draw (group indices, repeats allowed) and
/// returns the parameters or `None`. Returns the corrected standard
/// deviations and the number of replicates that gave a fit, or `None` when
/// too few did.
fn bootstrap(
    groups: usize,
    replicates: usize,
    seed: u64,
    min_distinct: usize,
    fit: impl Fn(&[usize]) -> Option<Vec<f64>> + Sync,
) -> Option<(Vec<f64>, usize)> {
    if groups < 2 {
        return None;
    }
    let results: Vec<Vec<f64>> = (0..replicates)
        .into_par_iter()
        .filter_map(|r| {
            let mut rng =
                ChaCha8Rng::seed_from_u64(seed ^ (r as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            // Redraw the rare draw with too few distinct groups (a few tries).
            let draw = (0..20)
                .map(|_| (0..groups).map(|_| rng.random_range(0..groups)).collect::<Vec<usize>>());
            let mut chosen = None;
            for d in draw {
                let mut distinct = d.clone();
                distinct.sort_unstable();
                distinct.dedup();
                if distinct.len() >= min_distinct.min(groups) {
                    chosen = Some(d);
                    break;
                }
            }
            fit(&chosen?)
        })
        .collect();
    if (results.len() as f64) < MIN_GOOD_REPLICATES * replicates as f64 || results.len() < 2 {
        return None;
    }
    let n = results.len() as f64;
    let dims = results[0].len();
    let correction = (groups as f64 / (groups as f64 - 1.0)).sqrt();
    let std = (0..dims)
        .map(|k| {
            let mean = results.iter().map(|p| p[k]).sum::<f64>() / n;
            let var = results.iter().map(|p| (p[k] - mean).powi(2)).sum::<f64>() / (n - 1.0);
            var.sqrt() * correction
        })
        .collect();
    Some((std, results.len()))
}

/// The bootstrap over the board poses the samples name (their `pose`),
/// with the samples as measured: a replicate refits `laser` on the
/// `inliers` of the drawn poses (inliers without a pose are left out).
/// `None` when fewer than [`MIN_BOOTSTRAP_POSES`] poses are named among the
/// inliers or the replicates fail.
pub(crate) fn bootstrap_samples(
    samples: &[LaserSample],
    inliers: &[usize],
    laser: &LaserModel,
    layout: Layout,
    residual: Residual,
    seed: u64,
) -> Option<(Vec<f64>, StdSource)> {
    let linearized = inliers.len() > LINEARIZED_BOOTSTRAP_SAMPLES;
    pose_bootstrap(samples, inliers, laser, layout, residual, seed, linearized)
}

/// [`bootstrap_samples`], each replicate a refit, or with `linearized` one
/// Gauss-Newton step from the fit.
fn pose_bootstrap(
    samples: &[LaserSample],
    inliers: &[usize],
    laser: &LaserModel,
    layout: Layout,
    residual: Residual,
    seed: u64,
    linearized: bool,
) -> Option<(Vec<f64>, StdSource)> {
    let mut poses: Vec<u32> = inliers.iter().filter_map(|&i| samples[i].pose).collect();
    poses.sort_unstable();
    poses.dedup();
    if poses.len() < MIN_BOOTSTRAP_POSES {
        return None;
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); poses.len()];
    for &i in inliers {
        if let Some(g) = samples[i].pose.and_then(|p| poses.binary_search(&p).ok()) {
            members[g].push(i);
        }
    }
    let (std, replicates) = if linearized {
        // One Gauss-Newton step from the fit per replicate: each pose's
        // normal equations at the fit, summed over the draw.
        let per_pose: Vec<(DMatrix<f64>, DVector<f64>)> = members
            .par_iter()
            .map(|m| normal_equations(samples, m, laser, layout, residual))
            .collect::<Option<_>>()?;
        let fitted = DVector::from_vec(layout.parameters(laser));
        let p = fitted.len();
        bootstrap(poses.len(), BOOTSTRAP_REPLICATES, seed, 2, |draw| {
            let (mut jtj, mut jtr) = (DMatrix::zeros(p, p), DVector::zeros(p));
            for &g in draw {
                jtj += &per_pose[g].0;
                jtr += &per_pose[g].1;
            }
            let step = jtj.cholesky()?.solve(&-jtr);
            Some((&fitted + step).iter().copied().collect())
        })?
    } else {
        bootstrap(poses.len(), BOOTSTRAP_REPLICATES, seed, 2, |draw| {
            // The drawn poses in sample order: the refit reads the samples
            // front to back.
            let mut draw = draw.to_vec();
            draw.sort_unstable();
            let indices: Vec<usize> =
                draw.iter().flat_map(|&g| members[g].iter().copied()).collect();
            refine(samples, &indices, laser, layout, residual)
                .ok()
                .map(|r| layout.parameters(&r.laser))
        })?
    };
    Some((std, StdSource::PoseBootstrap { poses: poses.len(), replicates, camera: false }))
}

/// Standard deviations of a given `laser` on `samples` that name their
/// board poses (`pose`): the samples within `threshold_mm` of it, a
/// bootstrap over their poses with each replicate one Gauss-Newton step
/// from the laser (the linearized bootstrap), over alpha, L0, beta (high
/// fidelity) and the slide scale k (where the samples span two or more
/// slide positions). `None` with fewer than [`MIN_BOOTSTRAP_POSES`] poses.
/// What a report needs for a laser read from a file.
pub fn laser_std_dev_at(
    samples: &[LaserSample],
    laser: &LaserModel,
    threshold_mm: f64,
) -> Option<crate::ParameterStdDev> {
    let inliers: Vec<usize> = (0..samples.len())
        .filter(|&i| crate::depth_error_mm(laser, &samples[i]).abs() <= threshold_mm)
        .collect();
    let inlier_samples = inliers.iter().map(|&i| &samples[i]);
    let layout = crate::linear::LinearForm::new(laser.fidelity, inlier_samples, true).layout();
    let (std, source) = pose_bootstrap(samples, &inliers, laser, layout, Residual::Depth, 0, true)?;
    crate::ParameterStdDev::from_parameters(&std, layout, source)
}

/// One board pose of a session as the bootstrap needs it.
#[derive(Debug, Clone)]
pub(crate) struct PoseData {
    /// The board's corners (of one of the pose's images).
    pub observation: BoardObservation,
    /// The pose found with the given camera.
    pub camera_from_board: Isometry3<f64>,
    /// Per image of this pose: its slide position and its laser pixels
    /// that the fit used.
    pub stripes: Vec<(f64, Vec<Point2<f64>>)>,
}

/// The bootstrap over a session's board poses, the whole calibration
/// repeated per replicate: the camera re-calibrated from the drawn poses'
/// corners (when `recalibrate_camera`, starting at `camera`), the laser
/// pixels turned into samples on the replicate's board planes, and the
/// laser refitted from `laser`.
pub(crate) fn bootstrap_session(
    poses: &[PoseData],
    camera: &Camera,
    laser: &LaserModel,
    layout: Layout,
    residual: Residual,
    recalibrate_camera: bool,
    seed: u64,
) -> Option<(Vec<f64>, StdSource)> {
    if poses.len() < MIN_BOOTSTRAP_POSES {
        return None;
    }
    let min_distinct = if recalibrate_camera { MIN_CAMERA_POSES } else { 2 };
    let linearized = if recalibrate_camera {
        let views: Vec<&BoardObservation> = poses.iter().map(|p| &p.observation).collect();
        let initial = poses.iter().map(|p| p.camera_from_board).collect();
        Some(CameraLinearization::new(camera.clone(), initial, &views).ok()?)
    } else {
        None
    };
    let (std, replicates) =
        bootstrap(poses.len(), BOOTSTRAP_REPLICATES, seed, min_distinct, |draw| {
            let (camera_r, poses_r) = match &linearized {
                Some(linearized) => {
                    let mut counts = vec![0; poses.len()];
                    for &g in draw {
                        counts[g] += 1;
                    }
                    linearized.replicate(&counts)?
                }
                None => (camera.clone(), poses.iter().map(|p| p.camera_from_board).collect()),
            };
            let mut samples = Vec::new();
            for &g in draw {
                for (slide_mm, pixels) in &poses[g].stripes {
                    samples.extend(
                        pixels.iter().filter_map(|px| {
                            sample_on_board(&camera_r, &poses_r[g], px, *slide_mm)
                        }),
                    );
                }
            }
            let all: Vec<usize> = (0..samples.len()).collect();
            refine(&samples, &all, laser, layout, residual)
                .ok()
                .map(|r| layout.parameters(&r.laser))
        })?;
    Some((
        std,
        StdSource::PoseBootstrap { poses: poses.len(), replicates, camera: recalibrate_camera },
    ))
}

/// A laser pixel's sample: its ray through `camera` met with the board
/// plane of `camera_from_board`.
pub(crate) fn sample_on_board(
    camera: &Camera,
    camera_from_board: &Isometry3<f64>,
    pixel: &Point2<f64>,
    slide_mm: f64,
) -> Option<LaserSample> {
    let normal: Vector3<f64> = camera_from_board.rotation * Vector3::z();
    let offset = normal.dot(&camera_from_board.translation.vector);
    let normalized = camera.undistort_pixel(pixel).ok()?;
    let denominator = normal.dot(&Vector3::new(normalized.x, normalized.y, 1.0));
    if denominator.abs() < 1e-9 {
        return None;
    }
    let z_mm = offset / denominator;
    (z_mm.is_finite() && z_mm > 0.0).then_some(LaserSample {
        u_n: normalized.x,
        v_n: normalized.y,
        z_mm,
        slide_mm,
        pose: None,
    })
}

/// The larger, parameter by parameter, of the bootstrap's and the
/// covariance's standard deviations.
pub(crate) fn at_least(bootstrap: &[f64], covariance: Option<&[f64]>) -> Vec<f64> {
    bootstrap
        .iter()
        .enumerate()
        .map(|(k, b)| covariance.and_then(|c| c.get(k)).map_or(*b, |c| b.max(*c)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use alacs_model::Fidelity;
    use nalgebra::Point2;
    use rand_distr::{Distribution, Normal};

    /// `poses` board poses of `per_pose` samples each, every pose's depths
    /// sharing one error (sd 0.5 mm) beside each sample's own (sd 0.3 mm).
    fn samples_with_pose_errors(
        laser: &LaserModel,
        poses: u32,
        per_pose: usize,
    ) -> Vec<LaserSample> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (shared, own) = (Normal::new(0.0, 0.5).unwrap(), Normal::new(0.0, 0.3).unwrap());
        (0..poses)
            .flat_map(|pose| {
                let offset = shared.sample(&mut rng);
                let slide_mm = f64::from(pose % 3) * 100.0;
                let depth_mm: f64 = rng.random_range(600.0..1200.0);
                (0..per_pose)
                    .map(|_| {
                        let v_n: f64 = rng.random_range(-0.3..0.3);
                        // The laser pixel's column at that depth and row.
                        let d = (laser.laser_distance_mm(slide_mm) / depth_mm).clamp(0.05, 2.0);
                        let u_n = (laser.alpha_rad.sin() - v_n * laser.beta_rad.tan() - d)
                            / laser.alpha_rad.cos();
                        let z_mm =
                            laser.depth_mm(&Point2::new(u_n, v_n), slide_mm).unwrap_or(depth_mm)
                                + offset
                                + own.sample(&mut rng);
                        LaserSample { u_n, v_n, z_mm, slide_mm, pose: Some(pose) }
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    #[test]
    fn the_linearized_bootstrap_agrees_with_the_refits() {
        let truth =
            LaserModel::new(Fidelity::High, 19.07_f64.to_radians(), 0.69_f64.to_radians(), 381.98);
        let samples = samples_with_pose_errors(&truth, 300, 40);
        let all: Vec<usize> = (0..samples.len()).collect();
        let layout = Layout { fidelity: Fidelity::High, slide_scale: true };
        let fit = refine(&samples, &all, &truth, layout, Residual::Depth).unwrap();
        let (refits, _) =
            pose_bootstrap(&samples, &all, &fit.laser, layout, Residual::Depth, 3, false).unwrap();
        let (steps, _) =
            pose_bootstrap(&samples, &all, &fit.laser, layout, Residual::Depth, 3, true).unwrap();
        let covariance = fit.covariance.unwrap();
        for k in 0..4 {
            let ratio = steps[k] / refits[k];
            assert!((0.95..1.05).contains(&ratio), "parameter {k}: {} vs {}", steps[k], refits[k]);
        }
        // The shared errors are there to be seen: the spread of alpha and L0
        // over poses is well beyond the samples-as-independent covariance's
        // (beta, fixed by the rows within each pose, hardly feels them).
        for k in 0..2 {
            assert!(refits[k] > 2.0 * covariance[(k, k)].sqrt(), "parameter {k}");
        }
    }
}
