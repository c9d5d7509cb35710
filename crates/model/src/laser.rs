//! The ALACS laser-triangulation model of the seed paper: the high-fidelity
//! model, eqs. (7)-(8), and its low-fidelity special case beta = 0, eq. (10).
//!
//! For normalized, undistorted coordinates (u_n, v_n) of a laser pixel and
//! slide travel d:
//!
//! ```text
//! D = sin(alpha) - u_n cos(alpha) - v_n tan(beta)
//! z = L / D,  x = u_n z,  y = v_n z,  L = L0 - k d
//! ```
//!
//! Equivalently the laser is the plane `-cos(alpha) x - tan(beta) y +
//! sin(alpha) z = L` in the camera frame, with the laser's origin at
//! `(-L cos(alpha), 0, L sin(alpha))`, eq. (4).
//!
//! # The slide's own error: k
//!
//! The seed paper takes the slide as perfect, L = L0 - d. A real slide moves
//! the laser by k d for a commanded d: a lead screw's pitch error, a belt's
//! stretch or a steps-per-mm setting make k a little off 1. A slide axis at
//! an angle to the baseline does the same and nothing more that the stripe
//! can show: moving the laser by d along an axis `a` (its length the travel
//! per commanded mm) shifts its plane, whose orientation a translation does
//! not change, by `n . a d` along the plane's normal `n`; the model's
//! baseline `b = (cos(alpha), 0, -sin(alpha))` (where eq. (4)'s origin moves
//! as d grows) shifts it by `n . b d`, so the plane is that of L = L0 - k d
//! with `k = (n . a) / (n . b)`: cos(angle) for a true-length axis turned
//! within the plane of the baseline and the camera's optical axis (the
//! turned part, `(sin(alpha), 0, cos(alpha))`, lies in the laser plane). The part of the motion
//! that lies in the laser plane moves no lit point and cannot be measured;
//! it moves only the laser's origin, which the model uses for shadows. So
//! the model has one more parameter, `slide_scale` k (1 for the seed's
//! model), and a calibration with two or more slide positions fits it.

use std::path::Path;

use nalgebra::{Matrix3x2, Point2, Point3, Vector3, Vector4};
use serde::{Deserialize, Serialize};

use crate::{Error, Plane, Result};

/// Full stroke of the seed paper's linear slide: 20 cm.
pub const SLIDE_STROKE_MM: f64 = 200.0;

/// Slack on the stroke's ends for a computed travel: rounding in
/// [`LaserModel::slide_for_point`] must not turn the end of the stroke into
/// "outside" (1 nm, far below any slide's resolution).
const STROKE_SLACK_MM: f64 = 1e-6;

/// Which of the seed paper's two models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Fidelity {
    /// Low fidelity, eq. (10): beta fixed at 0; parameters (alpha, L0).
    #[serde(rename = "low-fidelity", alias = "low")]
    Low,
    /// High fidelity, eq. (7): parameters (alpha, L0, beta).
    #[serde(rename = "high-fidelity", alias = "high")]
    High,
}

impl Fidelity {
    /// The name used in laser.yaml and JSON: `low-fidelity` or `high-fidelity`.
    pub fn as_str(self) -> &'static str {
        match self {
            Fidelity::Low => "low-fidelity",
            Fidelity::High => "high-fidelity",
        }
    }

    /// Number of free parameters: 2 (alpha, L0) or 3 (alpha, L0, beta).
    pub fn parameter_count(self) -> usize {
        match self {
            Fidelity::Low => 2,
            Fidelity::High => 3,
        }
    }
}

impl std::fmt::Display for Fidelity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Laser-camera extrinsics of the ALACS model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserModel {
    /// Which model; `Low` ignores `beta_rad`.
    pub fidelity: Fidelity,
    /// alpha: rotation about the laser frame's y axis between laser and camera frames.
    pub alpha_rad: f64,
    /// beta: angle between the laser plane and the laser frame's (y, z) plane.
    pub beta_rad: f64,
    /// L0: laser-camera distance at slide travel 0.
    pub l0_mm: f64,
    /// k: the laser's travel per unit of commanded slide travel, L = L0 - k
    /// d (1 for the seed paper's perfect slide; see the module documentation).
    pub slide_scale: f64,
}

