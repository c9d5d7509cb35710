//! ChArUco detection on simulated views, boards cut by the image's border
//! included, against the simulator's true corners.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use alacs_board::{MIN_CHARUCO_CORNERS, board_gray, detect_board};
use alacs_model::{ArucoDictionary, Camera, LaserModel};
use alacs_sim::{Checkerboard, SessionOptions, simulate_session};
use image::DynamicImage;

fn charuco_session(seed: u64, cut_by_border: bool) -> alacs_sim::SimulatedSession {
    let board = Checkerboard::charuco(ArucoDictionary::Dict5x5_100);
    let options = SessionOptions {
        n_views: 8,
        scale: 0.5,
        seed,
        board,
        cut_by_border,
        ..SessionOptions::default()
    };
    simulate_session(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options).unwrap()
}

/// Detects every view; returns (views found, views cut by the border found,
/// views cut by the border, largest corner error px, RMS corner error px).
fn detect_all(session: &alacs_sim::SimulatedSession) -> (usize, usize, usize, f64, f64) {
    let spec = session.board.spec();
    let (mut found, mut cut_found, mut cut) = (0, 0, 0);
    let (mut worst, mut sum_sq, mut n) = (0.0_f64, 0.0, 0usize);
    for (index, view) in session.views.iter().enumerate() {
        let truth: Vec<Option<nalgebra::Point2<f64>>> = (0..spec.corner_count())
            .map(|i| {
                let p = session
                    .camera
                    .project(&(view.camera_from_board * spec.corner_in_board(i)))
                    .ok()?;
                let inside = p.x >= 0.0
                    && p.y >= 0.0
                    && p.x <= f64::from(session.camera.width_px) - 1.0
                    && p.y <= f64::from(session.camera.height_px) - 1.0;
                inside.then_some(p)
            })
            .collect();
        let is_cut = truth.iter().any(Option::is_none);
        cut += usize::from(is_cut);
        let image = DynamicImage::ImageRgb8(session.render_view(index).unwrap());
        let Ok(corners) = detect_board(&board_gray(&image), &spec) else { continue };
        found += 1;
        cut_found += usize::from(is_cut);
        assert!(corners.found_count() >= MIN_CHARUCO_CORNERS);
        for (i, p) in corners.found() {
            let t = truth[i]
                .unwrap_or_else(|| panic!("view {index}: corner {i} found outside the image"));
            let e = (p - t).norm();
            worst = worst.max(e);
            sum_sq += e * e;
            n += 1;
        }
    }
    (found, cut_found, cut, worst, (sum_sq / n.max(1) as f64).sqrt())
}

#[test]
fn charuco_corners_are_found_with_their_labels_also_on_boards_cut_by_the_border() {
    for seed in [1, 2] {
        let session = charuco_session(seed, true);
        let (found, cut_found, cut, worst, rms) = detect_all(&session);
        println!(
            "seed {seed}: {found} of 8 views, {cut_found} of {cut} cut by the border; corner error RMS {rms:.3} px, worst {worst:.3} px"
        );
        assert!(cut >= 2, "the session should cut boards by the border");
        assert!(found == 8 && cut_found == cut, "{found} views, {cut_found} cut");
        // A wrong label is a square (15+ px) away.
        assert!(worst < 0.5 && rms < 0.1, "RMS {rms} worst {worst}");
    }
}
