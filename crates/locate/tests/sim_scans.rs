//! Localization against the simulator's ground truth, fixed seeds.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use alacs_locate::{
    Error, FrameImages, FusedFit, Localization, LocateOptions, Prior, Status, locate,
};
use alacs_model::Camera;
use alacs_sim::{OrchardOptions, RenderedScan, ScanOptions, SimulatedScan, simulate_rendered_scan};
use common::{laser, locate_in_black_frames};
use nalgebra::Point3;

mod common;

/// Simulates and renders the scan.
fn scan(options: ScanOptions) -> RenderedScan {
    scan_with_laser(&laser(), options)
}

/// Simulates and renders the scan with `laser` (another mount's).
fn scan_with_laser(laser: &alacs_model::LaserModel, options: ScanOptions) -> RenderedScan {
    simulate_rendered_scan(&Camera::blackfly_s_5mp(), laser, &options).unwrap()
}

/// Locates the scan's fruit with the true camera and laser.
fn run(sim: &RenderedScan) -> Localization {
    run_with_prior(sim, 40.0)
}

/// Locates the scan's fruit with the true camera and laser and a radius
/// prior of `fruit_radius_mm`.
fn run_with_prior(sim: &RenderedScan, fruit_radius_mm: f64) -> Localization {
    let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
    let scan = &sim.scan;
    let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm };
    locate(&scan.camera, &scan.laser, &prior, &frames, &LocateOptions::default()).unwrap()
}

fn error_mm(scan: &SimulatedScan, answer: &Localization) -> Option<f64> {
    answer.position_mm.map(|p| (p - scan.scene.fruit_centre).norm())
}

/// Asserts that `sim` is answered `ok` by a fused fit `kind` accepts,
/// within `max_error_mm` of the fruit (`label` names the scan); the answer.
fn assert_answered_by(
    sim: &RenderedScan,
    label: &str,
    kind: impl Fn(&FusedFit) -> bool,
    max_error_mm: f64,
) -> Localization {
    let answer = run(sim);
    assert_eq!(answer.status, Status::Ok, "{label}: {}", answer.reason);
    assert!(kind(answer.fused.as_ref().unwrap()), "{label}: {}", answer.reason);
    let error = error_mm(&sim.scan, &answer).unwrap();
    eprintln!("{label}: {error:.2} mm ({})", answer.reason);
    assert!(error < max_error_mm, "{label}: {error:.2} mm");
    answer
}

/// Asserts that `sim` is `not_found` or answered within `max_error_mm`.
fn assert_near_or_not_found(sim: &RenderedScan, max_error_mm: f64) {
    let answer = run(sim);
    if let Some(error) = error_mm(&sim.scan, &answer) {
        assert!(error < max_error_mm, "{error:.1} mm: {}", answer.reason);
    }
}

/// An ellipsoid the fruit's outline refined.
fn refined_ellipsoid(fit: &FusedFit) -> bool {
    fit.outline_refined && fit.ellipsoid.is_some()
}

/// A sphere fitted to the fruit's outline, the last resort.
fn outline_fallback(fit: &FusedFit) -> bool {
    fit.outline.is_some() && !fit.outline_refined
}

/// A half-scale scan with a fifth of the fruit hidden by leaves.
fn fifth_hidden_half_scale(seed: u64, sun: bool) -> RenderedScan {
    scan(ScanOptions {
        orchard: OrchardOptions { occlusion: 0.2, ..OrchardOptions::default() },
        scale: 0.5,
        sun,
        seed,
        ..ScanOptions::default()
    })
}

