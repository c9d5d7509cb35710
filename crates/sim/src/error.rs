//! The one error type of `alacs-sim`.

use alacs_model::io::OutputDir;

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
            Error::InvalidOptions(_) => BadInput,
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

/// The largest render scale accepted: twice the camera's resolution each
/// side (a 5 MP camera renders at 20 MP), so memory stays bounded (about
/// 1.5 GB of sub-pixel rays at the limit).
pub const MAX_SCALE: f64 = 2.0;

/// The most views a simulated session may have (the seed's has 10; a
/// thousand is more than any calibration takes).
pub const MAX_SESSION_VIEWS: usize = 1000;

/// The most calibration samples a simulation may make (views x points per
/// view): as many as fit in a samples.csv that `calibrate laser` reads,
/// [`alacs_model::io::MAX_TEXT_INPUT_BYTES`] at [`MAX_SAMPLE_ROW_BYTES`] a
/// row (2.68 million; a session of 1000 views gives about a million).
pub const MAX_SAMPLES: usize =
    (alacs_model::io::MAX_TEXT_INPUT_BYTES / MAX_SAMPLE_ROW_BYTES as u64) as usize;

/// The longest row of a simulated samples.csv, bytes: four shortest
/// round-trip floats (about 20 characters each at the simulator's
/// magnitudes) and a view number, with room to spare.
pub const MAX_SAMPLE_ROW_BYTES: usize = 100;

/// The most slide positions a simulation may use.
pub const MAX_SLIDE_POSITIONS: usize = 1000;

/// Checks that there is at least one slide position, not more than
/// [`MAX_SLIDE_POSITIONS`], all finite and within
/// [`alacs_model::MAX_ABS_SLIDE_MM`].
pub(crate) fn check_slides(slides_mm: &[f64]) -> Result<()> {
    let limit = alacs_model::MAX_ABS_SLIDE_MM;
    if slides_mm.is_empty()
        || slides_mm.len() > MAX_SLIDE_POSITIONS
        || slides_mm.iter().any(|d| !d.is_finite() || d.abs() > limit)
    {
        return Err(Error::InvalidOptions(format!(
            "slide positions must be 1 to {MAX_SLIDE_POSITIONS}, each finite and within +-{limit} mm"
        )));
    }
    Ok(())
}

/// Checks a render scale: positive and at most [`MAX_SCALE`].
pub(crate) fn check_scale(scale: f64) -> Result<()> {
    if scale > 0.0 && scale <= MAX_SCALE {
        Ok(())
    } else {
        Err(Error::InvalidOptions(format!("scale {scale} must lie in (0, {MAX_SCALE}]")))
    }
}

/// Writes `name` into `out`: an RGB8 PNG, or a JPEG of `jpeg_quality`
/// (1-100) when given, encoded straight into the atomic writer.
pub(crate) fn save_image(
    out: &mut OutputDir,
    name: &str,
    image: &image::RgbImage,
    jpeg_quality: Option<u8>,
) -> Result<()> {
    use image::ImageEncoder as _;
    out.write_with(name, |w| {
        let (width, height) = image.dimensions();
        let raw = image.as_raw();
        let color = image::ExtendedColorType::Rgb8;
        match jpeg_quality {
            None => image::codecs::png::PngEncoder::new(w).write_image(raw, width, height, color),
            Some(q) => image::codecs::jpeg::JpegEncoder::new_with_quality(w, q)
                .write_image(raw, width, height, color),
        }
        .map_err(std::io::Error::other)
    })?;
    Ok(())
}

/// Writes `value` as pretty JSON into `out` as `name`.
pub(crate) fn save_json(out: &mut OutputDir, name: &str, value: &serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).unwrap_or_default() + "\n";
    out.write(name, text)?;
    Ok(())
}
