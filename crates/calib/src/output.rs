//! A calibration as the `calibrate laser --json` object (docs/FORMATS.md):
//! [`CalibrationOutput`], built by [`LaserCalibration::to_output`].

use serde::{Deserialize, Serialize};

use crate::LaserCalibration;

/// One calibration as the `calibrate laser --json` object: the laser
/// (`model`, `alpha_deg`, `beta_deg`, `l0_mm`, `slide_scale`) with one standard deviation
/// of each (`*_std_*`, and how they were estimated: `std_source`), the
/// fit's `inliers` and statistics, and the paper's `method` number and `name`. Keys in
/// alphabetical order, as the CLI has always printed them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationOutput {
    /// alpha, degrees.
    pub alpha_deg: f64,
    /// One standard deviation of alpha, degrees (`null` where undefined).
    pub alpha_std_deg: Option<f64>,
    /// beta, degrees (0 for the low-fidelity model).
    pub beta_deg: f64,
    /// One standard deviation of beta, degrees (`null` for the low-fidelity
    /// model or where undefined).
    pub beta_std_deg: Option<f64>,
    /// 0-based indices of the samples the final fit used.
    pub inliers: Vec<usize>,
    /// L0, mm.
    pub l0_mm: f64,
    /// One standard deviation of L0, mm (`null` where undefined).
    pub l0_std_mm: Option<f64>,
    /// Mean |z - z_hat| over all samples, mm.
    pub mean_abs_error_all_mm: f64,
    /// Mean |z - z_hat| over the inliers, mm (the paper's Table 1 metric).
    pub mean_abs_error_mm: f64,
    /// The paper's method number, 1 to 4.
    pub method: u8,
    /// `low` or `high`.
    pub model: String,
    /// Number of samples given.
    pub n_samples: usize,
    /// The paper's name of the method.
    pub name: String,
    /// Hypotheses RANSAC drew (`null` for methods 1 and 3).
    pub ransac_iterations: Option<usize>,
    /// What the least-squares step minimized: `depth` or `plane`.
    pub residual: String,
    /// RMS of z - z_hat over the inliers, mm.
    pub rms_error_mm: f64,
    /// The slide scale k of L = L0 - k d (1 where it was not fitted).
    pub slide_scale: f64,
    /// Whether k was fitted (two or more slide positions, not held by
    /// `--hold-slide-scale`).
    pub slide_scale_fitted: bool,
    /// One standard deviation of k (`null` where k was not fitted or undefined).
    pub slide_scale_std: Option<f64>,
    /// How the standard deviations were estimated (`null` where undefined).
    pub std_source: Option<String>,
    /// The inlier threshold the fit ended with, mm.
    pub threshold_mm: f64,
}

impl LaserCalibration {
    /// The calibration as the `calibrate laser --json` object.
    pub fn to_output(&self) -> CalibrationOutput {
        CalibrationOutput {
            alpha_deg: self.laser.alpha_deg(),
            alpha_std_deg: self.std_dev.map(|s| s.alpha_deg),
            beta_deg: self.laser.beta_deg(),
            beta_std_deg: self.std_dev.and_then(|s| s.beta_deg),
            inliers: self.inliers.clone(),
            l0_mm: self.laser.l0_mm,
            l0_std_mm: self.std_dev.map(|s| s.l0_mm),
            mean_abs_error_all_mm: self.mean_abs_error_all_mm,
            mean_abs_error_mm: self.mean_abs_error_mm,
            method: self.method.number(),
            model: self.laser.fidelity.as_str().to_owned(),
            n_samples: self.n_samples,
            name: self.method.name().to_owned(),
            ransac_iterations: self.ransac_iterations,
            residual: self.residual.as_str().to_owned(),
            rms_error_mm: self.rms_error_mm,
            slide_scale: self.laser.slide_scale,
            slide_scale_fitted: self.slide_scale_fitted,
            slide_scale_std: self.std_dev.and_then(|s| s.slide_scale),
            std_source: self.std_dev.map(|s| s.source.describe()),
            threshold_mm: self.threshold_mm,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use crate::{CalibrationOptions, LaserSample, Method, calibrate};
    use alacs_model::{Fidelity, LaserModel};
    use nalgebra::Point2;

    #[test]
    fn the_output_has_the_calibrate_laser_json_keys_and_reads_back() {
        let truth = LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98);
        let samples: Vec<LaserSample> = (0..30)
            .map(|i| {
                let (u_n, v_n) = (-0.3 + 0.02 * f64::from(i), -0.4 + 0.8 * f64::from(i % 6) / 5.0);
                let z_mm = truth.depth_mm(&Point2::new(u_n, v_n), 0.0).unwrap();
                LaserSample { u_n, v_n, z_mm, slide_mm: 0.0, pose: None }
            })
            .collect();
        let fit = calibrate(&samples, Method::HighFidelityRansac, &CalibrationOptions::default())
            .unwrap();
        let value = serde_json::to_value(fit.to_output()).unwrap();
        let keys: Vec<&str> = value.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(
            keys,
            [
                "alpha_deg",
                "alpha_std_deg",
                "beta_deg",
                "beta_std_deg",
                "inliers",
                "l0_mm",
                "l0_std_mm",
                "mean_abs_error_all_mm",
                "mean_abs_error_mm",
                "method",
                "model",
                "n_samples",
                "name",
                "ransac_iterations",
                "residual",
                "rms_error_mm",
                "slide_scale",
                "slide_scale_fitted",
                "slide_scale_std",
                "std_source",
                "threshold_mm"
            ]
        );
        assert_eq!(value["method"], 4);
        assert_eq!(value["model"], "high-fidelity");
        assert_eq!(value["inliers"].as_array().unwrap().len(), 30);
        let back: super::CalibrationOutput = serde_json::from_value(value).unwrap();
        assert_eq!(back, fit.to_output());
    }
}