/// The bar: an unoccluded fruit at 0.6-1.2 m within 4 mm in 3-D,
/// spherical or slightly ellipsoidal. Scans whose plan had to be shifted
/// into the slide's stroke (the fruit at the edge of the scanner's reach,
/// so the laser never crosses its left half) are not part of the claim.
#[test]
fn unoccluded_fruit_within_4_mm() {
    let mut checked = 0;
    for (seed, ellipticity) in [(0, 0.0), (1, 0.0), (2, 0.08), (3, 0.08), (4, 0.08), (5, 0.08)] {
        let sim = scan(ScanOptions {
            orchard: OrchardOptions { max_ellipticity: ellipticity, ..OrchardOptions::default() },
            seed,
            ..ScanOptions::default()
        });
        let scan = &sim.scan;
        if scan.plan.shifted {
            continue;
        }
        let answer = run(&sim);
        assert_eq!(answer.status, Status::Ok, "seed {seed}: {}", answer.reason);
        let error = error_mm(scan, &answer).unwrap();
        eprintln!("seed {seed} ellipticity {ellipticity}: {error:.2} mm");
        assert!(error < 4.0, "seed {seed}: {error:.2} mm");
        let radius = answer.radius_mm.unwrap();
        assert!((radius - scan.scene.fruit_radius_mm).abs() < 3.0, "seed {seed}: radius {radius}");
        checked += 1;
    }
    assert!(checked >= 4, "only {checked} scans reached the fruit");
}

/// Issue 17: a slide that moves the laser 0.99 mm per commanded mm. With
/// the slide scale k in the laser model (as `calibrate laser` fits it),
/// localization keeps the unoccluded bar of 4 mm (0.5-0.8 mm on seeds
/// 0-2); the seed's model (k held at 1) was 4.5-4.6 mm off on the scans at
/// 125-171 mm of travel (0.85 mm at 40-80 mm).
#[test]
fn a_slide_with_a_scale_error_is_located_with_its_k() {
    let true_laser = laser().with_slide_scale(0.99);
    let mut checked = 0;
    for seed in [0, 1, 2] {
        let options = ScanOptions { seed, ..ScanOptions::default() };
        let sim = scan_with_laser(&true_laser, options);
        if sim.scan.plan.shifted {
            continue;
        }
        let answer = run(&sim);
        assert_eq!(answer.status, Status::Ok, "seed {seed}: {}", answer.reason);
        let error = error_mm(&sim.scan, &answer).unwrap();
        let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
        let prior = Prior { rough_position_mm: sim.scan.rough_position_mm, fruit_radius_mm: 40.0 };
        let seed_model = sim.scan.laser.with_slide_scale(1.0);
        let held =
            locate(&sim.scan.camera, &seed_model, &prior, &frames, &LocateOptions::default())
                .unwrap();
        let slides = &sim.scan.plan.slides_mm;
        eprintln!(
            "seed {seed}: slides {:.0}-{:.0} mm, {error:.2} mm with k = 0.99, {:?} mm with k held at 1",
            slides[0],
            slides[slides.len() - 1],
            error_mm(&sim.scan, &held)
        );
        assert!(error < 4.0, "seed {seed}: {error:.2} mm");
        checked += 1;
    }
    assert!(checked >= 2, "only {checked} scans reached the fruit");
}

