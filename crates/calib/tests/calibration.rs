//! Calibration against simulator ground truth. Tolerances follow from the
//! noise put in: 0.5 mm depth noise on 30 samples gives standard deviations
//! of about 0.02 deg in alpha and beta and 0.2 mm in L0 (see the
//! `standard_deviations_cover_the_truth` test), so the 0.1 deg / 1 mm
//! acceptance bounds sit at about five sigma.

// Test helpers outside #[test] functions may fail loudly too.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use alacs_calib::{
    CalibrationOptions, Error, LaserSample, Method, Residual, calibrate, compare, parse_samples_csv,
};
use alacs_model::{Camera, Fidelity, LaserModel};
use alacs_sim::{SampleOptions, SimulatedSamples, simulate_samples};

fn paper_laser() -> LaserModel {
    LaserModel::seed_paper()
}

fn simulate(options: SampleOptions) -> SimulatedSamples {
    simulate_samples(&Camera::blackfly_s_5mp(), &paper_laser(), &options).unwrap()
}

fn paper_like(outlier_fraction: f64, seed: u64) -> SimulatedSamples {
    simulate(SampleOptions { outlier_fraction, seed, ..SampleOptions::default() })
}

fn assert_close_to_truth(
    fit: &LaserModel,
    truth: &LaserModel,
    angle_deg: f64,
    l0_mm: f64,
    what: &str,
) {
    assert!(
        (fit.alpha_deg() - truth.alpha_deg()).abs() < angle_deg
            && (fit.beta_deg() - truth.beta_deg()).abs() < angle_deg
            && (fit.l0_mm - truth.l0_mm).abs() < l0_mm,
        "{what}: fitted alpha {:.4} deg, beta {:.4} deg, L0 {:.3} mm; truth {:.4}, {:.4}, {:.3}",
        fit.alpha_deg(),
        fit.beta_deg(),
        fit.l0_mm,
        truth.alpha_deg(),
        truth.beta_deg(),
        truth.l0_mm
    );
}

#[test]
fn exact_samples_give_the_exact_laser_with_every_high_fidelity_method() {
    let sim = simulate(SampleOptions { depth_noise_mm: 0.0, ..SampleOptions::default() });
    for method in [Method::HighFidelityAllData, Method::HighFidelityRansac] {
        let fit = calibrate(&sim.samples, method, &CalibrationOptions::default()).unwrap();
        assert_close_to_truth(&fit.laser, &paper_laser(), 1e-7, 1e-6, method.name());
        assert!(fit.mean_abs_error_mm < 1e-6);
        assert_eq!(fit.inliers.len(), 30);
    }
}

#[test]
fn low_fidelity_methods_recover_a_laser_without_beta() {
    let truth = LaserModel::from_degrees(Fidelity::Low, 19.03, 0.0, 382.83);
    let options = SampleOptions { depth_noise_mm: 0.0, ..SampleOptions::default() };
    let sim = simulate_samples(&Camera::blackfly_s_5mp(), &truth, &options).unwrap();
    for method in [Method::LowFidelityAllData, Method::LowFidelityRansac] {
        let fit = calibrate(&sim.samples, method, &CalibrationOptions::default()).unwrap();
        assert_eq!(fit.laser.fidelity, Fidelity::Low);
        assert_close_to_truth(&fit.laser, &truth, 1e-7, 1e-6, method.name());
    }
}

/// The core issue's acceptance: Method 4 within 0.1 deg and 1 mm at 0-40 %
/// outliers. With 18-30 inliers and 0.5 mm noise those bounds are 2-3 sigma
/// of the best possible fit (the least-squares fit on exactly the clean
/// samples), so they are required of 95 % of the seeds, while every seed
/// must agree with the truth within 4 of its own reported sigmas and reject
/// every planted outlier.
#[test]
fn method_4_recovers_the_paper_laser_at_0_to_40_percent_outliers() {
    let truth = paper_laser();
    let (mut within_bounds, mut total) = (0, 0);
    for fraction in [0.0, 0.1, 0.2, 0.3, 0.4] {
        for seed in 0..20 {
            let what = format!("{:.0} % outliers, seed {seed}", fraction * 100.0);
            let sim = paper_like(fraction, seed);
            let fit =
                calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
                    .unwrap();
            let std = fit.std_dev.unwrap();
            let errors = [
                (fit.laser.alpha_deg() - truth.alpha_deg()).abs(),
                (fit.laser.beta_deg() - truth.beta_deg()).abs(),
                (fit.laser.l0_mm - truth.l0_mm).abs(),
            ];
            let sigmas = [std.alpha_deg, std.beta_deg.unwrap(), std.l0_mm];
            for (error, sigma) in errors.iter().zip(sigmas) {
                assert!(*error < 4.0 * sigma, "{what}: error {error} > 4 sigma ({sigma})");
            }
            total += 1;
            within_bounds += usize::from(errors[0] < 0.1 && errors[1] < 0.1 && errors[2] < 1.0);
            // Planted outliers are 5-50 mm off, beyond the 2 mm threshold: all rejected.
            assert!(sim.outliers.iter().all(|i| !fit.inliers.contains(i)), "{what}");
        }
    }
    assert!(within_bounds * 100 >= 95 * total, "{within_bounds} of {total} within 0.1 deg / 1 mm");
}

