//! Checkerboard inner corners with sub-pixel positions, labelled in OpenCV's
//! order.
//!
//! Corner finding and grid labelling are the `calib-targets` crate's ChESS
//! detector (its three-configuration sweep); this module fits its labelled
//! grid to the board of session.yaml:
//! - the grid must span exactly `cols x rows` corners (or `rows x cols` for a
//!   board turned by 90 deg); a stray corner outside that window is dropped,
//!   and a few corners missing inside it (a bright laser line over a corner)
//!   are allowed, since the window still fixes every label;
//! - labels follow FORMATS.md's board frame: row-major, x along a row, y down
//!   a column, z into the board, i.e. seen from the camera the x axis turns
//!   clockwise onto the y axis. Of the two labellings that satisfy this (a
//!   board and the board turned by 180 deg look alike; four for a square
//!   grid), the one whose first corner lies nearest the image's top-left
//!   corner is chosen, as OpenCV usually does.
//!
//! The detector's corners are then refined with the image gradients (see
//! [`refine_corners`]) in a window of a quarter square: on OpenCV's
//! photographs this lowers the calibration RMS from 0.215 px to 0.191 px
//! (0.194 px when measured again on 2026-12-03),
//! on simulated 5 MP sessions from 0.22 px to 0.034 px. For calibration,
//! each corner is then fitted as an X-junction ([`crate::fit_board_junctions`]).
//!
//! Colour images are searched on their green channel: a red laser line
//! barely shows there, so it cannot break the corner pattern.

use alacs_model::BoardSpec;
use calib_targets::ChessCorner;
use calib_targets::chessboard::{self, ChessboardParams};
use chess_corners::Roi;
use image::{DynamicImage, GrayImage};
use nalgebra::{Point2, Vector2};
use rayon::prelude::*;

use crate::chess::chess_corners;
use crate::{Error, Result};

/// Largest fraction of a board's corners that may be missing inside the
/// detected window; beyond it the view is refused.
pub const MAX_MISSING_FRACTION: f64 = 0.1;

/// Half window of the corner refinement per square side in the image. A
/// quarter square: on OpenCV's photographs (squares of 25-45 px) 0.15,
/// 0.2, 0.25, 0.3 and 0.35 gave a calibration RMS of 0.219, 0.199, 0.191,
/// 0.236 and 0.357 px; on a simulated 5 MP session 0.043, 0.037, 0.034,
/// 0.034, 0.034 px (the window capped at 15 px from 0.3 on).
pub(crate) const REFINE_WINDOW_PER_CELL: f64 = 0.25;

/// Largest half window of the corner refinement (px).
pub(crate) const MAX_REFINE_HALF_WINDOW_PX: f64 = 15.0;

/// A board found in an image: every inner corner in OpenCV's order.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardCorners {
    /// Inner corners per row.
    pub cols: usize,
    /// Inner corners per column.
    pub rows: usize,
    /// Corner `row * cols + col` in pixels, `None` where the detector missed it.
    pub corners_px: Vec<Option<Point2<f64>>>,
}

impl BoardCorners {
    /// The found corners with their OpenCV indices.
    pub fn found(&self) -> impl Iterator<Item = (usize, Point2<f64>)> + '_ {
        self.corners_px.iter().enumerate().filter_map(|(i, c)| c.map(|c| (i, c)))
    }

    /// Number of corners found.
    pub fn found_count(&self) -> usize {
        self.corners_px.iter().filter(|c| c.is_some()).count()
    }

    /// The board's smallest square side in the image (px): the shorter of
    /// the mean steps between neighbouring corners along a row and a column.
    pub fn cell_size_px(&self) -> Option<f64> {
        let (step_x, step_y) = board_steps(&self.corners_px, self.cols, self.rows)?;
        Some(step_x.norm().min(step_y.norm()))
    }

    /// The outline of the corner grid in the image (the four outer corners,
    /// extrapolated where one is missing), in order around the board.
    pub fn outline_px(&self) -> Option<[Point2<f64>; 4]> {
        let (c, r) = (self.cols - 1, self.rows - 1);
        let at = |col: usize, row: usize| self.corners_px[row * self.cols + col];
        Some([at(0, 0)?, at(c, 0)?, at(c, r)?, at(0, r)?])
    }
}

/// The image a board is searched in: the green channel of a colour image
/// (the red laser hardly shows in it), the luminance of a grey one.
pub fn board_gray(image: &DynamicImage) -> GrayImage {
    if !image.color().has_color() {
        return image.to_luma8();
    }
    let rgb = image.to_rgb8();
    GrayImage::from_fn(rgb.width(), rgb.height(), |u, v| image::Luma([rgb.get_pixel(u, v)[1]]))
}

