//! The calibration report: a camera and a laser against a calibration
//! session, per view the detected corners and the stripe drawn over the
//! image, so that a bad view shows at a glance.

use std::path::{Path, PathBuf};

use alacs_calib::{
    BoardObservation, CalibrationOptions, LaserSample, ViewSamples, depth_error_mm,
    detect_session_boards, intrinsics_std_dev_at, laser_std_dev_at, pose_observations,
    session_view_samples,
};
use alacs_model::io::OutputDir;
use alacs_model::{Camera, LaserModel, LaserStdDev, PlusMinus, Session};
use alacs_vision::{StripeOptions, read_image};
use nalgebra::Point2;
use rayon::prelude::*;

use super::draw::{CYAN, Canvas, GREEN, GREY, MAGENTA, ORANGE, palette};
use super::page::{Page, fixed, num, txt};
use crate::accuracy::accuracy_from_views;
use crate::{
    AccuracyEvaluation, AccuracyOptions, CalibrationEvaluation, Result, ViewDiagnostics,
    evaluate_calibration, write_accuracy_report, write_calibration_report, write_view_plots,
};

/// Widest view image on the page (px): half the 5 MP camera's width.
const MAX_VIEW_WIDTH_PX: u32 = 1224;

/// A board pose whose corners reproject worse than this (px RMS) is
/// flagged: a good detection with a good camera is well below 0.5 px.
const FLAG_POSE_RMS_PX: f64 = 1.0;

/// One view of a [`CalibrationReport`].
#[derive(Debug, Clone)]
pub struct CalibrationReportView {
    /// What the laser calibration's per-view step gave with the reported
    /// camera: the board pose, its reprojection RMS, the samples, why none.
    pub view: ViewSamples,
    /// The image the board corners were searched in.
    pub board_image: String,
    /// The detected board corners, px.
    pub corners_px: Vec<Point2<f64>>,
    /// Where the board pose puts the corners that were not detected, px
    /// (a partial board's missing part; empty without a pose).
    pub missing_corners_px: Vec<Point2<f64>>,
    /// The view's laser samples as pixels (their normalized coordinates
    /// through the camera's distortion), px.
    pub stripe_px: Vec<Point2<f64>>,
    /// z - z_hat of each sample under the reported laser (eq. (9)), mm.
    pub residuals_mm: Vec<f64>,
    /// Why the view is flagged as bad, if it is.
    pub flag: Option<String>,
}

impl CalibrationReportView {
    /// Mean |z - z_hat| of the view's samples, mm.
    pub fn mean_abs_residual_mm(&self) -> Option<f64> {
        (!self.residuals_mm.is_empty()).then(|| {
            self.residuals_mm.iter().map(|r| r.abs()).sum::<f64>() / self.residuals_mm.len() as f64
        })
    }
}

/// A camera and a laser reported against a calibration session.
#[derive(Debug, Clone)]
pub struct CalibrationReport {
    /// The reported camera.
    pub camera: Camera,
    /// The reported laser.
    pub laser: LaserModel,
    /// Inner corners of the board (columns, rows).
    pub board_corners: (usize, usize),
    /// Every view, in session order.
    pub views: Vec<CalibrationReportView>,
    /// Every sample, in view order.
    pub samples: Vec<LaserSample>,
    /// Table 1: the four methods fitted on the session's samples, or why not.
    pub table_1: std::result::Result<CalibrationEvaluation, String>,
    /// The accuracy experiment on the session's own views with the reported
    /// laser, or why not.
    pub accuracy: std::result::Result<AccuracyEvaluation, String>,
    /// The inlier threshold of Table 1 and of the views' flags, mm.
    pub threshold_mm: f64,
    /// Standard deviations of the reported camera on this session's
    /// corners (fx, fy, cx, cy, then the distortion coefficients), where
    /// defined ([`alacs_calib::intrinsics_std_dev_at`]).
    pub camera_std: Option<Vec<f64>>,
    /// Standard deviations of the reported laser: those its calibration
    /// estimated (laser.yaml's `std_dev`) where given, else a bootstrap over
    /// this session's board poses at the laser
    /// ([`alacs_calib::laser_std_dev_at`]), where defined.
    pub laser_std: Option<LaserStdDev>,
    /// Whether [`Self::laser_std`] is the calibration's own (given with the laser).
    pub laser_std_given: bool,
}

