//! Each fruit's rough 3-D position from a depth image aligned to the
//! colour image (crate docs, "Locate"), and the RGB-D camera's error model.

use alacs_model::Camera;
use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::{Matrix3, Point2, Point3, Vector3};

use crate::colour::is_fruit_coloured;
use crate::{Detection, Error, Result};

/// A depth image aligned to the colour image, in one of REP 118's
/// encodings.
#[derive(Debug, Clone, PartialEq)]
pub enum DepthImage {
    /// `16UC1`: millimetres, 0 where there is no data.
    Millimetres(ImageBuffer<Luma<u16>, Vec<u16>>),
    /// `32FC1`: metres, NaN (or 0, or infinite) where there is no data.
    Metres(ImageBuffer<Luma<f32>, Vec<f32>>),
}

impl DepthImage {
    /// Width and height, px.
    pub fn dimensions(&self) -> (u32, u32) {
        match self {
            DepthImage::Millimetres(image) => image.dimensions(),
            DepthImage::Metres(image) => image.dimensions(),
        }
    }

    /// The depth (z along the optical axis) at a pixel, mm; `None` where
    /// there is no data or the pixel is outside the image.
    pub fn depth_mm(&self, u: u32, v: u32) -> Option<f64> {
        let (width, height) = self.dimensions();
        if u >= width || v >= height {
            return None;
        }
        let z = match self {
            DepthImage::Millimetres(image) => f64::from(image.get_pixel(u, v)[0]),
            DepthImage::Metres(image) => 1000.0 * f64::from(image.get_pixel(u, v)[0]),
        };
        (z.is_finite() && z > 0.0).then_some(z)
    }
}

/// The RGB-D camera's depth error, and what the rough position inherits.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthModel {
    /// Per-pixel depth noise, mm per m^2 of depth: a stereo camera's RMS
    /// error grows with z^2 (z^2 x subpixel / (f x baseline): a D435 at
    /// 848 x 480, f about 430 px, baseline 50 mm, subpixel 0.08: about
    /// 3.7 mm/m^2, 1.3 mm at 0.6 m; Grunnet-Jepsen et al., Intel's "Tuning
    /// depth cameras for best performance", ../shared/REFERENCES.md).
    pub noise_mm_per_m2: f64,
    /// The depth's scale error, a fraction of the depth (standard
    /// deviation): it does not average over pixels (Intel's D400 datasheet:
    /// at most 2 % at 2 m; a unit after its on-chip self-calibration about
    /// 0.5-1 %).
    pub scale_error: f64,
    /// The fruit's radius from its circle, relative standard deviation: the
    /// centre lies one radius behind the front the depth sees.
    pub radius_error: f64,
    /// The circle's centre in the image, standard deviation in px, at the
    /// least (a tenth of the radius where that is more).
    pub centre_error_px: f64,
    /// Radii a fruit can have, mm: a round patch of another size at its
    /// measured depth (a branch's stub, a leaf's red edge, a red roof far
    /// behind) is not a fruit. Apples at harvest are 50-100 mm across,
    /// crab apples and early thinning down to about 40 mm.
    pub radius_range_mm: (f64, f64),
}

impl Default for DepthModel {
    fn default() -> Self {
        DepthModel {
            noise_mm_per_m2: 3.7,
            scale_error: 0.006,
            radius_error: 0.1,
            centre_error_px: 1.0,
            radius_range_mm: (20.0, 65.0),
        }
    }
}

/// A fruit's rough position from the depth image.
#[derive(Debug, Clone, PartialEq)]
pub struct RoughPosition {
    /// The fruit's centre in the colour camera's optical frame, mm.
    pub position_mm: Point3<f64>,
    /// Its radius, mm.
    pub radius_mm: f64,
    /// The position's covariance (mm^2, the same frame): the depth's scale
    /// error, the radius's and the circle's, the pixels' noise.
    pub position_cov_mm2: Matrix3<f64>,
    /// The depth pixels it rests on.
    pub depth_pixels: usize,
}

/// The depth pixels read lie within this fraction of the circle's radius
/// of its centre: the fruit's middle, away from the edge, where flying
/// pixels mix fruit and background and the depth changes fastest.
const INNER_FRACTION: f64 = 0.7;

/// Fewest depth pixels a rough position rests on.
const MIN_DEPTH_PIXELS: usize = 12;

/// A pixel's estimate lies within this many robust standard deviations
/// (1.4826 MAD) of the median, or the noise's three sigmas, or it is a
/// hole's edge or a flying pixel.
const OUTLIER_SIGMAS: f64 = 3.0;

