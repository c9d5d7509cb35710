//! `alacs demo`: the main job on the built-in simulator.
//!
//! 1. Simulates the seed paper's calibration experiment (10 board poses at
//!    0.6-1.2 m, 3 laser points each, 0.5 mm depth noise) with 30 % gross
//!    outliers, and calibrates with all four methods (Table 1).
//! 2. Repeats the paper's accuracy experiment: points on boards at 0.6-1.2 m
//!    with the laser at d = 0, 50, ..., 200 mm, triangulated with the Method 4
//!    calibration and compared with the truth in x, y and z.
//! 3. From images: renders a calibration session, calibrates camera and laser
//!    from it, repeats the accuracy experiment on a second rendered session
//!    (10 board poses x d = 0-200 mm, every stripe point), and locates
//!    simulated fruit with that calibration.
//!
//! It writes the evaluation artefacts (Table 1 with residual plots, the
//! accuracy box plots and their JSON; `alacs-eval`) into `--out`, and two
//! HTML reports: the calibration against its rendered session
//! (`report_calibration/index.html`) and the first sunlit, 40 %-hidden scan
//! (`report_scan/index.html`).

use alacs::Session;
use alacs::calib::{
    IntrinsicsOptions, LaserSessionOptions, calibrate_camera_session, calibrate_laser_session,
};
use alacs::eval::{
    AccuracyEvaluation, AccuracyOptions, OutputKind, ScanReport, ScanReportFrame,
    calibration_report_from_views, evaluate_accuracy, evaluate_calibration, open_output,
    open_sub_output, write_accuracy_report, write_calibration_html, write_calibration_report,
    write_scan_html,
};
use alacs::locate::{FrameImages, LocateOptions, Prior, Status, locate};
use alacs::model::io::OutputDir;
use alacs::sim::{
    OrchardOptions, SampleOptions, ScanOptions, SessionOptions, simulate_samples, simulate_scan,
    simulate_session,
};
use alacs::{CalibrationOptions, Camera, Fidelity, LaserCalibration, LaserModel, Method};
use serde_json::{Value, json};

use crate::args::DemoArgs;
use crate::failure::CmdResult;
use crate::output;

/// The seed paper's Table 1, Method 4: the simulated laser.
const TRUE_ALPHA_DEG: f64 = 19.07;
const TRUE_BETA_DEG: f64 = 0.69;
const TRUE_L0_MM: f64 = 381.98;
/// The paper's slide positions in the accuracy experiment.
const ACCURACY_SLIDES_MM: [f64; 5] = [0.0, 50.0, 100.0, 150.0, 200.0];
/// Points per slide position (10 board poses x 3 points, as the paper).
const ACCURACY_VIEWS: usize = 10;

/// Worst and mean absolute error per axis at one slide position.
struct AxisErrors {
    slide_mm: f64,
    max_mm: [f64; 3],
    mean_mm: [f64; 3],
    n: usize,
}

/// Triangulates noise-free laser points at `slide_mm` with `fitted` and
/// compares them with the truth.
fn accuracy_at(
    camera: &Camera,
    truth: &LaserModel,
    fitted: &LaserModel,
    slide_mm: f64,
    seed: u64,
) -> CmdResult<AxisErrors> {
    let options = SampleOptions {
        n_views: ACCURACY_VIEWS,
        depth_noise_mm: 0.0,
        slides_mm: vec![slide_mm],
        seed,
        ..SampleOptions::default()
    };
    let sim = simulate_samples(camera, truth, &options)?;
    let (mut max_mm, mut sum_mm) = ([0.0f64; 3], [0.0f64; 3]);
    for (sample, &z_true) in sim.samples.iter().zip(&sim.true_depth_mm) {
        let n = sample.normalized();
        let truth_point = [n.x * z_true, n.y * z_true, z_true];
        let estimate = fitted.triangulate(&n, slide_mm)?;
        for axis in 0..3 {
            let e = (estimate[axis] - truth_point[axis]).abs();
            max_mm[axis] = max_mm[axis].max(e);
            sum_mm[axis] += e;
        }
    }
    let n = sim.samples.len();
    Ok(AxisErrors { slide_mm, max_mm, mean_mm: sum_mm.map(|s| s / n as f64), n })
}

