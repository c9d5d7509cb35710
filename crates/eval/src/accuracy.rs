//! The seed paper's localization-accuracy experiment (Section 4.2): views of
//! a checkerboard at several slide positions d; per laser pixel on the board
//!
//! - the true point: its camera ray intersected with the board plane of the
//!   board pose (PnP), as `alacs-calib`'s laser samples are made
//!   ([`alacs_calib::view_samples`]),
//! - the estimated point: the laser model's triangulation of the same pixel
//!   (eqs. (7)-(8) with L = L0 - k d),
//!
//! and per slide position the distribution of the errors in x, y and z.
//!
//! # The noise floor
//! A stripe centre off by sigma_px pixels moves u_n by sigma_px / f, and
//! since z = L / D with dD/du_n = -cos(alpha) (eq. (7)), the depth by
//!
//! ```text
//! sigma_z = z^2 cos(alpha) sigma_px / (f L),    L = L0 - k d,
//! ```
//!
//! which grows as the laser slides towards the camera (L shrinks). Each
//! slide position's summary carries this prediction at its median depth.
//!
//! sigma_px is measured from the session itself unless given: each point's
//! depth error minus its view's median (which removes the board pose's own
//! error, common to a view's points), scaled to pixels by f L / (z^2
//! cos(alpha)), has a robust spread (1.4826 times the median absolute
//! deviation) over all points: that is the stripe centre's noise as the
//! depths show it. Per slide position the same spread in mm
//! (`within_view_sigma_z_mm`) is what the prediction is to be compared with;
//! the box plots' quartiles also hold the board poses' errors.

use alacs_calib::{LaserSample, ViewSamples, rejection_note, session_view_samples};
use alacs_model::{Camera, LaserModel, Session};
use alacs_vision::StripeOptions;
use nalgebra::{Point3, Vector3};
use serde_json::{Value, json};

use crate::stats::median;
use crate::{BoxStats, Error, Result};

/// Scale from the median absolute deviation to the standard deviation of a
/// normal distribution.
const MAD_TO_SIGMA: f64 = 1.4826;

/// Which laser points of a view are evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PointsPerView {
    /// Every stripe pixel on the board (one per image row), the default.
    #[default]
    All,
    /// Three per view, as the seed paper: the stripe's points at 1/6, 3/6
    /// and 5/6 of its length on the board (the centres of its thirds).
    Three,
}

impl PointsPerView {
    /// `all` or `3`.
    pub fn as_str(self) -> &'static str {
        match self {
            PointsPerView::All => "all",
            PointsPerView::Three => "3",
        }
    }
}

/// Settings of [`evaluate_accuracy`].
#[derive(Debug, Clone)]
pub struct AccuracyOptions {
    /// Which points of each view.
    pub points: PointsPerView,
    /// Stripe-centre noise (px) for the predicted noise floor; `None`:
    /// measured from the session (module docs).
    pub sigma_px: Option<f64>,
    /// Stripe extraction (as the laser calibration's).
    pub stripe: StripeOptions,
    /// Where the evaluated laser was fitted to these very samples by RANSAC
    /// with this inlier threshold (mm on |z - z_hat|: the calibration
    /// report), the points beyond it are the ones such a fit rejects: they
    /// are counted and drawn apart (still in the boxes, whose quartiles one
    /// stray point barely moves, and not stretching the plot's range).
    /// `None` (a session of its own, `alacs evaluate accuracy`): none is.
    pub rejected_beyond_mm: Option<f64>,
}

impl Default for AccuracyOptions {
    fn default() -> Self {
        Self {
            points: PointsPerView::All,
            sigma_px: None,
            stripe: StripeOptions::default(),
            rejected_beyond_mm: None,
        }
    }
}

/// One evaluated laser point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccuracyPoint {
    /// Index of its view in the session.
    pub view: usize,
    /// The view's slide position d, mm.
    pub slide_mm: f64,
    /// The true point: its ray on the board plane, camera frame, mm.
    pub point_true_in_camera: Point3<f64>,
    /// The laser model's triangulation, camera frame, mm.
    pub point_estimated_in_camera: Point3<f64>,
    /// Whether a fit with the threshold rejects it ([`AccuracyOptions::rejected_beyond_mm`]).
    pub rejected: bool,
}

impl AccuracyPoint {
    /// Estimated minus true, camera frame, mm.
    pub fn error_mm(&self) -> Vector3<f64> {
        self.point_estimated_in_camera - self.point_true_in_camera
    }
}

