//! `alacs scan --sim`: the scan controller on the simulated rig, then
//! localization, compared with the simulator's truth.
//!
//! 1. Builds an orchard scene (as `alacs simulate scan`), with the RGB-D
//!    camera's rough position expressed in the RGB-D frame of
//!    `--alacs-from-rgbd`.
//! 2. Runs [`ScanController`] against the simulated slide, camera and laser:
//!    the seed's plan from the rough position, five frames.
//! 3. Localizes with the simulation's true camera and laser, or the
//!    calibrated files of `--camera` and `--laser`.
//!
//! Only the simulated rig is built in: a real rig's drivers implement
//! `alacs::scanner::{Slide, FrameCamera, LaserSwitch}` in their own crate.

use std::path::Path;
use std::sync::Arc;

use alacs::locate::{Localization, LocateOptions, Status};
use alacs::model::io::OutputDir;
use alacs::scanner::{
    CapturedScan, ControllerConfig, ScanController, SimulatedRig, SimulatedRigOptions,
};
use alacs::sim::{SimulatedScan, simulate_scan};
use alacs::{Camera, LaserModel};
use anyhow::anyhow;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use serde_json::{Value, json};

use crate::args::ScanArgs;
use crate::cmd::simulate::parse_list;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Parses `X,Y,Z,ROLL,PITCH,YAW` (mm, degrees) into the pose of the RGB-D
/// camera in the ALACS camera frame.
pub fn parse_pose(text: &str) -> CmdResult<Isometry3<f64>> {
    let limit_mm = alacs::model::MAX_ROUGH_DISTANCE_MM;
    match *parse_list(text, "--alacs-from-rgbd")?.as_slice() {
        [x, y, z, ..] if [x, y, z].iter().any(|t| t.abs() > limit_mm) => Err(Failure::bad_input(
            anyhow!("--alacs-from-rgbd `{text}`: the translation must lie within +-{limit_mm} mm"),
        )),
        [_, _, _, roll, pitch, yaw] if [roll, pitch, yaw].iter().any(|a| a.abs() > 360.0) => {
            Err(Failure::bad_input(anyhow!(
                "--alacs-from-rgbd `{text}`: roll, pitch and yaw must lie within +-360 deg"
            )))
        }
        [x, y, z, roll, pitch, yaw] => Ok(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(
                roll.to_radians(),
                pitch.to_radians(),
                yaw.to_radians(),
            ),
        )),
        _ => Err(Failure::bad_input(anyhow!(
            "--alacs-from-rgbd takes X,Y,Z,ROLL,PITCH,YAW (mm, degrees), got `{text}`"
        ))),
    }
}

/// Runs `alacs scan`.
pub fn run(args: &ScanArgs) -> CmdResult {
    if !args.rig.sim {
        return Err(Failure::bad_input(anyhow!(
            "only the simulated rig is built in: run `alacs scan --sim`. A real rig's drivers \
             implement alacs::scanner's Slide, FrameCamera and LaserSwitch traits in their own crate"
        )));
    }
    let alacs_from_rgbd = parse_pose(&args.rig.alacs_from_rgbd)?;
    // The simulated rig's true laser: the seed paper's Table 1, Method 4.
    let true_laser = LaserModel::seed_paper();
    let options = args.rig.scene.options()?;
    // The calibrated files, where given, are read before the long work.
    let camera_file = args.rig.camera.as_deref().map(Camera::from_yaml_file).transpose()?;
    let laser_file = args.rig.laser.as_deref().map(LaserModel::from_yaml_file).transpose()?;

    let bar = output::progress_bar(args.json, "building the scene and the camera's rays");
    let sim = Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &true_laser, &options)?);
    // The simulated RGB-D camera, mounted at `alacs_from_rgbd`, reports the
    // rough position in its own frame; the controller carries it back.
    let rough_in_rgbd = alacs_from_rgbd.inverse() * sim.rough_position_mm;
    let camera = camera_file.unwrap_or_else(|| sim.camera.clone());
    let laser = laser_file.unwrap_or(true_laser);
    if args.rig.camera.is_none() || args.rig.laser.is_none() {
        bar.suspend(|| {
            eprintln!(
                "note: localizing with the simulation's true {}; a real rig loads its calibrated \
                 camera.yaml and laser.yaml (--camera, --laser)",
                match (args.rig.camera.is_none(), args.rig.laser.is_none()) {
                    (true, true) => "camera and laser",
                    (true, false) => "camera",
                    _ => "laser",
                }
            );
        });
    }

    let config = ControllerConfig {
        alacs_from_rgbd,
        capture_laser_off: args.rig.laser_off,
        ..ControllerConfig::default()
    };
    let controller = ScanController::new(laser, config)?;
    let mut rig = SimulatedRig::new(sim.clone(), SimulatedRigOptions::default())?;
    output::start_progress(&bar, controller.image_count(), "scanning");
    let scan = controller.run_with_progress(&mut rig.rig(), &rough_in_rgbd, |done, _| {
        bar.set_position(done as u64);
    })?;
    bar.set_message("localizing");
    let answer = scan.localize(&camera, &laser, &LocateOptions::default()).map_err(|error| {
        let mut failure = Failure::from(error);
        if let Some(path) = &args.rig.camera {
            failure.error = failure.error.context(format!("localizing with {}", path.display()));
        }
        failure
    })?;
    if let Some(dir) = &args.out {
        bar.set_message("writing");
        write(dir, &scan, &sim, &camera, &laser, args, &alacs_from_rgbd)
            .map_err(|f| f.with_context(dir))?;
    }
    bar.finish_and_clear();

    let truth = sim.scene.fruit_centre;
    let error = answer.position_mm.map(|p| p - truth);
    let rig_time_s = rig.elapsed().as_secs_f64();
    if args.json {
        let mut value = output::localization_json(&answer);
        if let Value::Object(map) = &mut value {
            let extra = json!({
                "truth": {"position_mm": point(&truth), "radius_mm": sim.scene.fruit_radius_mm},
                "error_mm": error.map(|e| [e.x, e.y, e.z]),
                "error_3d_mm": error.map(|e| e.norm()),
                "rough_position_mm": point(&scan.rough_position_mm),
                "rough_position_in_rgbd_mm": point(&scan.rough_position_in_rgbd_mm),
                "slides_mm": scan.slides_mm(),
                "plan_shifted_into_stroke": scan.plan.shifted,
                "rig_time_s": rig_time_s,
                "image_width": camera.width_px,
                "image_height": camera.height_px,
                "out": args.out.as_ref().map(|d| d.display().to_string()),
            });
            if let Value::Object(extra) = extra {
                map.extend(extra);
            }
        }
        output::print_json(&value)?;
    } else {
        out!("{}", summary(&scan, &sim, &answer, rig_time_s, args));
    }
    Ok(())
}

