//! The controller on the simulated rig: the seed's scan of a simulated
//! apple, localized against the simulator's truth.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use alacs_locate::{Localization, LocateOptions, Status};
use alacs_model::{Camera, LaserModel};
use alacs_scanner::{
    CapturedScan, ControllerConfig, Device, Error, FrameCamera, Metering, ScanController, ScanMode,
    SimulatedRig, SimulatedRigOptions, Slide, Step, Sweep,
};
use alacs_sim::{OrchardOptions, ScanOptions, SimulatedScan, simulate_scan};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

fn laser() -> LaserModel {
    LaserModel::seed_paper()
}

fn scene(seed: u64, scale: f64) -> Arc<SimulatedScan> {
    let options = ScanOptions { scale, seed, ..ScanOptions::default() };
    Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap())
}

/// The RGB-D camera of the examples: 60 mm above, 40 mm left of and 10 mm
/// behind the ALACS camera, turned 5 degrees about its y axis and 2 about x.
fn alacs_from_rgbd() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(-40.0, -60.0, -10.0),
        UnitQuaternion::from_euler_angles(2f64.to_radians(), 5f64.to_radians(), 0.0),
    )
}

/// The scene on the simulated rig, scanned by the default controller from
/// its true rough position.
fn run_on_rig(scene: &Arc<SimulatedScan>) -> (SimulatedRig, CapturedScan) {
    scan_from(scene, 0.0, ScanMode::StopAndGo)
}

/// Localizes the captured scan with the scene's true camera and laser.
fn localize(scan: &CapturedScan, scene: &SimulatedScan) -> Localization {
    scan.localize(&scene.camera, &scene.laser, &LocateOptions::default()).unwrap()
}

/// Asserts that the scan finds the scene's apple within
/// [`HALF_SCALE_TOLERANCE_MM`].
fn assert_localized(scan: &CapturedScan, scene: &SimulatedScan) {
    let answer = localize(scan, scene);
    assert_eq!(answer.status, Status::Ok, "{}", answer.reason);
    let error = (answer.position_mm.unwrap() - scene.scene.fruit_centre).norm();
    assert!(error < HALF_SCALE_TOLERANCE_MM, "3-D error {error:.2} mm");
}

/// Localization tolerance at half the 5 MP camera's resolution, 3-D, mm.
/// Measured with `measure_localization_error_at_half_scale` (seeds 0-11,
/// unoccluded, shade): median 2.0 mm, 10 of 12 under 3.2 mm, worst 6.5 mm
/// (a far, elliptic apple); the seeds tested here measure 1.2 mm (seed 3)
/// and 1.2 mm (seed 1, with laser-off frames).
const HALF_SCALE_TOLERANCE_MM: f64 = 4.0;

#[test]
fn the_rig_captures_the_simulators_frames_and_localizes_the_apple() {
    let scene = scene(3, 0.5);
    let (rig, scan) = run_on_rig(&scene);
    // The same strategy from the same rough position: the simulator's plan,
    // and at its positions the rig's camera renders the simulator's frames.
    assert_eq!(scan.slides_mm(), scene.plan.slides_mm);
    for (k, frame) in scan.frames.iter().enumerate() {
        assert!(frame.image == scene.render_frame(k, true).unwrap(), "frame {k}");
    }
    assert!(!rig.laser_on());
    // The simulated clock: the slide's travel from 0 at 50 mm/s, each of
    // the five moves 0.1 s longer for its ramps up and down at 500 mm/s^2
    // (each is longer than the 5 mm the ramps cover), plus 50 ms settling
    // per move, 30 ms per frame, 2 ms per laser switch.
    let last_mm = scan.slides_mm()[4];
    assert!(scan.slides_mm()[0] >= 5.0);
    let expected = last_mm / 50.0 + 5.0 * (0.1 + 0.05 + 0.03) + 2.0 * 0.002;
    assert!((rig.elapsed().as_secs_f64() - expected).abs() < 1e-6, "{:?}", rig.elapsed());

    assert_localized(&scan, &scene);
}