/// Another rig's laser mount (alpha 19.6 deg, beta 0.3 deg, L0 376 mm
/// instead of the seed paper's), full scale, in sun, with radius priors
/// across the fruit's range (the sweep's `PRIOR_MM=random`). The issue's
/// bars: an unoccluded fruit within 4 mm, a fifth hidden within 15 mm.
/// Measured on seeds 1200-1215 (`LASER=19.6,0.3,376 PRIOR_MM=random sweep
/// -- 16 OCC sun 1.0 1200`): 16 of 16 found at 0 % and at 20 %, worst 1.19
/// and 13.43 mm (seed 1212, 29 % hidden: without the stripe points the
/// laser did not light, one frame's arc no longer bends beyond its noise,
/// the free fit fails and the sphere of the prior radius answers; 1.05 mm
/// before). Seed 1203 (a fruit 11 % shorter top to bottom than across,
/// whose front took a sphere of 45.6 mm for a 35.6 mm fruit) was 11.57 mm
/// off before, 2.43 mm now.
#[test]
fn another_lasers_mount_in_sun_is_located_as_well() {
    let true_laser =
        alacs_model::LaserModel::from_degrees(alacs_model::Fidelity::High, 19.6, 0.3, 376.0);
    for (seed, fruit_radius_mm) in [(1200, 41.4), (1201, 37.6), (1202, 43.8), (1203, 39.9)] {
        for (occlusion, bar_mm) in [(0.0, 4.0), (0.2, 15.0)] {
            let options = ScanOptions {
                orchard: OrchardOptions { occlusion, ..OrchardOptions::default() },
                sun: true,
                seed,
                ..ScanOptions::default()
            };
            let sim = scan_with_laser(&true_laser, options);
            let answer = run_with_prior(&sim, fruit_radius_mm);
            let label = format!("seed {seed}, {:.0} % hidden", 100.0 * sim.scan.scene.occlusion);
            assert_eq!(answer.status, Status::Ok, "{label}: {}", answer.reason);
            let error = error_mm(&sim.scan, &answer).unwrap();
            eprintln!("{label}, prior {fruit_radius_mm} mm: {error:.2} mm");
            assert!(error < bar_mm, "{label}: {error:.2} mm");
        }
    }
}

/// A fruit behind leaves: never a confident wrong point. An `ok` answer is
/// within the vacuum end-effector's 15 mm; a fully hidden fruit is not found.
/// Seeds 1, 2, 9 and 30 hide 44-47 % of the fruit in sun, and the laser
/// shows too little of it for a fit from the laser alone (one short arc, or
/// arcs that fix no sphere): the fruit's outline in the image answers.
#[test]
fn occluded_fruit_is_near_or_not_found() {
    let mut found = 0;
    let mut from_outline = 0;
    for (seed, occlusion) in [(1, 0.4), (2, 0.4), (9, 0.4), (30, 0.4), (300, 1.0), (301, 1.0)] {
        let sim = scan(ScanOptions {
            orchard: OrchardOptions { occlusion, ..OrchardOptions::default() },
            sun: true,
            seed,
            ..ScanOptions::default()
        });
        let scan = &sim.scan;
        let answer = run(&sim);
        match answer.status {
            Status::Ok => {
                let error = error_mm(scan, &answer).unwrap();
                eprintln!("seed {seed}: {error:.2} mm ({})", answer.reason);
                assert!(occlusion < 1.0, "seed {seed}: a fully hidden fruit was found");
                assert!(error < 15.0, "seed {seed}: {error:.1} mm");
                found += 1;
                from_outline += usize::from(
                    answer
                        .fused
                        .as_ref()
                        .is_some_and(|f| f.outline.is_some() && !f.outline_refined),
                );
            }
            Status::NotFound => assert!(!answer.reason.is_empty()),
        }
    }
    // A regression guard, not a rate (the README gives the rate): all four
    // partly hidden fruit are found today, within 4.1 mm, all from the outline.
    assert!(found >= 3, "{found} of 4 partly hidden fruit found");
    assert!(from_outline >= 2, "{from_outline} answers used the outline");
}

/// Regression: the sphere fitted to the front of a fruit whose semi-axes
/// are 42-46 mm took the front's curvature radius, 47.4 mm, and put the
/// centre 5.4 mm off (4.5 mm too deep; half scale, seed 102, unoccluded,
/// shade and sun alike). The fruit's outline fixes the radius across the
/// line of sight: refined by it, 3.0 mm.
#[test]
fn a_not_quite_round_fruits_outline_fixes_the_radius_its_front_does_not() {
    for sun in [false, true] {
        let sim = scan(ScanOptions { scale: 0.5, seed: 102, sun, ..ScanOptions::default() });
        let refined = |fit: &FusedFit| fit.outline_refined && fit.outline.is_some();
        assert_answered_by(&sim, &format!("sun {sun}"), refined, 4.0);
    }
}