impl CalibrationReport {
    /// RMS of the board poses' reprojection errors over the views with a
    /// pose (each view weighted alike), px.
    pub fn pose_rms_px(&self) -> Option<f64> {
        let rms: Vec<f64> = self.views.iter().filter_map(|v| v.view.pose_rms_px).collect();
        (!rms.is_empty())
            .then(|| (rms.iter().map(|r| r * r).sum::<f64>() / rms.len() as f64).sqrt())
    }

    /// Mean |z - z_hat| over every sample under the reported laser, mm.
    pub fn mean_abs_residual_mm(&self) -> Option<f64> {
        let n: usize = self.views.iter().map(|v| v.residuals_mm.len()).sum();
        (n > 0).then(|| {
            self.views.iter().flat_map(|v| &v.residuals_mm).map(|r| r.abs()).sum::<f64>() / n as f64
        })
    }
}

/// Measures `camera` and `laser` on `session`: per view the board corners
/// (searched once per distinct board image), the board pose and the laser
/// samples ([`alacs_calib::view_samples`]) with their residuals under `laser`; Table 1
/// on all samples; the accuracy experiment on the same views. `laser_std`:
/// the laser's standard deviations as its calibration estimated them,
/// where known (laser.yaml's `std_dev`). `progress` is called once per
/// board image searched and once per view.
pub fn calibration_report(
    session: &Session,
    camera: &Camera,
    laser: &LaserModel,
    laser_std: Option<&LaserStdDev>,
    progress: &(dyn Fn() + Sync),
) -> Result<CalibrationReport> {
    camera.validate()?;
    laser.validate()?;
    let per_view = session_view_samples(session, camera, &StripeOptions::default(), progress)?;
    calibration_report_from_views(session, camera, laser, laser_std, per_view, progress)
}

