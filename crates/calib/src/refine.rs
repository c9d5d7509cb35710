//! Nonlinear least-squares refinement of the laser parameters, eq. (9), by
//! Levenberg-Marquardt on the normal equations (two to four parameters,
//! up to millions of samples).

use alacs_model::{Fidelity, LaserModel, PreparedLaser};
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};
use rayon::prelude::*;

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

/// Which laser parameters a fit frees, and their order in its vectors:
/// alpha (rad), L0 (mm), then beta (rad) for the high-fidelity model, then
/// the slide scale k where the samples span several slide positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Layout {
    pub fidelity: Fidelity,
    /// Whether k is fitted (else held at the model's value).
    pub slide_scale: bool,
}

impl Layout {
    /// Number of fitted parameters.
    pub fn len(&self) -> usize {
        2 + usize::from(self.fidelity == Fidelity::High) + usize::from(self.slide_scale)
    }

    /// The fitted parameters' places in the full vector (alpha, L0, beta, k).
    fn places(&self) -> impl Iterator<Item = usize> {
        let beta = self.fidelity == Fidelity::High;
        [0, 1].into_iter().chain(beta.then_some(2)).chain(self.slide_scale.then_some(3))
    }

    /// The fitted parameters of `laser`, in this layout's order.
    pub fn parameters(&self, laser: &LaserModel) -> Vec<f64> {
        let full = full_parameters(laser);
        self.places().map(|k| full[k]).collect()
    }

    /// Where k sits in this layout's vectors, if it is fitted.
    pub fn slide_scale_index(&self) -> Option<usize> {
        self.slide_scale.then(|| self.len() - 1)
    }

    /// Where beta sits in this layout's vectors, if it is fitted.
    pub fn beta_index(&self) -> Option<usize> {
        (self.fidelity == Fidelity::High).then_some(2)
    }
}

/// All four of (alpha rad, L0 mm, beta rad, k).
fn full_parameters(laser: &LaserModel) -> [f64; 4] {
    [laser.alpha_rad, laser.l0_mm, laser.effective_beta_rad(), laser.slide_scale]
}

/// The refined model with its statistics.
#[derive(Debug, Clone)]
pub(crate) struct Refined {
    pub laser: LaserModel,
    /// Covariance of the layout's parameters, from sigma^2 (J^T J)^-1.
    pub covariance: Option<DMatrix<f64>>,
}

/// Smallest denominator D that the solver may evaluate: a trial step that
/// puts a sample's ray beyond the laser plane's horizon gets a huge finite
/// residual (so the step is rejected) instead of a division by ~0.
const MIN_DENOMINATOR: f64 = 1e-6;

/// The part of a [`levenberg_marquardt::LeastSquaresProblem`] over dynamic
/// vectors that every problem of this crate shares: the storage types, and
/// the parameters kept in the problem's field `params` (a `DVector<f64>`).
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

/// Samples per block of the one-pass sums: blocks are summed in parallel
/// and then in their order, so a fit is the same on any number of threads.
const BLOCK: usize = 8192;

/// Most Levenberg-Marquardt iterations (each one pass over the samples; a
/// fit from the linear solution normally converges in 3-6).
const MAX_ITERATIONS: usize = 100;

/// A step is done when the sum of squares falls by less than this fraction.
const RELATIVE_COST_TOLERANCE: f64 = 1e-14;

/// A step is done when no parameter moves by more than this fraction of its
/// scale (`1 / sqrt(diag(J^T J))`, the parameter change that moves the
/// residuals by one unit).
const SCALED_STEP_TOLERANCE: f64 = 1e-10;

/// The full parameter vector (alpha rad, L0 mm, beta rad, k), the fixed
/// ones included.
type Params = [f64; 4];

/// One pass over the samples at some parameters: the sum of squared
/// residuals and the normal equations' J^T J and J^T r over the fitted
/// parameters in the layout's order (p x p and p used).
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    cost: f64,
    jtj: Matrix4<f64>,
    jtr: Vector4<f64>,
    /// A sample's ray misses the laser plane: the gradient is undefined there.
    invalid: bool,
}

