//! Measures the two least-squares residuals against each other: RMS error
//! of the fitted parameters over 500 simulated paper-like sample sets
//! (30 samples, 0.5 mm depth noise, 20 % outliers, Method 4).
//!
//! `cargo run --release -p alacs-calib --example residual_choice`

use alacs_calib::{CalibrationOptions, Method, Residual, calibrate};
use alacs_model::{Camera, LaserModel};
use alacs_sim::{SampleOptions, simulate_samples};

const SETS: u64 = 500;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let truth = LaserModel::seed_paper();
    let camera = Camera::blackfly_s_5mp();
    println!("| residual | alpha (deg) | beta (deg) | L0 (mm) | mean abs z error (mm) |");
    println!("|---|---|---|---|---|");
    for residual in [Residual::Depth, Residual::PlaneDistance] {
        let options = CalibrationOptions { residual, ..CalibrationOptions::default() };
        let (mut squared, mut mean_error) = ([0.0f64; 3], 0.0);
        for seed in 0..SETS {
            let samples = SampleOptions { outlier_fraction: 0.2, seed, ..SampleOptions::default() };
            let sim = simulate_samples(&camera, &truth, &samples)?;
            let fit = calibrate(&sim.samples, Method::HighFidelityRansac, &options)?;
            let errors = [
                fit.laser.alpha_deg() - truth.alpha_deg(),
                fit.laser.beta_deg() - truth.beta_deg(),
                fit.laser.l0_mm - truth.l0_mm,
            ];
            for (sum, e) in squared.iter_mut().zip(errors) {
                *sum += e * e;
            }
            mean_error += fit.mean_abs_error_mm;
        }
        let rms = squared.map(|s| (s / SETS as f64).sqrt());
        println!(
            "| {} | {:.4} | {:.4} | {:.3} | {:.3} |",
            residual.as_str(),
            rms[0],
            rms[1],
            rms[2],
            mean_error / SETS as f64
        );
    }
    Ok(())
}