#[test]
fn a_rough_position_from_the_rgbd_frame_and_laser_off_frames_localize_too() {
    let scene = scene(1, 0.5);
    let transform = alacs_from_rgbd();
    // What an RGB-D camera mounted there reports.
    let rough_in_rgbd = transform.inverse() * scene.rough_position_mm;
    let config = ControllerConfig {
        alacs_from_rgbd: transform,
        capture_laser_off: true,
        ..ControllerConfig::default()
    };
    let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
    let scan =
        ScanController::new(laser(), config).unwrap().run(&mut rig.rig(), &rough_in_rgbd).unwrap();
    assert!((scan.rough_position_mm - scene.rough_position_mm).norm() < 1e-9);
    for (planned, captured) in scene.plan.slides_mm.iter().zip(scan.slides_mm()) {
        assert!((planned - captured).abs() < 1e-9);
    }
    assert!(scan.frames.iter().all(|f| f.image_laser_off.is_some()));
    assert_localized(&scan, &scene);
}

#[test]
fn the_simulated_devices_time_out_and_refuse_targets_beyond_the_stroke() {
    let scene = scene(2, 0.1);
    let rough = scene.rough_position_mm;
    // A slow slide: 1 mm/s cannot reach the first position within 3 s.
    let slow = SimulatedRigOptions { speed_mm_per_s: 1.0, ..SimulatedRigOptions::default() };
    let mut rig = SimulatedRig::new(scene.clone(), slow).unwrap();
    let config = ControllerConfig { move_timeout: Duration::from_secs(3), ..Default::default() };
    let error =
        ScanController::new(laser(), config).unwrap().run(&mut rig.rig(), &rough).unwrap_err();
    assert_eq!(error.device(), Some(Device::Slide));
    assert!(matches!(error.step(), Some(Step::Move { frame: 0, .. })), "{error}");
    // 1 mm/s is reached after 0.002 s and 0.001 mm; at 3 s the slide is at 2.999 mm.
    assert!(error.to_string().contains("stopped at 2.999 mm"), "{error}");
    assert!((rig.slide_mm() - 2.999).abs() < 1e-9);
    assert_eq!(rig.elapsed(), Duration::from_secs(3));
    assert!(!rig.laser_on());

    // A camera slower than its timeout.
    let slow = SimulatedRigOptions { frame_time: Duration::from_secs(1), ..Default::default() };
    let mut rig = SimulatedRig::new(scene.clone(), slow).unwrap();
    let config =
        ControllerConfig { capture_timeout: Duration::from_millis(500), ..Default::default() };
    let error =
        ScanController::new(laser(), config).unwrap().run(&mut rig.rig(), &rough).unwrap_err();
    assert_eq!(error.device(), Some(Device::Camera));
    assert_eq!(error.step(), Some(Step::Capture { frame: 0, laser_on: true }));
    assert!(!rig.laser_on());

    // Out of stroke: refused, nothing moves.
    let mut rig = SimulatedRig::new(scene, SimulatedRigOptions::default()).unwrap();
    for target in [-1.0, 200.5, f64::NAN] {
        let error = rig.slide.move_to(target, Duration::from_secs(10)).unwrap_err();
        assert!(matches!(error, Error::OutOfStroke { .. }), "{error}");
    }
    assert_eq!(rig.slide.position_mm().unwrap(), 0.0);
    assert_eq!(rig.elapsed(), Duration::ZERO);
}

#[test]
#[ignore = "measurement: cargo test --release -p alacs-scanner --test sim_rig -- --ignored --nocapture"]
fn measure_localization_error_at_half_scale() {
    for seed in 0..12 {
        let scene = scene(seed, 0.5);
        let (_, scan) = run_on_rig(&scene);
        let answer = localize(&scan, &scene);
        match answer.position_mm {
            Some(p) => {
                let e = p - scene.scene.fruit_centre;
                println!(
                    "seed {seed:2} z {:6.1} err ({:6.2} {:6.2} {:6.2}) 3d {:5.2} radius {:5.2} vs {:5.2}",
                    scene.scene.fruit_centre.z,
                    e.x,
                    e.y,
                    e.z,
                    e.norm(),
                    answer.radius_mm.unwrap(),
                    scene.scene.fruit_radius_mm
                );
            }
            None => println!("seed {seed:2} not found: {}", answer.reason),
        }
    }
}

