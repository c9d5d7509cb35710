//! The GenICam driver against aravis's fake GigE Vision camera
//! (`arv-fake-gv-camera-0.8`, Debian aravis-tools) on 127.0.0.1, started
//! and stopped here: software-triggered frames, exposure and gain through
//! GenICam, the rig check with a GenICam camera. Feature `genicam`.
//!
//! The camera is opened by its address, which does not broadcast; `.ci/run`
//! still runs this in a network namespace of its own with only loopback.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use alacs_rig::genicam::GenicamCamera;
use alacs_rig::{RigConfig, check_rig};
use alacs_scanner::FrameCamera;

/// One fake camera at a time: two on 127.0.0.1 share its port, and a test
/// could talk to the other's.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The fake camera, stopped when dropped.
struct FakeCamera(Child);

impl Drop for FakeCamera {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts the fake camera on 127.0.0.1 and waits until it answers.
fn fake_camera() -> (FakeCamera, GenicamCamera) {
    let child = Command::new("arv-fake-gv-camera-0.8")
        .args(["-i", "127.0.0.1", "-s", "ALACS01"])
        .stdout(Stdio::null())
        .spawn()
        .expect("arv-fake-gv-camera-0.8 runs (Debian aravis-tools)");
    let fake = FakeCamera(child);
    let start = Instant::now();
    loop {
        match GenicamCamera::open("127.0.0.1") {
            Ok(camera) => return (fake, camera),
            Err(e) if start.elapsed() > Duration::from_secs(20) => panic!("{e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(200)),
        }
    }
}

fn mean(image: &image::RgbImage) -> f64 {
    image.iter().map(|&v| f64::from(v)).sum::<f64>() / image.len() as f64
}

#[test]
fn the_fake_gige_camera_gives_triggered_frames_at_the_exposure_set() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (_fake, mut camera) = fake_camera();
    assert!(camera.describe().contains("Aravis"), "{}", camera.describe());
    // The fake's exposure only scales brightness, from 10 ms.
    assert_eq!(camera.set_exposure_us(10_000.0).unwrap(), 10_000.0);
    let gain = camera.set_gain_db(0.0).unwrap();
    assert_eq!(gain, 0.0);
    let bright = camera.capture(Duration::from_secs(5)).unwrap();
    assert_eq!(bright.dimensions(), (512, 512));
    let next = camera.capture(Duration::from_secs(5)).unwrap();
    assert_ne!(bright, next, "each trigger gives a new frame");
    camera.set_exposure_us(3_000.0).unwrap();
    let dark = camera.capture(Duration::from_secs(5)).unwrap();
    assert!(mean(&dark) < 0.7 * mean(&bright), "{} vs {}", mean(&dark), mean(&bright));
    // Out of range is refused, naming the range; the setting stays.
    let error = camera.set_exposure_us(1.0e9).unwrap_err().to_string();
    assert!(error.starts_with("camera error") && error.contains("us is outside"), "{error}");
    assert!(camera.set_gain_db(f64::NAN).is_err());
}

#[test]
fn the_rig_check_passes_with_a_genicam_camera_and_a_simulated_slide() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let (_fake, camera) = fake_camera();
    drop(camera);
    let config = RigConfig::from_toml(
        "[slide]\ndriver = \"sim\"\n[laser]\ndriver = \"sim\"\n\
         [camera]\ndriver = \"genicam\"\ndevice = \"127.0.0.1\"\nexposure_us = 10000.0\n",
        Path::new("rig.toml"),
    )
    .unwrap();
    let options = alacs_sim::ScanOptions { scale: 0.1, ..alacs_sim::ScanOptions::default() };
    let scene = alacs_sim::simulate_scan(
        &alacs_model::Camera::blackfly_s_5mp(),
        &alacs_model::LaserModel::seed_paper(),
        &options,
    )
    .unwrap();
    let steps = check_rig(&config, Some(std::sync::Arc::new(scene)), &mut |_| {});
    let failed: Vec<_> = steps.iter().filter(|s| s.outcome.is_err()).collect();
    assert!(failed.is_empty(), "{failed:#?}");
    let capture = steps.last().unwrap();
    assert_eq!(capture.outcome.as_deref(), Ok("512 x 512 px RGB"));
    let connect = &steps[2];
    assert!(connect.outcome.as_deref().unwrap().contains("GenICam camera Aravis"), "{connect:?}");
}
