//! Reading a scan folder (FORMATS.md): its scan.yaml and its images.

use alacs_model::{Camera, LaserModel, Scan};
use alacs_vision::read_image;
use image::RgbImage;
use rayon::prelude::*;

use crate::{Error, FrameImages, Localization, LocateOptions, Prior, Result, locate};

/// The images of a scan's frames, in frame order: the laser-on image and
/// the laser-off one where the frame has it.
pub type ScanImages = Vec<(RgbImage, Option<RgbImage>)>;

/// Reads the images of a scan folder ([`Scan`]) in parallel;
/// `progress(done, total)` after each frame read.
pub fn read_scan_images(scan: &Scan, progress: impl Fn(usize, usize) + Sync) -> Result<ScanImages> {
    let total = scan.frames.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    scan.frames
        .par_iter()
        .map(|frame| {
            let on = read_image(&scan.path_of(&frame.image))?.to_rgb8();
            let off = match &frame.image_laser_off {
                Some(path) => Some(read_image(&scan.path_of(path))?.to_rgb8()),
                None => None,
            };
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, total);
            Ok((on, off))
        })
        .collect()
}

/// Locates the fruit from a scan folder ([`Scan`]): [`read_scan_images`],
/// then [`locate_scan_images`].
pub fn locate_scan(
    scan: &Scan,
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Localization> {
    let images = read_scan_images(scan, progress)?;
    locate_scan_images(scan, &images, camera, laser, options)
}

/// [`locate`] on a scan's images already read ([`read_scan_images`]), with
/// the prior and slide positions of its scan.yaml.
pub fn locate_scan_images(
    scan: &Scan,
    images: &[(RgbImage, Option<RgbImage>)],
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
) -> Result<Localization> {
    let frames: Vec<FrameImages> = scan
        .frames
        .iter()
        .zip(images)
        .map(|(frame, (on, off))| FrameImages {
            image: on,
            image_laser_off: off.as_ref(),
            slide_mm: frame.slide_mm,
        })
        .collect();
    let prior =
        Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: scan.fruit_radius_mm };
    locate(camera, laser, &prior, &frames, options).map_err(|error| match error {
        Error::InvalidInput(message) => {
            Error::InvalidInput(format!("{}: {message}", scan.dir.display()))
        }
        other => other,
    })
}
