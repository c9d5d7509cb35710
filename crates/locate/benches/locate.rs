//! Stripe extraction on a full 5 MP orchard frame, and the whole 5-frame
//! localization, in memory and from a scan folder (PNG decoding included).
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use alacs_locate::{FrameImages, LocateOptions, Prior, locate, locate_scan};
use alacs_model::{Camera, Fidelity, LaserModel, Scan};
use alacs_sim::{ScanOptions, simulate_rendered_scan};
use alacs_vision::{Region, StripeOptions, extract_stripe_rgb};
use criterion::{Criterion, criterion_group, criterion_main};

fn localization(c: &mut Criterion) {
    let laser = LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98);
    let options = ScanOptions { seed: 4, sun: true, ..ScanOptions::default() };
    let sim = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &laser, &options).unwrap();
    let (scan, images) = (&sim.scan, &sim.images);
    let mut group = c.benchmark_group("5mp");
    group.sample_size(10);

    let (width, height) = images[0].dimensions();
    let region = Region::full(width, height);
    group.bench_function("orchard_stripe_full_frame", |b| {
        b.iter(|| extract_stripe_rgb(&images[0], None, &region, &StripeOptions::orchard()).unwrap())
    });

    let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
    let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
    group.bench_function("locate_5_frames_in_memory", |b| {
        b.iter(|| locate(&scan.camera, &laser, &prior, &frames, &LocateOptions::default()).unwrap())
    });

    let dir = std::env::temp_dir().join(format!("alacs-bench-scan-{}", std::process::id()));
    scan.write(&dir, |_, _| {}).unwrap();
    let folder = Scan::read(&dir).unwrap();
    group.bench_function("locate_scan_folder_5_png", |b| {
        b.iter(|| {
            locate_scan(&folder, &scan.camera, &laser, &LocateOptions::default(), |_, _| {})
                .unwrap()
        })
    });
    group.finish();
    std::fs::remove_dir_all(&dir).ok();
}

criterion_group!(benches, localization);
criterion_main!(benches);
