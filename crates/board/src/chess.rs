//! The ChESS corner pass (Bennett and Lasenby 2014, "ChESS - Quick and
//! Robust Detection of Chess-board Features") as calib-targets runs it,
//! with a response that the compiler vectorises.
//!
//! calib-targets' `detect_corners` runs chess-corners' detector: the dense
//! ChESS response, thresholding, non-maximum suppression and the response's
//! centre of mass, a merge of near duplicates, and an orientation fit per
//! corner. On stable Rust chess-corners computes the response one pixel at
//! a time (its SIMD kernel needs nightly's `portable_simd`), and on a
//! calibration view that is most of the pass. Here the response of a row is
//! computed in whole-row passes over 16-bit lanes, which the compiler turns
//! into vector code, rows in parallel, to the same `f32` values bit for bit
//! (test `the_response_is_chess_corners_own`); the stages after it are
//! chess-corners-core's own functions, composed as its detector composes
//! them (test `the_corner_pass_is_calib_targets_own` in the checkerboard
//! module).

use calib_targets::core::{AxisEstimate, PositionCovariance};
use calib_targets::{ChessCorner, detect};
use chess_corners::Roi;
use chess_corners_core::{
    CenterOfMassRefiner, ChessParams, Corner, CornerDescriptor, CornerRefiner, ResponseMap,
    chess_response_u8_patch, describe_corners, detect_corners_from_response, merge_corners_simple,
};
use image::GrayImage;
use rayon::prelude::*;

/// The ring of 16 samples at radius 5 around a pixel, clockwise from the
/// top (FAST-16 scaled to r = 5, as chess-corners' canonical ring).
const RING5: [(isize, isize); 16] = [
    (0, -5),
    (2, -5),
    (3, -3),
    (5, -2),
    (5, 0),
    (5, 2),
    (3, 3),
    (2, 5),
    (0, 5),
    (-2, 5),
    (-3, 3),
    (-5, 2),
    (-5, 0),
    (-5, -2),
    (-3, -3),
    (-2, -5),
];

/// Radius of [`RING5`] (px).
const RING5_RADIUS: usize = 5;

/// Rows of a response one parallel task computes at least.
const RESPONSE_ROWS_PER_TASK: usize = 8;

/// The ChESS corners of `level` (in `region` only, if given) with
/// calib-targets' corner settings, as calib-targets' chessboard detector
/// takes them: the corner pass of its `detect_corners` (which has no
/// region). A region's corners are those the whole image has there: the
/// response is computed over the region grown by the margin that the ring,
/// the maximum suppression and the centre of mass read, so every value
/// they use is the whole image's.
pub(crate) fn chess_corners(level: &GrayImage, region: Option<Roi>) -> Vec<ChessCorner> {
    let config = detect::default_chess_config();
    let params = config.chess_params();
    let (width, height) = (level.width() as usize, level.height() as usize);
    let whole = Roi::new(0, 0, width, height);
    let Some(region) = region.and_then(|r| clamp(r, width, height)).or(whole) else {
        return Vec::new();
    };
    let refiner = CenterOfMassRefiner::new(params.center_of_mass);
    let margin = params.ring_radius() as usize
        + params.nms_radius as usize
        + usize::try_from(refiner.radius()).unwrap_or(0);
    let patch = Roi::new(
        region.x0().saturating_sub(margin),
        region.y0().saturating_sub(margin),
        (region.x1() + margin).min(width),
        (region.y1() + margin).min(height),
    );
    let Some(patch) = patch else {
        return Vec::new();
    };
    let response = chess_response(level, patch, &params);
    // Peaks in the patch's frame, located by the response's centre of mass
    // (calib-targets' settings have no image refiner), shifted back; only
    // those inside the region are kept.
    let (x0, y0) = (patch.x0() as f32, patch.y0() as f32);
    let mut corners: Vec<Corner> = detect_corners_from_response(&response, &params)
        .into_iter()
        .map(|mut c| {
            c.x += x0;
            c.y += y0;
            c
        })
        .filter(|c| {
            (region.x0() as f32..region.x1() as f32).contains(&c.x)
                && (region.y0() as f32..region.y1() as f32).contains(&c.y)
        })
        .collect();
    let merged = merge_corners_simple(&mut corners, config.merge_radius);
    describe_corners(
        level.as_raw(),
        width,
        height,
        params.ring_radius(),
        merged,
        params.orientation_method,
    )
    .iter()
    .map(chess_corner)
    .collect()
}

/// `roi` cut to a `width x height` image, `None` if nothing is left.
fn clamp(roi: Roi, width: usize, height: usize) -> Option<Roi> {
    Roi::new(roi.x0(), roi.y0(), roi.x1().min(width), roi.y1().min(height))
}

/// The ChESS response over `patch` of `level`, in the patch's frame; 0
/// where the ring leaves the image (as chess-corners-core's
/// `chess_response_u8_patch`, which it is for a ring other than the
/// canonical radius 5).
fn chess_response(level: &GrayImage, patch: Roi, params: &ChessParams) -> ResponseMap {
    let (width, height) = (level.width() as usize, level.height() as usize);
    if params.ring_radius() as usize != RING5_RADIUS {
        return chess_response_u8_patch(level.as_raw(), width, height, params, patch);
    }
    let patch_width = patch.x1() - patch.x0();
    let mut data = vec![0.0_f32; patch_width * (patch.y1() - patch.y0())];
    let r = RING5_RADIUS;
    // Ring centres whose ring lies inside the image.
    let (x_start, x_end) = (patch.x0().max(r), patch.x1().min(width.saturating_sub(r)));
    if x_start < x_end {
        data.par_chunks_mut(patch_width)
            .with_min_len(RESPONSE_ROWS_PER_TASK)
            .enumerate()
            .for_each_init(RowSums::default, |sums, (row, out)| {
                let y = patch.y0() + row;
                if y >= r && y + r < height {
                    let out = &mut out[x_start - patch.x0()..x_end - patch.x0()];
                    sums.response_row(level.as_raw(), width, y, x_start, out);
                }
            });
    }
    ResponseMap::new(patch_width, patch.y1() - patch.y0(), data)
}

