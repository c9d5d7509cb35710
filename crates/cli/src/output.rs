//! What commands print: FORMATS.md's JSON objects and readable tables.

use std::fmt::Write as _;

use indicatif::{ProgressBar, ProgressStyle};

use alacs::LaserCalibration;
use alacs::model::Fidelity;
use serde_json::{Value, json};

/// One calibration as FORMATS.md's `calibrate laser --json` object, with
/// `method`, `name` and the fit's statistics added.
pub fn calibration_json(c: &LaserCalibration) -> Value {
    json!({
        "model": c.laser.fidelity.as_str(),
        "alpha_deg": c.laser.alpha_deg(),
        "beta_deg": c.laser.beta_deg(),
        "l0_mm": c.laser.l0_mm,
        "inliers": c.inliers,
        "mean_abs_error_mm": c.mean_abs_error_mm,
        "mean_abs_error_all_mm": c.mean_abs_error_all_mm,
        "n_samples": c.n_samples,
        "method": c.method.number(),
        "name": c.method.name(),
        "rms_error_mm": c.rms_error_mm,
        "residual": c.residual.as_str(),
        "ransac_iterations": c.ransac_iterations,
        "std_dev": c.std_dev.map(|s| json!({
            "alpha_deg": s.alpha_deg,
            "l0_mm": s.l0_mm,
            "beta_deg": s.beta_deg,
        })),
    })
}

/// Prints `value` as the one JSON object on standard output.
pub fn print_json(value: &Value) {
    println!("{value}");
}

/// The seed paper's Table 1 for `results`.
pub fn table_1(results: &[LaserCalibration]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<44} {:>11} {:>9} {:>10} {:>15} {:>9}",
        "", "alpha (deg)", "L0 (mm)", "beta (deg)", "Mean error (mm)", "inliers"
    );
    for c in results {
        let beta = match c.laser.fidelity {
            Fidelity::Low => "/".to_string(),
            Fidelity::High => format!("{:.2}", c.laser.beta_deg()),
        };
        let _ = writeln!(
            out,
            "{:<44} {:>11.2} {:>9.2} {:>10} {:>15.2} {:>9}",
            format!("Method {} ({})", c.method.number(), c.method.name()),
            c.laser.alpha_deg(),
            c.laser.l0_mm,
            beta,
            c.mean_abs_error_mm,
            format!("{}/{}", c.inliers.len(), c.n_samples)
        );
    }
    out
}

/// A readable summary of one calibration, with standard deviations.
pub fn summary(c: &LaserCalibration, threshold_mm: f64) -> String {
    let mut out = String::new();
    let _ =
        write!(out, "Method {} ({}): {} samples", c.method.number(), c.method.name(), c.n_samples);
    match c.ransac_iterations {
        Some(k) => {
            let _ = writeln!(
                out,
                ", {} inliers within {threshold_mm} mm ({k} RANSAC hypotheses)",
                c.inliers.len()
            );
        }
        None => out.push('\n'),
    }
    let std = c.std_dev;
    let pm = |v: Option<f64>, digits: usize| match v {
        Some(s) => format!("  +- {s:.digits$}"),
        None => String::new(),
    };
    let _ = writeln!(
        out,
        "  alpha = {:>9.4} deg{}",
        c.laser.alpha_deg(),
        pm(std.map(|s| s.alpha_deg), 4)
    );
    let _ = writeln!(out, "  L0    = {:>9.3} mm {}", c.laser.l0_mm, pm(std.map(|s| s.l0_mm), 3));
    if c.laser.fidelity == Fidelity::High {
        let _ = writeln!(
            out,
            "  beta  = {:>9.4} deg{}",
            c.laser.beta_deg(),
            pm(std.and_then(|s| s.beta_deg), 4)
        );
    }
    let _ = writeln!(
        out,
        "  mean |z - z_hat| = {:.3} mm over the fitted samples, {:.3} mm over all ({} residual)",
        c.mean_abs_error_mm,
        c.mean_abs_error_all_mm,
        c.residual.as_str()
    );
    out
}

/// A progress bar on standard error (hidden under `--json`, so standard
/// output holds only the JSON), spinning with `message` until its length is known.
pub fn progress_bar(json: bool, message: &'static str) -> ProgressBar {
    let bar = if json { ProgressBar::hidden() } else { ProgressBar::new_spinner() };
    bar.set_message(message);
    bar
}

/// Turns a spinner into a bar of `len` steps, showing `message`.
pub fn start_progress(bar: &ProgressBar, len: usize, message: &'static str) {
    bar.set_length(len as u64);
    if let Ok(style) = ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message);
}

/// `[x, y, z]` of a point, mm.
fn point_json(p: &nalgebra::Point3<f64>) -> Value {
    json!([p.x, p.y, p.z])
}

/// A localization as FORMATS.md's `localize --json` object: `position_mm`
/// and `radius_mm` (null when not found), `candidates` (one per frame that
/// gave one), `selected` (index into `candidates` of the holistic answer;
/// null for the fused answer, which no single frame gives), `status`,
/// `reason`; plus `method`, `holistic`, the fused fit and the search radius.
pub fn localization_json(l: &alacs::locate::Localization) -> Value {
    let candidates: Vec<Value> = l
        .candidates
        .iter()
        .map(|c| {
            json!({
                "frame": c.frame,
                "slide_mm": c.slide_mm,
                "position_mm": point_json(&c.position_mm),
                "n_points": c.n_points,
                "score": c.score,
                "circle_radius_mm": c.circle_radius_mm,
                "continuity": c.continuity,
                "fit_rms_mm": c.fit_rms_mm,
            })
        })
        .collect();
    json!({
        "position_mm": l.position_mm.as_ref().map(point_json),
        "radius_mm": l.radius_mm,
        "candidates": candidates,
        "selected": l.selected,
        "status": l.status.as_str(),
        "reason": l.reason,
        "method": l.method.as_str(),
        "holistic": l.holistic,
        "fused": l.fused.as_ref().map(|f| json!({
            "position_mm": point_json(&f.sphere.centre),
            "radius_mm": f.sphere.radius_mm,
            "n_points": f.n_points,
            "n_frames": f.n_frames,
            "rms_mm": f.rms_mm,
        })),
        "fused_rejected": l.fused_rejected,
        "search_radius_mm": l.search_radius_mm,
    })
}