/// Finds the `board.cols x board.rows` inner corners in a grey image.
pub fn detect_checkerboard(gray: &GrayImage, board: &BoardSpec) -> Result<BoardCorners> {
    // The corner grid is searched at half resolution first (the ChESS
    // response, which dominates the cost, over a quarter of the pixels),
    // positions mapped back and refined at full resolution below; there,
    // first only over the region that holds contrast (see
    // [`textured_region`]: a board fills 10-50 % of a calibration view),
    // then over the whole half image. A search is kept only if it labels
    // every corner; else (squares under ~10 px there, a blurred corner) the
    // next runs, the full image last, and the best labelling is kept. (A
    // quarter-resolution level was tried: the grid's assembly, not the
    // response, dominates there, and no faster.)
    let half = half_size(gray);
    let mut searches: Vec<(f64, &GrayImage, Option<Roi>)> = vec![(1.0, gray, None)];
    if half.width().min(half.height()) >= MIN_SEARCH_SIDE_PX {
        searches.push((2.0, &half, None));
        if let Some(region) = textured_region(&half) {
            searches.push((2.0, &half, Some(region)));
        }
    }
    let mut best: Option<(BoardCorners, Refined)> = None;
    let mut full_error = None;
    for &(scale, level, region) in searches.iter().rev() {
        match labelled_grid(level, region, scale, board, gray) {
            Ok(search) => {
                if keep_more(&mut best, search, |(corners, _)| corners) == board.corner_count() {
                    break;
                }
            }
            // The full-resolution search's reason is the one reported.
            Err(e) if scale == 1.0 => full_error = Some(e),
            Err(_) => {}
        }
    }
    let (mut corners, refined) =
        best.ok_or_else(|| full_error.unwrap_or_else(|| no_checkerboard(board, "no corner grid")))?;
    let half_window = refine_half_window(corners.cell_size_px().unwrap_or(0.0));
    refined.apply(gray, &mut corners, half_window);
    Ok(corners)
}

/// The half window of the corner refinement for squares of `cell_px` in the
/// image (px): [`REFINE_WINDOW_PER_CELL`] of a square, 2 to
/// [`MAX_REFINE_HALF_WINDOW_PX`].
fn refine_half_window(cell_px: f64) -> u32 {
    (REFINE_WINDOW_PER_CELL * cell_px).round().clamp(2.0, MAX_REFINE_HALF_WINDOW_PX) as u32
}

/// Rows of the half image one parallel task sums at least.
const ROWS_PER_TASK: usize = 64;

/// Corners one parallel task refines at least.
const CORNERS_PER_TASK: usize = 16;

/// A coarse search level's shorter side is at least this (px).
const MIN_SEARCH_SIDE_PX: u32 = 120;

/// The image at half size, each pixel the mean of a 2 x 2 block (its centre
/// at (2 u + 0.5, 2 v + 0.5) of the original).
fn half_size(gray: &GrayImage) -> GrayImage {
    let (width, height) = (gray.width() as usize / 2, gray.height() as usize / 2);
    let row = gray.width() as usize;
    let pixels = gray.as_raw();
    let mut half = vec![0_u8; width * height];
    if width == 0 {
        return GrayImage::default();
    }
    // Rows in parallel, each in two loops the compiler vectorises: the two
    // source rows' sums, then the sums of neighbouring columns.
    half.par_chunks_mut(width).with_min_len(ROWS_PER_TASK).enumerate().for_each_init(
        Vec::new,
        |sums, (v, out)| {
            let (top, bottom) =
                (&pixels[2 * v * row..][..2 * width], &pixels[(2 * v + 1) * row..][..2 * width]);
            sums.clear();
            sums.extend(top.iter().zip(bottom).map(|(&t, &b)| u16::from(t) + u16::from(b)));
            for (out, pair) in out.iter_mut().zip(sums.chunks_exact(2)) {
                *out = ((pair[0] + pair[1] + 2) / 4) as u8;
            }
        },
    );
    GrayImage::from_raw(width as u32, height as u32, half).unwrap_or_default()
}

/// The board's corners from calib-targets' corner grids of `level`, an
/// image `1 / scale` of `gray`'s size (positions in `gray`'s pixels), and
/// the ChESS corners refined at full resolution ([`Refined`]): the ChESS
/// corners once (in `region` of `level` only, if given), then the grid of
/// each of calib-targets' three chessboard settings (canonical, tighter,
/// looser) until one labels every corner, else the labelling with the most.
///
/// calib-targets assembles the grid on one thread; the refinement needs no
/// labels, only a window, which the corners' spacing gives before the grid
/// does, so it runs meanwhile on the other threads.
fn labelled_grid(
    level: &GrayImage,
    region: Option<Roi>,
    scale: f64,
    board: &BoardSpec,
    gray: &GrayImage,
) -> Result<(BoardCorners, Refined)> {
    let corners = chess_corners(level, region);
    let starts: Vec<Point2<f64>> =
        corners.iter().map(|c| level_to_image((c.position.x, c.position.y), scale)).collect();
    let half_window = refine_half_window(median_nearest_neighbour_px(&starts));
    let (labelled, refined) = rayon::join(
        || grid_labelling(&corners, scale, board, gray),
        || Refined::new(gray, starts, half_window),
    );
    Ok((labelled?, refined))
}

