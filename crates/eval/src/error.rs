//! The one error type of `alacs-eval`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong while evaluating or writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Calibration (or reading its samples or a session's images) failed.
    #[error(transparent)]
    Calib(#[from] alacs_calib::Error),
    /// A camera, laser or session file could not be used, or a report file
    /// could not be written (files go through `alacs_model::io`).
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// A plot could not be drawn or encoded.
    #[error("{path}: cannot draw the plot: {message}")]
    Plot {
        /// The plot's file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A report image could not be encoded or written.
    #[error("{path}: cannot write the image: {message}")]
    Image {
        /// The image's file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The evaluation has nothing to evaluate (no view gave a point, say).
    #[error("nothing to evaluate: {0}")]
    NoData(String),
    /// An option is out of range.
    #[error("invalid option: {0}")]
    InvalidOptions(String),
}

impl Error {
    /// Bad input (exit 2) or an evaluation that failed on readable data (1).
    /// A report that cannot be written is bad input (an output path that
    /// cannot be used), as everywhere in alacs.
    pub fn class(&self) -> alacs_model::ErrorClass {
        use alacs_model::ErrorClass::{BadInput, JobFailed};
        match self {
            Error::Calib(e) => e.class(),
            Error::Model(e) => e.class(),
            Error::InvalidOptions(_) | Error::Image { .. } => BadInput,
            Error::Plot { .. } | Error::NoData(_) => JobFailed,
        }
    }

    /// Whether [`Error::class`] is bad input.
    pub fn is_bad_input(&self) -> bool {
        self.class() == alacs_model::ErrorClass::BadInput
    }
}