/// Slide positions of the demo's calibration session (the paper's 0-20 cm).
const SESSION_SLIDES_MM: [f64; 3] = [0.0, 100.0, 200.0];
/// Board poses of the rendered accuracy session (the paper's 10), each at
/// every one of `ACCURACY_SLIDES_MM`.
const ACCURACY_SESSION_VIEWS: usize = 10;

/// The scan batch: (label, leaf occlusion, sun), `SCANS_PER_CONDITION` each.
const SCAN_CONDITIONS: [(&str, f64, bool); 3] = [
    ("unoccluded, shade", 0.0, false),
    ("20 % hidden, shade", 0.2, false),
    ("40 % hidden, sun", 0.4, true),
];
const SCANS_PER_CONDITION: u64 = 4;
/// The scan the demo writes an HTML report of: (condition, scan) indices,
/// the first sunlit, 40 %-hidden fruit.
const REPORTED_SCAN: (usize, u64) = (2, 0);

/// What the image pipeline measured.
struct Pipeline {
    camera_rms_px: f64,
    camera: Camera,
    laser: LaserModel,
    laser_samples: usize,
    accuracy: AccuracyEvaluation,
    conditions: Vec<ConditionErrors>,
    /// The HTML reports' pages (calibration, scan) and every file written for them.
    reports: Vec<std::path::PathBuf>,
    report_files: Vec<std::path::PathBuf>,
}

/// Localization errors of one scan condition.
struct ConditionErrors {
    label: &'static str,
    scans: usize,
    found: usize,
    within_15_mm: usize,
    /// Per found scan: |error| along x, y, z and in 3-D, mm.
    errors_mm: Vec<[f64; 4]>,
}

