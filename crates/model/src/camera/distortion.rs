//! Lens distortion w of the seed paper's eq. (2), exactly as OpenCV defines it
//! (`cv::projectPoints` without thin-prism or tilt terms):
//!
//! ```text
//! r2 = x² + y²
//! radial = (1 + k1 r2 + k2 r2² + k3 r2³) / (1 + k4 r2 + k5 r2² + k6 r2³)
//! x' = x radial + 2 p1 x y + p2 (r2 + 2 x²)
//! y' = y radial + p1 (r2 + 2 y²) + 2 p2 x y
//! ```
//!
//! for undistorted normalized coordinates (x, y) = (X/Z, Y/Z); the
//! denominator is 1 for `plumb_bob`.

use nalgebra::{Matrix2, Point2, Vector2};

/// Lens distortion in normalized image coordinates, with OpenCV's
/// coefficient order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distortion {
    /// No distortion.
    None,
    /// OpenCV / ROS `plumb_bob`: [k1, k2, p1, p2, k3].
    PlumbBob([f64; 5]),
    /// OpenCV / ROS `rational_polynomial`: [k1, k2, p1, p2, k3, k4, k5, k6].
    RationalPolynomial([f64; 8]),
}

/// The two distortion models a camera calibration can fit (OpenCV's
/// default and its `CALIB_RATIONAL_MODEL`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DistortionModel {
    /// `plumb_bob`: k1, k2, p1, p2, k3.
    #[default]
    PlumbBob,
    /// `rational_polynomial`: k1, k2, p1, p2, k3, k4, k5, k6.
    RationalPolynomial,
}

impl DistortionModel {
    /// The ROS / camera.yaml name.
    pub fn as_str(self) -> &'static str {
        match self {
            DistortionModel::PlumbBob => "plumb_bob",
            DistortionModel::RationalPolynomial => "rational_polynomial",
        }
    }
}

/// The coefficients of either model in the rational form, the others 0.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Coefficients {
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
    k4: f64,
    k5: f64,
    k6: f64,
}

/// Number of samples along the radius when checking that the radial profile
/// has not folded over between the image centre and a point. The radial
/// profile of both models is a low-degree rational function of r2, so 32
/// samples cannot miss a fold except in contrived coefficient sets.
const FOLD_SAMPLES: u32 = 32;

impl Distortion {
    /// The ROS `distortion_model` name and coefficients (`D`) that camera.yaml
    /// holds for this distortion; `None` is written as `plumb_bob` with five
    /// zeros, as ROS does for an undistorted camera.
    pub fn ros_model(&self) -> (&'static str, Vec<f64>) {
        let coefficients = match self {
            Distortion::None => vec![0.0; 5],
            _ => self.coefficients().to_vec(),
        };
        (self.model().as_str(), coefficients)
    }

    /// The coefficients in OpenCV's order (empty for `None`).
    pub fn coefficients(&self) -> &[f64] {
        match self {
            Distortion::None => &[],
            Distortion::PlumbBob(c) => c,
            Distortion::RationalPolynomial(c) => c,
        }
    }

    /// d(x_d, y_d) / d(coefficients) at the undistorted normalized point
    /// `normalized`: one column per coefficient of this model, in
    /// [`Self::coefficients`]' order (none for `None`). What a camera
    /// calibration needs for its distortion parameters.
    pub fn coefficient_jacobian(&self, normalized: &Point2<f64>) -> Vec<Vector2<f64>> {
        let all = self.unpack().coefficient_jacobian(normalized);
        all[..self.coefficients().len()].to_vec()
    }

    /// This distortion in `model`'s form: plumb_bob padded with zeros to
    /// rational_polynomial, rational_polynomial cut to its first five
    /// coefficients (exact where k4 = k5 = k6 = 0), `None` as zeros.
    pub fn to_model(&self, model: DistortionModel) -> Distortion {
        let c = self.unpack();
        match model {
            DistortionModel::PlumbBob => Distortion::PlumbBob([c.k1, c.k2, c.p1, c.p2, c.k3]),
            DistortionModel::RationalPolynomial => {
                Distortion::RationalPolynomial([c.k1, c.k2, c.p1, c.p2, c.k3, c.k4, c.k5, c.k6])
            }
        }
    }

    /// Which model this is (`None` counts as plumb_bob, as ROS writes it).
    pub fn model(&self) -> DistortionModel {
        match self {
            Distortion::RationalPolynomial(_) => DistortionModel::RationalPolynomial,
            Distortion::None | Distortion::PlumbBob(_) => DistortionModel::PlumbBob,
        }
    }

    /// The coefficients in OpenCV's order, to change in place (empty for `None`).
    pub fn coefficients_mut(&mut self) -> &mut [f64] {
        match self {
            Distortion::None => &mut [],
            Distortion::PlumbBob(c) => c,
            Distortion::RationalPolynomial(c) => c,
        }
    }

    /// Whether every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        self.coefficients().iter().all(|c| c.is_finite())
    }

    /// Whether this is the identity (`None`, or every coefficient zero).
    pub fn is_identity(&self) -> bool {
        self.coefficients().iter().all(|&c| c == 0.0)
    }

    pub(crate) fn unpack(&self) -> Coefficients {
        let zero =
            Coefficients { k1: 0.0, k2: 0.0, p1: 0.0, p2: 0.0, k3: 0.0, k4: 0.0, k5: 0.0, k6: 0.0 };
        match *self {
            Distortion::None => zero,
            Distortion::PlumbBob([k1, k2, p1, p2, k3]) => {
                Coefficients { k1, k2, p1, p2, k3, ..zero }
            }
            Distortion::RationalPolynomial([k1, k2, p1, p2, k3, k4, k5, k6]) => {
                Coefficients { k1, k2, p1, p2, k3, k4, k5, k6 }
            }
        }
    }
}