/// The errors at one slide position.
#[derive(Debug, Clone, PartialEq)]
pub struct SlideAccuracy {
    /// The slide position d, mm.
    pub slide_mm: f64,
    /// The laser-camera distance L = L0 - d of the evaluated laser, mm.
    pub laser_distance_mm: f64,
    /// The median true depth of the points, mm.
    pub median_depth_mm: f64,
    /// The predicted noise floor sigma_z at that depth (module docs), mm.
    pub predicted_sigma_z_mm: f64,
    /// The measured spread of the depth errors about each view's median
    /// (1.4826 MAD) over all the views' points, mm: the stripe's share of
    /// the error, to compare with `predicted_sigma_z_mm`.
    pub within_view_sigma_z_mm: f64,
    /// The same spread scaled to pixels point by point (module docs), px.
    pub within_view_sigma_px: f64,
    /// Error statistics along x, y and z (estimated - true), mm.
    pub error_mm: [BoxStats; 3],
}

/// The result of [`evaluate_accuracy`].
#[derive(Debug, Clone)]
pub struct AccuracyEvaluation {
    /// Every evaluated point, in view order (those a fit rejects among
    /// them, marked).
    pub points: Vec<AccuracyPoint>,
    /// The fit's inlier threshold the rejected points lie beyond, mm
    /// ([`AccuracyOptions::rejected_beyond_mm`]).
    pub rejected_beyond_mm: Option<f64>,
    /// Every view, in session order, with its board pose or why it gave nothing.
    pub views: Vec<ViewSamples>,
    /// Per slide position, ascending.
    pub slides: Vec<SlideAccuracy>,
    /// The evaluated laser.
    pub laser: LaserModel,
    /// The camera's focal length along u used for the noise floor, px.
    pub focal_px: f64,
    /// The options it ran with.
    pub points_per_view: PointsPerView,
    /// The stripe-centre noise of the noise floor, px.
    pub sigma_px: f64,
    /// Whether `sigma_px` was measured from the session (else given).
    pub sigma_px_measured: bool,
    /// The stripe-centre noise the session shows over all its points
    /// (whichever are evaluated), px.
    pub measured_sigma_px: f64,
}

/// The predicted depth noise sigma_z = z^2 cos(alpha) sigma_px / (f L) (module docs), mm.
pub fn noise_floor_mm(
    depth_mm: f64,
    alpha_rad: f64,
    sigma_px: f64,
    focal_px: f64,
    laser_distance_mm: f64,
) -> f64 {
    depth_mm * depth_mm * alpha_rad.cos() * sigma_px / (focal_px * laser_distance_mm)
}

/// The indices of `n` points a view keeps under `points`.
fn chosen(n: usize, points: PointsPerView) -> Vec<usize> {
    match points {
        PointsPerView::All => (0..n).collect(),
        PointsPerView::Three if n <= 3 => (0..n).collect(),
        PointsPerView::Three => {
            [1.0, 3.0, 5.0].iter().map(|k| ((k / 6.0) * n as f64).floor() as usize).collect()
        }
    }
}