/// [`calibration_report`] on the views' samples as a laser calibration of
/// the same session with the same camera already took them (in session
/// order, as [`alacs_calib::view_samples`] gives them; [`alacs_calib::calibrate_laser_session`]'s
/// `samples` split by its `views`' `n_samples`), which saves finding every
/// stripe again. `progress` is called once per board image searched.
pub fn calibration_report_from_views(
    session: &Session,
    camera: &Camera,
    laser: &LaserModel,
    laser_std: Option<&LaserStdDev>,
    per_view: Vec<(Vec<LaserSample>, ViewSamples)>,
    progress: &(dyn Fn() + Sync),
) -> Result<CalibrationReport> {
    if per_view.len() != session.views.len() {
        return Err(crate::Error::InvalidOptions(format!(
            "{} views' samples for a session of {} views",
            per_view.len(),
            session.views.len()
        )));
    }
    let (_, boards) = detect_session_boards(session, progress)?;
    let options = CalibrationOptions::default();
    let threshold_mm = options.threshold_mm;
    let mut views = Vec::with_capacity(per_view.len());
    let mut samples = Vec::new();
    for (spec, (view_samples, view)) in session.views.iter().zip(&per_view) {
        let board_image =
            spec.image_laser_off.as_deref().unwrap_or(&spec.image).display().to_string();
        let board = boards.iter().find(|b| b.image == board_image);
        let found: Vec<(usize, Point2<f64>)> = match board.map(|b| &b.corners) {
            Some(Ok(corners)) => corners.found().collect(),
            _ => Vec::new(),
        };
        let corners_px: Vec<Point2<f64>> = found.iter().map(|(_, p)| *p).collect();
        let missing_corners_px: Vec<Point2<f64>> = match view.camera_from_board {
            Some(camera_from_board) if !found.is_empty() => (0..session.board.cols
                * session.board.rows)
                .filter(|i| !found.iter().any(|(j, _)| j == i))
                .filter_map(|i| {
                    camera.project(&(camera_from_board * session.board.corner_in_board(i))).ok()
                })
                .collect(),
            _ => Vec::new(),
        };
        let stripe_px = view_samples.iter().map(|s| camera.normalized_to_pixel(&s.normalized()));
        let residuals_mm: Vec<f64> =
            view_samples.iter().map(|s| depth_error_mm(laser, s)).collect();
        let total_corners = session.board.cols * session.board.rows;
        let mean_abs = (!residuals_mm.is_empty())
            .then(|| residuals_mm.iter().map(|r| r.abs()).sum::<f64>() / residuals_mm.len() as f64);
        let flag = if let Some(reason) = &view.rejected {
            Some(format!("not used: {reason}"))
        } else if session.board.markers.is_none() && corners_px.len() < total_corners {
            // (A ChArUco board's corners label themselves: a part is a good view.)
            Some(format!("only {} of {total_corners} corners found", corners_px.len()))
        } else if let Some(rms) = view.pose_rms_px.filter(|&rms| rms > FLAG_POSE_RMS_PX) {
            Some(format!(
                "the board pose reprojects its corners at {rms:.2} px RMS (> {FLAG_POSE_RMS_PX} px): a wrong detection or a poor camera"
            ))
        } else {
            mean_abs.filter(|&m| m > threshold_mm).map(|mean| format!(
                "mean |z - z_hat| {mean:.2} mm exceeds the {threshold_mm} mm inlier threshold: the stripe or the laser disagrees with the board"
            ))
        };
        views.push(CalibrationReportView {
            view: view.clone(),
            board_image,
            corners_px,
            missing_corners_px,
            stripe_px: stripe_px.collect(),
            residuals_mm,
            flag,
        });
        samples.extend_from_slice(view_samples);
    }
    // One observation per board pose for the camera's standard deviations
    // (as calibrate camera takes them); every sample named by its pose for
    // the laser's.
    let observations: Vec<Option<&BoardObservation>> =
        per_view.iter().map(|(_, view)| view.observation.as_ref()).collect();
    let (groups, per_pose) = pose_observations(&observations);
    let camera_std = intrinsics_std_dev_at(camera, &per_pose.iter().collect::<Vec<_>>());
    let mut posed_samples = Vec::with_capacity(samples.len());
    for ((view_samples, _), group) in per_view.iter().zip(&groups) {
        posed_samples.extend(view_samples.iter().map(|s| LaserSample { pose: *group, ..*s }));
    }
    let laser_std_given = laser_std.is_some();
    let laser_std = match laser_std {
        Some(std) => Some(std.clone()),
        None => laser_std_dev_at(&posed_samples, laser, threshold_mm).map(|s| s.to_laser_std()),
    };
    let table_1 = evaluate_calibration(&samples, &options).map_err(|e| e.to_string());
    // The laser was probably fitted on these samples: those beyond the
    // threshold are the ones a RANSAC fit with it rejects.
    let accuracy_options =
        AccuracyOptions { rejected_beyond_mm: Some(threshold_mm), ..AccuracyOptions::default() };
    let accuracy =
        accuracy_from_views(per_view, camera, laser, &accuracy_options).map_err(|e| e.to_string());
    Ok(CalibrationReport {
        camera: camera.clone(),
        laser: *laser,
        board_corners: (session.board.cols, session.board.rows),
        views,
        samples,
        table_1,
        accuracy,
        threshold_mm,
        camera_std,
        laser_std,
        laser_std_given,
    })
}

