//! The linear form of the laser model, for closed-form estimates.
//!
//! Eq. (7) rearranged: `1/z = (sin a - u cos a - v tan b) / L`, which is
//! linear in `p = (sin a / L, cos a / L, tan b / L)`:
//!
//! ```text
//! p1 - u p2 - v p3 = 1/z                       (one slide position, L fixed)
//! p1 - u p2 - v p3 + d/z q = 1/z,  q = k/L0    (several slide positions)
//! ```
//!
//! with `p` divided by L0 in the second form, so that `hypot(p1, p2) = 1/L0`
//! and the slide scale k of L = L0 - k d is `q L0` (held at 1, `q = 1/L0`,
//! where the fit does not free it). Three samples (two for the
//! low-fidelity model, where p3 = 0; one more with several slide positions)
//! give a minimal solver for RANSAC hypotheses; all samples, weighted by z^2
//! so that the algebraic residual approximates the depth residual of
//! eq. (9), give the initial estimate for the nonlinear refinement.

use alacs_model::{Fidelity, LaserModel};
use nalgebra::{DMatrix, DVector, Matrix4, Vector4};

use crate::LaserSample;
use crate::refine::Layout;

/// Slide positions closer together than this are treated as one: the
/// column for 1/L0 would be nearly parallel to the right-hand side, leaving
/// L0 undetermined by the linear form.
const MIN_SLIDE_SPREAD_MM: f64 = 10.0;

/// Samples away from the main slide position make the slide a parameter
/// (the k/L0 column) only when there are at least this many: a stray
/// sample or two at another position (a mistyped `slide_mm`) cannot fix k
/// and L0 apart, and minimal samples drawn from the main position alone
/// would all be degenerate. With fewer, the samples share the main
/// position's model (k = 1) and the strays are judged by it.
const MIN_SAMPLES_AT_OTHER_SLIDES: usize = 8;

/// Singular-value ratio (of the column-scaled design) below which the
/// samples do not determine the parameters.
const RANK_TOLERANCE: f64 = 1e-9;

/// The linear system for one set of samples.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LinearForm {
    fidelity: Fidelity,
    /// `Some(d)` when every sample shares (to `MIN_SLIDE_SPREAD_MM`) slide travel d.
    common_slide_mm: Option<f64>,
    /// Whether several slide positions free the slide scale k.
    fit_slide_scale: bool,
}

