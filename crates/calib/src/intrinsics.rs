//! Camera calibration from views of a planar board: Zhang's closed form, then
//! Levenberg-Marquardt over intrinsics, `plumb_bob` or `rational_polynomial`
//! distortion and every board pose (the seed paper's camera model, eqs.
//! (1)-(2)), with OpenCV's controls (fixed k3, zero tangential distortion,
//! fixed aspect ratio, fixed principal point, a starting camera); and the board
//! pose of one view with a calibrated camera (PnP), which the laser
//! calibration needs per view.
//!
//! 1. A homography per view, board plane -> pixels (normalized DLT).
//! 2. Zhang's closed form for K with zero skew (Z. Zhang, "A flexible new
//!    technique for camera calibration", 2000), falling back to OpenCV's
//!    initialisation (principal point at the image centre, fx and fy from the
//!    homographies) when the views do not determine the principal point.
//! 3. Each view's pose from its homography and K.
//! 4. Levenberg-Marquardt on the reprojection error of every corner, with
//!    analytic Jacobians, over the free ones of fx, fy, cx, cy and the
//!    distortion coefficients (`IntrinsicsLayout`), and the poses (rotation
//!    vector, translation).
//! 5. Views whose RMS reprojection error is far above the others are
//!    rejected, with the reason, and the fit repeated.

use alacs_model::{Camera, Distortion, DistortionModel};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{
    DMatrix, DVector, Dyn, Isometry3, Matrix3, Point2, Point3, Translation3, UnitQuaternion,
    Vector3,
};

use crate::error::view_reasons;
use crate::refine::dynamic_problem_params;
use crate::{Error, Result};

/// The corners of one view: board points (z = 0) and where they were seen.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardObservation {
    /// Name of the view (its image file) for reports and errors.
    pub name: String,
    /// Corners in the board frame, mm, z = 0.
    pub points_in_board: Vec<Point3<f64>>,
    /// The same corners in the image, px.
    pub pixels: Vec<Point2<f64>>,
}

/// Settings of [`calibrate_intrinsics`].
#[derive(Debug, Clone, PartialEq)]
pub struct IntrinsicsOptions {
    /// A view whose RMS reprojection error exceeds this many times the
    /// median view's is rejected...
    pub reject_factor: f64,
    /// ...unless its RMS is below this floor (px): good views are never
    /// rejected for being a little worse than excellent ones.
    pub reject_floor_px: f64,
    /// Fewest views a calibration may use.
    pub min_views: usize,
    /// The distortion model fitted (OpenCV's default `plumb_bob`, or
    /// `rational_polynomial`: its `CALIB_RATIONAL_MODEL`).
    pub distortion: DistortionModel,
    /// Intrinsics held instead of fitted.
    pub fixed: FixedIntrinsics,
    /// A starting camera (OpenCV's `CALIB_USE_INTRINSIC_GUESS`): its
    /// intrinsics and distortion start the fit instead of Zhang's closed
    /// form, and give the values of the held ones. It must have the size of
    /// the views' images.
    pub initial: Option<Camera>,
}

impl Default for IntrinsicsOptions {
    fn default() -> Self {
        IntrinsicsOptions {
            reject_factor: 3.0,
            reject_floor_px: 1.0,
            min_views: 3,
            distortion: DistortionModel::PlumbBob,
            fixed: FixedIntrinsics::default(),
            initial: None,
        }
    }
}

/// Which intrinsics a camera calibration holds, as OpenCV's flags do; the
/// held values come from the starting camera, or are OpenCV's defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FixedIntrinsics {
    /// k3 held (`CALIB_FIX_K3`): the starting camera's, else 0.
    pub k3: bool,
    /// p1 = p2 = 0 (`CALIB_ZERO_TANGENT_DIST`).
    pub tangential: bool,
    /// fx / fy held (`CALIB_FIX_ASPECT_RATIO`): the starting camera's, else 1.
    pub aspect: bool,
    /// cx, cy held (`CALIB_FIX_PRINCIPAL_POINT`): the starting camera's,
    /// else the image centre ((w - 1) / 2, (h - 1) / 2).
    pub principal_point: bool,
}

impl FixedIntrinsics {
    /// What a calibrated camera shows it was calibrated with: a distortion
    /// coefficient that is exactly 0 (k3, or p1 and p2) was held there, fx
    /// equal to fy to the bit was an aspect ratio held at 1, and a principal
    /// point exactly at the image centre was held there (fitted values are
    /// never exact). For re-calibrations of a given camera (the bootstrap).
    pub fn inferred_from(camera: &Camera) -> FixedIntrinsics {
        let c = camera.distortion.coefficients();
        let zero = |i: usize| c.get(i).is_none_or(|&v| v == 0.0);
        let (cx, cy) = image_centre(camera.width_px, camera.height_px);
        FixedIntrinsics {
            k3: zero(K3),
            tangential: TANGENTIAL.clone().all(zero),
            aspect: camera.fx_px == camera.fy_px,
            principal_point: camera.cx_px == cx && camera.cy_px == cy,
        }
    }
}

/// Where k3 sits among the distortion coefficients (OpenCV's order).
const K3: usize = 4;

/// Where p1 and p2 sit among the distortion coefficients.
const TANGENTIAL: std::ops::Range<usize> = 2..4;

/// OpenCV's image centre, ((w - 1) / 2, (h - 1) / 2).
fn image_centre(width_px: u32, height_px: u32) -> (f64, f64) {
    ((f64::from(width_px) - 1.0) / 2.0, (f64::from(height_px) - 1.0) / 2.0)
}

