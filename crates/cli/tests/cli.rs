//! The `alacs` program end to end: outputs and exit codes of FORMATS.md.

// Test helpers outside #[test] functions may fail loudly too.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

use common::{
    arg, cmdline, evaluate_calibration, localize, report_scan, scratch, triangulate, with, write,
};
use serde_json::Value;

fn alacs(args: &[impl AsRef<OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_alacs")).args(args).output().expect("alacs runs")
}

fn stdout_json(output: &Output) -> Value {
    assert!(output.status.success(), "stderr: {}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout.clone()).unwrap();
    // Exactly one JSON object and nothing else on standard output.
    serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// With `--json`, a failure's standard output is exactly one object,
/// `{"error": {"exit_code": N, "message": ".."}}`, naming the same as stderr.
fn assert_error_json(output: &Output, code: i64) {
    let text = String::from_utf8(output.stdout.clone()).unwrap();
    let json: Value = serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("{e}: {text}"));
    assert_eq!(json["error"]["exit_code"].as_i64(), Some(code), "{json}");
    let message = json["error"]["message"].as_str().unwrap();
    assert!(stderr(output).contains(message), "{message} vs {}", stderr(output));
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Simulated samples with 30 % outliers in `dir`, returning the CSV path.
fn simulated_samples(dir: &Path, seed: &str) -> String {
    let out = dir.to_str().unwrap();
    let output = alacs(&["simulate", "samples", "--out", out, "--seed", seed, "--outliers", "0.3"]);
    assert!(output.status.success(), "{}", stderr(&output));
    dir.join("samples.csv").to_str().unwrap().to_owned()
}

/// Issue 42, item 2: a laser whose beta is 20 deg is beyond the
/// low-fidelity model; `calibrate laser --compare` and `evaluate
/// calibration` still exit 0 with four rows, the method that cannot fit a
/// row with its reason.
#[test]
fn a_method_that_cannot_fit_is_a_row_with_its_reason_not_a_failure() {
    let dir = scratch("compare_beta_20");
    let data = dir.join("data");
    let output = alacs(&[
        "simulate",
        "samples",
        "--beta-deg",
        "20",
        "--views",
        "10",
        "--outliers",
        "0.2",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let samples = data.join("samples.csv");
    let samples = samples.to_str().unwrap();
    let out = dir.join("evaluation");
    for args in [
        vec!["calibrate", "laser", "--samples", samples, "--compare"],
        vec!["evaluate", "calibration", "--samples", samples, "--out", out.to_str().unwrap()],
    ] {
        let output = alacs(&args);
        assert!(output.status.success(), "{args:?}: {}", stderr(&output));
        let text = String::from_utf8_lossy(&output.stdout);
        let rows: Vec<&str> = text.lines().filter(|l| l.starts_with("Method ")).collect();
        assert!(rows.len() >= 4, "{args:?}: {text}");
        assert!(rows.iter().any(|r| r.contains("cannot fit")), "{args:?}: {text}");
        assert!(rows.iter().any(|r| r.starts_with("Method 4") && !r.contains("cannot")), "{text}");
    }
}

/// Samples at one slide position (the default of `simulate samples`) do
/// not fix the slide scale: the summary and laser.yaml say it is held,
/// so that k = 1 is not taken for a measurement.
#[test]
fn a_slide_scale_not_fitted_is_said_so() {
    let dir = scratch("slide_scale_held");
    let samples = simulated_samples(&dir, "4");
    let laser = dir.join("laser.yaml");
    let output =
        alacs(&["calibrate", "laser", "--samples", &samples, "-o", laser.to_str().unwrap()]);
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.contains("held, not fitted"), "{text}");
    let yaml = std::fs::read_to_string(&laser).unwrap();
    assert!(yaml.lines().next().unwrap().contains("slide_scale is held, not fitted"), "{yaml}");
}

#[test]
fn calibrate_laser_json_has_the_formats_md_keys() {
    let dir = scratch("calibrate_json");
    let samples = simulated_samples(&dir, "5");
    let laser_yaml = dir.join("laser.yaml");
    let output =
        alacs(&cmdline("calibrate laser --samples {} --json -o {}", &[&samples, &laser_yaml]));
    let json = stdout_json(&output);
    for key in [
        "model",
        "alpha_deg",
        "beta_deg",
        "l0_mm",
        "inliers",
        "mean_abs_error_mm",
        "mean_abs_error_all_mm",
        "n_samples",
    ] {
        assert!(json.get(key).is_some(), "missing {key} in {json}");
    }
    assert_eq!(json["model"], "high-fidelity");
    assert_eq!(json["n_samples"], 30);
    assert!((json["alpha_deg"].as_f64().unwrap() - 19.07).abs() < 0.15);
    // The planted outliers are not among the inliers.
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let inliers = json["inliers"].as_array().unwrap();
    for outlier in truth["outliers"].as_array().unwrap() {
        assert!(!inliers.contains(outlier), "outlier {outlier} among inliers");
    }
    // laser.yaml reads back to the printed parameters.
    let laser = alacs::LaserModel::from_yaml_file(&laser_yaml).unwrap();
    assert_eq!(laser.l0_mm, json["l0_mm"].as_f64().unwrap());
}

#[test]
fn compare_json_lists_the_four_methods_ranked_as_table_1() {
    let dir = scratch("compare_json");
    let samples = simulated_samples(&dir, "6");
    let json =
        stdout_json(&alacs(&["calibrate", "laser", "--samples", &samples, "--compare", "--json"]));
    let methods = json["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 4);
    for (i, m) in methods.iter().enumerate() {
        assert_eq!(m["method"], i + 1);
        assert!(m["name"].as_str().is_some());
    }
    assert_eq!(methods[0]["model"], "low-fidelity");
    assert_eq!(methods[0]["beta_deg"], 0.0);
    let error = |i: usize| methods[i]["mean_abs_error_mm"].as_f64().unwrap();
    assert!(error(1) < error(0) && error(3) < error(2) && error(3) < error(1));
}

#[test]
fn compare_prints_a_table_like_the_papers() {
    let dir = scratch("compare_text");
    let samples = simulated_samples(&dir, "7");
    let output = alacs(&["calibrate", "laser", "--samples", &samples, "--compare"]);
    assert!(output.status.success());
    let text = String::from_utf8(output.stdout).unwrap();
    for needle in
        ["alpha (deg)", "L0 (mm)", "beta (deg)", "Mean error (mm)", "Method 1", "Method 4"]
    {
        assert!(text.contains(needle), "{needle} missing from\n{text}");
    }
}

#[test]
fn unreadable_input_exits_2_naming_the_file() {
    let dir = scratch("bad_input");
    let missing = dir.join("missing.csv");
    let output = alacs(&["calibrate", "laser", "--samples", missing.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("missing.csv"), "{}", stderr(&output));

    let malformed = dir.join("malformed.csv");
    std::fs::write(&malformed, "u_n,v_n,z_mm\n0.1,0.2,800\n0.1,0.2,NaN\n").unwrap();
    let output = alacs(&["calibrate", "laser", "--samples", malformed.to_str().unwrap(), "--json"]);
    assert_eq!(output.status.code(), Some(2));
    assert_error_json(&output, 2);
    let message = stderr(&output);
    assert!(message.contains("malformed.csv") && message.contains("line 3"), "{message}");
    assert!(!message.contains("panicked"), "{message}");

    let output =
        alacs(&["calibrate", "laser", "--samples", malformed.to_str().unwrap(), "--method", "5"]);
    assert_eq!(output.status.code(), Some(2));
}

#[test]
fn evaluate_bad_input_exits_2_naming_the_file() {
    let dir = scratch("evaluate_bad_input");
    let out = dir.join("evaluation");
    let out = out.to_str().unwrap();
    let missing = dir.join("missing.csv");
    let output = alacs(&evaluate_calibration(&missing, &out));
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("missing.csv"), "{}", stderr(&output));
    // A session folder without session.yaml.
    let template =
        "evaluate accuracy --session {} --camera camera.yaml --laser laser.yaml --out {}";
    let output = alacs(&cmdline(template, &[&dir, &out]));
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("session.yaml"), "{}", stderr(&output));
    // Neither --samples nor --session: usage.
    let output = alacs(&["evaluate", "calibration", "--out", out]);
    assert_eq!(output.status.code(), Some(2));
    assert!(!Path::new(out).exists(), "nothing written on bad input");
}

#[test]
fn evaluate_calibration_writes_table_1_and_residual_plots() {
    let dir = scratch("evaluate_calibration");
    let samples = simulated_samples(&dir, "5");
    let out = dir.join("evaluation");
    let output = alacs(&evaluate_calibration(&samples, &out));
    assert!(output.status.success(), "{}", stderr(&output));
    let text = String::from_utf8(output.stdout.clone()).unwrap();
    assert!(text.contains("Method 4 (High-fidelity model + RANSAC)"), "{text}");
    // Every written file is named on standard error, with --json too.
    assert!(stderr(&output).contains("wrote 10 files"), "{}", stderr(&output));
    let json_out = dir.join("evaluation_json");
    let output = alacs(&with(evaluate_calibration(&samples, &json_out), &["--json"]));
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(stderr(&output).contains("wrote 10 files"), "{}", stderr(&output));
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("calibration.json")).unwrap())
            .unwrap();
    let methods = json["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 4);
    // Method 4's fitted residuals: its inliers, small (0.5 mm depth noise).
    let stats = &methods[3]["residual_stats_mm"];
    assert_eq!(stats["n"], methods[3]["inliers"].as_array().unwrap().len());
    assert!(stats["rms"].as_f64().unwrap() < 1.0, "{stats}");
    for k in 1..=4 {
        for ext in ["png", "svg"] {
            let file = out.join(format!("calibration_residuals_method{k}.{ext}"));
            assert!(std::fs::metadata(&file).unwrap().len() > 1000, "{}", file.display());
        }
    }
    let png = image::open(out.join("calibration_residuals_method4.png")).unwrap();
    assert_eq!((png.width(), png.height()), (900, 560));
}

#[test]
fn evaluate_refuses_a_foreign_or_unwritable_folder_with_exit_2() {
    let dir = scratch("evaluate_foreign");
    let samples = simulated_samples(&dir, "5");
    let out = dir.join("mine");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "keep").unwrap();
    let run = |extra: &[&str]| alacs(&with(evaluate_calibration(&samples, &out), extra));
    let output = run(&[]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("--force"), "{}", stderr(&output));
    assert!(!out.join("calibration.json").exists());
    let output = run(&["--force"]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "keep");
    // notes.txt stays foreign: a rerun without --force is refused again.
    assert_eq!(run(&[]).status.code(), Some(2));
    // An output path that is a file: exit 2.
    let file = dir.join("a_file");
    std::fs::write(&file, "x").unwrap();
    let output = alacs(&evaluate_calibration(&samples, &file));
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
}

#[test]
fn degenerate_samples_exit_1_with_a_reason() {
    let dir = scratch("degenerate");
    let path = dir.join("one_depth.csv");
    let rows: String = (0..20)
        .map(|i| format!("{},{},800\n", -0.1 + 0.001 * f64::from(i), -0.3 + 0.03 * f64::from(i)))
        .collect();
    std::fs::write(&path, format!("u_n,v_n,z_mm\n{rows}")).unwrap();
    let output = alacs(&["calibrate", "laser", "--samples", path.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1));
    assert!(stderr(&output).contains("one depth"), "{}", stderr(&output));
}

/// Runs `alacs triangulate` on camera.yaml, laser.yaml and pixels.csv in `dir`.
fn triangulate_in(dir: &Path, slide_mm: &str, extra: &[&str]) -> Output {
    let file = |name: &str| dir.join(name);
    let args =
        triangulate(&file("camera.yaml"), &file("laser.yaml"), slide_mm, &file("pixels.csv"));
    alacs(&with(args, extra))
}

#[test]
fn triangulate_maps_pixels_to_points_on_the_laser_plane() {
    let dir = scratch("triangulate");
    let camera = alacs::Camera::blackfly_s_5mp();
    let camera_yaml = dir.join("camera.yaml");
    camera.to_yaml_file(&camera_yaml).unwrap();
    let laser = alacs::LaserModel::seed_paper();
    let laser_yaml = dir.join("laser.yaml");
    laser.to_yaml_file(&laser_yaml, "test", None).unwrap();
    let pixels = dir.join("pixels.csv");
    // The last row is far right: its ray misses the laser plane in front of the camera.
    std::fs::write(&pixels, "u_px,v_px\n1000,100\n1100.5,1024\n1200,2000\n2447,1000\n").unwrap();
    let output = triangulate_in(&dir, "50", &["--json"]);
    let json = stdout_json(&output);
    let points = json["points_mm"].as_array().unwrap();
    assert_eq!(points.len(), 4);
    for p in &points[..3] {
        let p: Vec<f64> = p.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let point = nalgebra::Point3::new(p[0], p[1], p[2]);
        assert!(laser.signed_distance_mm(&point, 50.0).abs() < 1e-6);
        let back = camera.project(&point).unwrap();
        assert!(back.x.is_finite());
    }
    let pixel = camera
        .project(&nalgebra::Point3::new(
            points[1][0].as_f64().unwrap(),
            points[1][1].as_f64().unwrap(),
            points[1][2].as_f64().unwrap(),
        ))
        .unwrap();
    assert!((pixel.x - 1100.5).abs() < 1e-6 && (pixel.y - 1024.0).abs() < 1e-6);
    assert!(points[3].is_null());
    assert!(stderr(&output).contains("row 4"));
}

#[test]
fn triangulate_rejects_a_malformed_camera_file() {
    let dir = scratch("triangulate_bad");
    write(&dir, "camera.yaml", "image_width: 640\nimage_height: [480\n");
    write(&dir, "laser.yaml", "model: high-fidelity\nalpha_deg: 19\nbeta_deg: 0.5\nl0_mm: 380\n");
    write(&dir, "pixels.csv", "u_px,v_px\n1,2\n");
    let output = triangulate_in(&dir, "0", &[]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("camera.yaml"), "{}", stderr(&output));
}

#[test]
fn simulate_samples_is_deterministic() {
    let a = scratch("sim_a");
    let b = scratch("sim_b");
    simulated_samples(&a, "42");
    simulated_samples(&b, "42");
    for file in ["samples.csv", "truth.json"] {
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{file}"
        );
    }
}

#[test]
fn demo_json_reports_four_methods_and_accuracy() {
    let dir = scratch("demo");
    let out = dir.join("artefacts");
    let json = stdout_json(&alacs(&["demo", "--json", "--out", out.to_str().unwrap()]));
    assert_eq!(json["methods"].as_array().unwrap().len(), 4);
    // The evaluation artefacts: Table 1, 4 residual plots and the accuracy
    // box plots (PNG and SVG), the JSON files and the points CSV.
    let files = json["files"].as_array().unwrap();
    assert_eq!(files.len(), 14, "{files:?}");
    for name in [
        "calibration_table1.txt",
        "calibration.json",
        "calibration_residuals_method1.png",
        "calibration_residuals_method4.svg",
        "accuracy.json",
        "accuracy_points.csv",
        "accuracy_boxplots.png",
        "accuracy_boxplots.svg",
    ] {
        let len = std::fs::metadata(out.join(name)).map(|m| m.len()).unwrap_or(0);
        assert!(len > 0, "{name} missing or empty");
    }
    // The accuracy experiment from images: 5 slide positions, medians within
    // 0.1 mm and the middle half within 0.5 mm in z (measured: 0.006-0.021
    // and 0.09-0.15 mm).
    let slides = json["images"]["accuracy"]["slides"].as_array().unwrap();
    assert_eq!(slides.len(), 5);
    for s in slides {
        assert!(s["z"]["median_mm"].as_f64().unwrap().abs() < 0.1, "{s}");
        assert!(s["z"]["iqr_mm"].as_f64().unwrap() < 0.5, "{s}");
    }
    let accuracy = json["accuracy"].as_array().unwrap();
    assert_eq!(accuracy.len(), 5);
    for a in accuracy {
        // The seed paper's worst cases: 0.6 / 1.2 / 4 mm. Calibration error
        // alone (noise-free pixels) must stay well inside them.
        assert!(a["max_abs_error_mm"]["z"].as_f64().unwrap() < 4.0, "{a}");
    }
    // From images: calibration near the truth, every unoccluded fruit found
    // within the paper's 4 mm, no found fruit beyond the end-effector's 15 mm.
    let images = &json["images"];
    assert!((images["laser"]["alpha_deg"].as_f64().unwrap() - 19.07).abs() < 0.05, "{images}");
    assert!((images["laser"]["l0_mm"].as_f64().unwrap() - 381.98).abs() < 0.5, "{images}");
    let conditions = images["localization"].as_array().unwrap();
    assert_eq!(conditions[0]["found"], conditions[0]["scans"], "{images}");
    assert!(conditions[0]["error_3d"]["max_abs_mm"].as_f64().unwrap() < 4.0, "{images}");
    for c in conditions {
        assert_eq!(c["found"], c["within_15_mm"], "{c}");
    }
    // The two HTML reports, each page with its images beside it.
    let reports: Vec<&str> =
        json["reports"].as_array().unwrap().iter().map(|r| r.as_str().unwrap()).collect();
    assert_eq!(reports.len(), 2, "{reports:?}");
    for (page, images) in [("report_calibration", "view01.jpg"), ("report_scan", "frame00.jpg")] {
        let index = out.join(page).join("index.html");
        assert!(reports.contains(&index.to_str().unwrap()), "{reports:?}");
        let html = std::fs::read_to_string(&index).unwrap();
        assert!(html.contains(&format!("images/{images}")), "{page}");
        assert!(std::fs::metadata(out.join(page).join("images").join(images)).unwrap().len() > 0);
    }
}

#[test]
fn simulate_session_writes_a_formats_md_session() {
    let dir = scratch("sim_session");
    let out = dir.to_str().unwrap();
    let template = "simulate session --out {} --seed 3 --views 2 --slides 0,100 --laser-off --scale 0.1 --json";
    let args = cmdline(template, &[&out]);
    let json = stdout_json(&alacs(&args));
    assert_eq!(json["n_views"], 4);
    assert_eq!(json["n_images"], 6);
    assert_eq!(
        (json["image_width"].as_u64(), json["image_height"].as_u64()),
        (Some(245), Some(205))
    );
    for file in ["session.yaml", "camera.yaml", "truth.json", "view01_slide1.png", "view02_off.png"]
    {
        assert!(dir.join(file).is_file(), "{file}");
    }
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["views"].as_array().unwrap().len(), 4);
    assert_eq!(truth["camera"]["image_width"], 245);
    // Same seed, same bytes.
    let again = scratch("sim_session_again");
    let json = stdout_json(&alacs(&[&args[..3], &[arg(&again)], &args[4..]].concat()));
    assert_eq!(json["n_images"], 6);
    for file in ["session.yaml", "truth.json", "view02_slide2.png", "view01_off.png"] {
        assert_eq!(
            std::fs::read(dir.join(file)).unwrap(),
            std::fs::read(again.join(file)).unwrap()
        );
    }
    // Invalid options are bad input (exit 2).
    let output = alacs(&["simulate", "session", "--out", out, "--scale", "0"]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("scale"), "{}", stderr(&output));
}

