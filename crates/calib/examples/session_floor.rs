//! The calibration's noise floor on simulated half-scale sessions: for each
//! seed, the board corners' error against the simulator's truth (RMS and
//! worst, px) and the largest depth error over the working volume
//! (0.6-1.2 m, the whole image) at slides 0, 100 and 200 mm, with the
//! session's own camera and laser. Issue 17's bound is 1 mm.
//!
//! `cargo run --release -p alacs-calib --example session_floor -- [VIEWS] [FIRST_SEED] [COUNT] [K]`
//! (defaults 8, 100, 12, 0.99).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use alacs_calib::{
    IntrinsicsOptions, LaserSessionOptions, calibrate_camera_session, calibrate_laser_session,
    detect_session_boards,
};
use alacs_model::{Camera, LaserModel, Session};
use alacs_sim::{SessionOptions, SlideError, simulate_session};

#[path = "../tests/volume/mod.rs"]
mod volume;
use volume::max_depth_error_mm;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: f64| args.get(i).map_or(default, |a| a.parse().unwrap());
    let views = arg(0, 8.0) as usize;
    let first = arg(1, 100.0) as u64;
    let count = arg(2, 12.0) as u64;
    let k = arg(3, 0.99);
    let mut over = 0;
    for seed in first..first + count {
        let options = SessionOptions {
            n_views: views,
            slides_mm: vec![0.0, 100.0, 200.0],
            scale: 0.5,
            seed,
            slide: SlideError { scale: k, angle_deg: 0.0 },
            ..SessionOptions::default()
        };
        let simulated =
            simulate_session(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options)
                .unwrap();
        let dir = std::env::temp_dir().join(format!("alacs-floor-{seed}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        simulated.write(&dir).unwrap();
        let session = Session::read(&dir).unwrap();
        // Corner errors against the truth.
        let (_, boards) = detect_session_boards(&session, &|| {}).unwrap();
        let mut all = Vec::new();
        for board in &boards {
            let Ok(corners) = &board.corners else { continue };
            let view = simulated
                .views
                .iter()
                .find(|v| v.image_laser_off.as_deref().unwrap_or(&v.image) == board.image)
                .unwrap();
            for (i, pixel) in corners.found() {
                let point = view.camera_from_board * session.board.corner_in_board(i);
                let truth = simulated.camera.project(&point).unwrap();
                let e = (pixel - truth).norm();
                all.push(e);
                if std::env::var("SHOW").is_ok() && e > 0.15 {
                    println!(
                        "  {} corner {i} ({:.1}, {:.1}) error {e:.3} ({:+.3}, {:+.3})",
                        board.image,
                        truth.x,
                        truth.y,
                        pixel.x - truth.x,
                        pixel.y - truth.y
                    );
                }
            }
        }
        all.sort_by(f64::total_cmp);
        let n = all.len();
        let rms_px = (all.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
        let worst_px = all.last().copied().unwrap_or(0.0);
        let pct = |q: f64| all[((all.len() - 1) as f64 * q) as usize];
        println!(
            "  p50 {:.4} p90 {:.4} p99 {:.4}, > 0.15 px: {}",
            pct(0.5),
            pct(0.9),
            pct(0.99),
            all.iter().filter(|&&e| e > 0.15).count()
        );
        let fit =
            calibrate_camera_session(&session, &IntrinsicsOptions::default(), &|| {}).unwrap();
        let camera = fit.camera;
        let laser =
            calibrate_laser_session(&session, &camera, &LaserSessionOptions::default(), &|| {})
                .unwrap()
                .calibration
                .laser;
        let truth = (&simulated.camera, &simulated.laser);
        let errors: Vec<f64> = [0.0, 100.0, 200.0]
            .iter()
            .map(|&d| max_depth_error_mm(truth, (&camera, &laser), d))
            .collect();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        over += usize::from(worst > 1.0);
        println!(
            "seed {seed}: corners rms {rms_px:.4} px worst {worst_px:.3} ({n}), fx {:.2} (truth {:.2}) cx {:.2} cy {:.2}, k {:.6} ({:+.4} %), depth error {errors:.2?} mm{}",
            camera.fx_px,
            simulated.camera.fx_px,
            camera.cx_px - simulated.camera.cx_px,
            camera.cy_px - simulated.camera.cy_px,
            laser.slide_scale,
            100.0 * (laser.slide_scale - k) / k,
            if worst > 1.0 { "  > 1 mm" } else { "" }
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
    println!("{over} of {count} sessions beyond 1 mm");
}