/// Regression: a fruit longer along the line of sight than across it (5 MP,
/// seed 116, unoccluded, shade) was 7.7 mm off: neither the laser's front
/// nor the outline alone shows the depth semi-axis, so the ellipsoid's
/// roundness prior chose it. The front's curvature radius is a^2 / c and
/// the outline shows a and b, so the ellipsoid fitted to both fixes c:
/// 1.3 mm.
#[test]
fn a_fruit_deeper_than_wide_is_fixed_by_its_outline_and_its_front_together() {
    let sim = scan(ScanOptions { seed: 116, ..ScanOptions::default() });
    assert_answered_by(&sim, "seed 116", refined_ellipsoid, 2.5);
}

/// Regression: a fruit a fifth hidden in sun, whose lower part lies in a
/// leaf's laser shadow, shows arcs of 10-30 rows in each frame, each too
/// short to bend beyond its own noise, so the outline's sphere was refused
/// as "nearly straight in every frame" (half scale, seeds 1013 and 1043);
/// the arcs of its five frames together bend 4 times beyond their scatter,
/// and the outline's answer is 0.2-1.0 mm from the fruit.
#[test]
fn short_arcs_of_several_frames_confirm_the_outlines_sphere() {
    for seed in [1013, 1043] {
        let sim = fifth_hidden_half_scale(seed, seed % 2 == 1);
        assert_answered_by(&sim, &format!("seed {seed}"), outline_fallback, 2.0);
    }
}

/// Regression: sunlit fruit a fifth hidden whose laser points, clipped and
/// scattered on the sunlit red, fixed no free sphere (one or two frames
/// kept an arc), were refused although the outline's sphere held 68-111 of
/// them over 4-5 frames: they bent away from a plane 2.8-2.9 times their
/// scatter about it, and the outline fallback asked 4 times, the free fit's
/// bar (half scale, seeds 201 and 211). The outline fixes the sphere's size
/// and its place across the line of sight, so twice the scatter is asked
/// now; the answers are 2.5 and 0.9 mm from the fruit.
#[test]
fn sunlit_arcs_bending_twice_their_noise_confirm_the_outlines_sphere() {
    for seed in [201, 211] {
        let sim = fifth_hidden_half_scale(seed, true);
        assert_answered_by(&sim, &format!("seed {seed}"), outline_fallback, 3.0);
    }
}

/// Regression: an unoccluded sunlit fruit 13 % from round (semi-axes 41,
/// 45 and 47 mm) at 1.2 m was answered by the free sphere, 4.45 mm off: no
/// sphere holds both its front and its outline (the outline's sphere kept
/// 116 of the free fit's 154 points), so the outline was dropped, although
/// its circle is the free sphere's silhouette within 3 %. The ellipsoid
/// fitted to the front and the outline's rays together answers, 1.4 mm off
/// (half scale, seed 201).
#[test]
fn a_fruit_no_sphere_fits_is_refined_by_its_outline_to_an_ellipsoid() {
    let sim = scan(ScanOptions { scale: 0.5, sun: true, seed: 201, ..ScanOptions::default() });
    assert_answered_by(&sim, "seed 201", refined_ellipsoid, 2.5);
}