impl Sums {
    /// J^T J (p x p) and J^T r (p) of the first `p` parameters.
    fn normal_equations(&self, p: usize) -> (DMatrix<f64>, DVector<f64>) {
        (self.jtj.view((0, 0), (p, p)).into_owned(), self.jtr.rows(0, p).into_owned())
    }

    fn add(mut self, other: &Sums) -> Sums {
        self.cost += other.cost;
        self.jtj += other.jtj;
        self.jtr += other.jtr;
        self.invalid |= other.invalid;
        self
    }
}

/// The least-squares problem of eq. (9) over the samples `indices`.
struct Problem<'a> {
    samples: &'a [LaserSample],
    indices: &'a [usize],
    layout: Layout,
    residual: Residual,
    /// The fitted parameters' places in [`Params`], `p` of them.
    places: [usize; 4],
}

impl<'a> Problem<'a> {
    fn new(
        samples: &'a [LaserSample],
        indices: &'a [usize],
        layout: Layout,
        residual: Residual,
    ) -> Self {
        let mut places = [0; 4];
        for (slot, k) in places.iter_mut().zip(layout.places()) {
            *slot = k;
        }
        Problem { samples, indices, layout, residual, places }
    }

    /// Number of fitted parameters.
    fn p(&self) -> usize {
        self.layout.len()
    }

    fn laser(&self, params: &Params) -> LaserModel {
        LaserModel::new(self.layout.fidelity, params[0], params[2], params[1])
            .with_slide_scale(params[3])
    }

    /// Residual and its gradient for one sample (`None` for the gradient
    /// where the ray misses the plane).
    fn residual_and_gradient(
        &self,
        laser: &PreparedLaser,
        s: &LaserSample,
    ) -> (f64, Option<Vector4<f64>>) {
        match self.residual {
            Residual::Depth => {
                let normalized = s.normalized();
                let d = laser.denominator(&normalized).max(MIN_DENOMINATOR);
                let r = s.z_mm - laser.model.laser_distance_mm(s.slide_mm) / d;
                // r = z - z_hat: dr/dp = -dz_hat/dp.
                (r, laser.depth_gradient_params(&normalized, s.slide_mm).ok().map(|g| -g))
            }
            Residual::PlaneDistance => {
                let point = s.point_in_camera();
                (
                    laser.signed_distance_mm(&point, s.slide_mm),
                    Some(laser.signed_distance_gradient_params(&point, s.slide_mm)),
                )
            }
        }
    }

    /// The sums over `block` under `laser`, in order on this thread.
    fn block_sums(&self, laser: &PreparedLaser, block: &[usize]) -> Sums {
        let p = self.p();
        let mut sums = Sums::default();
        for &i in block {
            let (r, gradient) = self.residual_and_gradient(laser, &self.samples[i]);
            sums.cost += r * r;
            match gradient {
                Some(full) => {
                    // The fitted parameters' entries first, the rest 0.
                    let g = Vector4::from_fn(|k, _| if k < p { full[self.places[k]] } else { 0.0 });
                    sums.jtj += g * g.transpose();
                    sums.jtr += g * r;
                }
                None => sums.invalid = true,
            }
        }
        sums
    }

    /// The sums of one pass at `params`.
    fn sums(&self, params: &Params) -> Sums {
        let laser = self.laser(params).prepare();
        if self.indices.len() <= BLOCK {
            // One block: no threads to wake (a bootstrap refits small sets
            // hundreds of times).
            return self.block_sums(&laser, self.indices);
        }
        let blocks: Vec<Sums> =
            self.indices.par_chunks(BLOCK).map(|block| self.block_sums(&laser, block)).collect();
        blocks.iter().fold(Sums::default(), |total, b| total.add(b))
    }
}

