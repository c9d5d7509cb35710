//! Reading a scan folder (FORMATS.md): its scan.yaml and its images.
//!
//! [`locate_scan`] decodes a few frames at a time ([`MAX_FRAMES_IN_FLIGHT`])
//! and keeps of each only what the answer needs (its [`FrameResult`], and
//! the per-pixel minimum of the views, for the outline and the stripe
//! points the laser did not light), so its memory does not grow with the
//! images. [`read_scan_images`] holds every image, for callers that show
//! them (the scan report), and refuses scans of more than
//! [`MAX_SCAN_FRAMES`].

use std::sync::atomic::{AtomicUsize, Ordering};

use alacs_model::{Camera, LaserModel, SCAN_FILE, Scan, ScanFrameSpec};
use alacs_vision::{read_colour_image, read_laser_off_image};
use image::RgbImage;
use rayon::prelude::*;

use crate::frame::{FrameContext, FrameCrop, SearchBall, unlit_views};
use crate::locate::{check_frame, check_options, check_prior, conclude};
use crate::{Error, FrameImages, FrameResult, Localization, LocateOptions, Prior, Result, locate};

/// Most frames a scan folder may have. The seed paper's scan has 5 (the
/// laser stepped 10 mm across an apple 80 mm wide); 64 allow steps of
/// 2 mm over 120 mm, finer than the stripe's own width on the fruit. A
/// scan.yaml with more is bad input, not a scan: localization keeps each
/// frame's stripe, and the scan report holds every image (about 1 MB per
/// frame at the simulator's scaled resolution, 15 MB at 5 MP).
pub const MAX_SCAN_FRAMES: usize = 64;

/// Frames [`locate_scan`] decodes at once: rayon's threads, at most this.
pub const MAX_FRAMES_IN_FLIGHT: usize = 4;

/// The images of a scan's frames, in frame order: the laser-on image and
/// the laser-off one where the frame has it.
pub type ScanImages = Vec<FrameImagePair>;

/// A frame's laser-on image and its laser-off image, if any.
pub type FrameImagePair = (RgbImage, Option<RgbImage>);

/// Refuses a scan of more than [`MAX_SCAN_FRAMES`] frames, naming its file.
fn check_frame_count(scan: &Scan) -> Result<()> {
    if scan.frames.len() > MAX_SCAN_FRAMES {
        return Err(Error::InvalidInput(format!(
            "{}: {} frames, more than the {MAX_SCAN_FRAMES} a scan may have",
            scan.dir.join(SCAN_FILE).display(),
            scan.frames.len()
        )));
    }
    Ok(())
}

/// Decodes one frame's images.
fn read_frame(scan: &Scan, frame: &ScanFrameSpec) -> Result<(RgbImage, Option<RgbImage>)> {
    // The colour score needs colour; with a laser-off image the difference does not.
    let on_path = scan.path_of(&frame.image);
    let on = read_colour_image(&on_path, frame.image_laser_off.is_some())?;
    let off = match &frame.image_laser_off {
        Some(path) => Some(read_laser_off_image(&scan.path_of(path), &on, &on_path)?),
        None => None,
    };
    Ok((on, off))
}

/// Reads every image of a scan folder ([`Scan`]) in parallel, for callers
/// that need them all (the scan report); [`locate_scan`] does not.
/// Refuses more than [`MAX_SCAN_FRAMES`] frames. `progress(done, total)`
/// after each frame read.
pub fn read_scan_images(scan: &Scan, progress: impl Fn(usize, usize) + Sync) -> Result<ScanImages> {
    check_frame_count(scan)?;
    let total = scan.frames.len();
    let done = AtomicUsize::new(0);
    scan.frames
        .par_iter()
        .map(|frame| {
            let images = read_frame(scan, frame)?;
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Ok(images)
        })
        .collect()
}

/// The prior of a scan's scan.yaml (its first fruit's).
fn prior_of(scan: &Scan) -> Prior {
    Prior::from(&scan.target())
}

/// The priors of every fruit a scan's scan.yaml names, in its order.
pub fn priors_of(scan: &Scan) -> Vec<Prior> {
    scan.targets().iter().map(Prior::from).collect()
}

/// Names a frame (its image's file) in an input error.
fn in_named(name: &str, error: Error) -> Error {
    match error {
        Error::InvalidInput(message) => Error::InvalidInput(format!("{name}: {message}")),
        other => other,
    }
}

