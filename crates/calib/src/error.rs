//! The one error type of `alacs-calib`.

use alacs_model::ErrorClass;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while reading samples or calibrating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Samples, a camera or a laser file that cannot be read or used, or a
    /// file that cannot be read or written (files go through `alacs_model::io`).
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// No board found in an image.
    #[error(transparent)]
    Board(#[from] alacs_board::Error),
    /// Fewer samples than the model needs.
    #[error("too few samples for the {model} model: got {got}, need at least {need}")]
    TooFewSamples {
        /// Samples given (or inliers found).
        got: usize,
        /// Samples needed.
        need: usize,
        /// `low-fidelity` or `high-fidelity`.
        model: &'static str,
    },
    /// The samples do not determine the laser parameters.
    #[error("samples too degenerate to calibrate: {0}")]
    Degenerate(String),
    /// RANSAC found no hypothesis that enough samples agree with.
    #[error(
        "RANSAC found no consensus: the best hypothesis explains {best} of {n} samples within {threshold_mm} mm (need {need}); check the samples or raise the threshold"
    )]
    NoConsensus {
        /// Largest inlier count seen.
        best: usize,
        /// Number of samples.
        n: usize,
        /// Inlier threshold epsilon.
        threshold_mm: f64,
        /// Inliers needed.
        need: usize,
    },
    /// RANSAC's best consensus is no better than chance: the samples hold no
    /// laser line (all outliers, or depths that belong to other pixels).
    #[error(
        "RANSAC found no consensus better than chance: its best hypothesis explains {best} of {n} samples within {threshold_mm} mm, while the same samples with their depths shuffled give {chance_percent:.0} %; the samples hold no laser line (check that depths and pixels belong together)"
    )]
    NotBetterThanChance {
        /// Inliers of the best hypothesis.
        best: usize,
        /// Number of samples.
        n: usize,
        /// The consensus found on the shuffled samples, percent of them.
        chance_percent: f64,
        /// Inlier threshold epsilon.
        threshold_mm: f64,
    },
    /// An image could not be read, or images of a session do not match.
    #[error(transparent)]
    Vision(#[from] alacs_vision::Error),
    /// The nonlinear refinement ended in parameters that describe no laser.
    #[error("the least-squares fit failed: {0}")]
    FitFailed(String),
}

impl Error {
    /// Bad input (exit 2) or a calibration that failed on readable data (1).
    pub fn class(&self) -> ErrorClass {
        match self {
            Error::Model(e) => e.class(),
            Error::Board(e) => e.class(),
            Error::Vision(e) => e.class(),
            Error::TooFewSamples { .. }
            | Error::Degenerate(_)
            | Error::NoConsensus { .. }
            | Error::NotBetterThanChance { .. }
            | Error::FitFailed(_) => ErrorClass::JobFailed,
        }
    }

    /// Whether [`Error::class`] is [`ErrorClass::BadInput`].
    pub fn is_bad_input(&self) -> bool {
        self.class() == ErrorClass::BadInput
    }
}

/// Images most named per reason in [`view_reasons`]: enough to find them,
/// short enough for one line when a whole session shares one reason.
const NAMED_PER_REASON: usize = 3;

/// Why views were rejected, for one line of a message: views that share a
/// reason are listed once with it (`a.png, b.png and 11 more: reason; c.png:
/// other reason`), in the order their reasons first appear.
pub(crate) fn view_reasons<'a>(views: impl IntoIterator<Item = (&'a str, &'a str)>) -> String {
    let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
    for (name, reason) in views {
        match groups.iter_mut().find(|(r, _)| *r == reason) {
            Some((_, names)) => names.push(name),
            None => groups.push((reason, vec![name])),
        }
    }
    let group = |(reason, names): &(&str, Vec<&str>)| {
        let shown = names[..names.len().min(NAMED_PER_REASON)].join(", ");
        match names.len().checked_sub(NAMED_PER_REASON) {
            Some(more) if more > 0 => format!("{shown} and {more} more: {reason}"),
            _ => format!("{shown}: {reason}"),
        }
    };
    groups.iter().map(group).collect::<Vec<_>>().join("; ")
}

#[cfg(test)]
mod tests {
    use super::view_reasons;

    #[test]
    fn views_that_share_a_reason_are_listed_once_with_it() {
        let views = [
            ("a.png", "only 54 of 70 corners found"),
            ("b.png", "only 54 of 70 corners found"),
            ("c.png", "no corners"),
            ("d.png", "only 54 of 70 corners found"),
            ("e.png", "only 54 of 70 corners found"),
            ("f.png", "only 54 of 70 corners found"),
        ];
        assert_eq!(
            view_reasons(views),
            "a.png, b.png, d.png and 2 more: only 54 of 70 corners found; c.png: no corners"
        );
        assert_eq!(view_reasons([("a.png", "x"), ("b.png", "x")]), "a.png, b.png: x");
        assert_eq!(view_reasons([]), "");
    }
}