#[test]
fn simulate_session_second_board_is_in_the_truth_and_not_taken_for_the_target() {
    let dir = scratch("sim_session_second");
    let out = dir.to_str().unwrap();
    let template = "simulate session --out {} --seed 5 --views 3 --scale 0.5 --charuco DICT_5X5_250 \
                    --second-board --max-tilt-deg 60 --json";
    let json = stdout_json(&alacs(&cmdline(template, &[&out])));
    assert_eq!(json["n_views"], 3);
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    // The same keys for both boards; no marker id on both.
    let keys = |v: &Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
    assert_eq!(keys(&truth["board"]), keys(&truth["second_board"]));
    assert_eq!(truth["board"]["dictionary"], "DICT_5X5_250");
    assert_eq!(truth["second_board"]["dictionary"], "DICT_4X4_50");
    assert_eq!(truth["second_board"]["inner_corners"], serde_json::json!([6, 4]));
    for view in truth["views"].as_array().unwrap() {
        assert_eq!(view["camera_from_second_board"].as_array().map(Vec::len), Some(4), "{view}");
    }
    // Every view's target is found, its camera near the truth.
    let calibrated = alacs(&["calibrate", "camera", "--session", out, "--json"]);
    let camera = stdout_json(&calibrated);
    assert_eq!(camera["views_used"], 3, "{camera}");
    let fx = camera["fx_px"].as_f64().unwrap();
    let fx_true = truth["camera"]["camera_matrix"]["data"][0].as_f64().unwrap();
    assert!((fx - fx_true).abs() < 0.01 * fx_true, "fx {fx} against {fx_true}");
}