/// Evaluates `laser` on a session's views with `camera` (see the module
/// docs). `progress` is called once per view. A view without a board or a
/// stripe is reported in `views` and skipped; no points at all is an error.
pub fn evaluate_accuracy(
    session: &Session,
    camera: &Camera,
    laser: &LaserModel,
    options: &AccuracyOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<AccuracyEvaluation> {
    if let Some(sigma_px) = options.sigma_px
        && !(sigma_px >= 0.0 && sigma_px.is_finite())
    {
        return Err(Error::InvalidOptions(format!(
            "the stripe-centre noise must be a finite number of px >= 0, got {sigma_px}"
        )));
    }
    let per_view = session_view_samples(session, camera, &options.stripe, progress)?;
    accuracy_from_views(per_view, camera, laser, options)
}

/// [`evaluate_accuracy`] on views whose samples are already taken (in
/// session order, as [`alacs_calib::view_samples`] gives them).
pub(crate) fn accuracy_from_views(
    per_view: Vec<(Vec<LaserSample>, ViewSamples)>,
    camera: &Camera,
    laser: &LaserModel,
    options: &AccuracyOptions,
) -> Result<AccuracyEvaluation> {
    let prepared = laser.prepare();
    // The evaluated points, and every point of every view: the stripe noise
    // is measured on all of them, whichever are evaluated.
    let mut points = Vec::new();
    let mut all_points = Vec::new();
    let mut views = Vec::with_capacity(per_view.len());
    for (index, (samples, report)) in per_view.into_iter().enumerate() {
        let mut keep = vec![false; samples.len()];
        for i in chosen(samples.len(), options.points) {
            keep[i] = true;
        }
        for (sample, keep) in samples.iter().zip(keep) {
            let normalized = sample.normalized();
            let point_true_in_camera =
                Point3::new(sample.u_n * sample.z_mm, sample.v_n * sample.z_mm, sample.z_mm);
            // A ray that misses the evaluated laser plane has no estimate.
            let Ok(point_estimated_in_camera) = prepared.triangulate(&normalized, sample.slide_mm)
            else {
                continue;
            };
            let depth_error_mm = point_estimated_in_camera.z - point_true_in_camera.z;
            let point = AccuracyPoint {
                view: index,
                slide_mm: sample.slide_mm,
                point_true_in_camera,
                point_estimated_in_camera,
                rejected: options.rejected_beyond_mm.is_some_and(|threshold| {
                    depth_error_mm.abs() > threshold || depth_error_mm.is_nan()
                }),
            };
            all_points.push(point);
            if keep {
                points.push(point);
            }
        }
        views.push(report);
    }
    if points.is_empty() {
        return Err(Error::NoData(format!(
            "no view of the session gave a laser point on the board{}",
            rejection_note(&views)
        )));
    }
    let residuals = within_view_residuals(&all_points, laser, camera.fx_px);
    let measured_sigma_px =
        robust_sigma(&residuals.iter().map(|r| r.1).collect::<Vec<_>>()).unwrap_or(f64::NAN);
    let sigma_px = options.sigma_px.unwrap_or(measured_sigma_px);
    let slides = per_slide(&points, &all_points, &residuals, laser, camera.fx_px, sigma_px);
    Ok(AccuracyEvaluation {
        points,
        rejected_beyond_mm: options.rejected_beyond_mm,
        views,
        slides,
        laser: *laser,
        focal_px: camera.fx_px,
        points_per_view: options.points,
        sigma_px,
        sigma_px_measured: options.sigma_px.is_none(),
        measured_sigma_px,
    })
}

/// 1.4826 times the median absolute deviation from the median; `None` for
/// fewer than two values.
fn robust_sigma(values: &[f64]) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let centre = median(values);
    let deviations: Vec<f64> = values.iter().map(|v| (v - centre).abs()).collect();
    Some(MAD_TO_SIGMA * median(&deviations))
}

/// Per point, its depth error minus its view's median depth error, in mm
/// and scaled to stripe pixels by f L / (z^2 cos(alpha)) (module docs).
fn within_view_residuals(
    points: &[AccuracyPoint],
    laser: &LaserModel,
    focal_px: f64,
) -> Vec<(f64, f64)> {
    let mut view_median = std::collections::HashMap::new();
    for p in points {
        view_median.entry(p.view).or_insert_with(|| {
            let errors: Vec<f64> =
                points.iter().filter(|q| q.view == p.view).map(|q| q.error_mm().z).collect();
            median(&errors)
        });
    }
    points
        .iter()
        .map(|p| {
            let residual_mm = p.error_mm().z - view_median.get(&p.view).copied().unwrap_or(0.0);
            let z_mm = p.point_true_in_camera.z;
            let mm_per_px = noise_floor_mm(
                z_mm,
                laser.alpha_rad,
                1.0,
                focal_px,
                laser.laser_distance_mm(p.slide_mm),
            );
            (residual_mm, residual_mm / mm_per_px)
        })
        .collect()
}

/// Groups the points by slide position and summarizes each group.
fn per_slide(
    points: &[AccuracyPoint],
    all_points: &[AccuracyPoint],
    residuals: &[(f64, f64)],
    laser: &LaserModel,
    focal_px: f64,
    sigma_px: f64,
) -> Vec<SlideAccuracy> {
    let mut slides_mm: Vec<f64> = points.iter().map(|p| p.slide_mm).collect();
    slides_mm.sort_by(f64::total_cmp);
    slides_mm.dedup();
    slides_mm
        .into_iter()
        .filter_map(|slide_mm| {
            let group: Vec<&AccuracyPoint> =
                points.iter().filter(|p| p.slide_mm == slide_mm).collect();
            let in_group: Vec<usize> =
                (0..all_points.len()).filter(|&i| all_points[i].slide_mm == slide_mm).collect();
            let spread = |k: usize| {
                let values: Vec<f64> = in_group
                    .iter()
                    .map(|&i| if k == 0 { residuals[i].0 } else { residuals[i].1 })
                    .collect();
                robust_sigma(&values).unwrap_or(f64::NAN)
            };
            let axis = |a: usize| -> Option<BoxStats> {
                let values: Vec<f64> = group.iter().map(|p| p.error_mm()[a]).collect();
                BoxStats::from_values(&values)
            };
            let depths: Vec<f64> = group.iter().map(|p| p.point_true_in_camera.z).collect();
            let median_depth_mm = median(&depths);
            let laser_distance_mm = laser.laser_distance_mm(slide_mm);
            Some(SlideAccuracy {
                slide_mm,
                laser_distance_mm,
                median_depth_mm,
                predicted_sigma_z_mm: noise_floor_mm(
                    median_depth_mm,
                    laser.alpha_rad,
                    sigma_px,
                    focal_px,
                    laser_distance_mm,
                ),
                within_view_sigma_z_mm: spread(0),
                within_view_sigma_px: spread(1),
                error_mm: [axis(0)?, axis(1)?, axis(2)?],
            })
        })
        .collect()
}