/// One row's sums of the ChESS response, each over the row's ring centres.
#[derive(Default)]
struct RowSums {
    /// `SR = sum_k |(s[k] + s[k+8]) - (s[k+4] + s[k+12])|`, k < 4.
    square: Vec<i16>,
    /// `DR = sum_k |s[k] - s[k+8]|`, k < 8.
    difference: Vec<i16>,
    /// The 16 ring samples' sum (16 x the ring mean).
    ring: Vec<i16>,
}

impl RowSums {
    /// `out[i]` = the response at `(x_start + i, y)`: `SR - DR - 16 |mean
    /// of the ring - mean of the cross|`, in `f32` as chess-corners-core
    /// evaluates it. The ring must lie inside the image at every centre.
    fn response_row(
        &mut self,
        pixels: &[u8],
        width: usize,
        y: usize,
        x_start: usize,
        out: &mut [f32],
    ) {
        let n = out.len();
        let at = |dx: isize, dy: isize| -> &[u8] {
            let start = (y as isize + dy) as usize * width + (x_start as isize + dx) as usize;
            &pixels[start..start + n]
        };
        for sums in [&mut self.square, &mut self.difference, &mut self.ring] {
            sums.clear();
            sums.resize(n, 0);
        }
        let (square, difference, ring) =
            (&mut self.square[..n], &mut self.difference[..n], &mut self.ring[..n]);
        // The four samples k, k + 4, k + 8, k + 12 of a quarter turn.
        for k in 0..4 {
            let (a, b, c, d) = (
                at(RING5[k].0, RING5[k].1),
                at(RING5[k + 4].0, RING5[k + 4].1),
                at(RING5[k + 8].0, RING5[k + 8].1),
                at(RING5[k + 12].0, RING5[k + 12].1),
            );
            for i in 0..n {
                let (a, b, c, d) =
                    (i16::from(a[i]), i16::from(b[i]), i16::from(c[i]), i16::from(d[i]));
                square[i] += ((a + c) - (b + d)).abs();
                difference[i] += (a - c).abs() + (b - d).abs();
                ring[i] += a + b + c + d;
            }
        }
        // The 5-pixel cross's sum (5 x the local mean).
        let (centre, west, east, north, south) =
            (at(0, 0), at(-1, 0), at(1, 0), at(0, -1), at(0, 1));
        for i in 0..n {
            let cross = i16::from(centre[i])
                + i16::from(north[i])
                + i16::from(south[i])
                + i16::from(east[i])
                + i16::from(west[i]);
            let mean_ring = f32::from(ring[i]) / 16.0;
            let mean_cross = f32::from(cross) / 5.0;
            out[i] = f32::from(square[i])
                - f32::from(difference[i])
                - 16.0 * (mean_ring - mean_cross).abs();
        }
    }
}

/// One ChESS corner as calib-targets' chessboard detector takes it (its
/// `detect_corners` adapts them so): a corner without an orientation fit
/// gets calib-targets' no-information axes, which its grid skips.
fn chess_corner(c: &CornerDescriptor) -> ChessCorner {
    let axis = |a: chess_corners::AxisEstimate| AxisEstimate {
        angle: a.angle,
        fit_std_error: a.fit_std_error,
    };
    let axes = c.axes.map_or([AxisEstimate::default(); 2], |[a, b]| [axis(a), axis(b)]);
    // Fields set on a default: calib-targets' nalgebra is not this crate's.
    let mut corner = ChessCorner::default()
        .with_position_covariance(c.position_covariance.map(PositionCovariance::from));
    (corner.position.x, corner.position.y) = (c.x, c.y);
    (corner.axes, corner.strength) = (axes, c.response);
    corner
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use super::*;
    use crate::checkerboard::tests::photo;
    use chess_corners_core::chess_response_u8;

    #[test]
    fn the_response_is_chess_corners_own() {
        let image = photo();
        let (w, h) = (image.width() as usize, image.height() as usize);
        let params = detect::default_chess_config().chess_params();
        let theirs = chess_response_u8(image.as_raw(), w, h, &params);
        let ours = chess_response(&image, Roi::new(0, 0, w, h).unwrap(), &params);
        assert_eq!(ours.data(), theirs.data());
        // A patch touching the image's edges and one inside it.
        for patch in [Roi::new(0, 3, 200, 150).unwrap(), Roi::new(101, 57, 530, 401).unwrap()] {
            let theirs = chess_response_u8_patch(image.as_raw(), w, h, &params, patch);
            let ours = chess_response(&image, patch, &params);
            assert_eq!((ours.width(), ours.height()), (theirs.width(), theirs.height()));
            assert_eq!(ours.data(), theirs.data(), "{patch:?}");
        }
    }

    #[test]
    fn an_image_smaller_than_the_ring_has_no_corners() {
        for (w, h) in [(0, 0), (4, 30), (30, 9), (11, 11)] {
            assert!(chess_corners(&GrayImage::new(w, h), None).is_empty());
        }
    }
}
