//! The seed paper's four calibration methods (Section 4.1, Table 1).

use alacs_model::{Fidelity, LaserModel, PreparedLaser};

use crate::linear::LinearForm;
use crate::refine::{Layout, Residual, refine};
use crate::uncertainty::{StdSource, at_least, bootstrap_samples};
use crate::{Error, LaserSample, Result, validate_samples};
use alacs_model::ransac::{self, Estimator, RansacOptions};

/// The four methods of the seed paper's Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Method 1: low-fidelity model (beta = 0), all data.
    LowFidelityAllData,
    /// Method 2: low-fidelity model, RANSAC.
    LowFidelityRansac,
    /// Method 3: high-fidelity model, all data.
    HighFidelityAllData,
    /// Method 4: high-fidelity model, RANSAC (Algorithm 1): the seed's method and the default.
    HighFidelityRansac,
}

impl Method {
    /// All four, in the paper's order.
    pub const ALL: [Method; 4] = [
        Method::LowFidelityAllData,
        Method::LowFidelityRansac,
        Method::HighFidelityAllData,
        Method::HighFidelityRansac,
    ];

    /// The paper's number, 1 to 4.
    pub fn number(self) -> u8 {
        match self {
            Method::LowFidelityAllData => 1,
            Method::LowFidelityRansac => 2,
            Method::HighFidelityAllData => 3,
            Method::HighFidelityRansac => 4,
        }
    }

    /// The method with the paper's number `n`.
    pub fn from_number(n: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.number() == n)
    }

    /// The paper's name, e.g. `High-fidelity model + RANSAC`.
    pub fn name(self) -> &'static str {
        match self {
            Method::LowFidelityAllData => "Low-fidelity model + All data",
            Method::LowFidelityRansac => "Low-fidelity model + RANSAC",
            Method::HighFidelityAllData => "High-fidelity model + All data",
            Method::HighFidelityRansac => "High-fidelity model + RANSAC",
        }
    }

    /// Which model the method fits.
    pub fn fidelity(self) -> Fidelity {
        match self {
            Method::LowFidelityAllData | Method::LowFidelityRansac => Fidelity::Low,
            Method::HighFidelityAllData | Method::HighFidelityRansac => Fidelity::High,
        }
    }

    /// Whether the method rejects outliers with RANSAC.
    pub fn is_robust(self) -> bool {
        matches!(self, Method::LowFidelityRansac | Method::HighFidelityRansac)
    }
}

/// Default inlier threshold epsilon: 2 mm, four standard deviations of the
/// 0.5 mm depth noise that the paper's Method 4 residual (0.39 mm mean) implies.
pub const DEFAULT_THRESHOLD_MM: f64 = 2.0;

/// Calibration settings; `Default` gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationOptions {
    /// What the least-squares step minimizes.
    pub residual: Residual,
    /// RANSAC inlier threshold epsilon on |z - z_hat|, in mm.
    pub threshold_mm: f64,
    /// RANSAC stopping confidence.
    pub confidence: f64,
    /// RANSAC cap on hypotheses (k_max).
    pub max_iterations: usize,
    /// RANSAC seed.
    pub seed: u64,
    /// Fit the slide scale k (L = L0 - k d) where the samples span two or
    /// more slide positions; `false` holds k = 1, the seed paper's model.
    pub fit_slide_scale: bool,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            residual: Residual::Depth,
            threshold_mm: DEFAULT_THRESHOLD_MM,
            confidence: 0.999,
            max_iterations: 2000,
            seed: 0,
            fit_slide_scale: true,
        }
    }
}

/// One standard deviation of each fitted parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterStdDev {
    /// Of alpha, degrees.
    pub alpha_deg: f64,
    /// Of L0, mm.
    pub l0_mm: f64,
    /// Of beta, degrees (`None` for the low-fidelity model).
    pub beta_deg: Option<f64>,
    /// Of the slide scale k (`None` where k was not fitted).
    pub slide_scale: Option<f64>,
    /// How they were estimated.
    pub source: StdSource,
}

