//! The project's one camera type: a pinhole camera K with OpenCV lens
//! distortion w, the seed paper's eqs. (1)-(3).
//!
//! ```text
//! p_bar = (X/Z, Y/Z)        eq. (1), undistorted normalized coordinates
//! m     = w(K p_bar)        eq. (2), projection with lens distortion w
//! p_bar = K^-1 w^-1(m)      eq. (3), undistortion
//! ```
//!
//! As in OpenCV, w acts on normalized coordinates, so in code eq. (2) is
//! `m = K w(p_bar)` ([`Camera::distort`], then the intrinsic matrix) and
//! eq. (3) is `p_bar = w^-1(K^-1 m)`, with w inverted by Newton's method
//! ([`Camera::undistort_pixel`]).

mod distortion;
mod yaml;

use nalgebra::{Matrix2, Matrix2x3, Point2, Point3, Vector2, Vector3};

use crate::{Error, Num, Result};

pub use distortion::{Distortion, DistortionModel};
pub use yaml::CameraFileFormat;

/// A pinhole camera with OpenCV lens distortion; pixels (u, v) = (column,
/// row) with (0, 0) the centre of the top-left pixel.
///
/// # Example
/// ```
/// use alacs_model::Camera;
/// use nalgebra::Point3;
///
/// let camera = Camera::blackfly_s_5mp();
/// let point_in_camera = Point3::new(100.0, -50.0, 800.0);
/// let pixel = camera.project(&point_in_camera)?; // eqs. (1)-(2)
/// let ray = camera.pixel_ray(&pixel)?; // eq. (3): (u_n, v_n, 1)
/// assert!((ray * 800.0 - point_in_camera.coords).norm() < 1e-9);
/// # Ok::<(), alacs_model::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// `camera_name` of camera.yaml.
    pub name: String,
    /// Image width in pixels.
    pub width_px: u32,
    /// Image height in pixels.
    pub height_px: u32,
    /// Focal length along u (`camera_matrix[0][0]`).
    pub fx_px: f64,
    /// Focal length along v (`camera_matrix[1][1]`).
    pub fy_px: f64,
    /// Principal point, column (`camera_matrix[0][2]`).
    pub cx_px: f64,
    /// Principal point, row (`camera_matrix[1][2]`).
    pub cy_px: f64,
    /// Skew (`camera_matrix[0][1]`), usually 0.
    pub skew_px: f64,
    /// Lens distortion, applied to normalized coordinates.
    pub distortion: Distortion,
}

/// Most Newton iterations [`Camera::undistort_pixel`] spends; it converges
/// quadratically, in under 10 iterations even at the corners of a strongly
/// distorted image, so this only bounds the work on a pixel beyond a fold.
const UNDISTORT_MAX_ITERATIONS: usize = 100;

/// The largest |coefficient| of a distortion model accepted. Real lenses,
/// even wide-angle ones under OpenCV's rational model, stay within tens;
/// 1e4 leaves room for any of them and refuses unit or typing errors (1e10).
pub const MAX_ABS_DISTORTION: f64 = 1e4;

/// The longest focal length accepted, in image sides: 100 sides is a field
/// of view of 0.57 deg, narrower than any lens a fruit scanner uses (the
/// seed's 8 mm lens on a 2/3" sensor: about 0.95 sides).
pub const MAX_FOCAL_SIDES: f64 = 100.0;

/// The largest image side accepted, px: beyond any machine-vision sensor
/// (the seed's is 2448 px), and a bound on the memory a camera.yaml can ask
/// a simulated render or a ray map for.
pub const MAX_IMAGE_SIDE_PX: u32 = 20_000;

/// Newton stops once the forward residual |w(p_bar) - m_n| falls below this
/// (times max(1, |m_n|)): a few units in the last place of f64.
const UNDISTORT_TARGET_RESIDUAL: f64 = 1e-15;

/// Largest forward residual, in normalized units, that is still accepted
/// when Newton stalls on rounding: 1e-12 is about 2e-9 px at f = 2320 px,
/// far below any pixel measurement.
const UNDISTORT_ACCEPT_RESIDUAL: f64 = 1e-12;

/// Step halvings tried before a Newton step counts as stalled: 2^-40 of a
/// Newton step is below rounding at normalized scale.
const UNDISTORT_MAX_HALVINGS: usize = 40;

impl Camera {
    /// Like a FLIR Blackfly S 5 MP (Sony IMX250): 2448 x 2048 px, f = 2320 px
    /// (a 8 mm lens on 3.45 um pixels), principal point at the image centre,
    /// mild `plumb_bob` barrel distortion. The simulator's default camera.
    pub fn blackfly_s_5mp() -> Camera {
        let (width_px, height_px) = (2448, 2048);
        Camera {
            name: "blackfly_s_5mp".to_string(),
            width_px,
            height_px,
            fx_px: 2320.0,
            fy_px: 2320.0,
            cx_px: (f64::from(width_px) - 1.0) / 2.0,
            cy_px: (f64::from(height_px) - 1.0) / 2.0,
            skew_px: 0.0,
            distortion: Distortion::PlumbBob([-0.08, 0.12, 1e-4, -1e-4, 0.0]),
        }
    }

