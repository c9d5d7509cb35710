//! Renders the small example images shown in docs/simulator.md (docs/images/):
//! a calibration-session view and a sunny, occluded scan frame.
//!
//! `cargo run --release -p alacs-sim --example render_examples -- docs/images`

use std::path::PathBuf;

use alacs_model::{Camera, LaserModel};
use alacs_sim::{OrchardOptions, ScanOptions, SessionOptions, simulate_scan, simulate_session};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "docs/images".into()));
    std::fs::create_dir_all(&out)?;
    let camera = Camera::blackfly_s_5mp();
    let laser = LaserModel::seed_paper();

    let session = SessionOptions { n_views: 1, scale: 0.25, seed: 3, ..SessionOptions::default() };
    let session = simulate_session(&camera, &laser, &session)?;
    session.render_view(0)?.save(out.join("session_view.jpg"))?;

    for (name, sun, occlusion, seed) in
        [("scan_shade.jpg", false, 0.0, 11), ("scan_sun_occluded.jpg", true, 0.3, 12)]
    {
        let orchard =
            OrchardOptions { occlusion, depth_mm: (700.0, 800.0), ..OrchardOptions::default() };
        let options = ScanOptions { orchard, sun, scale: 0.25, seed, ..ScanOptions::default() };
        let scan = simulate_scan(&camera, &laser, &options)?;
        scan.render_frame(2, true)?.save(out.join(name))?;
        println!(
            "{name}: fruit at {:?}, occlusion {:.2}",
            scan.scene.fruit_centre, scan.scene.occlusion
        );
    }
    Ok(())
}
