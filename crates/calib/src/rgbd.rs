//! The RGB-D camera's pose in the ALACS camera frame, `alacs_from_rgbd`,
//! from board poses both cameras saw (session.yaml's `image_rgbd`): per
//! pose, the board's pose in each camera (PnP with each camera's
//! calibration), `alacs_from_rgbd = alacs_from_board * rgbd_from_board^-1`;
//! the poses' rotations averaged (the chordal mean of their quaternions)
//! and their translations averaged, each pose's deviation from the mean
//! reported.

use alacs_board::{board_gray, detect_board_precise};
use alacs_model::{Camera, Session};
use alacs_vision::read_image;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::error::view_reasons;
use crate::intrinsics::{BoardObservation, board_pose};
use crate::{Error, Result};

/// One board pose both cameras saw.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdPose {
    /// The ALACS camera's image of the pose.
    pub image: String,
    /// The RGB-D camera's image of it.
    pub image_rgbd: String,
    /// `alacs_from_rgbd` from this pose alone.
    pub alacs_from_rgbd: Isometry3<f64>,
    /// The board's RMS reprojection error in the ALACS camera and in the
    /// RGB-D camera, px.
    pub rms_px: [f64; 2],
    /// How far this pose's estimate lies from the mean: rotation, degrees.
    pub rotation_deviation_deg: f64,
    /// ... and translation, mm.
    pub translation_deviation_mm: f64,
}

/// The calibrated transform and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdCalibration {
    /// `point_in_alacs = alacs_from_rgbd * point_in_rgbd`, mm.
    pub alacs_from_rgbd: Isometry3<f64>,
    /// The poses used.
    pub poses: Vec<RgbdPose>,
    /// Poses not used, with the reason (no board in one of the images, a
    /// PnP that failed).
    pub rejected: Vec<(String, String)>,
    /// RMS of the poses' rotation deviations, degrees.
    pub rotation_rms_deg: f64,
    /// RMS of the poses' translation deviations, mm.
    pub translation_rms_mm: f64,
}

/// Why a view gave no board pose: an image of another size than its camera
/// (bad input: the wrong camera file), or no board found in it.
enum PoseFailure {
    WrongSize(String),
    NoPose(String),
}

/// The board's pose in `camera` from the image at `path`.
fn pose_in(
    session: &Session,
    camera: &Camera,
    image: &std::path::Path,
) -> std::result::Result<(Isometry3<f64>, f64), PoseFailure> {
    let path = session.path_of(image);
    let decoded = read_image(&path).map_err(|e| PoseFailure::NoPose(e.to_string()))?;
    if (decoded.width(), decoded.height()) != (camera.width_px, camera.height_px) {
        return Err(PoseFailure::WrongSize(format!(
            "{} is {} x {} px, its camera {} x {} px: the camera file does not belong to these images",
            image.display(),
            decoded.width(),
            decoded.height(),
            camera.width_px,
            camera.height_px
        )));
    }
    let corners = detect_board_precise(&board_gray(&decoded), &session.board)
        .map_err(|e| PoseFailure::NoPose(format!("{}: {e}", image.display())))?;
    let (points_in_board, pixels) =
        corners.found().map(|(i, p)| (session.board.corner_in_board(i), p)).unzip();
    let observation =
        BoardObservation { name: image.display().to_string(), points_in_board, pixels };
    board_pose(camera, &observation).map_err(|e| PoseFailure::NoPose(e.to_string()))
}

