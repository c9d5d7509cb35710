//! The `localize --json` object ([`LocalizeOutput`]) on simulated scans.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use alacs_locate::{
    FrameImages, Localization, LocalizeOutput, LocateOptions, Method, Prior, Status, locate,
};
use alacs_model::Camera;
use alacs_sim::{ScanOptions, simulate_rendered_scan};
use common::{laser, locate_in_black_frames};
use serde_json::Value;

mod common;

/// FORMATS.md's keys (checked once against the object the command line
/// built by hand with `json!`, then that code was dropped), and read back
/// unchanged (exactly: serde_json's `float_roundtrip`).
fn check(answer: &Localization) {
    let output = LocalizeOutput::from(answer);
    let value = serde_json::to_value(&output).unwrap();
    let keys = |v: &Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>().join(" ");
    assert_eq!(
        keys(&value),
        "candidates frames fused fused_rejected holistic_selection method position_cov_mm2 position_mm radius_mm reason selected status"
    );
    assert_eq!(value["status"], answer.status.as_str());
    assert_eq!(value["method"], answer.method.as_str());
    // A covariance exactly when the fused method found the fruit.
    let fused_ok = answer.status == Status::Ok && answer.method == Method::Fused;
    assert_eq!(!value["position_cov_mm2"].is_null(), fused_ok, "{}", value["position_cov_mm2"]);
    if let Some(c) = value["candidates"].get(0) {
        assert_eq!(
            keys(c),
            "circle_radius_mm continuity fit_rms_mm frame n_points position_mm score slide_mm"
        );
    }
    if !value["fused"].is_null() {
        assert_eq!(
            keys(&value["fused"]),
            "ellipsoid_semi_axes_mm n_frames n_points outline outline_refined radius_from_prior rms_mm sphere_centre_mm sphere_radius_mm"
        );
    }
    assert_eq!(keys(&value["frames"][0]), "fruit_points rejected slide_mm stripe_points");
    let text = serde_json::to_string(&output).unwrap();
    let back: LocalizeOutput = serde_json::from_str(&text).unwrap();
    assert_eq!(back, output);
}

#[test]
fn the_localize_object_keeps_its_keys_and_values_and_reads_back() {
    let options = ScanOptions { scale: 0.25, seed: 3, ..ScanOptions::default() };
    let sim = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let scan = &sim.scan;
    let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
    let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
    // The paper's per-frame selection may refuse where frames cut the
    // fruit far from its centre; its object has the same keys either way.
    for method in [Method::Fused, Method::Holistic] {
        let options = LocateOptions { method, ..LocateOptions::default() };
        let answer = locate(&scan.camera, &scan.laser, &prior, &frames, &options).unwrap();
        if method == Method::Fused {
            assert_eq!(answer.status, Status::Ok, "{}", answer.reason);
        }
        check(&answer);
    }

    // Not found: nulls and every frame's reason.
    let answer = locate_in_black_frames(3, 70.0);
    assert_eq!(answer.status, Status::NotFound);
    check(&answer);
}