impl ParameterStdDev {
    /// As laser.yaml's `std_dev` block holds them, the source in words.
    pub fn to_laser_std(&self) -> alacs_model::LaserStdDev {
        alacs_model::LaserStdDev {
            alpha_deg: self.alpha_deg,
            beta_deg: self.beta_deg,
            l0_mm: self.l0_mm,
            slide_scale: self.slide_scale,
            source: self.source.describe(),
        }
    }

    /// From standard deviations of the parameters of `layout`, in its order.
    pub(crate) fn from_parameters(std: &[f64], layout: Layout, source: StdSource) -> Option<Self> {
        let (alpha, l0) = (*std.first()?, *std.get(1)?);
        let all_finite = std.len() == layout.len() && std.iter().all(|s| s.is_finite());
        all_finite.then(|| ParameterStdDev {
            alpha_deg: alpha.to_degrees(),
            l0_mm: l0,
            beta_deg: layout.beta_index().map(|k| std[k].to_degrees()),
            slide_scale: layout.slide_scale_index().map(|k| std[k]),
            source,
        })
    }

    /// The standard deviations of (alpha rad, L0 mm[, beta rad][, k]), as
    /// [`Self::from_parameters`] takes them.
    pub(crate) fn to_parameters(self) -> Vec<f64> {
        let mut std = vec![self.alpha_deg.to_radians(), self.l0_mm];
        std.extend(self.beta_deg.map(f64::to_radians));
        std.extend(self.slide_scale);
        std
    }
}

/// The result of one calibration method.
#[derive(Debug, Clone)]
pub struct LaserCalibration {
    /// Which method.
    pub method: Method,
    /// The fitted laser.
    pub laser: LaserModel,
    /// 0-based indices of the samples the final fit used (all for methods 1 and 3).
    pub inliers: Vec<usize>,
    /// Whether the slide scale k was fitted (two or more slide positions
    /// and [`CalibrationOptions::fit_slide_scale`]); else it is 1.
    pub slide_scale_fitted: bool,
    /// Number of samples given.
    pub n_samples: usize,
    /// Mean |z - z_hat| over `inliers`, the paper's Table 1 metric.
    pub mean_abs_error_mm: f64,
    /// Mean |z - z_hat| over all samples.
    pub mean_abs_error_all_mm: f64,
    /// Root mean square of z - z_hat over `inliers`.
    pub rms_error_mm: f64,
    /// Parameter standard deviations, where defined: over board poses where
    /// the samples name theirs (see `uncertainty`), else the fit's covariance.
    pub std_dev: Option<ParameterStdDev>,
    /// Hypotheses RANSAC drew (robust methods only).
    pub ransac_iterations: Option<usize>,
    /// What the least-squares step minimized.
    pub residual: Residual,
    /// The inlier threshold the robust fit ended with, mm: `--threshold-mm`,
    /// or more where the model's residual scale asked for it (see
    /// `robust_fit`); the option's value for methods 1 and 3.
    pub threshold_mm: f64,
}

/// Rounds of "refit on the inliers, re-classify with the refit model" after
/// RANSAC; the set is normally stable after one.
const MAX_REFIT_ROUNDS: usize = 5;

/// How many times more samples than chance the RANSAC consensus must
/// explain. Chance is measured, not assumed: the same samples with their
/// depths shuffled among them (the pixels keep their places, so any laser
/// relation is broken while the distributions stay) go through the same
/// RANSAC, and the count it finds there is what a laser-free data set
/// gives. On simulated paper-like sets of 30 samples (seeds 1-5) that are
/// all outliers the consensus holds 6-7 samples where chance finds 5-6
/// (17-20 %); with 30 % outliers it holds 21 (70 %). 1.5 keeps clear of
/// both, and of a good session with few board depths, where shuffled
/// depths from one depth can agree with a near-constant-depth plane.
const MIN_CONSENSUS_OVER_CHANCE: f64 = 1.5;

/// The most samples the chance test shuffles (a random subset beyond);
/// counts are compared as fractions.
const CHANCE_TEST_SAMPLES: usize = 2000;