/// A sunlit apple: at the simulator's reference exposure (1 ms) the apple
/// with the laser on it clips. Metering brings the apple's bright end to
/// about 100 DN with a shorter exposure, takes laser-off frames (a bright
/// scene), and the scan localizes; in shade it keeps about the reference
/// exposure and takes none.
#[test]
fn metering_shortens_the_exposure_in_sun_and_takes_laser_off_frames() {
    let sunny = |sun: bool| {
        let options = ScanOptions { scale: 0.5, seed: 3, sun, ..ScanOptions::default() };
        Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap())
    };
    for sun in [true, false] {
        let scene = sunny(sun);
        let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
        let config = ControllerConfig {
            metering: Some(Metering::new(scene.camera.clone())),
            ..ControllerConfig::default()
        };
        let controller = ScanController::new(laser(), config).unwrap();
        let mut totals = Vec::new();
        let scan = controller
            .run_with_progress(&mut rig.rig(), &scene.rough_position_mm, |done, total| {
                totals.push((done, total));
            })
            .unwrap();
        let exposure = scan.exposure.unwrap();
        let (done, total) = *totals.last().unwrap();
        assert_eq!(done, total);
        let laser_off = scan.frames.iter().all(|f| f.image_laser_off.is_some());
        if sun {
            assert!(exposure.exposure_us < 600.0, "{exposure:?}");
            assert!(laser_off);
            // One or two metering frames (a clipped look quarters the
            // exposure), then five frames with the laser on and five off.
            assert!((11..=12).contains(&total), "{totals:?}");
        } else {
            assert!((600.0..2000.0).contains(&exposure.exposure_us), "{exposure:?}");
            assert!(scan.frames.iter().all(|f| f.image_laser_off.is_none()));
            assert_eq!(total, 1 + 5, "{totals:?}");
        }
        assert_eq!(exposure.gain_db, 0.0);
        // The laser-off frame of the metered exposure: the apple is below clipping.
        let image = scan.frames[2].image_laser_off.as_deref().unwrap_or(&scan.frames[2].image);
        let centre = scene.camera.project(&scene.scene.fruit_centre).unwrap();
        let radius_px =
            0.5 * scene.camera.fx_px * scene.scene.fruit_radius_mm / scene.scene.fruit_centre.z;
        let (mut clipped, mut all) = (0, 0);
        for p in disc_pixels(image, centre, radius_px) {
            clipped += usize::from(p.0[0] == 255);
            all += 1;
        }
        assert!(clipped * 100 < all, "{clipped} of {all} clipped, sun {sun}");
        assert_localized(&scan, &scene);
        let yaml = scan.scan_yaml();
        assert!(yaml.contains("exposure_us"), "{yaml}");
    }
}

/// The pixels of `image` within `radius_px` of `centre`.
fn disc_pixels(
    image: &image::RgbImage,
    centre: nalgebra::Point2<f64>,
    radius_px: f64,
) -> impl Iterator<Item = &image::Rgb<u8>> {
    image.enumerate_pixels().filter_map(move |(u, v, p)| {
        let d = (f64::from(u) - centre.x).hypot(f64::from(v) - centre.y);
        (d < radius_px).then_some(p)
    })
}