/// The page's images of one view: its image with the corners (green
/// crosses; magenta circles where the board pose puts corners that were
/// not detected) and the stripe samples (cyan: within the threshold of the
/// reported laser, orange: beyond; not red, the laser's colour) drawn over it, at most
/// [`MAX_VIEW_WIDTH_PX`] wide, and at full size when the image is wider.
fn view_image(
    session: &Session,
    spec_image: &Path,
    view: &CalibrationReportView,
    threshold_mm: f64,
    paths: (&Path, &Path),
) -> Result<(Vec<u8>, Option<Vec<u8>>)> {
    let image = read_image(&session.path_of(spec_image)).map_err(alacs_calib::Error::from)?;
    let image = image.to_rgb8();
    let draw = |max_width_px: u32, path: &Path| {
        let mut canvas = Canvas::whole(&image, max_width_px);
        let (mark, dot) = (canvas.mark_px(), canvas.dot_px());
        for (p, r) in view.stripe_px.iter().zip(&view.residuals_mm) {
            canvas.dot(p, dot, if r.abs() <= threshold_mm { CYAN } else { ORANGE });
        }
        for p in &view.corners_px {
            canvas.cross(p, mark, GREEN);
        }
        for p in &view.missing_corners_px {
            canvas.circle(p, 1.2 * mark / canvas.scale(), MAGENTA);
        }
        canvas.jpeg(path)
    };
    let full = (image.width() > MAX_VIEW_WIDTH_PX).then(|| draw(image.width(), paths.1));
    Ok((draw(MAX_VIEW_WIDTH_PX, paths.0)?, full.transpose()?))
}

/// Cells across and down the image in which corner coverage is counted.
const COVERAGE_CELLS: (usize, usize) = (8, 6);

/// Where the board corners of the used views fell and how well the camera
/// reprojects them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerCoverage {
    /// Cells of an 8 x 6 grid over the image holding a corner.
    pub cells_covered: usize,
    /// Cells in the grid (48).
    pub cells: usize,
    /// Corners of the views with a board pose.
    pub corners: usize,
    /// Largest corner reprojection error, px.
    pub max_error_px: f64,
    /// How many times the error vectors are drawn enlarged.
    pub magnification: f64,
}

impl CalibrationReport {
    /// Every used view's corners as (view index, detected pixel,
    /// reprojection error vector: reprojected - detected, px).
    pub fn corner_errors(&self) -> Vec<(usize, Point2<f64>, nalgebra::Vector2<f64>)> {
        self.views
            .iter()
            .enumerate()
            .filter_map(|(i, v)| Some((i, v.view.observation.as_ref()?, v.view.camera_from_board?)))
            .flat_map(|(i, observation, pose)| {
                observation.points_in_board.iter().zip(&observation.pixels).filter_map(
                    move |(point, pixel)| {
                        let projected = self.camera.project(&(pose * point)).ok()?;
                        Some((i, *pixel, projected - pixel))
                    },
                )
            })
            .collect()
    }
}

/// The coverage image: every used view's corners over the image (one
/// colour per view), each with its reprojection error vector enlarged, the
/// 8 x 6 grid the coverage is counted in; and the counts.
fn coverage_image(report: &CalibrationReport, path: &Path) -> Result<(Vec<u8>, CornerCoverage)> {
    let camera = &report.camera;
    let errors = report.corner_errors();
    let max_error_px = errors.iter().map(|(_, _, e)| e.norm()).fold(0.0, f64::max);
    // The largest vector drawn 3 % of the image's width long.
    let magnification =
        (0.03 * f64::from(camera.width_px) / max_error_px.max(1e-9)).clamp(1.0, 1000.0).round();
    let background =
        image::RgbImage::from_pixel(camera.width_px, camera.height_px, image::Rgb([40, 40, 40]));
    let mut canvas = Canvas::whole(&background, MAX_VIEW_WIDTH_PX);
    let (cols, rows) = COVERAGE_CELLS;
    let (w, h) = (f64::from(camera.width_px), f64::from(camera.height_px));
    for c in 1..cols {
        let x = w * c as f64 / cols as f64;
        canvas.polyline(&[Point2::new(x, 0.0), Point2::new(x, h)], false, GREY);
    }
    for r in 1..rows {
        let y = h * r as f64 / rows as f64;
        canvas.polyline(&[Point2::new(0.0, y), Point2::new(w, y)], false, GREY);
    }
    let mut covered = vec![false; cols * rows];
    for (view, pixel, error) in &errors {
        let colour = palette(*view);
        canvas.polyline(&[*pixel, pixel + error * magnification], false, colour);
        canvas.dot(pixel, 1, colour);
        let c = ((pixel.x / w * cols as f64).floor().max(0.0) as usize).min(cols - 1);
        let r = ((pixel.y / h * rows as f64).floor().max(0.0) as usize).min(rows - 1);
        covered[r * cols + c] = true;
    }
    let coverage = CornerCoverage {
        cells_covered: covered.iter().filter(|c| **c).count(),
        cells: cols * rows,
        corners: errors.len(),
        max_error_px,
        magnification,
    };
    Ok((canvas.jpeg(path)?, coverage))
}

