//! `alacs scan`: the scan controller on a rig, then localization, compared
//! with the simulator's truth when the camera is simulated.
//!
//! 1. Opens the rig ([`rig::open`]): the simulated rig (`--sim`: an orchard
//!    scene as `alacs simulate scan`) or rig.toml's devices (`--rig`), whose
//!    "sim" devices show that scene.
//! 2. Runs [`ScanController`] on it: the seed's plan from the RGB-D
//!    camera's rough position (`--rough-mm`, or the simulated RGB-D
//!    camera's), five frames.
//! 3. Localizes with `--camera` and `--laser`, or with a simulated camera
//!    the simulation's true camera and laser; where a fruit is not found
//!    for want of evidence, the controller extends the sweep beyond both
//!    ends ([`ScanController::localize_extending`]) and localizes it again.

use std::time::Instant;

use alacs::locate::{Localization, Status};
use alacs::model::MAX_SCAN_TARGETS;
use alacs::model::io::OutputDir;
use alacs::ros::Frames;
use alacs::ros::bag::BagWriter;
use alacs::scanner::{CapturedScan, ScanController};
use alacs::sim::SimulatedScan;
use alacs::{Camera, LaserModel};
use anyhow::anyhow;
use nalgebra::{Isometry3, Point3};
use serde_json::{Value, json};