/// Simulates a calibration session, calibrates camera and laser from its
/// images, then locates simulated fruit with that calibration.
fn image_pipeline(
    args: &DemoArgs,
    out: &mut OutputDir,
    truth: &LaserModel,
    bar: &indicatif::ProgressBar,
) -> CmdResult<Pipeline> {
    let true_camera = Camera::blackfly_s_5mp();
    bar.set_message("rendering a calibration session (10 board poses x 3 slide positions)");
    let session_options = SessionOptions {
        slides_mm: SESSION_SLIDES_MM.to_vec(),
        seed: args.seed,
        ..SessionOptions::default()
    };
    let session = simulate_session(&true_camera, truth, &session_options)?;
    // The session's images live in a folder of the output's own, removed
    // when it drops (on every error path too): nothing outside `--out`.
    let scratch = out.scratch()?;
    session.write(scratch.path())?;
    bar.inc(1);
    let session = Session::read(scratch.path())?;
    bar.set_message("calibrating the camera from the board views");
    let fit = calibrate_camera_session(&session, &IntrinsicsOptions::default(), &|| {})?;
    bar.inc(1);
    bar.set_message("calibrating the laser from the stripes on the board");
    let laser_fit =
        calibrate_laser_session(&session, &fit.camera, &LaserSessionOptions::default(), &|| {})?;
    bar.inc(1);
    bar.set_message("report: the calibration against its session");
    // The laser calibration's samples split by view: the report needs not find the stripes again.
    let mut samples = laser_fit.samples.iter();
    let per_view = laser_fit
        .views
        .iter()
        .map(|view| (samples.by_ref().take(view.n_samples).copied().collect(), view.clone()))
        .collect();
    let laser_std = laser_fit.calibration.std_dev.as_ref().map(|s| s.to_laser_std());
    let report = calibration_report_from_views(
        &session,
        &fit.camera,
        &laser_fit.calibration.laser,
        laser_std.as_ref(),
        per_view,
        &|| {},
    );
    let report_files = report.and_then(|report| {
        let mut report_out = open_sub_output(
            out,
            "report_calibration",
            OutputKind::ReportCalibration,
            args.folder.force,
        )?;
        let files = write_calibration_html(
            &mut report_out,
            &session,
            &report,
            "the demo's rendered session",
        )?;
        report_out.finish()?;
        Ok(files)
    });
    drop(scratch);
    let mut report_files = report_files?;
    let mut reports = vec![args.out.join("report_calibration").join("index.html")];
    bar.inc(1);

    bar.set_message(format!(
        "rendering an accuracy session ({ACCURACY_SESSION_VIEWS} board poses x {} slide positions)",
        ACCURACY_SLIDES_MM.len()
    ));
    let accuracy_options = SessionOptions {
        n_views: ACCURACY_SESSION_VIEWS,
        slides_mm: ACCURACY_SLIDES_MM.to_vec(),
        seed: args.seed.wrapping_add(1),
        ..SessionOptions::default()
    };
    let accuracy_session = simulate_session(&true_camera, truth, &accuracy_options)?;
    let scratch = out.scratch()?;
    accuracy_session.write(scratch.path())?;
    bar.inc(1);
    bar.set_message("accuracy: every stripe point against its board plane");
    let accuracy = evaluate_accuracy(
        &Session::read(scratch.path())?,
        &fit.camera,
        &laser_fit.calibration.laser,
        &AccuracyOptions::default(),
        &|| {},
    );
    drop(scratch);
    let accuracy = accuracy?;
    bar.inc(1);

    let mut conditions = Vec::new();
    for (c, &(label, occlusion, sun)) in SCAN_CONDITIONS.iter().enumerate() {
        let mut errors =
            ConditionErrors { label, scans: 0, found: 0, within_15_mm: 0, errors_mm: Vec::new() };
        for k in 0..SCANS_PER_CONDITION {
            bar.set_message(format!("scanning: {label}, fruit {}", k + 1));
            let options = ScanOptions {
                orchard: OrchardOptions { occlusion, ..OrchardOptions::default() },
                sun,
                seed: args.seed.wrapping_add(100 * c as u64 + k),
                ..ScanOptions::default()
            };
            let scan = simulate_scan(&true_camera, truth, &options)?;
            let images = (0..scan.frames.len())
                .map(|i| scan.render_frame(i, true))
                .collect::<Result<Vec<_>, _>>()?;
            let frames: Vec<FrameImages> = images
                .iter()
                .zip(&scan.frames)
                .map(|(image, f)| FrameImages {
                    image,
                    image_laser_off: None,
                    slide_mm: f.slide_mm,
                })
                .collect();
            let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
            let answer = locate(
                &fit.camera,
                &laser_fit.calibration.laser,
                &prior,
                &frames,
                &LocateOptions::default(),
            )?;
            if (c, k) == REPORTED_SCAN {
                let report_frames: Vec<ScanReportFrame> = images
                    .iter()
                    .zip(&scan.frames)
                    .map(|(image, f)| ScanReportFrame { name: &f.image, image })
                    .collect();
                let mut report_out =
                    open_sub_output(out, "report_scan", OutputKind::ReportScan, args.folder.force)?;
                let source = format!("simulated ({label}, fruit {})", k + 1);
                report_files.extend(write_scan_html(
                    &mut report_out,
                    &ScanReport {
                        source: &source,
                        camera: &fit.camera,
                        laser: &laser_fit.calibration.laser,
                        prior: &prior,
                        frames: &report_frames,
                        localization: &answer,
                    },
                )?);
                report_out.finish()?;
                reports.push(args.out.join("report_scan").join("index.html"));
            }
            errors.scans += 1;
            if let (Status::Ok, Some(p)) = (answer.status, answer.position_mm) {
                let e = p - scan.scene.fruit_centre;
                errors.found += 1;
                errors.within_15_mm += usize::from(e.norm() <= 15.0);
                errors.errors_mm.push([e.x.abs(), e.y.abs(), e.z.abs(), e.norm()]);
            }
            bar.inc(1);
        }
        conditions.push(errors);
    }
    Ok(Pipeline {
        camera_rms_px: fit.rms_px,
        camera: fit.camera,
        laser: laser_fit.calibration.laser,
        laser_samples: laser_fit.samples.len(),
        accuracy,
        conditions,
        reports,
        report_files,
    })
}

