//! The one error type of `alacs-board`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong finding a board.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No board of the requested size was found in an image.
    #[error("no {cols} x {rows} {kind} found: {reason}")]
    NoBoard {
        /// "checkerboard" or "ChArUco board".
        kind: &'static str,
        /// Inner corners per row the search was for.
        cols: usize,
        /// Inner corners per column the search was for.
        rows: usize,
        /// Why the detection was refused.
        reason: String,
    },
    /// The board of session.yaml cannot be searched for (a ChArUco board
    /// the detector cannot describe).
    #[error("invalid board: {reason}")]
    InvalidBoard {
        /// What is wrong with it.
        reason: String,
    },
}

impl Error {
    /// Whether the error is about unreadable or invalid input rather than a
    /// job that failed on readable input: a board not found is a failed job,
    /// a board that cannot be described is bad input.
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::NoBoard { .. } => alacs_model::ErrorClass::JobFailed,
            Error::InvalidBoard { .. } => alacs_model::ErrorClass::BadInput,
        }
    }
}