fn opencv_right() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/opencv_right")
        .to_str()
        .unwrap()
        .to_owned()
}

#[test]
fn calibrate_camera_json_has_the_formats_md_keys() {
    let dir = scratch("camera_opencv");
    let yaml = dir.join("camera.yaml");
    let template = "calibrate camera --session {} --json -o {}";
    let output = alacs(&cmdline(template, &[&opencv_right(), &yaml]));
    let json = stdout_json(&output);
    for key in ["fx_px", "fy_px", "cx_px", "cy_px", "rms_px", "views_used"] {
        assert!(json[key].is_number(), "{key}: {json}");
    }
    assert_eq!(json["distortion_model"], "plumb_bob");
    assert_eq!(json["dist"].as_array().unwrap().len(), 5);
    assert_eq!(json["views_used"], 13);
    assert_eq!(json["views_rejected"].as_array().unwrap().len(), 0);
    // OpenCV on the same photographs: RMS 0.207-0.246 px, fx 534.6-542.4 px.
    assert!(json["rms_px"].as_f64().unwrap() < 0.207);
    // The written camera.yaml reads back with the same intrinsics.
    let text = std::fs::read_to_string(&yaml).unwrap();
    assert!(text.contains("camera_matrix") && text.contains("plumb_bob"), "{text}");
    assert!(text.contains(&format!("{}", json["fx_px"].as_f64().unwrap())), "{text}");
    // OpenCV's controls: the rational model with k3 and the tangential terms held.
    let template =
        "calibrate camera --session {} --json --distortion rational_polynomial --fix k3,tangential";
    let json = stdout_json(&alacs(&cmdline(template, &[&opencv_right()])));
    assert_eq!(json["distortion_model"], "rational_polynomial");
    let dist: Vec<f64> =
        json["dist"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(dist.len(), 8);
    assert_eq!((dist[2], dist[3], dist[4]), (0.0, 0.0, 0.0));
    assert_eq!(json["dist_std"].as_array().unwrap().len(), 8);
    assert_eq!(json["fixed"], serde_json::json!(["k3", "tangential"]));
    // --format names the layout of -o: without -o it is refused (exit 2),
    // not silently unused.
    let output =
        alacs(&cmdline("calibrate camera --session {} --format opencv", &[&opencv_right()]));
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("--output"), "{}", stderr(&output));
    // An unknown control is refused naming it (exit 2).
    let output = alacs(&cmdline("calibrate camera --session {} --fix k9", &[&opencv_right()]));
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("k9"), "{}", stderr(&output));
}

