//! The rig of `scan` and `ros` (`--sim` or `--rig rig.toml`), and
//! `alacs rig check`.

use std::sync::Arc;

use alacs::rig::{CheckStep, RealRig, RigConfig, ScanModeName, check_rig};
use alacs::scanner::{
    ControllerConfig, Metering, ScanMode, ScanRig, SimulatedRig, SimulatedRigOptions, Sweep,
};
use alacs::sim::{SimulatedScan, simulate_scan};
use alacs::{Camera, LaserModel};
use anyhow::anyhow;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde_json::json;

use crate::args::{RigArgs, RigCheckArgs, SceneArgs};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// A rig ready to scan, with the calibration to plan and localize with.
pub struct OpenRig {
    /// The devices.
    pub devices: Box<dyn ScanRig>,
    /// The simulated scene, when a camera is simulated: the truth.
    pub sim: Option<Arc<SimulatedScan>>,
    /// The camera to localize with.
    pub camera: Camera,
    /// The laser to plan and localize with.
    pub laser: LaserModel,
    /// The RGB-D camera's pose in the ALACS frame.
    pub alacs_from_rgbd: Isometry3<f64>,
    /// The scan's settings that the rig gives (its move timeout), the rest
    /// the defaults.
    pub controller: ControllerConfig,
}

/// The pose of x, y, z (mm), roll, pitch, yaw (degrees):
/// R = Rz(yaw) Ry(pitch) Rx(roll).
pub fn pose([x, y, z, roll, pitch, yaw]: [f64; 6]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll.to_radians(), pitch.to_radians(), yaw.to_radians()),
    )
}

/// Builds the simulated scene of `scene` (a few seconds at full scale).
fn build_scene(scene: &SceneArgs) -> CmdResult<Arc<SimulatedScan>> {
    let options = scene.options()?;
    Ok(Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options)?))
}

/// Opens the rig of `args`: the simulated rig (`--sim`) or rig.toml's
/// (`--rig`), whose "sim" devices show the simulated scene. The camera
/// and laser are `--camera` / `--laser`, else (with a simulated camera)
/// the simulation's (its true ones, or with `--randomize` the nominal ones
/// the drawn rig is off). `note` prints what the user should know.
pub fn open(args: &RigArgs, note: &mut dyn FnMut(&str)) -> CmdResult<OpenRig> {
    let config = match (&args.rig_file, args.sim) {
        (Some(path), _) => Some(RigConfig::from_file(path)?),
        (None, true) => None,
        (None, false) => {
            return Err(Failure::bad_input(anyhow!(
                "which rig? --sim for the simulated rig, or --rig rig.toml for a real one \
                 (docs/FORMATS.md, \"rig.toml\")"
            )));
        }
    };
    let alacs_from_rgbd = match (&args.alacs_from_rgbd, &config) {
        (Some(given), _) => *given,
        (None, Some(config)) => pose(config.rgbd.alacs_from_rgbd),
        (None, None) => Isometry3::identity(),
    };
    // The calibrated files, where given, are read before the long work.
    let camera_file = args.camera.as_deref().map(Camera::from_yaml_file).transpose()?;
    let laser_file = args.laser.as_deref().map(LaserModel::from_yaml_file).transpose()?;
    let simulated_camera =
        config.as_ref().is_none_or(|c| c.camera.driver == alacs::rig::CameraDriver::Sim);
    if !simulated_camera && (camera_file.is_none() || laser_file.is_none()) {
        return Err(Failure::bad_input(anyhow!(
            "a real camera needs its calibration: --camera camera.yaml and --laser laser.yaml"
        )));
    }
    let needs_scene = config.as_ref().is_none_or(RigConfig::has_simulated_devices);
    let sim = if needs_scene {
        note("building the simulated orchard scene and the camera's rays ...");
        Some(build_scene(&args.scene)?)
    } else {
        None
    };
    let devices: Box<dyn ScanRig> = match (&config, &sim) {
        (None, Some(sim)) => {
            Box::new(SimulatedRig::new(Arc::clone(sim), SimulatedRigOptions::default())?)
        }
        (Some(config), _) => {
            let path = args.rig_file.as_deref().unwrap_or(std::path::Path::new("rig.toml"));
            let rig = RealRig::open(config, sim.clone())
                .map_err(|e| Failure::from(e).with_context(path))?;
            note(&format!("rig: {}", rig.describe()));
            Box::new(rig)
        }
        (None, None) => return Err(Failure::bad_input(anyhow!("no rig"))),
    };
    let (camera, laser) = match &sim {
        Some(sim) if simulated_camera => {
            if camera_file.is_none() || laser_file.is_none() {
                let (which, drawn) = match sim.variation {
                    Some(_) => ("nominal", " (--randomize rendered a rig drawn off them)"),
                    None => ("true", ""),
                };
                note(&format!(
                    "note: localizing with the simulation's {which} {}{drawn}; a real rig loads \
                     its calibrated camera.yaml and laser.yaml (--camera, --laser)",
                    match (camera_file.is_none(), laser_file.is_none()) {
                        (true, true) => "camera and laser",
                        (true, false) => "camera",
                        _ => "laser",
                    },
                ));
            }
            (
                camera_file.unwrap_or_else(|| sim.camera.clone()),
                laser_file.unwrap_or_else(LaserModel::seed_paper),
            )
        }
        _ => match (camera_file, laser_file) {
            (Some(camera), Some(laser)) => (camera, laser),
            _ => return Err(Failure::bad_input(anyhow!("--camera and --laser are needed"))),
        },
    };
    let mut controller = ControllerConfig {
        alacs_from_rgbd,
        capture_laser_off: args.laser_off,
        ..ControllerConfig::default()
    };
    // Metering, on unless turned off: the target metered with the laser off
    // and the exposure set so the fruit does not clip.
    let metering_on = !args.fixed_exposure && config.as_ref().is_none_or(|c| c.camera.metering);
    if metering_on {
        let mut metering = Metering::new(camera.clone());
        if let Some(config) = &config {
            let start_us = config.camera.exposure_us;
            metering.start_exposure_us = start_us;
            let (low, high) = metering.exposure_range_us;
            metering.exposure_range_us = (low.min(start_us), high.max(start_us));
            metering.bright_below_us = config.camera.bright_below_us;
        }
        controller.metering = Some(metering);
    }
    let scan_config = config.as_ref().map(|c| c.scan.clone()).unwrap_or_default();
    let mode = match args.scan_mode {
        Some(mode) => mode,
        None => scan_config.mode,
    };
    if mode == ScanModeName::Continuous {
        controller.mode = ScanMode::Continuous(Sweep {
            max_speed_mm_per_s: scan_config.sweep_speed_mm_per_s,
            max_smear_px: scan_config.max_smear_px,
            ..Sweep::new(camera.clone())
        });
    }
    if let Some(config) = &config {
        controller.move_timeout = config.slide.move_timeout();
        // A frame takes its exposure and a readout; 2 s at the least.
        let exposure_s = config.camera.exposure_us * 1e-6;
        controller.capture_timeout = controller
            .capture_timeout
            .max(std::time::Duration::from_secs_f64(2.0 * exposure_s + 1.0));
    }
    // The simulated scene is the truth only when the camera shows it: a real
    // camera with a simulated slide sees the real fruit.
    let sim = if simulated_camera { sim } else { None };
    Ok(OpenRig { devices, sim, camera, laser, alacs_from_rgbd, controller })
}

