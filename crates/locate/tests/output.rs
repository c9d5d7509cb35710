//! The `localize --json` object ([`LocalizeOutput`]) on simulated scans.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use alacs_locate::{
    FrameImages, Localization, LocalizeOutput, LocateOptions, Method, Prior, Status, locate,
};
use alacs_model::{Camera, Fidelity, LaserModel};
use alacs_sim::{ScanOptions, simulate_scan};
use nalgebra::Point3;
use serde_json::{Value, json};

fn laser() -> LaserModel {
    LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98)
}

/// The object as the command line built it by hand before
/// [`LocalizeOutput`] owned it.
fn old_localization_json(answer: &Localization) -> Value {
    let point = |p: &nalgebra::Point3<f64>| json!([p.x, p.y, p.z]);
    json!({
        "position_mm": answer.position_mm.as_ref().map(point),
        "radius_mm": answer.radius_mm,
        "candidates": answer.candidates.iter().map(|c| json!({
            "frame": c.frame,
            "slide_mm": c.slide_mm,
            "position_mm": point(&c.position_mm),
            "n_points": c.n_points,
            "score": c.score,
            "circle_radius_mm": c.circle_radius_mm,
            "continuity": c.continuity,
            "fit_rms_mm": c.fit_rms_mm,
        })).collect::<Vec<_>>(),
        "selected": answer.selected,
        "status": answer.status.as_str(),
        "reason": answer.reason,
        "method": answer.method.as_str(),
        "holistic_selection": answer.holistic,
        "fused": answer.fused.as_ref().map(|f| json!({
            "sphere_centre_mm": point(&f.sphere.centre),
            "sphere_radius_mm": f.sphere.radius_mm,
            "ellipsoid_semi_axes_mm": f.ellipsoid.map(|e| { let a = e.semi_axes_mm(); [a.x, a.y, a.z] }),
            "n_points": f.n_points,
            "n_frames": f.n_frames,
            "rms_mm": f.rms_mm,
            "radius_from_prior": f.radius_from_prior,
            "outline": f.outline.as_ref().map(|o| json!({
                "centre_px": [o.centre_px.x, o.centre_px.y],
                "radius_px": o.radius_px,
                "support": o.support,
                "fill": o.fill,
            })),
        })),
        "fused_rejected": answer.fused_rejected,
        "frames": answer.frames.iter().map(|f| json!({
            "slide_mm": f.slide_mm,
            "stripe_points": f.stripe.len(),
            "fruit_points": f.fruit.len(),
            "rejected": f.rejected,
        })).collect::<Vec<_>>(),
    })
}

/// The same keys and values as before, and read back unchanged (exactly:
/// serde_json's `float_roundtrip`).
fn check(answer: &Localization) {
    let output = LocalizeOutput::from(answer);
    let value = serde_json::to_value(&output).unwrap();
    assert_eq!(value, old_localization_json(answer));
    let text = serde_json::to_string(&output).unwrap();
    let back: LocalizeOutput = serde_json::from_str(&text).unwrap();
    assert_eq!(back, output);
}

#[test]
fn the_localize_object_keeps_its_keys_and_values_and_reads_back() {
    let options = ScanOptions { scale: 0.25, seed: 3, ..ScanOptions::default() };
    let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let images: Vec<_> =
        (0..scan.frames.len()).map(|i| scan.render_frame(i, true).unwrap()).collect();
    let frames: Vec<_> = images
        .iter()
        .zip(&scan.frames)
        .map(|(image, f)| FrameImages { image, image_laser_off: None, slide_mm: f.slide_mm })
        .collect();
    let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
    for method in [Method::Fused, Method::Holistic] {
        let options = LocateOptions { method, ..LocateOptions::default() };
        let answer = locate(&scan.camera, &scan.laser, &prior, &frames, &options).unwrap();
        assert_eq!(answer.status, Status::Ok, "{}", answer.reason);
        check(&answer);
    }

    // Not found: nulls and every frame's reason.
    let camera = Camera::blackfly_s_5mp().scaled(0.2);
    let black = image::RgbImage::new(camera.width_px, camera.height_px);
    let frames: Vec<_> = (0..3)
        .map(|k| FrameImages {
            image: &black,
            image_laser_off: None,
            slide_mm: 70.0 + 10.0 * k as f64,
        })
        .collect();
    let prior = Prior { rough_position_mm: Point3::new(0.0, 0.0, 800.0), fruit_radius_mm: 40.0 };
    let answer = locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap();
    assert_eq!(answer.status, Status::NotFound);
    check(&answer);
}
