//! The detector and the rough positions on the simulator's RGB-D views
//! (`alacs_sim::SimulatedScan::render_rgbd`), judged per family against the
//! truth: found, wrong, and the rough position's error.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_detect::{DepthImage, DepthModel, DetectOptions, detect, locate_detections};
use alacs_model::{Camera, LaserModel};
use alacs_sim::{OrchardOptions, RgbdErrors, RgbdOptions, ScanOptions, simulate_scan};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// First seed of these tests' scenes (the tuning range of the families).
const SEED: u64 = 10_000;

/// A rough position within this of the truth is right (issue 41's bar at
/// 0.6-1.2 m).
const ROUGH_MM: f64 = 15.0;

struct Outcome {
    /// Per target apple in view: the error of the detection on it, if any.
    target_errors: Vec<Option<f64>>,
    /// Detections with a rough position, and those on no apple.
    detections: usize,
    false_detections: usize,
}

/// Scans `n` scenes of `orchard` (sun on odd seeds) as the RGB-D camera,
/// mounted 150 mm above the ALACS camera and looking down at its axis
/// 0.9 m away, sees them. A target is judged where it lies wholly in the
/// colour image and at most `max_hidden` of it is hidden there.
fn run(orchard: &OrchardOptions, n: u64, salt: u64, max_hidden: f64) -> Outcome {
    let camera = RgbdOptions::colour_camera_720p();
    let alacs_from_rgbd = Isometry3::from_parts(
        Translation3::new(0.0, -150.0, 0.0),
        // Pitched down to look at 0.9 m on the ALACS camera's axis.
        UnitQuaternion::from_euler_angles(-(150f64 / 900.0).atan(), 0.0, 0.0),
    );
    let mut outcome = Outcome { target_errors: Vec::new(), detections: 0, false_detections: 0 };
    for i in 0..n {
        let seed = SEED + salt + i;
        let options = ScanOptions {
            orchard: orchard.clone(),
            sun: i % 2 == 1,
            scale: 0.25,
            seed,
            ..ScanOptions::default()
        };
        let scan = simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options)
            .expect("a scene");
        let view = scan.render_rgbd(&camera, &alacs_from_rgbd, &RgbdErrors::default()).unwrap();
        if std::env::var_os("ALACS_DUMP").is_some() {
            view.colour.save(format!("/tmp/rgbd_{seed}.png")).unwrap();
        }
        let mut found = detect(&view.colour, &DetectOptions::default()).unwrap();
        let depth = DepthImage::Millimetres(view.depth_mm.clone());
        locate_detections(&mut found, &view.colour, &depth, &camera, &DepthModel::default())
            .unwrap();
        if std::env::var_os("ALACS_DUMP").is_some() {
            for d in &found {
                eprintln!(
                    "  {:?} r {:.1} px score {:.2}: {:?}",
                    d.centre_px,
                    d.radius_px,
                    d.score,
                    d.rough.as_ref().map(|r| (r.position_mm, r.radius_mm))
                );
            }
            for a in &view.apples {
                eprintln!(
                    "  apple {:?} r {:.1} hidden {:.2} at {:?}",
                    a.centre_mm,
                    a.radius_mm,
                    a.hidden,
                    camera.project(&a.centre_mm).ok()
                );
            }
        }
        let located: Vec<_> = found.iter().filter_map(|d| d.rough.as_ref()).collect();
        outcome.detections += located.len();
        for rough in &located {
            let on_apple =
                view.apples.iter().any(|a| (rough.position_mm - a.centre_mm).norm() < a.radius_mm);
            if !on_apple {
                outcome.false_detections += 1;
            }
        }
        let target = view.apples.iter().find(|a| a.target).unwrap();
        let in_image = camera.project(&target.centre_mm).is_ok_and(|c| {
            let r = camera.fx_px * target.radius_mm / target.centre_mm.z;
            c.x >= r
                && c.y >= r
                && c.x + r < f64::from(camera.width_px)
                && c.y + r < f64::from(camera.height_px)
        });
        if !in_image || target.hidden > max_hidden {
            eprintln!(
                "seed {seed}: target out of the image or {:.0} % hidden, not judged",
                100.0 * target.hidden
            );
            continue;
        }
        let error = located
            .iter()
            .map(|r| (r.position_mm - target.centre_mm).norm())
            .min_by(f64::total_cmp)
            .filter(|e| *e < 2.0 * target.radius_mm);
        eprintln!(
            "seed {seed}: target at {:.0} mm, {:.0} % hidden: {}; {} detections",
            target.centre_mm.z,
            100.0 * target.hidden,
            error.map_or("not found".into(), |e| format!("{e:.1} mm off")),
            located.len()
        );
        outcome.target_errors.push(error);
    }
    outcome
}

/// Unoccluded apples at 0.6-1.2 m, sun and shade: every one found, its
/// rough position within 15 mm; at least 85 % of the detections apples.
#[test]
fn unoccluded_fruit_is_found_within_15_mm() {
    let outcome = run(&OrchardOptions::default(), 8, 0, 0.1);
    assert!(outcome.target_errors.len() >= 6, "{} targets judged", outcome.target_errors.len());
    let found: Vec<f64> = outcome.target_errors.iter().flatten().copied().collect();
    assert_eq!(found.len(), outcome.target_errors.len(), "targets found");
    let worst = found.iter().copied().fold(0.0, f64::max);
    assert!(worst <= ROUGH_MM, "worst rough position {worst:.1} mm off");
    assert!(
        outcome.false_detections * 100 <= 15 * outcome.detections,
        "{} of {} detections on no apple",
        outcome.false_detections,
        outcome.detections
    );
}

/// Clusters of three apples, 20 % of the target hidden behind leaves (as
/// the ALACS camera sees it; the RGB-D camera, 150 mm above, sees another
/// share): overlapping apples of one colour merge into one silhouette, and
/// a fruit behind a leaf shows a crescent, so only some targets are found
/// (docs/DETECTION.md states the limit); what is found is an apple: at
/// least 85 % of the detections, each rough position on an apple.
#[test]
fn clustered_fruit_detections_are_apples() {
    let orchard = OrchardOptions { cluster: 2, occlusion: 0.2, ..OrchardOptions::default() };
    let outcome = run(&orchard, 8, 100, 0.4);
    let judged = outcome.target_errors.len();
    let within = outcome.target_errors.iter().flatten().filter(|e| **e <= ROUGH_MM).count();
    eprintln!(
        "clusters: {within} of {judged} targets within {ROUGH_MM} mm; {} of {} detections on no apple",
        outcome.false_detections, outcome.detections
    );
    assert!(judged >= 4, "{judged} targets judged");
    assert!(outcome.detections >= judged, "{} detections", outcome.detections);
    assert!(
        outcome.false_detections * 100 <= 15 * outcome.detections,
        "{} of {} detections on no apple",
        outcome.false_detections,
        outcome.detections
    );
}