/// One intrinsic parameter a calibration fits.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Intrinsic {
    Fx,
    Fy,
    /// fx, with fy = `aspect` fx (the aspect ratio held).
    Focal {
        aspect: f64,
    },
    Cx,
    Cy,
    /// The distortion coefficient at this index, in OpenCV's order.
    Coefficient(usize),
}

/// The intrinsics a calibration fits, in their order in its parameter
/// vector; the held ones keep their values in the camera it starts from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct IntrinsicsLayout {
    free: Vec<Intrinsic>,
    coefficients: usize,
}

impl IntrinsicsLayout {
    /// The layout for `fixed` on `start` (which holds the held values).
    pub(crate) fn new(start: &Camera, fixed: FixedIntrinsics) -> Self {
        let mut free = if fixed.aspect {
            vec![Intrinsic::Focal { aspect: start.fy_px / start.fx_px }]
        } else {
            vec![Intrinsic::Fx, Intrinsic::Fy]
        };
        if !fixed.principal_point {
            free.extend([Intrinsic::Cx, Intrinsic::Cy]);
        }
        let coefficients = start.distortion.coefficients().len();
        free.extend(
            (0..coefficients)
                .filter(|&i| {
                    let held =
                        (fixed.tangential && TANGENTIAL.contains(&i)) || (fixed.k3 && i == K3);
                    !held
                })
                .map(Intrinsic::Coefficient),
        );
        IntrinsicsLayout { free, coefficients }
    }

    /// The layout of the intrinsics `camera` shows were fitted
    /// ([`FixedIntrinsics::inferred_from`]), for re-calibrations of it.
    pub(crate) fn inferred(camera: &Camera) -> Self {
        Self::new(camera, FixedIntrinsics::inferred_from(camera))
    }

    fn len(&self) -> usize {
        self.free.len()
    }

    /// The free intrinsics' values in `camera`.
    fn pack(&self, camera: &Camera) -> impl Iterator<Item = f64> {
        let coefficients = camera.distortion.coefficients().to_vec();
        let (fx, fy, cx, cy) = (camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px);
        self.free.iter().map(move |p| match *p {
            Intrinsic::Fx | Intrinsic::Focal { .. } => fx,
            Intrinsic::Fy => fy,
            Intrinsic::Cx => cx,
            Intrinsic::Cy => cy,
            Intrinsic::Coefficient(i) => coefficients.get(i).copied().unwrap_or(0.0),
        })
    }

    /// `template` with the free intrinsics set to `values`.
    fn camera(&self, values: &[f64], template: &Camera) -> Camera {
        let mut camera = template.clone();
        for (p, &v) in self.free.iter().zip(values) {
            match *p {
                Intrinsic::Fx => camera.fx_px = v,
                Intrinsic::Fy => camera.fy_px = v,
                Intrinsic::Focal { aspect } => {
                    camera.fx_px = v;
                    camera.fy_px = aspect * v;
                }
                Intrinsic::Cx => camera.cx_px = v,
                Intrinsic::Cy => camera.cy_px = v,
                Intrinsic::Coefficient(i) => {
                    if let Some(slot) = camera.distortion.coefficients_mut().get_mut(i) {
                        *slot = v;
                    }
                }
            }
        }
        camera
    }

    /// d(pixel)/d(free intrinsics) of a corner at undistorted normalized
    /// `normalized` under `camera`: one (du, dv) per free intrinsic.
    fn jacobian(&self, camera: &Camera, normalized: &Point2<f64>) -> Vec<(f64, f64)> {
        let distorted = camera.distort(normalized);
        let d_coefficients = camera.distortion.coefficient_jacobian(normalized);
        self.free
            .iter()
            .map(|p| match *p {
                Intrinsic::Fx => (distorted.x, 0.0),
                Intrinsic::Fy => (0.0, distorted.y),
                Intrinsic::Focal { aspect } => (distorted.x, aspect * distorted.y),
                Intrinsic::Cx => (1.0, 0.0),
                Intrinsic::Cy => (0.0, 1.0),
                Intrinsic::Coefficient(i) => d_coefficients.get(i).map_or((0.0, 0.0), |d| {
                    (camera.fx_px * d.x + camera.skew_px * d.y, camera.fy_px * d.y)
                }),
            })
            .collect()
    }

    /// Standard deviations of fx, fy, cx, cy and every distortion
    /// coefficient (0 for held ones) from those of the free intrinsics.
    fn full_std_dev(&self, free_std: &[f64]) -> Vec<f64> {
        let mut std = vec![0.0; 4 + self.coefficients];
        for (p, &s) in self.free.iter().zip(free_std) {
            match *p {
                Intrinsic::Fx => std[0] = s,
                Intrinsic::Fy => std[1] = s,
                Intrinsic::Focal { aspect } => {
                    std[0] = s;
                    std[1] = aspect.abs() * s;
                }
                Intrinsic::Cx => std[2] = s,
                Intrinsic::Cy => std[3] = s,
                Intrinsic::Coefficient(i) => std[4 + i] = s,
            }
        }
        std
    }
}

/// One view's part in a camera calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewFit {
    /// The view's name.
    pub name: String,
    /// Board pose, where the view was used.
    pub camera_from_board: Option<Isometry3<f64>>,
    /// RMS reprojection error of its corners, px (under the final camera,
    /// with the view's own best pose, also for rejected views where one could
    /// be found).
    pub rms_px: Option<f64>,
    /// Why the view was not used; `None` for used views.
    pub rejected: Option<String>,
}

