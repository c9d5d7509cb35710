//! The one error type of `alacs-ros`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What stops the node from starting or running. A goal that fails is not
/// an error of the node: its result says "error" with the reason, and the
/// node stays up.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A setting, file or environment variable that cannot be used.
    #[error("{0}")]
    InvalidInput(String),
    /// The camera or laser file could not be used.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
    /// The rig could not be built.
    #[error(transparent)]
    Scanner(#[from] alacs_scanner::Error),
    /// DDS could not be set up or failed while running.
    #[error("DDS: {0}")]
    Dds(String),
    /// A recording (MCAP) that cannot be read or written.
    #[error("{}: {message}", .path.display())]
    Bag {
        /// The .mcap file.
        path: std::path::PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

impl Error {
    /// Bad input (exit 2) or a failed job (exit 1).
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::InvalidInput(_) => alacs_model::ErrorClass::BadInput,
            Error::Model(e) => e.class(),
            Error::Scanner(e) => e.class(),
            Error::Dds(_) => alacs_model::ErrorClass::JobFailed,
            Error::Bag { .. } => alacs_model::ErrorClass::BadInput,
        }
    }

    /// A DDS failure, from any of ros2-client's error types.
    pub(crate) fn dds(what: &str, error: impl std::fmt::Debug) -> Self {
        Error::Dds(format!("{what}: {error:?}"))
    }
}
