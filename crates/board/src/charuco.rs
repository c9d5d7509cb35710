//! ChArUco boards: calib-targets' ChArUco detector (its corner grid labelled
//! by the markers it decodes), the corners in OpenCV's ChArUco order, then
//! refined with the image gradients as a checkerboard's are (in a disc
//! that keeps the markers out; so is the X-junction fit).
//!
//! A ChArUco board needs no complete view: each corner's label comes from
//! the markers around it, so a board cut by the image's border, or partly
//! hidden, still gives labelled corners (at least [`MIN_CHARUCO_CORNERS`],
//! not all on one line). The corner numbering is OpenCV's ChArUco corner id:
//! row-major from the top-left inner corner, as a checkerboard's.

use alacs_model::{BoardSpec, CharucoMarkers};
use calib_targets::charuco::{CharucoBoard, CharucoBoardSpec, CharucoParams, MarkerLayout};
use calib_targets::detect;
use image::GrayImage;

use crate::checkerboard::{
    MAX_REFINE_HALF_WINDOW_PX, REFINE_WINDOW_PER_CELL, keep_more, level_to_image,
    refine_corners_within,
};
use crate::{BoardCorners, Error, Result};

/// Fewest corners a ChArUco view must show (OpenCV's own interpolation asks
/// for at least a marker's worth; a homography needs 4 off one line).
pub const MIN_CHARUCO_CORNERS: usize = 6;

/// A board whose squares are smaller than this (px) and that shows fewer
/// than all its corners is searched again at [`UPSCALE`] times the size.
const SMALL_SQUARE_PX: f64 = 40.0;

/// The factor a missed board is searched again at (see [`detect_charuco`]):
/// at twice the size squares of 15-35 px (a half-scale 5 MP view) reach the
/// size at which the marker decoder reads them.
const UPSCALE: u32 = 2;

/// The refinement's radius in white margins (between a marker and its
/// square's edge): the window must not reach the markers, whose edges would
/// pull the corner, and a little more than one margin holds most of
/// the corner's edges (measured on simulated half-scale boards: smaller and
/// larger windows both gave larger corner errors).
const REFINE_RADIUS_PER_MARGIN: f64 = 1.3;

/// calib-targets' description of the board.
pub fn charuco_spec(board: &BoardSpec, markers: &CharucoMarkers) -> Result<CharucoBoardSpec> {
    let invalid = |reason: String| Error::InvalidBoard { reason };
    let dictionary =
        calib_targets::aruco::builtins::builtin_dictionary(markers.dictionary.as_str())
            .ok_or_else(|| {
                invalid(format!("calib-targets has no dictionary {}", markers.dictionary))
            })?;
    let square_mm = board.square_x_mm.min(board.square_y_mm);
    let (across, down) = board.squares();
    let spec = CharucoBoardSpec::new(
        u32::try_from(down).map_err(|e| invalid(e.to_string()))?,
        u32::try_from(across).map_err(|e| invalid(e.to_string()))?,
        square_mm as f32,
        (markers.marker_mm / square_mm) as f32,
        dictionary,
    )
    .with_marker_layout(MarkerLayout::OpenCvCharuco);
    CharucoBoard::new(spec).map_err(|e| invalid(e.to_string()))?;
    Ok(spec)
}

/// Finds a ChArUco board's corners in a grey image: every corner the
/// markers label, `None` for the rest.
pub fn detect_charuco(gray: &GrayImage, board: &BoardSpec) -> Result<BoardCorners> {
    let no_board = |reason: String| Error::NoBoard {
        kind: "ChArUco board",
        cols: board.cols,
        rows: board.rows,
        reason,
    };
    let Some(markers) = board.markers else {
        return Err(Error::InvalidBoard { reason: "the board has no markers".into() });
    };
    let spec = charuco_spec(board, &markers)?;
    let configs = CharucoParams::sweep_for_board(&spec);
    // Small squares (a far board at 15-35 px a square) often defeat the
    // corner grid at the image's own resolution (no board, or a piece of
    // it), so such a board is searched again at twice the resolution (the
    // positions mapped back; the refinement below runs on the original),
    // and the search that labelled more corners is kept.
    let first = detect::detect_charuco_best(gray, &configs)
        .map(|detection| labelled(&detection.corners, board, gray, 1));
    let retry = match &first {
        Err(_) => true,
        Ok(corners) => {
            corners.found_count() < board.corner_count()
                && corners.cell_size_px().is_none_or(|cell| cell < SMALL_SQUARE_PX)
        }
    };
    let mut corners = if retry {
        let upscaled = image::imageops::resize(
            gray,
            gray.width().saturating_mul(UPSCALE),
            gray.height().saturating_mul(UPSCALE),
            image::imageops::FilterType::Triangle,
        );
        let second = detect::detect_charuco_best(&upscaled, &configs)
            .map(|detection| labelled(&detection.corners, board, gray, UPSCALE));
        let first_error = first.as_ref().err().map(ToString::to_string);
        let mut best = first.ok();
        if let Ok(second) = second {
            keep_more(&mut best, second, |c| c);
        }
        best.ok_or_else(|| {
            no_board(format!("no ChArUco corners ({})", first_error.unwrap_or_default()))
        })?
    } else {
        first.map_err(|e| no_board(format!("no ChArUco corners ({e})")))?
    };
    let found = corners.found_count();
    if found < MIN_CHARUCO_CORNERS {
        return Err(no_board(format!(
            "only {found} ChArUco corners labelled, at least {MIN_CHARUCO_CORNERS} needed"
        )));
    }
    let (mut rows_seen, mut cols_seen) = (Vec::new(), Vec::new());
    for (i, _) in corners.found() {
        rows_seen.push(i / board.cols);
        cols_seen.push(i % board.cols);
    }
    rows_seen.dedup();
    cols_seen.sort_unstable();
    cols_seen.dedup();
    if rows_seen.len() < 2 || cols_seen.len() < 2 {
        return Err(no_board("the labelled ChArUco corners lie on one line".into()));
    }
    let cell_px = corners.cell_size_px().unwrap_or(0.0);
    let radius_px = marker_free_radius_px(board, &markers, cell_px)
        .min(REFINE_WINDOW_PER_CELL * cell_px)
        .clamp(2.0, MAX_REFINE_HALF_WINDOW_PX);
    refine_corners_within(gray, &mut corners, radius_px.ceil() as u32, radius_px);
    Ok(corners)
}