/// A cluster of 2-4 touching apples with branches across the target:
/// `localize` answers the target or `not_found`, never a neighbour (an
/// `ok` within 15 mm of the target, nearer the target than any neighbour).
/// Half scale, shade and sun, 0-20 % hidden by leaves.
#[test]
fn clusters_give_the_target_never_a_neighbour() {
    let mut found = 0;
    let n = 16;
    for seed in 0..n {
        let orchard = OrchardOptions {
            cluster: 1 + seed as usize % 3,
            front_branches: usize::from(seed % 2 == 0),
            occlusion: [0.0, 0.1, 0.2][seed as usize % 3],
            ..OrchardOptions::default()
        };
        let sim = scan(ScanOptions {
            orchard,
            sun: seed % 4 < 2,
            scale: 0.5,
            seed: 5000 + seed,
            ..ScanOptions::default()
        });
        let scan = &sim.scan;
        let neighbours: Vec<Point3<f64>> = scan.scene.neighbours().iter().map(|n| n.0).collect();
        assert!(!neighbours.is_empty(), "seed {seed}: no cluster");
        let answer = run(&sim);
        if answer.status == Status::Ok {
            let position = answer.position_mm.unwrap();
            let error = error_mm(scan, &answer).unwrap();
            eprintln!("seed {seed}: {error:.2} mm ({})", answer.reason);
            assert!(error < 15.0, "seed {seed}: {error:.1} mm from the target");
            for neighbour in &neighbours {
                assert!((position - neighbour).norm() > error, "seed {seed}: a neighbour");
            }
            found += 1;
        } else {
            eprintln!("seed {seed}: not found ({})", answer.reason);
            assert!(!answer.reason.is_empty());
        }
    }
    // A regression guard, not a rate: 15 of 16 are found today (seed 12 by
    // the outline, after the laser's free fit found a neighbour and was
    // refused for it).
    assert!(found >= 13, "{found} of {n} targets found");
}

/// Regression: a sphere of the prior radius through a sunlit fruit's edge
/// and a branch in front of it was answered 28.9 mm from the fruit (it held
/// 50 of the frames' 113 fruit points). It must hold most of them.
#[test]
fn a_prior_radius_sphere_through_a_fruit_and_a_branch_is_refused() {
    // As `alacs simulate scan --seed 2408 --scale 0.5 --sun --front-branches 2`
    // renders it (3 x 3 rays per pixel).
    let orchard = OrchardOptions { front_branches: 2, ..OrchardOptions::default() };
    let defaults = ScanOptions::default();
    let render = alacs_sim::RenderOptions { supersampling: 3, ..defaults.render };
    let options = ScanOptions { orchard, sun: true, scale: 0.5, seed: 2408, render, ..defaults };
    assert_near_or_not_found(&scan(options), 15.0);
}

/// A half-scale scan in a cluster of `neighbours` apples behind
/// `branches` branches, `occlusion` of the target hidden by leaves.
fn cluster_half_scale(
    neighbours: usize,
    branches: usize,
    occlusion: f64,
    seed: u64,
) -> RenderedScan {
    let orchard = OrchardOptions {
        cluster: neighbours,
        front_branches: branches,
        occlusion,
        ..OrchardOptions::default()
    };
    scan(ScanOptions { orchard, scale: 0.5, seed, ..ScanOptions::default() })
}

/// Regression: a target 73 % hidden, with a neighbour right behind it
/// whose outline shows beside it, was answered by the outline fallback
/// 20.4 mm off: the neighbour's outline and 13 points of the target's one
/// clean arc, which that sphere cut across (13 of 31). An arc the sphere
/// crosses is no support for it.
#[test]
fn an_outline_behind_the_target_does_not_lend_the_target_its_sphere() {
    assert_near_or_not_found(&cluster_half_scale(2, 1, 0.6, 123), 15.0);
}