/// Relative depth spread (max - min over the median) below which the samples
/// count as taken at one depth: one board distance cannot separate L0 from alpha.
const MIN_RELATIVE_DEPTH_SPREAD: f64 = 0.01;

/// Ratio of the minor to the major spread of the laser pixels (u_n, v_n)
/// below which they count as collinear: one line in the image is one line in
/// space, and many planes contain it.
const MIN_IMAGE_SPREAD_RATIO: f64 = 1e-3;

/// Calibrates the laser from `samples` with `method`.
pub fn calibrate(
    samples: &[LaserSample],
    method: Method,
    options: &CalibrationOptions,
) -> Result<LaserCalibration> {
    validate_samples(samples)?;
    let fidelity = method.fidelity();
    let form = LinearForm::new(fidelity, samples, options.fit_slide_scale);
    let layout = form.layout();
    check_geometry(samples, fidelity, form.unknowns() + 1)?;

    let mut threshold_mm = options.threshold_mm;
    let (laser, inliers, covariance, ransac_iterations) = if method.is_robust() {
        let (refined, inliers, iterations, threshold) = robust_fit(samples, &form, options)?;
        threshold_mm = threshold;
        (refined.laser, inliers, refined.covariance, Some(iterations))
    } else {
        let all: Vec<usize> = (0..samples.len()).collect();
        let initial = form.solve_least_squares(samples.iter()).ok_or_else(|| {
            Error::Degenerate("the linear system of eq. (7) is rank deficient".into())
        })?;
        let refined = refine(samples, &all, &initial, layout, options.residual)?;
        (refined.laser, all, refined.covariance, None)
    };

    let prepared = laser.prepare();
    let errors: Vec<f64> = samples.iter().map(|s| depth_error(&prepared, s).abs()).collect();
    let mean = |indices: &mut dyn Iterator<Item = usize>| {
        let (sum, count) = indices.fold((0.0, 0usize), |(sum, n), i| (sum + errors[i], n + 1));
        sum / count.max(1) as f64
    };
    let rms = (inliers.iter().map(|&i| errors[i] * errors[i]).sum::<f64>()
        / inliers.len().max(1) as f64)
        .sqrt();
    let covariance_std: Option<Vec<f64>> =
        covariance.map(|c| (0..c.nrows()).map(|k| c[(k, k)].max(0.0).sqrt()).collect());
    // Samples that name their board poses get standard deviations over the
    // poses (none from fewer than MIN_BOOTSTRAP_POSES: a spread over so few
    // says nothing, and the covariance's would understate it); samples
    // without poses are taken as independent.
    let with_poses = !inliers.is_empty() && inliers.iter().all(|&i| samples[i].pose.is_some());
    let std_dev = if with_poses {
        bootstrap_samples(samples, &inliers, &laser, layout, options.residual, options.seed)
            .and_then(|(std, source)| {
                let std = at_least(&std, covariance_std.as_deref());
                ParameterStdDev::from_parameters(&std, layout, source)
            })
    } else {
        covariance_std
            .and_then(|std| ParameterStdDev::from_parameters(&std, layout, StdSource::Covariance))
    };
    Ok(LaserCalibration {
        method,
        laser,
        mean_abs_error_mm: mean(&mut inliers.iter().copied()),
        mean_abs_error_all_mm: mean(&mut (0..samples.len())),
        rms_error_mm: rms,
        inliers,
        slide_scale_fitted: layout.slide_scale,
        n_samples: samples.len(),
        std_dev,
        ransac_iterations,
        residual: options.residual,
        threshold_mm,
    })
}

/// The paper's four methods on the same samples (Table 1): the methods
/// that fitted, and for each that could not, why.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The calibrations that fitted, in the paper's order.
    pub fitted: Vec<LaserCalibration>,
    /// The methods that could not fit the samples, with the reason (the
    /// low-fidelity model cannot model a laser tilted in beta, a refinement
    /// diverged, ...), in the paper's order.
    pub failed: Vec<(Method, String)>,
}