/// The result of [`calibrate_intrinsics`].
#[derive(Debug, Clone)]
pub struct IntrinsicsFit {
    /// The calibrated camera (`plumb_bob`, zero skew).
    pub camera: Camera,
    /// RMS reprojection error over the corners of the used views, px (as
    /// OpenCV's `calibrateCamera` reports it).
    pub rms_px: f64,
    /// Every view, in input order.
    pub views: Vec<ViewFit>,
    /// Standard deviations of fx, fy, cx, cy (px) and the distortion
    /// coefficients in OpenCV's order (0 for held ones), from sigma^2
    /// (J^T J)^-1 over the corners of one observation per board pose.
    pub std_dev: Option<Vec<f64>>,
    /// Images the views came from (a session's images of one board pose at
    /// several slide positions are one view).
    pub images: usize,
}

impl IntrinsicsFit {
    /// Number of views used.
    pub fn views_used(&self) -> usize {
        self.views.iter().filter(|v| v.rejected.is_none()).count()
    }
}

/// Calibrates a camera of `width_px` x `height_px` from board views.
pub fn calibrate_intrinsics(
    width_px: u32,
    height_px: u32,
    views: &[BoardObservation],
    options: &IntrinsicsOptions,
) -> Result<IntrinsicsFit> {
    let mut fits: Vec<ViewFit> = views
        .iter()
        .map(|v| ViewFit {
            name: v.name.clone(),
            camera_from_board: None,
            rms_px: None,
            rejected: None,
        })
        .collect();
    for (view, fit) in views.iter().zip(&mut fits) {
        if let Err(reason) = check_view(view) {
            fit.rejected = Some(reason);
        }
    }
    loop {
        let used: Vec<usize> = (0..views.len()).filter(|&i| fits[i].rejected.is_none()).collect();
        if used.len() < options.min_views {
            return Err(Error::Degenerate(format!(
                "camera calibration needs at least {} usable board views, got {}{}",
                options.min_views,
                used.len(),
                rejected_summary(&fits)
            )));
        }
        let used_views: Vec<&BoardObservation> = used.iter().map(|&i| &views[i]).collect();
        let (camera, poses) = initial_guess(width_px, height_px, &used_views, options)?;
        let layout = IntrinsicsLayout::new(&camera, options.fixed);
        let (camera, poses, std_dev) = refine(camera, poses, &used_views, &layout)?;
        let mut sum_sq = 0.0;
        let mut count = 0usize;
        let mut view_rms = Vec::with_capacity(used.len());
        for ((&i, view), pose) in used.iter().zip(&used_views).zip(&poses) {
            let (sq, n) = squared_error(&camera, pose, view);
            sum_sq += sq;
            count += n;
            let rms = (sq / n as f64).sqrt();
            fits[i].camera_from_board = Some(*pose);
            fits[i].rms_px = Some(rms);
            view_rms.push((i, rms));
        }
        let mut sorted: Vec<f64> = view_rms.iter().map(|v| v.1).collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let limit = (options.reject_factor * median).max(options.reject_floor_px);
        let worst = view_rms.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, rms)) = worst.filter(|w| w.1 > limit) {
            fits[i].rejected = Some(format!(
                "reprojection RMS {rms:.2} px is above {limit:.2} px ({} x the median view's {median:.2} px)",
                options.reject_factor
            ));
            fits[i].camera_from_board = None;
            continue;
        }
        // Rejected views: their RMS under the final camera, where a pose fits.
        for (view, fit) in views.iter().zip(&mut fits) {
            if fit.rejected.is_some()
                && check_view(view).is_ok()
                && let Ok((_, rms)) = board_pose(&camera, view)
            {
                fit.rms_px = Some(rms);
            }
        }
        return Ok(IntrinsicsFit {
            camera,
            rms_px: (sum_sq / count as f64).sqrt(),
            images: views.len(),
            views: fits,
            std_dev,
        });
    }
}

fn rejected_summary(fits: &[ViewFit]) -> String {
    let rejected = view_reasons(
        fits.iter().filter_map(|f| f.rejected.as_deref().map(|r| (f.name.as_str(), r))),
    );
    if rejected.is_empty() { String::new() } else { format!(" (rejected: {rejected})") }
}

/// Why a view cannot be used at all, if it cannot.
fn check_view(view: &BoardObservation) -> std::result::Result<(), String> {
    if view.points_in_board.len() != view.pixels.len() {
        return Err(format!(
            "{} board points but {} pixels",
            view.points_in_board.len(),
            view.pixels.len()
        ));
    }
    if view.pixels.len() < 6 {
        return Err(format!("only {} corners (need 6)", view.pixels.len()));
    }
    let finite = view.pixels.iter().all(|p| p.x.is_finite() && p.y.is_finite())
        && view.points_in_board.iter().all(|p| p.x.is_finite() && p.y.is_finite() && p.z == 0.0);
    if !finite {
        return Err("a corner is not finite or not on the board plane (z != 0)".into());
    }
    Ok(())
}

/// The homography H (board (x, y, 1) -> pixel (u, v, 1) up to scale) by the
/// normalized direct linear transform; `None` when the points are degenerate.
pub(crate) fn homography(from: &[Point2<f64>], to: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let normalizer = |points: &[Point2<f64>]| -> Option<Matrix3<f64>> {
        let n = points.len() as f64;
        let centre = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords.push(0.0)) / n;
        let spread = points.iter().map(|p| (p.coords - centre.xy()).norm()).sum::<f64>() / n;
        (spread > 0.0 && spread.is_finite()).then(|| {
            let s = std::f64::consts::SQRT_2 / spread;
            Matrix3::new(s, 0.0, -s * centre.x, 0.0, s, -s * centre.y, 0.0, 0.0, 1.0)
        })
    };
    let (t_from, t_to) = (normalizer(from)?, normalizer(to)?);
    let mut a = DMatrix::zeros(2 * from.len(), 9);
    for (k, (p, q)) in from.iter().zip(to).enumerate() {
        let p = t_from * p.to_homogeneous();
        let q = t_to * q.to_homogeneous();
        let (x, y) = (p.x / p.z, p.y / p.z);
        let (u, v) = (q.x / q.z, q.y / q.z);
        let rows = [
            [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u],
            [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v],
        ];
        for (r, row) in rows.iter().enumerate() {
            for (c, value) in row.iter().enumerate() {
                a[(2 * k + r, c)] = *value;
            }
        }
    }
    let h = smallest_right_singular_vector(a)?;
    let h_n = Matrix3::from_row_slice(h.as_slice());
    let h = t_to.try_inverse()? * h_n * t_from;
    let scale = h[(2, 2)];
    (scale.abs() > 1e-300 && h.iter().all(|v| v.is_finite())).then(|| h / scale)
}