use crate::args::ScanArgs;
use crate::cmd::rig::{self, OpenRig};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs scan`.
pub fn run(args: &ScanArgs) -> CmdResult {
    let bar = output::progress_bar(args.json, "opening the rig");
    let given = args.rough_mm.clone();
    if given.len() > MAX_SCAN_TARGETS {
        return Err(Failure::bad_input(anyhow!(
            "{} --rough-mm: a scan covers 1-{MAX_SCAN_TARGETS} fruit",
            given.len()
        )));
    }
    let OpenRig { mut devices, sim, camera, laser, alacs_from_rgbd, controller: config } =
        rig::open(&args.rig, &mut |line| bar.suspend(|| errln!("{line}")))?;
    // The RGB-D camera's rough position: given, or the simulated RGB-D
    // camera's (mounted at `alacs_from_rgbd`, it reports the position in its
    // own frame; the controller carries it back).
    // With --all-targets, every apple of the simulated cluster.
    let from_sim = given.is_empty();
    let roughs_in_rgbd: Vec<Point3<f64>> = match (from_sim, &sim) {
        (false, _) => given,
        (true, Some(sim)) => {
            sim.rough_positions().iter().map(|rough| alacs_from_rgbd.inverse() * rough).collect()
        }
        (true, None) => {
            return Err(Failure::bad_input(anyhow!(
                "--rough-mm X,Y,Z is needed: the rough position of the fruit in the RGB-D \
                 camera's frame"
            )));
        }
    };
    if roughs_in_rgbd.len() > 1 && args.record.is_some() {
        return Err(Failure::bad_input(anyhow!(
            "--record holds one fruit per scan (the action goal's rough position), and this \
             scan covers {}: scan them one at a time, or leave out --record",
            roughs_in_rgbd.len()
        )));
    }
    let controller = ScanController::new(laser, config)?;
    // Where the scan goes is checked before the rig moves: a scan of real
    // hardware must not be lost to an output that cannot be written.
    let mut recording = args
        .record
        .as_deref()
        .map(|path| BagWriter::create(path, "/alacs", &Frames::default(), args.force))
        .transpose()?;
    let out_was_there = args.out.as_deref().is_some_and(std::path::Path::exists);
    let mut folder = match &args.out {
        Some(dir) => Some(
            OutputDir::create(dir, "scan", args.force)
                .map_err(|e| Failure::from(e).with_context(dir))?,
        ),
        None => None,
    };
    output::start_progress(&bar, controller.image_count(), "scanning");
    let started = Instant::now();
    let locate_options = args.rig.rough_error.locate_options(alacs::locate::Method::Fused);
    let scanned =
        controller.run_targets_with_progress(&mut devices.rig(), &roughs_in_rgbd, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        });
    // Localization, and where a fruit is not found for want of evidence
    // the strategy's frames beyond its sweep (the rig is still open).
    let scanned = scanned.map(|mut scan| {
        bar.set_message("localizing");
        let (swept_images, swept_done) = (bar.length().unwrap_or(0), bar.position());
        let localized = controller.localize_extending(
            &mut devices.rig(),
            &mut scan,
            &camera,
            &laser,
            &locate_options,
            |slides| {
                bar.set_message("extending the sweep");
                bar.suspend(|| {
                    errln!("not found in the sweep: {} frames more beyond its ends", slides.len())
                });
            },
            |done, total| {
                bar.set_length(swept_images + total as u64);
                bar.set_position(swept_done + done as u64);
            },
        );
        (scan, localized)
    });
    let (scan, answers) = match scanned {
        Ok(scan) => scan,
        Err(error) => {
            // No scan: the --out folder made for it goes again (only if empty).
            if let (Some(dir), false) = (&args.out, out_was_there) {
                drop(folder);
                let _ = std::fs::remove_dir(dir);
            }
            return Err(error.into());
        }
    };
    // A real rig's time: the wall clock without localization's.
    let localizing = answers.as_ref().map_or(std::time::Duration::ZERO, |l| l.localizing);
    let rig_time_s = devices
        .simulated_time()
        .unwrap_or_else(|| started.elapsed().saturating_sub(localizing))
        .as_secs_f64();
    // The laser is off (the controller switched it off); a real rig's
    // connection closes here.
    drop(devices);
    let answers = answers.map(|localized| {
        if let Some(error) = &localized.extension_error {
            bar.suspend(|| {
                errln!("warning: the extension's frames were not taken ({error}); the answers are the sweep's")
            });
        }
        localized.answers
    });
    let answer = answers.map_err(|error| {
        let mut failure = Failure::from(error);
        if let Some(path) = &args.rig.camera {
            failure.error = failure.error.context(format!("localizing with {}", path.display()));
        }
        failure
    });
    // The scan is kept whatever localization said.
    if let Some(mut bag) = recording.take() {
        bar.set_message("recording");
        bag.write_scan(&scan, Some(&camera), answer.as_ref().ok().and_then(|a| a.first()))?;
        let path = bag.finish()?;
        bar.suspend(|| {
            errln!(
                "recorded the scan ({} frames) as a ROS 2 bag: {}",
                scan.frames.len(),
                path.display()
            )
        });
    }
    if let (Some(out), Some(dir)) = (folder.as_mut(), &args.out) {
        bar.set_message("writing");
        write(out, &scan, sim.as_deref(), &camera, &laser, args, &alacs_from_rgbd)
            .map_err(|f| f.with_context(dir))?;
    }
    if let Some(out) = folder.take() {
        let files = out.finish()?;
        if let Some(dir) = &args.out {
            errln!("{}", output::files_written(dir, &files));
        }
    }
    let mut answers = answer?;
    bar.finish_and_clear();
    if answers.len() > 1 {
        let truths = sim.as_deref().filter(|_| from_sim).map(|sim| sim.scene.apples());
        return print_targets(&scan, &answers, truths.as_deref(), rig_time_s, &camera, args);
    }
    let Some(answer) = answers.pop() else {
        return Err(Failure::job_failed(anyhow!("localization gave no answer")));
    };

    let truth = sim.as_ref().map(|sim| (sim.scene.fruit_centre, sim.scene.fruit_radius_mm));
    let error = answer.position_mm.zip(truth).map(|(p, (t, _))| p - t);
    if args.json {
        let mut value = output::localization_json(&answer);
        if let Value::Object(map) = &mut value {
            map.extend(truth_keys(truth, error));
            map.insert("rough_position_mm".into(), json!(point(&scan.rough_position_mm)));
            map.insert(
                "rough_position_in_rgbd_mm".into(),
                json!(point(&scan.rough_position_in_rgbd_mm)),
            );
            map.extend(scan_keys(&scan, rig_time_s, &camera, args));
        }
        output::print_json(&value)?;
    } else {
        out!("{}", summary(&scan, sim.as_deref(), &answer, rig_time_s, args));
    }
    Ok(())
}

/// `alacs scan --json`'s keys of a fruit's truth: `truth`, `error_mm` and
/// `error_3d_mm` (`null` without a truth or an answer).
fn truth_keys(
    truth: Option<(Point3<f64>, f64)>,
    error: Option<nalgebra::Vector3<f64>>,
) -> serde_json::Map<String, Value> {
    let mut keys = serde_json::Map::new();
    keys.insert(
        "truth".into(),
        json!(truth.map(|(t, r)| json!({"position_mm": point(&t), "radius_mm": r}))),
    );
    keys.insert("error_mm".into(), json!(error.map(|e| [e.x, e.y, e.z])));
    keys.insert("error_3d_mm".into(), json!(error.map(|e| e.norm())));
    keys
}

/// " in a continuous sweep at V mm/s" or nothing.
fn sweep_note(scan: &CapturedScan) -> String {
    scan.sweep_speed_mm_per_s
        .map(|v| format!(" in a continuous sweep at {v:.0} mm/s"))
        .unwrap_or_default()
}

/// `alacs scan --json`'s keys of the scan itself: slides, rig time,
/// image size and where it was written.
fn scan_keys(
    scan: &CapturedScan,
    rig_time_s: f64,
    camera: &Camera,
    args: &ScanArgs,
) -> serde_json::Map<String, Value> {
    let path = |p: &Option<std::path::PathBuf>| p.as_ref().map(|d| d.display().to_string());
    let mut keys = serde_json::Map::new();
    keys.insert("slides_mm".into(), json!(scan.slides_mm()));
    keys.insert("plan_shifted_into_stroke".into(), json!(scan.plan.shifted));
    keys.insert("rig_time_s".into(), json!(rig_time_s));
    keys.insert("scan_mode".into(), json!(scan.mode_name()));
    keys.insert("sweep_speed_mm_per_s".into(), json!(scan.sweep_speed_mm_per_s));
    keys.insert("image_width".into(), json!(camera.width_px));
    keys.insert("image_height".into(), json!(camera.height_px));
    keys.insert("out".into(), json!(path(&args.out)));
    keys.insert("record".into(), json!(path(&args.record)));
    keys
}

/// The answer for a scan of several fruit: FORMATS.md's several-fruit
/// localize object (`TargetsOutput`), each fruit with its truth and error
/// when they are known, and the scan's extra keys.
fn print_targets(
    scan: &CapturedScan,
    answers: &[Localization],
    truths: Option<&[(Point3<f64>, f64)]>,
    rig_time_s: f64,
    camera: &Camera,
    args: &ScanArgs,
) -> CmdResult {
    let truth = |k: usize| truths.and_then(|t| t.get(k)).copied();
    let error = |k: usize| {
        let answer = answers.get(k)?;
        answer
            .position_mm
            .filter(|_| answer.status == Status::Ok)
            .zip(truth(k))
            .map(|(p, (t, _))| p - t)
    };
    if args.json {
        let mut value = output::targets_json(answers, &scan.priors());
        if let Value::Object(map) = &mut value {
            if let Some(Value::Array(targets)) = map.get_mut("targets") {
                for (k, target) in targets.iter_mut().enumerate() {
                    if let Value::Object(target) = target {
                        target.extend(truth_keys(truth(k), error(k)));
                    }
                }
            }
            map.extend(scan_keys(scan, rig_time_s, camera, args));
        }
        output::print_json(&value)?;
    } else {
        let slides: Vec<String> = scan.slides_mm().iter().map(|d| format!("{d:.1}")).collect();
        out!(
            "scanned {} fruit in one sweep: {} frames at slides {} mm{}, {:.2} s of rig time\n",
            answers.len(),
            scan.frames.len(),
            slides.join(", "),
            sweep_note(scan),
            rig_time_s
        );
        out!("{}", output::targets_summary(answers, &scan.priors()));
        for k in 0..answers.len() {
            if let (Some((t, _)), Some(e)) = (truth(k), error(k)) {
                out!(
                    "target {k}: truth ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, error {:.2} mm in 3-D\n",
                    t.x,
                    t.y,
                    t.z,
                    e.norm()
                );
            }
        }
    }
    Ok(())
}

fn point(p: &Point3<f64>) -> [f64; 3] {
    [p.x, p.y, p.z]
}

/// The readable summary of a scan and its localization.
fn summary(
    scan: &CapturedScan,
    sim: Option<&SimulatedScan>,
    answer: &Localization,
    rig_time_s: f64,
    args: &ScanArgs,
) -> String {
    let xyz = |p: &Point3<f64>| format!("({:.1}, {:.1}, {:.1}) mm", p.x, p.y, p.z);
    let slides: Vec<String> = scan.slides_mm().iter().map(|d| format!("{d:.1}")).collect();
    let mut out = match sim {
        Some(sim) => format!(
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
        ),
        None => format!(
            "scanned: rough position {} in the RGB-D frame, {} in the ALACS frame\n",
            xyz(&scan.rough_position_in_rgbd_mm),
            xyz(&scan.rough_position_mm),
        ),
    };
    out += &format!(
        "  {} frames at slides {} mm{}{}{}, {:.2} s of rig time\n",
        scan.frames.len(),
        slides.join(", "),
        if args.rig.laser_off { " with laser-off frames" } else { "" },
        if scan.plan.shifted { " (the plan shifted into the stroke)" } else { "" },
        sweep_note(scan),
        rig_time_s
    );
    match (answer.status, answer.position_mm) {
        (Status::Ok, Some(p)) => {
            out += &format!(
                "  found the apple at {} in the ALACS frame, radius {:.1} mm ({})\n",
                xyz(&p),
                answer.radius_mm.unwrap_or(f64::NAN),
                answer.reason
            );
            if let Some(sim) = sim {
                let (truth, e) = (sim.scene.fruit_centre, p - sim.scene.fruit_centre);
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
        }
        _ => {
            out += &format!("  not found: {}\n", answer.reason);
            if let Some(sim) = sim {
                out += &format!(
                    "  truth {}, radius {:.1} mm\n",
                    xyz(&sim.scene.fruit_centre),
                    sim.scene.fruit_radius_mm
                );
            }
        }
    }
    out
}

/// Writes the scan folder, the camera and laser it was localized with, and truth.json.
fn write(
    out: &mut OutputDir,
    scan: &CapturedScan,
    sim: Option<&SimulatedScan>,
    camera: &Camera,
    laser: &LaserModel,
    args: &ScanArgs,
    alacs_from_rgbd: &Isometry3<f64>,
) -> CmdResult {
    scan.write_into(out)?;
    out.write("camera.yaml", camera.to_yaml_string())?;
    let header = if args.rig.laser.is_some() {
        "the calibrated laser the scan was planned and localized with"
    } else {
        "true laser of the simulated rig"
    };
    laser.to_yaml_file(&out.file("laser.yaml")?, header, None)?;
    let Some(sim) = sim else {
        return Ok(());
    };
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
    Ok(())
}