/// The radius around a ChArUco corner that holds no marker pixel, with
/// squares of `cell_px` in the image: the nearest marker pixel lies a white
/// margin away from the corner along both board axes, sqrt(2) margins; the
/// disc of [`REFINE_RADIUS_PER_MARGIN`] margins stays inside.
pub(crate) fn marker_free_radius_px(
    board: &BoardSpec,
    markers: &CharucoMarkers,
    cell_px: f64,
) -> f64 {
    let margin_px =
        (1.0 - markers.marker_mm / board.square_x_mm.min(board.square_y_mm)) / 2.0 * cell_px;
    REFINE_RADIUS_PER_MARGIN * margin_px
}

/// The corners of a detection (in an image `factor` times the size of
/// `gray`) by their ids, those outside `gray` dropped.
fn labelled(
    found: &[calib_targets::charuco::CharucoCorner],
    board: &BoardSpec,
    gray: &GrayImage,
    factor: u32,
) -> BoardCorners {
    let mut corners_px = vec![None; board.corner_count()];
    for corner in found {
        let position =
            level_to_image((corner.position.x, corner.position.y), 1.0 / f64::from(factor));
        let inside = position.x >= -0.5
            && position.y >= -0.5
            && position.x <= f64::from(gray.width()) - 0.5
            && position.y <= f64::from(gray.height()) - 0.5;
        if let Some(slot) = corners_px.get_mut(corner.id as usize)
            && inside
        {
            *slot = Some(position);
        }
    }
    BoardCorners { cols: board.cols, rows: board.rows, corners_px }
}

/// Finds the board of session.yaml: a checkerboard's full grid, or a
/// ChArUco board's labelled corners, refined as OpenCV's `cornerSubPix`
/// refines (the detector's speed and accuracy class; calibration takes
/// [`detect_board_precise`]).
pub fn detect_board(gray: &GrayImage, board: &BoardSpec) -> Result<BoardCorners> {
    if board.markers.is_some() {
        detect_charuco(gray, board)
    } else {
        crate::detect_checkerboard(gray, board)
    }
}

/// [`detect_board`], then every corner fitted as an X-junction
/// ([`fit_board_junctions`]): what calibration uses. About four times
/// closer to the truth on simulated views (0.014 px RMS against 0.05), at
/// about 2 ms more per 640 x 480 board of 54 corners.
pub fn detect_board_precise(gray: &GrayImage, board: &BoardSpec) -> Result<BoardCorners> {
    let mut corners = detect_board(gray, board)?;
    crate::fit_board_junctions(gray, board, &mut corners);
    Ok(corners)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use alacs_model::ArucoDictionary;
    use calib_targets::core::Coord;

    use super::*;

    #[test]
    fn the_models_dictionaries_are_calib_targets_ones() {
        for dictionary in ArucoDictionary::ALL {
            let found = calib_targets::aruco::builtins::builtin_dictionary(dictionary.as_str())
                .unwrap_or_else(|| panic!("{dictionary} missing"));
            assert_eq!(found.marker_size(), dictionary.marker_bits(), "{dictionary}");
            assert_eq!(found.codes().len(), dictionary.size(), "{dictionary}");
        }
    }

    #[test]
    fn the_models_marker_layout_is_calib_targets_one() {
        for (across, down) in [(5, 4), (6, 7), (10, 7), (11, 8)] {
            let mut board = BoardSpec::checkerboard(across - 1, down - 1, 20.0, 20.0);
            board.markers =
                Some(CharucoMarkers { marker_mm: 15.0, dictionary: ArucoDictionary::Dict5x5_100 });
            let theirs =
                CharucoBoard::new(charuco_spec(&board, &board.markers.unwrap()).unwrap()).unwrap();
            assert_eq!(theirs.marker_count(), board.marker_count());
            for j in 0..down {
                for i in 0..across {
                    let their_id = theirs.marker_id_at(Coord::new(i as i32, j as i32));
                    assert_eq!(
                        board.marker_id_at_square(i, j),
                        their_id.map(|id| id as usize),
                        "{across} x {down}, square ({i}, {j})"
                    );
                }
            }
        }
    }
}