/// The unit vector x minimizing |A x| (right singular vector of the smallest
/// singular value), from the eigen decomposition of A^T A.
fn smallest_right_singular_vector(a: DMatrix<f64>) -> Option<DVector<f64>> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let ata = a.transpose() * &a;
    let eigen = ata.symmetric_eigen();
    let (index, _) = eigen.eigenvalues.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    Some(eigen.eigenvectors.column(index).into_owned())
}

/// The camera the fit starts from, with each view's pose: the options'
/// starting camera (each pose by PnP with it), or Zhang's closed form for K
/// (zero skew) from the homographies, or OpenCV's initialisation when that
/// is not possible (each pose from its homography). In the options'
/// distortion model, with the held intrinsics at their values.
fn initial_guess(
    width_px: u32,
    height_px: u32,
    views: &[&BoardObservation],
    options: &IntrinsicsOptions,
) -> Result<(Camera, Vec<Isometry3<f64>>)> {
    let (mut camera, poses) = match &options.initial {
        Some(initial) => {
            if (initial.width_px, initial.height_px) != (width_px, height_px) {
                return Err(Error::Degenerate(format!(
                    "the starting camera is {} x {} px; the views' images are {width_px} x {height_px} px",
                    initial.width_px, initial.height_px
                )));
            }
            let k_inv = intrinsic_matrix(initial)
                .try_inverse()
                .ok_or_else(|| Error::Degenerate("the starting camera's K is singular".into()))?;
            let mut poses = Vec::with_capacity(views.len());
            for view in views {
                let pose = match board_pose(initial, view) {
                    Ok((pose, _)) => pose,
                    Err(_) => pose_from_homography(&k_inv, &view_homography(view)?),
                };
                poses.push(pose);
            }
            (initial.clone(), poses)
        }
        None => zhang_guess(width_px, height_px, views)?,
    };
    camera.distortion = camera.distortion.to_model(options.distortion);
    if options.fixed.tangential
        && let Some(tangential) = camera.distortion.coefficients_mut().get_mut(TANGENTIAL)
    {
        tangential.fill(0.0);
    }
    if options.initial.is_none() {
        if options.fixed.aspect {
            camera.fy_px = camera.fx_px;
        }
        if options.fixed.principal_point {
            (camera.cx_px, camera.cy_px) = image_centre(width_px, height_px);
        }
    }
    Ok((camera, poses))
}

/// K of `camera`.
fn intrinsic_matrix(camera: &Camera) -> Matrix3<f64> {
    Matrix3::new(
        camera.fx_px,
        camera.skew_px,
        camera.cx_px,
        0.0,
        camera.fy_px,
        camera.cy_px,
        0.0,
        0.0,
        1.0,
    )
}

/// The homography board plane -> pixels of one view.
fn view_homography(view: &BoardObservation) -> Result<Matrix3<f64>> {
    let board: Vec<Point2<f64>> = view.points_in_board.iter().map(|p| p.xy()).collect();
    homography(&board, &view.pixels).ok_or_else(|| {
        Error::Degenerate(format!("{}: the corners do not determine a homography", view.name))
    })
}

/// Zhang's closed form for K (zero skew) from the homographies, or OpenCV's
/// initialisation when that is not possible; then each view's pose.
fn zhang_guess(
    width_px: u32,
    height_px: u32,
    views: &[&BoardObservation],
) -> Result<(Camera, Vec<Isometry3<f64>>)> {
    let mut homographies = Vec::with_capacity(views.len());
    for view in views {
        homographies.push(view_homography(view)?);
    }
    // Work in pixel coordinates scaled to about unit size, for conditioning.
    let scale = f64::from(width_px.max(height_px)).max(1.0);
    let (cx0, cy0) = image_centre(width_px, height_px);
    let to_unit =
        Matrix3::new(1.0 / scale, 0.0, -cx0 / scale, 0.0, 1.0 / scale, -cy0 / scale, 0.0, 0.0, 1.0);
    let unit_h: Vec<Matrix3<f64>> = homographies.iter().map(|h| to_unit * h).collect();
    let k_unit = zhang(&unit_h).or_else(|| centred(&unit_h)).ok_or_else(|| {
        Error::Degenerate(
            "the board views do not determine the focal length (are all boards parallel to the image?)"
                .into(),
        )
    })?;
    let k = to_unit.try_inverse().unwrap_or_else(Matrix3::identity) * k_unit;
    let camera = Camera {
        name: "camera".into(),
        width_px,
        height_px,
        fx_px: k[(0, 0)],
        fy_px: k[(1, 1)],
        cx_px: k[(0, 2)],
        cy_px: k[(1, 2)],
        skew_px: 0.0,
        distortion: Distortion::PlumbBob([0.0; 5]),
    };
    let k_inv = k.try_inverse().ok_or_else(|| Error::Degenerate("singular initial K".into()))?;
    let poses = homographies.iter().map(|h| pose_from_homography(&k_inv, h)).collect();
    Ok((camera, poses))
}