    /// Checks that the parameters describe a usable camera. Refuses, naming the value: a zero or absurd image size, non-finite
    /// or non-positive focal lengths, and distortion coefficients that are
    /// not finite or beyond [`MAX_ABS_DISTORTION`].
    pub fn validate(&self) -> Result<()> {
        let invalid = |message: String| Err(Error::InvalidParameters { what: "camera", message });
        if self.width_px == 0 || self.height_px == 0 {
            return invalid(format!(
                "image size must be positive, got {} x {} px",
                self.width_px, self.height_px
            ));
        }
        let intrinsics = [
            ("fx_px", self.fx_px),
            ("fy_px", self.fy_px),
            ("cx_px", self.cx_px),
            ("cy_px", self.cy_px),
            ("skew_px", self.skew_px),
        ];
        if let Some((name, value)) = intrinsics.iter().find(|(_, value)| !value.is_finite()) {
            return invalid(format!("{name} must be finite, got {}", Num(*value)));
        }
        if !(self.fx_px > 0.0 && self.fy_px > 0.0) {
            return invalid(format!(
                "focal lengths must be positive, got fx {} px, fy {} px",
                self.fx_px, self.fy_px
            ));
        }
        if !self.distortion.is_finite() {
            return invalid(format!(
                "distortion coefficients must be finite, got {:?}",
                self.distortion.coefficients()
            ));
        }
        if let Some(k) =
            self.distortion.coefficients().iter().find(|k| k.abs() > MAX_ABS_DISTORTION)
        {
            return invalid(format!(
                "distortion coefficient {k:e} is beyond +-{MAX_ABS_DISTORTION:e}: no lens has it (a unit or typing error)"
            ));
        }
        let side = f64::from(self.width_px.max(self.height_px));
        if self.fx_px.max(self.fy_px) > MAX_FOCAL_SIDES * side {
            return invalid(format!(
                "focal length fx {} px, fy {} px is more than {MAX_FOCAL_SIDES} image sides ({side} px): a field of view under 0.6 deg (a unit or typing error)",
                Num(self.fx_px),
                Num(self.fy_px)
            ));
        }
        let (w, h) = (f64::from(self.width_px), f64::from(self.height_px));
        if !((-w..=2.0 * w).contains(&self.cx_px) && (-h..=2.0 * h).contains(&self.cy_px)) {
            return invalid(format!(
                "principal point ({}, {}) px lies more than an image size outside the {} x {} px image",
                Num(self.cx_px),
                Num(self.cy_px),
                self.width_px,
                self.height_px
            ));
        }
        if self.skew_px.abs() > self.fx_px {
            return invalid(format!(
                "skew {} px exceeds fx {} px (pixels skewed by more than 45 deg)",
                Num(self.skew_px),
                Num(self.fx_px)
            ));
        }
        let max_size_px = MAX_IMAGE_SIDE_PX;
        if self.width_px > max_size_px || self.height_px > max_size_px {
            return invalid(format!(
                "image size {} x {} px is beyond {max_size_px} px a side",
                self.width_px, self.height_px
            ));
        }
        Ok(())
    }

    /// A copy for the image resized by `scale` (0.5 halves each side): focal
    /// lengths and skew scale by `scale`, the principal point with the
    /// pixel-centre convention `c' = (c + 0.5) scale - 0.5`, and the image size
    /// is rounded to whole pixels. Distortion acts on normalized coordinates
    /// and is unchanged. A `scale` that is not positive and finite gives a
    /// camera that fails [`Camera::validate`].
    pub fn scaled(&self, scale: f64) -> Camera {
        // `as` saturates (and maps NaN to 0), which validate() then rejects.
        let scale_size = |size: u32| (f64::from(size) * scale).round() as u32;
        Camera {
            name: self.name.clone(),
            width_px: scale_size(self.width_px),
            height_px: scale_size(self.height_px),
            fx_px: self.fx_px * scale,
            fy_px: self.fy_px * scale,
            cx_px: (self.cx_px + 0.5) * scale - 0.5,
            cy_px: (self.cy_px + 0.5) * scale - 0.5,
            skew_px: self.skew_px * scale,
            distortion: self.distortion,
        }
    }

