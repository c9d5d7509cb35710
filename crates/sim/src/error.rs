//! The one error type of `alacs-sim`.

use std::path::{Path, PathBuf};

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What can go wrong while simulating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Options that describe no scene (e.g. an empty depth range).
    #[error("invalid simulation options: {0}")]
    InvalidOptions(String),
    /// The scene could not be generated (e.g. the laser never appears in the image).
    #[error("cannot simulate: {0}")]
    Infeasible(String),
    /// Writing an output failed.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// Writing an image failed.
    #[error("{path}: {error}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What the image encoder said.
        error: image::ImageError,
    },
    /// A camera or laser model error.
    #[error(transparent)]
    Model(#[from] alacs_model::Error),
}

impl Error {
    /// Bad input (exit 2: options out of range, files that cannot be
    /// written) or a simulation that could not be made (exit 1).
    pub fn class(&self) -> alacs_model::ErrorClass {
        use alacs_model::ErrorClass::{BadInput, JobFailed};
        match self {
            Error::InvalidOptions(_) | Error::Io { .. } | Error::Image { .. } => BadInput,
            Error::Model(e) => e.class(),
            Error::Infeasible(_) => JobFailed,
        }
    }
}

/// Checks that `range` (mm) is positive, finite and ordered; `what` names it.
pub(crate) fn check_positive_range(what: &str, (low, high): (f64, f64)) -> Result<()> {
    if low > 0.0 && high >= low && high.is_finite() {
        Ok(())
    } else {
        Err(Error::InvalidOptions(format!("{what} {low}..{high} mm must be positive and ordered")))
    }
}

/// Checks that there is at least one slide position and all are finite.
pub(crate) fn check_slides(slides_mm: &[f64]) -> Result<()> {
    if slides_mm.is_empty() || slides_mm.iter().any(|d| !d.is_finite()) {
        return Err(Error::InvalidOptions(
            "slide positions must be finite and at least one".into(),
        ));
    }
    Ok(())
}

/// Maps an I/O error on `path` to [`Error::Io`].
pub(crate) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error {
    let path = path.to_path_buf();
    move |error| Error::Io { path, error }
}

/// Writes an RGB8 PNG, or a JPEG of `jpeg_quality` (1-100) when given.
pub(crate) fn save_image(
    image: &image::RgbImage,
    path: &Path,
    jpeg_quality: Option<u8>,
) -> Result<()> {
    let image_error = |error| Error::Image { path: path.to_path_buf(), error };
    match jpeg_quality {
        None => image.save_with_format(path, image::ImageFormat::Png).map_err(image_error),
        Some(quality) => {
            let file = std::fs::File::create(path).map_err(io_error(path))?;
            let mut writer = std::io::BufWriter::new(file);
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut writer, quality)
                .encode_image(image)
                .map_err(image_error)
        }
    }
}
