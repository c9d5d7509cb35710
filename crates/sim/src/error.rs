//! The one error type of `alacs-sim`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong while simulating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Options that describe no scene (e.g. an empty depth range).
    #[error("invalid simulation options: {0}")]
    InvalidOptions(String),
    /// The scene could not be generated (e.g. the laser never appears in the image).
    #[error("cannot simulate: {0}")]
    Infeasible(String),
    /// Writing an output failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A camera or laser model error.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// Writing samples failed.
    #[error(transparent)]
    Calib(#[from] alacs_calib::Error),
}