    /// Projects a point in the camera frame (mm) to a pixel: eq. (1)
    /// p_bar = (X/Z, Y/Z), then eq. (2) m = K w(p_bar).
    ///
    /// Fails with [`Error::NotProjectable`] for a point that is not finite or
    /// not in front of the camera (z <= 0). The distortion is evaluated as
    /// OpenCV does wherever it is defined; whether the point lies inside the
    /// region where it is one-to-one is [`Camera::is_distortion_invertible_at`].
    pub fn project(&self, point_in_camera: &Point3<f64>) -> Result<Point2<f64>> {
        let normalized = normalize(point_in_camera)?;
        Ok(self.normalized_to_pixel(&normalized))
    }

    /// The 2x3 Jacobian of [`Camera::project`] with respect to the point (px/mm).
    pub fn project_jacobian(&self, point_in_camera: &Point3<f64>) -> Result<Matrix2x3<f64>> {
        let normalized = normalize(point_in_camera)?;
        let (x, y, z) = (point_in_camera.x, point_in_camera.y, point_in_camera.z);
        let normalized_from_point =
            Matrix2x3::new(1.0 / z, 0.0, -x / (z * z), 0.0, 1.0 / z, -y / (z * z));
        Ok(self.pixel_from_normalized_jacobian(&normalized) * normalized_from_point)
    }

    /// Lens distortion w of eq. (2): undistorted normalized coordinates (x/z,
    /// y/z) -> distorted normalized coordinates, with OpenCV's formulas.
    pub fn distort(&self, normalized: &Point2<f64>) -> Point2<f64> {
        self.distortion.unpack().distort(normalized)
    }

    /// The 2x2 Jacobian of [`Camera::distort`].
    pub fn distort_jacobian(&self, normalized: &Point2<f64>) -> Matrix2<f64> {
        self.distortion.unpack().distort_jacobian(normalized)
    }

    /// Eq. (2) from normalized coordinates: undistorted normalized -> pixel,
    /// w then K.
    pub fn normalized_to_pixel(&self, normalized: &Point2<f64>) -> Point2<f64> {
        let distorted = self.distort(normalized);
        Point2::new(
            self.fx_px * distorted.x + self.skew_px * distorted.y + self.cx_px,
            self.fy_px * distorted.y + self.cy_px,
        )
    }

    /// Eq. (3), p_bar = K^-1 w^-1(m): pixel -> undistorted normalized
    /// coordinates (x/z, y/z).
    ///
    /// w is inverted by Newton's method on the 2x2 system w(p_bar) = K^-1 m
    /// with the analytic Jacobian, starting from the distorted point, halving
    /// a step while it would not reduce the residual or would cross a fold of
    /// the model. It converges to a forward residual of about 1e-15 in
    /// normalized units everywhere the model is one-to-one, including the
    /// corners of strongly distorted images where OpenCV's fixed-point
    /// iteration diverges.
    ///
    /// Fails with [`Error::UndistortNotConverged`] for a non-finite pixel, a
    /// pixel that no undistorted point maps to (beyond the fold of a
    /// distortion that turns back on itself), or a solution outside the
    /// region where the model is one-to-one; never returns NaN.
    pub fn undistort_pixel(&self, pixel: &Point2<f64>) -> Result<Point2<f64>> {
        let not_converged = |residual: f64, iterations: usize| Error::UndistortNotConverged {
            u_px: pixel.x,
            v_px: pixel.y,
            residual,
            iterations,
        };
        let distorted = self.pixel_to_distorted_normalized(pixel);
        if !(distorted.x.is_finite() && distorted.y.is_finite()) {
            return Err(not_converged(f64::NAN, 0));
        }
        let coefficients = self.distortion.unpack();
        let target = UNDISTORT_TARGET_RESIDUAL * distorted.coords.norm().max(1.0);
        let residual_at = |normalized: &Point2<f64>| coefficients.distort(normalized) - distorted;

        let mut normalized = distorted;
        let mut residual = residual_at(&normalized);
        let mut residual_norm = residual.norm();
        let mut iterations = 0;
        while residual_norm > target && iterations < UNDISTORT_MAX_ITERATIONS {
            iterations += 1;
            let jacobian = coefficients.distort_jacobian(&normalized);
            let Some(step) = newton_step(&jacobian, &residual) else { break };
            let mut accepted = None;
            let mut fraction = 1.0;
            for _ in 0..=UNDISTORT_MAX_HALVINGS {
                let trial = normalized + step * fraction;
                let trial_residual = residual_at(&trial);
                let trial_norm = trial_residual.norm();
                // Stay on the centre's side of any fold: a step onto a region
                // where w reverses orientation would find a spurious root.
                if trial_norm < residual_norm
                    && coefficients.distort_jacobian(&trial).determinant() > 0.0
                {
                    accepted = Some((trial, trial_residual, trial_norm));
                    break;
                }
                fraction *= 0.5;
            }
            let Some((trial, trial_residual, trial_norm)) = accepted else { break };
            normalized = trial;
            residual = trial_residual;
            residual_norm = trial_norm;
        }
        // A NaN residual fails this comparison too.
        let converged = residual_norm <= UNDISTORT_ACCEPT_RESIDUAL;
        if !converged || !coefficients.is_invertible_at(&normalized) {
            return Err(not_converged(residual_norm, iterations));
        }
        Ok(normalized)
    }