/// What the paper's Table 1 shows: RANSAC improves each model, and Method 4 is best.
#[test]
fn compare_ranks_the_methods_as_table_1_on_contaminated_data() {
    for seed in 0..10 {
        let sim = paper_like(0.2, seed);
        let results = compare(&sim.samples, &CalibrationOptions::default()).unwrap().fitted;
        let error = |n: usize| results[n - 1].mean_abs_error_mm;
        assert!(error(2) < error(1), "seed {seed}: method 2 {} vs 1 {}", error(2), error(1));
        assert!(error(4) < error(3), "seed {seed}: method 4 {} vs 3 {}", error(4), error(3));
        assert!((1..=3).all(|m| error(4) < error(m)), "seed {seed}: method 4 not best");
        // Method 4's error is the noise floor: mean |N(0, 0.5)| = 0.4 mm.
        assert!(error(4) < 0.6, "seed {seed}: {}", error(4));
    }
}

#[test]
fn standard_deviations_cover_the_truth() {
    let (mut covered, mut total) = (0, 0);
    for seed in 0..40 {
        let sim = paper_like(0.2, seed);
        let fit =
            calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
                .unwrap();
        let std = fit.std_dev.unwrap();
        let truth = paper_laser();
        for (error, sigma) in [
            (fit.laser.alpha_deg() - truth.alpha_deg(), std.alpha_deg),
            (fit.laser.l0_mm - truth.l0_mm, std.l0_mm),
            (fit.laser.beta_deg() - truth.beta_deg(), std.beta_deg.unwrap()),
        ] {
            assert!(sigma > 0.0 && sigma.is_finite());
            total += 1;
            covered += usize::from(error.abs() <= 2.0 * sigma);
        }
    }
    // 95 % of a Gaussian lies within two sigma; allow for 40 small samples.
    assert!(covered as f64 >= 0.85 * total as f64, "{covered} of {total} within 2 sigma");
}

#[test]
fn several_slide_positions_fit_l0_jointly() {
    let sim = simulate(SampleOptions {
        n_views: 15,
        slides_mm: vec![0.0, 50.0, 100.0, 150.0, 200.0],
        outlier_fraction: 0.2,
        seed: 7,
        ..SampleOptions::default()
    });
    for method in [Method::HighFidelityAllData, Method::HighFidelityRansac] {
        let clean: Vec<LaserSample> = if method == Method::HighFidelityAllData {
            sim.samples
                .iter()
                .enumerate()
                .filter(|(i, _)| !sim.outliers.contains(i))
                .map(|(_, s)| *s)
                .collect()
        } else {
            sim.samples.clone()
        };
        let fit = calibrate(&clean, method, &CalibrationOptions::default()).unwrap();
        assert_close_to_truth(&fit.laser, &paper_laser(), 0.1, 1.0, method.name());
    }
}

#[test]
fn plane_distance_residual_also_recovers_the_laser() {
    let options =
        CalibrationOptions { residual: Residual::PlaneDistance, ..CalibrationOptions::default() };
    for seed in 0..10 {
        let sim = paper_like(0.3, seed);
        let fit = calibrate(&sim.samples, Method::HighFidelityRansac, &options).unwrap();
        assert_eq!(fit.residual, Residual::PlaneDistance);
        // 21 inliers: 0.15 deg / 1.5 mm is about 3 sigma (see the Method 4 test).
        assert_close_to_truth(
            &fit.laser,
            &paper_laser(),
            0.15,
            1.5,
            &format!("plane residual, seed {seed}"),
        );
    }
}