/// Where the slide must go to put the laser plane on a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlideTarget {
    /// Slide travel d that puts the point on the laser plane.
    pub slide_mm: f64,
    /// Whether `slide_mm` lies within `0 ..= stroke`.
    pub within_stroke: bool,
    /// `slide_mm` clamped to the stroke.
    pub clamped_mm: f64,
}

/// laser.yaml's keys as written on disk (FORMATS.md), degrees at the edge:
/// also the `laser` object of truth.json and of `evaluate accuracy --json`
/// (serialize [`LaserModel::to_file`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LaserFile {
    /// `low-fidelity` or `high-fidelity`.
    pub model: Fidelity,
    /// alpha, degrees.
    pub alpha_deg: f64,
    /// beta, degrees (may be absent for the low-fidelity model).
    pub beta_deg: Option<f64>,
    /// L0, mm.
    pub l0_mm: f64,
    /// k of L = L0 - k d (absent: 1).
    pub slide_scale: Option<f64>,
}

/// One standard deviation of each laser parameter as the calibration that
/// wrote a laser.yaml estimated it: its optional `std_dev` block
/// (FORMATS.md), so that a report on the file shows the calibration's own
/// sigmas, not a second estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaserStdDev {
    /// Of alpha, degrees.
    pub alpha_deg: f64,
    /// Of beta, degrees (absent for the low-fidelity model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta_deg: Option<f64>,
    /// Of L0, mm.
    pub l0_mm: f64,
    /// Of the slide scale k (absent where k was not fitted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slide_scale: Option<f64>,
    /// How they were estimated, in words.
    pub source: String,
}

impl LaserStdDev {
    /// Checks that every sigma is finite and not negative.
    fn validate(&self) -> std::result::Result<(), String> {
        let values = [Some(self.alpha_deg), self.beta_deg, Some(self.l0_mm), self.slide_scale];
        match values.into_iter().flatten().find(|v| !(v.is_finite() && *v >= 0.0)) {
            Some(bad) => Err(format!("std_dev: {bad} is not a standard deviation (finite, >= 0)")),
            None => Ok(()),
        }
    }
}

/// The range of k a laser.yaml or a fit may hold: a slide whose travel is
/// off by more than a fifth is a wrong steps-per-mm setting (or a wrong
/// unit), not a calibration result.
pub const SLIDE_SCALE_RANGE: (f64, f64) = (0.8, 1.25);

impl LaserModel {
    /// A model from radians, with the seed's perfect slide (k = 1).
    pub fn new(fidelity: Fidelity, alpha_rad: f64, beta_rad: f64, l0_mm: f64) -> Self {
        let beta_rad = if fidelity == Fidelity::Low { 0.0 } else { beta_rad };
        Self { fidelity, alpha_rad, beta_rad, l0_mm, slide_scale: 1.0 }
    }

    /// This model with slide scale `k`: L = L0 - k d.
    pub fn with_slide_scale(self, slide_scale: f64) -> Self {
        Self { slide_scale, ..self }
    }

    /// A model from degrees, as files and the paper give them.
    pub fn from_degrees(fidelity: Fidelity, alpha_deg: f64, beta_deg: f64, l0_mm: f64) -> Self {
        Self::new(fidelity, alpha_deg.to_radians(), beta_deg.to_radians(), l0_mm)
    }

    /// The seed paper's calibrated laser (its Table 1, method 4: alpha
    /// 19.07 deg, beta 0.69 deg, L0 381.98 mm), high fidelity: the default
    /// of the simulator and the examples.
    pub fn seed_paper() -> Self {
        Self::from_degrees(Fidelity::High, 19.07, 0.69, 381.98)
    }

    /// alpha in degrees.
    pub fn alpha_deg(&self) -> f64 {
        self.alpha_rad.to_degrees()
    }

    /// beta in degrees (0 for the low-fidelity model).
    pub fn beta_deg(&self) -> f64 {
        self.effective_beta_rad().to_degrees()
    }

    /// beta as the model uses it: 0 for the low-fidelity model.
    pub fn effective_beta_rad(&self) -> f64 {
        match self.fidelity {
            Fidelity::Low => 0.0,
            Fidelity::High => self.beta_rad,
        }
    }