impl AccuracyEvaluation {
    /// How many points lie beyond the fit's threshold
    /// ([`AccuracyOptions::rejected_beyond_mm`]).
    pub fn n_rejected(&self) -> usize {
        self.points.iter().filter(|p| p.rejected).count()
    }

    /// The errors (estimated - true, mm) along `axis` (0 x, 1 y, 2 z) of the
    /// points at `slide_mm`: what one box of the plot shows.
    pub fn errors_at(&self, slide_mm: f64, axis: usize) -> Vec<f64> {
        self.points
            .iter()
            .filter(|p| p.slide_mm == slide_mm)
            .map(|p| p.error_mm()[axis.min(2)])
            .collect()
    }

    /// The summary as JSON: the laser, the noise-floor inputs, per view the
    /// points and the board pose's RMS, and per slide position `n`, the
    /// laser-camera distance, the median depth, the predicted sigma_z and
    /// the box-plot statistics of the x, y and z errors (`x`, `y`, `z`:
    /// n, median, q1, q3, min, max, the whiskers' ends at 1.5 IQR, mean,
    /// rms, all mm); `n_rejected` counts the points beyond
    /// `rejected_beyond_mm` (null where no threshold applies).
    pub fn to_json(&self) -> Value {
        let stats = |s: &BoxStats| {
            json!({
                "n": s.n, "median_mm": s.median, "q1_mm": s.q1, "q3_mm": s.q3,
                "min_mm": s.min, "max_mm": s.max, "mean_mm": s.mean, "rms_mm": s.rms,
                "iqr_mm": s.iqr(), "whisker_low_mm": s.whisker_low,
                "whisker_high_mm": s.whisker_high,
            })
        };
        json!({
            // laser.yaml's keys, from their one owner (it cannot fail).
            "laser": serde_json::to_value(self.laser.to_file()).unwrap_or_default(),
            "points_per_view": self.points_per_view.as_str(),
            "n_points": self.points.len(),
            "n_rejected": self.n_rejected(),
            "rejected_beyond_mm": self.rejected_beyond_mm,
            "noise_floor": {
                "formula": "sigma_z = z^2 cos(alpha) sigma_px / (f L), L = L0 - d, z the median depth",
                "sigma_px": self.sigma_px,
                "sigma_px_source": if self.sigma_px_measured { "measured" } else { "given" },
                "measured_sigma_px": self.measured_sigma_px,
                "focal_px": self.focal_px,
            },
            "views": self.views.iter().enumerate().map(|(i, v)| json!({
                "image": v.image,
                "slide_mm": v.slide_mm,
                "n_points": self.points.iter().filter(|p| p.view == i).count(),
                "board_pose_rms_px": v.pose_rms_px,
                "rejected": v.rejected,
            })).collect::<Vec<_>>(),
            "slides": self.slides.iter().map(|s| json!({
                "slide_mm": s.slide_mm,
                "laser_distance_mm": s.laser_distance_mm,
                "n": s.error_mm[2].n,
                "median_depth_mm": s.median_depth_mm,
                "predicted_sigma_z_mm": s.predicted_sigma_z_mm,
                "within_view_sigma_z_mm": s.within_view_sigma_z_mm,
                "within_view_sigma_px": s.within_view_sigma_px,
                "x": stats(&s.error_mm[0]),
                "y": stats(&s.error_mm[1]),
                "z": stats(&s.error_mm[2]),
            })).collect::<Vec<_>>(),
        })
    }

