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
    /// Bad input (exit 2) or a failed job (exit 1); the camera's and
    /// laser's own errors say which they are, contradicting inputs are bad
    /// input.
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::Model(e) => e.class(),
            Error::Vision(e) => e.class(),
            Error::InvalidInput(_) => alacs_model::ErrorClass::BadInput,
        }
    }

    /// Whether [`Error::class`] is bad input.
    pub fn is_bad_input(&self) -> bool {
        self.class() == alacs_model::ErrorClass::BadInput
    }
}