/// Calibrates `alacs_from_rgbd` from the session's views that have an
/// `image_rgbd`, with the calibrated ALACS `camera` and `rgbd_camera`.
pub fn calibrate_rgbd(
    session: &Session,
    camera: &Camera,
    rgbd_camera: &Camera,
) -> Result<RgbdCalibration> {
    camera.validate()?;
    rgbd_camera.validate()?;
    // One entry per board pose: the RGB-D image names it.
    let mut pairs: Vec<(&std::path::Path, &std::path::Path)> = Vec::new();
    for view in &session.views {
        if let Some(rgbd) = view.image_rgbd.as_deref()
            && !pairs.iter().any(|(_, r)| *r == rgbd)
        {
            pairs.push((view.image_laser_off.as_deref().unwrap_or(&view.image), rgbd));
        }
    }
    if pairs.is_empty() {
        return Err(Error::Model(alacs_model::Error::Parse {
            path: session.dir.join(alacs_model::SESSION_FILE),
            message: "no view has an `image_rgbd` (the RGB-D camera's image of the same board \
                      pose), which calibrating the RGB-D camera's pose needs"
                .into(),
        }));
    }
    let results: Vec<std::result::Result<RgbdPose, (String, PoseFailure)>> = pairs
        .par_iter()
        .map(|(image, image_rgbd)| {
            let name = image_rgbd.display().to_string();
            let (alacs_from_board, rms_alacs) =
                pose_in(session, camera, image).map_err(|e| (name.clone(), e))?;
            let (rgbd_from_board, rms_rgbd) =
                pose_in(session, rgbd_camera, image_rgbd).map_err(|e| (name.clone(), e))?;
            Ok(RgbdPose {
                image: image.display().to_string(),
                image_rgbd: name,
                alacs_from_rgbd: alacs_from_board * rgbd_from_board.inverse(),
                rms_px: [rms_alacs, rms_rgbd],
                rotation_deviation_deg: 0.0,
                translation_deviation_mm: 0.0,
            })
        })
        .collect();
    let (mut poses, mut rejected) = (Vec::new(), Vec::new());
    for result in results {
        match result {
            Ok(pose) => poses.push(pose),
            Err((_, PoseFailure::WrongSize(message))) => {
                return Err(Error::Vision(alacs_vision::Error::Mismatch { message }));
            }
            Err((name, PoseFailure::NoPose(reason))) => rejected.push((name, reason)),
        }
    }
    if poses.is_empty() {
        return Err(Error::Degenerate(format!(
            "no board pose was found in both cameras' images ({})",
            view_reasons(rejected.iter().map(|(n, r)| (n.as_str(), r.as_str())))
        )));
    }
    let alacs_from_rgbd = mean_pose(poses.iter().map(|p| &p.alacs_from_rgbd));
    let (mut rotation_sq, mut translation_sq) = (0.0, 0.0);
    for pose in &mut poses {
        let delta = alacs_from_rgbd.inverse() * pose.alacs_from_rgbd;
        pose.rotation_deviation_deg = delta.rotation.angle().to_degrees();
        pose.translation_deviation_mm =
            (pose.alacs_from_rgbd.translation.vector - alacs_from_rgbd.translation.vector).norm();
        rotation_sq += pose.rotation_deviation_deg.powi(2);
        translation_sq += pose.translation_deviation_mm.powi(2);
    }
    let n = poses.len() as f64;
    Ok(RgbdCalibration {
        alacs_from_rgbd,
        rotation_rms_deg: (rotation_sq / n).sqrt(),
        translation_rms_mm: (translation_sq / n).sqrt(),
        poses,
        rejected,
    })
}

/// The mean of rigid transforms: the chordal mean of the rotations (the
/// normalized sum of their quaternions, signs aligned with the first) and
/// the mean translation.
fn mean_pose<'a>(poses: impl Iterator<Item = &'a Isometry3<f64>>) -> Isometry3<f64> {
    let mut sum = Quaternion::new(0.0, 0.0, 0.0, 0.0);
    let mut translation = Vector3::zeros();
    let mut first: Option<Quaternion<f64>> = None;
    let mut n = 0.0_f64;
    for pose in poses {
        let q = *pose.rotation.quaternion();
        let reference = *first.get_or_insert(q);
        sum += if q.dot(&reference) < 0.0 { -q } else { q };
        translation += pose.translation.vector;
        n += 1.0;
    }
    let rotation = UnitQuaternion::from_quaternion(sum);
    Isometry3::from_parts(Translation3::from(translation / n.max(1.0)), rotation)
}