impl Comparison {
    /// The calibration of `method`, if it fitted.
    pub fn get(&self, method: Method) -> Option<&LaserCalibration> {
        self.fitted.iter().find(|c| c.method == method)
    }
}

/// All four methods on the same samples, as the paper's Table 1. One
/// method that cannot fit is a row with its reason, not the end of the
/// table; the comparison fails only when Method 4 (high fidelity with
/// RANSAC, the one calibrations use) fails, with its error.
pub fn compare(samples: &[LaserSample], options: &CalibrationOptions) -> Result<Comparison> {
    let mut comparison = Comparison { fitted: Vec::new(), failed: Vec::new() };
    for method in Method::ALL {
        match calibrate(samples, method, options) {
            Ok(fit) => comparison.fitted.push(fit),
            Err(error) if method == Method::HighFidelityRansac => return Err(error),
            Err(error) => {
                let reason = match method.fidelity() {
                    Fidelity::Low => format!("{error} (the low-fidelity model has no beta)"),
                    Fidelity::High => error.to_string(),
                };
                comparison.failed.push((method, reason));
            }
        }
    }
    Ok(comparison)
}

/// z - z_hat for one sample under `laser` (eq. (9)'s residual).
pub fn depth_error_mm(laser: &LaserModel, sample: &LaserSample) -> f64 {
    depth_error(&laser.prepare(), sample)
}

/// [`depth_error_mm`] with the trigonometry evaluated once.
fn depth_error(laser: &PreparedLaser, sample: &LaserSample) -> f64 {
    sample.z_mm
        - laser.model.laser_distance_mm(sample.slide_mm) / laser.denominator(&sample.normalized())
}

/// Rejects sample sets that cannot determine the parameters, naming why.
fn check_geometry(samples: &[LaserSample], fidelity: Fidelity, need: usize) -> Result<()> {
    if samples.len() < need {
        return Err(Error::TooFewSamples { got: samples.len(), need, model: fidelity.as_str() });
    }
    let mut depths: Vec<f64> = samples.iter().map(|s| s.z_mm).collect();
    let (min, max) = depths
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| (lo.min(z), hi.max(z)));
    let middle = depths.len() / 2;
    let median = *depths.select_nth_unstable_by(middle, f64::total_cmp).1;
    if max - min < MIN_RELATIVE_DEPTH_SPREAD * median {
        return Err(Error::Degenerate(format!(
            "all samples lie at one depth (z {min:.1}..{max:.1} mm); place the board at several distances (the paper uses 0.6-1.2 m)"
        )));
    }
    if fidelity == Fidelity::High {
        let n = samples.len() as f64;
        let (mu, mv) = samples.iter().fold((0.0, 0.0), |(a, b), s| (a + s.u_n / n, b + s.v_n / n));
        let (suu, suv, svv) = samples.iter().fold((0.0, 0.0, 0.0), |(a, b, c), s| {
            let (du, dv) = (s.u_n - mu, s.v_n - mv);
            (a + du * du, b + du * dv, c + dv * dv)
        });
        // Eigenvalues of the 2x2 scatter matrix.
        let half_trace = 0.5 * (suu + svv);
        let root = (0.25 * (suu - svv).powi(2) + suv * suv).sqrt();
        let (major, minor) = (half_trace + root, (half_trace - root).max(0.0));
        if major <= 0.0 || (minor / major).sqrt() < MIN_IMAGE_SPREAD_RATIO {
            return Err(Error::Degenerate(
                "the laser pixels are collinear in the image, which leaves beta undetermined; use laser points from several board positions".into(),
            ));
        }
    }
    Ok(())
}