/// Numerator and denominator of the radial factor at r2, with their
/// derivatives with respect to r2.
struct Radial {
    numerator: f64,
    denominator: f64,
    d_numerator: f64,
    d_denominator: f64,
}

impl Coefficients {
    fn radial(&self, r2: f64) -> Radial {
        let r4 = r2 * r2;
        let r6 = r4 * r2;
        Radial {
            // OpenCV's `cdist` and the reciprocal of its `icdist2`.
            numerator: 1.0 + self.k1 * r2 + self.k2 * r4 + self.k3 * r6,
            denominator: 1.0 + self.k4 * r2 + self.k5 * r4 + self.k6 * r6,
            d_numerator: self.k1 + 2.0 * self.k2 * r2 + 3.0 * self.k3 * r4,
            d_denominator: self.k4 + 2.0 * self.k5 * r2 + 3.0 * self.k6 * r4,
        }
    }

    /// Undistorted normalized -> distorted normalized, in OpenCV's order of
    /// operations (`cvProjectPoints2Internal`).
    pub(crate) fn distort(&self, normalized: &Point2<f64>) -> Point2<f64> {
        let (x, y) = (normalized.x, normalized.y);
        let r2 = x * x + y * y;
        let a1 = 2.0 * x * y;
        let a2 = r2 + 2.0 * x * x;
        let a3 = r2 + 2.0 * y * y;
        let radial = self.radial(r2);
        let icdist2 = 1.0 / radial.denominator;
        let cdist = radial.numerator;
        Point2::new(
            x * cdist * icdist2 + self.p1 * a1 + self.p2 * a2,
            y * cdist * icdist2 + self.p1 * a3 + self.p2 * a1,
        )
    }

    /// d(x_d, y_d) / d(k1, k2, p1, p2, k3, k4, k5, k6) of
    /// [`Coefficients::distort`] at `normalized`: one column per
    /// coefficient, in OpenCV's order.
    fn coefficient_jacobian(&self, normalized: &Point2<f64>) -> [Vector2<f64>; 8] {
        let (x, y) = (normalized.x, normalized.y);
        let r2 = x * x + y * y;
        let (r4, r6) = (r2 * r2, r2 * r2 * r2);
        let radial = self.radial(r2);
        let d = radial.denominator;
        // x_d = x N / D + ..., N = 1 + k1 r2 + k2 r4 + k3 r6, D = 1 + k4 r2 + k5 r4 + k6 r6.
        let numerator_term = |power: f64| Vector2::new(x * power / d, y * power / d);
        let denominator_term = |power: f64| {
            let scale = -radial.numerator * power / (d * d);
            Vector2::new(x * scale, y * scale)
        };
        [
            numerator_term(r2),
            numerator_term(r4),
            Vector2::new(2.0 * x * y, r2 + 2.0 * y * y),
            Vector2::new(r2 + 2.0 * x * x, 2.0 * x * y),
            numerator_term(r6),
            denominator_term(r2),
            denominator_term(r4),
            denominator_term(r6),
        ]
    }

    /// The 2x2 Jacobian of [`Coefficients::distort`].
    pub(crate) fn distort_jacobian(&self, normalized: &Point2<f64>) -> Matrix2<f64> {
        let (x, y) = (normalized.x, normalized.y);
        let r2 = x * x + y * y;
        let radial = self.radial(r2);
        let factor = radial.numerator / radial.denominator;
        // d(factor)/d(r2) by the quotient rule.
        let d_factor = (radial.d_numerator * radial.denominator
            - radial.numerator * radial.d_denominator)
            / (radial.denominator * radial.denominator);
        let (p1, p2) = (self.p1, self.p2);
        Matrix2::new(
            factor + 2.0 * x * x * d_factor + 2.0 * p1 * y + 6.0 * p2 * x,
            2.0 * x * y * d_factor + 2.0 * p1 * x + 2.0 * p2 * y,
            2.0 * x * y * d_factor + 2.0 * p1 * x + 2.0 * p2 * y,
            factor + 2.0 * y * y * d_factor + 6.0 * p1 * y + 2.0 * p2 * x,
        )
    }

    /// Whether the radial profile `r -> r * factor(r²)` is increasing with a
    /// positive factor all the way from the centre out to squared radius
    /// `r2`: inside that disc the radial part of the distortion is one-to-one.
    fn radial_profile_increasing_to(&self, r2: f64) -> bool {
        (1..=FOLD_SAMPLES).all(|i| {
            let fraction = f64::from(i) / f64::from(FOLD_SAMPLES);
            let s = r2 * fraction * fraction;
            let radial = self.radial(s);
            // d/dr [r N(s)/D(s)] = (N D + 2 s (N' D - N D')) / D², s = r².
            let slope_numerator = radial.numerator * radial.denominator
                + 2.0
                    * s
                    * (radial.d_numerator * radial.denominator
                        - radial.numerator * radial.d_denominator);
            radial.denominator > 0.0 && radial.numerator > 0.0 && slope_numerator > 0.0
        })
    }

    /// Whether `normalized` lies in the region around the image centre where
    /// the distortion is one-to-one and orientation-preserving: the radial
    /// profile has not folded over on the way out, and the full Jacobian
    /// (tangential terms included) has a positive determinant there.
    pub(crate) fn is_invertible_at(&self, normalized: &Point2<f64>) -> bool {
        let r2 = normalized.coords.norm_squared();
        r2.is_finite()
            && self.radial_profile_increasing_to(r2)
            && self.distort_jacobian(normalized).determinant() > 0.0
    }
}