/// At the reference exposure, the same sunlit apple clips where the laser
/// crosses it: what metering is for.
#[test]
fn a_sunlit_apple_clips_at_the_reference_exposure() {
    let options = ScanOptions { scale: 0.5, seed: 3, sun: true, ..ScanOptions::default() };
    let scene = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let image = scene.render_frame(2, true).unwrap();
    let centre = scene.camera.project(&scene.scene.fruit_centre).unwrap();
    let radius_px =
        0.8 * scene.camera.fx_px * scene.scene.fruit_radius_mm / scene.scene.fruit_centre.z;
    let clipped = disc_pixels(&image, centre, radius_px).filter(|p| p.0[0] == 255).count();
    assert!(clipped > 50, "{clipped} clipped red pixels");
}

/// Several fruit in one sweep: a cluster of three, each named with its
/// own rough position (the simulator's `neighbours_as_targets`). The
/// controller plans the simulator's sweep (each fruit its five frames,
/// frames that fall together taken once), meters so that none clips, and
/// each fruit is localized to its own centre, never a neighbour's.
#[test]
fn one_sweep_covers_every_fruit_of_a_cluster_and_each_is_localized() {
    let options = ScanOptions {
        orchard: OrchardOptions { cluster: 2, ..OrchardOptions::default() },
        neighbours_as_targets: true,
        scale: 0.5,
        seed: 3,
        ..ScanOptions::default()
    };
    let scene = Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap());
    let roughs = scene.rough_positions();
    assert_eq!(roughs.len(), 3);
    let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
    let config = ControllerConfig {
        metering: Some(Metering::new(scene.camera.clone())),
        ..ControllerConfig::default()
    };
    let controller = ScanController::new(laser(), config).unwrap();
    let scan = controller.run_targets_with_progress(&mut rig.rig(), &roughs, |_, _| {}).unwrap();
    assert_eq!(scan.slides_mm(), scene.plan.slides_mm);
    assert!((6..=15).contains(&scan.frames.len()), "{:?}", scan.slides_mm());
    assert!(!rig.laser_on());
    assert!(scan.scan_yaml().contains("targets:"));
    let truth: Vec<_> = scene.scene.apples().iter().map(|a| a.0).collect();
    let answers = scan.localize_targets(&scene.camera, &scene.laser, &LocateOptions::default());
    let mut found = 0;
    for (k, answer) in answers.unwrap().iter().enumerate() {
        let Some(position) = answer.position_mm.filter(|_| answer.status == Status::Ok) else {
            eprintln!("fruit {k}: not found ({})", answer.reason);
            continue;
        };
        let error = (position - truth[k]).norm();
        eprintln!("fruit {k}: {error:.2} mm ({})", answer.reason);
        assert!(error < 15.0, "fruit {k}: {error:.1} mm off");
        for (j, other) in truth.iter().enumerate().filter(|(j, _)| *j != k) {
            assert!((position - other).norm() > error, "fruit {k} answered fruit {j}");
        }
        found += 1;
    }
    // A regression guard, not a rate.
    assert!(found >= 2, "{found} of 3 found");
    // Too many fruit for one scan: refused before the rig moves.
    let many = vec![scene.rough_position_mm; alacs_model::MAX_SCAN_TARGETS + 1];
    let error = controller.run_targets_with_progress(&mut rig.rig(), &many, |_, _| {}).unwrap_err();
    assert!(matches!(error, Error::InvalidInput(_)), "{error}");
}

/// Regression: a target still dark (under 8 DN) at the longest exposure
/// ended metering there at 0 dB; the gain now makes up the rest. A shaded
/// apple with exposures capped at 30 us (about 3 DN) gets the largest gain.
#[test]
fn a_target_dark_at_the_longest_exposure_gets_gain() {
    let scene = scene(3, 0.25);
    let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
    let metering = Metering {
        start_exposure_us: 30.0,
        exposure_range_us: (10.0, 30.0),
        ..Metering::new(scene.camera.clone())
    };
    let config = ControllerConfig { metering: Some(metering), ..ControllerConfig::default() };
    let controller = ScanController::new(laser(), config).unwrap();
    let scan = controller.run(&mut rig.rig(), &scene.rough_position_mm).unwrap();
    let exposure = scan.exposure.unwrap();
    assert_eq!(exposure.exposure_us, 30.0);
    assert!((exposure.gain_db - 12.0).abs() < 1e-9, "{exposure:?}");
}

