//! `alacs ros`: the ROS 2 node on the simulated rig (a real rig's rig.toml
//! comes with the drivers).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use alacs::locate::LocateOptions;
use alacs::ros::{Frames, JobContext, NodeConfig, RosEnvironment, run_node};
use alacs::scanner::{ControllerConfig, SimulatedRig, SimulatedRigOptions};
use alacs::sim::simulate_scan;
use alacs::{Camera, LaserModel};
use anyhow::anyhow;
use serde_json::json;

use crate::args::RosArgs;
use crate::cmd::scan::parse_pose;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs ros` until SIGINT or SIGTERM (or `--max-goals`).
pub fn run(args: &RosArgs) -> CmdResult {
    if let Some(rig) = &args.rig_file {
        return Err(Failure::bad_input(anyhow!(
            "--rig {}: real rigs (rig.toml) are not built in yet; run the node on the \
             simulated rig with --sim",
            rig.display()
        )));
    }
    if !args.rig.sim {
        return Err(Failure::bad_input(anyhow!(
            "only the simulated rig is built in: run `alacs ros --sim`"
        )));
    }
    let env = RosEnvironment::from_env()?;
    env.service_mapping()?;
    let alacs_from_rgbd = parse_pose(&args.rig.alacs_from_rgbd)?;
    let config = NodeConfig {
        namespace: args.namespace.clone(),
        node_name: args.node_name.clone(),
        frames: Frames { camera: args.camera_frame.clone(), rgbd: args.rgbd_frame.clone() },
        publish_images: !args.no_images,
        max_goals: args.max_goals,
    };
    config.validate()?;
    let camera_file = args.rig.camera.as_deref().map(Camera::from_yaml_file).transpose()?;
    let laser_file = args.rig.laser.as_deref().map(LaserModel::from_yaml_file).transpose()?;

    // The simulated rig's true laser: the seed paper's Table 1, Method 4.
    let true_laser = LaserModel::seed_paper();
    let options = args.rig.scene.options()?;
    eprintln!("building the simulated orchard scene and the camera's rays ...");
    let sim = Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &true_laser, &options)?);
    let c = sim.scene.fruit_centre;
    let rough_in_rgbd = alacs_from_rgbd.inverse() * sim.rough_position_mm;
    eprintln!(
        "simulated apple (seed {}) at ({:.1}, {:.1}, {:.1}) mm, radius {:.1} mm; the RGB-D camera \
         sees it at ({:.1}, {:.1}, {:.1}) mm in its frame",
        args.rig.scene.seed,
        c.x,
        c.y,
        c.z,
        sim.scene.fruit_radius_mm,
        rough_in_rgbd.x,
        rough_in_rgbd.y,
        rough_in_rgbd.z
    );
    let job = JobContext {
        camera: camera_file.unwrap_or_else(|| sim.camera.clone()),
        laser: laser_file.unwrap_or(true_laser),
        config: ControllerConfig {
            alacs_from_rgbd,
            capture_laser_off: args.rig.laser_off,
            ..ControllerConfig::default()
        },
        locate: LocateOptions::default(),
    };
    let rig = SimulatedRig::new(sim, SimulatedRigOptions::default())?;

    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| Failure::job_failed(anyhow!("cannot handle signal {signal}: {e}")))?;
    }
    let log = |line: &str| eprintln!("{line}");
    let summary = run_node(&config, &env, job, Box::new(rig), stop, &log)?;
    if args.json {
        output::print_json(&json!({
            "goals": summary.goals,
            "found": summary.found,
            "rejected": summary.rejected,
            "errors": summary.errors,
            "cancelled": summary.cancelled,
            "stopped": summary.stopped,
        }))?;
    } else {
        outln!(
            "served {} goals: {} found, {} rejected, {} errors, {} cancelled, {} stopped by a signal",
            summary.goals,
            summary.found,
            summary.rejected,
            summary.errors,
            summary.cancelled,
            summary.stopped
        );
    }
    Ok(())
}