/// Adds each detection's [`RoughPosition`] from `depth` (aligned to
/// `image`, both as `camera` sees them) and drops those whose radius at
/// their depth no fruit has ([`DepthModel::radius_range_mm`]); a detection
/// whose fruit shows too few depth pixels stays, with `rough: None`.
pub fn locate_detections(
    detections: &mut Vec<Detection>,
    image: &RgbImage,
    depth: &DepthImage,
    camera: &Camera,
    model: &DepthModel,
) -> Result<()> {
    let (width, height) = image.dimensions();
    if depth.dimensions() != (width, height) {
        let (dw, dh) = depth.dimensions();
        return Err(Error::InvalidInput(format!(
            "the depth image is {dw} x {dh} px, the colour image {width} x {height} px: the depth must be aligned to the colour image"
        )));
    }
    if (camera.width_px, camera.height_px) != (width, height) {
        return Err(Error::InvalidInput(format!(
            "the camera is {} x {} px, the images {width} x {height} px",
            camera.width_px, camera.height_px
        )));
    }
    for detection in detections.iter_mut() {
        detection.rough = rough_position(detection, image, depth, camera, model);
    }
    let (least, most) = model.radius_range_mm;
    detections.retain(|d| d.rough.as_ref().is_none_or(|r| (least..=most).contains(&r.radius_mm)));
    Ok(())
}

/// One detection's rough position (see [`locate_detections`]).
fn rough_position(
    detection: &Detection,
    image: &RgbImage,
    depth: &DepthImage,
    camera: &Camera,
    model: &DepthModel,
) -> Option<RoughPosition> {
    let (centre, r_px) = (detection.centre_px, detection.radius_px);
    let ray = |p: &Point2<f64>| -> Option<Vector3<f64>> {
        let n = camera.undistort_pixel(p).ok()?;
        Some(Vector3::new(n.x, n.y, 1.0))
    };
    let centre_ray = ray(&centre)?;
    // Each fruit pixel near the middle: its range along its ray and its
    // distance from the circle's centre in radii.
    let reach = INNER_FRACTION * r_px;
    let mut samples: Vec<(f64, f64)> = Vec::new();
    let (u0, u1) = ((centre.x - reach).floor().max(0.0) as u32, (centre.x + reach).ceil() as u32);
    let (v0, v1) = ((centre.y - reach).floor().max(0.0) as u32, (centre.y + reach).ceil() as u32);
    for v in v0..=v1.min(image.height().saturating_sub(1)) {
        for u in u0..=u1.min(image.width().saturating_sub(1)) {
            let p = Point2::new(f64::from(u), f64::from(v));
            let rho = (p - centre).norm() / r_px;
            if rho > INNER_FRACTION || !is_fruit_coloured(image.get_pixel(u, v).0) {
                continue;
            }
            let (Some(z), Some(direction)) = (depth.depth_mm(u, v), ray(&p)) else { continue };
            samples.push((z * direction.norm(), rho));
        }
    }
    if samples.len() < MIN_DEPTH_PIXELS {
        return None;
    }
    // The centre's range: each pixel's range plus the sphere's depth there,
    // R sqrt(1 - rho^2); R from the circle at that range. Twice, from the
    // front's median.
    let f = camera.fx_px.max(camera.fy_px);
    let radius_at = |range: f64| range * r_px / f.hypot(r_px);
    let mut range = median(samples.iter().map(|s| s.0).collect())?;
    let mut used = samples.len();
    for _ in 0..3 {
        let radius = radius_at(range);
        let estimates: Vec<f64> =
            samples.iter().map(|(d, rho)| d + radius * (1.0 - rho * rho).max(0.0).sqrt()).collect();
        let middle = median(estimates.clone())?;
        let spread = 1.4826 * median(estimates.iter().map(|e| (e - middle).abs()).collect())?;
        let noise = model.noise_mm_per_m2 * (middle / 1000.0).powi(2);
        let limit = OUTLIER_SIGMAS * spread.max(noise).max(1.0);
        let kept: Vec<f64> =
            estimates.into_iter().filter(|e| (e - middle).abs() <= limit).collect();
        used = kept.len();
        range = median(kept)?;
    }
    if used < MIN_DEPTH_PIXELS {
        return None;
    }
    let radius_mm = radius_at(range);
    let sight = centre_ray.normalize();
    let position_mm = Point3::from(sight * range);
    let along = (model.scale_error * range).powi(2)
        + (model.radius_error * radius_mm).powi(2)
        + (model.noise_mm_per_m2 * (range / 1000.0).powi(2)).powi(2) / used as f64;
    let across = (range * model.centre_error_px.max(0.1 * r_px) / f).powi(2);
    let projector = sight * sight.transpose();
    let position_cov_mm2 = projector * along + (Matrix3::identity() - projector) * across;
    Some(RoughPosition { position_mm, radius_mm, position_cov_mm2, depth_pixels: used })
}

/// The median (the upper of the two middle values), `None` of nothing.
fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let middle = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(middle, f64::total_cmp);
    Some(*m)
}