/// A scan of the scene in `mode` from where the slide stands.
fn scan_from(
    scene: &Arc<SimulatedScan>,
    start_mm: f64,
    mode: ScanMode,
) -> (SimulatedRig, CapturedScan) {
    let options = SimulatedRigOptions { start_mm, ..SimulatedRigOptions::default() };
    let config = ControllerConfig { mode, ..ControllerConfig::default() };
    let (rig, scan) = scan_with(scene, options, config);
    (rig, scan.unwrap())
}

/// A scan of the scene from its true rough position on a rig of `options`
/// with `config`.
fn scan_with(
    scene: &Arc<SimulatedScan>,
    options: SimulatedRigOptions,
    config: ControllerConfig,
) -> (SimulatedRig, Result<CapturedScan, Error>) {
    let mut rig = SimulatedRig::new(scene.clone(), options).unwrap();
    let scan =
        ScanController::new(laser(), config).unwrap().run(&mut rig.rig(), &scene.rough_position_mm);
    (rig, scan)
}

/// The controller's default configuration with a continuous sweep for the scene's camera.
fn sweeping(scene: &SimulatedScan) -> ControllerConfig {
    ControllerConfig {
        mode: ScanMode::Continuous(Sweep::new(scene.camera.clone())),
        ..ControllerConfig::default()
    }
}

#[test]
fn a_continuous_sweep_localizes_as_stop_and_go_does_in_less_time() {
    let scene = scene(3, 0.5);
    for start_mm in [0.0, 200.0] {
        let (stop_and_go_rig, stop_and_go) = scan_from(&scene, start_mm, ScanMode::StopAndGo);
        let sweep = ScanMode::Continuous(Sweep::new(scene.camera.clone()));
        let (rig, scan) = scan_from(&scene, start_mm, sweep);
        assert!(!rig.laser_on());
        assert_eq!(scan.frames.len(), 5);
        // Each frame near its planned position (within the slide's travel
        // in one report and half an exposure), at the position it reports.
        for (frame, planned) in scan.frames.iter().zip(&scene.plan.slides_mm) {
            assert_eq!(frame.planned_slide_mm, *planned);
            assert!((frame.slide_mm - planned).abs() < 0.5, "{} vs {planned}", frame.slide_mm);
        }
        let speed = scan.sweep_speed_mm_per_s.unwrap();
        assert!(speed > 0.0 && speed <= SimulatedRigOptions::default().speed_mm_per_s + 1e-9);
        // Measured: 1.90 s against 2.63 s from 0 mm, 3.24 s against 4.78 s from 200 mm.
        assert!(
            rig.elapsed().as_secs_f64() < 0.8 * stop_and_go_rig.elapsed().as_secs_f64(),
            "{:?} vs {:?}",
            rig.elapsed(),
            stop_and_go_rig.elapsed()
        );
        assert_localized(&scan, &scene);
        // As accurate as the stop-and-go frames: no more than 1 mm worse
        // (the frames stand up to 0.5 mm from the plan's positions and have
        // their own noise). Over 20 scans the medians agree (the
        // `scan_modes` example).
        let error = |scan: &CapturedScan| {
            (localize(scan, &scene).position_mm.unwrap() - scene.scene.fruit_centre).norm()
        };
        let (moving, standing) = (error(&scan), error(&stop_and_go));
        println!(
            "from {start_mm} mm: continuous {:?} at {speed:.1} mm/s, {moving:.2} mm; stop-and-go {:?}, {standing:.2} mm",
            rig.elapsed(),
            stop_and_go_rig.elapsed()
        );
        assert!(moving - standing < 1.0, "{moving:.3} vs {standing:.3} mm");
        // From the far end the sweep runs the other way and stops at the
        // plan's first position.
        let plan = &scene.plan.slides_mm;
        let expected_end = if start_mm == 0.0 { plan[4] } else { plan[0] };
        assert!((rig.slide_mm() - expected_end).abs() < 1e-9);
    }
}

