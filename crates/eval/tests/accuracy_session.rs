//! The accuracy experiment on a simulated 5-position session (the seed
//! paper's d = 0, 50, ..., 200 mm): the JSON agrees with the box plots'
//! inputs, the errors are small, and the depth error's spread grows with d
//! as the noise floor sigma_z = z^2 cos(alpha) sigma_px / (f L) predicts.
//!
//! Half-scale renders (1224 x 1024 px, f = 1160 px) of 6 board poses keep it
//! to a few seconds; the evaluated laser and camera are the simulation's
//! truth, so what remains is the stripe centre's and the board pose's noise.

use std::path::PathBuf;

use alacs_eval::{
    AccuracyOptions, BoxStats, OutputKind, PointsPerView, evaluate_accuracy, open_output,
    write_accuracy_report,
};
use alacs_model::{Camera, Fidelity, LaserModel, Session};
use alacs_sim::{SessionOptions, simulate_session};

const SLIDES_MM: [f64; 5] = [0.0, 50.0, 100.0, 150.0, 200.0];

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("alacs-eval-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    dir
}

#[test]
fn five_slide_positions_agree_with_the_noise_floor() {
    let truth = LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98);
    let options = SessionOptions {
        n_views: 6,
        slides_mm: SLIDES_MM.to_vec(),
        scale: 0.5,
        seed: 11,
        ..SessionOptions::default()
    };
    let simulated = simulate_session(&Camera::blackfly_s_5mp(), &truth, &options).unwrap();
    let dir = temp_dir("session");
    simulated.write(&dir).unwrap();
    let session = Session::read(&dir).unwrap();

    let eval =
        evaluate_accuracy(&session, &simulated.camera, &truth, &AccuracyOptions::default(), &|| {})
            .unwrap();
    let out = dir.join("report");
    let mut output = open_output(&out, OutputKind::EvaluateAccuracy, false).unwrap();
    let files = write_accuracy_report(&mut output, &eval).unwrap();
    output.finish().unwrap();
    for file in &files {
        assert!(std::fs::metadata(file).unwrap().len() > 0, "{}", file.display());
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("accuracy.json")).unwrap()).unwrap();

    assert_eq!(eval.slides.len(), 5);
    println!("measured stripe noise {:.3} px", eval.measured_sigma_px);
    println!(
        "   d    n  median z    IQR z  sigma_z in-view  predicted  in-view px   max|x|   max|y|   max|z|  (mm)"
    );
    for (k, slide) in eval.slides.iter().enumerate() {
        assert_eq!(slide.slide_mm, SLIDES_MM[k]);
        // The JSON holds the statistics of exactly what the box plot draws.
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            let stats = BoxStats::from_values(&eval.errors_at(slide.slide_mm, axis)).unwrap();
            assert_eq!(stats, slide.error_mm[axis]);
            let j = &json["slides"][k][name];
            assert_eq!(j["n"].as_u64().unwrap() as usize, stats.n);
            for (key, value) in [
                ("median_mm", stats.median),
                ("q1_mm", stats.q1),
                ("q3_mm", stats.q3),
                ("min_mm", stats.min),
                ("max_mm", stats.max),
                ("mean_mm", stats.mean),
                ("rms_mm", stats.rms),
            ] {
                assert!((j[key].as_f64().unwrap() - value).abs() < 1e-12, "{name} {key}");
            }
        }
        let [x, y, z] = slide.error_mm;
        println!(
            "{:>4.0} {:>4} {:>9.4} {:>8.4} {:>16.4} {:>10.4} {:>11.3} {:>8.3} {:>8.3} {:>8.3}",
            slide.slide_mm,
            z.n,
            z.median,
            z.iqr(),
            slide.within_view_sigma_z_mm,
            slide.predicted_sigma_z_mm,
            slide.within_view_sigma_px,
            x.min.abs().max(x.max.abs()),
            y.min.abs().max(y.max.abs()),
            z.min.abs().max(z.max.abs()),
        );
        println!(
            "      x median {:.4} IQR {:.4}, y median {:.4} IQR {:.4}",
            x.median,
            x.iqr(),
            y.median,
            y.iqr()
        );
        assert!(z.n > 300, "d = {}: {} points", slide.slide_mm, z.n);
        // Unbiased: the true laser, so only noise remains (medians within
        // 0.05 mm in x and y and 0.1 mm in z; measured up to 0.0004, 0.0011
        // and 0.02 mm).
        assert!(x.median.abs() < 0.05 && y.median.abs() < 0.05, "d = {}", slide.slide_mm);
        assert!(z.median.abs() < 0.1, "d = {}: median z {}", slide.slide_mm, z.median);
        // Small: the middle half of the points within 0.6 mm in z, 0.2 mm in
        // x and y (measured IQR 0.23-0.37 mm in z, under 0.06 mm in x and y).
        assert!(z.iqr() < 0.6 && x.iqr() < 0.2 && y.iqr() < 0.2, "d = {}", slide.slide_mm);
        // The stripe's share of the depth error is the noise floor's
        // prediction within 25 % (measured ratios 0.89-1.15).
        // Regression, stripe points with a square's edge under the profile:
        // their biased centres made the worst depth errors 7-14 mm here;
        // dropped, the worst are 1.3-4.0 mm.
        assert!(z.min.abs().max(z.max.abs()) < 5.0, "d = {}: worst z", slide.slide_mm);
        let ratio = slide.within_view_sigma_z_mm / slide.predicted_sigma_z_mm;
        assert!((0.75..1.33).contains(&ratio), "d = {}: ratio {ratio}", slide.slide_mm);
    }
    // The stripe noise in pixels: 0.05-0.15 px (measured 0.089 px on these
    // half-scale renders; 0.061 px RMS on full-scale boards in docs/calibration.md).
    assert!((0.05..0.15).contains(&eval.measured_sigma_px), "{}", eval.measured_sigma_px);
    // The depth error grows with d as L = L0 - d shrinks: predicted 1.9 x
    // from d = 0 to 200 mm, measured 1.5 x; the far half of the stroke
    // spreads at least 20 % more than the near half.
    let sigma = |k: usize| eval.slides[k].within_view_sigma_z_mm;
    let predicted = |k: usize| eval.slides[k].predicted_sigma_z_mm;
    assert!(predicted(4) > 1.7 * predicted(0));
    for k in 1..5 {
        assert!(predicted(k) > predicted(k - 1));
    }
    assert!(sigma(4) > 1.3 * sigma(0), "{} vs {}", sigma(4), sigma(0));
    assert!(sigma(3) + sigma(4) > 1.2 * (sigma(0) + sigma(1)));

    // Points per view: 3 gives 3 per view (fewer where the stripe has fewer).
    let three = AccuracyOptions { points: PointsPerView::Three, ..AccuracyOptions::default() };
    let eval3 = evaluate_accuracy(&session, &simulated.camera, &truth, &three, &|| {}).unwrap();
    let expected: usize = eval.views.iter().map(|v| v.n_samples.min(3)).sum();
    assert_eq!(eval3.points.len(), expected);
    if std::env::var_os("ALACS_EVAL_KEEP").is_none() {
        std::fs::remove_dir_all(&dir).ok();
    }
}