/// RANSAC over the linear minimal solver, then LM refits on the inliers
/// until the inlier set is stable.
fn robust_fit_at(
    samples: &[LaserSample],
    form: &LinearForm,
    options: &CalibrationOptions,
) -> Result<(crate::refine::Refined, Vec<usize>, usize)> {
    let estimator = LaserEstimator { samples, form };
    let ransac_options = RansacOptions {
        threshold: options.threshold_mm,
        confidence: options.confidence,
        max_iterations: options.max_iterations,
        seed: options.seed,
    };
    let need = form.unknowns() + 1;
    let no_consensus = |best| Error::NoConsensus {
        best,
        n: samples.len(),
        threshold_mm: options.threshold_mm,
        need,
    };
    let outcome = ransac::ransac(&estimator, &ransac_options).ok_or_else(|| no_consensus(0))?;
    if outcome.inliers.len() < need {
        return Err(no_consensus(outcome.inliers.len()));
    }
    check_better_than_chance(samples, form, &ransac_options, outcome.inliers.len())?;
    let mut inliers = outcome.inliers;
    let mut laser = outcome.model.model;
    for _ in 0..MAX_REFIT_ROUNDS {
        if inliers.len() < need {
            return Err(no_consensus(inliers.len()));
        }
        let refined = refine(samples, &inliers, &laser, form.layout(), options.residual)?;
        let next = ransac::inliers(&estimator, &refined.laser.prepare(), options.threshold_mm);
        if next == inliers || next.len() < need {
            return Ok((refined, inliers, outcome.iterations));
        }
        laser = refined.laser;
        inliers = next;
    }
    let refined = refine(samples, &inliers, &laser, form.layout(), options.residual)?;
    Ok((refined, inliers, outcome.iterations))
}

/// The inlier threshold follows each model's residual scale (MSAC and
/// MAGSAC choose it so too): `--threshold-mm` (2 mm: four sigma of the
/// paper's 0.5 mm depth noise) fits the high-fidelity model, whose
/// residuals are the noise, but not the low-fidelity model, whose own bias
/// (beta left out) reaches several mm at the image's top and bottom rows:
/// at 2 mm its consensus can be a band of rows, no better than chance, and
/// a fit that extrapolates badly to the rest of the working volume. So
/// after each robust fit the threshold becomes [`SCALE_THRESHOLD_FACTOR`]
/// times the fit's robust residual scale (least median of squares:
/// 1.4826 (1 + 5 / (n - p)) sqrt(median r^2), which holds up to half the
/// samples being outliers), never below `--threshold-mm` nor above
/// [`MAX_THRESHOLD_FACTOR`] times it, and the fit is repeated until the
/// threshold stands. A low-fidelity fit with no clear consensus tries twice
/// the threshold (its bias is not known before a fit); a high-fidelity
/// model's residuals are the noise, and no consensus at the noise's
/// threshold is an answer (samples that are all outliers are refused).
fn robust_fit(
    samples: &[LaserSample],
    form: &LinearForm,
    options: &CalibrationOptions,
) -> Result<(crate::refine::Refined, Vec<usize>, usize, f64)> {
    let ceiling = MAX_THRESHOLD_FACTOR * options.threshold_mm;
    let mut threshold = options.threshold_mm;
    for _ in 0..MAX_SCALE_ROUNDS {
        let at = CalibrationOptions { threshold_mm: threshold, ..*options };
        match robust_fit_at(samples, form, &at) {
            Ok((refined, inliers, iterations)) => {
                let scale = residual_scale(samples, &refined.laser, form.unknowns());
                let adapted = (SCALE_THRESHOLD_FACTOR * scale).clamp(options.threshold_mm, ceiling);
                if adapted <= threshold * 1.05 {
                    return Ok((refined, inliers, iterations, threshold));
                }
                threshold = adapted;
            }
            Err(Error::NoConsensus { .. } | Error::NotBetterThanChance { .. })
                if form.fidelity() == Fidelity::Low && threshold < ceiling =>
            {
                threshold = (2.0 * threshold).min(ceiling);
            }
            Err(e) => return Err(e),
        }
    }
    // The rounds are spent: a last fit at the threshold they ended with
    // (also the doubled one the last failure asked for).
    let at = CalibrationOptions { threshold_mm: threshold, ..*options };
    robust_fit_at(samples, form, &at).map(|(r, i, k)| (r, i, k, threshold))
}