    /// The 2x2 Jacobian of [`Camera::undistort_pixel`] with respect to the
    /// pixel: the inverse of the forward Jacobian of
    /// [`Camera::normalized_to_pixel`] at the solution.
    pub fn undistort_jacobian(&self, pixel: &Point2<f64>) -> Result<Matrix2<f64>> {
        let normalized = self.undistort_pixel(pixel)?;
        let forward = self.pixel_from_normalized_jacobian(&normalized);
        // undistort_pixel only returns points where det(w') > 0 and fx, fy
        // are nonzero for a valid camera; a singular K is reported as such.
        forward.try_inverse().ok_or_else(|| Error::InvalidParameters {
            what: "camera",
            message: format!(
                "intrinsic matrix is singular (fx {} px, fy {} px)",
                self.fx_px, self.fy_px
            ),
        })
    }

    /// The unit-free ray direction (u_n, v_n, 1) through a pixel: every point
    /// `z * direction`, z > 0, projects onto the pixel.
    pub fn pixel_ray(&self, pixel: &Point2<f64>) -> Result<Vector3<f64>> {
        let normalized = self.undistort_pixel(pixel)?;
        Ok(Vector3::new(normalized.x, normalized.y, 1.0))
    }

    /// Whether a pixel lies inside the image: -0.5 <= u <= width - 0.5 and
    /// -0.5 <= v <= height - 0.5 (pixel centres at integers). False for NaN.
    pub fn contains_pixel(&self, pixel: &Point2<f64>) -> bool {
        let inside = |value: f64, size: u32| (-0.5..=f64::from(size) - 0.5).contains(&value);
        inside(pixel.x, self.width_px) && inside(pixel.y, self.height_px)
    }

    /// Whether the distortion is one-to-one around the undistorted normalized
    /// point: its radial profile has not folded over between the image centre
    /// and the point, and the Jacobian of w has a positive determinant there.
    /// Points beyond a fold (far off-axis with strong barrel distortion)
    /// still project with OpenCV's formulas, but onto pixels that belong to
    /// other points; a simulator should treat them as not visible.
    pub fn is_distortion_invertible_at(&self, normalized: &Point2<f64>) -> bool {
        self.distortion.unpack().is_invertible_at(normalized)
    }

    /// K^-1 m without undoing the distortion: distorted normalized coordinates.
    fn pixel_to_distorted_normalized(&self, pixel: &Point2<f64>) -> Point2<f64> {
        let y = (pixel.y - self.cy_px) / self.fy_px;
        let x = (pixel.x - self.cx_px - self.skew_px * y) / self.fx_px;
        Point2::new(x, y)
    }

    /// Jacobian of [`Camera::normalized_to_pixel`]: K's upper 2x2 times w'.
    fn pixel_from_normalized_jacobian(&self, normalized: &Point2<f64>) -> Matrix2<f64> {
        let intrinsic = Matrix2::new(self.fx_px, self.skew_px, 0.0, self.fy_px);
        intrinsic * self.distort_jacobian(normalized)
    }
}

/// Eq. (1): p_bar = (X/Z, Y/Z) for a finite point in front of the camera.
fn normalize(point: &Point3<f64>) -> Result<Point2<f64>> {
    let not_projectable =
        |reason| Error::NotProjectable { x_mm: point.x, y_mm: point.y, z_mm: point.z, reason };
    if !point.iter().all(|c| c.is_finite()) {
        return Err(not_projectable("not finite"));
    }
    if point.z <= 0.0 {
        return Err(not_projectable("not in front of the camera (z <= 0)"));
    }
    Ok(Point2::new(point.x / point.z, point.y / point.z))
}

/// The Newton step `-J^-1 r` of a 2x2 system, or `None` where J is singular
/// or reverses orientation (det <= 0: the model has folded over).
fn newton_step(jacobian: &Matrix2<f64>, residual: &Vector2<f64>) -> Option<Vector2<f64>> {
    let determinant = jacobian.determinant();
    if !(determinant > 0.0 && determinant.is_finite()) {
        return None;
    }
    let step = -Vector2::new(
        jacobian[(1, 1)] * residual.x - jacobian[(0, 1)] * residual.y,
        -jacobian[(1, 0)] * residual.x + jacobian[(0, 0)] * residual.y,
    ) / determinant;
    step.iter().all(|s| s.is_finite()).then_some(step)
}