    /// Checks that the parameters describe a laser in front of the camera:
    /// finite values, L0 > 0, 0 < alpha < 180 deg, |beta| < 90 deg, k within
    /// [`SLIDE_SCALE_RANGE`].
    pub fn validate(&self) -> Result<()> {
        let invalid = |message: String| Err(Error::InvalidParameters { what: "laser", message });
        if !self.slide_scale.is_finite()
            || !(SLIDE_SCALE_RANGE.0..=SLIDE_SCALE_RANGE.1).contains(&self.slide_scale)
        {
            return invalid(format!(
                "slide_scale must lie in [{}, {}] (the laser's travel per mm of slide travel), got {}",
                SLIDE_SCALE_RANGE.0,
                SLIDE_SCALE_RANGE.1,
                crate::Num(self.slide_scale)
            ));
        }
        if !(self.alpha_rad.is_finite() && self.beta_rad.is_finite() && self.l0_mm.is_finite()) {
            return invalid(format!(
                "parameters must be finite (alpha {} rad, beta {} rad, L0 {} mm)",
                crate::Num(self.alpha_rad),
                crate::Num(self.beta_rad),
                crate::Num(self.l0_mm)
            ));
        }
        if self.l0_mm <= 0.0 || self.l0_mm > crate::MAX_ABS_SLIDE_MM {
            return invalid(format!(
                "l0_mm must lie in (0, {}] mm (a laser beside its camera), got {}",
                crate::MAX_ABS_SLIDE_MM,
                crate::Num(self.l0_mm)
            ));
        }
        if !(self.alpha_rad > 0.0 && self.alpha_rad < std::f64::consts::PI) {
            return invalid(format!(
                "alpha_deg must lie in (0, 180), got {}",
                crate::Num(self.alpha_deg())
            ));
        }
        if self.effective_beta_rad().abs() >= std::f64::consts::FRAC_PI_2 {
            return invalid(format!(
                "beta_deg must lie in (-90, 90), got {}",
                crate::Num(self.beta_deg())
            ));
        }
        Ok(())
    }

    /// L = L0 - k d: the laser-camera distance at slide travel `slide_mm`.
    pub fn laser_distance_mm(&self, slide_mm: f64) -> f64 {
        self.l0_mm - self.slide_scale * slide_mm
    }

    /// This model with its trigonometric terms evaluated once, for loops
    /// over many pixels or samples.
    pub fn prepare(&self) -> PreparedLaser {
        let (sin_alpha, cos_alpha) = self.alpha_rad.sin_cos();
        let (sin_beta, cos_beta) = self.effective_beta_rad().sin_cos();
        PreparedLaser {
            model: *self,
            sin_alpha,
            cos_alpha,
            sin_beta,
            cos_beta,
            tan_beta: sin_beta / cos_beta,
        }
    }

    /// D = sin(alpha) - u_n cos(alpha) - v_n tan(beta), the denominator of eq. (7).
    pub fn denominator(&self, normalized: &Point2<f64>) -> f64 {
        self.prepare().denominator(normalized)
    }

    /// Depth z of the laser point seen at `normalized`, eq. (7) (eq. (10) for
    /// the low-fidelity model). Errors where the ray misses the laser plane
    /// in front of the camera.
    pub fn depth_mm(&self, normalized: &Point2<f64>, slide_mm: f64) -> Result<f64> {
        self.prepare().depth_mm(normalized, slide_mm)
    }

    /// The 3-D point in the camera frame seen at `normalized`, eqs. (7)-(8).
    pub fn triangulate(&self, normalized: &Point2<f64>, slide_mm: f64) -> Result<Point3<f64>> {
        self.prepare().triangulate(normalized, slide_mm)
    }

    /// 3x2 Jacobian of [`Self::triangulate`] with respect to (u_n, v_n).
    pub fn triangulate_jacobian(
        &self,
        normalized: &Point2<f64>,
        slide_mm: f64,
    ) -> Result<Matrix3x2<f64>> {
        self.prepare().triangulate_jacobian(normalized, slide_mm)
    }

    /// Gradient of the modelled depth z_hat of eq. (9) with respect to the
    /// parameters (alpha in rad, L0 in mm, beta in rad, k); see
    /// [`PreparedLaser::depth_gradient_params`].
    pub fn depth_gradient_params(
        &self,
        normalized: &Point2<f64>,
        slide_mm: f64,
    ) -> Result<Vector4<f64>> {
        self.prepare().depth_gradient_params(normalized, slide_mm)
    }

