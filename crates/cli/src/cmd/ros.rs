//! `alacs ros`: the ROS 2 node on the simulated rig (`--sim`) or a
//! rig.toml's (`--rig`).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use alacs::ros::{Frames, FruitDetector, JobContext, NodeConfig, RosEnvironment, run_node};
use anyhow::anyhow;
use serde_json::json;

use crate::args::{RgbdDetectorArg, RosArgs};
use crate::cmd::rig::{self, OpenRig};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs ros` until SIGINT or SIGTERM (or `--max-goals`).
pub fn run(args: &RosArgs) -> CmdResult {
    // First of all: a signal while the rig opens or the scene is built (a
    // simulated scene takes a second) ends the node as any other stop does,
    // with its summary, not with the default action's exit 130 or 143.
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| Failure::job_failed(anyhow!("cannot handle signal {signal}: {e}")))?;
    }
    let env = RosEnvironment::from_env()?;
    env.service_mapping()?;
    let config = NodeConfig {
        namespace: args.namespace.clone(),
        node_name: args.node_name.clone(),
        frames: Frames { camera: args.camera_frame.clone(), rgbd: args.rgbd_frame.clone() },
        publish_images: !args.no_images,
        max_goals: args.max_goals,
        record: args.record.clone(),
        mount: if args.no_static_tf {
            None
        } else {
            Some((args.mount_frame.clone(), args.mount_from_camera))
        },
        remaps: args.remap.iter().map(|r| parse_remap(r)).collect::<CmdResult<_>>()?,
        rgbd_ns: (args.rgbd_detector != RgbdDetectorArg::None).then(|| args.rgbd_ns.clone()),
        detector: match args.rgbd_detector {
            RgbdDetectorArg::Topic => {
                FruitDetector::Topic { classes: args.detection_classes.clone() }
            }
            RgbdDetectorArg::Builtin | RgbdDetectorArg::None => FruitDetector::Builtin,
        },
        sources: [
            ("rig", &args.rig.rig_file),
            ("camera", &args.rig.camera),
            ("laser", &args.rig.laser),
        ]
        .into_iter()
        .filter_map(|(what, path)| Some((what.to_string(), path.clone()?)))
        .collect(),
        parameters: args.parameters.clone(),
    };
    config.validate()?;
    let OpenRig { devices, sim, camera, laser, alacs_from_rgbd, controller } =
        rig::open(&args.rig, &mut |line| errln!("{line}"))?;
    if let Some(sim) = &sim {
        let c = sim.scene.fruit_centre;
        let rough_in_rgbd = alacs_from_rgbd.inverse() * sim.rough_position_mm;
        errln!(
            "simulated apple (seed {}) at ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, radius {:.1} mm; the RGB-D \
             camera sees it at ({:.1}, {:.1}, {:.1}) mm in its frame",
            args.rig.scene.seed,
            c.x,
            c.y,
            c.z,
            sim.scene.fruit_radius_mm,
            rough_in_rgbd.x,
            rough_in_rgbd.y,
            rough_in_rgbd.z
        );
    }
    let job = JobContext {
        camera,
        laser,
        config: controller,
        locate: args.rig.rough_error.locate_options(alacs::locate::Method::Fused),
    };
    let rig = devices;

    let log = |line: &str| errln!("{line}");
    let summary = run_node(&config, &env, job, rig, stop, &log)?;
    if args.json {
        output::print_json(&json!({
            "goals": summary.goals,
            "found": summary.found,
            "rejected": summary.rejected,
            "errors": summary.errors,
            "cancelled": summary.cancelled,
            "stopped": summary.stopped,
            "sweeps": summary.sweeps,
        }))?;
    } else {
        outln!(
            "served {} goals and {} sweeps: {} fruit found, {} rejected, {} errors, {} cancelled, {} stopped by a signal",
            summary.goals,
            summary.sweeps,
            summary.found,
            summary.rejected,
            summary.errors,
            summary.cancelled,
            summary.stopped
        );
    }
    Ok(())
}

/// `FROM:=TO`, both non-empty.
fn parse_remap(text: &str) -> CmdResult<(String, String)> {
    match text.split_once(":=") {
        Some((from, to)) if !from.trim().is_empty() && !to.trim().is_empty() => {
            Ok((from.trim().to_owned(), to.trim().to_owned()))
        }
        _ => Err(Failure::bad_input(anyhow!(
            "--remap `{text}`: FROM:=TO, e.g. fruit:=/harvester/fruit"
        ))),
    }
}
