//! Writing a simulation's images one by one, with progress.

use alacs_model::io::OutputDir;
use image::RgbImage;

use crate::Result;
use crate::error::save_image;

/// Saves images into an output folder (PNG, or JPEG of `jpeg_quality`),
/// calling `progress(done, total)` after each.
pub(crate) struct ImageWriter<'a, P> {
    out: &'a mut OutputDir,
    jpeg_quality: Option<u8>,
    progress: P,
    done: usize,
    total: usize,
}

impl<'a, P: FnMut(usize, usize)> ImageWriter<'a, P> {
    /// A writer of `total` images.
    pub(crate) fn new(
        out: &'a mut OutputDir,
        total: usize,
        jpeg_quality: Option<u8>,
        progress: P,
    ) -> Self {
        Self { out, jpeg_quality, progress, done: 0, total }
    }

    /// Saves `image` as `name` and reports the progress.
    pub(crate) fn save(&mut self, name: &str, image: &RgbImage) -> Result<()> {
        save_image(self.out, name, image, self.jpeg_quality)?;
        self.done += 1;
        (self.progress)(self.done, self.total);
        Ok(())
    }
}