/// Zhang's closed-form K (zero skew) from normalized homographies.
fn zhang(homographies: &[Matrix3<f64>]) -> Option<Matrix3<f64>> {
    let v = |h: &Matrix3<f64>, i: usize, j: usize| -> [f64; 6] {
        let (hi, hj) = (h.column(i), h.column(j));
        [
            hi[0] * hj[0],
            hi[0] * hj[1] + hi[1] * hj[0],
            hi[1] * hj[1],
            hi[2] * hj[0] + hi[0] * hj[2],
            hi[2] * hj[1] + hi[1] * hj[2],
            hi[2] * hj[2],
        ]
    };
    let mut rows: Vec<[f64; 6]> = Vec::new();
    for h in homographies {
        let (v11, v12, v22) = (v(h, 0, 0), v(h, 0, 1), v(h, 1, 1));
        rows.push(v12);
        rows.push(std::array::from_fn(|k| v11[k] - v22[k]));
    }
    rows.push([0.0, 1.0, 0.0, 0.0, 0.0, 0.0]); // zero skew: B12 = 0
    if rows.len() < 6 {
        return None;
    }
    let a = DMatrix::from_fn(rows.len(), 6, |r, c| rows[r][c]);
    let b = smallest_right_singular_vector(a)?;
    let b = if b[0] < 0.0 { -b } else { b };
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let denominator = b11 * b22 - b12 * b12;
    if b11 <= 0.0 || denominator <= 0.0 {
        return None;
    }
    let v0 = (b12 * b13 - b11 * b23) / denominator;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let (fx2, fy2) = (lambda / b11, lambda * b11 / denominator);
    if !(fx2 > 0.0 && fy2 > 0.0) {
        return None;
    }
    let (fx, fy) = (fx2.sqrt(), fy2.sqrt());
    let u0 = -b13 * fx * fx / lambda;
    let k = Matrix3::new(fx, 0.0, u0, 0.0, fy, v0, 0.0, 0.0, 1.0);
    // Refuse a principal point far outside the image (unit coordinates: the
    // image spans about [-0.5, 0.5]) or an absurd focal-length ratio.
    let plausible = u0.abs() < 0.5 && v0.abs() < 0.5 && (fx / fy) > 0.5 && (fx / fy) < 2.0;
    (plausible && k.iter().all(|x| x.is_finite())).then_some(k)
}

/// OpenCV's initialisation: principal point at the image centre (the origin
/// of the normalized coordinates), 1/fx^2 and 1/fy^2 by least squares from
/// the orthogonality and equal-norm constraints of each homography.
fn centred(homographies: &[Matrix3<f64>]) -> Option<Matrix3<f64>> {
    let (mut ata, mut atb) = (nalgebra::Matrix2::<f64>::zeros(), nalgebra::Vector2::<f64>::zeros());
    for h in homographies {
        let (h1, h2) = (h.column(0), h.column(1));
        let rows = [
            ([h1[0] * h2[0], h1[1] * h2[1]], -h1[2] * h2[2]),
            (
                [h1[0] * h1[0] - h2[0] * h2[0], h1[1] * h1[1] - h2[1] * h2[1]],
                -(h1[2] * h1[2] - h2[2] * h2[2]),
            ),
        ];
        for (a, b) in rows {
            let a = nalgebra::Vector2::new(a[0], a[1]);
            ata += a * a.transpose();
            atb += a * b;
        }
    }
    let x = ata.try_inverse()? * atb;
    (x[0] > 0.0 && x[1] > 0.0).then(|| {
        Matrix3::new(1.0 / x[0].sqrt(), 0.0, 0.0, 0.0, 1.0 / x[1].sqrt(), 0.0, 0.0, 0.0, 1.0)
    })
}

/// The board pose from K^-1 and a homography: [r1 r2 t] ~ K^-1 H, the
/// rotation made orthonormal, the board in front of the camera.
fn pose_from_homography(k_inv: &Matrix3<f64>, h: &Matrix3<f64>) -> Isometry3<f64> {
    let m = k_inv * h;
    let norm = (m.column(0).norm() + m.column(1).norm()) / 2.0;
    let sign = if m[(2, 2)] < 0.0 { -1.0 } else { 1.0 };
    let m = m * (sign / norm);
    let (r1, r2) = (m.column(0).into_owned(), m.column(1).into_owned());
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let svd = r.svd(true, true);
    let rotation = match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let mut rotation = u * v_t;
            if rotation.determinant() < 0.0 {
                rotation = -rotation;
            }
            rotation
        }
        _ => Matrix3::identity(),
    };
    let rotation = UnitQuaternion::from_matrix(&rotation);
    Isometry3::from_parts(Translation3::from(m.column(2).into_owned()), rotation)
}

/// Sum of squared reprojection errors (px^2) of a view, and its corner count.
fn squared_error(camera: &Camera, pose: &Isometry3<f64>, view: &BoardObservation) -> (f64, usize) {
    let mut sum = 0.0;
    for (point, pixel) in view.points_in_board.iter().zip(&view.pixels) {
        sum += match camera.project(&(pose * point)) {
            Ok(projected) => (projected - pixel).norm_squared(),
            Err(_) => BEHIND_CAMERA_PX * BEHIND_CAMERA_PX,
        };
    }
    (sum, view.pixels.len())
}

/// Residual given to a corner that a trial step puts behind the camera: large
/// and finite, so Levenberg-Marquardt rejects the step.
const BEHIND_CAMERA_PX: f64 = 1e6;