    /// Signed Euclidean distance of `point_in_camera` from the laser plane at
    /// slide travel `slide_mm` (positive on the side away from the camera):
    /// the geometric residual offered beside eq. (9)'s depth residual.
    pub fn signed_distance_mm(&self, point_in_camera: &Point3<f64>, slide_mm: f64) -> f64 {
        self.prepare().signed_distance_mm(point_in_camera, slide_mm)
    }

    /// Gradient of [`Self::signed_distance_mm`] with respect to the parameters
    /// (alpha in rad, L0 in mm, beta in rad, k); see
    /// [`PreparedLaser::signed_distance_gradient_params`].
    pub fn signed_distance_gradient_params(
        &self,
        point_in_camera: &Point3<f64>,
        slide_mm: f64,
    ) -> Vector4<f64> {
        self.prepare().signed_distance_gradient_params(point_in_camera, slide_mm)
    }

    /// The laser plane in the camera frame at slide travel `slide_mm`:
    /// `-cos(alpha) x - tan(beta) y + sin(alpha) z = L`.
    pub fn plane_in_camera(&self, slide_mm: f64) -> Plane {
        self.prepare().plane_in_camera(slide_mm)
    }

    /// The laser's origin (the line generator) in the camera frame, eq. (4):
    /// `(-L cos(alpha), 0, L sin(alpha))`. Surfaces that the segment from it
    /// to a point crosses shadow that point.
    pub fn origin_in_camera(&self, slide_mm: f64) -> Point3<f64> {
        let l_mm = self.laser_distance_mm(slide_mm);
        let (sin_a, cos_a) = self.alpha_rad.sin_cos();
        Point3::new(-l_mm * cos_a, 0.0, l_mm * sin_a)
    }

    /// The inverse the scanner needs: the slide travel d that puts the laser
    /// plane through `point_in_camera`, from `n · p = L0 - k d`.
    pub fn slide_for_point(&self, point_in_camera: &Point3<f64>) -> f64 {
        let plane = self.plane_in_camera(0.0);
        (self.l0_mm - plane.normal.dot(&point_in_camera.coords)) / self.slide_scale
    }

    /// [`Self::slide_for_point`] with the stroke `0 ..= stroke_mm` checked and clamped.
    pub fn slide_target(&self, point_in_camera: &Point3<f64>, stroke_mm: f64) -> SlideTarget {
        let slide_mm = self.slide_for_point(point_in_camera);
        SlideTarget {
            slide_mm,
            within_stroke: (-STROKE_SLACK_MM..=stroke_mm + STROKE_SLACK_MM).contains(&slide_mm),
            clamped_mm: slide_mm.clamp(0.0, stroke_mm.max(0.0)),
        }
    }

    /// Parses laser.yaml text (FORMATS.md). `beta_deg` may be omitted for the
    /// low-fidelity model, `slide_scale` (k) where it is 1; unknown extra
    /// keys are ignored.
    pub fn from_yaml_str(text: &str) -> Result<Self> {
        Self::parse_yaml(text, Path::new("<string>"))
    }

    /// Reads laser.yaml.
    pub fn from_yaml_file(path: &Path) -> Result<Self> {
        let text = crate::io::read_text(path)?;
        Self::parse_yaml(&text, path)
    }

    /// Reads laser.yaml with its `std_dev` block, where it has one.
    pub fn from_yaml_file_with_std(path: &Path) -> Result<(Self, Option<LaserStdDev>)> {
        #[derive(Deserialize)]
        struct WithStd {
            std_dev: Option<LaserStdDev>,
        }
        let text = crate::io::read_text(path)?;
        let model = Self::parse_yaml(&text, path)?;
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: WithStd = serde_saphyr::from_str(&text)
            .map_err(|e| parse_error(crate::error::yaml_message(&e)))?;
        if let Some(std) = &file.std_dev {
            std.validate().map_err(parse_error)?;
        }
        Ok((model, file.std_dev))
    }

