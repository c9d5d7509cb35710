//! The localizer given inputs that contradict the images: the frames'
//! slide positions, the laser or the camera wrong by what a rig team gets
//! wrong (issue 43's list), over a family of simulated scans. An `ok`
//! answer more than 15 mm off is a confident answer from contradicting
//! data; `not_found` is the right answer where the contradiction shows.
//!
//! `cargo run --release -p alacs-locate --example contradictions -- [--seeds tune|report] [--n N]`
//!
//! The scans: half scale, 0-40 % hidden, shade and sun, the seed's rough
//! position error; rendered with the true calibration, located with the
//! wrong one. Progress to standard error, the table (markdown) to
//! standard output.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_locate::{FrameImages, LocateOptions, Prior, Status, locate};
use alacs_model::{Camera, LaserModel};
use alacs_sim::{OrchardOptions, ScanOptions, simulate_rendered_scan};

/// First seed of the tuning range (apart from `families`' ranges).
const TUNE_SEEDS: u64 = 500_000;
/// First seed of the reporting range.
const REPORT_SEEDS: u64 = 5_000_000;
/// An `ok` answer farther than this from the truth is wrong (issue 40's bar).
const WRONG_MM: f64 = 15.0;
/// The renders' scale (half the 5 MP camera, as the families).
const SCALE: f64 = 0.5;

/// The inputs given to the localizer.
struct Inputs {
    camera: Camera,
    laser: LaserModel,
    slides_mm: Vec<f64>,
}

/// One way the inputs contradict the images.
struct Case {
    name: &'static str,
    apply: fn(&mut Inputs),
}

const CASES: &[Case] = &[
    Case { name: "none (the true calibration)", apply: |_| {} },
    Case {
        name: "every frame claims the first frame's slide position",
        apply: |i| {
            let first = i.slides_mm[0];
            i.slides_mm.iter_mut().for_each(|s| *s = first);
        },
    },
    Case {
        name: "slides all 10 mm off",
        apply: |i| i.slides_mm.iter_mut().for_each(|s| *s += 10.0),
    },
    Case {
        name: "slides all 30 mm off",
        apply: |i| i.slides_mm.iter_mut().for_each(|s| *s += 30.0),
    },
    Case { name: "laser L0 10 mm off", apply: |i| i.laser.l0_mm += 10.0 },
    Case { name: "laser alpha 0.5 deg off", apply: |i| i.laser.alpha_rad += 0.5_f64.to_radians() },
    Case { name: "laser beta 1 deg off", apply: |i| i.laser.beta_rad += 1.0_f64.to_radians() },
    Case { name: "slide scale 0.9 (true 1)", apply: |i| i.laser.slide_scale = 0.9 },
    Case { name: "camera cy 20 px off (at full scale)", apply: |i| i.camera.cy_px += 20.0 * SCALE },
    Case {
        name: "camera fx, fy 2 % off",
        apply: |i| {
            i.camera.fx_px *= 1.02;
            i.camera.fy_px *= 1.02;
        },
    },
];

#[derive(Default)]
struct Tally {
    right: usize,
    wrong: Vec<f64>,
    not_found: usize,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1));
    let base = match value("--seeds").map(String::as_str) {
        None | Some("tune") => TUNE_SEEDS,
        Some("report") => REPORT_SEEDS,
        Some(other) => panic!("--seeds tune|report, got {other}"),
    };
    let n: u64 = value("--n").map_or(12, |v| v.parse().expect("--n N"));
    // Every answer's offsets from the rough position (tuning seeds only).
    let verbose = args.iter().any(|a| a == "--scans");
    // The RGB-D camera's largest depth error, as a fraction of the depth:
    // the simulator draws the rough position within it, and the localizer
    // is told it.
    let rough_depth_error: f64 =
        value("--rough-depth-error").map_or(0.03, |v| v.parse().expect("--rough-depth-error F"));
    let locate_options = LocateOptions { rough_depth_error, ..LocateOptions::default() };
    assert!(!(verbose && base == REPORT_SEEDS), "--scans is for the tuning seeds");
    let camera = Camera::blackfly_s_5mp();
    let laser = LaserModel::seed_paper();
    let mut tallies: Vec<Tally> = CASES.iter().map(|_| Tally::default()).collect();
    for i in 0..n {
        eprintln!("scan {} of {n}", i + 1);
        let occlusion = 0.4 * (i as f64 + 0.5) / n as f64;
        let options = ScanOptions {
            orchard: OrchardOptions { occlusion, ..OrchardOptions::default() },
            sun: i % 2 == 1,
            scale: SCALE,
            seed: base + i,
            rough_depth_error,
            ..ScanOptions::default()
        };
        let Ok(sim) = simulate_rendered_scan(&camera, &laser, &options) else { continue };
        let scan = &sim.scan;
        let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
        for (case, tally) in CASES.iter().zip(&mut tallies) {
            let mut inputs = Inputs {
                camera: scan.camera.clone(),
                laser: scan.laser,
                slides_mm: sim.frames().map(|(_, s)| s).collect(),
            };
            (case.apply)(&mut inputs);
            let frames: Vec<FrameImages> = sim
                .frames()
                .zip(&inputs.slides_mm)
                .map(|((image, _), slide)| FrameImages::from((image, *slide)))
                .collect();
            let answer = locate(&inputs.camera, &inputs.laser, &prior, &frames, &locate_options)
                .expect("valid input");
            match (answer.status, answer.position_mm) {
                (Status::Ok, Some(p)) => {
                    let error = (p - scan.scene.fruit_centre).norm();
                    if verbose {
                        let rough = scan.rough_position_mm;
                        let sight = rough.coords.normalize();
                        let off = p - rough;
                        let truth_off = scan.scene.fruit_centre - rough;
                        let sigma = answer
                            .position_cov_mm2
                            .map_or(f64::NAN, |c| (sight.dot(&(c * sight))).sqrt());
                        eprintln!(
                            "  {}: error {error:.1} mm; answer - rough along {:.1} across {:.1}; truth - rough along {:.1}; sigma along {sigma:.1}; depth {:.0}",
                            case.name,
                            off.dot(&sight),
                            (off - sight * off.dot(&sight)).norm(),
                            truth_off.dot(&sight),
                            rough.coords.norm()
                        );
                    }
                    if error <= WRONG_MM {
                        tally.right += 1;
                    } else {
                        tally.wrong.push(error);
                    }
                }
                _ => tally.not_found += 1,
            }
        }
    }
    println!(
        "| inputs given | found within {WRONG_MM} mm | `ok` more than {WRONG_MM} mm off | not found |"
    );
    println!("|---|---|---|---|");
    for (case, tally) in CASES.iter().zip(&tallies) {
        let wrong = if tally.wrong.is_empty() {
            "0".to_string()
        } else {
            let list: Vec<String> = tally.wrong.iter().map(|e| format!("{e:.0}")).collect();
            format!("{} ({} mm)", tally.wrong.len(), list.join(", "))
        };
        println!("| {} | {} | {wrong} | {} |", case.name, tally.right, tally.not_found);
    }
}
