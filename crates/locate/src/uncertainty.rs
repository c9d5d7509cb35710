//! The fused answer's position covariance (`position_cov_mm2`), the sum of
//! what the fit can see and what it cannot:
//!
//! 1. The fit's noise: sigma^2 (J^T J)^-1 of the sphere's centre over the
//!    fruit points on it (J the derivative of each point's distance from
//!    the sphere by the centre and, where it was fitted, the radius;
//!    sigma^2 their mean squared distance, at least `MIN_NOISE_MM`^2).
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
//!    random ones of this argument). Where the fruit's outline refined the
//!    sphere to an ellipsoid (its rays fix the two semi-axes across the
//!    line of sight, and with the front's curvature the one along it), the
//!    variance taken is that of an ellipsoid whose depth semi-axis only
//!    the roundness prior knew, the unseen semi-axis against the mean of
//!    the two seen: 3/2 (s r)^2 along, 4/15 across, on the large side. A
//!    fruit that needed a fallback (the prior's radius, a sphere from the
//!    outline) is not seen from limb to limb, and gets the sphere's
//!    along-sight variance in every direction.
//! 3. The radius, where one cut cannot fix it and the radius prior does:
//!    the centre moves with the radius as the fit at a fixed radius says,
//!    `dc/dR = (J^T J)^-1 J^T 1`, times the prior's standard deviation
//!    (`estimate`'s `RADIUS_PRIOR_STD`). For one cut, a circle of
//!    radius a, that is `R / sqrt(R^2 - a^2)` along the laser plane's
//!    normal: a cut near the fruit's middle leaves its depth across the
//!    plane unknown however well the circle is measured.
//!
//! 4. The stripe's systematic error along each frame's cut: light entering
//!    the flesh moves the stripe's centre by up to about a millimetre,
//!    depending on the angle of incidence, and the skin departs from the
//!    sphere; along one cut both vary smoothly, not point by point, so more
//!    points do not average them away. Each frame's cut gets an offset, a
//!    tilt and a bend along the stripe (Legendre polynomials 1, t,
//!    (3t^2 - 1) / 2 of the position along it), each with the standard
//!    deviation `SYSTEMATIC_STRIPE_MM`, carried to the centre by the
//!    fit's sensitivity `(J^T J)^-1 J^T q`. A long arc barely moves; a
//!    short one, whose bend is the only thing that says where its centre
//!    lies, moves by many millimetres.
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

/// Standard deviation of each systematic term of a frame's stripe along
/// its cut, mm: half the "up to about 1 mm" by which light scattered in an
/// apple moves the stripe's centre ([`crate::estimate`]'s surface band;
/// reduced scattering about 1/mm, ../shared/REFERENCES.md), a bound taken
/// as two standard deviations.
const SYSTEMATIC_STRIPE_MM: f64 = 0.5;

/// The covariance of `fit`'s centre (mm^2, camera frame), from the frames'
/// laser points within the inlier threshold of its sphere; `None` when
/// the points do not fix it.
pub(crate) fn position_covariance(
    fit: &FusedFit,
    results: &[FrameResult],
    options: &LocateOptions,
) -> Option<Matrix3<f64>> {
    let sphere = &fit.sphere;
    let points: Vec<(usize, Point3<f64>)> = results
        .iter()
        .enumerate()
        .flat_map(|(k, r)| r.points_in_camera.iter().map(move |(_, p)| (k, *p)))
        .filter(|(_, p)| sphere.distance_mm(p) <= options.inlier_threshold_mm)
        .collect();
    let free_radius = !fit.radius_from_prior;
    let centre = fit.ellipsoid.as_ref().map_or(sphere.centre, |e| e.centre);
    let radius = fit.ellipsoid.as_ref().map_or(sphere.radius_mm, |e| e.equal_volume_radius_mm());
    // The radius prior's standard deviation: what is known of the fruit's
    // size where the points do not fix it (the estimator's own prior).
    let radius_std = crate::estimate::RADIUS_PRIOR_STD * radius;
    let fitted = fit_covariance(&points, sphere, free_radius);
    let fit_part = fitted
        .as_ref()
        .map_or_else(|| Matrix3::identity() * radius_std * radius_std, |f| f.noise + f.systematic);
    let sight: Vector3<f64> = centre.coords.try_normalize(1e-9)?;
    let along = sight * sight.transpose();
    let shape = (options.shape_std * radius).powi(2);
    // A fruit that needed a fallback (one cut, or a sphere from the outline
    // where the laser saw too little) is not seen from limb to limb: the
    // sphere's along-sight variance, in every direction, whatever refined it.
    let fallback = fit.radius_from_prior || (fit.outline.is_some() && !fit.outline_refined);
    let (along_shape, across_shape) = if fallback {
        (SPHERE_SHAPE.0, SPHERE_SHAPE.0)
    } else if fit.ellipsoid.is_some() || fit.outline_refined {
        ELLIPSOID_SHAPE
    } else {
        SPHERE_SHAPE
    };
    let across = Matrix3::identity() - along;
    let mut covariance = fit_part + (across * across_shape + along * along_shape) * shape;
    if fit.radius_from_prior {
        // How the centre follows the radius (see the module docs); along the
        // line of sight where the points cannot tell.
        let centre_per_radius = fitted.and_then(|f| f.centre_per_radius).unwrap_or(sight);
        covariance += centre_per_radius * centre_per_radius.transpose() * radius_std * radius_std;
    }
    let symmetric = 0.5 * (covariance + covariance.transpose());
    (symmetric.iter().all(|v| v.is_finite()) && symmetric.cholesky().is_some()).then_some(symmetric)
}