    fn parse_yaml(text: &str, path: &Path) -> Result<Self> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: LaserFile = serde_saphyr::from_str(text)
            .map_err(|e| parse_error(crate::error::yaml_message(&e)))?;
        let beta_deg = match (file.model, file.beta_deg) {
            (Fidelity::High, None) => {
                return Err(parse_error(
                    "missing key `beta_deg` (required for model: high-fidelity)".into(),
                ));
            }
            (_, beta) => beta.unwrap_or(0.0),
        };
        let model = Self::from_degrees(file.model, file.alpha_deg, beta_deg, file.l0_mm)
            .with_slide_scale(file.slide_scale.unwrap_or(1.0));
        model.validate().map_err(|e| parse_error(e.to_string()))?;
        Ok(model)
    }

    /// The five keys of laser.yaml, every one given.
    pub fn to_file(&self) -> LaserFile {
        LaserFile {
            model: self.fidelity,
            alpha_deg: self.alpha_deg(),
            beta_deg: Some(self.beta_deg()),
            l0_mm: self.l0_mm,
            slide_scale: Some(self.slide_scale),
        }
    }

    /// laser.yaml text with the five keys of FORMATS.md (shortest
    /// round-trip float formatting, so reading it back gives the same model).
    pub fn to_yaml_string(&self) -> String {
        format!(
            "model: {}\nalpha_deg: {}\nbeta_deg: {}\nl0_mm: {}\nslide_scale: {}\n",
            self.fidelity,
            self.alpha_deg(),
            self.beta_deg(),
            self.l0_mm,
            self.slide_scale
        )
    }

    /// Writes laser.yaml, with `header` (e.g. provenance) as leading `#`
    /// comment lines and the calibration's standard deviations, where it
    /// estimated them, as its `std_dev` block.
    pub fn to_yaml_file(&self, path: &Path, header: &str, std: Option<&LaserStdDev>) -> Result<()> {
        let mut text: String = header.lines().map(|line| format!("# {line}\n")).collect();
        text.push_str(&self.to_yaml_string());
        if let Some(std) = std {
            text.push_str("std_dev:                    # one standard deviation of each, as the calibration estimated it\n");
            text.push_str(&format!("  alpha_deg: {}\n", std.alpha_deg));
            if let Some(beta) = std.beta_deg {
                text.push_str(&format!("  beta_deg: {beta}\n"));
            }
            text.push_str(&format!("  l0_mm: {}\n", std.l0_mm));
            if let Some(k) = std.slide_scale {
                text.push_str(&format!("  slide_scale: {k}\n"));
            }
            // A JSON string is a YAML double-quoted scalar.
            let source = serde_json::Value::String(std.source.clone());
            text.push_str(&format!("  source: {source}\n"));
        }
        crate::io::write_file(path, text)
    }
}

/// A [`LaserModel`] with its sines, cosines and tangents evaluated once: the
/// form for loops over many pixels or samples. The formulas of eqs. (7)-(8)
/// and the residuals of eq. (9) live here; [`LaserModel`]'s methods of the
/// same names call these.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreparedLaser {
    /// The model.
    pub model: LaserModel,
    sin_alpha: f64,
    cos_alpha: f64,
    sin_beta: f64,
    cos_beta: f64,
    tan_beta: f64,
}

impl PreparedLaser {
    /// D = sin(alpha) - u_n cos(alpha) - v_n tan(beta), the denominator of eq. (7).
    pub fn denominator(&self, normalized: &Point2<f64>) -> f64 {
        self.sin_alpha - normalized.x * self.cos_alpha - normalized.y * self.tan_beta
    }

    /// Depth z of the laser point seen at `normalized`, eq. (7) (eq. (10) for
    /// the low-fidelity model). Errors where the ray misses the laser plane
    /// in front of the camera.
    pub fn depth_mm(&self, normalized: &Point2<f64>, slide_mm: f64) -> Result<f64> {
        let denominator = self.denominator(normalized);
        let depth_mm = self.model.laser_distance_mm(slide_mm) / denominator;
        if denominator > 0.0 && depth_mm.is_finite() && depth_mm > 0.0 {
            Ok(depth_mm)
        } else {
            Err(Error::NoIntersection { u_n: normalized.x, v_n: normalized.y, denominator })
        }
    }

