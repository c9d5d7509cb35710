//! One test harness for every camera and laser model (after kalibr's
//! `CameraGeometryTestHarness`): analytic Jacobians against central finite
//! differences, round trips, finite outputs.

// Test helpers outside `#[test]` functions, where clippy.toml's
// allow-*-in-tests does not reach: failing loudly is their job.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::{DMatrix, DVector};

/// A differentiable map R^n -> R^m under test.
pub trait Differentiable {
    /// Name used in failure messages.
    fn name(&self) -> String;
    /// The value, or `None` where the map is undefined.
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>>;
    /// The analytic Jacobian (m x n).
    fn jacobian(&self, x: &DVector<f64>) -> Option<DMatrix<f64>>;
}

/// Central finite-difference Jacobian.
pub fn numeric_jacobian(f: &dyn Differentiable, x: &DVector<f64>) -> DMatrix<f64> {
    let y0 = f.eval(x).expect("defined at x");
    let mut jac = DMatrix::zeros(y0.len(), x.len());
    for j in 0..x.len() {
        let h = 1e-6 * x[j].abs().max(1.0);
        let mut xp = x.clone();
        let mut xm = x.clone();
        xp[j] += h;
        xm[j] -= h;
        let yp = f.eval(&xp).expect("defined at x + h");
        let ym = f.eval(&xm).expect("defined at x - h");
        jac.set_column(j, &((yp - ym) / (2.0 * h)));
    }
    jac
}

/// Asserts that the analytic Jacobian matches finite differences at `x`,
/// element by element, within `tol * max(1, |element|)`.
pub fn assert_jacobian(f: &dyn Differentiable, x: &DVector<f64>, tol: f64) {
    let analytic = f.jacobian(x).expect("jacobian defined at x");
    let numeric = numeric_jacobian(f, x);
    assert_eq!(analytic.shape(), numeric.shape(), "{}: Jacobian shape", f.name());
    for (a, n) in analytic.iter().zip(numeric.iter()) {
        assert!(a.is_finite(), "{}: non-finite Jacobian at {x}", f.name());
        assert!(
            (a - n).abs() <= tol * n.abs().max(1.0),
            "{}: analytic Jacobian\n{analytic}\ndiffers from numeric\n{numeric}\nat {x}",
            f.name()
        );
    }
}

/// Asserts that `f` is defined and finite at `x`.
pub fn assert_finite(f: &dyn Differentiable, x: &DVector<f64>) {
    let y = f.eval(x).unwrap_or_else(|| panic!("{}: undefined at {x}", f.name()));
    assert!(y.iter().all(|v| v.is_finite()), "{}: non-finite value {y} at {x}", f.name());
}

/// Asserts `inverse(forward(x)) == x` within `tol` (max-norm).
pub fn assert_round_trip(
    name: &str,
    forward: impl Fn(&DVector<f64>) -> Option<DVector<f64>>,
    inverse: impl Fn(&DVector<f64>) -> Option<DVector<f64>>,
    x: &DVector<f64>,
    tol: f64,
) {
    let y = forward(x).unwrap_or_else(|| panic!("{name}: forward undefined at {x}"));
    let back = inverse(&y).unwrap_or_else(|| panic!("{name}: inverse undefined at {y}"));
    let err = (back - x).amax();
    assert!(err <= tol, "{name}: round trip error {err:e} > {tol:e} at {x}");
}