fn point(p: &Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// The readable summary of a scan and its localization.
fn summary(
    scan: &CapturedScan,
    sim: &SimulatedScan,
    answer: &Localization,
    rig_time_s: f64,
    args: &ScanArgs,
) -> String {
    let xyz = |p: &Point3<f64>| format!("({:.1}, {:.1}, {:.1}) mm", p.x, p.y, p.z);
    let slides: Vec<String> = scan.slides_mm().iter().map(|d| format!("{d:.1}")).collect();
    let mut out = format!(
        "scanned a simulated apple (seed {}, {} x {} px{}{}): rough position {} in the RGB-D frame, {} in the ALACS frame\n",
        args.rig.scene.seed,
        sim.camera.width_px,
        sim.camera.height_px,
        if args.rig.scene.sun { ", sun" } else { "" },
        if args.rig.scene.occlusion > 0.0 {
            format!(", {:.0} % hidden", sim.scene.occlusion * 100.0)
        } else {
            String::new()
        },
        xyz(&scan.rough_position_in_rgbd_mm),
        xyz(&scan.rough_position_mm),
    );
    out += &format!(
        "  {} frames at slides {} mm{}{}, {:.2} s of rig time\n",
        scan.frames.len(),
        slides.join(", "),
        if args.rig.laser_off { " with laser-off frames" } else { "" },
        if scan.plan.shifted { " (the plan shifted into the stroke)" } else { "" },
        rig_time_s
    );
    let truth = sim.scene.fruit_centre;
    match (answer.status, answer.position_mm) {
        (Status::Ok, Some(p)) => {
            let e = p - truth;
            out += &format!(
                "  found the apple at {}, radius {:.1} mm ({})\n",
                xyz(&p),
                answer.radius_mm.unwrap_or(f64::NAN),
                answer.reason
            );
            out += &format!(
                "  truth {}, radius {:.1} mm: error ({:.2}, {:.2}, {:.2}) mm, {:.2} mm in 3-D\n",
                xyz(&truth),
                sim.scene.fruit_radius_mm,
                e.x,
                e.y,
                e.z,
                e.norm()
            );
        }
        _ => {
            out += &format!("  not found: {}\n", answer.reason);
            out +=
                &format!("  truth {}, radius {:.1} mm\n", xyz(&truth), sim.scene.fruit_radius_mm);
        }
    }
    if let Some(dir) = &args.out {
        out += &format!(
            "  wrote {} (scan.yaml, {} frames, camera.yaml, laser.yaml, truth.json)\n",
            dir.display(),
            scan.image_count()
        );
    }
    out
}

/// Writes the scan folder, the camera and laser it was localized with, and truth.json.
fn write(
    dir: &Path,
    scan: &CapturedScan,
    sim: &SimulatedScan,
    camera: &Camera,
    laser: &LaserModel,
    args: &ScanArgs,
    alacs_from_rgbd: &Isometry3<f64>,
) -> CmdResult {
    let mut out = OutputDir::create(dir, args.force)?;
    scan.write_into(&mut out)?;
    out.write("camera.yaml", camera.to_yaml_string())?;
    let header = if args.rig.laser.is_some() {
        "the calibrated laser the scan was planned and localized with"
    } else {
        "true laser of the simulated rig"
    };
    laser.to_yaml_file(&out.file("laser.yaml")?, header)?;
    let mut truth = sim.truth_json();
    if let Value::Object(map) = &mut truth {
        // The scan's slides are the controller's, not the simulator's own plan.
        map.insert("slides_mm".into(), json!(scan.slides_mm()));
        map.insert("plan_shifted_into_stroke".into(), json!(scan.plan.shifted));
        map.insert(
            "rough_position_in_rgbd_mm".into(),
            json!(point(&scan.rough_position_in_rgbd_mm)),
        );
        let matrix = alacs_from_rgbd.to_homogeneous();
        let rows: Vec<Vec<f64>> = matrix.row_iter().map(|r| r.iter().copied().collect()).collect();
        map.insert("alacs_from_rgbd".into(), json!({"matrix": rows}));
    }
    out.write("truth.json", serde_json::to_string_pretty(&truth).unwrap_or_default() + "\n")?;
    out.finish()?;
    Ok(())
}
