//! The one error type of `alacs-detect`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can stop a detection. An image without fruit is not an error: it
/// gives no detections.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The camera is invalid.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// Inputs that do not fit together (image sizes, camera), or options
    /// out of their range.
    #[error("{0}")]
    InvalidInput(String),
    /// A learned detector's model failed to run on an image.
    #[error("{0}")]
    Failed(String),
}

impl Error {
    /// Bad input (exit 2) or a failed job (exit 1).
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::Model(e) => e.class(),
            Error::InvalidInput(_) => alacs_model::ErrorClass::BadInput,
            Error::Failed(_) => alacs_model::ErrorClass::JobFailed,
        }
    }

    /// Whether [`Error::class`] is bad input.
    pub fn is_bad_input(&self) -> bool {
        self.class() == alacs_model::ErrorClass::BadInput
    }
}
