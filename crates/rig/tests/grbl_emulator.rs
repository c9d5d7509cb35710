//! The GRBL driver against an emulated GRBL 1.1 controller on a
//! pseudo-terminal (`devices/grbl_emulator.py`, Python's standard library
//! only, written from GRBL's documented protocol, not from this driver):
//! the rig check, a whole scan with the simulator's camera, and the faults
//! a serial controller has: a lost `ok`, a garbage line, a soft-limit
//! alarm, a controller that stops answering, the port vanishing. Every
//! fault must end in an error naming the slide, with the laser off.
//!
//! Needs `python3` (or `ALACS_PYTHON`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use alacs_locate::LocateOptions;
use alacs_model::{Camera, LaserModel};
use alacs_rig::{RealRig, RigConfig, check_rig};
use alacs_scanner::{ControllerConfig, Device, ScanController, ScanMode, Sweep};
use alacs_sim::{ScanOptions, SimulatedScan, simulate_scan};
use nalgebra::Point3;

/// The emulator, stopped when dropped.
struct Emulator {
    child: Child,
    port: String,
    log: PathBuf,
    _dir: tempfile::TempDir,
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Emulator {
    /// Starts the emulator with `options` (faults, time scale), logging
    /// every line it receives.
    fn start(options: &[&str]) -> Self {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/grbl_emulator.py");
        let python = std::env::var("ALACS_PYTHON").unwrap_or_else(|_| "python3".into());
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("received.log");
        let mut child = Command::new(python)
            .arg(&script)
            .args(["--time-scale", "0.2", "--log"])
            .arg(&log)
            .args(options)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("python3 runs the GRBL emulator");
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
        let port = first.trim().to_string();
        assert!(port.starts_with("/dev/"), "the emulator printed `{first}`");
        Self { child, port, log, _dir: dir }
    }

    /// The lines the controller received, in order.
    fn received(&self) -> Vec<String> {
        std::fs::read_to_string(&self.log).unwrap_or_default().lines().map(str::to_string).collect()
    }

    /// A rig.toml for this port: GRBL slide and laser, simulated camera.
    fn rig(&self, extra_slide: &str) -> RigConfig {
        let text = format!(
            "[slide]\n\
             driver = \"grbl\"\n\
             port = \"{}\"\n\
             feed_mm_per_min = 6000.0\n\
             command_timeout_s = 0.5\n\
             move_timeout_s = 3.0\n\
             {extra_slide}\n\
             [laser]\n\
             driver = \"grbl-spindle\"\n\
             power = 800\n\
             [camera]\n\
             driver = \"sim\"\n",
            self.port
        );
        RigConfig::from_toml(&text, Path::new("rig.toml")).unwrap()
    }
}

/// The simulated orchard scene every test's camera shows (built once).
fn scene() -> Arc<SimulatedScan> {
    static SCENE: OnceLock<Arc<SimulatedScan>> = OnceLock::new();
    SCENE
        .get_or_init(|| {
            let options = ScanOptions { scale: 0.25, seed: 4, ..ScanOptions::default() };
            Arc::new(
                simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options)
                    .unwrap(),
            )
        })
        .clone()
}

/// Runs the seed's scan of the scene's fruit on `rig`.
fn scan(rig: &mut RealRig, move_timeout: Duration) -> alacs_scanner::Result<Point3<f64>> {
    let config = ControllerConfig { move_timeout, ..ControllerConfig::default() };
    let controller = ScanController::new(LaserModel::seed_paper(), config)?;
    let scene = scene();
    let captured = controller.run(&mut rig.rig(), &scene.rough_position_mm)?;
    let answer =
        captured.localize(&scene.camera, &LaserModel::seed_paper(), &LocateOptions::default())?;
    Ok(answer.position_mm.expect("the fruit is found"))
}

#[test]
fn the_rig_check_against_an_emulated_grbl_passes_every_step() {
    let emulator = Emulator::start(&[]);
    let mut seen = Vec::new();
    let steps = check_rig(&emulator.rig(""), Some(scene()), &mut |s| seen.push(s.name.clone()));
    let failed: Vec<_> = steps.iter().filter(|s| s.outcome.is_err()).collect();
    assert!(failed.is_empty(), "{failed:#?}");
    let names: Vec<_> = steps.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "connect",
            "home",
            "connect",
            "connect",
            "move to 0 mm",
            "move to 100 mm",
            "move to 200 mm",
            "switch on",
            "switch off",
            "capture a frame"
        ]
    );
    assert_eq!(seen.len(), steps.len());
    // The moves stand where they were sent, as the controller reports.
    assert_eq!(steps[6].outcome.as_deref(), Ok("stands at 200.000 mm"));
    let received = emulator.received();
    assert!(received.contains(&"$H".to_string()), "{received:?}");
    assert!(received.contains(&"G90 G1 X100.000 F6000".to_string()), "{received:?}");
    assert!(received.contains(&"M3 S800".to_string()), "{received:?}");
    assert_eq!(received.last().map(String::as_str), Some("M5"), "{received:?}");
}

