//! Nonlinear least-squares refinement of the laser parameters, eq. (9), by
//! Levenberg-Marquardt (the `levenberg-marquardt` crate, a MINPACK port).

use alacs_model::{Fidelity, LaserModel};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn};

use crate::{Error, LaserSample, Result};

/// Which residual the least-squares fit minimizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Residual {
    /// The seed paper's eq. (9): `z_i - L_i / D_i`, the depth error. The
    /// maximum-likelihood choice when the measured depths carry the noise, as
    /// they do when they come from the board pose.
    #[default]
    Depth,
    /// The Euclidean distance of the measured point `z_i (u_i, v_i, 1)` from
    /// the laser plane. It weights each sample by `D_i cos(beta)` relative to
    /// the depth residual, so near samples count more.
    PlaneDistance,
}

impl Residual {
    /// Name used on the command line and in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Residual::Depth => "depth",
            Residual::PlaneDistance => "plane",
        }
    }
}

/// The refined model with its statistics.
#[derive(Debug, Clone)]
pub(crate) struct Refined {
    pub laser: LaserModel,
    /// Covariance of (alpha in rad, L0 in mm, beta in rad) (beta row/column
    /// absent for the low-fidelity model), from sigma^2 (J^T J)^-1.
    pub covariance: Option<DMatrix<f64>>,
}

/// Smallest denominator D that the solver may evaluate: a trial step that
/// puts a sample's ray beyond the laser plane's horizon gets a huge finite
/// residual (so the step is rejected) instead of a division by ~0.
const MIN_DENOMINATOR: f64 = 1e-6;

/// The part of a [`LeastSquaresProblem`] over dynamic vectors that every
/// problem of this crate shares: the storage types, and the parameters kept
/// in the problem's field `params` (a `DVector<f64>`).
macro_rules! dynamic_problem_params {
    () => {
        type ResidualStorage = nalgebra::Owned<f64, nalgebra::Dyn>;
        type JacobianStorage = nalgebra::Owned<f64, nalgebra::Dyn, nalgebra::Dyn>;
        type ParameterStorage = nalgebra::Owned<f64, nalgebra::Dyn>;

        fn set_params(&mut self, params: &nalgebra::DVector<f64>) {
            self.params.copy_from(params);
        }

        fn params(&self) -> nalgebra::DVector<f64> {
            self.params.clone()
        }
    };
}
pub(crate) use dynamic_problem_params;

struct Problem<'a> {
    samples: Vec<&'a LaserSample>,
    fidelity: Fidelity,
    residual: Residual,
    params: DVector<f64>,
}

impl Problem<'_> {
    fn laser(&self) -> LaserModel {
        let beta = if self.fidelity == Fidelity::High { self.params[2] } else { 0.0 };
        LaserModel::new(self.fidelity, self.params[0], beta, self.params[1])
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    dynamic_problem_params!();

    fn residuals(&self) -> Option<DVector<f64>> {
        let laser = self.laser().prepare();
        Some(DVector::from_iterator(
            self.samples.len(),
            self.samples.iter().map(|s| match self.residual {
                Residual::Depth => {
                    let d = laser.denominator(&s.normalized()).max(MIN_DENOMINATOR);
                    s.z_mm - laser.model.laser_distance_mm(s.slide_mm) / d
                }
                Residual::PlaneDistance => {
                    laser.signed_distance_mm(&s.point_in_camera(), s.slide_mm)
                }
            }),
        ))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let laser = self.laser().prepare();
        let p = self.params.len();
        let mut jac = DMatrix::zeros(self.samples.len(), p);
        for (i, s) in self.samples.iter().enumerate() {
            let gradient = match self.residual {
                // r = z - z_hat: dr/dp = -dz_hat/dp.
                Residual::Depth => {
                    -laser.depth_gradient_params(&s.normalized(), s.slide_mm).ok()?
                }
                Residual::PlaneDistance => {
                    laser.signed_distance_gradient_params(&s.point_in_camera(), s.slide_mm)
                }
            };
            for j in 0..p {
                jac[(i, j)] = gradient[j];
            }
        }
        Some(jac)
    }
}

/// Refines `initial` on the samples `indices` by minimizing `residual`.
pub(crate) fn refine(
    samples: &[LaserSample],
    indices: &[usize],
    initial: &LaserModel,
    residual: Residual,
) -> Result<Refined> {
    let fidelity = initial.fidelity;
    let mut params = vec![initial.alpha_rad, initial.l0_mm];
    if fidelity == Fidelity::High {
        params.push(initial.beta_rad);
    }
    let problem = Problem {
        samples: indices.iter().map(|&i| &samples[i]).collect(),
        fidelity,
        residual,
        params: DVector::from_vec(params),
    };
    let (problem, report) = LevenbergMarquardt::new().minimize(problem);
    let laser = problem.laser();
    if laser.validate().is_err() || !report.objective_function.is_finite() {
        return Err(Error::FitFailed(format!(
            "Levenberg-Marquardt ended at alpha {:.3} deg, L0 {:.3} mm, beta {:.3} deg ({:?})",
            laser.alpha_deg(),
            laser.l0_mm,
            laser.beta_deg(),
            report.termination
        )));
    }
    let covariance = problem.jacobian().and_then(|jac| {
        let (n, p) = jac.shape();
        if n <= p {
            return None;
        }
        let sigma2 = 2.0 * report.objective_function / (n - p) as f64;
        (jac.transpose() * &jac).try_inverse().map(|inv| inv * sigma2)
    });
    Ok(Refined { laser, covariance })
}