/// Reprojection error of every corner of every view, over the free
/// intrinsics of `layout` (none: the camera fixed, PnP) and the poses.
struct Reprojection<'a> {
    views: &'a [&'a BoardObservation],
    /// The fitted intrinsics; `None` when the camera is fixed (PnP).
    layout: Option<&'a IntrinsicsLayout>,
    /// The camera with the held intrinsics (all of them without a layout).
    template: Camera,
    params: DVector<f64>,
}

impl Reprojection<'_> {
    fn n_intrinsics(&self) -> usize {
        self.layout.map_or(0, IntrinsicsLayout::len)
    }

    fn camera(&self) -> Camera {
        match self.layout {
            Some(layout) => layout.camera(&self.params.as_slice()[..layout.len()], &self.template),
            None => self.template.clone(),
        }
    }

    fn rotation_vector(&self, view: usize) -> Vector3<f64> {
        let at = self.n_intrinsics() + 6 * view;
        Vector3::new(self.params[at], self.params[at + 1], self.params[at + 2])
    }

    fn pose(&self, view: usize) -> Isometry3<f64> {
        let at = self.n_intrinsics() + 6 * view;
        let t = Vector3::new(self.params[at + 3], self.params[at + 4], self.params[at + 5]);
        Isometry3::from_parts(
            Translation3::from(t),
            UnitQuaternion::from_scaled_axis(self.rotation_vector(view)),
        )
    }

    /// The parameter vector: `layout`'s intrinsics of `camera` (none
    /// without a layout), then each pose.
    fn pack(
        layout: Option<&IntrinsicsLayout>,
        camera: &Camera,
        poses: &[Isometry3<f64>],
    ) -> DVector<f64> {
        let mut params = Vec::with_capacity(layout.map_or(0, |l| l.len()) + 6 * poses.len());
        if let Some(layout) = layout {
            params.extend(layout.pack(camera));
        }
        for pose in poses {
            params.extend(pose.rotation.scaled_axis().iter());
            params.extend(pose.translation.vector.iter());
        }
        DVector::from_vec(params)
    }

    fn n_residuals(&self) -> usize {
        2 * self.views.iter().map(|v| v.pixels.len()).sum::<usize>()
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Reprojection<'_> {
    dynamic_problem_params!();

    fn residuals(&self) -> Option<DVector<f64>> {
        let camera = self.camera();
        let mut residuals = DVector::zeros(self.n_residuals());
        let mut row = 0;
        for (v, view) in self.views.iter().enumerate() {
            let pose = self.pose(v);
            for (point, pixel) in view.points_in_board.iter().zip(&view.pixels) {
                let (du, dv) = match camera.project(&(pose * point)) {
                    Ok(p) => (p.x - pixel.x, p.y - pixel.y),
                    Err(_) => (BEHIND_CAMERA_PX, BEHIND_CAMERA_PX),
                };
                residuals[row] = du;
                residuals[row + 1] = dv;
                row += 2;
            }
        }
        residuals.iter().all(|r| r.is_finite()).then_some(residuals)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let camera = self.camera();
        let n_k = self.n_intrinsics();
        let mut jacobian = DMatrix::zeros(self.n_residuals(), self.params.len());
        let mut row = 0;
        for (v, view) in self.views.iter().enumerate() {
            let pose = self.pose(v);
            let left = so3_left_jacobian(&self.rotation_vector(v));
            let col = n_k + 6 * v;
            for point in &view.points_in_board {
                let rotated = pose.rotation * point.coords;
                let in_camera = Point3::from(rotated + pose.translation.vector);
                let Ok(d_pixel_d_point) = camera.project_jacobian(&in_camera) else {
                    row += 2;
                    continue;
                };
                // d(R(w) X)/dw = -[R X]x J_l(w); d/dt = I.
                let d_rotation = -d_pixel_d_point * rotated.cross_matrix() * left;
                for r in 0..2 {
                    for c in 0..3 {
                        jacobian[(row + r, col + c)] = d_rotation[(r, c)];
                        jacobian[(row + r, col + 3 + c)] = d_pixel_d_point[(r, c)];
                    }
                }
                if let Some(layout) = self.layout {
                    let normalized =
                        Point2::new(in_camera.x / in_camera.z, in_camera.y / in_camera.z);
                    for (k, (du, dv)) in
                        layout.jacobian(&camera, &normalized).into_iter().enumerate()
                    {
                        jacobian[(row, k)] = du;
                        jacobian[(row + 1, k)] = dv;
                    }
                }
                row += 2;
            }
        }
        Some(jacobian)
    }
}

/// The left Jacobian of SO(3) at rotation vector w:
/// I + (1 - cos t)/t^2 [w]x + (t - sin t)/t^3 [w]x^2, t = |w|.
fn so3_left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let (a, b) = if theta2 < 1e-8 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = theta2.sqrt();
        ((1.0 - theta.cos()) / theta2, (theta - theta.sin()) / (theta2 * theta))
    };
    let wx = w.cross_matrix();
    Matrix3::identity() + wx * a + wx * wx * b
}

/// A refined camera, its board poses and its intrinsics' standard deviations.
type Refined = (Camera, Vec<Isometry3<f64>>, Option<Vec<f64>>);

/// Runs Levenberg-Marquardt over the free intrinsics of `layout` and the
/// poses, from `camera` (which holds the held intrinsics).
fn refine(
    camera: Camera,
    poses: Vec<Isometry3<f64>>,
    views: &[&BoardObservation],
    layout: &IntrinsicsLayout,
) -> Result<Refined> {
    let problem = Reprojection {
        views,
        layout: Some(layout),
        params: Reprojection::pack(Some(layout), &camera, &poses),
        template: camera,
    };
    let (problem, report) = LevenbergMarquardt::new().with_patience(200).minimize(problem);
    if !report.termination.was_successful() && report.objective_function.is_nan() {
        return Err(Error::FitFailed(format!("camera calibration: {:?}", report.termination)));
    }
    let camera = problem.camera();
    camera.validate().map_err(|e| {
        Error::FitFailed(format!("camera calibration ended at an unusable camera: {e}"))
    })?;
    let poses: Vec<Isometry3<f64>> = (0..views.len()).map(|v| problem.pose(v)).collect();
    let std_dev = intrinsics_std_dev(&problem);
    Ok((camera, poses, std_dev))
}

