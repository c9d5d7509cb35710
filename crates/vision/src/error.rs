//! The one error type of `alacs-vision`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong reading images and finding boards and stripes.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An image file could not be opened or decoded.
    #[error("{path}: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What is wrong (missing, not an image, truncated, ...).
        message: String,
    },
    /// Two images that must match (a view and its laser-off image) do not.
    #[error("{message}")]
    Mismatch {
        /// What differs.
        message: String,
    },
}

impl Error {
    /// Bad input (exit 2): an image that cannot be read, or images that do
    /// not belong together.
    pub fn class(&self) -> alacs_model::ErrorClass {
        alacs_model::ErrorClass::BadInput
    }
}
