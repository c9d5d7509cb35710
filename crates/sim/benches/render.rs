//! One full-size (2448 x 2048 px, 5 MP) checkerboard view with the laser
//! line, and one orchard scan frame, 3 x 3 rays per pixel, sensor noise on; the camera's ray map is
//! computed once, outside the timed loop, as a session does.
//! Run with `cargo bench -p alacs-sim`.

// criterion's macros generate undocumented items; a bench without its scene
// cannot run, so it panics.
#![allow(missing_docs, clippy::panic)]

use alacs_model::{Camera, LaserModel};
use alacs_sim::{OrchardOptions, ScanOptions, SessionOptions, simulate_scan, simulate_session};
use criterion::{Criterion, criterion_group, criterion_main};
use image::RgbImage;

/// The simulated scene, or a panic naming `what` could not be simulated.
fn simulated<T>(what: &str, scene: alacs_sim::Result<T>) -> T {
    match scene {
        Ok(scene) => scene,
        Err(e) => panic!("simulating {what}: {e}"),
    }
}

/// Times each of `frames` (name, render). A frame takes a few hundred
/// milliseconds: 10 samples are plenty.
fn bench_frames(c: &mut Criterion, frames: &[(&str, &dyn Fn() -> alacs_sim::Result<RgbImage>)]) {
    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    for (name, render) in frames {
        group.bench_function(*name, |b| b.iter(|| std::hint::black_box(render())));
    }
    group.finish();
}

fn board_view(c: &mut Criterion) {
    let laser = LaserModel::seed_paper();
    let options = SessionOptions { n_views: 1, seed: 1, ..SessionOptions::default() };
    let session =
        simulated("a session", simulate_session(&Camera::blackfly_s_5mp(), &laser, &options));
    bench_frames(
        c,
        &[
            ("board_view_5mp", &|| session.render_view(0)),
            ("board_view_5mp_laser_off", &|| session.render_laser_off(0)),
        ],
    );
}

/// A full-size sunny scan frame with 30 % of the fruit behind leaves,
/// branches and background foliage, laser on.
fn scan_frame(c: &mut Criterion) {
    let laser = LaserModel::seed_paper();
    let orchard = OrchardOptions { occlusion: 0.3, ..OrchardOptions::default() };
    let options = ScanOptions { orchard, sun: true, seed: 2, ..ScanOptions::default() };
    let scan = simulated("a scan", simulate_scan(&Camera::blackfly_s_5mp(), &laser, &options));
    bench_frames(c, &[("scan_frame_5mp", &|| scan.render_frame(0, true))]);
}

criterion_group!(benches, board_view, scan_frame);
criterion_main!(benches);
