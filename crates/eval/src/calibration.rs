//! The seed paper's calibration evaluation (Section 4.1, Table 1): the four
//! methods on one set of samples, each with its depth residuals
//! z - z_hat (eq. (9)) per sample and which samples it kept.
//!
//! The calibrations themselves are `alacs-calib`'s ([`alacs_calib::compare`]);
//! this module only measures and reports them.

use std::fmt::Write as _;

use alacs_calib::{
    CalibrationOptions, LaserCalibration, LaserSample, Method, compare, depth_error_mm,
};
use alacs_model::Fidelity;
use serde_json::{Value, json};

use crate::{BoxStats, Result};

/// One method of Table 1 with its residuals.
#[derive(Debug, Clone)]
pub struct MethodEvaluation {
    /// The calibration.
    pub calibration: LaserCalibration,
    /// z - z_hat of every sample (eq. (9)), mm, in sample order.
    pub residuals_mm: Vec<f64>,
    /// Whether each sample is one the final fit used (an inlier).
    pub is_inlier: Vec<bool>,
}

impl MethodEvaluation {
    /// The statistics of the residuals of the fitted samples (the inliers).
    pub fn inlier_stats(&self) -> Option<BoxStats> {
        let inliers: Vec<f64> = self
            .residuals_mm
            .iter()
            .zip(&self.is_inlier)
            .filter(|(_, inlier)| **inlier)
            .map(|(r, _)| *r)
            .collect();
        BoxStats::from_values(&inliers)
    }
}

/// The four methods of Table 1 on one set of samples.
#[derive(Debug, Clone)]
pub struct CalibrationEvaluation {
    /// The samples, in input order.
    pub samples: Vec<LaserSample>,
    /// The methods that fitted, in the paper's order.
    pub methods: Vec<MethodEvaluation>,
    /// The methods that could not fit the samples, with the reason.
    pub failed: Vec<(Method, String)>,
    /// The options every method ran with.
    pub options: CalibrationOptions,
}

/// Runs the paper's four methods on `samples` and measures every sample's
/// depth residual under each.
pub fn evaluate_calibration(
    samples: &[LaserSample],
    options: &CalibrationOptions,
) -> Result<CalibrationEvaluation> {
    let comparison = compare(samples, options)?;
    let methods = comparison
        .fitted
        .into_iter()
        .map(|calibration| {
            let residuals_mm =
                samples.iter().map(|s| depth_error_mm(&calibration.laser, s)).collect();
            let mut is_inlier = vec![false; samples.len()];
            for &i in &calibration.inliers {
                if let Some(flag) = is_inlier.get_mut(i) {
                    *flag = true;
                }
            }
            MethodEvaluation { calibration, residuals_mm, is_inlier }
        })
        .collect();
    Ok(CalibrationEvaluation {
        samples: samples.to_vec(),
        methods,
        failed: comparison.failed,
        options: *options,
    })
}

/// The methods that could not fit, as FORMATS.md's `failed` list:
/// `{"method": 1, "name": "...", "reason": "..."}` each.
pub fn failed_json(failed: &[(Method, String)]) -> Value {
    Value::Array(
        failed
            .iter()
            .map(|(m, reason)| json!({"method": m.number(), "name": m.name(), "reason": reason}))
            .collect(),
    )
}

/// One calibration as FORMATS.md's `calibrate laser --json` object
/// (alacs-calib's [`alacs_calib::CalibrationOutput`]).
fn calibration_json(c: &LaserCalibration) -> Value {
    serde_json::to_value(c.to_output()).unwrap_or(Value::Null)
}