/// Standard deviations of a given `camera`'s intrinsics on `views` (one
/// observation per board pose): each view's pose by PnP with the camera,
/// then sigma^2 (J^T J)^-1 of the reprojection problem over the intrinsics
/// the camera shows were fitted ([`FixedIntrinsics::inferred_from`]) and
/// the poses, at the camera. In the order of [`IntrinsicsFit::std_dev`]: fx,
/// fy, cx, cy, then the distortion coefficients (0 for held ones). `None`
/// with fewer than 3 poses or a singular problem. What a report needs for a
/// camera read from a file, whose own calibration's are not at hand.
pub fn intrinsics_std_dev_at(camera: &Camera, views: &[&BoardObservation]) -> Option<Vec<f64>> {
    let posed: Vec<(&BoardObservation, Isometry3<f64>)> = views
        .iter()
        .filter_map(|view| board_pose(camera, view).ok().map(|(pose, _)| (*view, pose)))
        .collect();
    if posed.len() < 3 {
        return None;
    }
    let views: Vec<&BoardObservation> = posed.iter().map(|(view, _)| *view).collect();
    let poses: Vec<Isometry3<f64>> = posed.iter().map(|(_, pose)| *pose).collect();
    let layout = IntrinsicsLayout::inferred(camera);
    let problem = Reprojection {
        views: &views,
        layout: Some(&layout),
        params: Reprojection::pack(Some(&layout), camera, &poses),
        template: camera.clone(),
    };
    intrinsics_std_dev(&problem)
}

/// A camera calibration linearized at its optimum, for a bootstrap over its
/// board poses: per pose, its part of the normal equations over the
/// intrinsics and its own pose. A replicate (each pose counted as often as
/// it was drawn) is one Gauss-Newton step from the optimum on the
/// reweighted problem: the first-order bootstrap of a least-squares fit,
/// exact to the step's second-order terms, which at reprojection errors of
/// a tenth of a pixel are far below its spread, and a thousand times
/// cheaper than a Levenberg-Marquardt run per replicate.
pub(crate) struct CameraLinearization {
    params: DVector<f64>,
    template: Camera,
    layout: IntrinsicsLayout,
    /// Per pose: J_g^T J_g and J_g^T r_g over (intrinsics, the pose's six).
    blocks: Vec<(DMatrix<f64>, DVector<f64>)>,
}

impl CameraLinearization {
    /// Refines `camera` and `poses` on `views` (Levenberg-Marquardt, over
    /// the intrinsics `camera` shows were fitted: [`FixedIntrinsics::inferred_from`])
    /// and linearizes the problem there.
    pub(crate) fn new(
        camera: Camera,
        poses: Vec<Isometry3<f64>>,
        views: &[&BoardObservation],
    ) -> Result<CameraLinearization> {
        let layout = IntrinsicsLayout::inferred(&camera);
        let (camera, poses, _) = refine(camera, poses, views, &layout)?;
        let n_intrinsics = layout.len();
        let problem = Reprojection {
            views,
            layout: Some(&layout),
            params: Reprojection::pack(Some(&layout), &camera, &poses),
            template: camera,
        };
        let failed = || Error::FitFailed("camera calibration: no Jacobian at the optimum".into());
        let jacobian = problem.jacobian().ok_or_else(failed)?;
        let residuals = problem.residuals().ok_or_else(failed)?;
        let mut blocks = Vec::with_capacity(views.len());
        let mut row = 0;
        for (v, view) in views.iter().enumerate() {
            let rows = 2 * view.pixels.len();
            let columns: Vec<usize> =
                (0..n_intrinsics).chain(n_intrinsics + 6 * v..n_intrinsics + 6 * v + 6).collect();
            let j = DMatrix::from_fn(rows, columns.len(), |r, c| jacobian[(row + r, columns[c])]);
            let r = residuals.rows(row, rows).into_owned();
            blocks.push((j.transpose() * &j, j.transpose() * r));
            row += rows;
        }
        let (params, template) = (problem.params, problem.template);
        Ok(CameraLinearization { params, template, layout, blocks })
    }

    /// The camera and every pose of the replicate that counts pose `g`
    /// `counts[g]` times (a pose drawn no times keeps its pose).
    pub(crate) fn replicate(&self, counts: &[usize]) -> Option<(Camera, Vec<Isometry3<f64>>)> {
        let drawn: Vec<usize> = (0..self.blocks.len()).filter(|&g| counts[g] > 0).collect();
        let n_intrinsics = self.layout.len();
        let n = n_intrinsics + 6 * drawn.len();
        let mut normal = DMatrix::<f64>::zeros(n, n);
        let mut gradient = DVector::<f64>::zeros(n);
        for (k, &g) in drawn.iter().enumerate() {
            let weight = counts[g] as f64;
            let (jtj, jtr) = &self.blocks[g];
            let index = |c: usize| {
                if c < n_intrinsics { c } else { n_intrinsics + 6 * k + c - n_intrinsics }
            };
            for a in 0..jtj.nrows() {
                gradient[index(a)] += weight * jtr[a];
                for b in 0..jtj.ncols() {
                    normal[(index(a), index(b))] += weight * jtj[(a, b)];
                }
            }
        }
        let step = normal.cholesky()?.solve(&gradient);
        let mut params = self.params.clone();
        for i in 0..n_intrinsics {
            params[i] -= step[i];
        }
        for (k, &g) in drawn.iter().enumerate() {
            for i in 0..6 {
                params[n_intrinsics + 6 * g + i] -= step[n_intrinsics + 6 * k + i];
            }
        }
        let views: [&BoardObservation; 0] = [];
        let problem = Reprojection {
            views: &views,
            layout: Some(&self.layout),
            params,
            template: self.template.clone(),
        };
        let camera = problem.camera();
        camera.validate().ok()?;
        Some((camera, (0..self.blocks.len()).map(|g| problem.pose(g)).collect()))
    }
}

