//! Reading images with errors that name the file.

use std::path::Path;

use image::DynamicImage;

use crate::{Error, Result};

/// Opens and decodes an image (PNG or JPEG, by content); a missing, truncated
/// or non-image file gives [`Error::Image`] naming it.
pub fn read_image(path: &Path) -> Result<DynamicImage> {
    let error = |message: String| Error::Image { path: path.to_path_buf(), message };
    let reader = image::ImageReader::open(path)
        .map_err(|e| error(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| error(e.to_string()))?;
    if reader.format().is_none() {
        return Err(error("not a PNG or JPEG image".into()));
    }
    reader.decode().map_err(|e| error(format!("cannot decode: {e}")))
}
