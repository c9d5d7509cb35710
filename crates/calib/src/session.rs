//! Calibration from a session folder (FORMATS.md): the camera from the board
//! corners of every view, then the laser from dense samples, the seed
//! paper's three steps per view:
//! 1. the board pose (PnP with the calibrated camera),
//! 2. every laser pixel on the board: the stripe's sub-pixel centre on each
//!    image row inside the board's corner polygon (laser-off differencing
//!    where the view has a laser-off image),
//! 3. each pixel's ray intersected with the board plane: a sample
//!    (u_n, v_n, z, slide_mm), unless a square's edge runs under the
//!    stripe's profile there (the reflectance step biases its centre),
//!
//! and the robust calibration (Algorithm 1, method 4 by default) over the
//! samples of all views, L0 fitted jointly when the slide positions differ.

use std::path::Path;

use alacs_board::{BoardCorners, board_gray, detect_checkerboard};
use alacs_model::{Camera, Session, SessionView};
use alacs_vision::{Region, StripeOptions, extract_stripe, laser_score, read_image};
use nalgebra::{Isometry3, Vector3};
use rayon::prelude::*;

use crate::{
    BoardObservation, CalibrationOptions, Error, IntrinsicsFit, IntrinsicsOptions,
    LaserCalibration, LaserSample, Method, Result, ViewFit, board_pose, calibrate,
    calibrate_intrinsics,
};

/// Laser pixels closer than this to the board's corner polygon are not used:
/// the stripe there may straddle the board's edge squares' neighbours.
const BOARD_MARGIN_PX: f64 = 3.0;

/// How far each side of a stripe point, in stripe widths (FWHM), the board
/// must show one shade for the point to become a sample.
const EDGE_REACH_WIDTHS: f64 = 1.5;

/// Fewest views with laser samples a laser calibration accepts: the samples
/// of one board lie on one line, which does not fix a plane.
const MIN_LASER_VIEWS: usize = 2;

/// A laser calibration whose samples span less depth than this warns: the
/// seed paper's boards span 0.6-1.2 m.
const WARN_DEPTH_SPAN_MM: f64 = 200.0;

/// Inlier fraction below which a laser calibration warns.
const WARN_INLIER_FRACTION: f64 = 0.8;

/// RMS depth residual above which a laser calibration warns (mm).
const WARN_RMS_MM: f64 = 1.0;

/// Detection result of one view's board.
#[derive(Debug, Clone)]
pub struct ViewBoard {
    /// The image the corners were found in.
    pub image: String,
    /// The corners, or why none were found.
    pub corners: std::result::Result<BoardCorners, String>,
}

/// Finds the board in every distinct pose of a session: a view's laser-off
/// image where it has one (several slide positions share it), else its image.
/// `progress` is called once per image searched. Returns the image size and
/// the detections. A missing or unreadable image is an error; an image
/// without a board is a rejected view.
pub fn detect_session_boards(
    session: &Session,
    progress: &(dyn Fn() + Sync),
) -> Result<((u32, u32), Vec<ViewBoard>)> {
    let mut images: Vec<&Path> = Vec::new();
    for view in &session.views {
        let image = view.image_laser_off.as_deref().unwrap_or(&view.image);
        if !images.contains(&image) {
            images.push(image);
        }
    }
    let results: Vec<Result<((u32, u32), ViewBoard)>> = images
        .par_iter()
        .map(|image| {
            let decoded = read_image(&session.path_of(image))?;
            let size = (decoded.width(), decoded.height());
            let gray = board_gray(&decoded);
            let corners = detect_checkerboard(&gray, &session.board).map_err(|e| e.to_string());
            progress();
            Ok((size, ViewBoard { image: image.display().to_string(), corners }))
        })
        .collect();
    let mut size = None;
    let mut boards = Vec::with_capacity(results.len());
    for (result, image) in results.into_iter().zip(&images) {
        let (this_size, board) = result?;
        match size {
            None => size = Some(this_size),
            Some(s) if s != this_size => {
                return Err(Error::Vision(alacs_vision::Error::Image {
                    path: session.path_of(image),
                    message: format!(
                        "is {} x {} px; the session's first image is {} x {} px",
                        this_size.0, this_size.1, s.0, s.1
                    ),
                }));
            }
            Some(_) => {}
        }
        boards.push(board);
    }
    Ok((size.unwrap_or((0, 0)), boards))
}