/// Regression: where a leaf's shadow hides the laser, a row's stripe peak
/// can be a red ridge of the scene itself, there in every frame (a sunlit
/// fruit's rim against a leaf). Triangulated on the frame's laser plane,
/// such points fixed the depth of the outline's sphere: full scale,
/// another laser's mount, 64 % hidden, sun (`LASER=18.6,1.1,372
/// PRIOR_MM=random sweep -- 1 0.6 sun 1.0 4011`), 33.4 mm off, the points
/// 30 mm behind the fruit's front; half scale, a cluster of four behind
/// two branches, 73 % hidden, sun (`CLUSTER=3 BRANCHES=2 sweep -- 1 0.4 sun
/// 0.5 533`), 25.2 mm off. A stripe point whose pixel is no brighter than
/// in the frames' per-pixel minimum is not the laser's.
#[test]
fn a_red_ridge_in_every_frame_is_no_laser_point() {
    let true_laser =
        alacs_model::LaserModel::from_degrees(alacs_model::Fidelity::High, 18.6, 1.1, 372.0);
    let options = ScanOptions {
        orchard: OrchardOptions { occlusion: 0.6, ..OrchardOptions::default() },
        sun: true,
        seed: 4011,
        ..ScanOptions::default()
    };
    let sim = scan_with_laser(&true_laser, options);
    let answer = run_with_prior(&sim, 44.3);
    if let Some(error) = error_mm(&sim.scan, &answer) {
        assert!(error < 15.0, "seed 4011: {error:.1} mm: {}", answer.reason);
    }
    let orchard = OrchardOptions {
        cluster: 3,
        front_branches: 2,
        occlusion: 0.4,
        ..OrchardOptions::default()
    };
    let sim =
        scan(ScanOptions { orchard, scale: 0.5, sun: true, seed: 533, ..ScanOptions::default() });
    assert_near_or_not_found(&sim, 15.0);
}

/// The frames' per-pixel minimum is the scene without the laser only where
/// their slides lie apart: copies of one frame at one slide position light
/// the same pixels, and keep every stripe point the frame alone keeps.
#[test]
fn frames_at_one_slide_keep_their_stripe() {
    let sim = scan(ScanOptions { scale: 0.5, seed: 0, ..ScanOptions::default() });
    let (image, slide_mm) = sim.frames().nth(2).unwrap();
    let prior = Prior { rough_position_mm: sim.scan.rough_position_mm, fruit_radius_mm: 40.0 };
    let at = |n: usize| {
        let frames: Vec<FrameImages> =
            (0..n).map(|_| FrameImages::from((image, slide_mm))).collect();
        let (camera, laser) = (&sim.scan.camera, &sim.scan.laser);
        locate(camera, laser, &prior, &frames, &LocateOptions::default()).unwrap()
    };
    let alone = at(1).frames[0].points_in_camera.len();
    assert!(alone > 50, "{alone} points");
    for frame in at(3).frames {
        assert_eq!(frame.points_in_camera.len(), alone);
    }
}

/// Regression: in a cluster of four behind two branches, the outline took
/// in a neighbour and refined the target's sphere (4.5 mm off) to an
/// ellipsoid with semi-axes 45, 48 and 60 mm, 17 mm off. No apple is that
/// long; the sphere stands.
#[test]
fn an_ellipsoid_no_apple_could_be_is_refused() {
    let sim = cluster_half_scale(3, 2, 0.4, 303);
    let answer = run(&sim);
    let error = error_mm(&sim.scan, &answer).unwrap();
    assert!(error < 6.0, "{error:.1} mm: {}", answer.reason);
    let fit = answer.fused.unwrap();
    if let Some(ellipsoid) = fit.ellipsoid {
        let axes = ellipsoid.semi_axes_mm();
        assert!(axes.max() <= 1.25 * axes.min(), "{axes:?}");
    }
}

/// Regression: in a cluster of four, the free fit took the target's two
/// whole arcs and 12 points of two frames whose arcs lay on a neighbour (it
/// held 5 of 16 and 7 of 21): a 39 mm fruit became a 52 mm sphere, 15.1 mm
/// off. Fitted again without the frames whose arcs it crosses: 10.2 mm.
#[test]
fn a_sphere_crossing_a_frames_arc_is_fitted_again_without_that_frame() {
    assert_near_or_not_found(&cluster_half_scale(3, 2, 0.4, 310), 12.0);
}