    /// Every point as CSV: `view,slide_mm,x_true_mm,y_true_mm,z_true_mm,x_error_mm,y_error_mm,z_error_mm,rejected`
    /// (`rejected` 1 where a fit with the threshold rejects the point, else 0).
    pub fn points_csv(&self) -> String {
        let mut out = String::from(
            "view,slide_mm,x_true_mm,y_true_mm,z_true_mm,x_error_mm,y_error_mm,z_error_mm,rejected\n",
        );
        for p in &self.points {
            let t = p.point_true_in_camera;
            let e = p.error_mm();
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                p.view,
                p.slide_mm,
                t.x,
                t.y,
                t.z,
                e.x,
                e.y,
                e.z,
                u8::from(p.rejected)
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn three_points_are_the_centres_of_the_thirds() {
        assert_eq!(chosen(600, PointsPerView::Three), vec![100, 300, 500]);
        assert_eq!(chosen(2, PointsPerView::Three), vec![0, 1]);
        assert_eq!(chosen(4, PointsPerView::All), vec![0, 1, 2, 3]);
    }

    /// Samples on the laser's plane at two slide positions, a little noise,
    /// and one stray stripe sample 192 mm off (a reflection the fit rejected).
    fn views_with_a_stray_sample(laser: &LaserModel) -> Vec<(Vec<LaserSample>, ViewSamples)> {
        [0.0, 100.0]
            .iter()
            .enumerate()
            .map(|(view, &slide_mm)| {
                let mut samples: Vec<LaserSample> = (0..60)
                    .map(|i| {
                        let (u_n, v_n) = (0.02, -0.2 + 0.007 * f64::from(i));
                        let z = laser.triangulate(&Point2::new(u_n, v_n), slide_mm).unwrap().z;
                        let noise = 0.1 * (f64::from(i) * 1.7).sin();
                        LaserSample { u_n, v_n, z_mm: z + noise, slide_mm, pose: Some(view as u32) }
                    })
                    .collect();
                if view == 0 {
                    samples[30].z_mm -= 192.0;
                }
                let report = ViewSamples {
                    image: format!("view{view}.png"),
                    slide_mm,
                    camera_from_board: None,
                    pose_rms_px: Some(0.1),
                    n_samples: samples.len(),
                    n_on_square_edges: 0,
                    rejected: None,
                    observation: None,
                    pixels_px: Vec::new(),
                    pose: Some(view as u32),
                };
                (samples, report)
            })
            .collect()
    }

    #[test]
    fn points_beyond_the_fits_threshold_are_marked() {
        let laser = LaserModel::seed_paper();
        let camera = Camera::blackfly_s_5mp();
        let options =
            AccuracyOptions { rejected_beyond_mm: Some(2.0), ..AccuracyOptions::default() };
        let eval =
            accuracy_from_views(views_with_a_stray_sample(&laser), &camera, &laser, &options)
                .unwrap();
        assert_eq!(eval.points.len(), 120);
        assert_eq!(eval.points.iter().filter(|p| p.rejected).count(), 1);
        // Still in its box, whose quartiles it barely moves.
        let z = &eval.slides[0].error_mm[2];
        assert_eq!(z.n, 60);
        assert!(z.q1 > -0.5 && z.q3 < 0.5 && z.max > 150.0, "{z:?}");
        let json = eval.to_json();
        assert_eq!(json["n_rejected"], 1);
        assert_eq!(json["rejected_beyond_mm"], 2.0);
        let csv = eval.points_csv();
        assert!(csv.lines().next().unwrap().ends_with(",rejected"));
        assert_eq!(csv.lines().filter(|l| l.ends_with(",1")).count(), 1);
        // Without a fit to speak for (a session of its own) none is marked.
        let eval = accuracy_from_views(
            views_with_a_stray_sample(&laser),
            &camera,
            &laser,
            &AccuracyOptions::default(),
        )
        .unwrap();
        assert!(eval.points.iter().all(|p| !p.rejected));
        assert!(eval.to_json()["rejected_beyond_mm"].is_null());
    }

    #[test]
    fn noise_floor_grows_as_the_laser_nears_the_camera() {
        let alpha = 19.07f64.to_radians();
        // z = 900 mm, f = 2320 px, 0.06 px: 0.052 mm at L = 382 mm, 0.110 mm at L = 182 mm.
        let near = noise_floor_mm(900.0, alpha, 0.06, 2320.0, 381.98);
        let far = noise_floor_mm(900.0, alpha, 0.06, 2320.0, 181.98);
        assert!((near - 0.0519).abs() < 1e-3, "{near}");
        assert!((far / near - 381.98 / 181.98).abs() < 1e-12);
    }
}