/// The labelling of `corners` (ChESS corners of a level `1 / scale` of
/// `gray`'s size) with the most corners of calib-targets' three settings
/// (see [`labelled_grid`]).
fn grid_labelling(
    corners: &[ChessCorner],
    scale: f64,
    board: &BoardSpec,
    gray: &GrayImage,
) -> Result<BoardCorners> {
    let mut best: Option<BoardCorners> = None;
    let mut last_error = no_checkerboard(board, "no corner grid");
    for params in ChessboardParams::sweep_default() {
        let Some(detection) =
            chessboard::ChessboardDetector::new(params).ok().and_then(|d| d.detect(corners))
        else {
            continue;
        };
        let grid: Vec<((i64, i64), Point2<f64>)> = detection
            .corners
            .iter()
            .map(|c| {
                (
                    (i64::from(c.grid.u), i64::from(c.grid.v)),
                    level_to_image((c.position.x, c.position.y), scale),
                )
            })
            .filter(|(_, p)| p.x.is_finite() && p.y.is_finite())
            .collect();
        match label_grid(&grid, board, gray.width(), gray.height()) {
            Ok(corners) => {
                if keep_more(&mut best, corners, |c| c) == board.corner_count() {
                    break;
                }
            }
            Err(e) => last_error = e,
        }
    }
    best.ok_or(last_error)
}

/// The median distance from a point to its nearest neighbour (0 for fewer
/// than two points): the side of a board's squares, from its corners alone.
fn median_nearest_neighbour_px(points: &[Point2<f64>]) -> f64 {
    let mut by_x: Vec<Point2<f64>> = points.to_vec();
    by_x.sort_by(|a, b| a.x.total_cmp(&b.x));
    let mut nearest: Vec<f64> = (0..by_x.len())
        .map(|i| {
            let p = by_x[i];
            let mut best_sq = f64::INFINITY;
            // Outwards in x from the point, each way until x alone is farther.
            let mut look = |q: &Point2<f64>| {
                let far = (q.x - p.x).powi(2) >= best_sq;
                if !far {
                    best_sq = best_sq.min((q - p).norm_squared());
                }
                !far
            };
            for q in &by_x[i + 1..] {
                if !look(q) {
                    break;
                }
            }
            for q in by_x[..i].iter().rev() {
                if !look(q) {
                    break;
                }
            }
            best_sq.sqrt()
        })
        .filter(|d| d.is_finite())
        .collect();
    nearest.sort_by(f64::total_cmp);
    nearest.get(nearest.len() / 2).copied().unwrap_or(0.0)
}

/// ChESS corners refined at full resolution with one window before they
/// were labelled, by where they started.
struct Refined {
    half_window_px: u32,
    /// (start's bits, refined position), sorted by the start's bits.
    by_start: Vec<((u64, u64), Point2<f64>)>,
}

impl Refined {
    fn new(gray: &GrayImage, starts: Vec<Point2<f64>>, half_window_px: u32) -> Self {
        let refiner = SubPixel::new(gray, half_window_px, f64::INFINITY);
        let mut by_start: Vec<((u64, u64), Point2<f64>)> = starts
            .into_par_iter()
            .with_min_len(CORNERS_PER_TASK)
            .map(|p| (bits(p), refiner.refine(p)))
            .collect();
        by_start.sort_by_key(|(key, _)| *key);
        Self { half_window_px, by_start }
    }

    /// Refines `corners` as [`refine_corners`] does: with the positions
    /// refined ahead where they were refined with the same window (every
    /// corner of a board's own labelling, unless the squares' spacing
    /// before the labelling rounded to another window), else afresh.
    fn apply(&self, gray: &GrayImage, corners: &mut BoardCorners, half_window_px: u32) {
        if half_window_px != self.half_window_px {
            refine_corners(gray, corners, half_window_px);
            return;
        }
        let mut refiner = None;
        for corner in corners.corners_px.iter_mut().flatten() {
            *corner = match self.by_start.binary_search_by_key(&bits(*corner), |(key, _)| *key) {
                Ok(i) => self.by_start[i].1,
                Err(_) => refiner
                    .get_or_insert_with(|| SubPixel::new(gray, half_window_px, f64::INFINITY))
                    .refine(*corner),
            };
        }
    }
}

/// A position's bits, to find it again exactly.
fn bits(p: Point2<f64>) -> (u64, u64) {
    (p.x.to_bits(), p.y.to_bits())
}

/// Side of the tiles of [`textured_region`] (px of the searched level).
const REGION_TILE_PX: usize = 8;