/// Regression: one frame's whole arc of the target (91 points) and 12
/// points of a neighbour's arc in another frame (16 % of the rows the
/// sphere predicts there) made a free sphere 20 mm off. A sphere needs two
/// cuts of its own fruit. Then the sphere of the prior radius through the
/// same arc and 10 of the neighbour's points (a frame needs 11) was the
/// mirror of the right one across the laser's plane, 17.5 mm off: it needs
/// two cuts too.
#[test]
fn a_free_fit_needs_two_frames_that_each_cut_the_fruit() {
    let sim = cluster_half_scale(3, 2, 0.4, 324);
    assert_refused_and_near(&sim, &["a sphere needs two cuts", "rests on one frame's arc"]);
}

/// Regression: a target 75 % hidden in a cluster of three behind a branch,
/// full scale, 1.15 m away (`CLUSTER=2 BRANCHES=1 PRIOR_MM=random sweep --
/// 1 0.6 shade 1.0 1401`): two frames' candidates lay within 3.1 mm of the
/// fruit, but the sphere of the prior radius, started from them, took its
/// first step with every frame's points, a third frame's arc on something
/// else among them, and settled 14.3 mm off, holding 44 of the 87 fruit
/// points where the fruit's own surface held 77. Each start now also
/// begins from the points its own sphere holds: 1.8 mm. Since the stripe
/// points the laser did not light are dropped, seed 1401 shows the fruit in
/// one frame (not found); the start from the held points decides on a
/// target 66 % hidden in a cluster of four behind two branches, in sun
/// (`CLUSTER=3 BRANCHES=2 PRIOR_MM=random sweep -- 1 0.4 sun 1.0 1300`):
/// 4.75 mm, where the starts from every point find no sphere that passes.
#[test]
fn a_prior_radius_sphere_started_at_the_fruit_is_not_pulled_off_by_another_arc() {
    let orchard = OrchardOptions {
        cluster: 3,
        front_branches: 2,
        occlusion: 0.4,
        ..OrchardOptions::default()
    };
    let sim = scan(ScanOptions { orchard, sun: true, seed: 1300, ..ScanOptions::default() });
    let answer = run_with_prior(&sim, 39.44);
    assert_eq!(answer.status, Status::Ok, "{}", answer.reason);
    assert!(answer.fused.as_ref().unwrap().radius_from_prior, "{}", answer.reason);
    let error = error_mm(&sim.scan, &answer).unwrap();
    assert!(error < 6.0, "{error:.2} mm: {}", answer.reason);
}

/// Where the free fit fails and both fallbacks hold, the sphere of the
/// prior radius and the outline's, and lie within a fifth of the prior of
/// each other, the outline's answers: it fixes the fruit across the line
/// of sight and its size, where a sphere of an assumed radius through
/// short arcs slides along them. Half scale, 40 % hidden (`sweep -- 12 0.4
/// LIGHT 0.5 200`): when this came in, seed 202 in shade, the prior's
/// sphere 6.2 mm off, the outline's 0.4 mm; seed 205 in sun, 6.2 and 1.1
/// mm. Since the stripe points the laser did not light are dropped, the
/// prior's sphere fails on those two (they show one arc each) and the
/// outline answers them as the last resort; seed 211 in shade and 207 in
/// sun are answered where both hold, 1.3 and 0.1 mm off.
#[test]
fn where_both_fallbacks_agree_the_outline_answers() {
    for (seed, sun) in [(211, false), (207, true)] {
        let sim = scan(ScanOptions {
            orchard: OrchardOptions { occlusion: 0.4, ..OrchardOptions::default() },
            scale: 0.5,
            sun,
            seed,
            ..ScanOptions::default()
        });
        let label = format!("seed {seed}");
        let answer = assert_answered_by(&sim, &label, outline_fallback, 2.0);
        assert!(answer.reason.contains("the sphere of the prior radius"), "{}", answer.reason);
    }
}

