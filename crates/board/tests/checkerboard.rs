//! Checkerboard detection on OpenCV's real sample photographs, compared with
//! OpenCV's own corners.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::{Path, PathBuf};

use alacs_board::{board_gray, detect_checkerboard};
use alacs_model::Session;
use alacs_vision::read_image;
use nalgebra::Point2;
use serde_json::Value;

fn opencv_right() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/opencv_right")
}

/// OpenCV's corners per image file (None where OpenCV found no board).
fn reference(name: &str) -> Vec<(String, Option<Vec<Point2<f64>>>)> {
    let text = std::fs::read_to_string(opencv_right().join("reference").join(name)).unwrap();
    let json: Value = serde_json::from_str(&text).unwrap();
    json["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|image| {
            let corners = image["found"].as_bool().unwrap().then(|| {
                image["corners"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|c| Point2::new(c[0].as_f64().unwrap(), c[1].as_f64().unwrap()))
                    .collect()
            });
            (image["file"].as_str().unwrap().to_string(), corners)
        })
        .collect()
}

/// RMS distance between our corners and OpenCV's, in OpenCV's order or
/// reversed (OpenCV does not normalise the start corner).
fn rms_to_reference(ours: &[Point2<f64>], theirs: &[Point2<f64>]) -> f64 {
    let rms = |pairs: &mut dyn Iterator<Item = (&Point2<f64>, &Point2<f64>)>| {
        let d: Vec<f64> = pairs.map(|(a, b)| (a - b).norm_squared()).collect();
        (d.iter().sum::<f64>() / d.len() as f64).sqrt()
    };
    rms(&mut ours.iter().zip(theirs)).min(rms(&mut ours.iter().zip(theirs.iter().rev())))
}

#[test]
fn every_view_opencv_detects_is_detected_with_its_labels() {
    let session = Session::read(&opencv_right()).unwrap();
    for reference_file in ["opencv_right_corners_sb.json", "opencv_right_corners_classic_win5.json"]
    {
        for (file, corners) in reference(reference_file) {
            let Some(theirs) = corners else { continue };
            let image = read_image(&opencv_right().join(&file)).unwrap();
            let found = detect_checkerboard(&board_gray(&image), &session.board)
                .unwrap_or_else(|e| panic!("{file}: {e}"));
            assert_eq!(found.found_count(), 54, "{file}");
            let ours: Vec<Point2<f64>> = found.corners_px.iter().map(|c| c.unwrap()).collect();
            let rms = rms_to_reference(&ours, &theirs);
            // Same labels (a mislabelled corner is a whole square, 20+ px, away).
            assert!(rms < 1.0, "{file}: {rms:.3} px from {reference_file}");
        }
    }
}