/// A tile holds a board's contrast when its grey levels span at least this
/// fraction of the most contrasted tile's span ...
const REGION_CONTRAST_FRACTION: f64 = 0.25;

/// ... and at least this (DN).
const REGION_MIN_CONTRAST_DN: u8 = 16;

/// Tiles added around the contrasted ones: a corner's ChESS ring (5 px)
/// and its refinement stay inside.
const REGION_MARGIN_TILES: usize = 1;

/// Where a board can be in `level`: the bounding box of the 8 x 8 px tiles
/// whose grey levels span at least a quarter of the largest span of any
/// tile (and 16 DN), grown by a tile. Each square edge and corner of a
/// board is such a tile. `None` where that is (nearly) the whole image, or
/// nothing: then the whole image is searched. Only a first try: a board
/// the region cuts is searched again in the whole image.
fn textured_region(level: &GrayImage) -> Option<Roi> {
    let (width, height) = (level.width() as usize, level.height() as usize);
    let (tiles_x, tiles_y) = (width / REGION_TILE_PX, height / REGION_TILE_PX);
    if tiles_x == 0 || tiles_y == 0 {
        return None;
    }
    let pixels = level.as_raw();
    // Each band of tile rows: the column-wise minimum and maximum over its
    // rows (whole-row vector loops), then each tile's span.
    let mut spans = vec![0_u8; tiles_x * tiles_y];
    let (mut low, mut high) = (vec![0_u8; width], vec![0_u8; width]);
    for (ty, band) in pixels.chunks_exact(REGION_TILE_PX * width).take(tiles_y).enumerate() {
        low.fill(u8::MAX);
        high.fill(0);
        for row in band.chunks_exact(width) {
            for ((low, high), &p) in low.iter_mut().zip(high.iter_mut()).zip(row) {
                *low = (*low).min(p);
                *high = (*high).max(p);
            }
        }
        let tiles = low.chunks_exact(REGION_TILE_PX).zip(high.chunks_exact(REGION_TILE_PX));
        for (span, (low, high)) in spans[ty * tiles_x..(ty + 1) * tiles_x].iter_mut().zip(tiles) {
            let (low, high) =
                (low.iter().fold(u8::MAX, |m, &p| m.min(p)), high.iter().fold(0, |m, &p| m.max(p)));
            *span = high - low;
        }
    }
    let largest = spans.iter().copied().max().unwrap_or(0);
    let threshold =
        ((REGION_CONTRAST_FRACTION * f64::from(largest)).ceil() as u8).max(REGION_MIN_CONTRAST_DN);
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (i, _) in spans.iter().enumerate().filter(|&(_, &span)| span >= threshold) {
        let (tx, ty) = (i % tiles_x, i / tiles_x);
        (x0, y0, x1, y1) = (x0.min(tx), y0.min(ty), x1.max(tx + 1), y1.max(ty + 1));
    }
    if x0 >= x1 {
        return None;
    }
    let grow = |from: usize, to: usize, tiles: usize, side: usize| {
        let from = from.saturating_sub(REGION_MARGIN_TILES) * REGION_TILE_PX;
        // A last tile row or column grown to the image's edge.
        let to = if to + REGION_MARGIN_TILES >= tiles {
            side
        } else {
            (to + REGION_MARGIN_TILES) * REGION_TILE_PX
        };
        (from, to)
    };
    let ((x0, x1), (y0, y1)) = (grow(x0, x1, tiles_x, width), grow(y0, y1, tiles_y, height));
    // Not worth a second search where the region is most of the image.
    if ((x1 - x0) * (y1 - y0)) as f64 > REGION_WHOLE_FRACTION * (width * height) as f64 {
        return None;
    }
    Roi::new(x0, y0, x1, y1)
}

/// A region covering more than this fraction of the image is searched as
/// the whole image.
const REGION_WHOLE_FRACTION: f64 = 0.7;

/// A position found in an image rescaled from the original, in the
/// original's pixels; `scale` is original pixels per rescaled pixel (2 for
/// a half-size image, 0.5 for a double-size one). Pixel centres:
/// u = scale u' + (scale - 1) / 2.
pub(crate) fn level_to_image((u, v): (f32, f32), scale: f64) -> Point2<f64> {
    let shift = (scale - 1.0) / 2.0;
    Point2::new(scale * f64::from(u) + shift, scale * f64::from(v) + shift)
}

/// Keeps in `best` whichever of it and `candidate` labels more corners (the
/// earlier one on a tie; `corners` gives a candidate's labelling); returns
/// how many `best` now labels.
pub(crate) fn keep_more<T>(
    best: &mut Option<T>,
    candidate: T,
    corners: impl Fn(&T) -> &BoardCorners,
) -> usize {
    let found = |t: &T| corners(t).found_count();
    if best.as_ref().is_none_or(|b| found(b) < found(&candidate)) {
        *best = Some(candidate);
    }
    best.as_ref().map_or(0, found)
}

