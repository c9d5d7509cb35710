//! The one error type of `alacs-rig`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong with a rig: a rig.toml that does not describe one
/// (bad input), or a device that fails (the scanner's device errors, a
/// failed job).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// rig.toml cannot be read or does not describe a rig.
    #[error("{}: {message}", .path.display())]
    Config {
        /// The rig.toml.
        path: PathBuf,
        /// What is wrong, naming the section and key.
        message: String,
    },
    /// A device failed: the scanner's error, naming the device.
    #[error(transparent)]
    Device(#[from] alacs_scanner::Error),
    /// A file of the model's could not be read.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
}

impl Error {
    /// Bad input (exit 2: rig.toml) or a failed job (exit 1: a device).
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::Config { .. } => alacs_model::ErrorClass::BadInput,
            Error::Device(e) => e.class(),
            Error::Model(e) => e.class(),
        }
    }
}
