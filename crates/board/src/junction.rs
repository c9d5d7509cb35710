//! Checkerboard corners fitted as X-junctions, the last refinement stage.
//!
//! Around an inner corner the image is two straight edges crossing (a
//! homography keeps lines straight, and over a few pixels lens distortion
//! bends them by far less than a pixel), dark and light squares in opposite
//! quadrants. The model of a pixel at signed distances d1, d2 from the two
//! edges is `mean + contrast * E(d1) * E(d2)`, where `E` is a smooth step
//! of width `s` averaged over the pixel's width across the edge (the pixel
//! integrates light over its area; without that, a sharp edge that runs
//! along the pixel grid puts all its pixels at one phase, and the edge's
//! position trades against its width). Seven parameters (corner, the two
//! edges' angles, mean, contrast, ln s) are fitted by Levenberg-Marquardt
//! to the pixels of a disc around the gradient refinement's corner, the
//! edges started along the board's grid lines through the corner.
//!
//! Why: the gradient refinement (OpenCV's cornerSubPix) solves for the
//! point every gradient in its window points away from; where the edges are
//! sharp and cross at a skew its answer moves with the sampling. Measured
//! on 24 simulated half-scale sessions of 8 poses (`session_floor`
//! example, corner error against the simulator's truth): 0.042-0.059 px
//! RMS before, 0.011-0.017 px with this fit, and the depth error over the
//! working volume of the camera and laser they calibrate, 1.0-1.8 mm in 5
//! of the 24 before, is 0.86 mm at worst; on OpenCV's 13 right-camera
//! photographs the calibration's RMS falls from 0.194 px to 0.158 px. It
//! costs about 2 ms per 640 x 480 board of 54 corners on 2 cores, which
//! would double the detector's time (and put it behind OpenCV's
//! `findChessboardCorners` + `cornerSubPix`); so the detector
//! ([`crate::detect_board`]) stops at the gradient refinement and
//! calibration takes [`crate::detect_board_precise`].
//!
//! The step is the algebraic sigmoid x / sqrt(1 + x^2), whose integral
//! over the pixel is a difference of two square roots: a logistic step
//! (tanh, its integral ln cosh) gave the same corners at twice the cost.

use image::GrayImage;
use nalgebra::{Point2, SMatrix, SVector};
use rayon::prelude::*;

use alacs_model::BoardSpec;

use crate::BoardCorners;

/// Disc radius of the fit per square side in the image. Measured on
/// simulated half-scale sessions (seeds 100-105, mean corner error RMS
/// against the truth) and OpenCV's photographs (calibration RMS) with the
/// logistic step and no cap: 0.2, 0.3, 0.4 gave 0.0171, 0.0133, 0.0114 px
/// and 0.160, 0.157, 0.156 px; with this step, 0.25 (at most 8 px) 0.0158
/// and 0.160, 0.3 (at most 10 px) 0.0140 and 0.158. The disc must stay
/// inside the four squares (at 0.5 it meets the next edges), and the cost
/// grows with its area.
pub const JUNCTION_RADIUS_PER_CELL: f64 = 0.3;

/// Largest disc radius (px): the fit's cost grows with the disc's area
/// (at 10 px, about 2 ms for a 640 x 480 board of 54 corners on 2 cores).
pub const MAX_JUNCTION_RADIUS_PX: f64 = 10.0;

/// Smallest disc radius (px) worth fitting seven parameters in.
pub const MIN_JUNCTION_RADIUS_PX: f64 = 3.0;

/// A fit that moves the corner further than this from the gradient
/// refinement's (px) is not trusted; the gradient's corner stays.
const MAX_MOVE_PX: f64 = 1.0;

/// The fit has converged when the corner moves less than this (px).
const TOLERANCE_PX: f64 = 1e-3;

/// Parameters: the corner's offset from the start (x, y), the two edges'
/// angles, mean, contrast, ln of the edge width.
type Params = SVector<f64, 7>;

/// The fit's disc radius for squares of `cell_px` in the image.
fn junction_radius_px(cell_px: f64) -> f64 {
    (JUNCTION_RADIUS_PER_CELL * cell_px).min(MAX_JUNCTION_RADIUS_PX)
}