/// The board observation (corners and their board points) of a detection.
fn observation(session: &Session, name: &str, corners: &BoardCorners) -> BoardObservation {
    let (points_in_board, pixels) =
        corners.found().map(|(i, p)| (session.board.corner_in_board(i), p)).unzip();
    BoardObservation { name: name.to_string(), points_in_board, pixels }
}

/// Calibrates the camera from a session's board views (the laser is
/// ignored). Views without a board are listed as rejected with the reason.
pub fn calibrate_camera_session(
    session: &Session,
    options: &IntrinsicsOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<IntrinsicsFit> {
    let ((width, height), boards) = detect_session_boards(session, progress)?;
    let observations: Vec<BoardObservation> = boards
        .iter()
        .filter_map(|b| b.corners.as_ref().ok().map(|c| observation(session, &b.image, c)))
        .collect();
    let no_board = || {
        boards
            .iter()
            .filter_map(|b| b.corners.as_ref().err().map(|e| format!("{}: {e}", b.image)))
            .collect::<Vec<_>>()
    };
    if observations.len() < options.min_views {
        let rejected = no_board();
        return Err(Error::Degenerate(format!(
            "camera calibration needs at least {} views with a {} x {} board, found {} of {}{}",
            options.min_views,
            session.board.cols,
            session.board.rows,
            observations.len(),
            boards.len(),
            if rejected.is_empty() { String::new() } else { format!(" ({})", rejected.join("; ")) }
        )));
    }
    let mut fit = calibrate_intrinsics(width, height, &observations, options)?;
    // Every image in session order, the ones without a board included.
    let mut fitted = std::mem::take(&mut fit.views).into_iter();
    fit.views = boards
        .iter()
        .filter_map(|board| match &board.corners {
            Ok(_) => fitted.next(),
            Err(reason) => Some(ViewFit {
                name: board.image.clone(),
                camera_from_board: None,
                rms_px: None,
                rejected: Some(reason.clone()),
            }),
        })
        .collect();
    Ok(fit)
}

/// Settings of [`calibrate_laser_session`].
#[derive(Debug, Clone, Default)]
pub struct LaserSessionOptions {
    /// Stripe extraction.
    pub stripe: StripeOptions,
    /// The robust calibration.
    pub calibration: CalibrationOptions,
    /// Which of the four methods (default: 4, high fidelity + RANSAC).
    pub method: Option<Method>,
}

/// What one view gave the laser calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewSamples {
    /// The view's image.
    pub image: String,
    /// Its slide position.
    pub slide_mm: f64,
    /// The board pose found with the calibrated camera.
    pub camera_from_board: Option<Isometry3<f64>>,
    /// RMS reprojection error of that pose, px.
    pub pose_rms_px: Option<f64>,
    /// Samples it gave.
    pub n_samples: usize,
    /// Stripe points dropped because a square's edge runs under the
    /// stripe's profile (its sub-pixel centre is biased there).
    pub n_on_square_edges: usize,
    /// Why it gave none, where it gave none.
    pub rejected: Option<String>,
}

/// The result of [`calibrate_laser_session`].
#[derive(Debug, Clone)]
pub struct LaserSessionCalibration {
    /// The robust calibration on the samples.
    pub calibration: LaserCalibration,
    /// Every sample, in view order (`calibration.inliers` index into it).
    pub samples: Vec<LaserSample>,
    /// Every view, in session order.
    pub views: Vec<ViewSamples>,
    /// Quality warnings (poor depth coverage, residual spread, few views).
    pub warnings: Vec<String>,
}

/// Why views were rejected, for an error message: ` (view01.png: reason;
/// ...)`, or nothing when none was.
pub fn rejection_note(views: &[ViewSamples]) -> String {
    let reasons: Vec<String> = views
        .iter()
        .filter_map(|v| v.rejected.as_ref().map(|r| format!("{}: {r}", v.image)))
        .collect();
    if reasons.is_empty() { String::new() } else { format!(" ({})", reasons.join("; ")) }
}