/// No checkerboard of `board`'s size found, for `reason`.
fn no_checkerboard(board: &BoardSpec, reason: impl Into<String>) -> Error {
    Error::NoBoard {
        kind: "checkerboard",
        cols: board.cols,
        rows: board.rows,
        reason: reason.into(),
    }
}

/// Fits a labelled corner grid (grid coordinates, pixel) to the board:
/// chooses the window and the labelling (see the module docs).
fn label_grid(
    grid: &[((i64, i64), Point2<f64>)],
    board: &BoardSpec,
    width: u32,
    height: u32,
) -> Result<BoardCorners> {
    let refused = |reason: String| no_checkerboard(board, reason);
    let (cols, rows) = (board.cols as i64, board.rows as i64);
    let needed = board.corner_count();
    let allowed_missing = (needed as f64 * MAX_MISSING_FRACTION).floor() as usize;
    let (min_i, max_i) = min_max(grid.iter().map(|g| g.0.0));
    let (min_j, max_j) = min_max(grid.iter().map(|g| g.0.1));
    if grid.len() + allowed_missing < needed {
        // A whole grid one corner short each way: the board was given by
        // its squares, not its inner corners.
        let (span_i, span_j) = (max_i.saturating_sub(min_i) + 1, max_j.saturating_sub(min_j) + 1);
        let whole = !grid.is_empty() && grid.len() as i64 == span_i.saturating_mul(span_j);
        let one_short = |a: i64, b: i64| a == cols - 1 && b == rows - 1;
        if whole && (one_short(span_i, span_j) || one_short(span_j, span_i)) {
            return Err(Error::GivenBySquares {
                cols: board.cols,
                rows: board.rows,
                found: grid.len(),
            });
        }
        return Err(refused(format!("only {} of {} corners found", grid.len(), needed)));
    }
    // Candidate windows (origin, width along i, height along j) of the board's size.
    let mut best: Option<(usize, i64, i64, i64, i64)> = None;
    let mut tie = false;
    for (w, h) in [(cols, rows), (rows, cols)] {
        if cols == rows && w != cols {
            continue;
        }
        for i0 in min_i..=(max_i - w + 1).max(min_i) {
            for j0 in min_j..=(max_j - h + 1).max(min_j) {
                let inside = grid
                    .iter()
                    .filter(|((i, j), _)| (i0..i0 + w).contains(i) && (j0..j0 + h).contains(j))
                    .count();
                match best {
                    Some((n, ..)) if n > inside => {}
                    Some((n, ..)) if n == inside => tie = true,
                    _ => {
                        best = Some((inside, i0, j0, w, h));
                        tie = false;
                    }
                }
            }
        }
    }
    let Some((inside, i0, j0, w, h)) = best else {
        return Err(refused("no corners".into()));
    };
    if inside + allowed_missing < needed {
        return Err(refused(format!(
            "the largest {}-corner window of the detected {} x {} grid holds only {inside} corners",
            needed,
            max_i - min_i + 1,
            max_j - min_j + 1
        )));
    }
    if tie {
        return Err(refused(format!(
            "the detected {} x {} grid fits the board in more than one place",
            max_i - min_i + 1,
            max_j - min_j + 1
        )));
    }
    // Corners of the window by window coordinates (a, b), a along i, b along j.
    let mut window = vec![None; needed];
    for ((i, j), p) in grid {
        let (a, b) = (i - i0, j - j0);
        if (0..w).contains(&a) && (0..h).contains(&b) {
            window[(b * w + a) as usize] = Some(*p);
        }
    }
    // A labelling maps (col, row) to window coordinates (a, b): rows and
    // columns swapped or not, then either axis reversed or not.
    let labellings = (0..8u8).map(|bits| (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0));
    let labellings: Vec<(bool, bool, bool)> = labellings
        .filter(|&(swap, _, _)| if swap { (w, h) == (rows, cols) } else { (w, h) == (cols, rows) })
        .collect();
    let corner = |&(swap, flip_a, flip_b): &(bool, bool, bool), c: i64, r: i64| {
        let (a, b) = if swap { (r, c) } else { (c, r) };
        let a = if flip_a { w - 1 - a } else { a };
        let b = if flip_b { h - 1 - b } else { b };
        window[(b * w + a) as usize]
    };
    let mut chosen: Option<(f64, Vec<Option<Point2<f64>>>)> = None;
    for label in &labellings {
        let corners: Vec<Option<Point2<f64>>> = (0..rows)
            .flat_map(|r| (0..cols).map(move |c| (c, r)))
            .map(|(c, r)| corner(label, c, r))
            .collect();
        let Some((step_x, step_y)) = board_steps(&corners, board.cols, board.rows) else {
            continue;
        };
        // Seen from the camera (image u right, v down), x turns clockwise onto y.
        if step_x.perp(&step_y) <= 0.0 {
            continue;
        }
        let origin = first_corner_estimate(&corners, board.cols, step_x, step_y);
        let distance = origin.coords.norm();
        if chosen.as_ref().is_none_or(|(d, _)| distance < *d) {
            chosen = Some((distance, corners));
        }
    }
    let (_, corners_px) =
        chosen.ok_or_else(|| refused("the corner grid is degenerate (no board axes)".into()))?;
    if let Some((i, p)) = corners_px.iter().enumerate().find_map(|(i, p)| {
        p.filter(|p| {
            p.x < -0.5 || p.y < -0.5 || p.x > width as f64 - 0.5 || p.y > height as f64 - 0.5
        })
        .map(|p| (i, p))
    }) {
        return Err(refused(format!(
            "corner {i} at ({:.1}, {:.1}) lies outside the image",
            p.x, p.y
        )));
    }
    Ok(BoardCorners { cols: cols as usize, rows: rows as usize, corners_px })
}

