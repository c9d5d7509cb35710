//! `alacs evaluate calibration` and `alacs evaluate accuracy`: the seed
//! paper's experiments as reports (crate `alacs-eval`).

use alacs::calib::{
    CalibrationOptions, LaserSessionOptions, calibrate_camera_session, calibrate_laser_session,
    read_samples_csv,
};
use alacs::eval::{
    AccuracyOptions, OutputKind, PointsPerView, evaluate_accuracy, evaluate_calibration,
    open_output, write_accuracy_report, write_calibration_report,
};
use alacs::{Camera, LaserModel, LaserSample, Session};
use anyhow::anyhow;
use serde_json::{Value, json};

use crate::args::{EvaluateAccuracyArgs, EvaluateCalibrationArgs, PointsArg};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// The dense samples of a session: with `camera`, or with a camera
/// calibrated from the session's own board views.
fn session_samples(
    args: &EvaluateCalibrationArgs,
    dir: &std::path::Path,
) -> CmdResult<Vec<LaserSample>> {
    let session = Session::read(dir)?;
    let camera = match &args.camera {
        Some(_) if args.controls.any() => {
            return Err(Failure::bad_input(anyhow!(
                "--distortion, --fix and --initial control the camera calibration that --camera replaces: give one or the other"
            )));
        }
        Some(path) => Camera::from_yaml_file(path)?,
        None => {
            let options = crate::cmd::calibrate::intrinsics_options(&args.controls)?;
            let bar = output::progress_bar(args.json, "board corners");
            output::start_progress(&bar, session.views.len(), "views: board corners (camera)");
            let fit = calibrate_camera_session(&session, &options, &|| bar.inc(1));
            bar.finish_and_clear();
            let fit = fit.map_err(|e| Failure::from(e).with_context(dir))?;
            errln!(
                "note: no --camera: calibrated the camera from the session's board views ({:.3} px RMS, {} views)",
                fit.rms_px,
                fit.views_used()
            );
            fit.camera
        }
    };
    let bar = output::progress_bar(args.json, "laser samples");
    output::start_progress(&bar, session.views.len(), "views: board pose and laser stripe");
    let result =
        calibrate_laser_session(&session, &camera, &LaserSessionOptions::default(), &|| bar.inc(1));
    bar.finish_and_clear();
    let result = result.map_err(|e| Failure::from(e).with_context(dir))?;
    for view in &result.views {
        if let Some(reason) = &view.rejected {
            errln!("warning: {}: not used: {reason}", view.image);
        }
    }
    Ok(result.samples)
}

/// Runs `alacs evaluate calibration`.
pub fn calibration(args: &EvaluateCalibrationArgs) -> CmdResult {
    if !(args.threshold_mm > 0.0 && args.threshold_mm.is_finite()) {
        return Err(Failure::bad_input(anyhow!(
            "--threshold-mm must be a positive number of mm, got {}",
            args.threshold_mm
        )));
    }
    if args.samples.is_some() && args.controls.any() {
        return Err(Failure::bad_input(anyhow!(
            "--distortion, --fix and --initial control the camera calibration of --session; --samples has no camera to calibrate"
        )));
    }
    let (samples, source) = match (&args.samples, &args.session) {
        (Some(path), _) => (read_samples_csv(path)?, path.clone()),
        (None, Some(dir)) => (session_samples(args, dir)?, dir.clone()),
        (None, None) => {
            return Err(Failure::bad_input(anyhow!("give --samples FILE or --session DIR")));
        }
    };
    let mut out = open_output(&args.out, OutputKind::EvaluateCalibration, args.folder.force)?;
    let options = CalibrationOptions {
        threshold_mm: args.threshold_mm,
        seed: args.seed,
        ..CalibrationOptions::default()
    };
    let eval = evaluate_calibration(&samples, &options)
        .map_err(|e| Failure::from(e).with_context(&source))?;
    let files = write_calibration_report(&mut out, &eval)?;
    out.finish()?;
    if args.json {
        let mut value = eval.to_json();
        if let Value::Object(map) = &mut value {
            map.insert("source".into(), json!(source.display().to_string()));
            map.insert("out".into(), json!(args.out.display().to_string()));
            map.insert("files".into(), json!(paths(&files)));
        }
        output::print_json(&value)?;
    } else {
        outln!(
            "Calibration (the seed paper's Table 1) on {} samples from {}:",
            samples.len(),
            source.display()
        );
        out!("{}", eval.table_1());
        outln!("\nDepth residuals z - z_hat of the fitted samples (mm):");
        outln!("{:<10} {:>8} {:>8} {:>8} {:>8} {:>8}", "", "median", "IQR", "min", "max", "RMS");
        for method in &eval.methods {
            if let Some(s) = method.inlier_stats() {
                outln!(
                    "{:<10} {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
                    format!("Method {}", method.calibration.method.number()),
                    s.median,
                    s.iqr(),
                    s.min,
                    s.max,
                    s.rms
                );
            }
        }
    }
    errln!("{}", output::files_written(&args.out, &files));
    Ok(())
}

/// The paths as strings.
fn paths(files: &[std::path::PathBuf]) -> Vec<String> {
    files.iter().map(|f| f.display().to_string()).collect()
}

/// Runs `alacs evaluate accuracy`.
pub fn accuracy(args: &EvaluateAccuracyArgs) -> CmdResult {
    let session = Session::read(&args.session)?;
    let camera = Camera::from_yaml_file(&args.camera)?;
    let laser = LaserModel::from_yaml_file(&args.laser)?;
    let mut out = open_output(&args.out, OutputKind::EvaluateAccuracy, args.folder.force)?;
    let options = AccuracyOptions {
        points: match args.points {
            PointsArg::All => PointsPerView::All,
            PointsArg::Three => PointsPerView::Three,
        },
        sigma_px: args.sigma_px,
        ..AccuracyOptions::default()
    };
    let bar = output::progress_bar(args.json, "accuracy");
    output::start_progress(&bar, session.views.len(), "views: board pose and laser stripe");
    let eval = evaluate_accuracy(&session, &camera, &laser, &options, &|| bar.inc(1));
    bar.finish_and_clear();
    let eval = eval.map_err(|e| Failure::from(e).with_context(&args.session))?;
    for view in &eval.views {
        if let Some(reason) = &view.rejected {
            errln!("warning: {}: not used: {reason}", view.image);
        }
    }
    let files = write_accuracy_report(&mut out, &eval)?;
    out.finish()?;
    if args.json {
        let mut value = eval.to_json();
        if let Value::Object(map) = &mut value {
            map.insert("session".into(), json!(args.session.display().to_string()));
            map.insert("out".into(), json!(args.out.display().to_string()));
            map.insert("files".into(), json!(paths(&files)));
        }
        output::print_json(&value)?;
    } else {
        let used = eval.views.iter().filter(|v| v.n_samples > 0).count();
        outln!(
            "Accuracy of {} on {} of {} views of {} ({} points, {} per view):",
            args.laser.display(),
            used,
            eval.views.len(),
            args.session.display(),
            eval.points.len(),
            eval.points_per_view.as_str()
        );
        out!("{}", output::accuracy_table(&eval));
    }
    errln!("{}", output::files_written(&args.out, &files));
    Ok(())
}