#[test]
fn a_scan_on_the_emulated_slide_finds_the_simulated_fruit() {
    let emulator = Emulator::start(&[]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    let found = scan(&mut rig, Duration::from_secs(3)).unwrap();
    let truth = scene().scene.fruit_centre;
    assert!((found - truth).norm() < 15.0, "{found} vs the truth {truth}");
    drop(rig);
    let received = emulator.received();
    // Five moves, five laser-on frames, the laser off after the scan.
    assert_eq!(received.iter().filter(|l| l.starts_with("G90 G1 X")).count(), 5);
    assert_eq!(received.last().map(String::as_str), Some("M5"), "{received:?}");
}

#[test]
fn a_continuous_sweep_on_the_emulated_slide_takes_each_frame_where_grbl_reported_it() {
    // In real time: the sweep's speed follows the camera's frame time.
    let emulator = Emulator::start(&["--time-scale", "1"]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    let scene = scene();
    let config = ControllerConfig {
        move_timeout: Duration::from_secs(5),
        mode: ScanMode::Continuous(Sweep::new(scene.camera.clone())),
        ..ControllerConfig::default()
    };
    let controller = ScanController::new(LaserModel::seed_paper(), config).unwrap();
    let captured = controller.run(&mut rig.rig(), &scene.rough_position_mm).unwrap();
    // The simulated camera renders where GRBL last reported the slide, and
    // the frame keeps that position: each frame near its planned position
    // (the slide runs on between the reports: measured 0.002-0.074 mm at
    // 55 mm/s; a quarter step allows for a loaded machine), in the plan's order.
    let planned = &scene.plan.slides_mm;
    assert_eq!(captured.frames.len(), planned.len());
    for (frame, planned) in captured.frames.iter().zip(planned) {
        println!("frame at {:.3} mm for {planned:.3} mm", frame.slide_mm);
        assert!((frame.slide_mm - planned).abs() < 2.5, "{} vs {planned}", frame.slide_mm);
    }
    assert!(captured.frames.windows(2).all(|w| w[0].slide_mm < w[1].slide_mm));
    let speed = captured.sweep_speed_mm_per_s.unwrap();
    println!("sweep at {speed:.1} mm/s");
    let answer = captured
        .localize(&scene.camera, &LaserModel::seed_paper(), &LocateOptions::default())
        .unwrap();
    let truth = scene.scene.fruit_centre;
    let found = answer.position_mm.expect("the fruit is found");
    assert!((found - truth).norm() < 15.0, "{found} vs the truth {truth}");
    drop(rig);
    // One G1 line for the whole sweep (the slide stood at 0 after homing,
    // below the plan), the laser off last.
    let received = emulator.received();
    let moves: Vec<_> = received.iter().filter(|l| l.starts_with("G90 G1 X")).collect();
    assert_eq!(moves.len(), 1, "{received:?}");
    assert!(moves[0].starts_with(&format!("G90 G1 X{:.3} F", planned[planned.len() - 1])));
    assert_eq!(received.last().map(String::as_str), Some("M5"), "{received:?}");
}

#[test]
fn a_lost_ok_and_a_garbage_line_do_not_stop_the_scan() {
    // Line 1 is $$ (the settings), 2 $H, 3 the first M5, 4 the first
    // move: its `ok` is lost and a garbage line follows the next move's `ok`.
    let emulator = Emulator::start(&["--drop-ok", "4", "--garbage-after", "6"]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    scan(&mut rig, Duration::from_secs(3)).unwrap();
}

#[test]
fn a_controller_that_stops_answering_mid_scan_ends_in_a_slide_error_with_m5_last() {
    // Silent after the first frame's M3 (line 5, after $$, $H, M5 and the
    // first move): the second move hangs.
    let emulator = Emulator::start(&["--silent-after", "5"]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    let error = scan(&mut rig, Duration::from_secs(1)).unwrap_err();
    assert_eq!(error.device(), Some(Device::Slide), "{error}");
    let message = error.to_string();
    assert!(message.contains("slide error at frame 1"), "{message}");
    assert!(message.contains(&emulator.port), "{message}");
    drop(rig);
    let received = emulator.received();
    assert_eq!(received.last().map(String::as_str), Some("M5"), "{received:?}");
}

#[test]
fn the_port_vanishing_mid_scan_is_an_error_naming_the_slide() {
    let emulator = Emulator::start(&["--vanish-after", "6"]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    let error = scan(&mut rig, Duration::from_secs(3)).unwrap_err();
    assert_eq!(error.device(), Some(Device::Slide), "{error}");
    assert!(error.to_string().contains("serial port"), "{error}");
}

#[test]
fn a_soft_limit_alarm_is_an_error_naming_the_slide_and_alarm_2() {
    // rig.toml claims 250 mm; the controller's travel ($130) is 200 mm.
    let emulator = Emulator::start(&[]);
    let config = emulator.rig("stroke_mm = 250.0");
    let mut rig = RealRig::open(&config, Some(scene())).unwrap();
    let error = rig.rig().slide.move_to(240.0, Duration::from_secs(3)).unwrap_err();
    assert_eq!(error.device(), Some(Device::Slide), "{error}");
    assert!(error.to_string().contains("ALARM:2"), "{error}");
    drop(rig);
    assert_eq!(emulator.received().last().map(String::as_str), Some("M5"));
}

#[test]
fn a_target_outside_the_stroke_is_refused_before_anything_is_sent() {
    let emulator = Emulator::start(&[]);
    let mut rig = RealRig::open(&emulator.rig(""), Some(scene())).unwrap();
    let before = emulator.received().len();
    for target in [-1.0, 200.5, f64::NAN] {
        let error = rig.rig().slide.move_to(target, Duration::from_secs(3)).unwrap_err();
        assert!(matches!(error, alacs_scanner::Error::OutOfStroke { .. }), "{error}");
    }
    assert_eq!(emulator.received().len(), before);
}

#[test]
fn no_controller_on_the_port_is_an_error_naming_the_slide_and_the_port() {
    // A pseudo-terminal whose controller never answers.
    let emulator = Emulator::start(&["--silent-after", "0"]);
    let error = RealRig::open(&emulator.rig(""), Some(scene())).unwrap_err();
    let message = error.to_string();
    assert!(message.starts_with("slide error"), "{message}");
    assert!(message.contains(&emulator.port), "{message}");
    let missing = RigConfig::from_toml(
        "[slide]\ndriver = \"grbl\"\nport = \"/dev/alacs-no-such-port\"\n",
        Path::new("rig.toml"),
    )
    .unwrap();
    let message = RealRig::open(&missing, None).unwrap_err().to_string();
    assert!(message.contains("cannot open the serial port /dev/alacs-no-such-port"), "{message}");
}

#[test]
fn grbl_laser_mode_is_refused_naming_the_setting() {
    // $32=1: the spindle output (the laser) is powered only while the axes
    // move, so every frame at a standing slide would be dark.
    let emulator = Emulator::start(&["--setting", "32=1"]);
    let Err(alacs_rig::Error::Device(error)) = RealRig::open(&emulator.rig(""), Some(scene()))
    else {
        panic!("a controller in laser mode was accepted, or refused for another reason");
    };
    assert_eq!(error.device(), Some(Device::Laser), "{error}");
    let message = error.to_string();
    assert!(message.contains("$32=1") && message.contains("$32=0"), "{message}");
    assert!(emulator.received().contains(&"$$".to_string()));
}

#[test]
fn grbl_reporting_inches_is_refused_naming_the_setting() {
    // $13=1: status reports in inches, which the slide would read as mm.
    let emulator = Emulator::start(&["--setting", "13=1"]);
    let Err(alacs_rig::Error::Device(error)) = RealRig::open(&emulator.rig(""), Some(scene()))
    else {
        panic!("a controller reporting inches was accepted, or refused for another reason");
    };
    assert_eq!(error.device(), Some(Device::Slide), "{error}");
    let message = error.to_string();
    assert!(message.contains("$13=1") && message.contains("$13=0"), "{message}");
    // The settings are read once for the slide and the laser.
    assert_eq!(emulator.received().iter().filter(|l| *l == "$$").count(), 1);
}