/// Rounds of "fit, then set the threshold from the fit's residual scale".
const MAX_SCALE_ROUNDS: usize = 4;

/// The inlier threshold in robust residual scales: 2.5 sigma keeps 98.8 %
/// of Gaussian inliers.
const SCALE_THRESHOLD_FACTOR: f64 = 2.5;

/// The threshold never grows beyond this many times `--threshold-mm`.
const MAX_THRESHOLD_FACTOR: f64 = 4.0;

/// Least-median-of-squares scale of the depth residuals of `laser` over all
/// samples (Rousseeuw and Leroy, 1987), `p` the fitted unknowns.
fn residual_scale(samples: &[LaserSample], laser: &LaserModel, p: usize) -> f64 {
    let prepared = laser.prepare();
    let mut squared: Vec<f64> = samples.iter().map(|s| depth_error(&prepared, s).powi(2)).collect();
    if squared.is_empty() {
        return 0.0;
    }
    let middle = squared.len() / 2;
    let median = *squared.select_nth_unstable_by(middle, f64::total_cmp).1;
    let n = samples.len() as f64;
    1.4826 * (1.0 + 5.0 / (n - p as f64).max(1.0)) * median.sqrt()
}

/// Refuses a consensus of `best` samples that is not clearly more than the
/// same samples give with their depths shuffled (see
/// [`MIN_CONSENSUS_OVER_CHANCE`]).
fn check_better_than_chance(
    samples: &[LaserSample],
    form: &LinearForm,
    options: &RansacOptions,
    best: usize,
) -> Result<()> {
    use rand::SeedableRng as _;
    use rand::seq::SliceRandom as _;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed ^ 0x5eed_c4a5);
    let mut shuffled: Vec<LaserSample> = if samples.len() > CHANCE_TEST_SAMPLES {
        rand::seq::index::sample(&mut rng, samples.len(), CHANCE_TEST_SAMPLES)
            .into_iter()
            .map(|i| samples[i])
            .collect()
    } else {
        samples.to_vec()
    };
    let mut depths: Vec<(f64, f64)> = shuffled.iter().map(|s| (s.z_mm, s.slide_mm)).collect();
    depths.shuffle(&mut rng);
    for (sample, (z_mm, slide_mm)) in shuffled.iter_mut().zip(depths) {
        sample.z_mm = z_mm;
        sample.slide_mm = slide_mm;
    }
    let null = LaserEstimator { samples: &shuffled, form };
    let chance = ransac::ransac(&null, options).map_or(0, |o| o.inliers.len());
    let chance_fraction = chance as f64 / shuffled.len() as f64;
    let best_fraction = best as f64 / samples.len() as f64;
    if best_fraction < MIN_CONSENSUS_OVER_CHANCE * chance_fraction {
        return Err(Error::NotBetterThanChance {
            best,
            n: samples.len(),
            chance_percent: 100.0 * chance_fraction,
            threshold_mm: options.threshold,
        });
    }
    Ok(())
}

/// The laser model as a RANSAC estimator: minimal linear solver, depth residual.
struct LaserEstimator<'a> {
    samples: &'a [LaserSample],
    form: &'a LinearForm,
}

impl Estimator for LaserEstimator<'_> {
    type Model = PreparedLaser;

    fn len(&self) -> usize {
        self.samples.len()
    }

    fn sample_size(&self) -> usize {
        self.form.unknowns()
    }

    fn fit_minimal(&self, indices: &[usize]) -> Option<PreparedLaser> {
        let subset: Vec<&LaserSample> = indices.iter().map(|&i| &self.samples[i]).collect();
        self.form.solve_minimal(&subset).map(|laser| laser.prepare())
    }

    fn residual(&self, laser: &PreparedLaser, index: usize) -> f64 {
        let sample = &self.samples[index];
        if laser.denominator(&sample.normalized()) <= 0.0 {
            return f64::INFINITY;
        }
        depth_error(laser, sample).abs()
    }
}
