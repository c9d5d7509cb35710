//! ChArUco boards against OpenCV (issue 17, item 2): a simulated session of
//! a ChArUco board cut by the image's border, its corners found by alacs and
//! by OpenCV's `CharucoDetector` (the same ids, and each side's distance to
//! the simulator's true corners), and the camera calibrated by alacs and by
//! OpenCV's `calibrateCamera` on alacs's partial-board corners (the same
//! minimum). The peer is opencv-python-headless from PyPI in
//! `ALACS_PEER_PYTHON` (`.ci/run` installs it); without it the alacs side
//! still runs and the comparison is skipped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use alacs_calib::{
    BoardObservation, IntrinsicsOptions, calibrate_intrinsics, detect_session_boards,
    pose_observations,
};
use alacs_model::{ArucoDictionary, Camera, LaserModel, Session};
use alacs_sim::{Checkerboard, SessionOptions, simulate_session};
use nalgebra::Point2;
use serde_json::json;

mod peers;

#[test]
fn charuco_corners_and_calibration_agree_with_opencv() {
    let board = Checkerboard::charuco(ArucoDictionary::Dict5x5_100);
    let options = SessionOptions {
        n_views: 8,
        scale: 0.5,
        seed: 1,
        board,
        cut_by_border: true,
        ..SessionOptions::default()
    };
    let simulated =
        simulate_session(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options).unwrap();
    let dir = std::env::temp_dir().join(format!("alacs-opencv-charuco-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    simulated.write(&dir).unwrap();
    let session = Session::read(&dir).unwrap();
    let spec = session.board;

    // alacs's corners, and their distance to the truth.
    let ((width, height), boards) = detect_session_boards(&session, &|| {}).unwrap();
    let truth = |view: usize, id: usize| {
        simulated
            .camera
            .project(&(simulated.views[view].camera_from_board * spec.corner_in_board(id)))
            .unwrap()
    };
    let mut observations = Vec::new();
    let mut cut = 0;
    let (mut ours_sq, mut n_ours) = (0.0, 0usize);
    for (view, detected) in boards.iter().enumerate() {
        let corners = detected.corners.as_ref().unwrap_or_else(|e| panic!("view {view}: {e}"));
        let outside = (0..spec.corner_count()).any(|id| {
            let p = truth(view, id);
            let (w, h) =
                (f64::from(simulated.camera.width_px), f64::from(simulated.camera.height_px));
            !(0.0..w).contains(&p.x) || !(0.0..h).contains(&p.y)
        });
        cut += usize::from(outside);
        for (id, p) in corners.found() {
            ours_sq += (p - truth(view, id)).norm_squared();
            n_ours += 1;
        }
        let (points_in_board, pixels) =
            corners.found().map(|(i, p)| (spec.corner_in_board(i), p)).unzip();
        observations.push(BoardObservation {
            name: detected.image.clone(),
            points_in_board,
            pixels,
        });
    }
    assert!(cut >= 2, "{cut} views cut by the border");
    let (_, poses) = pose_observations(&observations.iter().map(Some).collect::<Vec<_>>());
    let fit = calibrate_intrinsics(width, height, &poses, &IntrinsicsOptions::default()).unwrap();
    assert_eq!(fit.views_used(), 8);
    let ours_rms = (ours_sq / n_ours as f64).sqrt();
    let (across, down) = spec.squares();
    let request = json!({
        "squares": [across, down],
        "square_mm": spec.square_x_mm,
        "marker_mm": 22.5,
        "dictionary": "DICT_5X5_100",
        "images": boards.iter().map(|b| dir.join(&b.image).display().to_string()).collect::<Vec<_>>(),
    });
    let Some(theirs) = peers::run("opencv_charuco.py", &request) else {
        eprintln!(
            "alacs: corner error {ours_rms:.3} px RMS; SKIPPED OpenCV: set ALACS_PEER_PYTHON"
        );
        let _ = std::fs::remove_dir_all(&dir);
        return;
    };

    // The same ids where both found a corner; each side's error to the truth.
    let (mut both, mut only_theirs, mut theirs_sq, mut n_theirs) = (0, 0, 0.0, 0usize);
    for (view, image) in theirs["images"].as_array().unwrap().iter().enumerate() {
        let corners = boards[view].corners.as_ref().unwrap();
        let ids = image["ids"].as_array().unwrap();
        for (id, c) in ids.iter().zip(image["corners"].as_array().unwrap()) {
            let id = id.as_u64().unwrap() as usize;
            let p = Point2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
            theirs_sq += (p - truth(view, id)).norm_squared();
            n_theirs += 1;
            match corners.corners_px[id] {
                Some(ours) => {
                    both += 1;
                    // A wrong label is a square (15+ px) away.
                    assert!((ours - p).norm() < 1.0, "view {view} corner {id}: {ours} vs {p}");
                }
                None => only_theirs += 1,
            }
        }
    }
    let theirs_rms = (theirs_sq / n_theirs.max(1) as f64).sqrt();

    // OpenCV's calibrateCamera on alacs's corners: the same minimum.
    let calibrated = peers::calibrate_camera((width, height), &poses, &[], None).unwrap();
    eprintln!(
        "corners: alacs {n_ours} ({ours_rms:.3} px RMS to the truth), OpenCV {n_theirs} ({theirs_rms:.3} px), {both} in both, {only_theirs} only OpenCV's; truth fx {:.1}",
        simulated.camera.fx_px
    );
    // alacs finds nearly every corner OpenCV finds, at least as close to the truth.
    assert!(both * 20 >= n_theirs * 19, "{both} of OpenCV's {n_theirs}");
    assert!(ours_rms <= theirs_rms, "alacs {ours_rms} px vs OpenCV {theirs_rms} px");
    // The same minimum on the same corners.
    peers::assert_same_minimum("ChArUco, default controls", &fit, &calibrated);
    let _ = std::fs::remove_dir_all(&dir);
}