/// Mean image step from one corner to the next along the board's x axis
/// (along a row) and y axis (down a column).
fn board_steps(
    corners: &[Option<Point2<f64>>],
    cols: usize,
    rows: usize,
) -> Option<(Vector2<f64>, Vector2<f64>)> {
    let (mut step_x, mut n_x) = (Vector2::zeros(), 0.0);
    let (mut step_y, mut n_y) = (Vector2::zeros(), 0.0);
    for r in 0..rows {
        for c in 0..cols {
            let Some(p) = corners[r * cols + c] else { continue };
            if let Some(q) =
                corners.get(r * cols + c + 1).copied().flatten().filter(|_| c + 1 < cols)
            {
                step_x += q - p;
                n_x += 1.0;
            }
            if let Some(q) = corners.get((r + 1) * cols + c).copied().flatten() {
                step_y += q - p;
                n_y += 1.0;
            }
        }
    }
    (n_x > 0.0 && n_y > 0.0).then(|| (step_x / n_x, step_y / n_y))
}

/// Where the first corner lies, from every found corner and the mean steps
/// (so it is known even when the detector missed that corner).
fn first_corner_estimate(
    corners: &[Option<Point2<f64>>],
    cols: usize,
    step_x: Vector2<f64>,
    step_y: Vector2<f64>,
) -> Point2<f64> {
    let (mut sum, mut n) = (Vector2::zeros(), 0.0_f64);
    for (i, p) in corners.iter().enumerate() {
        if let Some(p) = p {
            let (c, r) = ((i % cols) as f64, (i / cols) as f64);
            sum += p.coords - step_x * c - step_y * r;
            n += 1.0;
        }
    }
    Point2::from(sum / n.max(1.0))
}