/// A straight edge at signed distance `d` (px) from a pixel's centre, seen
/// by the pixel: a smooth step of width `s` (the algebraic sigmoid
/// x / sqrt(1 + x^2) of x = d / s) averaged over a pixel's width along the
/// edge's normal, from -1 to 1. Returns the value, its derivative by `d`
/// and by ln `s`.
fn edge(d: f64, s: f64) -> (f64, f64, f64) {
    let s_sq = s * s;
    let (a, b) = (d + 0.5, d - 0.5);
    let (ra, rb) = ((s_sq + a * a).sqrt(), (s_sq + b * b).sqrt());
    let (ia, ib) = (1.0 / ra, 1.0 / rb);
    (ra - rb, a * ia - b * ib, s_sq * (ia - ib))
}

/// The squared residual of the model at `p` over `pixels` ((du, dv) from
/// the start, intensity), and the normal equations J^T J, J^T r.
fn normal_equations(p: &Params, pixels: &[(f64, f64, f64)]) -> (f64, SMatrix<f64, 7, 7>, Params) {
    let s = p[6].exp();
    let (s1, c1) = p[2].sin_cos();
    let (s2, c2) = p[3].sin_cos();
    let (m, c) = (p[4], p[5]);
    let mut jtj = SMatrix::<f64, 7, 7>::zeros();
    let mut jtr = Params::zeros();
    let mut cost = 0.0;
    for &(du, dv, intensity) in pixels {
        let (dx, dy) = (du - p[0], dv - p[1]);
        let d1 = -s1 * dx + c1 * dy;
        let d2 = -s2 * dx + c2 * dy;
        let (t1, g1, h1) = edge(d1, s);
        let (t2, g2, h2) = edge(d2, s);
        let r = intensity - (m + c * t1 * t2);
        let (df_dd1, df_dd2) = (c * g1 * t2, c * t1 * g2);
        let g = Params::from([
            df_dd1 * s1 + df_dd2 * s2,
            -df_dd1 * c1 - df_dd2 * c2,
            df_dd1 * (-c1 * dx - s1 * dy),
            df_dd2 * (-c2 * dx - s2 * dy),
            1.0,
            t1 * t2,
            c * (h1 * t2 + t1 * h2),
        ]);
        cost += r * r;
        jtj.syger(1.0, &g, &g, 1.0);
        jtr.axpy(r, &g, 1.0);
    }
    (cost, jtj, jtr)
}

/// Fits one corner from `start` with its edges along `dir1` and `dir2`
/// (rad) in a disc of `radius` px. `None` if the disc leaves the image, the
/// fit does not converge, or it moves more than [`MAX_MOVE_PX`].
fn fit(
    gray: &GrayImage,
    start: Point2<f64>,
    dir1: f64,
    dir2: f64,
    radius: f64,
) -> Option<Point2<f64>> {
    let (width, height) = (i64::from(gray.width()), i64::from(gray.height()));
    let r = radius.ceil() as i64;
    let (cu, cv) = (start.x.round() as i64, start.y.round() as i64);
    if cu - r < 0 || cv - r < 0 || cu + r >= width || cv + r >= height {
        return None;
    }
    let mut pixels = Vec::with_capacity(((2 * r + 1) * (2 * r + 1)) as usize);
    for v in cv - r..=cv + r {
        for u in cu - r..=cu + r {
            let (du, dv) = (u as f64 - start.x, v as f64 - start.y);
            if du * du + dv * dv <= radius * radius {
                pixels.push((du, dv, f64::from(gray.get_pixel(u as u32, v as u32)[0])));
            }
        }
    }
    // Mean and contrast by linear least squares at the start, edges 0.3 px
    // wide.
    let mut p = Params::from([0.0, 0.0, dir1, dir2, 0.0, 0.0, 0.3f64.ln()]);
    let (mut sx, mut sxx, mut sy, mut sxy) = (0.0, 0.0, 0.0, 0.0);
    let n = pixels.len() as f64;
    let (s1, c1) = dir1.sin_cos();
    let (s2, c2) = dir2.sin_cos();
    let s = p[6].exp();
    for &(du, dv, i) in &pixels {
        let t = edge(-s1 * du + c1 * dv, s).0 * edge(-s2 * du + c2 * dv, s).0;
        sx += t;
        sxx += t * t;
        sy += i;
        sxy += t * i;
    }
    let det = n * sxx - sx * sx;
    if det.abs() < 1e-9 {
        return None;
    }
    p[5] = (n * sxy - sx * sy) / det;
    p[4] = (sy - p[5] * sx) / n;
    let (mut cost, mut jtj, mut jtr) = normal_equations(&p, &pixels);
    let mut lambda = 1e-3;
    let mut converged = false;
    'outer: for _ in 0..30 {
        for _ in 0..8 {
            let mut a = jtj;
            for k in 0..7 {
                a[(k, k)] = a[(k, k)] * (1.0 + lambda) + 1e-12;
            }
            let step = a.lu().solve(&jtr)?;
            let next = p + step;
            let (next_cost, next_jtj, next_jtr) = normal_equations(&next, &pixels);
            if next_cost < cost {
                (p, cost, jtj, jtr) = (next, next_cost, next_jtj, next_jtr);
                lambda = (lambda / 10.0).max(1e-9);
                if step[0].hypot(step[1]) < TOLERANCE_PX {
                    converged = true;
                    break 'outer;
                }
                continue 'outer;
            }
            lambda *= 10.0;
        }
        // No step lowers the cost: a minimum.
        converged = true;
        break;
    }
    let q = Point2::new(start.x + p[0], start.y + p[1]);
    (converged && p[0].hypot(p[1]) <= MAX_MOVE_PX && q.x.is_finite() && q.y.is_finite())
        .then_some(q)
}