#[test]
fn dense_samples_with_many_outliers_calibrate_to_a_tenth_of_a_millimetre() {
    // 20 views x 500 points: issue 4's dense samples from images.
    let sim = simulate(SampleOptions {
        n_views: 20,
        points_per_view: 500,
        outlier_fraction: 0.4,
        seed: 3,
        ..SampleOptions::default()
    });
    let fit = calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
        .unwrap();
    assert_close_to_truth(&fit.laser, &paper_laser(), 0.01, 0.1, "10,000 samples");
    // Adaptive stopping: 60 % inliers, 3-point samples need about 30 hypotheses.
    assert!(fit.ransac_iterations.unwrap() < 100, "{:?}", fit.ransac_iterations);
}

#[test]
fn same_seed_same_result() {
    let sim = paper_like(0.3, 11);
    let a = calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
        .unwrap();
    let b = calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
        .unwrap();
    assert_eq!(a.laser, b.laser);
    assert_eq!(a.inliers, b.inliers);
}

fn sample(u_n: f64, v_n: f64, z_mm: f64) -> LaserSample {
    LaserSample { u_n, v_n, z_mm, slide_mm: 0.0, pose: None }
}

#[test]
fn too_few_samples_is_an_error_naming_the_counts() {
    let sim = paper_like(0.0, 1);
    let err =
        calibrate(&sim.samples[..3], Method::HighFidelityRansac, &CalibrationOptions::default())
            .unwrap_err();
    assert!(matches!(err, Error::TooFewSamples { got: 3, need: 4, .. }), "{err}");
    assert!(!err.is_bad_input());
    let err =
        calibrate(&[], Method::LowFidelityAllData, &CalibrationOptions::default()).unwrap_err();
    assert!(matches!(err, Error::TooFewSamples { got: 0, .. }), "{err}");
}

#[test]
fn samples_at_one_depth_are_degenerate() {
    let laser = paper_laser();
    let samples: Vec<LaserSample> = (0..30)
        .map(|i| {
            let v_n = -0.4 + 0.8 * f64::from(i) / 29.0;
            let z_mm = 800.0 + 0.1 * f64::from(i % 3);
            let u_n = (laser.alpha_rad.sin() - v_n * laser.beta_rad.tan() - laser.l0_mm / z_mm)
                / laser.alpha_rad.cos();
            sample(u_n, v_n, z_mm)
        })
        .collect();
    for method in Method::ALL {
        let err = calibrate(&samples, method, &CalibrationOptions::default()).unwrap_err();
        assert!(matches!(err, Error::Degenerate(_)), "{err}");
        assert!(err.to_string().contains("one depth"), "{err}");
    }
}

#[test]
fn collinear_laser_pixels_are_degenerate_for_the_high_fidelity_model() {
    // One tilted board: the laser line is one 3-D line, so its pixels are collinear.
    let laser = paper_laser();
    let samples: Vec<LaserSample> = (0..30)
        .map(|i| {
            let t = f64::from(i) / 29.0;
            let (u_n, v_n) = (-0.2 + 0.2 * t, -0.3 + 0.6 * t);
            sample(u_n, v_n, laser.depth_mm(&nalgebra::Point2::new(u_n, v_n), 0.0).unwrap())
        })
        .collect();
    let err = calibrate(&samples, Method::HighFidelityAllData, &CalibrationOptions::default())
        .unwrap_err();
    assert!(err.to_string().contains("collinear"), "{err}");
}

#[test]
fn non_finite_or_non_positive_samples_are_bad_input() {
    let refused = |samples: &[LaserSample]| {
        calibrate(samples, Method::HighFidelityRansac, &CalibrationOptions::default()).unwrap_err()
    };
    let invalid_sample = |err: &Error, i: usize| matches!(err, Error::Model(alacs_model::Error::InvalidSample { index, .. }) if *index == i);
    let mut samples = paper_like(0.0, 2).samples;
    samples[4].z_mm = f64::NAN;
    let err = refused(&samples);
    assert!(invalid_sample(&err, 4), "{err}");
    assert!(err.is_bad_input());
    samples[4].z_mm = -1.0;
    let err = refused(&samples);
    assert!(err.to_string().contains("positive"), "{err}");
    samples[4].z_mm = 900.0;
    samples[5].u_n = f64::INFINITY;
    let err = refused(&samples);
    assert!(invalid_sample(&err, 5), "{err}");
}