/// Asserts that the fused fits of `sim` were refused for each of `reasons`
/// (parts of `fused_rejected`) and that whatever answered, if anything,
/// is within 15 mm of the fruit.
fn assert_refused_and_near(sim: &RenderedScan, reasons: &[&str]) {
    let answer = run(sim);
    let rejected = answer.fused_rejected.clone().unwrap_or_default();
    for reason in reasons {
        assert!(rejected.contains(reason), "{rejected}");
    }
    if let Some(error) = error_mm(&sim.scan, &answer) {
        assert!(error < 15.0, "{error:.1} mm: {}", answer.reason);
    }
}

/// Regression: a target 37 % hidden in a cluster of three behind a branch,
/// 1.07 m away (radius 36.7 mm, prior 40): the free fit through its arcs
/// and a neighbour's swelled to a sphere of 52.8 mm and stood 17.1 mm off.
/// No answer's sphere may be more than 1.3 times the prior. Since the
/// stripe points the laser did not light are dropped, the free fit of this
/// scan lies beyond the rough position's error and is refused before its
/// radius is looked at (the check itself: `fusion`'s unit test
/// `a_sphere_swollen_beyond_the_prior_is_refused`).
#[test]
fn a_sphere_swollen_far_beyond_the_prior_is_no_answer() {
    assert_near_or_not_found(&cluster_half_scale(2, 1, 0.2, 603), 15.0);
}

/// Regression: with a radius prior of 46 mm, a fruit 46 mm across and
/// 41 mm deep at 1.2 m took a free sphere of 57 mm from its flat front,
/// 16.4 mm off, and its outline (0.78 of that sphere's silhouette) was not
/// searched for. A sphere fitted to a fruit's front may be 1.3 times its
/// silhouette.
#[test]
fn a_flat_fronts_big_sphere_is_refined_by_its_smaller_outline() {
    let sim = fifth_hidden_half_scale(201, false);
    let answer = run_with_prior(&sim, 46.0);
    let error = error_mm(&sim.scan, &answer).unwrap();
    assert!(error < 4.0, "{error:.1} mm: {}", answer.reason);
    assert!(answer.fused.unwrap().outline_refined);
}

#[test]
fn frames_that_do_not_fit_the_camera_are_refused() {
    let camera = Camera::blackfly_s_5mp().scaled(0.1);
    let image = image::RgbImage::new(10, 10);
    let frames = [FrameImages { image: &image, image_laser_off: None, slide_mm: 0.0 }];
    let prior = Prior { rough_position_mm: Point3::new(0.0, 0.0, 800.0), fruit_radius_mm: 40.0 };
    let error = locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap_err();
    assert!(matches!(error, Error::InvalidInput(ref m) if m.contains("frame 0")), "{error}");
    let error = locate(&camera, &laser(), &prior, &[], &LocateOptions::default()).unwrap_err();
    assert!(error.to_string().contains("no frames"), "{error}");
    let fits = image::RgbImage::new(camera.width_px, camera.height_px);
    let frames = [FrameImages { image: &fits, image_laser_off: Some(&image), slide_mm: 0.0 }];
    let error = locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap_err();
    assert!(error.to_string().contains("laser-off image"), "{error}");
    let behind = Prior { rough_position_mm: Point3::new(0.0, 0.0, -5.0), ..prior };
    let frames = [];
    assert!(locate(&camera, &laser(), &behind, &frames, &LocateOptions::default()).is_err());
}

/// A frame where the laser hits nothing near the fruit (a black image)
/// gives `not_found` with a reason naming the frames, not an error.
#[test]
fn an_empty_scan_is_not_found_with_a_reason() {
    let answer = locate_in_black_frames(5, 60.0);
    assert_eq!(answer.status, Status::NotFound);
    assert!(answer.position_mm.is_none());
    assert!(answer.reason.contains("frame 0"), "{}", answer.reason);
}