/// [`view_samples`] of every view of `session`, in parallel, in session
/// order; `progress` is called once per view. The first view (in session
/// order) that fails gives the error.
pub fn session_view_samples(
    session: &Session,
    camera: &Camera,
    stripe: &StripeOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<(Vec<LaserSample>, ViewSamples)>> {
    let per_view: Vec<Result<(Vec<LaserSample>, ViewSamples)>> = session
        .views
        .par_iter()
        .map(|view| {
            let result = view_samples(session, view, camera, stripe);
            progress();
            result
        })
        .collect();
    per_view.into_iter().collect()
}

/// The laser samples of one view with a calibrated camera (see the module
/// docs).
pub fn view_samples(
    session: &Session,
    view: &SessionView,
    camera: &Camera,
    stripe: &StripeOptions,
) -> Result<(Vec<LaserSample>, ViewSamples)> {
    let mut report = ViewSamples {
        image: view.image.display().to_string(),
        slide_mm: view.slide_mm,
        camera_from_board: None,
        pose_rms_px: None,
        n_samples: 0,
        n_on_square_edges: 0,
        rejected: None,
    };
    let on = read_image(&session.path_of(&view.image))?;
    let off = match &view.image_laser_off {
        Some(off) => Some(read_image(&session.path_of(off))?),
        None => None,
    };
    if (on.width(), on.height()) != (camera.width_px, camera.height_px) {
        return Err(Error::Vision(alacs_vision::Error::Image {
            path: session.path_of(&view.image),
            message: format!(
                "is {} x {} px; the camera is {} x {} px",
                on.width(),
                on.height(),
                camera.width_px,
                camera.height_px
            ),
        }));
    }
    let board_image = off.as_ref().unwrap_or(&on);
    let gray = board_gray(board_image);
    let corners = match detect_checkerboard(&gray, &session.board) {
        Ok(corners) => corners,
        Err(e) => {
            report.rejected = Some(e.to_string());
            return Ok((Vec::new(), report));
        }
    };
    let observation = observation(session, &report.image, &corners);
    let (camera_from_board, rms) = match board_pose(camera, &observation) {
        Ok(pose) => pose,
        Err(e) => {
            report.rejected = Some(format!("no board pose: {e}"));
            return Ok((Vec::new(), report));
        }
    };
    report.camera_from_board = Some(camera_from_board);
    report.pose_rms_px = Some(rms);
    let Some(outline) = corners.outline_px() else {
        report.rejected = Some("an outer corner of the board was not found".into());
        return Ok((Vec::new(), report));
    };
    let region =
        Region::convex_polygon(&outline, BOARD_MARGIN_PX, camera.width_px, camera.height_px);
    let score = laser_score(&on.to_rgb8(), off.as_ref().map(|o| o.to_rgb8()).as_ref())?;
    let stripe_points = extract_stripe(&score, &region, stripe);
    // The board plane in the camera frame: normal n, through the board origin t.
    let normal: Vector3<f64> = camera_from_board.rotation * Vector3::z();
    let offset = normal.dot(&camera_from_board.translation.vector);
    // A pixel's ray on the board: its normalized coordinates and the point.
    let on_board = |u_px: f64, v_px: f64| {
        let normalized = camera.undistort_pixel(&nalgebra::Point2::new(u_px, v_px)).ok()?;
        let ray = Vector3::new(normalized.x, normalized.y, 1.0);
        let denominator = normal.dot(&ray);
        if denominator.abs() < 1e-9 {
            return None;
        }
        let z_mm = offset / denominator;
        (z_mm.is_finite() && z_mm > 0.0).then(|| (normalized, nalgebra::Point3::from(ray * z_mm)))
    };
    let board_from_camera = camera_from_board.inverse();
    let shade_at = |u_px: f64, v_px: f64| {
        on_board(u_px, v_px).map(|(_, p)| board_shade(&session.board, &(board_from_camera * p)))
    };
    let mut samples = Vec::with_capacity(stripe_points.len());
    for point in stripe_points {
        let Some((normalized, point_in_camera)) = on_board(point.u_px, point.v_px) else {
            continue;
        };
        // The stripe's profile must lie on one shade of the board: where a
        // square's edge runs under it, the reflectance step shifts the
        // sub-pixel centre by up to a pixel (millimetres in depth). On the
        // demo's 5-slide session, checking 1.5 widths each side cut the
        // worst depth error from 8.4 to 1.9 mm (1 width: 4.2 mm), keeping
        // 84 % of the points.
        let reach_px = EDGE_REACH_WIDTHS * point.width_px.max(1.0);
        let shade = shade_at(point.u_px, point.v_px);
        if shade.is_none()
            || shade_at(point.u_px - reach_px, point.v_px) != shade
            || shade_at(point.u_px + reach_px, point.v_px) != shade
        {
            report.n_on_square_edges += 1;
            continue;
        }
        samples.push(LaserSample {
            u_n: normalized.x,
            v_n: normalized.y,
            z_mm: point_in_camera.z,
            slide_mm: view.slide_mm,
        });
    }
    report.n_samples = samples.len();
    if samples.is_empty() {
        report.rejected = Some("no laser stripe found on the board".into());
    }
    Ok((samples, report))
}

/// The printed shade at a point on the board (board frame, mm): 0 or 1 for
/// the two colours of the squares, 2 for the margin around them (a third
/// shade, so that the pattern's border always counts as an edge).
fn board_shade(board: &alacs_model::BoardSpec, point_in_board: &nalgebra::Point3<f64>) -> u8 {
    // The squares span -1 ..= cols (rows) squares from the first inner corner.
    let col = (point_in_board.x / board.square_x_mm).floor();
    let row = (point_in_board.y / board.square_y_mm).floor();
    let inside =
        (-1.0..board.cols as f64).contains(&col) && (-1.0..board.rows as f64).contains(&row);
    if inside { ((col + row).rem_euclid(2.0)) as u8 } else { 2 }
}

/// Calibrates the laser from a session's views with a calibrated camera,
/// with the quality gate: refuses fewer than two views with samples, warns
/// on poor depth coverage, a low inlier fraction or a large residual spread.
pub fn calibrate_laser_session(
    session: &Session,
    camera: &Camera,
    options: &LaserSessionOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<LaserSessionCalibration> {
    let per_view = session_view_samples(session, camera, &options.stripe, progress)?;
    let mut samples = Vec::new();
    let mut views = Vec::with_capacity(per_view.len());
    for (view_samples, report) in per_view {
        samples.extend(view_samples);
        views.push(report);
    }
    let contributing = views.iter().filter(|v| v.n_samples > 0).count();
    if contributing < MIN_LASER_VIEWS {
        return Err(Error::Degenerate(format!(
            "laser calibration needs laser samples from at least {MIN_LASER_VIEWS} board views, got {contributing} of {}{}",
            views.len(),
            rejection_note(&views)
        )));
    }
    let method = options.method.unwrap_or(Method::HighFidelityRansac);
    let calibration = calibrate(&samples, method, &options.calibration)?;
    let warnings =
        quality_warnings(&samples, &calibration, contributing, options.calibration.threshold_mm);
    Ok(LaserSessionCalibration { calibration, samples, views, warnings })
}

/// The quality gate's warnings for a finished laser calibration.
fn quality_warnings(
    samples: &[LaserSample],
    fit: &LaserCalibration,
    views: usize,
    threshold_mm: f64,
) -> Vec<String> {
    let mut warnings = Vec::new();
    let (near, far) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| (lo.min(s.z_mm), hi.max(s.z_mm)));
    if far - near < WARN_DEPTH_SPAN_MM {
        warnings.push(format!(
            "the samples span only {:.0} mm in depth ({near:.0}-{far:.0} mm); boards spread over at least {WARN_DEPTH_SPAN_MM:.0} mm (the seed paper: 600-1200 mm) fix alpha and L0 much better",
            far - near
        ));
    }
    if views < 4 {
        warnings.push(format!(
            "only {views} views gave laser samples; use more board poses (the seed paper uses 10)"
        ));
    }
    let fraction = fit.inliers.len() as f64 / fit.n_samples.max(1) as f64;
    if fraction < WARN_INLIER_FRACTION {
        warnings.push(format!(
            "only {:.0} % of the samples agree with the fitted plane within {} mm: check for reflections or a wrong board pose",
            100.0 * fraction,
            threshold_mm
        ));
    }
    if fit.rms_error_mm > WARN_RMS_MM {
        warnings.push(format!(
            "the depth residuals spread widely (RMS {:.2} mm): check the camera calibration and the stripe",
            fit.rms_error_mm
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_shades_alternate_and_the_margin_is_its_own() {
        let board =
            alacs_model::BoardSpec { cols: 3, rows: 2, square_x_mm: 10.0, square_y_mm: 20.0 };
        let shade = |x: f64, y: f64| board_shade(&board, &nalgebra::Point3::new(x, y, 0.0));
        // The square left of and above the first inner corner, and its neighbours.
        assert_eq!(shade(-5.0, -10.0), shade(5.0, 10.0));
        assert_ne!(shade(-5.0, -10.0), shade(5.0, -10.0));
        assert_ne!(shade(-5.0, -10.0), shade(-5.0, 10.0));
        // The squares span -10..30 mm along x and -20..40 mm along y.
        assert_eq!(shade(29.0, 0.0), shade(9.0, 0.0));
        assert_eq!(shade(31.0, 0.0), 2);
        assert_eq!(shade(-11.0, 0.0), 2);
        assert_eq!(shade(0.0, 41.0), 2);
        assert_eq!(shade(0.0, -21.0), 2);
    }
}
