//! The one error type of `alacs-board`.

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong finding a board.
#[derive(Debug, Clone, thiserror::Error)]
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
    /// A whole grid of inner corners one short each way was found: the
    /// board was given by its squares, not its inner corners.
    #[error(
        "no {cols} x {rows} checkerboard found: only {found} of {} corners, a whole {} x {} grid of inner corners; the board counts inner corners (squares - 1 each way), so a board of {cols} x {rows} squares is {} x {}",
        cols * rows,
        cols.saturating_sub(1),
        rows.saturating_sub(1),
        cols.saturating_sub(1),
        rows.saturating_sub(1)
    )]
    GivenBySquares {
        /// Inner corners per row the search was for.
        cols: usize,
        /// Inner corners per column the search was for.
        rows: usize,
        /// Corners of the whole grid found.
        found: usize,
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
    /// a board that cannot be described or was given by its squares is bad
    /// input.
    pub fn class(&self) -> alacs_model::ErrorClass {
        match self {
            Error::NoBoard { .. } => alacs_model::ErrorClass::JobFailed,
            Error::InvalidBoard { .. } | Error::GivenBySquares { .. } => {
                alacs_model::ErrorClass::BadInput
            }
        }
    }
}
