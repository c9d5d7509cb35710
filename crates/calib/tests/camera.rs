//! Camera calibration from checkerboard views: OpenCV's real photographs,
//! compared with OpenCV's own calibration.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::{Path, PathBuf};

use alacs_board::{board_gray, detect_board_precise};
use alacs_calib::{BoardObservation, IntrinsicsOptions, calibrate_intrinsics};
use alacs_model::Session;
use alacs_vision::read_image;

fn opencv_right() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/opencv_right")
}

fn observations(session: &Session) -> Vec<BoardObservation> {
    session
        .views
        .iter()
        .map(|view| {
            let image = read_image(&session.path_of(&view.image)).unwrap();
            let corners = detect_board_precise(&board_gray(&image), &session.board).unwrap();
            let (points_in_board, pixels) =
                corners.found().map(|(i, p)| (session.board.corner_in_board(i), p)).unzip();
            BoardObservation { name: view.image.display().to_string(), points_in_board, pixels }
        })
        .collect()
}

#[test]
fn opencv_right_calibrates_like_opencv() {
    let session = Session::read(&opencv_right()).unwrap();
    let views = observations(&session);
    let fit = calibrate_intrinsics(640, 480, &views, &IntrinsicsOptions::default()).unwrap();
    let c = &fit.camera;
    eprintln!(
        "rms {:.4} px, fx {:.2} fy {:.2} cx {:.2} cy {:.2} dist {:?}, used {}",
        fit.rms_px,
        c.fx_px,
        c.fy_px,
        c.cx_px,
        c.cy_px,
        c.distortion.coefficients(),
        fit.views_used()
    );
    for v in &fit.views {
        eprintln!("{}: {:?} {:?}", v.name, v.rms_px, v.rejected);
    }
    // OpenCV on its SB corners: RMS 0.246 px; fx of its refinements 534.6-542.4 px.
    assert!(fit.rms_px <= 0.246, "RMS {:.4} px", fit.rms_px);
    assert!((534.6..=542.4).contains(&c.fx_px), "fx {:.2}", c.fx_px);
}
