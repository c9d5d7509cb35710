//! Checkerboard detection and stripe extraction per image.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use alacs_board::{board_gray, detect_checkerboard};
use alacs_model::{BoardSpec, Camera, LaserModel};
use alacs_sim::{SessionOptions, simulate_session};
use alacs_vision::{
    Region, StripeOptions, extract_stripe, extract_stripe_rgb, laser_score, read_image,
};
use criterion::{Criterion, criterion_group, criterion_main};

fn detection(c: &mut Criterion) {
    let photo =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/opencv_right/right01.jpg");
    let photo = board_gray(&read_image(&photo).unwrap());
    let board_9x6 = BoardSpec::checkerboard(9, 6, 25.0, 25.0);
    c.bench_function("checkerboard_640x480_photo", |b| {
        b.iter(|| detect_checkerboard(&photo, &board_9x6).unwrap())
    });

    let laser = LaserModel::seed_paper();
    let options = SessionOptions { n_views: 1, seed: 1, ..SessionOptions::default() };
    let session = simulate_session(&Camera::blackfly_s_5mp(), &laser, &options).unwrap();
    let view = session.render_view(0).unwrap();
    let gray = board_gray(&image::DynamicImage::ImageRgb8(view.clone()));
    let (cols, rows) = session.board.inner_corners;
    let (square_x_mm, square_y_mm) = session.board.square_mm;
    let board = BoardSpec::checkerboard(cols, rows, square_x_mm, square_y_mm);
    let mut group = c.benchmark_group("5mp");
    group.sample_size(10);
    group.bench_function("checkerboard_5mp_view", |b| {
        b.iter(|| detect_checkerboard(&gray, &board).unwrap())
    });
    let region = Region::full(view.width(), view.height());
    group.bench_function("stripe_5mp_full_frame", |b| {
        b.iter(|| extract_stripe_rgb(&view, None, &region, &StripeOptions::default()).unwrap())
    });
    // The score image first, then the peaks (f32, one thread): the way
    // before the integer, parallel pass.
    group.bench_function("stripe_5mp_full_frame_score_image", |b| {
        b.iter(|| {
            let score = laser_score(&view, None, &StripeOptions::default()).unwrap();
            extract_stripe(&score, &region, &StripeOptions::default())
        })
    });
    group.finish();
}

criterion_group!(benches, detection);
criterion_main!(benches);