    /// The 3-D point in the camera frame seen at `normalized`, eqs. (7)-(8).
    pub fn triangulate(&self, normalized: &Point2<f64>, slide_mm: f64) -> Result<Point3<f64>> {
        let z_mm = self.depth_mm(normalized, slide_mm)?;
        Ok(Point3::new(normalized.x * z_mm, normalized.y * z_mm, z_mm))
    }

    /// 3x2 Jacobian of [`Self::triangulate`] with respect to (u_n, v_n).
    pub fn triangulate_jacobian(
        &self,
        normalized: &Point2<f64>,
        slide_mm: f64,
    ) -> Result<Matrix3x2<f64>> {
        let z = self.depth_mm(normalized, slide_mm)?;
        let denominator = self.denominator(normalized);
        // dz/du = L cos(alpha) / D^2 = z cos(alpha) / D, likewise for v with tan(beta).
        let dz_du = z * self.cos_alpha / denominator;
        let dz_dv = z * self.tan_beta / denominator;
        let (u, v) = (normalized.x, normalized.y);
        Ok(Matrix3x2::new(z + u * dz_du, u * dz_dv, v * dz_du, z + v * dz_dv, dz_du, dz_dv))
    }

    /// Gradient of the modelled depth z_hat of eq. (9) with respect to the
    /// parameters (alpha in rad, L0 in mm, beta in rad, k). For the
    /// low-fidelity model the beta entry is the derivative at beta = 0,
    /// which callers that fit two parameters ignore.
    pub fn depth_gradient_params(
        &self,
        normalized: &Point2<f64>,
        slide_mm: f64,
    ) -> Result<Vector4<f64>> {
        let z = self.depth_mm(normalized, slide_mm)?;
        let denominator = self.denominator(normalized);
        let (sin_a, cos_a, cos_b) = (self.sin_alpha, self.cos_alpha, self.cos_beta);
        // z = L / D:  dz/dp = -z/D * dD/dp for the angles, dz/dL0 = 1/D,
        // dz/dk = -d/D (L = L0 - k d).
        let dz_dalpha = -z / denominator * (cos_a + normalized.x * sin_a);
        let dz_dl0 = 1.0 / denominator;
        let dz_dbeta = z / denominator * normalized.y / (cos_b * cos_b);
        let dz_dk = -slide_mm / denominator;
        Ok(Vector4::new(dz_dalpha, dz_dl0, dz_dbeta, dz_dk))
    }

    /// Signed Euclidean distance of `point_in_camera` from the laser plane at
    /// slide travel `slide_mm` (positive on the side away from the camera):
    /// the geometric residual offered beside eq. (9)'s depth residual.
    pub fn signed_distance_mm(&self, point_in_camera: &Point3<f64>, slide_mm: f64) -> f64 {
        self.plane_in_camera(slide_mm).signed_distance_mm(point_in_camera)
    }

    /// Gradient of [`Self::signed_distance_mm`] with respect to the parameters
    /// (alpha in rad, L0 in mm, beta in rad, k). With the normal scaled to
    /// unit length the distance is
    /// `-cos(a) cos(b) x - sin(b) y + sin(a) cos(b) z - L cos(b)`, L = L0 - k d.
    pub fn signed_distance_gradient_params(
        &self,
        point_in_camera: &Point3<f64>,
        slide_mm: f64,
    ) -> Vector4<f64> {
        let (x, y, z) = (point_in_camera.x, point_in_camera.y, point_in_camera.z);
        let (sin_a, cos_a) = (self.sin_alpha, self.cos_alpha);
        let (sin_b, cos_b) = (self.sin_beta, self.cos_beta);
        let l_mm = self.model.laser_distance_mm(slide_mm);
        Vector4::new(
            (sin_a * x + cos_a * z) * cos_b,
            -cos_b,
            cos_a * sin_b * x - cos_b * y - sin_a * sin_b * z + l_mm * sin_b,
            slide_mm * cos_b,
        )
    }

    /// The laser plane in the camera frame at slide travel `slide_mm`:
    /// `-cos(alpha) x - tan(beta) y + sin(alpha) z = L`.
    pub fn plane_in_camera(&self, slide_mm: f64) -> Plane {
        Plane {
            normal: Vector3::new(-self.cos_alpha, -self.tan_beta, self.sin_alpha),
            offset_mm: self.model.laser_distance_mm(slide_mm),
        }
    }
}