impl LinearForm {
    /// The form for `samples`; several slide positions add the k/L0 column,
    /// and free k where `fit_slide_scale`.
    pub(crate) fn new<'a>(
        fidelity: Fidelity,
        samples: impl IntoIterator<Item = &'a LaserSample>,
        fit_slide_scale: bool,
    ) -> Self {
        let mut slides: Vec<f64> = samples.into_iter().map(|s| s.slide_mm).collect();
        slides.sort_by(f64::total_cmp);
        // The most samples within one slide position's spread, and their mean.
        let (mut best, mut best_sum, mut sum, mut start) = (0usize, 0.0, 0.0, 0usize);
        for (end, &d) in slides.iter().enumerate() {
            sum += d;
            while d - slides[start] >= MIN_SLIDE_SPREAD_MM {
                sum -= slides[start];
                start += 1;
            }
            if end + 1 - start > best {
                (best, best_sum) = (end + 1 - start, sum);
            }
        }
        let others = slides.len() - best;
        let common_slide_mm =
            (others < MIN_SAMPLES_AT_OTHER_SLIDES).then(|| best_sum / best.max(1) as f64);
        Self { fidelity, common_slide_mm, fit_slide_scale }
    }

    /// The model's fidelity.
    pub(crate) fn fidelity(&self) -> Fidelity {
        self.fidelity
    }

    /// The parameters the nonlinear refinement frees: k where the samples
    /// span several slide positions and the caller asked for it.
    pub(crate) fn layout(&self) -> Layout {
        Layout {
            fidelity: self.fidelity,
            slide_scale: self.fit_slide_scale && self.common_slide_mm.is_none(),
        }
    }

    /// Number of unknowns, which is also the minimal sample size.
    pub(crate) fn unknowns(&self) -> usize {
        let angles = match self.fidelity {
            Fidelity::Low => 2,
            Fidelity::High => 3,
        };
        angles + usize::from(self.common_slide_mm.is_none())
    }

    /// One row `a · p = b` of the system (entries past `unknowns()` are 0).
    fn row(&self, s: &LaserSample) -> (Vector4<f64>, f64) {
        let w = 1.0 / s.z_mm;
        let mut a = Vector4::zeros();
        a[0] = 1.0;
        a[1] = -s.u_n;
        let mut next = 2;
        if self.fidelity == Fidelity::High {
            a[2] = -s.v_n;
            next = 3;
        }
        if self.common_slide_mm.is_none() {
            a[next] = s.slide_mm * w;
        }
        (a, w)
    }

    /// The model from a solution `p` of the system, if it describes a laser
    /// in front of the camera.
    fn model(&self, p: &[f64]) -> Option<LaserModel> {
        let tan_term = if self.fidelity == Fidelity::High { p[2] } else { 0.0 };
        let (l0_mm, tan_beta, slide_scale) = match self.common_slide_mm {
            // p = (sin a, cos a, tan b) / L, L = L0 - d (k = 1: one slide
            // position cannot tell k from L0).
            Some(slide_mm) => {
                let l_mm = 1.0 / p[0].hypot(p[1]);
                (l_mm + slide_mm, tan_term * l_mm, 1.0)
            }
            // p = (sin a, cos a, tan b, k) / L0.
            None => {
                let q = p[self.unknowns() - 1];
                if self.fit_slide_scale {
                    let l0_mm = 1.0 / p[0].hypot(p[1]);
                    (l0_mm, tan_term * l0_mm, q * l0_mm)
                } else {
                    (1.0 / q, tan_term / q, 1.0)
                }
            }
        };
        let laser = LaserModel::new(self.fidelity, p[0].atan2(p[1]), tan_beta.atan(), l0_mm)
            .with_slide_scale(slide_scale);
        laser.validate().ok().map(|()| laser)
    }

    /// Minimal solver: the model through exactly `unknowns()` samples, or
    /// `None` for a degenerate subset.
    pub(crate) fn solve_minimal(&self, subset: &[&LaserSample]) -> Option<LaserModel> {
        let k = self.unknowns();
        let mut a = DMatrix::zeros(k, k);
        let mut b = DVector::zeros(k);
        for (i, s) in subset.iter().take(k).enumerate() {
            let (row, rhs) = self.row(s);
            for j in 0..k {
                a[(i, j)] = row[j];
            }
            b[i] = rhs;
        }
        let p = a.lu().solve(&b)?;
        self.model(p.as_slice())
    }

    /// Weighted least squares over `samples` (rows weighted by z^2, so the
    /// residual approximates the depth error). `None` when the samples do not
    /// determine the parameters.
    pub(crate) fn solve_least_squares<'a>(
        &self,
        samples: impl Iterator<Item = &'a LaserSample>,
    ) -> Option<LaserModel> {
        let k = self.unknowns();
        // Normal equations: k <= 4 unknowns, one pass, no allocation per sample.
        let mut ata = Matrix4::<f64>::zeros();
        let mut atb = Vector4::<f64>::zeros();
        for s in samples {
            let (row, rhs) = self.row(s);
            let weight = s.z_mm * s.z_mm;
            let (row, rhs) = (row * weight, rhs * weight);
            ata += row * row.transpose();
            atb += row * rhs;
        }
        // Values far outside any camera's range can overflow the sums; such
        // a system determines nothing.
        if !(ata.iter().all(|v| v.is_finite()) && atb.iter().all(|v| v.is_finite())) {
            return None;
        }
        // Equilibrate columns so the rank test compares like with like.
        let scale = Vector4::from_fn(|i, _| {
            if i < k && ata[(i, i)] > 0.0 { 1.0 / ata[(i, i)].sqrt() } else { 0.0 }
        });
        let scaled = DMatrix::from_fn(k, k, |i, j| ata[(i, j)] * scale[i] * scale[j]);
        let rhs = DVector::from_fn(k, |i, _| atb[i] * scale[i]);
        let svd = scaled.svd(true, true);
        let max = svd.singular_values.max();
        let min = svd.singular_values.min();
        // Singular values of A^T A are squares of those of A.
        if max.is_nan() || max <= 0.0 || (min / max).sqrt() < RANK_TOLERANCE {
            return None;
        }
        let y = svd.solve(&rhs, 0.0).ok()?;
        let p: Vec<f64> = (0..k).map(|i| y[i] * scale[i]).collect();
        self.model(&p)
    }
}
