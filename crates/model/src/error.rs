//! The one error type of `alacs-model`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in the camera and laser models and their files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// A YAML file (camera.yaml, laser.yaml) is malformed or misses a key.
    #[error("{path}: {message}")]
    Parse {
        /// The file, or `<string>` for text parsed from memory.
        path: PathBuf,
        /// What is wrong, naming the key.
        message: String,
    },
    /// Parameters that do not describe a usable camera or laser.
    #[error("invalid {what}: {message}")]
    InvalidParameters {
        /// `camera` or `laser`.
        what: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The iterative undistortion did not converge for this pixel.
    #[error(
        "undistortion did not converge for pixel ({u_px:.3}, {v_px:.3}): residual {residual:.3e} after {iterations} iterations"
    )]
    UndistortNotConverged {
        /// Pixel column.
        u_px: f64,
        /// Pixel row.
        v_px: f64,
        /// Remaining residual in normalized units.
        residual: f64,
        /// Iterations spent.
        iterations: usize,
    },
    /// A point that cannot be projected (behind the camera or not finite).
    #[error("point ({x_mm:.3}, {y_mm:.3}, {z_mm:.3}) mm cannot be projected: {reason}")]
    NotProjectable {
        /// x in the camera frame.
        x_mm: f64,
        /// y in the camera frame.
        y_mm: f64,
        /// z in the camera frame.
        z_mm: f64,
        /// Why.
        reason: &'static str,
    },
    /// The camera ray through a pixel does not meet the laser plane in front of the camera.
    #[error(
        "the ray through normalized ({u_n:.6}, {v_n:.6}) does not meet the laser plane in front of the camera (denominator {denominator:.3e})"
    )]
    NoIntersection {
        /// Normalized x.
        u_n: f64,
        /// Normalized y.
        v_n: f64,
        /// sin(alpha) - u_n cos(alpha) - v_n tan(beta): must be positive.
        denominator: f64,
    },
}