/// sigma^2 (J^T J)^-1 for the intrinsics, sigma^2 = SSE / (m - n): of fx,
/// fy, cx, cy and every distortion coefficient (0 for held ones).
fn intrinsics_std_dev(problem: &Reprojection<'_>) -> Option<Vec<f64>> {
    let layout = problem.layout?;
    let jacobian = problem.jacobian()?;
    let residuals = problem.residuals()?;
    let (m, n) = jacobian.shape();
    if m <= n {
        return None;
    }
    let sigma2 = residuals.norm_squared() / (m - n) as f64;
    let covariance = (jacobian.transpose() * &jacobian).try_inverse()?;
    let free: Vec<f64> = (0..layout.len()).map(|i| (sigma2 * covariance[(i, i)]).sqrt()).collect();
    free.iter().all(|s| s.is_finite()).then(|| layout.full_std_dev(&free))
}

/// The pose of a board seen by a calibrated camera (PnP): a homography on
/// undistorted normalized corners, then Levenberg-Marquardt on the
/// reprojection error. Returns the pose and the RMS reprojection error (px).
pub fn board_pose(camera: &Camera, view: &BoardObservation) -> Result<(Isometry3<f64>, f64)> {
    check_view(view).map_err(|reason| Error::Degenerate(format!("{}: {reason}", view.name)))?;
    let mut normalized = Vec::with_capacity(view.pixels.len());
    for pixel in &view.pixels {
        let n = camera.undistort_pixel(pixel).map_err(|e| {
            Error::Degenerate(format!(
                "{}: corner ({:.1}, {:.1}): {e}",
                view.name, pixel.x, pixel.y
            ))
        })?;
        normalized.push(n);
    }
    let board: Vec<Point2<f64>> = view.points_in_board.iter().map(|p| p.xy()).collect();
    let h = homography(&board, &normalized).ok_or_else(|| {
        Error::Degenerate(format!("{}: the corners do not determine a homography", view.name))
    })?;
    let initial = pose_from_homography(&Matrix3::identity(), &h);
    let views = [view];
    let problem = Reprojection {
        views: &views,
        layout: None,
        params: Reprojection::pack(None, camera, &[initial]),
        template: camera.clone(),
    };
    let (problem, _) = LevenbergMarquardt::new().with_patience(100).minimize(problem);
    let pose = problem.pose(0);
    let (sq, n) = squared_error(camera, &pose, view);
    let rms = (sq / n as f64).sqrt();
    if !rms.is_finite() || rms >= BEHIND_CAMERA_PX {
        return Err(Error::FitFailed(format!("{}: no board pose fits the corners", view.name)));
    }
    Ok((pose, rms))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn board_view(camera: &Camera, pose: &Isometry3<f64>) -> BoardObservation {
        let mut view =
            BoardObservation { name: "v".into(), points_in_board: vec![], pixels: vec![] };
        for r in 0..8 {
            for c in 0..11 {
                let p = Point3::new(c as f64 * 30.0, r as f64 * 30.0, 0.0);
                view.pixels.push(camera.project(&(pose * p)).unwrap());
                view.points_in_board.push(p);
            }
        }
        view
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let rational = Camera {
            distortion: Distortion::RationalPolynomial([
                -0.08, 0.12, 1e-4, -1e-4, 0.01, 0.02, -0.01, 0.003,
            ]),
            fy_px: 2330.0,
            ..Camera::blackfly_s_5mp()
        };
        for (camera, aspect) in [(Camera::blackfly_s_5mp(), false), (rational, true)] {
            jacobian_matches_finite_differences_for(camera, aspect);
        }
    }

    fn jacobian_matches_finite_differences_for(camera: Camera, aspect: bool) {
        let pose =
            Isometry3::new(Vector3::new(-150.0, -100.0, 800.0), Vector3::new(0.3, -0.4, 0.2));
        let view = board_view(&camera, &pose);
        let views = [&view];
        let fixed = FixedIntrinsics { aspect, ..FixedIntrinsics::default() };
        let layout = IntrinsicsLayout::new(&camera, fixed);
        let mut problem = Reprojection {
            views: &views,
            layout: Some(&layout),
            params: Reprojection::pack(Some(&layout), &camera, &[pose]),
            template: camera.clone(),
        };
        let analytic = problem.jacobian().unwrap();
        let params = problem.params();
        for j in 0..params.len() {
            let h = 1e-6 * params[j].abs().max(1.0);
            let mut plus = params.clone();
            plus[j] += h;
            problem.set_params(&plus);
            let r_plus = problem.residuals().unwrap();
            let mut minus = params.clone();
            minus[j] -= h;
            problem.set_params(&minus);
            let r_minus = problem.residuals().unwrap();
            let numeric = (r_plus - r_minus) / (2.0 * h);
            let error = (numeric - analytic.column(j)).amax();
            let scale = analytic.column(j).amax().max(1.0);
            assert!(error / scale < 1e-5, "parameter {j}: {error} (scale {scale})");
        }
        problem.set_params(&params);
    }
}
