//! Writing an evaluation's artefacts into a folder: text, JSON, CSV and
//! plots (PNG and SVG), each file written atomically through an
//! [`OutputDir`] (see [`crate::open_output`]: a folder belongs to one
//! command, which replaces its own earlier files). The names:
//!
//! | file | what |
//! |---|---|
//! | `calibration_table1.txt` | the seed paper's Table 1 |
//! | `calibration.json` | [`CalibrationEvaluation::to_json`] |
//! | `calibration_residuals_method{1..4}.png`, `.svg` | z - z_hat against z per method |
//! | `accuracy.json` | [`AccuracyEvaluation::to_json`] |
//! | `accuracy_points.csv` | every point's truth and error |
//! | `accuracy_boxplots.png`, `.svg` | x, y, z errors per slide position |

use std::path::PathBuf;

use alacs_model::io::OutputDir;

use crate::plot::{write_accuracy_boxplots, write_residual_plot};
use crate::{AccuracyEvaluation, CalibrationEvaluation, Result};

/// Writes the calibration evaluation's Table 1, JSON and residual plots
/// into `out`; returns the files written.
pub fn write_calibration_report(
    out: &mut OutputDir,
    eval: &CalibrationEvaluation,
) -> Result<Vec<PathBuf>> {
    let mut files = vec![
        out.write("calibration_table1.txt", eval.table_1())?,
        out.write("calibration.json", format!("{:#}\n", eval.to_json()))?,
    ];
    let depths_mm: Vec<f64> = eval.samples.iter().map(|s| s.z_mm).collect();
    let slides_mm: Vec<f64> = eval.samples.iter().map(|s| s.slide_mm).collect();
    for method in &eval.methods {
        let stem = format!("calibration_residuals_method{}", method.calibration.method.number());
        files.extend(write_residual_plot(out, &stem, method, &depths_mm, &slides_mm)?);
    }
    Ok(files)
}

/// Writes the accuracy evaluation's JSON, points CSV and box plots into
/// `out`; returns the files written.
pub fn write_accuracy_report(
    out: &mut OutputDir,
    eval: &AccuracyEvaluation,
) -> Result<Vec<PathBuf>> {
    let mut files = vec![
        out.write("accuracy.json", format!("{:#}\n", eval.to_json()))?,
        out.write("accuracy_points.csv", eval.points_csv())?,
    ];
    files.extend(write_accuracy_boxplots(out, "accuracy_boxplots", eval)?);
    Ok(files)
}