/// Fits every corner of a board found in `gray` ([`crate::detect_board`])
/// as an X-junction, in a disc of [`JUNCTION_RADIUS_PER_CELL`] of a square
/// (at most [`MAX_JUNCTION_RADIUS_PX`]; on a ChArUco board no larger than
/// the disc without marker pixels). A corner whose fit fails keeps its
/// position; a disc under [`MIN_JUNCTION_RADIUS_PX`] fits nothing.
pub fn fit_board_junctions(gray: &GrayImage, board: &BoardSpec, corners: &mut BoardCorners) {
    let cell_px = corners.cell_size_px().unwrap_or(0.0);
    let mut radius_px = junction_radius_px(cell_px);
    if let Some(markers) = &board.markers {
        radius_px = radius_px.min(crate::charuco::marker_free_radius_px(board, markers, cell_px));
    }
    if radius_px >= MIN_JUNCTION_RADIUS_PX {
        fit_junctions(gray, corners, radius_px);
    }
}

/// Fits every corner of `corners` as an X-junction in a disc of
/// `radius_px`, its edges started along the grid's lines to its neighbours
/// (a corner without a neighbour along a grid axis keeps its position, as
/// does one whose fit fails or moves more than [`MAX_MOVE_PX`]).
fn fit_junctions(gray: &GrayImage, corners: &mut BoardCorners, radius_px: f64) {
    let (cols, rows) = (corners.cols, corners.rows);
    let original = corners.corners_px.clone();
    let at = |c: i64, r: i64| -> Option<Point2<f64>> {
        if c < 0 || r < 0 || c >= cols as i64 || r >= rows as i64 {
            return None;
        }
        original.get(r as usize * cols + c as usize).copied().flatten()
    };
    let direction = |c: i64, r: i64, dc: i64, dr: i64| -> Option<f64> {
        let q = at(c, r)?;
        let d = match (at(c + dc, r + dr), at(c - dc, r - dr)) {
            (Some(a), Some(b)) => a - b,
            (Some(a), None) => a - q,
            (None, Some(b)) => q - b,
            (None, None) => return None,
        };
        Some(d.y.atan2(d.x))
    };
    corners.corners_px.par_iter_mut().enumerate().for_each(|(index, corner)| {
        let Some(start) = *corner else { return };
        let (c, r) = ((index % cols) as i64, (index / cols) as i64);
        if let (Some(a), Some(b)) = (direction(c, r, 1, 0), direction(c, r, 0, 1))
            && let Some(q) = fit(gray, start, a, b, radius_px)
        {
            *corner = Some(q);
        }
    });
}