/// Mean and maximum of column `axis` of the errors.
fn mean_max(errors: &[[f64; 4]], axis: usize) -> (f64, f64) {
    let n = errors.len().max(1) as f64;
    let sum: f64 = errors.iter().map(|e| e[axis]).sum();
    (sum / n, errors.iter().map(|e| e[axis]).fold(0.0, f64::max))
}

/// Runs `alacs demo`.
pub fn run(args: &DemoArgs) -> CmdResult {
    let camera = Camera::blackfly_s_5mp();
    let truth = LaserModel::from_degrees(Fidelity::High, TRUE_ALPHA_DEG, TRUE_BETA_DEG, TRUE_L0_MM);
    let mut out = open_output(&args.out, OutputKind::Demo, args.folder.force)?;
    let bar = output::progress_bar(args.json, "calibrating");
    let scans = SCAN_CONDITIONS.len() * SCANS_PER_CONDITION as usize;
    output::start_progress(&bar, 1 + ACCURACY_SLIDES_MM.len() + 6 + scans, "calibrating");

    bar.set_message("calibrating: four methods on simulated samples with 30 % outliers");
    let sample_options =
        SampleOptions { outlier_fraction: 0.3, seed: args.seed, ..SampleOptions::default() };
    let sim = simulate_samples(&camera, &truth, &sample_options)?;
    let calibration_eval = evaluate_calibration(&sim.samples, &CalibrationOptions::default())?;
    let results = calibration_eval.calibrations();
    bar.inc(1);

    let method4: &LaserCalibration = results
        .iter()
        .find(|c| c.method == Method::HighFidelityRansac)
        .unwrap_or(&results[results.len() - 1]);
    let outliers_found = sim.outliers.iter().filter(|i| !method4.inliers.contains(i)).count();

    let mut accuracy = Vec::new();
    for (k, &slide_mm) in ACCURACY_SLIDES_MM.iter().enumerate() {
        bar.set_message(format!("accuracy at d = {slide_mm} mm"));
        let seed = args.seed.wrapping_add(1000 + k as u64);
        accuracy.push(accuracy_at(&camera, &truth, &method4.laser, slide_mm, seed)?);
        bar.inc(1);
    }
    let pipeline = image_pipeline(args, &mut out, &truth, &bar)?;
    bar.finish_and_clear();
    let mut files = write_calibration_report(&mut out, &calibration_eval)?;
    files.extend(write_accuracy_report(&mut out, &pipeline.accuracy)?);
    out.finish()?;
    let condition_json = |c: &ConditionErrors| {
        let stat = |axis| {
            let (mean, max) = mean_max(&c.errors_mm, axis);
            json!({"mean_abs_mm": mean, "max_abs_mm": max})
        };
        json!({
            "condition": c.label, "scans": c.scans, "found": c.found,
            "within_15_mm": c.within_15_mm,
            "x": stat(0), "y": stat(1), "z": stat(2), "error_3d": stat(3),
        })
    };

    if args.json {
        let value = json!({
            "truth": {"alpha_deg": TRUE_ALPHA_DEG, "beta_deg": TRUE_BETA_DEG, "l0_mm": TRUE_L0_MM, "slide_scale": 1.0},
            "n_samples": sim.samples.len(),
            "outliers": sim.outliers,
            "methods": results.iter().map(output::calibration_json).collect::<Vec<Value>>(),
            "accuracy": accuracy.iter().map(|a| json!({
                "slide_mm": a.slide_mm,
                "n_points": a.n,
                "max_abs_error_mm": {"x": a.max_mm[0], "y": a.max_mm[1], "z": a.max_mm[2]},
                "mean_abs_error_mm": {"x": a.mean_mm[0], "y": a.mean_mm[1], "z": a.mean_mm[2]},
            })).collect::<Vec<Value>>(),
            "images": {
                "camera_rms_px": pipeline.camera_rms_px,
                "fx_px": pipeline.camera.fx_px,
                "laser": pipeline.laser.to_file(),
                "laser_samples": pipeline.laser_samples,
                "localization": pipeline.conditions.iter().map(condition_json).collect::<Vec<Value>>(),
                "accuracy": pipeline.accuracy.to_json(),
            },
            "out": args.out.display().to_string(),
            "files": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "reports": pipeline.reports.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
            "report_files": pipeline.report_files.len(),
        });
        output::print_json(&value)?;
        return Ok(());
    }

    outln!(
        "Calibration (the seed paper's Table 1) on {} simulated samples, {} of them gross outliers:",
        sim.samples.len(),
        sim.outliers.len()
    );
    out!("{}", output::table_1(&results, &calibration_eval.failed));
    outln!("{:<44} {:>11.2} {:>9.2} {:>10.2}", "Truth", TRUE_ALPHA_DEG, TRUE_L0_MM, TRUE_BETA_DEG);
    outln!("Method 4 rejected {outliers_found} of the {} planted outliers.\n", sim.outliers.len());
    outln!(
        "Accuracy of triangulated points with the Method 4 calibration (boards at 0.6-1.2 m;\n\
         noise-free laser pixels, so what remains is the calibration's error):"
    );
    outln!(
        "{:>8} {:>7}   {:>24}   {:>24}",
        "d (mm)",
        "points",
        "max |error| x/y/z (mm)",
        "mean |error| x/y/z (mm)"
    );
    for a in &accuracy {
        outln!(
            "{:>8.0} {:>7}   {:>7.3} {:>7.3} {:>8.3}   {:>7.3} {:>7.3} {:>8.3}",
            a.slide_mm,
            a.n,
            a.max_mm[0],
            a.max_mm[1],
            a.max_mm[2],
            a.mean_mm[0],
            a.mean_mm[1],
            a.mean_mm[2]
        );
    }
    outln!("(the seed paper reports worst cases below 0.6 / 1.2 / 4 mm in x / y / z)\n");
    outln!(
        "From images: a rendered session (10 board poses x slides {SESSION_SLIDES_MM:?} mm) calibrated\n\
         the camera to {:.3} px RMS (fx {:.2} px, truth 2320) and the laser from {} stripe samples:\n\
         alpha {:.3} deg (truth {TRUE_ALPHA_DEG}), beta {:.3} deg ({TRUE_BETA_DEG}), L0 {:.2} mm ({TRUE_L0_MM}),\n\
         slide scale k {:.5} (1).",
        pipeline.camera_rms_px,
        pipeline.camera.fx_px,
        pipeline.laser_samples,
        pipeline.laser.alpha_deg(),
        pipeline.laser.beta_deg(),
        pipeline.laser.l0_mm,
        pipeline.laser.slide_scale
    );
    let accuracy = &pipeline.accuracy;
    outln!(
        "Accuracy with that calibration (the paper's experiment from images: a second session,\n\
         {ACCURACY_SESSION_VIEWS} board poses x d = 0-200 mm, {} stripe points on the boards):",
        accuracy.points.len()
    );
    out!("{}", output::accuracy_table(accuracy));
    outln!("Fruit localization with that calibration (simulated 5-frame scans at 0.6-1.2 m):");
    outln!(
        "{:<20} {:>5} {:>6} {:>7}   {:>26}   {:>8}",
        "condition",
        "scans",
        "found",
        "<=15mm",
        "mean |error| x/y/z (mm)",
        "max 3-D"
    );
    for c in &pipeline.conditions {
        let (x, _) = mean_max(&c.errors_mm, 0);
        let (y, _) = mean_max(&c.errors_mm, 1);
        let (z, _) = mean_max(&c.errors_mm, 2);
        let (_, worst) = mean_max(&c.errors_mm, 3);
        outln!(
            "{:<20} {:>5} {:>6} {:>7}   {:>8.2} {:>8.2} {:>8.2}   {:>8.2}",
            c.label,
            c.scans,
            c.found,
            c.within_15_mm,
            x,
            y,
            z,
            worst
        );
    }
    outln!("(not found is an answer: the scan reports why instead of a doubtful point)\n");
    outln!(
        "Evaluation artefacts (Table 1, residual plots per method, accuracy box plots, JSON):\n{}",
        output::files_written(&args.out, &files)
    );
    outln!("HTML reports (open in a browser; images beside each page):");
    for page in &pipeline.reports {
        outln!("  {}", page.display());
    }
    Ok(())
}