/// Refuses a camera whose image size is not the scan's: the first frame's
/// size, read from its header (nothing decoded). The message names the
/// frame's file; the caller names the camera's.
pub fn check_camera_fits(scan: &Scan, camera: &Camera) -> Result<()> {
    let Some(first) = scan.frames.first() else { return Ok(()) };
    let path = scan.path_of(&first.image);
    let Ok((width, height)) = image::image_dimensions(&path) else {
        // Unreadable: reading the frame itself says why, naming it.
        return Ok(());
    };
    if (width, height) != (camera.width_px, camera.height_px) {
        return Err(Error::InvalidInput(format!(
            "the camera is for {} x {} px images, but the scan's frame {} is {width} x {height} px",
            camera.width_px,
            camera.height_px,
            path.display()
        )));
    }
    Ok(())
}

/// Names the scan folder in an input error.
fn in_folder(scan: &Scan, error: Error) -> Error {
    match error {
        Error::InvalidInput(message) => {
            Error::InvalidInput(format!("{}: {message}", scan.dir.display()))
        }
        other => other,
    }
}

/// Locates the fruit from a scan folder ([`Scan`]), as [`locate`] does
/// with its frames in memory, decoding at most [`MAX_FRAMES_IN_FLIGHT`]
/// frames at a time and dropping their images once processed. Refuses
/// more than [`MAX_SCAN_FRAMES`] frames. `progress(done, total)` after
/// each frame read. The first fruit of a scan naming several
/// ([`locate_scan_targets`] answers each).
pub fn locate_scan(
    scan: &Scan,
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Localization> {
    let mut answers = locate_priors(scan, &[prior_of(scan)], camera, laser, options, progress)?;
    answers.pop().ok_or_else(|| Error::InvalidInput("no fruit to locate".into()))
}

/// [`locate_scan`] for every fruit the scan names (scan.yaml's `targets`),
/// in its order: each frame is decoded once and searched around each
/// fruit's rough position, and each fruit is concluded on its own, so the
/// answer for one is the answer a scan naming only it would get.
pub fn locate_scan_targets(
    scan: &Scan,
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Vec<Localization>> {
    locate_priors(scan, &priors_of(scan), camera, laser, options, progress)
}

fn locate_priors(
    scan: &Scan,
    priors: &[Prior],
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Vec<Localization>> {
    check_frame_count(scan)?;
    for prior in priors {
        check_prior(prior).map_err(|e| in_folder(scan, e))?;
    }
    check_options(options).map_err(|e| in_folder(scan, e))?;
    let frames = scan.frames.iter().map(|spec| {
        Ok(PendingFrame {
            slide_mm: spec.slide_mm,
            name: scan.path_of(&spec.image).display().to_string(),
            decode: Box::new(move || read_frame(scan, spec)),
        })
    });
    locate_frames(frames, Some(scan.frames.len()), priors, camera, laser, options, progress)
}

/// A frame of a scan before its images are decoded: where the laser was,
/// what names it in an error (its file, or its place in a recording), and
/// how to get its images (laser-on, laser-off if any).
pub struct PendingFrame<'a> {
    /// The slide travel of the frame, mm.
    pub slide_mm: f64,
    /// Names the frame in an error.
    pub name: String,
    /// Decodes the frame's images.
    pub decode: Box<dyn FnOnce() -> Result<FrameImagePair> + Send + 'a>,
}

/// [`locate`] for each fruit of `priors` over frames that come one after
/// another (a scan folder's files, a recording's messages): at most
/// [`MAX_FRAMES_IN_FLIGHT`] are decoded at once and of each only what the
/// answer needs is kept, so memory does not grow with the images. More
/// than [`MAX_SCAN_FRAMES`] frames are refused, as none at all.
/// `progress(done, total)` after each frame read (`total` 0 where not
/// known).
pub fn locate_frames<'a>(
    frames: impl Iterator<Item = Result<PendingFrame<'a>>>,
    total: Option<usize>,
    priors: &[Prior],
    camera: &Camera,
    laser: &LaserModel,
    options: &LocateOptions,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<Vec<Localization>> {
    camera.validate()?;
    laser.validate()?;
    for prior in priors {
        check_prior(prior)?;
    }
    check_options(options)?;
    let searches: Vec<SearchBall> = priors.iter().map(|p| SearchBall::new(p, options)).collect();
    let contexts: Vec<FrameContext> = priors
        .iter()
        .zip(&searches)
        .map(|(prior, search)| FrameContext { camera, laser, prior, search, options })
        .collect();
    let total = total.unwrap_or(0);
    let done = AtomicUsize::new(0);
    let chunk = rayon::current_num_threads().clamp(1, MAX_FRAMES_IN_FLIGHT);
    // Per fruit, per frame: the pixels around its search ball.
    let mut crops: Vec<Vec<FrameCrop>> = priors.iter().map(|_| Vec::new()).collect();
    // The per-pixel minimum of the frames' views: the scene without the
    // laser, all the outline and `drop_unlit_points` need.
    let mut least: Option<RgbImage> = None;
    let mut frames = frames.enumerate().peekable();
    while frames.peek().is_some() {
        let mut batch = Vec::with_capacity(chunk);
        for (index, frame) in frames.by_ref().take(chunk) {
            if index >= MAX_SCAN_FRAMES {
                return Err(Error::InvalidInput(format!(
                    "more than the {MAX_SCAN_FRAMES} frames a scan may have"
                )));
            }
            batch.push((index, frame?));
        }
        // Per frame: each fruit's crop, and the frame's images.
        let processed: Vec<(Vec<FrameCrop>, FrameImagePair)> = batch
            .into_par_iter()
            .map(|(index, pending)| {
                let PendingFrame { slide_mm, name, decode } = pending;
                let (on, off) = decode()?;
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                let frame = FrameImages { image: &on, image_laser_off: off.as_ref(), slide_mm };
                check_frame(camera, index, &frame).map_err(|e| in_named(&name, e))?;
                let per_fruit = contexts.iter().map(|context| context.crop(&frame)).collect();
                Ok((per_fruit, (on, off)))
            })
            .collect::<Result<_>>()?;
        for (per_fruit, (on, off)) in processed {
            for (fruit, crop) in crops.iter_mut().zip(per_fruit) {
                fruit.push(crop);
            }
            darken(&mut least, off.unwrap_or(on));
        }
    }
    if least.is_none() {
        return Err(Error::InvalidInput("the scan has no frames".into()));
    }
    let views: Vec<&RgbImage> = least.iter().collect();
    crops
        .iter()
        .zip(&contexts)
        .map(|(crops, context)| {
            let unlit = unlit_views(crops);
            let results = crops
                .par_iter()
                .zip(&unlit)
                .enumerate()
                .map(|(index, (crop, unlit))| context.frame(index, crop, unlit.as_ref()))
                .collect::<Result<Vec<FrameResult>>>()?;
            Ok(conclude(results, context, &views))
        })
        .collect()
}

/// Folds `view` into the per-pixel minimum `least` (the views share their
/// size, [`check_frame`]).
fn darken(least: &mut Option<RgbImage>, view: RgbImage) {
    match least {
        None => *least = Some(view),
        Some(least) => {
            for (l, v) in least.pixels_mut().zip(view.pixels()) {
                for c in 0..3 {
                    l.0[c] = l.0[c].min(v.0[c]);
                }
            }
        }
    }
}

/// [`locate`] on a scan's images already read ([`read_scan_images`]), with
/// the slide positions of its scan.yaml, for the fruit of `prior` (one of
/// [`priors_of`] the scan).
pub fn locate_scan_images(
    scan: &Scan,
    images: &[(RgbImage, Option<RgbImage>)],
    prior: &Prior,
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
    locate(camera, laser, prior, &frames, options).map_err(|e| in_folder(scan, e))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_scan_of_more_frames_than_the_limit_is_refused() {
        // A scan.yaml that lists more frames than a scan has is bad input:
        // held at once, its images (about 1 MB a frame at the simulator's
        // scaled resolution) would grow the memory without bound.
        let mut text = String::from("rough_position_mm: [0, 0, 800]\nframes:\n");
        for k in 0..=MAX_SCAN_FRAMES {
            text.push_str(&format!("  - {{image: frame{k}.png, slide_mm: {k}}}\n"));
        }
        let dir = std::path::Path::new("/nonexistent/scan");
        let scan = Scan::parse(&text, dir, &dir.join(SCAN_FILE)).unwrap();
        let camera = Camera::blackfly_s_5mp();
        let laser = LaserModel::seed_paper();
        let error =
            locate_scan(&scan, &camera, &laser, &LocateOptions::default(), |_, _| {}).unwrap_err();
        let message = error.to_string();
        assert!(message.contains("scan.yaml") && message.contains("65 frames"), "{message}");
        assert!(error.is_bad_input());
        assert!(read_scan_images(&scan, |_, _| {}).is_err());
    }
}
