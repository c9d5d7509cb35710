//! Method 4 (high fidelity + RANSAC + LM refit) on the paper's 30 samples and
//! on 100,000 dense samples, both with 30 % gross outliers.
//! Run with `cargo bench -p alacs-calib`.

// criterion's macros generate undocumented items; a bench without its data
// cannot run, so it panics.
#![allow(missing_docs, clippy::panic)]

use alacs_calib::{CalibrationOptions, Method, calibrate};
use alacs_model::{Camera, LaserModel};
use alacs_sim::{SampleOptions, simulate_samples};
use criterion::{Criterion, criterion_group, criterion_main};

fn samples(n_views: usize, points_per_view: usize) -> Vec<alacs_calib::LaserSample> {
    let laser = LaserModel::seed_paper();
    let options = SampleOptions {
        n_views,
        points_per_view,
        outlier_fraction: 0.3,
        seed: 1,
        ..SampleOptions::default()
    };
    match simulate_samples(&Camera::blackfly_s_5mp(), &laser, &options) {
        Ok(sim) => sim.samples,
        Err(e) => panic!("simulating samples: {e}"),
    }
}

fn method_4(c: &mut Criterion) {
    let options = CalibrationOptions::default();
    for (name, data) in
        [("method4_30_samples", samples(10, 3)), ("method4_100k_samples", samples(200, 500))]
    {
        c.bench_function(name, |b| {
            b.iter(|| calibrate(std::hint::black_box(&data), Method::HighFidelityRansac, &options))
        });
    }
}

criterion_group!(benches, method_4);
criterion_main!(benches);