/// Writes the report as `dir`/index.html with its images (`images/`) and
/// plots (the files of [`write_calibration_report`] and
/// [`write_accuracy_report`]) beside it; `source` names the session on the
/// page. Returns every file written, the page first.
pub fn write_calibration_html(
    out: &mut OutputDir,
    session: &Session,
    report: &CalibrationReport,
    source: &str,
) -> Result<Vec<PathBuf>> {
    let image_names: Vec<(String, String)> = (0..report.views.len())
        .map(|i| {
            (format!("images/view{:02}.jpg", i + 1), format!("images/view{:02}_full.jpg", i + 1))
        })
        .collect();
    // Every image encoded first: one that fails leaves the folder as it was.
    let dir = out.path().to_path_buf();
    let images: Vec<(Vec<u8>, Option<Vec<u8>>)> = session
        .views
        .par_iter()
        .zip(&report.views)
        .zip(&image_names)
        .map(|((spec, view), (name, full))| {
            let paths = (dir.join(name), dir.join(full));
            view_image(session, &spec.image, view, report.threshold_mm, (&paths.0, &paths.1))
        })
        .collect::<Result<_>>()?;
    let coverage_name = "images/corner_coverage.jpg";
    let (coverage_bytes, coverage) = coverage_image(report, &dir.join(coverage_name))?;
    let mut files = Vec::new();
    if let Ok(eval) = &report.table_1 {
        files.extend(write_calibration_report(out, eval)?);
    }
    if let Ok(eval) = &report.accuracy {
        files.extend(write_accuracy_report(out, eval)?);
    }
    let diagnostics: Vec<ViewDiagnostics> = report
        .views
        .iter()
        .map(|v| ViewDiagnostics {
            pose_rms_px: v.view.pose_rms_px,
            slide_mm: v.view.slide_mm,
            residuals_mm: v.residuals_mm.clone(),
            // The bar shows the pose's RMS: red only for that reason.
            pose_flagged: v.view.pose_rms_px.is_some_and(|rms| rms > FLAG_POSE_RMS_PX),
        })
        .collect();
    files.extend(write_view_plots(out, "calibration_views", &diagnostics, report.threshold_mm)?);
    files.push(out.write(coverage_name, coverage_bytes)?);
    let mut links = Vec::with_capacity(image_names.len());
    for ((name, full), (bytes, full_bytes)) in image_names.iter().zip(images) {
        files.push(out.write(name, bytes)?);
        match full_bytes {
            Some(full_bytes) => {
                files.push(out.write(full, full_bytes)?);
                links.push((name.as_str(), full.as_str()));
            }
            None => links.push((name.as_str(), name.as_str())),
        }
    }

    let title = "alacs calibration report";
    let mut page = Page::new(title);
    page.paragraph(
        &format!(
            "Session {source}: {} views of a {} x {} board. The camera \"{}\" ({} x {} px) and a {} laser reported against it.",
            report.views.len(),
            report.board_corners.0,
            report.board_corners.1,
            report.camera.name,
            report.camera.width_px,
            report.camera.height_px,
            report.laser.fidelity.as_str()
        ),
        None,
    );
    summary(&mut page, report, &coverage);
    views_table(&mut page, report);
    page.heading("Corner coverage and reprojection errors");
    page.linked_figure(
        &[(coverage_name, coverage_name)],
        &format!(
            "The {} corners of the views with a board pose over the {} x {} px image, one colour per view, each with its reprojection error vector (reprojected - detected) drawn {} x enlarged (largest {:.3} px); they fall in {} of the {} cells of the {} x {} grid.",
            coverage.corners,
            report.camera.width_px,
            report.camera.height_px,
            coverage.magnification,
            coverage.max_error_px,
            coverage.cells_covered,
            coverage.cells,
            COVERAGE_CELLS.0,
            COVERAGE_CELLS.1
        ),
        (coverage.cells_covered * 2 < coverage.cells).then_some(
            "the corners cover less than half of the image: distortion is extrapolated where there are none",
        ),
    );
    page.plot("calibration_views.png", "per-view board pose RMS and residuals");
    plots(&mut page, report);
    page.heading("Views");
    page.raw(
        "<p class=\"legend\"><span style=\"color:#0a0\">+ detected corner</span><span style=\"color:#e22\">&bull; stripe sample within the threshold</span><span style=\"color:#28f\">&bull; stripe sample beyond it</span></p>",
    );
    page.paragraph("Each image links to its full-size copy.", Some("note"));
    page.grid_start();
    for (i, (view, link)) in report.views.iter().zip(&links).enumerate() {
        let caption = format!(
            "{}. {} (slide {:.1} mm): {} corners, pose RMS {} px, {} samples, mean |residual| {} mm",
            i + 1,
            view.view.image,
            view.view.slide_mm,
            view.corners_px.len(),
            fixed(view.view.pose_rms_px, 3),
            view.view.n_samples,
            fixed(view.mean_abs_residual_mm(), 3)
        );
        page.linked_figure(&[*link], &caption, view.flag.as_deref());
    }
    page.grid_end();
    files.insert(0, page.write(out, title)?);
    Ok(files)
}