#[test]
fn a_sweep_keeps_the_stripes_smear_under_its_limit() {
    // A long exposure: the speed drops so that the stripe moves at most
    // max_smear_px during it.
    let scene = scene(3, 0.5);
    let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
    rig.camera.set_exposure_us(20_000.0).unwrap();
    let sweep = Sweep::new(scene.camera.clone());
    let rough = scene.rough_position_mm;
    let px_per_mm = sweep.stripe_px_per_slide_mm(&laser(), &rough, 40.0, scene.plan.slides_mm[2]);
    let config =
        ControllerConfig { mode: ScanMode::Continuous(sweep), ..ControllerConfig::default() };
    let scan = ScanController::new(laser(), config).unwrap().run(&mut rig.rig(), &rough).unwrap();
    let speed = scan.sweep_speed_mm_per_s.unwrap();
    let smear_px = speed * 0.020 * px_per_mm;
    assert!(smear_px <= 1.0 + 1e-6, "{smear_px:.3} px at {speed:.2} mm/s");
    assert!(smear_px > 0.5, "{smear_px:.3} px: slower than it needs to be");
}

#[test]
fn a_sweep_whose_camera_times_out_names_the_camera_and_turns_the_laser_off() {
    let scene = scene(2, 0.1);
    let slow = SimulatedRigOptions { frame_time: Duration::from_secs(1), ..Default::default() };
    let config =
        ControllerConfig { capture_timeout: Duration::from_millis(500), ..sweeping(&scene) };
    let (rig, scan) = scan_with(&scene, slow, config);
    let error = scan.unwrap_err();
    assert_eq!(error.device(), Some(Device::Camera));
    // The sweep's first capture is its laser-off reference frame, before the slide moves.
    assert_eq!(error.step(), Some(Step::Capture { frame: 0, laser_on: false }), "{error}");
    assert!(!rig.laser_on());
    assert_eq!(rig.slide_mm(), 0.0);
}

#[test]
fn a_sweep_with_laser_off_frames_differences_every_frame_with_its_reference_frame() {
    let scene = scene(1, 0.5);
    let config = ControllerConfig { capture_laser_off: true, ..sweeping(&scene) };
    let scan = scan_with(&scene, SimulatedRigOptions::default(), config).1.unwrap();
    // The camera and the scene stand still: one laser-off frame, taken
    // before the sweep, is every frame's.
    let reference = scan.frames[0].image_laser_off.as_ref().unwrap();
    assert!(scan.frames.iter().all(|f| f.image_laser_off.as_ref() == Some(reference)));
    assert!(**reference == scene.render_at(0.0, false, 0).unwrap());
    // The scan folder holds it once, named by every frame.
    let spec = scan.to_scan(Path::new("scan"));
    assert!(
        spec.frames
            .iter()
            .all(|f| f.image_laser_off.as_deref() == Some(Path::new("frame0_off.png")))
    );
    assert_localized(&scan, &scene);
}

#[test]
fn a_sweep_of_a_one_frame_plan_moves_to_it_and_stands() {
    let scene = scene(2, 0.1);
    let mut config = sweeping(&scene);
    config.strategy.frames = 1;
    let (rig, scan) = scan_with(&scene, SimulatedRigOptions::default(), config);
    let scan = scan.unwrap();
    assert_eq!(scan.frames.len(), 1);
    assert_eq!(scan.frames[0].slide_mm, scene.plan.slides_mm[0]);
    assert_eq!(rig.slide_mm(), scene.plan.slides_mm[0]);
}

