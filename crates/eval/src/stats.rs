//! Box-plot statistics: median, quartiles, Tukey's whiskers (the most
//! extreme values within 1.5 IQR of the quartiles; values beyond them are
//! drawn as points), the extremes, the mean and the root mean square.

use serde::Serialize;

/// The statistics of one set of values (errors in mm, say), as one box of a
/// box plot: whiskers to the last values within [`WHISKER_IQRS`] of the
/// quartiles (Tukey's convention, matplotlib's default), so that one stray
/// value shows as a point instead of stretching the whole plot.
///
/// Quartiles interpolate linearly between order statistics (the "type 7"
/// definition of Hyndman and Fan, NumPy's and R's default): the q-quantile of
/// n sorted values is at position q (n - 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoxStats {
    /// How many values.
    pub n: usize,
    /// The median (the 0.5 quantile).
    pub median: f64,
    /// The lower quartile (the 0.25 quantile).
    pub q1: f64,
    /// The upper quartile (the 0.75 quantile).
    pub q3: f64,
    /// The smallest value.
    pub min: f64,
    /// The largest value.
    pub max: f64,
    /// The lower whisker's end: the smallest value at or above
    /// `q1 - 1.5 IQR`.
    pub whisker_low: f64,
    /// The upper whisker's end: the largest value at or below `q3 + 1.5 IQR`.
    pub whisker_high: f64,
    /// The arithmetic mean.
    pub mean: f64,
    /// The root mean square (about zero, not about the mean).
    pub rms: f64,
}

impl BoxStats {
    /// The statistics of `values`; `None` when there are none or one of
    /// them is not finite.
    pub fn from_values(values: &[f64]) -> Option<Self> {
        if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let sum: f64 = sorted.iter().sum();
        let sum_squares: f64 = sorted.iter().map(|v| v * v).sum();
        let (q1, q3) = (quantile_sorted(&sorted, 0.25), quantile_sorted(&sorted, 0.75));
        let reach = WHISKER_IQRS * (q3 - q1);
        // The quartiles lie between values, so each whisker has one to end at.
        let whisker_low = sorted.iter().copied().find(|&v| v >= q1 - reach).unwrap_or(q1);
        let whisker_high = sorted.iter().rev().copied().find(|&v| v <= q3 + reach).unwrap_or(q3);
        Some(Self {
            n,
            median: quantile_sorted(&sorted, 0.5),
            q1,
            q3,
            min: sorted[0],
            max: sorted[n - 1],
            whisker_low,
            whisker_high,
            mean: sum / n as f64,
            rms: (sum_squares / n as f64).sqrt(),
        })
    }

    /// The interquartile range q3 - q1.
    pub fn iqr(&self) -> f64 {
        self.q3 - self.q1
    }

    /// Whether `value` lies beyond the whiskers (an outlier point).
    pub fn is_outlier(&self, value: f64) -> bool {
        value < self.whisker_low || value > self.whisker_high
    }
}

/// How far beyond the quartiles the whiskers reach, in interquartile
/// ranges (Tukey 1977, Exploratory Data Analysis; matplotlib's `whis`).
pub const WHISKER_IQRS: f64 = 1.5;

/// The `q`-quantile (0 to 1) of ascending `sorted` values, interpolated
/// linearly (see [`BoxStats`]); NaN for no values.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    match sorted.len() {
        0 => f64::NAN,
        1 => sorted[0],
        n => {
            let position = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let below = position.floor() as usize;
            let above = (below + 1).min(n - 1);
            let fraction = position - below as f64;
            sorted[below] + fraction * (sorted[above] - sorted[below])
        }
    }
}

/// The median of `values` (any order); NaN for none.
pub fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    quantile_sorted(&sorted, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn odd_count_matches_numpy() {
        // numpy.percentile([7, 1, 3, 9, 5], [25, 50, 75]) = [3, 5, 7]
        let s = BoxStats::from_values(&[7.0, 1.0, 3.0, 9.0, 5.0]).unwrap();
        assert_eq!((s.n, s.q1, s.median, s.q3), (5, 3.0, 5.0, 7.0));
        assert_eq!((s.min, s.max), (1.0, 9.0));
        assert_eq!(s.mean, 5.0);
        assert!((s.rms - (165.0f64 / 5.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.iqr(), 4.0);
    }

    #[test]
    fn even_count_interpolates() {
        // numpy.percentile([1, 2, 3, 4], [25, 50, 75]) = [1.75, 2.5, 3.25]
        let s = BoxStats::from_values(&[4.0, 3.0, 2.0, 1.0]).unwrap();
        assert!((s.q1 - 1.75).abs() < 1e-12);
        assert!((s.median - 2.5).abs() < 1e-12);
        assert!((s.q3 - 3.25).abs() < 1e-12);
    }

    #[test]
    fn whiskers_stop_at_one_and_a_half_iqr_and_the_stray_value_is_an_outlier() {
        // Quartiles 2 and 3: whiskers may reach 0.5 and 4.5 (matplotlib's boxplot
        // of these values draws them to 1 and 3 and 100 as a flier).
        let s = BoxStats::from_values(&[1.0, 2.0, 2.0, 3.0, 100.0]).unwrap();
        assert_eq!((s.whisker_low, s.whisker_high), (1.0, 3.0));
        assert_eq!((s.min, s.max, s.median), (1.0, 100.0, 2.0));
        assert!(s.is_outlier(100.0) && !s.is_outlier(3.0));
    }

    #[test]
    fn one_value_and_none() {
        let s = BoxStats::from_values(&[-2.5]).unwrap();
        assert_eq!((s.min, s.q1, s.median, s.q3, s.max), (-2.5, -2.5, -2.5, -2.5, -2.5));
        assert_eq!((s.whisker_low, s.whisker_high), (-2.5, -2.5));
        assert_eq!(s.rms, 2.5);
        assert!(BoxStats::from_values(&[]).is_none());
        assert!(BoxStats::from_values(&[1.0, f64::NAN]).is_none());
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn order_does_not_matter() {
        let values: Vec<f64> = (0..101).map(|i| ((i * 37) % 101) as f64 * 0.1 - 3.0).collect();
        let mut reversed = values.clone();
        reversed.reverse();
        assert_eq!(BoxStats::from_values(&values), BoxStats::from_values(&reversed));
        let s = BoxStats::from_values(&values).unwrap();
        // 0..=100 scaled: quartiles at 25, 50, 75 exactly.
        assert!((s.q1 - (2.5 - 3.0)).abs() < 1e-12);
        assert!((s.median - (5.0 - 3.0)).abs() < 1e-12);
        assert!((s.q3 - (7.5 - 3.0)).abs() < 1e-12);
    }
}