/// `value +- sd` as every sigma is shown ([`PlusMinus`]): two significant
/// figures of the sigma; `digits` decimals without one.
fn plus_minus(value: f64, sd: Option<f64>, digits: usize) -> String {
    PlusMinus { value, sigma: sd, decimals: digits }.to_string()
}

/// The names of a distortion model's coefficients, in OpenCV's order.
const COEFFICIENT_NAMES: [&str; 8] = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"];

/// The summary: camera, views, laser and Table 1.
fn summary(page: &mut Page, report: &CalibrationReport, coverage: &CornerCoverage) {
    let camera = &report.camera;
    page.heading("Camera");
    let (model, coefficients) = camera.distortion.ros_model();
    let std = |i: usize| report.camera_std.as_ref().and_then(|s| s.get(i).copied());
    let pm = |value: f64, i: usize, digits: usize| plus_minus(value, std(i), digits);
    let coefficients: Vec<String> = coefficients
        .iter()
        .zip(COEFFICIENT_NAMES)
        .enumerate()
        .map(|(i, (c, name))| format!("{name} {}", pm(*c, 4 + i, 5)))
        .collect();
    let used = report.views.iter().filter(|v| v.view.camera_from_board.is_some()).count();
    page.table(
        &[txt(""), num("value")],
        &[
            (
                vec![
                    txt("fx, fy (px)"),
                    num(format!("{}, {}", pm(camera.fx_px, 0, 2), pm(camera.fy_px, 1, 2))),
                ],
                false,
            ),
            (
                vec![
                    txt("cx, cy (px)"),
                    num(format!("{}, {}", pm(camera.cx_px, 2, 2), pm(camera.cy_px, 3, 2))),
                ],
                false,
            ),
            (vec![txt(format!("distortion ({model})")), num(coefficients.join(", "))], false),
            (
                vec![txt("board-pose reprojection RMS (px)"), num(fixed(report.pose_rms_px(), 3))],
                report.pose_rms_px().is_some_and(|r| r > FLAG_POSE_RMS_PX),
            ),
            (
                vec![
                    txt("views with a board pose"),
                    num(format!("{used} of {}", report.views.len())),
                ],
                used < report.views.len(),
            ),
            (
                vec![
                    txt(format!(
                        "corner coverage ({} x {} cells)",
                        COVERAGE_CELLS.0, COVERAGE_CELLS.1
                    )),
                    num(format!("{} of {}", coverage.cells_covered, coverage.cells)),
                ],
                coverage.cells_covered * 2 < coverage.cells,
            ),
        ],
    );
    let rejected: Vec<String> = report
        .views
        .iter()
        .filter_map(|v| v.view.rejected.as_ref().map(|r| format!("{}: {r}", v.view.image)))
        .collect();
    if !rejected.is_empty() {
        page.paragraph(&format!("Views not used: {}", rejected.join("; ")), Some("flag"));
    }
    page.heading("Laser");
    let laser = &report.laser;
    let std = report.laser_std.as_ref();
    let pm = plus_minus;
    page.table(
        &[
            txt(""),
            num("alpha (deg)"),
            num("beta (deg)"),
            num("L0 (mm)"),
            num("slide scale k"),
            num("samples"),
            num("mean |z - z_hat| (mm)"),
            num("within threshold"),
        ],
        &[(
            vec![
                txt(format!("reported ({})", laser.fidelity.as_str())),
                num(pm(laser.alpha_deg(), std.map(|s| s.alpha_deg), 3)),
                num(pm(laser.beta_deg(), std.and_then(|s| s.beta_deg), 3)),
                num(pm(laser.l0_mm, std.map(|s| s.l0_mm), 2)),
                num(pm(laser.slide_scale, std.and_then(|s| s.slide_scale), 5)),
                num(report.samples.len().to_string()),
                num(fixed(report.mean_abs_residual_mm(), 3)),
                num({
                    let within = report
                        .views
                        .iter()
                        .flat_map(|v| &v.residuals_mm)
                        .filter(|r| r.abs() <= report.threshold_mm)
                        .count();
                    format!("{within} of {}", report.samples.len())
                }),
            ],
            false,
        )],
    );
    page.paragraph(
        &format!(
            "+- one standard deviation: the camera's on this session's corners (sigma^2 (J^T J)^-1 over the intrinsics and the board poses at the reported camera; {}); the laser's {}.",
            if report.camera_std.is_some() { "held intrinsics 0" } else { "not defined here" },
            match (std, report.laser_std_given) {
                (Some(s), true) => format!("as its calibration estimated them, the ones calibrate laser prints and writes to laser.yaml's std_dev ({})", s.source),
                (Some(s), false) => format!("on this session, laser.yaml holding none: a bootstrap over the board poses at the reported laser with the camera taken as exact ({}), so smaller than calibrate laser's, which re-calibrates the camera in each replicate", s.source),
                (None, _) => "not defined here: laser.yaml holds none and the session has fewer than 5 board poses".to_string(),
            }
        ),
        Some("note"),
    );
    page.heading("Table 1: the four methods on this session's samples");
    match &report.table_1 {
        Ok(eval) => {
            let rows = eval
                .methods
                .iter()
                .map(|m| {
                    let c = &m.calibration;
                    (
                        vec![
                            txt(format!("Method {} ({})", c.method.number(), c.method.name())),
                            num(format!("{:.3}", c.laser.alpha_deg())),
                            num(match c.laser.fidelity {
                                alacs_model::Fidelity::Low => "/".to_string(),
                                alacs_model::Fidelity::High => format!("{:.3}", c.laser.beta_deg()),
                            }),
                            num(format!("{:.2}", c.laser.l0_mm)),
                            num(if c.slide_scale_fitted {
                                format!("{:.5}", c.laser.slide_scale)
                            } else {
                                "1 (held)".to_string()
                            }),
                            num(format!("{:.3}", c.mean_abs_error_mm)),
                            num(format!("{}/{}", c.inliers.len(), c.n_samples)),
                        ],
                        false,
                    )
                })
                .collect::<Vec<_>>();
            page.table(
                &[
                    txt(""),
                    num("alpha (deg)"),
                    num("beta (deg)"),
                    num("L0 (mm)"),
                    num("slide scale k"),
                    num("mean |z - z_hat| (mm)"),
                    num("inliers"),
                ],
                &rows,
            );
            for (method, reason) in &eval.failed {
                page.paragraph(
                    &format!(
                        "Method {} ({}) cannot fit these samples: {reason}",
                        method.number(),
                        method.name()
                    ),
                    Some("flag"),
                );
            }
            if eval.methods.iter().any(|m| !m.calibration.slide_scale_fitted) {
                page.paragraph(
                    "The slide scale k was held at 1, not fitted: the samples lie at one slide position (or k was held on purpose). A slide whose steps are off by a fraction of a percent then moves every answer by that fraction of the slide travel; take the session at three or more slide positions to fit it.",
                    Some("flag"),
                );
            }
            page.paragraph(
                &format!(
                    "Mean error over each method's inliers (all samples for methods without RANSAC); inlier threshold {} mm.",
                    eval.options.threshold_mm
                ),
                Some("note"),
            );
        }
        Err(reason) => page.paragraph(&format!("Not computed: {reason}"), Some("flag")),
    }
}

