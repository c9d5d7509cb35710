//! The one error type of `alacs-locate`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can stop a localization before it gives an answer. A fruit that
/// cannot be found is not an error: it is a [`crate::Localization`] with
/// status `NotFound` and a reason.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The camera, the laser or a file of them is invalid.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// An image could not be read or does not fit the others.
    #[error(transparent)]
    Vision(#[from] alacs_vision::Error),
    /// Inputs that contradict each other or the options.
    #[error("{0}")]
    InvalidInput(String),
}

impl Error {
    /// Whether the error is about unreadable or invalid input (exit code 2
    /// in FORMATS.md) rather than a job that failed on good input.
    pub fn is_bad_input(&self) -> bool {
        true
    }
}
