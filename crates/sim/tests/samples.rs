//! Simulated calibration samples stay within what the readers take: a
//! samples.csv at the simulator's limit is one `calibrate laser` reads.

#![allow(clippy::unwrap_used)]

use alacs_model::io::MAX_TEXT_INPUT_BYTES;
use alacs_model::{Camera, LaserModel, samples_csv_string};
use alacs_sim::{MAX_SAMPLE_ROW_BYTES, MAX_SAMPLES, SampleOptions, simulate_samples};

#[test]
fn samples_at_the_simulators_limit_fit_the_readers_limit() {
    assert!(MAX_SAMPLES as u64 * MAX_SAMPLE_ROW_BYTES as u64 <= MAX_TEXT_INPUT_BYTES);
    // The longest rows the simulator writes: far boards, many slide
    // positions, noise and outliers, view numbers in the thousands.
    let options = SampleOptions {
        n_views: 2000,
        points_per_view: 20,
        depth_mm: (600.0, 1500.0),
        outlier_fraction: 0.3,
        slides_mm: vec![0.0, 33.3, 66.7, 123.456],
        seed: 11,
        ..SampleOptions::default()
    };
    let sim =
        simulate_samples(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options).unwrap();
    let text = samples_csv_string(&sim.samples);
    let longest = text.lines().skip(1).map(str::len).max().unwrap();
    // With its newline.
    assert!(longest < MAX_SAMPLE_ROW_BYTES, "a row of {longest} bytes");
}
