//! A small generic RANSAC driver (Fischler and Bolles; the seed paper's
//! Algorithm 1) with adaptive stopping, reusable by every robust fit.
//!
//! Algorithm 1 draws k_max random minimal subsets, counts the samples within
//! epsilon of each hypothesis and keeps the largest inlier set. This driver
//! does the same, and stops early once the best inlier ratio w makes another
//! all-inlier draw unlikely to have been missed:
//! `k >= ln(1 - confidence) / ln(1 - w^m)` for minimal sample size m.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A model family that RANSAC can fit.
pub trait Estimator {
    /// The fitted model.
    type Model;

    /// Number of data points.
    fn len(&self) -> usize;

    /// Whether there are no data points.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Minimal number of points for one hypothesis.
    fn sample_size(&self) -> usize;

    /// A hypothesis through the points `indices` (of length `sample_size()`),
    /// or `None` when the subset is degenerate.
    fn fit_minimal(&self, indices: &[usize]) -> Option<Self::Model>;

    /// Absolute residual of point `index` under `model` (may be infinite).
    fn residual(&self, model: &Self::Model, index: usize) -> f64;

    /// A least-squares model through the points `indices` (the inliers of
    /// a hypothesis), for [`ransac_refit`]; `None` when it cannot be fitted
    /// (too few points, degenerate). Estimators without one keep the
    /// minimal-sample hypothesis.
    fn refit(&self, indices: &[usize]) -> Option<Self::Model> {
        let _ = indices;
        None
    }
}

/// RANSAC settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacOptions {
    /// epsilon of Algorithm 1: a point is an inlier if its residual is at most this.
    pub threshold: f64,
    /// Probability of having drawn at least one all-inlier subset before stopping.
    pub confidence: f64,
    /// k_max of Algorithm 1: the cap on hypotheses.
    pub max_iterations: usize,
    /// Seed of the subset sampler: same seed, same result.
    pub seed: u64,
}

/// What RANSAC found.
#[derive(Debug, Clone)]
pub struct RansacOutcome<M> {
    /// The best hypothesis (before any refit).
    pub model: M,
    /// Indices of its inliers, ascending.
    pub inliers: Vec<usize>,
    /// Hypotheses drawn.
    pub iterations: usize,
}

/// Hypotheses needed so that an all-inlier subset of size `m` is drawn with
/// probability `confidence` when a fraction `inlier_ratio` are inliers.
pub fn required_iterations(inlier_ratio: f64, m: usize, confidence: f64) -> f64 {
    let all_inlier = inlier_ratio.powi(m as i32);
    if all_inlier >= 1.0 {
        return 1.0;
    }
    if all_inlier <= 0.0 {
        return f64::INFINITY;
    }
    ((1.0 - confidence).ln() / (1.0 - all_inlier).ln()).ceil().max(1.0)
}

/// Runs RANSAC: the hypothesis with most inliers (ties broken by the smaller
/// sum of squared inlier residuals), or `None` if no subset gave a model.
pub fn ransac<E: Estimator>(
    estimator: &E,
    options: &RansacOptions,
) -> Option<RansacOutcome<E::Model>> {
    let n = estimator.len();
    let m = estimator.sample_size();
    if n < m || m == 0 {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut best: Option<(E::Model, usize, f64)> = None;
    let mut needed = options.max_iterations as f64;
    let mut iterations = 0;
    while iterations < options.max_iterations && (iterations as f64) < needed {
        iterations += 1;
        // 1. Hypothesis generation: a random minimal subset.
        let subset = rand::seq::index::sample(&mut rng, n, m).into_vec();
        let Some(model) = estimator.fit_minimal(&subset) else { continue };
        // 2. Verification: count the samples within epsilon.
        let (mut count, mut cost) = (0usize, 0.0);
        for i in 0..n {
            let r = estimator.residual(&model, i);
            if r <= options.threshold {
                count += 1;
                cost += r * r;
            }
        }
        let better = match &best {
            None => count > 0,
            Some((_, best_count, best_cost)) => {
                count > *best_count || (count == *best_count && cost < *best_cost)
            }
        };
        if better {
            best = Some((model, count, cost));
            needed = required_iterations(count as f64 / n as f64, m, options.confidence);
        }
    }
    let (model, _, _) = best?;
    let inliers = inliers(estimator, &model, options.threshold);
    Some(RansacOutcome { model, inliers, iterations })
}

/// [`ransac`], then up to `rounds` refits of the model to its inliers
/// ([`Estimator::refit`]), the inliers taken anew after each, until they no
/// longer change or a refit fails (the last model and its inliers are kept).
pub fn ransac_refit<E: Estimator>(
    estimator: &E,
    options: &RansacOptions,
    rounds: usize,
) -> Option<RansacOutcome<E::Model>> {
    let mut outcome = ransac(estimator, options)?;
    for _ in 0..rounds {
        let Some(model) = estimator.refit(&outcome.inliers) else { break };
        let inliers = inliers(estimator, &model, options.threshold);
        let stable = inliers == outcome.inliers;
        outcome.model = model;
        outcome.inliers = inliers;
        if stable {
            break;
        }
    }
    Some(outcome)
}

/// Indices of the points within `threshold` of `model`.
pub fn inliers<E: Estimator>(estimator: &E, model: &E::Model, threshold: f64) -> Vec<usize> {
    (0..estimator.len()).filter(|&i| estimator.residual(model, i) <= threshold).collect()
}