#[test]
fn a_board_given_by_its_squares_gets_the_hint_once_not_once_per_view() {
    let dir = scratch("board_by_squares");
    for entry in std::fs::read_dir(opencv_right()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "jpg") {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    // The photographs' board has 10 x 7 squares: 9 x 6 inner corners.
    let init = alacs(&cmdline("session init --board 10x7 --square-mm 25 {}", &[&dir]));
    assert!(init.status.success(), "{}", stderr(&init));
    // Every view says so: session.yaml is wrong, bad input (exit 2).
    let output = alacs(&cmdline("calibrate camera --session {}", &[&dir]));
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    let text = stderr(&output);
    let hint = "so a board of 10 x 7 squares is 9 x 6";
    assert_eq!(text.matches(hint).count(), 1, "{text}");
    assert_eq!(text.lines().count(), 1, "{text}");
}

#[test]
fn calibrate_from_a_simulated_session_end_to_end() {
    let dir = scratch("session_end_to_end");
    let out = dir.to_str().unwrap();
    let template =
        "simulate session --out {} --seed 7 --views 6 --slides 0,100,200 --scale 0.4 --json";
    let output = alacs(&cmdline(template, &[&out]));
    stdout_json(&output);
    let camera = dir.join("estimated_camera.yaml");
    let camera = camera.to_str().unwrap();
    stdout_json(&alacs(&["calibrate", "camera", "--session", out, "-o", camera, "--json"]));
    let samples = dir.join("samples_out.csv");
    let laser = dir.join("laser_out.yaml");
    let template = "calibrate laser --session {} --camera {} --export-samples {} -o {} --json";
    let json = stdout_json(&alacs(&cmdline(template, &[&out, &camera, &samples, &laser])));
    assert_eq!(json["model"], "high-fidelity");
    assert!((json["alpha_deg"].as_f64().unwrap() - 19.07).abs() < 0.1, "{json}");
    assert!((json["l0_mm"].as_f64().unwrap() - 381.98).abs() < 1.0, "{json}");
    let n = json["n_samples"].as_u64().unwrap();
    assert!(n > 1000, "{n} samples");
    let csv = std::fs::read_to_string(&samples).unwrap();
    assert!(csv.starts_with("u_n,v_n,z_mm,slide_mm"));
    assert_eq!(csv.lines().count() as u64, n + 1);
    assert!(std::fs::read_to_string(&laser).unwrap().contains("alpha_deg"));
    // Three slide positions: the slide scale k fitted, with its standard
    // deviation, and written to laser.yaml.
    assert_eq!(json["slide_scale_fitted"], true, "{json}");
    assert!((json["slide_scale"].as_f64().unwrap() - 1.0).abs() < 0.002, "{json}");
    assert!(json["slide_scale_std"].as_f64().unwrap() > 0.0, "{json}");
    assert!(std::fs::read_to_string(&laser).unwrap().contains("slide_scale:"));
    // laser.yaml carries the standard deviations calibrate laser printed.
    let (_, std) = alacs::LaserModel::from_yaml_file_with_std(&laser).unwrap();
    let std = std.expect("a std_dev block");
    assert_eq!(Some(std.alpha_deg), json["alpha_std_deg"].as_f64(), "{json}");
    assert_eq!(std.slide_scale, json["slide_scale_std"].as_f64(), "{json}");
    assert_eq!(Some(std.source.as_str()), json["std_source"].as_str(), "{json}");
    // The exported samples calibrate to the same laser.
    let again = stdout_json(&alacs(&cmdline("calibrate laser --samples {} --json", &[&samples])));
    assert_eq!(again["alpha_deg"], json["alpha_deg"]);
    assert_eq!(again["slide_scale"], json["slide_scale"]);
    // --hold-slide-scale: the seed's model, k = 1 and no standard deviation.
    let template = "calibrate laser --samples {} --hold-slide-scale --json";
    let held = stdout_json(&alacs(&cmdline(template, &[&samples])));
    assert_eq!(held["slide_scale"], 1.0);
    assert_eq!(held["slide_scale_fitted"], false);
    assert!(held["slide_scale_std"].is_null(), "{held}");
    // Evaluate: Table 1 on the session's samples, then the accuracy experiment.
    let eval_dir = dir.join("evaluation");
    let eval_out = eval_dir.to_str().unwrap();
    let template = "evaluate calibration --session {} --camera {} --out {} --json";
    let table = stdout_json(&alacs(&cmdline(template, &[&out, &camera, &eval_out])));
    assert_eq!(table["methods"].as_array().unwrap().len(), 4);
    assert_eq!(table["methods"][3]["alpha_deg"], json["alpha_deg"]);
    // A folder of its own: an output folder belongs to one command.
    let accuracy_out = dir.join("accuracy");
    let template =
        "evaluate accuracy --session {} --camera {} --laser {} --out {} --points 3 --json";
    let accuracy = stdout_json(&alacs(&cmdline(template, &[&out, &camera, &laser, &accuracy_out])));
    assert_eq!(accuracy["points_per_view"], "3");
    assert_eq!(accuracy["slides"].as_array().unwrap().len(), 3, "{accuracy}");
    // Three per view, fewer where the stripe on the board has fewer points.
    let views = accuracy["views"].as_array().unwrap();
    assert_eq!(views.len(), 18);
    assert!(views.iter().all(|v| v["n_points"].as_u64().unwrap() <= 3), "{accuracy}");
    let per_view: u64 = views.iter().map(|v| v["n_points"].as_u64().unwrap()).sum();
    assert_eq!(accuracy["n_points"], per_view);
    assert!(per_view >= 3 * 15, "{per_view} points");
    for file in
        accuracy["files"].as_array().unwrap().iter().chain(table["files"].as_array().unwrap())
    {
        let len = std::fs::metadata(file.as_str().unwrap()).unwrap().len();
        assert!(len > 0, "{file}");
    }
    // The HTML report of that camera and laser against the session.
    let report_dir = dir.join("report");
    let template = "report calibration --session {} --camera {} --laser {} --out {} --json";
    let report = stdout_json(&alacs(&cmdline(template, &[&out, &camera, &laser, &report_dir])));
    assert_eq!(report["views"], 18, "{report}");
    // A far board at d = 200 mm whose stripe crosses dark squares may be
    // flagged (its mean |z - z_hat| beyond the 2 mm threshold; seed 7: 1 of 18).
    let flagged = report["flagged"].as_array().unwrap();
    assert!(flagged.len() <= 2, "{report}");
    let html = std::fs::read_to_string(report_dir.join("index.html")).unwrap();
    // One sigma per quantity: the report shows the laser's as its calibration estimated them.
    assert!(html.contains("laser.yaml&#39;s std_dev"), "the laser's sigmas are not laser.yaml's");
    for view in flagged {
        assert!(html.contains(view.as_str().unwrap()), "{view}");
    }
    for name in ["images/view01.jpg", "images/view18.jpg", "calibration_residuals_method4.png"] {
        assert!(html.contains(name), "{name}");
        assert!(std::fs::metadata(report_dir.join(name)).unwrap().len() > 0, "{name}");
    }
    // Stripe of one view: CSV with a header, one row per stripe row.
    let stripe = alacs(&["stripe", "--image", dir.join("view01_slide1.png").to_str().unwrap()]);
    assert!(stripe.status.success(), "{}", stderr(&stripe));
    let text = String::from_utf8(stripe.stdout).unwrap();
    assert!(text.starts_with("u_px,v_px,strength\n") && text.lines().count() > 50, "{text}");
}

#[test]
fn session_errors_name_the_input() {
    let dir = scratch("session_errors");
    // No session.yaml: bad input.
    let output = alacs(&["calibrate", "camera", "--session", dir.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("session.yaml"), "{}", stderr(&output));
    // A session whose images hold no board: the job fails (exit 1) with the reason.
    std::fs::write(
        dir.join("session.yaml"),
        "board: {inner_corners: [9, 6], square_mm: 25}\nviews: [{image: a.png}, {image: b.png}, {image: c.png}]\n",
    )
    .unwrap();
    for name in ["a.png", "b.png", "c.png"] {
        image_like_grey(&dir.join(name));
    }
    let output = alacs(&["calibrate", "camera", "--session", dir.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    assert!(stderr(&output).contains("no 9 x 6 checkerboard"), "{}", stderr(&output));
    // A missing image: bad input naming it.
    std::fs::remove_file(dir.join("b.png")).unwrap();
    let output = alacs(&["calibrate", "camera", "--session", dir.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("b.png"), "{}", stderr(&output));
    // --session without --camera for the laser: usage error.
    let output = alacs(&["calibrate", "laser", "--session", dir.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    // A stripe --roi that makes no sense.
    let output =
        alacs(&["stripe", "--image", dir.join("a.png").to_str().unwrap(), "--roi", "5,5,1"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("--roi"), "{}", stderr(&output));
}

/// A uniform grey PNG: a view without a board.
fn image_like_grey(path: &Path) {
    image::RgbImage::from_pixel(320, 240, image::Rgb([90, 90, 90])).save(path).unwrap();
}

#[test]
fn scan_sim_json_localizes_the_simulated_apple_and_writes_a_scan_folder() {
    let dir = scratch("scan_sim");
    let out = dir.join("scan");
    let template = "scan --sim --scale 0.25 --rgbd-to-alacs -40,-60,-10,2,5,0 --out {} --json";
    let output = alacs(&cmdline(template, &[&out]));
    let json = stdout_json(&output);
    for key in ["position_mm", "radius_mm", "candidates", "selected", "status", "reason"] {
        assert!(json.get(key).is_some(), "missing {key} in {json}");
    }
    assert_eq!(json["status"], "ok", "{json}");
    let position: Vec<f64> =
        json["position_mm"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let truth: Vec<f64> = json["truth"]["position_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let error: Vec<f64> =
        json["error_mm"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    for axis in 0..3 {
        assert!((position[axis] - truth[axis] - error[axis]).abs() < 1e-9);
    }
    // A quarter of the 5 MP camera's resolution (612 x 512 px): seed 0
    // measures 3.3 mm; the pixels are four times the full camera's.
    assert!(json["error_3d_mm"].as_f64().unwrap() < 8.0, "{json}");
    assert!(json["truth"]["radius_mm"].as_f64().unwrap() > 30.0);
    // The folder reads back as a scan of FORMATS.md at the reported slides.
    let scan = alacs::Scan::read(&out).unwrap();
    assert_eq!(scan.frames.len(), 5);
    for (frame, slide) in scan.frames.iter().zip(json["slides_mm"].as_array().unwrap()) {
        assert_eq!(frame.slide_mm, slide.as_f64().unwrap());
        assert!(scan.path_of(&frame.image).is_file());
    }
    for file in ["camera.yaml", "laser.yaml", "truth.json"] {
        assert!(out.join(file).is_file(), "{file}");
    }
    // The true camera and laser are a simulation's shortcut, and said so.
    assert!(stderr(&output).contains("calibrated camera.yaml"), "{}", stderr(&output));

    // `alacs localize` on the written folder gives the same answer.
    let (camera, laser) = (out.join("camera.yaml"), out.join("laser.yaml"));
    let localize = |extra: &[&str]| alacs(&with(localize(&out, &camera, &laser), extra));
    let again = stdout_json(&localize(&["--json"]));
    assert_eq!(again["status"], "ok", "{again}");
    for axis in 0..3 {
        let p = again["position_mm"][axis].as_f64().unwrap();
        assert!((p - position[axis]).abs() < 1e-6, "{again}");
    }
    let text = localize(&[]);
    assert_eq!(text.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&text.stdout).contains("fruit at"));

    // `alacs report scan` on the written folder: the page, its images, the same answer.
    let report_dir = dir.join("report");
    let report = report_scan(&out, &camera, &laser, &report_dir);
    let report = stdout_json(&alacs(&with(report, &["--json"])));
    assert_eq!(report["html"], report_dir.join("index.html").to_str().unwrap(), "{report}");
    assert_eq!(report["files"].as_array().unwrap().len(), 7, "{report}");
    for file in report["files"].as_array().unwrap() {
        assert!(std::fs::metadata(file.as_str().unwrap()).unwrap().len() > 0, "{file}");
    }
    assert_eq!(report["localization"]["status"], "ok");
    for axis in 0..3 {
        let p = report["localization"]["position_mm"][axis].as_f64().unwrap();
        assert!((p - position[axis]).abs() < 1e-6, "{report}");
    }

    // The stripe of an orchard frame, with the settings localize uses.
    let frame = scan.path_of(&scan.frames[2].image);
    let stripe = alacs(&["stripe", "--image", frame.to_str().unwrap(), "--orchard", "--json"]);
    let stripe = stdout_json(&stripe);
    assert!(!stripe["points"].as_array().unwrap().is_empty(), "{stripe}");
}

#[test]
fn localize_bad_input_exits_2_naming_the_file() {
    let dir = scratch("localize_bad");
    let camera = write(&dir, "camera.yaml", "not: [a camera");
    let missing = dir.join("no_such_scan");
    let output = alacs(&localize(&missing, &camera, &camera));
    assert_eq!(output.status.code(), Some(2));
    assert!(output.stdout.is_empty());
    assert!(stderr(&output).contains("scan.yaml"), "{}", stderr(&output));
}

#[test]
fn report_bad_input_exits_2_naming_the_file() {
    let dir = scratch("report_bad");
    let missing = dir.join("no_such_scan");
    let camera = dir.join("camera.yaml");
    let out = dir.join("out");
    let output = alacs(&with(report_scan(&missing, &camera, &camera, &out), &["--json"]));
    assert_eq!(output.status.code(), Some(2));
    assert_error_json(&output, 2);
    assert!(stderr(&output).contains("no_such_scan"), "{}", stderr(&output));
    let missing = dir.join("no_such_session");
    let template = "report calibration --session {} --camera {} --laser {} --out {}";
    let output = alacs(&cmdline(template, &[&missing, &camera, &camera, &out]));
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("no_such_session"), "{}", stderr(&output));
    assert!(!out.exists(), "nothing written for unreadable input");
}

#[test]
fn scan_without_a_rig_exits_2_naming_both_rigs() {
    let output = alacs(&["scan"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(output.stdout.is_empty());
    let message = stderr(&output);
    assert!(message.contains("--sim") && message.contains("--rig rig.toml"), "{message}");
    let output = alacs(&["scan", "--sim", "--rgbd-to-alacs", "1,2,3"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("--alacs-from-rgbd"), "{}", stderr(&output));
}

#[test]
fn an_output_folder_with_foreign_files_is_refused_unless_forced() {
    // Regression: simulate and report wrote silently into existing folders.
    let dir = scratch("foreign_folder");
    let out = dir.join("samples");
    let out_s = out.to_str().unwrap();
    assert!(alacs(&["simulate", "samples", "--out", out_s]).status.success());
    // Its own earlier output: replaced.
    assert!(alacs(&["simulate", "samples", "--out", out_s, "--seed", "3"]).status.success());
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let output = alacs(&["simulate", "samples", "--out", out_s, "--json"]);
    assert_eq!(output.status.code(), Some(2));
    assert_error_json(&output, 2);
    assert!(stderr(&output).contains("notes.txt") && stderr(&output).contains("--force"));
    assert!(alacs(&["simulate", "samples", "--out", out_s, "--force"]).status.success());
    assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
}

#[test]
fn a_write_cut_short_leaves_the_old_laser_yaml_whole() {
    // Regression: with a file-size limit (or a full disk) an existing
    // `-o laser.yaml` was left at 0 bytes.
    let dir = scratch("cut_short");
    let samples = simulated_samples(&dir.join("sim"), "4");
    let laser = dir.join("laser.yaml");
    std::fs::write(&laser, "model: low-fidelity\nalpha_deg: 20\nl0_mm: 380\n").unwrap();
    let script = format!(
        "ulimit -f 0; exec {} calibrate laser --samples {samples} -o {}",
        env!("CARGO_BIN_EXE_alacs"),
        laser.display()
    );
    let output = Command::new("sh").args(["-c", &script]).output().unwrap();
    assert!(!output.status.success());
    assert_eq!(
        std::fs::read_to_string(&laser).unwrap(),
        "model: low-fidelity\nalpha_deg: 20\nl0_mm: 380\n"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.len() <= 1, "{leftovers:?}");
}

#[test]
fn session_init_lists_the_folders_images_and_refuses_to_overwrite() {
    let dir = scratch("session_init");
    for name in ["view01.png", "view01_off.png", "view02.png"] {
        image_like_grey(&dir.join(name));
    }
    let d = dir.to_str().unwrap();
    let template = "session init {} --board 9x6 --square-mm 25 --slide-mm 50 --json";
    let output = alacs(&cmdline(template, &[&d]));
    let json = stdout_json(&output);
    assert_eq!(json["n_views"], 2, "{json}");
    let session = alacs::Session::read(&dir).unwrap();
    assert_eq!(session.board.cols, 9);
    assert_eq!(session.views[0].image_laser_off.as_deref(), Some(Path::new("view01_off.png")));
    assert!(session.views.iter().all(|v| v.slide_mm == 50.0));
    let again = alacs(&["session", "init", d, "--board", "9x6", "--square-mm", "25"]);
    assert_eq!(again.status.code(), Some(2));
    assert!(stderr(&again).contains("--force"), "{}", stderr(&again));
    let bad = alacs(&["session", "init", d, "--board", "nine", "--square-mm", "25", "--force"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("--board"), "{}", stderr(&bad));
    let template =
        "session init {} --board 9x6 --square-mm 25 --charuco 5x5_100 --marker-mm 18.75 --force";
    assert_eq!(alacs(&cmdline(template, &[&d])).status.code(), Some(0));
    let markers = alacs::Session::read(&dir).unwrap().board.markers.unwrap();
    assert_eq!((markers.marker_mm, markers.dictionary.as_str()), (18.75, "DICT_5X5_100"));
}

/// A scan naming several fruit (scan.yaml's `targets`: a cluster of three
/// from `simulate scan --all-targets`, one sweep over all): `localize`
/// answers each in scan.yaml's order, within 15 mm of that fruit and
/// nearer it than any other, or `not_found`; `--points` writes a cloud per
/// fruit.
#[test]
fn localize_answers_each_fruit_a_scan_names() {
    let dir = scratch("targets");
    let scan = dir.join("scan");
    let template = "simulate scan --seed 3 --cluster 2 --all-targets --scale 0.4 --out {} --json";
    stdout_json(&alacs(&cmdline(template, &[&scan])));
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(scan.join("truth.json")).unwrap()).unwrap();
    let fruit: Vec<[f64; 3]> = truth["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| std::array::from_fn(|i| t["position_mm"][i].as_f64().unwrap()))
        .collect();
    assert_eq!(fruit.len(), 3, "{truth}");
    let scan_yaml = std::fs::read_to_string(scan.join("scan.yaml")).unwrap();
    assert!(scan_yaml.contains("targets:"), "{scan_yaml}");
    let cloud = dir.join("cloud.ply");
    let (camera, laser) = (scan.join("camera.yaml"), scan.join("laser.yaml"));
    let args =
        with(localize(&scan, &camera, &laser), &["--json", "--points", arg(&cloud).as_str()]);
    let json = stdout_json(&alacs(&args));
    assert_eq!(json["n_targets"], 3, "{json}");
    let distance = |p: &Value, q: &[f64; 3]| {
        (0..3).map(|i| (p[i].as_f64().unwrap() - q[i]).powi(2)).sum::<f64>().sqrt()
    };
    let mut found = 0;
    for (k, answer) in json["targets"].as_array().unwrap().iter().enumerate() {
        assert_eq!(answer["target"], k);
        assert!(dir.join(format!("cloud.target{k}.ply")).is_file());
        if answer["status"] != "ok" {
            assert!(!answer["reason"].as_str().unwrap().is_empty());
            continue;
        }
        found += 1;
        let error = distance(&answer["position_mm"], &fruit[k]);
        eprintln!("target {k}: {error:.2} mm ({})", answer["reason"]);
        assert!(error < 15.0, "target {k}: {error:.1} mm off: {answer}");
        for (j, other) in fruit.iter().enumerate().filter(|(j, _)| *j != k) {
            assert!(
                distance(&answer["position_mm"], other) > error,
                "target {k} answered fruit {j}"
            );
        }
    }
    assert_eq!(json["n_found"], found);
    // A regression guard, not a rate.
    assert!(found >= 2, "{json}");
    // The scan report is about one fruit: --target picks it, and one beyond them is refused.
    let report = dir.join("report");
    let args = with(report_scan(&scan, &camera, &laser, &report), &["--target", "1", "--json"]);
    let page = stdout_json(&alacs(&args));
    assert_eq!(page["localization"]["position_mm"], json["targets"][1]["position_mm"]);
    let args = with(report_scan(&scan, &camera, &laser, &report), &["--target", "3", "--force"]);
    let output = alacs(&args);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("3 fruit"), "{}", stderr(&output));
}

/// `alacs scan --sim --cluster 2 --all-targets`: one sweep over the three
/// apples of a cluster, each answered with its truth and error; the scan
/// folder names them all; a recording, which holds one fruit per scan, is
/// refused before the rig moves.
#[test]
fn scan_sim_all_targets_sweeps_a_cluster_once_and_answers_each() {
    let dir = scratch("scan_targets");
    let out = dir.join("scan");
    let template = "scan --sim --scale 0.4 --seed 3 --cluster 2 --all-targets --out {} --json";
    let json = stdout_json(&alacs(&cmdline(template, &[&out])));
    assert_eq!(json["n_targets"], 3, "{json}");
    let slides = json["slides_mm"].as_array().unwrap().len();
    assert!((6..=15).contains(&slides), "{json}");
    let mut found = 0;
    for target in json["targets"].as_array().unwrap() {
        assert!(target["truth"]["position_mm"].is_array(), "{target}");
        if target["status"] == "ok" {
            let error = target["error_3d_mm"].as_f64().unwrap();
            assert!(error < 15.0, "{target}");
            found += 1;
        }
    }
    assert!(found >= 2, "{json}");
    assert!(std::fs::read_to_string(out.join("scan.yaml")).unwrap().contains("targets:"));
    let bag = dir.join("scan.mcap");
    let template = "scan --sim --scale 0.4 --seed 3 --cluster 2 --all-targets --record {}";
    let output = alacs(&cmdline(template, &[&bag]));
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("one fruit per scan"), "{}", stderr(&output));
    assert!(!bag.exists());
}

/// `--help` is read by users of the binary alone: its footer names the
/// built-in contract (`alacs formats`) and the exit codes, not a file of
/// the source tree; simulator knobs stand under their own heading in
/// `ros` and `rig check`, not among the node's or rig's options.
#[test]
fn help_points_to_the_built_in_contract_and_groups_the_simulator() {
    for command in [&["ros", "--help"][..], &["rig", "check", "--help"], &["localize", "--help"]] {
        let output = alacs(command);
        assert!(output.status.success());
        let text = String::from_utf8_lossy(&output.stdout);
        assert!(text.contains("`alacs formats`") && text.contains("Exit codes"), "{text}");
        assert!(!text.contains("source repository"), "{text}");
        if command[0] != "localize" {
            let heading = text.find("Simulated scene").expect("a heading for the scene");
            assert!(text.find("--occlusion").unwrap() > heading, "{text}");
        }
    }
    let output = alacs(&["formats"]);
    assert!(output.status.success());
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.contains("## Exit codes") || text.contains("exit code"), "{}", &text[..200]);
    assert!(text.contains("scan.yaml") && text.contains("laser.yaml"));
}

/// `--randomize` draws the rig from the seed: truth.json records what was
/// drawn, the folder holds the calibration the localizer is given (not the
/// drawn one), and the same seed draws the same rig.
#[test]
fn simulate_scan_randomize_records_the_drawn_rig_in_truth_json() {
    let dir = scratch("randomize");
    let truth_of = |name: &str, extra: &str| -> Value {
        let out = dir.join(name);
        let template = format!("simulate scan --seed 5 --scale 0.25 {extra} --out {{}} --json");
        let output = alacs(&cmdline(&template, &[&out]));
        assert!(output.status.success(), "{}", stderr(&output));
        serde_json::from_str(&std::fs::read_to_string(out.join("truth.json")).unwrap()).unwrap()
    };
    let drawn = truth_of("a", "--randomize");
    let variation = &drawn["variation"];
    for key in ["fruit_colour", "stripe_sigma_px", "blur_sigma_px", "alpha_error_deg"] {
        assert!(variation.get(key).is_some(), "missing {key} in {variation}");
    }
    assert_eq!(truth_of("b", "--randomize")["variation"], *variation, "one seed, one rig");
    assert!(truth_of("c", "").get("variation").is_none(), "a fixed renderer draws nothing");
}
