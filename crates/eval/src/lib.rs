//! Evaluation of ALACS calibrations, the seed paper's experiments as reports
//! a user can read:
//!
//! - [`evaluate_calibration`]: Table 1 (Section 4.1), the four methods of
//!   `alacs-calib` on one set of samples with every sample's depth residual
//!   z - z_hat (eq. (9)) and whether the method kept it;
//! - [`evaluate_accuracy`]: the localization experiment (Section 4.2), board
//!   views at several slide positions d, each laser pixel's triangulation
//!   (eqs. (7)-(8)) against its ray on the board plane, with the errors in
//!   x, y and z per slide position as box-plot statistics ([`BoxStats`]:
//!   median, quartiles, whiskers at 1.5 IQR and the values beyond them)
//!   and the predicted noise floor sigma_z = z^2 cos(alpha) sigma_px / (f L);
//! - [`write_calibration_report`], [`write_accuracy_report`]: text, JSON,
//!   CSV and plots (PNG and SVG, plotters with a built-in font), written
//!   atomically into a folder [`open_output`] opened for one command;
//! - [`html`]: self-contained HTML reports of a calibration (per-view
//!   images with the corners and the stripe drawn over them) and of a scan
//!   (frames with the stripe, the fruit points and the candidate).
//!
//! # Conventions
//! Camera frame as OpenCV's (x right, y down, z forward); errors are
//! estimated minus true, in millimetres; radians inside, degrees in files.
//!
//! # Example
//! ```
//! use alacs_eval::BoxStats;
//!
//! let s = BoxStats::from_values(&[0.3, -0.1, 0.2, 0.0, 5.0]).unwrap();
//! assert_eq!((s.min, s.median, s.max), (-0.1, 0.2, 5.0));
//! // Whiskers stop within 1.5 IQR of the quartiles: 5.0 is an outlier point.
//! assert_eq!((s.whisker_low, s.whisker_high), (-0.1, 0.3));
//! assert!(s.is_outlier(5.0));
//! assert!((s.q1 - 0.0).abs() < 1e-12 && (s.q3 - 0.3).abs() < 1e-12);
//! ```

mod accuracy;
mod calibration;
mod error;
pub mod html;
mod output;
mod plot;
mod report;
mod stats;

pub use accuracy::{
    AccuracyEvaluation, AccuracyOptions, AccuracyPoint, PointsPerView, SlideAccuracy,
    evaluate_accuracy, noise_floor_mm,
};
pub use calibration::{
    CalibrationEvaluation, MethodEvaluation, evaluate_calibration, failed_json, table_1,
};
pub use error::{Error, Result};
pub use html::{
    CalibrationReport, ScanReport, ScanReportFrame, calibration_report,
    calibration_report_from_views, write_calibration_html, write_scan_html,
};
pub use output::{OutputKind, open_output, open_sub_output};
pub use plot::{ViewDiagnostics, write_accuracy_boxplots, write_residual_plot, write_view_plots};
pub use report::{write_accuracy_report, write_calibration_report};
pub use stats::{BoxStats, WHISKER_IQRS, median, quantile_sorted};