/// What the fit's points say of its centre's uncertainty.
struct FitCovariance {
    /// sigma^2 (J^T J)^-1: the points' own noise.
    noise: Matrix3<f64>,
    /// Each frame's systematic stripe error (see the module docs).
    systematic: Matrix3<f64>,
    /// At a fixed radius, how the centre moves per mm of radius,
    /// `(J^T J)^-1 J^T 1`.
    centre_per_radius: Option<Vector3<f64>>,
}

/// The centre's uncertainty from `points` (with their frames) on `sphere`
/// (the radius a parameter too where `free_radius`); `None` when the
/// points do not fix the centre.
fn fit_covariance(
    points: &[(usize, Point3<f64>)],
    sphere: &Sphere,
    free_radius: bool,
) -> Option<FitCovariance> {
    let unknowns = if free_radius { 4 } else { 3 };
    if points.len() <= unknowns {
        return None;
    }
    let mut jacobian = DMatrix::<f64>::zeros(points.len(), unknowns);
    let mut sum_sq = 0.0;
    for (row, (_, p)) in points.iter().enumerate() {
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
    let noise = Matrix3::from_fn(|r, c| sigma2 * inverse[(r, c)]);
    // The centre's shift for residuals that move by `q` (one per point).
    let centre_shift = |q: &nalgebra::DVector<f64>| {
        let shift = &inverse * (jacobian.transpose() * q);
        Vector3::new(shift[0], shift[1], shift[2])
    };
    let mut systematic = Matrix3::zeros();
    let frames: std::collections::BTreeSet<usize> = points.iter().map(|(k, _)| *k).collect();
    for frame in frames {
        // Position along the stripe: the camera's y (the line runs down the
        // image), -1 to 1 over the frame's points.
        let (lo, hi) = points
            .iter()
            .filter(|(k, _)| *k == frame)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, p)| {
                (lo.min(p.y), hi.max(p.y))
            });
        let half = 0.5 * (hi - lo);
        let along = |p: &Point3<f64>| if half > 0.0 { (p.y - lo) / half - 1.0 } else { 0.0 };
        let terms: [fn(f64) -> f64; 3] = [|_| 1.0, |t| t, |t| 0.5 * (3.0 * t * t - 1.0)];
        for term in terms {
            let q = nalgebra::DVector::from_iterator(
                points.len(),
                points.iter().map(|(k, p)| if *k == frame { term(along(p)) } else { 0.0 }),
            );
            let shift = centre_shift(&q);
            systematic += shift * shift.transpose() * SYSTEMATIC_STRIPE_MM.powi(2);
        }
    }
    // The residuals fall by 1 per mm of radius.
    let centre_per_radius =
        (!free_radius).then(|| centre_shift(&nalgebra::DVector::from_element(points.len(), 1.0)));
    let finite = |m: &Matrix3<f64>| m.iter().all(|v| v.is_finite());
    (finite(&noise)
        && finite(&systematic)
        && centre_per_radius.is_none_or(|g| g.iter().all(|v| v.is_finite())))
    .then_some(FitCovariance { noise, systematic, centre_per_radius })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One laser cut, a full circle `h` mm from the centre of a sphere of
    /// radius `r`: at a fixed radius the centre follows the radius along
    /// the cut's normal by r / h, and not across it.
    #[test]
    fn one_cut_moves_the_centre_along_its_normal_by_r_over_h() {
        let (r, centre) = (40.0_f64, Point3::new(0.0, 0.0, 1000.0));
        for h in [5.0_f64, 20.0, 35.0] {
            let a = (r * r - h * h).sqrt();
            let points: Vec<Point3<f64>> = (0..60)
                .map(|k| {
                    let t = f64::from(k) / 60.0 * std::f64::consts::TAU;
                    centre + Vector3::new(h, a * t.cos(), a * t.sin())
                })
                .collect();
            let sphere = Sphere { centre, radius_mm: r };
            let points: Vec<(usize, Point3<f64>)> = points.into_iter().map(|p| (0, p)).collect();
            let g = fit_covariance(&points, &sphere, false).unwrap().centre_per_radius.unwrap();
            assert!((g.x.abs() - r / h).abs() < 1e-6 * r / h, "h {h}: {g}");
            assert!(g.y.abs() < 1e-9 && g.z.abs() < 1e-9, "h {h}: {g}");
        }
    }

    /// The stripe's systematic error moves the centre of a fit to a short
    /// arc by far more than one to a long arc of the same number of points:
    /// the short arc's bend alone says where its centre lies.
    #[test]
    fn a_short_arc_leaves_its_centre_uncertain_a_long_one_does_not() {
        let (r, centre) = (40.0_f64, Point3::new(0.0, 0.0, 1000.0));
        // Two cuts 10 mm either side of the centre, points over +-`half` rad.
        let worst_std = |half: f64| {
            let points: Vec<(usize, Point3<f64>)> = [(0, -10.0), (1, 10.0)]
                .iter()
                .flat_map(|&(k, h): &(usize, f64)| {
                    let a = (r * r - h * h).sqrt();
                    (0..40).map(move |i| {
                        let t = -half + 2.0 * half * f64::from(i) / 39.0;
                        (k, centre + Vector3::new(h, a * t.sin(), -a * t.cos()))
                    })
                })
                .collect();
            let sphere = Sphere { centre, radius_mm: r };
            let fit = fit_covariance(&points, &sphere, true).unwrap();
            fit.systematic.symmetric_eigenvalues().max().sqrt()
        };
        let (short, long) = (worst_std(0.2), worst_std(1.2));
        assert!(long < 4.0 * SYSTEMATIC_STRIPE_MM, "long arc: {long} mm");
        assert!(short > 10.0 * long, "short arc {short} mm, long arc {long} mm");
    }
}
