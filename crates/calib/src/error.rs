//! The one error type of `alacs-calib`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while reading samples or calibrating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// A samples CSV is malformed: a missing column, a value that is not a
    /// number, NaN or infinite, or a non-positive depth.
    #[error("{path}{}: {message}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number, where known.
        line: Option<u64>,
        /// What is wrong.
        message: String,
    },
    /// An in-memory sample is unusable (non-finite value, non-positive depth).
    #[error("sample {index}: {message}")]
    InvalidSample {
        /// 0-based index of the sample.
        index: usize,
        /// What is wrong.
        message: String,
    },
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
    /// An image could not be read, or images of a session do not match.
    #[error(transparent)]
    Vision(#[from] alacs_vision::Error),
    /// The nonlinear refinement ended in parameters that describe no laser.
    #[error("the least-squares fit failed: {0}")]
    FitFailed(String),
}

impl Error {
    /// Whether the error is about unreadable or invalid input (exit code 2 in
    /// FORMATS.md) rather than a calibration that failed on readable data (1).
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            Error::Io { .. }
                | Error::Csv { .. }
                | Error::InvalidSample { .. }
                | Error::Vision(
                    alacs_vision::Error::Image { .. } | alacs_vision::Error::Mismatch { .. }
                )
        )
    }
}
