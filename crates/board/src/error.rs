//! The one error type of `alacs-board`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong finding a board.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No checkerboard of the requested size was found in an image.
    #[error("no {cols} x {rows} checkerboard found: {reason}")]
    NoBoard {
        /// Inner corners per row the search was for.
        cols: usize,
        /// Inner corners per column the search was for.
        rows: usize,
        /// Why the detection was refused.
        reason: String,
    },
}

impl Error {
    /// Whether the error is about unreadable or invalid input rather than a
    /// job that failed on readable input: a board not found is a failed job.
    pub fn class(&self) -> alacs_model::ErrorClass {
        alacs_model::ErrorClass::JobFailed
    }
}