#[test]
fn samples_that_are_all_outliers_are_refused_not_calibrated() {
    // Regression: RANSAC kept 7 of 30 and reported alpha 15.7 deg (truth
    // 19.07) with exit 0.
    for seed in 1..=5 {
        let options = alacs_sim::SampleOptions {
            outlier_fraction: 1.0,
            seed,
            ..alacs_sim::SampleOptions::default()
        };
        let sim = alacs_sim::simulate_samples(
            &Camera::blackfly_s_5mp(),
            &LaserModel::seed_paper(),
            &options,
        )
        .unwrap();
        let err =
            calibrate(&sim.samples, Method::HighFidelityRansac, &CalibrationOptions::default())
                .unwrap_err();
        assert!(matches!(err, Error::NotBetterThanChance { .. }), "seed {seed}: {err}");
        assert!(!err.is_bad_input());
    }
}

#[test]
fn a_threshold_nothing_agrees_with_is_no_consensus() {
    let sim = paper_like(0.0, 3);
    let options = CalibrationOptions { threshold_mm: 1e-6, ..CalibrationOptions::default() };
    let err = calibrate(&sim.samples, Method::HighFidelityRansac, &options).unwrap_err();
    assert!(matches!(err, Error::NoConsensus { .. }), "{err}");
}

fn parse(text: &str) -> alacs_model::Result<Vec<LaserSample>> {
    parse_samples_csv(text.as_bytes(), Path::new("samples.csv"))
}

#[test]
fn samples_csv_reads_with_and_without_slide() {
    let samples = parse("u_n,v_n,z_mm\n0.1,0.2,800\n-0.1, 0.0 ,650.5\n").unwrap();
    assert_eq!(samples, vec![sample(0.1, 0.2, 800.0), sample(-0.1, 0.0, 650.5)]);
    let samples = parse("# comment\nz_mm,slide_mm,v_n,u_n,extra\n800,50,0.2,0.1,x\n").unwrap();
    assert_eq!(
        samples,
        vec![LaserSample { u_n: 0.1, v_n: 0.2, z_mm: 800.0, slide_mm: 50.0, pose: None }]
    );
    let round_trip = parse(&alacs_calib::samples_csv_string(&paper_like(0.1, 4).samples)).unwrap();
    assert_eq!(round_trip, paper_like(0.1, 4).samples);
}

#[test]
fn samples_csv_errors_name_the_file_line_and_problem() {
    let cases = [
        ("u_n,v_n\n0.1,0.2\n", "missing column `z_mm`"),
        ("u_n,v_n,z_mm\n0.1,0.2,800\n0.1,abc,800\n", "line 3"),
        ("u_n,v_n,z_mm\n0.1,0.2,NaN\n", "not a finite number"),
        ("u_n,v_n,z_mm\n0.1,0.2,inf\n", "not a finite number"),
        ("u_n,v_n,z_mm\n0.1,0.2,-5\n", "positive"),
        ("u_n,v_n,z_mm\n", "no samples"),
        ("", "missing column"),
        ("u_n,v_n,z_mm\n0.1,0.2\n", "line 2"),
    ];
    for (text, needle) in cases {
        let err = parse(text).unwrap_err();
        assert!(err.is_bad_input(), "{err}");
        let message = err.to_string();
        assert!(message.starts_with("samples.csv"), "{message}");
        assert!(message.contains(needle), "`{message}` should mention `{needle}`");
    }
    let err = alacs_calib::read_samples_csv(Path::new("/nonexistent/samples.csv")).unwrap_err();
    assert!(err.to_string().contains("/nonexistent/samples.csv"), "{err}");
}

/// A fuzzed CSV with values near f64::MAX made the linear solver's SVD panic
/// on NaN ("Singular value was NaN"); such values are now rejected as input.
#[test]
fn regression_huge_values_are_rejected_not_a_panic() {
    let err =
        parse("u_n,v_n,z_mm\n1e308,1e308,1e308\n-1e308,2,3\n0,0,1e-300\n5,5,5\n").unwrap_err();
    assert!(err.is_bad_input(), "{err}");
    let tiny_depths = [
        sample(0.1, 0.0, 1e-300),
        sample(-0.1, 0.1, 2e-300),
        sample(0.0, -0.2, 3e-300),
        sample(0.2, 0.3, 1e-299),
        sample(0.05, 0.2, 5e-300),
    ];
    for method in Method::ALL {
        // Either an error or a result: never a panic.
        let _ = calibrate(&tiny_depths, method, &CalibrationOptions::default());
    }
}