/// Runs `alacs rig check`.
pub fn check(args: &RigCheckArgs) -> CmdResult {
    let config = RigConfig::from_file(&args.rig_file)?;
    let scene = if config.has_simulated_devices() {
        if !args.json {
            errln!("building the simulated scene for the rig's \"sim\" devices ...");
        }
        Some(build_scene(&args.scene)?)
    } else {
        None
    };
    if !args.json {
        outln!("checking the rig of {}", args.rig_file.display());
    }
    let json = args.json;
    let mut print = |step: &CheckStep| {
        if !json {
            let (mark, text) = match &step.outcome {
                Ok(detail) => ("ok  ", detail.as_str()),
                Err(error) => ("FAIL", error.as_str()),
            };
            errln!(
                "  {mark} {:<7} {:<28} {:>7.3} s  {text}",
                step.device.to_string(),
                step.name,
                step.seconds
            );
        }
    };
    let steps = check_rig(&config, scene, &mut print);
    let failed = steps.iter().find(|s| s.outcome.is_err());
    let steps_json: Vec<_> = steps
        .iter()
        .map(|s| {
            let mut step = json!({
                "device": s.device.to_string(),
                "step": s.name,
                "seconds": s.seconds,
                "ok": s.outcome.is_ok(),
            });
            match &s.outcome {
                Ok(detail) => step["detail"] = json!(detail),
                Err(error) => step["error"] = json!(error),
            }
            step
        })
        .collect();
    let report = json!({
        "rig": args.rig_file.display().to_string(),
        "passed": failed.is_none(),
        "steps": steps_json,
    });
    if let Some(step) = failed {
        let mut failure = Failure::job_failed(anyhow!(
            "{}: the {} failed at `{}`: {}",
            args.rig_file.display(),
            step.device,
            step.name,
            step.outcome.as_ref().err().map(String::as_str).unwrap_or_default()
        ));
        failure.report = Some(report);
        return Err(failure);
    }
    if json {
        output::print_json(&report)?;
    } else {
        outln!("the rig passed: {} steps", steps.len());
    }
    Ok(())
}