fn min_max(values: impl Iterator<Item = i64>) -> (i64, i64) {
    values.fold((i64::MAX, i64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// Refines corners to where the image gradients around each are orthogonal
/// to the line towards it (the saddle of the checker pattern): minimizes
/// sum_p (g_p . (q - p))^2 over a Gaussian-weighted window, as OpenCV's
/// `cornerSubPix` does, iterating until the corner moves less than 0.001 px.
/// A corner whose refinement wanders off by more than a window is kept where
/// it was. ([`crate::fit_board_junctions`] goes further, for calibration.)
pub fn refine_corners(gray: &GrayImage, corners: &mut BoardCorners, half_window_px: u32) {
    refine_corners_within(gray, corners, half_window_px, f64::INFINITY);
}

/// [`refine_corners`] using only the window's pixels within `max_radius_px`
/// of the corner (a ChArUco board's markers must stay out of it).
pub(crate) fn refine_corners_within(
    gray: &GrayImage,
    corners: &mut BoardCorners,
    half_window_px: u32,
    max_radius_px: f64,
) {
    let refiner = SubPixel::new(gray, half_window_px, max_radius_px);
    corners
        .corners_px
        .par_iter_mut()
        .with_min_len(CORNERS_PER_TASK)
        .flatten()
        .for_each(|corner| *corner = refiner.refine(*corner));
}

/// The gradient refinement of [`refine_corners`] over one image with one
/// window.
struct SubPixel<'a> {
    pixels: &'a [u8],
    width: i64,
    height: i64,
    /// Half window (px), at least 2.
    w: i64,
    /// The Gaussian weights by offset from the window's centre pixel,
    /// computed once (as OpenCV's cornerSubPix does): the same pixels with
    /// the same weights give the same answer, so an iteration that stays on
    /// its pixel has converged.
    mask: Vec<f64>,
    max_radius_px: f64,
}

impl<'a> SubPixel<'a> {
    fn new(gray: &'a GrayImage, half_window_px: u32, max_radius_px: f64) -> Self {
        let w = i64::from(half_window_px.max(2));
        let sigma = w as f64 / 2.0;
        let side = (2 * w + 1) as usize;
        let mask: Vec<f64> = (0..side * side)
            .map(|k| {
                let (du, dv) = ((k % side) as f64 - w as f64, (k / side) as f64 - w as f64);
                (-(du * du + dv * dv) / (2.0 * sigma * sigma)).exp()
            })
            .collect();
        Self {
            pixels: gray.as_raw(),
            width: i64::from(gray.width()),
            height: i64::from(gray.height()),
            w,
            mask,
            max_radius_px,
        }
    }

    /// The corner refined from `start`; `start` itself where the refinement
    /// wanders off by more than a window.
    fn refine(&self, start: Point2<f64>) -> Point2<f64> {
        let (w, width, height) = (self.w, self.width, self.height);
        let side = (2 * w + 1) as usize;
        let max_radius_sq = self.max_radius_px * self.max_radius_px;
        let row = width as usize;
        let at = |u: i64, v: i64| f64::from(self.pixels[v as usize * row + u as usize]);
        let mut q = start;
        let mut last_centre = None;
        for _ in 0..20 {
            let (cu, cv) = (q.x.round() as i64, q.y.round() as i64);
            if cu - w - 1 < 0 || cv - w - 1 < 0 || cu + w + 1 >= width || cv + w + 1 >= height {
                break;
            }
            // The radius (a ChArUco board's markers) is about q itself, so
            // the pixels used change with q's sub-pixel position only then.
            if last_centre == Some((cu, cv)) && self.max_radius_px.is_infinite() {
                break;
            }
            last_centre = Some((cu, cv));
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for v in cv - w..=cv + w {
                let mask_row = &self.mask[((v - cv + w) as usize) * side..][..side];
                for (u, &weight) in (cu - w..=cu + w).zip(mask_row) {
                    let (du, dv) = (u as f64 - q.x, v as f64 - q.y);
                    if du * du + dv * dv > max_radius_sq {
                        continue;
                    }
                    let gx = (at(u + 1, v) - at(u - 1, v)) / 2.0;
                    let gy = (at(u, v + 1) - at(u, v - 1)) / 2.0;
                    let (gxx, gxy, gyy) = (gx * gx * weight, gx * gy * weight, gy * gy * weight);
                    a11 += gxx;
                    a12 += gxy;
                    a22 += gyy;
                    b1 += gxx * u as f64 + gxy * v as f64;
                    b2 += gxy * u as f64 + gyy * v as f64;
                }
            }
            let det = a11 * a22 - a12 * a12;
            if det.abs() <= 1e-9 || !det.is_finite() {
                break;
            }
            let next = Point2::new((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
            let moved = (next - q).norm();
            q = next;
            if moved < 1e-3 {
                break;
            }
        }
        if (q - start).norm() <= w as f64 && q.x.is_finite() && q.y.is_finite() { q } else { start }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use super::*;
    use calib_targets::detect;

    /// OpenCV's first right-camera photograph, grey.
    pub(crate) fn photo() -> GrayImage {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/opencv_right/right01.jpg");
        image::open(path).unwrap().to_luma8()
    }

    /// A 1152 x 768 grey view: dark background, a lighter board of 10 x 7
    /// squares (40 px) on a grey sheet, turned a little.
    fn board_view() -> GrayImage {
        let (angle, cell, centre) = (0.12_f64, 40.0, (500.0, 330.0));
        GrayImage::from_fn(1152, 768, |u, v| {
            let (du, dv) = (f64::from(u) - centre.0, f64::from(v) - centre.1);
            let (x, y) =
                (du * angle.cos() + dv * angle.sin(), -du * angle.sin() + dv * angle.cos());
            let (i, j) = ((x / cell + 5.0).floor(), (y / cell + 3.5).floor());
            let value = if (0.0..10.0).contains(&i) && (0.0..7.0).contains(&j) {
                if (i + j) as i64 % 2 == 0 { 20 } else { 200 }
            } else if x.abs() < 6.0 * cell && y.abs() < 4.5 * cell {
                200
            } else {
                30
            };
            image::Luma([value])
        })
    }

    #[test]
    fn the_corner_pass_is_calib_targets_own() {
        let photos =
            std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/opencv_right"))
                .unwrap()
                .map(|entry| entry.unwrap().path())
                .filter(|path| path.extension().is_some_and(|e| e == "jpg"))
                .map(|path| image::open(path).unwrap().to_luma8());
        // Each photograph, its half image (as searched first), a simulated view.
        let images: Vec<GrayImage> = photos
            .flat_map(|photo| {
                let half = half_size(&photo);
                [photo, half]
            })
            .chain([half_size(&board_view())])
            .collect();
        assert_eq!(images.len(), 27);
        for image in images {
            let ours = chess_corners(&image, None);
            let theirs = chessboard::detect_corners(
                &detect::gray_view(&image),
                &detect::default_chess_config(),
            );
            assert!(ours.len() > 40, "{} corners", ours.len());
            assert_eq!(ours, theirs);
        }
    }

    #[test]
    fn a_region_finds_the_whole_images_corners_inside_it() {
        let half = half_size(&board_view());
        let region = textured_region(&half).expect("a region");
        let area = (region.x1() - region.x0()) * (region.y1() - region.y0());
        assert!(area * 2 < (half.width() * half.height()) as usize, "region {region:?}");
        let inside = |c: &ChessCorner| {
            let (u, v) = (c.position.x as f64, c.position.y as f64);
            (region.x0() as f64..region.x1() as f64).contains(&u)
                && (region.y0() as f64..region.y1() as f64).contains(&v)
        };
        let key = |c: &ChessCorner| (c.position.x.to_bits(), c.position.y.to_bits());
        let mut whole: Vec<ChessCorner> =
            chess_corners(&half, None).into_iter().filter(inside).collect();
        let mut in_region = chess_corners(&half, Some(region));
        whole.sort_by_key(key);
        in_region.sort_by_key(key);
        assert!(whole.len() >= 54, "{} corners", whole.len());
        // The same corners; positions to f32 rounding (a region's are
        // found in its patch and shifted back).
        assert_eq!(in_region.len(), whole.len());
        for (a, b) in in_region.iter().zip(&whole) {
            assert!((a.position - b.position).norm() < 1e-3, "{a:?} vs {b:?}");
            assert!((a.axes[0].angle - b.axes[0].angle).abs() < 1e-4, "{a:?} vs {b:?}");
            assert_eq!(a.strength, b.strength);
        }
    }

    #[test]
    fn a_board_is_found_the_same_in_its_region_and_in_the_whole_image() {
        let (gray, board) = (board_view(), BoardSpec::checkerboard(9, 6, 1.0, 1.0));
        let half = half_size(&gray);
        let region = textured_region(&half);
        let (in_region, _) = labelled_grid(&half, region, 2.0, &board, &gray).unwrap();
        let (whole, _) = labelled_grid(&half, None, 2.0, &board, &gray).unwrap();
        assert_eq!(in_region.found_count(), 54);
        for (a, b) in in_region.corners_px.iter().zip(&whole.corners_px) {
            assert!((a.unwrap() - b.unwrap()).norm() < 1e-3, "{a:?} vs {b:?}");
        }
        assert_eq!(detect_checkerboard(&gray, &board).unwrap().found_count(), 54);
    }

    #[test]
    fn corners_refined_ahead_of_their_labels_are_those_refined_after_them() {
        let board = BoardSpec::checkerboard(9, 6, 1.0, 1.0);
        for (gray, ahead_expected) in [(board_view(), true), (photo(), false)] {
            let half = half_size(&gray);
            let region = textured_region(&half);
            let (mut after, refined) = labelled_grid(&half, region, 2.0, &board, &gray).unwrap();
            let half_window = refine_half_window(after.cell_size_px().unwrap());
            // The synthetic view's squares give the labelled window before
            // the labels; the photograph's clutter corners do not (then the
            // corners are refined again, as before).
            assert_eq!(refined.half_window_px == half_window, ahead_expected);
            refine_corners(&gray, &mut after, half_window);
            let ahead = detect_checkerboard(&gray, &board).unwrap();
            assert_eq!(ahead, after);
        }
    }

    #[test]
    fn the_nearest_neighbour_spacing_of_a_grid_is_its_step() {
        let grid: Vec<Point2<f64>> = (0..30)
            .map(|i| {
                Point2::new(f64::from(i % 6) * 12.0 + 0.1 * f64::from(i), f64::from(i / 6) * 15.0)
            })
            .collect();
        assert!((median_nearest_neighbour_px(&grid) - 12.1).abs() < 1e-9);
        assert_eq!(median_nearest_neighbour_px(&grid[..1]), 0.0);
        assert_eq!(median_nearest_neighbour_px(&[]), 0.0);
    }

    #[test]
    fn a_plain_image_has_no_region() {
        assert!(textured_region(&GrayImage::from_pixel(300, 200, image::Luma([90]))).is_none());
        assert!(textured_region(&GrayImage::new(5, 5)).is_none());
    }

    #[test]
    fn half_size_averages_two_by_two_blocks() {
        let gray = GrayImage::from_fn(7, 5, |u, v| image::Luma([(u * 30 + v * 7) as u8]));
        let half = half_size(&gray);
        assert_eq!(half.dimensions(), (3, 2));
        for (u, v, p) in half.enumerate_pixels() {
            let at = |du, dv| u16::from(gray.get_pixel(2 * u + du, 2 * v + dv)[0]);
            let sum = at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1);
            assert_eq!(u16::from(p[0]), (sum + 2) / 4);
        }
    }
}