/// RMS depth error of `fit` against `truth` over the working volume: the
/// true laser's points at depths 600-1200 mm on image rows v_n -0.45..0.45
/// (a 5 MP camera's whole height), seen at slide 0.
fn working_volume_rms_mm(fit: &LaserModel, truth: &LaserModel) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for i in 0..=12 {
        let z = 600.0 + 50.0 * f64::from(i);
        for j in 0..=18 {
            let v_n = -0.45 + 0.05 * f64::from(j);
            // eq. (7): z = L / (sin a - u cos a - v tan b), solved for u.
            let u_n = (truth.alpha_rad.sin() - truth.l0_mm / z - v_n * truth.beta_rad.tan())
                / truth.alpha_rad.cos();
            let z_hat = fit.depth_mm(&nalgebra::Point2::new(u_n, v_n), 0.0).unwrap_or(f64::MAX);
            sum += (z_hat - z).powi(2);
            n += 1;
        }
    }
    (sum / n as f64).sqrt()
}

/// The seed's Table 1 ranking over the whole working volume, not only on
/// the samples: RANSAC improves each model (method 2 beats 1, 4 beats 3)
/// and method 4 is best, on 60 contaminated paper-like sets.
#[test]
fn table_1_ranking_holds_over_the_working_volume() {
    let truth = paper_laser();
    let mut failures = Vec::new();
    for fraction in [0.2, 0.3, 0.4] {
        for seed in 0..20 {
            let sim = paper_like(fraction, 700 + seed);
            let results = compare(&sim.samples, &CalibrationOptions::default()).unwrap().fitted;
            let e: Vec<f64> =
                results.iter().map(|r| working_volume_rms_mm(&r.laser, &truth)).collect();
            if !(e[1] < e[0] && e[3] < e[2] && e[3] < e[1]) {
                failures.push(format!(
                    "{fraction} seed {seed}: {:.2} {:.2} {:.2} {:.2} mm (inliers {:?})",
                    e[0],
                    e[1],
                    e[2],
                    e[3],
                    results.iter().map(|r| r.inliers.len()).collect::<Vec<_>>()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Issue 42, item 2: a method that cannot fit is a row with its reason, not
/// the end of the comparison. A laser tilted 20 deg in beta (the real
/// session's) defeats the low-fidelity model, and samples from three slide
/// positions with 20 % outliers can make Method 1's refinement diverge;
/// Method 4 still fits, so the comparison holds it and says why for the rest.
#[test]
fn compare_keeps_going_when_a_low_fidelity_method_cannot_fit() {
    let tilted = LaserModel::from_degrees(Fidelity::High, 19.07, 20.0, 381.98);
    let mut failures = 0;
    for seed in 0..6 {
        let options = SampleOptions {
            outlier_fraction: 0.2,
            slides_mm: vec![0.0, 100.0, 200.0],
            seed,
            ..SampleOptions::default()
        };
        let sim = simulate_samples(&Camera::blackfly_s_5mp(), &tilted, &options).unwrap();
        let comparison = compare(&sim.samples, &CalibrationOptions::default()).unwrap();
        let fit = comparison.get(Method::HighFidelityRansac).expect("Method 4 fits");
        assert!((fit.laser.beta_deg() - 20.0).abs() < 0.1, "seed {seed}: {}", fit.laser.beta_deg());
        assert_eq!(comparison.fitted.len() + comparison.failed.len(), 4, "seed {seed}");
        for (method, reason) in &comparison.failed {
            assert!(!reason.is_empty(), "seed {seed}: method {}", method.number());
        }
        failures += comparison.failed.len();
    }
    eprintln!("{failures} method runs could not fit, each a row with its reason");
}

/// Issue 43 item 9: one sample at another slide position (a mistyped
/// `slide_mm`) among 29 at one position made every minimal sample
/// degenerate ("explains 0 of 30"). A handful of strays cannot free the
/// slide scale: they are judged by the main position's model and rejected.
#[test]
fn one_stray_sample_at_another_slide_position_does_not_defeat_ransac() {
    let sim = paper_like(0.0, 3);
    let mut samples: Vec<LaserSample> = sim.samples.clone();
    let last = samples.len() - 1;
    samples[last].slide_mm += 100.0;
    let fit = calibrate(&samples, Method::HighFidelityRansac, &CalibrationOptions::default())
        .expect("the stray is an outlier, not the end of the fit");
    assert_eq!(fit.inliers.len(), samples.len() - 1, "the stray alone is rejected");
    assert!(!fit.inliers.contains(&last));
    assert_close_to_truth(&fit.laser, &paper_laser(), 0.1, 1.0, "with one stray sample");
}