/// The per-view table.
fn views_table(page: &mut Page, report: &CalibrationReport) {
    page.heading("Per view");
    let rows = report
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            (
                vec![
                    num((i + 1).to_string()),
                    txt(v.view.image.clone()),
                    num(format!("{:.1}", v.view.slide_mm)),
                    num(v.corners_px.len().to_string()),
                    num(fixed(v.view.pose_rms_px, 3)),
                    num(v.view.n_samples.to_string()),
                    num(fixed(v.mean_abs_residual_mm(), 3)),
                    txt(v.flag.clone().unwrap_or_default()),
                ],
                v.flag.is_some(),
            )
        })
        .collect::<Vec<_>>();
    page.table(
        &[
            num("#"),
            txt("image"),
            num("slide (mm)"),
            num("corners"),
            num("reprojection RMS (px)"),
            num("laser samples"),
            num("mean |z - z_hat| (mm)"),
            txt("flag"),
        ],
        &rows,
    );
}

/// The residual plots and the accuracy box plots.
fn plots(page: &mut Page, report: &CalibrationReport) {
    if let Ok(eval) = &report.table_1 {
        page.heading("Depth residuals z - z_hat per method");
        for method in &eval.methods {
            let n = method.calibration.method.number();
            page.plot(
                &format!("calibration_residuals_method{n}.png"),
                &format!("residuals of method {n}"),
            );
        }
    }
    page.heading("Accuracy on this session's views");
    match &report.accuracy {
        Ok(eval) => {
            let n_rejected = eval.n_rejected();
            page.paragraph(
                &format!(
                    "Every stripe point triangulated with the reported laser against its board plane, per slide position (the laser was probably fitted on these views: for an independent check run alacs evaluate accuracy on a second session). {n_rejected} of {} points lie beyond the {} mm inlier threshold, the ones a RANSAC fit with it rejects: red crosses beside the boxes (which count them), the panels' range set by the others.",
                    eval.points.len(),
                    report.threshold_mm
                ),
                Some("note"),
            );
            page.plot("accuracy_boxplots.png", "accuracy box plots");
        }
        Err(reason) => page.paragraph(&format!("Not computed: {reason}"), Some("flag")),
    }
}
