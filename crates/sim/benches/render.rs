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

fn board_view(c: &mut Criterion) {
    let laser = LaserModel::seed_paper();
    let options = SessionOptions { n_views: 1, seed: 1, ..SessionOptions::default() };
    let session = match simulate_session(&Camera::blackfly_s_5mp(), &laser, &options) {
        Ok(session) => session,
        Err(e) => panic!("simulating a session: {e}"),
    };
    let mut group = c.benchmark_group("render");
    // A frame takes a few hundred milliseconds: 10 samples are plenty.
    group.sample_size(10);
    group.bench_function("board_view_5mp", |b| {
        b.iter(|| std::hint::black_box(session.render_view(0)))
    });
    group.bench_function("board_view_5mp_laser_off", |b| {
        b.iter(|| std::hint::black_box(session.render_laser_off(0)))
    });
    group.finish();
}

/// A full-size sunny scan frame with 30 % of the fruit behind leaves,
/// branches and background foliage, laser on.
fn scan_frame(c: &mut Criterion) {
    let laser = LaserModel::seed_paper();
    let orchard = OrchardOptions { occlusion: 0.3, ..OrchardOptions::default() };
    let options = ScanOptions { orchard, sun: true, seed: 2, ..ScanOptions::default() };
    let scan = match simulate_scan(&Camera::blackfly_s_5mp(), &laser, &options) {
        Ok(scan) => scan,
        Err(e) => panic!("simulating a scan: {e}"),
    };
    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    group.bench_function("scan_frame_5mp", |b| {
        b.iter(|| std::hint::black_box(scan.render_frame(0, true)))
    });
    group.finish();
}

criterion_group!(benches, board_view, scan_frame);
criterion_main!(benches);
