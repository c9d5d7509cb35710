//! `alacs report calibration` and `alacs report scan`: self-contained HTML
//! reports (`alacs-eval`'s `html` module); this is the loader around it.

use std::path::{Path, PathBuf};

use alacs::eval::{
    OutputKind, ScanReport, ScanReportFrame, calibration_report, open_output,
    write_calibration_html, write_scan_html,
};
use alacs::locate::{locate_scan_images, priors_of, read_scan_images};
use alacs::{Camera, LaserModel, Scan, Session};
use serde_json::{Value, json};

use crate::args::{ReportCalibrationArgs, ReportScanArgs};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// The report's JSON: the page, every file, and `extra`'s keys.
fn report_json(out: &Path, files: &[PathBuf], extra: Value) -> Value {
    let mut value = json!({
        "html": out.join("index.html").display().to_string(),
        "out": out.display().to_string(),
        "files": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
    });
    if let (Value::Object(map), Value::Object(more)) = (&mut value, extra) {
        map.extend(more);
    }
    value
}

/// Runs `alacs report calibration`.
pub fn calibration(args: &ReportCalibrationArgs) -> CmdResult {
    let session = Session::read(&args.session)?;
    let camera = Camera::from_yaml_file(&args.camera)?;
    let (laser, laser_std) = LaserModel::from_yaml_file_with_std(&args.laser)?;
    let mut out = open_output(&args.out, OutputKind::ReportCalibration, args.folder.force)?;
    let bar = output::progress_bar(args.json, "views");
    output::start_progress(&bar, 2 * session.views.len(), "views: corners, board pose, stripe");
    let report = calibration_report(&session, &camera, &laser, laser_std.as_ref(), &|| bar.inc(1));
    let report = report.map_err(|e| Failure::from(e).with_context(&args.session));
    let report = match report {
        Ok(report) => report,
        Err(failure) => {
            bar.finish_and_clear();
            return Err(failure);
        }
    };
    bar.set_message("writing the page and its images");
    let files =
        write_calibration_html(&mut out, &session, &report, &args.session.display().to_string());
    bar.finish_and_clear();
    let files = files?;
    out.finish()?;
    let flagged: Vec<&str> =
        report.views.iter().filter(|v| v.flag.is_some()).map(|v| v.view.image.as_str()).collect();
    if args.json {
        output::print_json(&report_json(
            &args.out,
            &files,
            json!({
                "views": report.views.len(),
                "flagged": flagged,
                "pose_rms_px": report.pose_rms_px(),
                "mean_abs_error_mm": report.mean_abs_residual_mm(),
            }),
        ))?;
    } else {
        outln!(
            "Calibration report on {} views of {} ({} flagged{}): {}",
            report.views.len(),
            args.session.display(),
            flagged.len(),
            if flagged.is_empty() { String::new() } else { format!(": {}", flagged.join(", ")) },
            args.out.join("index.html").display()
        );
    }
    errln!("{}", output::files_written(&args.out, &files));
    Ok(())
}

/// Runs `alacs report scan`.
pub fn scan(args: &ReportScanArgs) -> CmdResult {
    let scan = Scan::read(&args.scan)?;
    let priors = priors_of(&scan);
    let Some(prior) = priors.get(args.target).copied() else {
        return Err(Failure::bad_input(anyhow::anyhow!(
            "--target {}: {} names {} fruit (from 0)",
            args.target,
            args.scan.join(alacs::model::SCAN_FILE).display(),
            priors.len()
        )));
    };
    let camera = Camera::from_yaml_file(&args.camera)?;
    alacs::locate::check_camera_fits(&scan, &camera)
        .map_err(|e| Failure::from(e).with_context(&args.camera))?;
    let laser = LaserModel::from_yaml_file(&args.laser)?;
    let mut out = open_output(&args.out, OutputKind::ReportScan, args.folder.force)?;
    let bar = output::progress_bar(args.json, "frames");
    output::start_progress(&bar, scan.frames.len(), "frames read");
    let images = read_scan_images(&scan, |_, _| bar.inc(1));
    bar.finish_and_clear();
    let images = images?;
    let options = args.rough_error.locate_options(args.method.method());
    let answer = locate_scan_images(&scan, &images, &prior, &camera, &laser, &options)?;
    let names: Vec<String> = scan.frames.iter().map(|f| f.image.display().to_string()).collect();
    let report_frames: Vec<ScanReportFrame> = names
        .iter()
        .zip(&images)
        .map(|(name, (image, _))| ScanReportFrame { name, image })
        .collect();
    let source = args.scan.display().to_string();
    let files = write_scan_html(
        &mut out,
        &ScanReport {
            source: &source,
            camera: &camera,
            laser: &laser,
            prior: &prior,
            frames: &report_frames,
            localization: &answer,
        },
    )?;
    out.finish()?;
    if args.json {
        output::print_json(&report_json(
            &args.out,
            &files,
            json!({ "localization": output::localization_json(&answer) }),
        ))?;
    } else {
        output::print_text(&output::localization_summary(&answer))?;
        outln!("Scan report: {}", args.out.join("index.html").display());
    }
    errln!("{}", output::files_written(&args.out, &files));
    Ok(())
}