#[test]
fn an_extension_captures_frames_beyond_both_ends_of_the_sweep_and_turns_the_laser_off() {
    let scene = scene(3, 0.1);
    for (config, per_frame_off) in [
        (ControllerConfig { capture_laser_off: true, ..ControllerConfig::default() }, true),
        (ControllerConfig { capture_laser_off: true, ..sweeping(&scene) }, false),
    ] {
        let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
        let controller = ScanController::new(laser(), config).unwrap();
        let mut scan = controller.run(&mut rig.rig(), &scene.rough_position_mm).unwrap();
        let swept = scan.slides_mm();
        // Two 10 mm steps after the sweep's last planned frame (the slide
        // stands there), then two before its first.
        let plan = scan.plan.slides_mm.clone();
        let slides = controller.extension_slides(&scan, &[0], 200.0);
        assert_eq!(slides, vec![plan[4] + 10.0, plan[4] + 20.0, plan[0] - 10.0, plan[0] - 20.0]);
        // A slide shorter than the strategy's stroke leaves out what it cannot reach.
        assert_eq!(controller.extension_slides(&scan, &[0], plan[4] + 15.0).len(), 3);
        assert!(controller.extension_slides(&scan, &[], 200.0).is_empty());
        let mut calls = Vec::new();
        controller
            .capture_more(&mut rig.rig(), &mut scan, &slides, |done, total| {
                calls.push((done, total))
            })
            .unwrap();
        assert!(!rig.laser_on());
        // The sweep's frames first, as they were; then the extension's, each
        // rendered where the slide stood.
        assert_eq!(scan.slides_mm()[..5], swept[..]);
        for (k, want) in slides.iter().enumerate() {
            let frame = &scan.frames[k + 5];
            assert!((frame.slide_mm - want).abs() < 1e-6, "frame {}", k + 5);
            assert!(frame.image == scene.render_at(frame.slide_mm, true, (k + 5) as u64).unwrap());
        }
        // Laser-off images as the sweep took them: per frame, or a
        // continuous sweep's one reference for all.
        assert!(scan.frames.iter().all(|f| f.image_laser_off.is_some()));
        let reference = scan.frames[0].image_laser_off.clone().unwrap();
        let shared = scan.frames[5..]
            .iter()
            .all(|f| std::sync::Arc::ptr_eq(f.image_laser_off.as_ref().unwrap(), &reference));
        assert_eq!(shared, !per_frame_off);
        let images = if per_frame_off { 8 } else { 4 };
        assert_eq!(calls.first(), Some(&(1, images)));
        assert_eq!(calls.last(), Some(&(images, images)));
    }
}

#[test]
fn an_extension_that_fails_turns_the_laser_off_and_adds_no_frame() {
    let scene = scene(3, 0.1);
    let mut rig = SimulatedRig::new(scene.clone(), SimulatedRigOptions::default()).unwrap();
    let controller = ScanController::new(laser(), ControllerConfig::default()).unwrap();
    let mut scan = controller.run(&mut rig.rig(), &scene.rough_position_mm).unwrap();
    // The second position lies beyond the simulated slide's stroke.
    let last = scan.slides_mm()[4];
    let error = controller
        .capture_more(&mut rig.rig(), &mut scan, &[last + 10.0, 500.0], |_, _| {})
        .unwrap_err();
    assert!(error.to_string().contains("500"), "{error}");
    assert!(!rig.laser_on());
    assert_eq!(scan.frames.len(), 5);
}

#[test]
fn a_fruit_found_in_the_sweep_takes_no_extension() {
    let scene = scene(3, 0.5);
    let (mut rig, mut scan) = run_on_rig(&scene);
    let controller = ScanController::new(laser(), ControllerConfig::default()).unwrap();
    let localized = controller
        .localize_extending(
            &mut rig.rig(),
            &mut scan,
            &scene.camera,
            &scene.laser,
            &LocateOptions::default(),
            |_| panic!("no extension"),
            |_, _| {},
        )
        .unwrap();
    assert_eq!(localized.added, 0);
    assert_eq!(scan.frames.len(), 5);
    assert_eq!(localized.answers.len(), 1);
    assert_eq!(localized.answers[0].status, Status::Ok, "{}", localized.answers[0].reason);
}
