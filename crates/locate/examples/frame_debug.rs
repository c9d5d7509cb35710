//! Prints one frame's stripe points of a scan folder as CSV (u,v,fruit):
//! `cargo run --release -p alacs-locate --example frame_debug -- DIR FRAME`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use alacs_locate::{LocateOptions, locate_scan};
use alacs_model::{Camera, LaserModel, Scan};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = std::path::Path::new(&args[1]);
    let k: usize = args[2].parse().unwrap();
    let scan = Scan::read(dir).unwrap();
    let camera = Camera::from_yaml_file(&dir.join("camera.yaml")).unwrap();
    let laser = LaserModel::from_yaml_file(&dir.join("laser.yaml")).unwrap();
    let answer = locate_scan(&scan, &camera, &laser, &LocateOptions::default(), |_, _| {}).unwrap();
    let frame = &answer.frames[k];
    for (i, p) in frame.stripe.iter().enumerate() {
        let z = frame.points_in_camera.iter().find(|(j, _)| *j == i).map_or(f64::NAN, |(_, q)| q.z);
        println!(
            "{:.2},{},{},{:.1},{:.1}",
            p.u_px,
            p.v_px,
            u8::from(frame.fruit.contains(&i)),
            p.strength,
            z
        );
    }
    eprintln!(
        "outline {:?}",
        frame.region_outline_px.iter().map(|p| (p.x as i32, p.y as i32)).collect::<Vec<_>>()
    );
}
