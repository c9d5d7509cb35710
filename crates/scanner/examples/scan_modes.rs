//! Stop-and-go against the continuous sweep, in simulated time, on the
//! same simulated scans: `cargo run --release -p alacs-scanner --example
//! scan_modes -- [scans] [scale] [first_seed] [speed_mm_per_s] [acceleration_mm_per_s2] [settle_ms]`
//! (defaults: 20 scans at half scale from seed 0 on the simulated rig's
//! default slide: 50 mm/s, 500 mm/s^2, 50 ms settling).
//!
//! The scans run one after another, as a harvester's would: each starts
//! where the slide stood after the one before (the first at 0 mm). With
//! `FROM_PLAN=1` each starts at its plan's first position instead (the
//! slide already brought there): the frames' own cost. The
//! cycle is the rig's simulated time from the scan's start to its last
//! frame and the slide at rest; the error is the localized centre's
//! distance from the simulator's true centre (the scene's true camera and
//! laser). Prints one line per scan and the medians, and the least time
//! the slide's travel alone takes (one trapezoidal move from the start
//! through the nearer end of the plan to the other at full speed, no
//! frame, no settling): the bound under any mode's cycle on this slide.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;
use std::time::Duration;

use alacs_locate::{LocateOptions, Status};
use alacs_model::{Camera, LaserModel};
use alacs_scanner::{
    ControllerConfig, ScanController, ScanMode, SimulatedRig, SimulatedRigOptions, Sweep,
};
use alacs_sim::{ScanOptions, simulate_scan};

/// One mode's scan: cycle time, s; 3-D error, mm (None: not found); the
/// slide's position afterwards; the sweep speed.
struct Outcome {
    cycle_s: f64,
    error_mm: Option<f64>,
    end_mm: f64,
    speed: Option<f64>,
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 { values[n / 2] } else { 0.5 * (values[n / 2 - 1] + values[n / 2]) }
}

/// The least time of a move of `distance_mm` from rest to rest at top
/// speed `speed` and acceleration `acceleration` (trapezoidal, or
/// triangular when too short to reach the top speed).
fn move_time_s(distance_mm: f64, speed: f64, acceleration: f64) -> f64 {
    if distance_mm >= speed * speed / acceleration {
        distance_mm / speed + speed / acceleration
    } else {
        2.0 * (distance_mm / acceleration).sqrt()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |k: usize, default: f64| args.get(k).map_or(default, |a| a.parse().unwrap());
    let scans = arg(1, 20.0) as u64;
    let scale = arg(2, 0.5);
    let first_seed = arg(3, 0.0) as u64;
    let defaults = SimulatedRigOptions::default();
    let rig_options = SimulatedRigOptions {
        speed_mm_per_s: arg(4, defaults.speed_mm_per_s),
        acceleration_mm_per_s2: arg(5, defaults.acceleration_mm_per_s2),
        settle: Duration::from_secs_f64(arg(6, defaults.settle.as_secs_f64() * 1e3) / 1e3),
        ..defaults
    };
    let camera = Camera::blackfly_s_5mp();
    let laser = LaserModel::seed_paper();
    println!(
        "slide: {} mm/s, {} mm/s^2, settling {} ms; frame {} ms, report {} ms; scale {scale}",
        rig_options.speed_mm_per_s,
        rig_options.acceleration_mm_per_s2,
        rig_options.settle.as_millis(),
        rig_options.frame_time.as_millis(),
        rig_options.report_time.as_millis()
    );
    let names = ["stop_and_go", "continuous"];
    let from_plan = std::env::var("FROM_PLAN").is_ok_and(|v| v == "1");
    let mut starts = [0.0, 0.0];
    let mut outcomes: [Vec<Outcome>; 2] = [Vec::new(), Vec::new()];
    let mut bounds = Vec::new();
    for seed in first_seed..first_seed + scans {
        let options = ScanOptions { scale, seed, ..ScanOptions::default() };
        let scene = Arc::new(simulate_scan(&camera, &laser, &options).unwrap());
        let mut line = format!("seed {seed:3} z {:6.1} |", scene.scene.fruit_centre.z);
        if from_plan {
            starts = [scene.plan.slides_mm[0]; 2];
        }
        // The travel's bound from where the continuous scan starts.
        let (low, high) = scene
            .plan
            .slides_mm
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &d| (l.min(d), h.max(d)));
        let distance = (starts[1] - low).abs().min((starts[1] - high).abs()) + (high - low);
        bounds.push(move_time_s(
            distance,
            rig_options.speed_mm_per_s,
            rig_options.acceleration_mm_per_s2,
        ));
        // The sweep's smear limit uses the camera the frames are taken with.
        let modes = [ScanMode::StopAndGo, ScanMode::Continuous(Sweep::new(scene.camera.clone()))];
        for (m, mode) in modes.iter().enumerate() {
            let options = SimulatedRigOptions { start_mm: starts[m], ..rig_options };
            let mut rig = SimulatedRig::new(scene.clone(), options).unwrap();
            let config = ControllerConfig { mode: mode.clone(), ..ControllerConfig::default() };
            let controller = ScanController::new(laser, config).unwrap();
            let scan = controller.run(&mut rig.rig(), &scene.rough_position_mm).unwrap();
            let answer =
                scan.localize(&scene.camera, &scene.laser, &LocateOptions::default()).unwrap();
            let error_mm = (answer.status == Status::Ok)
                .then(|| (answer.position_mm.unwrap() - scene.scene.fruit_centre).norm());
            let outcome = Outcome {
                cycle_s: rig.elapsed().as_secs_f64(),
                error_mm,
                end_mm: rig.slide_mm(),
                speed: scan.sweep_speed_mm_per_s,
            };
            line += &format!(
                " {}: {:.3} s, {} from {:5.1} mm{} |",
                mode.name(),
                outcome.cycle_s,
                error_mm.map_or("not found".into(), |e| format!("{e:5.2} mm")),
                starts[m],
                outcome.speed.map_or(String::new(), |v| format!(" at {v:.0} mm/s")),
            );
            starts[m] = outcome.end_mm;
            outcomes[m].push(outcome);
        }
        println!("{line}");
    }
    for (m, name) in names.iter().enumerate() {
        let mut cycles: Vec<f64> = outcomes[m].iter().map(|o| o.cycle_s).collect();
        let mut errors: Vec<f64> = outcomes[m].iter().filter_map(|o| o.error_mm).collect();
        let found = errors.len();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        let total: f64 = cycles.iter().sum();
        println!(
            "{:12} cycle median {:.3} s, mean {:.3} s | found {found}/{} | error median {:.2} mm, worst {worst:.2} mm",
            name,
            median(&mut cycles),
            total / cycles.len() as f64,
            outcomes[m].len(),
            median(&mut errors),
        );
    }
    let mean = |m: usize| outcomes[m].iter().map(|o| o.cycle_s).sum::<f64>();
    println!("stop_and_go / continuous cycle time: {:.2}", mean(0) / mean(1));
    let bound: f64 = bounds.iter().sum();
    println!(
        "the slide's travel alone (continuous scans' starts): median {:.3} s, mean {:.3} s; stop_and_go / travel: {:.2}, continuous / travel: {:.2}",
        median(&mut bounds.clone()),
        bound / bounds.len() as f64,
        mean(0) / bound,
        mean(1) / bound
    );
}
