//! The fused answer's position covariance (`position_cov_mm2`), the sum of
//! what the fit can see and what it cannot:
//!
//! 1. The fit's noise: sigma^2 (J^T J)^-1 of the sphere's centre over the
//!    fruit points on it (J the derivative of each point's distance from
//!    the sphere by the centre and, where it was fitted, the radius;
//!    sigma^2 their mean squared distance, at least [`MIN_NOISE_MM`]^2).
//! 2. The fruit's shape: an apple is not a sphere. Its semi-axes differ
//!    from its mean radius r by a relative standard deviation s
//!    ([`LocateOptions::shape_std`], default 5 %: apples' height over
//!    diameter is about 0.85-0.95), and the camera sees the front of the
//!    fruit only. A sphere fitted to the front of an ellipsoid with
//!    semi-axes a, b across the line of sight and c along it takes the
//!    front's curvature radius, about (a^2 + b^2) / 2c, so its centre lies
//!    about 2 r (mean(e_a, e_b) - e_c) behind the true one (e the relative
//!    deviations): variance 4 (1/2 + 1) (s r)^2 = 6 (s r)^2 along the line
//!    of sight. A tilted fruit moves it sideways by that times sin t cos t
//!    (E[sin^2 t cos^2 t] = 2/15 over random tilts): 16/15 (s r)^2 across,
//!    the two directions together, which is applied to each, a factor of
//!    two on the large side (a real apple's semi-axes and tilt are not the
//!    random ones of this argument). Where an ellipsoid replaced the
//!    sphere, its depth semi-axis comes from the roundness prior, and the
//!    error is the unseen semi-axis against the mean of the two seen: 3/2
//!    (s r)^2 along, 4/15 across; the same where the fruit's outline
//!    refined the fit (its rays fix the two semi-axes across the line of
//!    sight, and with the front's curvature the one along it: this errs
//!    on the large side, the measured mean squared distance is 1.0, not
//!    3). A fruit that needed a fallback (the prior's radius, the
//!    outline) is not seen from limb to limb, and gets the along-sight
//!    variance across it too.
//! 3. The radius, where one cut cannot fix it and the radius prior does:
//!    the centre moves along the line of sight by the prior's standard
//!    deviation ([`crate::estimate`]'s `RADIUS_PRIOR_STD`).
//!
//! The calibration's own error (alpha, L0, beta) is not in it: at the
//! standard deviations docs/calibration.md's 10-pose session gives (alpha
//! 0.0017 deg, L0 0.004 mm, beta 0.0006 deg) it moves a point at 1 m by
//! about 0.07-0.1 mm (dz/d alpha = z^2 (cos a + u sin a) / L, L = 280-380
//! mm), a variance under 0.1 % of the shape's along the line of sight
//! (about 5 mm for a 40 mm sphere fit); before the corners were fitted as
//! X-junctions (alpha 0.009 deg), 0.4-0.6 mm, still under 2 %.

use nalgebra::{DMatrix, Matrix3, Point3, Vector3};

use crate::fit::Sphere;
use crate::frame::MIN_NOISE_MM;
use crate::{FrameResult, FusedFit, LocateOptions};

/// The shape's variances (along, across the line of sight) in (s r)^2
/// for a sphere fit (see the module docs).
const SPHERE_SHAPE: (f64, f64) = (6.0, 16.0 / 15.0);

/// The same where an ellipsoid replaced the sphere.
const ELLIPSOID_SHAPE: (f64, f64) = (1.5, 4.0 / 15.0);

/// The covariance of `fit`'s centre (mm^2, camera frame), from the frames'
/// laser points within the inlier threshold of its sphere; `None` when
/// the points do not fix it.
pub(crate) fn position_covariance(
    fit: &FusedFit,
    results: &[FrameResult],
    options: &LocateOptions,
) -> Option<Matrix3<f64>> {
    let sphere = &fit.sphere;
    let points: Vec<Point3<f64>> = results
        .iter()
        .flat_map(|r| r.points_in_camera.iter().map(|(_, p)| *p))
        .filter(|p| sphere.distance_mm(p).abs() <= options.inlier_threshold_mm)
        .collect();
    let free_radius = !fit.radius_from_prior;
    let centre = fit.ellipsoid.as_ref().map_or(sphere.centre, |e| e.centre);
    let radius = fit.ellipsoid.as_ref().map_or(sphere.radius_mm, |e| e.equal_volume_radius_mm());
    // The radius prior's standard deviation: what is known of the fruit's
    // size where the points do not fix it (the estimator's own prior).
    let radius_std = crate::estimate::RADIUS_PRIOR_STD * radius;
    let fit_part = fit_covariance(&points, sphere, free_radius)
        .unwrap_or_else(|| Matrix3::identity() * radius_std * radius_std);
    let sight: Vector3<f64> = centre.coords.try_normalize(1e-9)?;
    let along = sight * sight.transpose();
    let shape = (options.shape_std * radius).powi(2);
    let (along_shape, across_shape) =
        if fit.ellipsoid.is_some() || fit.outline_refined { ELLIPSOID_SHAPE } else { SPHERE_SHAPE };
    // A fruit that needed a fallback is not seen from limb to limb.
    let fallback = fit.radius_from_prior || (fit.outline.is_some() && !fit.outline_refined);
    let across_shape = if fallback { along_shape } else { across_shape };
    let across = Matrix3::identity() - along;
    let mut covariance = fit_part + (across * across_shape + along * along_shape) * shape;
    if fit.radius_from_prior {
        covariance += along * radius_std * radius_std;
    }
    let symmetric = 0.5 * (covariance + covariance.transpose());
    (symmetric.iter().all(|v| v.is_finite()) && symmetric.cholesky().is_some()).then_some(symmetric)
}

/// sigma^2 (J^T J)^-1 of the sphere's centre over `points` (the radius a
/// parameter too where `free_radius`); `None` when they do not fix it.
fn fit_covariance(
    points: &[Point3<f64>],
    sphere: &Sphere,
    free_radius: bool,
) -> Option<Matrix3<f64>> {
    let unknowns = if free_radius { 4 } else { 3 };
    if points.len() <= unknowns {
        return None;
    }
    let mut jacobian = DMatrix::<f64>::zeros(points.len(), unknowns);
    let mut sum_sq = 0.0;
    for (row, p) in points.iter().enumerate() {
        let offset = p - sphere.centre;
        let distance = offset.norm();
        if distance <= 0.0 {
            return None;
        }
        let normal = offset / distance;
        for k in 0..3 {
            jacobian[(row, k)] = -normal[k];
        }
        if free_radius {
            jacobian[(row, 3)] = -1.0;
        }
        sum_sq += (distance - sphere.radius_mm).powi(2);
    }
    let sigma2 = (sum_sq / (points.len() - unknowns) as f64).max(MIN_NOISE_MM * MIN_NOISE_MM);
    let inverse = (jacobian.transpose() * &jacobian).try_inverse()?;
    let covariance = Matrix3::from_fn(|r, c| sigma2 * inverse[(r, c)]);
    covariance.iter().all(|v| v.is_finite()).then_some(covariance)
}