/// The normal equations of `laser`'s residuals over `indices`: J^T J
/// (p x p) and J^T r (p) over the parameters of `layout`, summed in order
/// on this thread. `None` where a sample's ray misses the laser plane.
pub(crate) fn normal_equations(
    samples: &[LaserSample],
    indices: &[usize],
    laser: &LaserModel,
    layout: Layout,
    residual: Residual,
) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let problem = Problem::new(samples, indices, layout, residual);
    let p = problem.p();
    let sums = problem.block_sums(&laser.prepare(), indices);
    (!sums.invalid).then(|| sums.normal_equations(p))
}

/// Solves `(A + lambda diag(A)) x = -b` over the first `p` parameters
/// (Marquardt's scaling), or `None` where it is singular.
fn damped_step(sums: &Sums, p: usize, lambda: f64) -> Option<Vector4<f64>> {
    let (a, b) = sums.normal_equations(p);
    let mut damped = a.clone();
    for k in 0..p {
        damped[(k, k)] += lambda * a[(k, k)];
    }
    let x = damped.cholesky()?.solve(&-b);
    let mut step = Vector4::zeros();
    step.rows_mut(0, p).copy_from(&x);
    step.iter().all(|v| v.is_finite()).then_some(step)
}

/// Refines `initial` on the samples `indices` by minimizing `residual`
/// over the parameters of `layout` (the others held at `initial`'s):
/// Levenberg-Marquardt on the normal equations. With two to four
/// parameters and up to millions of samples, each iteration is one pass
/// that sums J^T J and J^T r (no N x p Jacobian is stored, and the pass runs
/// in parallel), and the step is a 4 x 4 solve at most.
pub(crate) fn refine(
    samples: &[LaserSample],
    indices: &[usize],
    initial: &LaserModel,
    layout: Layout,
    residual: Residual,
) -> Result<Refined> {
    let problem = Problem::new(samples, indices, layout, residual);
    let p = problem.p();
    let mut params: Params = full_parameters(initial);
    let mut current = problem.sums(&params);
    let failed = |params: &Params, why: &str| {
        let laser = problem.laser(params);
        Error::FitFailed(format!(
            "Levenberg-Marquardt ended at alpha {:.3} deg, L0 {:.3} mm, beta {:.3} deg, slide scale {:.5} ({why})",
            laser.alpha_deg(),
            laser.l0_mm,
            laser.beta_deg(),
            laser.slide_scale,
        ))
    };
    if current.invalid || !current.cost.is_finite() {
        return Err(failed(&params, "a sample's ray misses the starting laser plane"));
    }
    let mut lambda = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        let Some(step) = damped_step(&current, p, lambda) else {
            lambda *= 10.0;
            if lambda > 1e16 {
                break;
            }
            continue;
        };
        let scaled_step =
            (0..p).map(|k| step[k].abs() * current.jtj[(k, k)].sqrt()).fold(0.0, f64::max);
        if scaled_step <= SCALED_STEP_TOLERANCE {
            break;
        }
        let mut trial_params: Params = params;
        for (k, &place) in problem.places[..p].iter().enumerate() {
            trial_params[place] += step[k];
        }
        let trial = problem.sums(&trial_params);
        if trial.invalid || !(trial.cost.is_finite() && trial.cost <= current.cost) {
            lambda *= 10.0;
            if lambda > 1e16 {
                break;
            }
            continue;
        }
        let decrease = current.cost - trial.cost;
        params = trial_params;
        current = trial;
        lambda = (lambda / 10.0).max(1e-12);
        if decrease <= RELATIVE_COST_TOLERANCE * current.cost.max(f64::MIN_POSITIVE) {
            break;
        }
    }
    let laser = problem.laser(&params);
    if laser.validate().is_err() || !current.cost.is_finite() {
        return Err(failed(&params, "not a valid laser"));
    }
    let n = indices.len();
    let covariance = (n > p).then(|| {
        let sigma2 = current.cost / (n - p) as f64;
        current.normal_equations(p).0.try_inverse().map(|inv| inv * sigma2)
    });
    Ok(Refined { laser, covariance: covariance.flatten() })
}
