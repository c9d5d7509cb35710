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
//! samples of all views, L0 and the slide scale k fitted jointly when the
//! slide positions differ.

use std::path::Path;

use alacs_board::{BoardCorners, board_gray, detect_board_precise};
use alacs_model::{Camera, Session, SessionView};
use alacs_vision::{Region, StripeOptions, extract_stripe_rgb, read_image};
use nalgebra::{Isometry3, Point2};
use rayon::prelude::*;

use crate::error::view_reasons;
use crate::refine::Layout;
use crate::uncertainty::{
    MIN_BOOTSTRAP_POSES, PoseData, at_least, bootstrap_session, sample_on_board,
};
use crate::{
    BoardObservation, CalibrationOptions, Error, IntrinsicsFit, IntrinsicsOptions,
    LaserCalibration, LaserSample, Method, ParameterStdDev, Result, ViewFit, board_pose, calibrate,
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

/// Largest distance (px) between the same corner in two images for them to
/// show one board pose: the corner detector's noise is a few hundredths of
/// a pixel, and a board moved by hand moves its corners by many pixels.
const SAME_POSE_PX: f64 = 1.0;

/// Whether two images' corners show one board pose: at least half of the
/// smaller one's corners in common (by their board points; a ChArUco board
/// cut by the border may show different parts in two images of one pose),
/// and nine in ten of the common corners within [`SAME_POSE_PX`] (a laser
/// line over a corner in one image may move that corner further).
fn same_pose(a: &BoardObservation, b: &BoardObservation) -> bool {
    let (mut common, mut close) = (0usize, 0usize);
    for (point, pixel) in a.points_in_board.iter().zip(&a.pixels) {
        if let Some(k) = b.points_in_board.iter().position(|q| q == point) {
            common += 1;
            close += usize::from((b.pixels[k] - pixel).norm() < SAME_POSE_PX);
        }
    }
    common >= 4 && 2 * common >= a.pixels.len().min(b.pixels.len()) && 10 * close >= 9 * common
}

/// The board pose of each image, numbered 0, 1, ... in order of first
/// appearance (`None` where no board was found): a session takes each pose
/// at several slide positions, and those images are one pose, not several.
pub fn board_pose_groups(observations: &[Option<&BoardObservation>]) -> Vec<Option<u32>> {
    let mut first_of_group: Vec<&BoardObservation> = Vec::new();
    observations
        .iter()
        .map(|observation| {
            let observation = (*observation)?;
            let group = match first_of_group.iter().position(|f| same_pose(f, observation)) {
                Some(g) => g,
                None => {
                    first_of_group.push(observation);
                    first_of_group.len() - 1
                }
            };
            u32::try_from(group).ok()
        })
        .collect()
}

/// One observation of a board pose seen in several images: per corner the
/// median of where the images saw it (a laser line over a corner in one
/// image does not move it), named by the first image.
fn merge_pose(members: &[&BoardObservation]) -> Option<BoardObservation> {
    let first = members.first()?;
    let mut merged = BoardObservation {
        name: if members.len() > 1 {
            format!("{} (+{} images of the same pose)", first.name, members.len() - 1)
        } else {
            first.name.clone()
        },
        points_in_board: Vec::with_capacity(first.pixels.len()),
        pixels: Vec::with_capacity(first.pixels.len()),
    };
    for point in &first.points_in_board {
        let (mut us, mut vs): (Vec<f64>, Vec<f64>) = members
            .iter()
            .filter_map(|m| {
                let k = m.points_in_board.iter().position(|q| q == point)?;
                Some((m.pixels[k].x, m.pixels[k].y))
            })
            .unzip();
        us.sort_by(f64::total_cmp);
        vs.sort_by(f64::total_cmp);
        let median = |v: &[f64]| {
            let n = v.len();
            if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
        };
        merged.points_in_board.push(*point);
        merged.pixels.push(Point2::new(median(&us), median(&vs)));
    }
    Some(merged)
}

/// Detection result of one view's board.
#[derive(Debug, Clone)]
pub struct ViewBoard {
    /// The image the corners were found in.
    pub image: String,
    /// The corners, or why none were found.
    pub corners: std::result::Result<BoardCorners, alacs_board::Error>,
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
            let corners = detect_board_precise(&gray, &session.board);
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

/// One observation per board pose of a session's images (`observations`,
/// `None` where an image has no board): the images of one pose at several
/// slide positions are one view of the board, not several, with each
/// corner at the median of where they saw it. Returns each image's pose
/// ([`board_pose_groups`]) and the poses' observations, in pose order.
pub fn pose_observations(
    observations: &[Option<&BoardObservation>],
) -> (Vec<Option<u32>>, Vec<BoardObservation>) {
    let groups = board_pose_groups(observations);
    let n_poses = groups.iter().flatten().map(|&g| g as usize + 1).max().unwrap_or(0);
    let merged = (0..n_poses)
        .filter_map(|g| {
            let members: Vec<&BoardObservation> = observations
                .iter()
                .zip(&groups)
                .filter(|(_, group)| **group == u32::try_from(g).ok())
                .filter_map(|(o, _)| *o)
                .collect();
            merge_pose(&members)
        })
        .collect();
    (groups, merged)
}

/// Calibrates the camera from a session's board views (the laser is
/// ignored). Views without a board are listed as rejected with the reason.
pub fn calibrate_camera_session(
    session: &Session,
    options: &IntrinsicsOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<IntrinsicsFit> {
    let ((width, height), boards) = detect_session_boards(session, progress)?;
    let found: Vec<Option<BoardObservation>> = boards
        .iter()
        .map(|b| b.corners.as_ref().ok().map(|c| observation(session, &b.image, c)))
        .collect();
    let (_, observations) =
        pose_observations(&found.iter().map(Option::as_ref).collect::<Vec<_>>());
    if observations.len() < options.min_views {
        // Most images show a whole grid one corner short each way (a stray
        // corner spoils the rest): session.yaml's board counts squares, bad
        // input rather than a failed job.
        let squares: Vec<&alacs_board::Error> = boards
            .iter()
            .filter_map(|b| b.corners.as_ref().err())
            .filter(|e| matches!(e, alacs_board::Error::GivenBySquares { .. }))
            .collect();
        if observations.is_empty() && squares.len() * 2 > boards.len() {
            return Err(Error::Board(squares[0].clone()));
        }
        let reasons: Vec<(&str, String)> = boards
            .iter()
            .filter_map(|b| b.corners.as_ref().err().map(|e| (b.image.as_str(), e.to_string())))
            .collect();
        let rejected = view_reasons(reasons.iter().map(|(n, r)| (*n, r.as_str())));
        return Err(Error::Degenerate(format!(
            "camera calibration needs at least {} board poses with a {} x {} board, found {} in {} images{}",
            options.min_views,
            session.board.cols,
            session.board.rows,
            observations.len(),
            boards.len(),
            if rejected.is_empty() { String::new() } else { format!(" ({rejected})") }
        )));
    }
    let mut fit = calibrate_intrinsics(width, height, &observations, options)?;
    // Every pose in order, then every image without a board.
    fit.views.extend(boards.iter().filter_map(|board| {
        board.corners.as_ref().err().map(|reason| ViewFit {
            name: board.image.clone(),
            camera_from_board: None,
            rms_px: None,
            rejected: Some(reason.to_string()),
        })
    }));
    fit.images = boards.len();
    Ok(fit)
}

/// Settings of [`calibrate_laser_session`].
#[derive(Debug, Clone)]
pub struct LaserSessionOptions {
    /// Stripe extraction.
    pub stripe: StripeOptions,
    /// The robust calibration.
    pub calibration: CalibrationOptions,
    /// Which of the four methods (default: 4, high fidelity + RANSAC).
    pub method: Option<Method>,
    /// Whether the standard deviations include the camera's: each bootstrap
    /// replicate re-calibrates the camera from its board poses' corners.
    /// Off takes the camera as exact (one calibrated from far more views
    /// than the session holds).
    pub camera_uncertainty: bool,
}

impl Default for LaserSessionOptions {
    fn default() -> Self {
        LaserSessionOptions {
            stripe: StripeOptions::default(),
            calibration: CalibrationOptions::default(),
            method: None,
            camera_uncertainty: true,
        }
    }
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
    /// The board's corners found in it.
    pub observation: Option<BoardObservation>,
    /// The laser pixel of each of its samples, in order.
    pub pixels_px: Vec<Point2<f64>>,
    /// Which board pose it shows (0, 1, ... in session order; images of one
    /// pose at several slide positions share it), where the board was found.
    pub pose: Option<u32>,
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
    let reasons = view_reasons(
        views.iter().filter_map(|v| v.rejected.as_deref().map(|r| (v.image.as_str(), r))),
    );
    if reasons.is_empty() { String::new() } else { format!(" ({reasons})") }
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
        observation: None,
        pixels_px: Vec::new(),
        pose: None,
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
    let corners = match detect_board_precise(&gray, &session.board) {
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
    report.observation = Some(observation);
    // The squares between the found corners: the four outer corners where
    // all were found, else (a ChArUco board cut by the border, a corner
    // under the laser) the convex hull of the corners found.
    let outline = match corners.outline_px() {
        Some(outline) => outline.to_vec(),
        None => convex_hull(corners.found().map(|(_, p)| p).collect()),
    };
    let region =
        Region::convex_polygon(&outline, BOARD_MARGIN_PX, camera.width_px, camera.height_px);
    let stripe_points = extract_stripe_rgb(
        &on.to_rgb8(),
        off.as_ref().map(|o| o.to_rgb8()).as_ref(),
        &region,
        stripe,
    )?;
    let board_from_camera = camera_from_board.inverse();
    let shade_at = |u_px: f64, v_px: f64| {
        sample_on_board(camera, &camera_from_board, &Point2::new(u_px, v_px), 0.0)
            .map(|s| board_shade(&session.board, &(board_from_camera * s.point_in_camera())))
    };
    let mut samples = Vec::with_capacity(stripe_points.len());
    for point in stripe_points {
        let pixel = nalgebra::Point2::new(point.u_px, point.v_px);
        let Some(sample) = sample_on_board(camera, &camera_from_board, &pixel, view.slide_mm)
        else {
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
        samples.push(sample);
        report.pixels_px.push(pixel);
    }
    report.n_samples = samples.len();
    if samples.is_empty() {
        report.rejected = Some("no laser stripe found on the board".into());
    }
    Ok((samples, report))
}

/// The printed shade at a point on the board (board frame, mm): 0 or 1 for
/// the two colours of the squares, 2 for the margin around them (a third
/// shade, so that the pattern's border always counts as an edge); `None` on
/// a ChArUco board's marker, whose bits are no one shade.
fn board_shade(
    board: &alacs_model::BoardSpec,
    point_in_board: &nalgebra::Point3<f64>,
) -> Option<u8> {
    if board.marker_cell_at(point_in_board.x, point_in_board.y).is_some() {
        return None;
    }
    Some(match board.square_at(point_in_board.x, point_in_board.y) {
        Some((i, j)) => ((i + j) % 2) as u8,
        None => 2,
    })
}

/// The convex hull of points, counter-clockwise in the image's (u, v)
/// (Andrew's monotone chain); fewer than three points give no polygon.
fn convex_hull(mut points: Vec<Point2<f64>>) -> Vec<Point2<f64>> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return Vec::new();
    }
    let cross = |o: &Point2<f64>, a: &Point2<f64>, b: &Point2<f64>| {
        (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
    };
    let mut hull: Vec<Point2<f64>> = Vec::with_capacity(2 * points.len());
    for pass in [points.clone(), points.into_iter().rev().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2
                && cross(&hull[hull.len() - 2], &hull[hull.len() - 1], &p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
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
    let groups = board_pose_groups(
        &per_view.iter().map(|(_, report)| report.observation.as_ref()).collect::<Vec<_>>(),
    );
    let mut samples = Vec::new();
    let mut poses_of_samples = Vec::new();
    let mut views = Vec::with_capacity(per_view.len());
    for ((view_samples, mut report), pose) in per_view.into_iter().zip(groups) {
        report.pose = pose;
        poses_of_samples.extend(std::iter::repeat_n(pose, view_samples.len()));
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
    // Fitted without the poses, so that its standard deviations are the
    // covariance's: the floor of the bootstrap's below.
    let mut calibration = calibrate(&samples, method, &options.calibration)?;
    for (sample, pose) in samples.iter_mut().zip(poses_of_samples) {
        sample.pose = pose;
    }
    let poses = pose_data(&views, &calibration.inliers);
    let mut warnings =
        quality_warnings(&samples, &calibration, contributing, calibration.threshold_mm);
    let layout = Layout {
        fidelity: calibration.laser.fidelity,
        slide_scale: calibration.slide_scale_fitted,
    };
    if let Some((std, source)) = bootstrap_session(
        &poses,
        camera,
        &calibration.laser,
        layout,
        options.calibration.residual,
        options.camera_uncertainty,
        options.calibration.seed,
    ) {
        let covariance = calibration.std_dev.map(ParameterStdDev::to_parameters);
        calibration.std_dev = ParameterStdDev::from_parameters(
            &at_least(&std, covariance.as_deref()),
            layout,
            source,
        );
    } else {
        calibration.std_dev = None;
        warnings.push(if poses.len() < MIN_BOOTSTRAP_POSES {
            format!(
                "only {} board poses gave laser samples: no standard deviations (samples of one pose share its error, and a spread over fewer than {MIN_BOOTSTRAP_POSES} poses says nothing); use more poses",
                poses.len()
            )
        } else {
            format!(
                "no standard deviations: the bootstrap over {} board poses failed (the camera's problem could not be linearized at this camera, or too few replicates gave a fit)",
                poses.len()
            )
        });
    }
    Ok(LaserSessionCalibration { calibration, samples, views, warnings })
}

/// The board poses that gave inlier samples, for the bootstrap: per pose the
/// corners of its first image, its pose, and per image its inlier pixels.
fn pose_data(views: &[ViewSamples], inliers: &[usize]) -> Vec<PoseData> {
    let mut is_inlier = vec![false; views.iter().map(|v| v.n_samples).sum()];
    for &i in inliers {
        if let Some(flag) = is_inlier.get_mut(i) {
            *flag = true;
        }
    }
    let mut poses: Vec<(u32, PoseData)> = Vec::new();
    let mut first_sample = 0;
    for view in views {
        let flags = &is_inlier[first_sample..first_sample + view.n_samples];
        first_sample += view.n_samples;
        let (Some(pose), Some(observation), Some(camera_from_board)) =
            (view.pose, &view.observation, view.camera_from_board)
        else {
            continue;
        };
        let pixels: Vec<Point2<f64>> =
            view.pixels_px.iter().zip(flags).filter(|(_, f)| **f).map(|(p, _)| *p).collect();
        if pixels.is_empty() {
            continue;
        }
        match poses.iter_mut().find(|(p, _)| *p == pose) {
            Some((_, data)) => data.stripes.push((view.slide_mm, pixels)),
            None => poses.push((
                pose,
                PoseData {
                    observation: observation.clone(),
                    camera_from_board,
                    stripes: vec![(view.slide_mm, pixels)],
                },
            )),
        }
    }
    poses.into_iter().map(|(_, data)| data).collect()
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
        let board = alacs_model::BoardSpec::checkerboard(3, 2, 10.0, 20.0);
        let shade = |x: f64, y: f64| board_shade(&board, &nalgebra::Point3::new(x, y, 0.0));
        // The square left of and above the first inner corner, and its neighbours.
        assert_eq!(shade(-5.0, -10.0), shade(5.0, 10.0));
        assert_ne!(shade(-5.0, -10.0), shade(5.0, -10.0));
        assert_ne!(shade(-5.0, -10.0), shade(-5.0, 10.0));
        // The squares span -10..30 mm along x and -20..40 mm along y.
        assert_eq!(shade(29.0, 0.0), shade(9.0, 0.0));
        assert_eq!(shade(31.0, 0.0), Some(2));
        assert_eq!(shade(-11.0, 0.0), Some(2));
        assert_eq!(shade(0.0, 41.0), Some(2));
        assert_eq!(shade(0.0, -21.0), Some(2));
    }

    #[test]
    fn a_charuco_markers_square_is_no_shade_but_its_white_margin_is() {
        let mut board = alacs_model::BoardSpec::checkerboard(3, 2, 10.0, 10.0);
        board.markers = Some(alacs_model::CharucoMarkers {
            marker_mm: 6.0,
            dictionary: alacs_model::ArucoDictionary::Dict4x4_50,
        });
        let shade = |x: f64, y: f64| board_shade(&board, &nalgebra::Point3::new(x, y, 0.0));
        // Square (1, 0) (x 0..10, y -10..0) is white with its marker at 2..8.
        assert_eq!(shade(5.0, -5.0), None);
        assert_eq!(shade(1.0, -5.0), shade(1.0, 15.0), "white margins");
        assert_ne!(shade(-5.0, -5.0), shade(1.0, -5.0));
    }

    #[test]
    fn the_hull_of_a_partial_board_holds_its_corners() {
        let points: Vec<Point2<f64>> =
            [(0.0, 0.0), (2.0, 0.0), (1.0, 1.0), (2.0, 2.0), (0.0, 2.0), (1.0, 0.0)]
                .iter()
                .map(|&(x, y)| Point2::new(x, y))
                .collect();
        let hull = convex_hull(points);
        assert_eq!(hull.len(), 4, "{hull:?}");
        assert!(convex_hull(vec![Point2::new(0.0, 0.0), Point2::new(1.0, 1.0)]).is_empty());
    }
}
