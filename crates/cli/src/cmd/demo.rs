//! `alacs demo`: the main job on the built-in simulator.
//!
//! 1. Simulates the seed paper's calibration experiment (10 board poses at
//!    0.6-1.2 m, 3 laser points each, 0.5 mm depth noise) with 30 % gross
//!    outliers, and calibrates with all four methods (Table 1).
//! 2. Repeats the paper's accuracy experiment: points on boards at 0.6-1.2 m
//!    with the laser at d = 0, 50, ..., 200 mm, triangulated with the Method 4
//!    calibration and compared with the truth in x, y and z.

use alacs::sim::{SampleOptions, simulate_samples};
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

/// Runs `alacs demo`.
pub fn run(args: &DemoArgs) -> CmdResult {
    let camera = Camera::blackfly_s_5mp();
    let truth = LaserModel::from_degrees(Fidelity::High, TRUE_ALPHA_DEG, TRUE_BETA_DEG, TRUE_L0_MM);
    let bar = output::progress_bar(args.json, "calibrating");
    output::start_progress(&bar, 1 + ACCURACY_SLIDES_MM.len(), "calibrating");

    bar.set_message("calibrating: four methods on simulated samples with 30 % outliers");
    let sample_options =
        SampleOptions { outlier_fraction: 0.3, seed: args.seed, ..SampleOptions::default() };
    let sim = simulate_samples(&camera, &truth, &sample_options)?;
    let results = alacs::compare(&sim.samples, &CalibrationOptions::default())?;
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
    bar.finish_and_clear();

    if args.json {
        let value = json!({
            "truth": {"alpha_deg": TRUE_ALPHA_DEG, "beta_deg": TRUE_BETA_DEG, "l0_mm": TRUE_L0_MM},
            "n_samples": sim.samples.len(),
            "outliers": sim.outliers,
            "methods": results.iter().map(output::calibration_json).collect::<Vec<Value>>(),
            "accuracy": accuracy.iter().map(|a| json!({
                "slide_mm": a.slide_mm,
                "n_points": a.n,
                "max_abs_error_mm": {"x": a.max_mm[0], "y": a.max_mm[1], "z": a.max_mm[2]},
                "mean_abs_error_mm": {"x": a.mean_mm[0], "y": a.mean_mm[1], "z": a.mean_mm[2]},
            })).collect::<Vec<Value>>(),
        });
        output::print_json(&value);
        return Ok(());
    }

    println!(
        "Calibration (the seed paper's Table 1) on {} simulated samples, {} of them gross outliers:",
        sim.samples.len(),
        sim.outliers.len()
    );
    print!("{}", output::table_1(&results));
    println!(
        "{:<44} {:>11.2} {:>9.2} {:>10.2}",
        "Truth", TRUE_ALPHA_DEG, TRUE_L0_MM, TRUE_BETA_DEG
    );
    println!(
        "Method 4 rejected {outliers_found} of the {} planted outliers.\n",
        sim.outliers.len()
    );
    println!(
        "Accuracy of triangulated points with the Method 4 calibration (boards at 0.6-1.2 m;\n\
         noise-free laser pixels, so what remains is the calibration's error):"
    );
    println!(
        "{:>8} {:>7}   {:>24}   {:>24}",
        "d (mm)", "points", "max |error| x/y/z (mm)", "mean |error| x/y/z (mm)"
    );
    for a in &accuracy {
        println!(
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
    println!("(the seed paper reports worst cases below 0.6 / 1.2 / 4 mm in x / y / z)");
    Ok(())
}