/// The seed paper's Table 1 for `results`, as text, with a row saying why
/// for each method in `failed`; with a column for the slide scale k where
/// a method fitted it (samples from several slide positions).
pub fn table_1(results: &[LaserCalibration], failed: &[(Method, String)]) -> String {
    let with_k = results.iter().any(|c| c.slide_scale_fitted);
    let mut out = String::new();
    let _ = write!(
        out,
        "{:<44} {:>11} {:>9} {:>10} {:>15} {:>9}",
        "", "alpha (deg)", "L0 (mm)", "beta (deg)", "Mean error (mm)", "inliers"
    );
    out.push_str(if with_k { "   slide scale k\n" } else { "\n" });
    for method in Method::ALL {
        let name = format!("Method {} ({})", method.number(), method.name());
        if let Some(c) = results.iter().find(|c| c.method == method) {
            let beta = match c.laser.fidelity {
                Fidelity::Low => "/".to_string(),
                Fidelity::High => format!("{:.2}", c.laser.beta_deg()),
            };
            let _ = write!(
                out,
                "{name:<44} {:>11.2} {:>9.2} {beta:>10} {:>15.2} {:>9}",
                c.laser.alpha_deg(),
                c.laser.l0_mm,
                c.mean_abs_error_mm,
                format!("{}/{}", c.inliers.len(), c.n_samples)
            );
            if with_k {
                let _ = write!(out, " {:>17.5}", c.laser.slide_scale);
            }
            out.push('\n');
        } else if let Some((_, reason)) = failed.iter().find(|(m, _)| *m == method) {
            let _ = writeln!(out, "{name:<44} cannot fit: {reason}");
        }
    }
    out
}

impl CalibrationEvaluation {
    /// The calibrations, in the paper's order.
    pub fn calibrations(&self) -> Vec<LaserCalibration> {
        self.methods.iter().map(|m| m.calibration.clone()).collect()
    }

    /// Table 1 as text, a row with the reason for each method that failed.
    pub fn table_1(&self) -> String {
        table_1(&self.calibrations(), &self.failed)
    }

    /// The evaluation as JSON: `{"methods": [...]}` as `calibrate laser
    /// --compare --json` prints it, each method with the statistics of its
    /// inliers' residuals (`residual_stats_mm`: n, median, q1, q3, min, max,
    /// mean, rms), and `n_samples`, `threshold_mm`.
    pub fn to_json(&self) -> Value {
        json!({
            "n_samples": self.samples.len(),
            "threshold_mm": self.options.threshold_mm,
            "methods": self.methods.iter().map(|m| {
                let mut value = calibration_json(&m.calibration);
                if let Value::Object(map) = &mut value {
                    map.insert("residual_stats_mm".into(), json!(m.inlier_stats()));
                }
                value
            }).collect::<Vec<_>>(),
            "failed": failed_json(&self.failed),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alacs_model::LaserModel;
    use nalgebra::Point2;

    #[test]
    fn residuals_are_depth_errors_and_inliers_are_flagged() {
        let truth = LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98);
        let mut samples = Vec::new();
        for i in 0..40 {
            let v_n = -0.4 + 0.8 * f64::from(i % 8) / 7.0;
            let u_n = -0.3 + 0.015 * f64::from(i);
            let mut z_mm = truth.depth_mm(&Point2::new(u_n, v_n), 0.0).unwrap();
            if i % 10 == 3 {
                z_mm += 30.0; // a gross outlier
            }
            samples.push(LaserSample { u_n, v_n, z_mm, slide_mm: 0.0, pose: None });
        }
        let eval = evaluate_calibration(&samples, &CalibrationOptions::default()).unwrap();
        assert_eq!(eval.methods.len(), 4);
        let method4 = &eval.methods[3];
        for (i, (&r, &inlier)) in method4.residuals_mm.iter().zip(&method4.is_inlier).enumerate() {
            assert_eq!(inlier, i % 10 != 3, "sample {i}");
            if inlier {
                assert!(r.abs() < 1e-6, "sample {i}: {r}");
            } else {
                assert!((r - 30.0).abs() < 1e-6, "sample {i}: {r}");
            }
        }
        let json = eval.to_json();
        assert_eq!(json["methods"][3]["method"], 4);
        assert_eq!(json["methods"][3]["residual_stats_mm"]["n"], 36);
        assert!(eval.table_1().contains("Method 4 (High-fidelity model + RANSAC)"));
    }
}
