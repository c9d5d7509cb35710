//! Writing an evaluation's artefacts into a folder: text, JSON, CSV and
//! plots (PNG and SVG). Names are fixed so that a calibration and an
//! accuracy evaluation can share one folder:
//!
//! | file | what |
//! |---|---|
//! | `calibration_table1.txt` | the seed paper's Table 1 |
//! | `calibration.json` | [`CalibrationEvaluation::to_json`] |
//! | `calibration_residuals_method{1..4}.png`, `.svg` | z - z_hat against z per method |
//! | `accuracy.json` | [`AccuracyEvaluation::to_json`] |
//! | `accuracy_points.csv` | every point's truth and error |
//! | `accuracy_boxplots.png`, `.svg` | x, y, z errors per slide position |

use std::path::{Path, PathBuf};

use crate::plot::{write_accuracy_boxplots, write_residual_plot};
use crate::{AccuracyEvaluation, CalibrationEvaluation, Error, Result};

/// Creates `dir` (and its parents).
fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|error| Error::Io { path: dir.to_path_buf(), error })
}

/// Writes `contents` to `dir`/`name`, returning the path.
fn write_file(dir: &Path, name: &str, contents: &str) -> Result<PathBuf> {
    let path = dir.join(name);
    std::fs::write(&path, contents).map_err(|error| Error::Io { path: path.clone(), error })?;
    Ok(path)
}

/// Writes the calibration evaluation's Table 1, JSON and residual plots into
/// `dir` (created); returns the files written.
pub fn write_calibration_report(dir: &Path, eval: &CalibrationEvaluation) -> Result<Vec<PathBuf>> {
    create_dir(dir)?;
    let mut files = vec![
        write_file(dir, "calibration_table1.txt", &eval.table_1())?,
        write_file(dir, "calibration.json", &format!("{:#}\n", eval.to_json()))?,
    ];
    let depths_mm: Vec<f64> = eval.samples.iter().map(|s| s.z_mm).collect();
    for method in &eval.methods {
        let stem =
            dir.join(format!("calibration_residuals_method{}", method.calibration.method.number()));
        files.extend(write_residual_plot(&stem, method, &depths_mm)?);
    }
    Ok(files)
}

/// Writes the accuracy evaluation's JSON, points CSV and box plots into
/// `dir` (created); returns the files written.
pub fn write_accuracy_report(dir: &Path, eval: &AccuracyEvaluation) -> Result<Vec<PathBuf>> {
    create_dir(dir)?;
    let mut files = vec![
        write_file(dir, "accuracy.json", &format!("{:#}\n", eval.to_json()))?,
        write_file(dir, "accuracy_points.csv", &eval.points_csv())?,
    ];
    files.extend(write_accuracy_boxplots(&dir.join("accuracy_boxplots"), eval)?);
    Ok(files)
}
