//! Metering: the exposure that keeps the target fruit below clipping,
//! chosen from laser-off frames through the camera trait.
//!
//! In direct sun a red apple alone nearly fills the red channel at an
//! exposure made for shade, and a red laser on it adds nothing a clipped
//! pixel can show. Light and laser both scale with the exposure time, so a
//! shorter exposure keeps the fruit and the line on it below the full well
//! and the line stands out by its own irradiance. The controller meters the
//! target (the disc the rough position and the radius prior project to) in
//! a laser-off frame, sets the exposure that brings the target's bright end
//! to [`Metering::target_dn`], leaving headroom for the laser, and takes
//! laser-off frames for differencing when the scene is bright (a metered
//! exposure shorter than [`Metering::bright_below_us`]).
//!
//! A linear sensor needs one unclipped look: the exposure scales the level
//! by its ratio. A clipped look says only "too bright", so the exposure is
//! quartered until the target no longer clips.

use alacs_model::Camera;
use image::RgbImage;
use nalgebra::Point3;
use std::time::Duration;

use crate::hardware::Rig;
use crate::{Error, Result, Step};

/// How the controller meters. `Default`: start at 1 ms and 0 dB, bring the
/// target's 95th percentile to 100 DN, exposures 10 us - 20 ms, gain up to
/// 12 dB only past the longest exposure, laser-off frames below 600 us.
#[derive(Debug, Clone, PartialEq)]
pub struct Metering {
    /// The calibrated camera: projects the rough position into the image.
    pub camera: Camera,
    /// Exposure of the first metering frame, microseconds.
    pub start_exposure_us: f64,
    /// Shortest and longest exposure the controller sets, microseconds.
    pub exposure_range_us: (f64, f64),
    /// Largest gain, dB, used only when the longest exposure is too dark.
    pub max_gain_db: f64,
    /// The level the target's bright end (the 95th percentile of its
    /// pixels' brightest channel) is brought to, DN of 255: 100 leaves room
    /// for a laser line 1.5 times as bright as the lit fruit before the line
    /// clips.
    pub target_dn: f64,
    /// A metered exposure shorter than this means a bright scene: every
    /// frame is also captured with the laser off, for differencing. 600 us
    /// is a fruit lit by about as much light as the laser gives it (on the
    /// simulator's sensor, 100 W/m^2 in the red band fills a white pixel in
    /// 1 ms; see `alacs_sim::render`); a rig sets its own.
    pub bright_below_us: f64,
    /// Metering frames at most.
    pub max_frames: usize,
}

impl Metering {
    /// The default metering for `camera`.
    pub fn new(camera: Camera) -> Self {
        Self {
            camera,
            start_exposure_us: 1000.0,
            exposure_range_us: (10.0, 20_000.0),
            max_gain_db: 12.0,
            target_dn: 100.0,
            bright_below_us: 600.0,
            max_frames: 8,
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::InvalidInput(format!("metering: {m}")));
        self.camera.validate().map_err(|e| Error::InvalidInput(format!("metering camera: {e}")))?;
        let (low, high) = self.exposure_range_us;
        if !(low.is_finite() && high.is_finite() && 0.0 < low && low <= high) {
            return invalid(format!("exposure range {low}-{high} us must be positive and ordered"));
        }
        if !(low..=high).contains(&self.start_exposure_us) {
            return invalid(format!(
                "start exposure {} us is outside the range {low}-{high} us",
                self.start_exposure_us
            ));
        }
        if !(self.max_gain_db.is_finite() && self.max_gain_db >= 0.0) {
            return invalid(format!("largest gain {} dB must be non-negative", self.max_gain_db));
        }
        if !(self.target_dn.is_finite() && (10.0..=240.0).contains(&self.target_dn)) {
            return invalid(format!("target level {} DN must lie within 10-240", self.target_dn));
        }
        if !(self.bright_below_us.is_finite() && self.bright_below_us >= 0.0) {
            return invalid(format!(
                "bright-scene exposure {} us must be non-negative",
                self.bright_below_us
            ));
        }
        if self.max_frames == 0 {
            return invalid("at least one metering frame is needed".into());
        }
        Ok(())
    }
}

/// What metering chose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeteredExposure {
    /// The exposure the camera took, microseconds.
    pub exposure_us: f64,
    /// The gain the camera took, dB.
    pub gain_db: f64,
    /// The target's level (95th percentile of the brightest channel, DN)
    /// expected at this exposure: measured on the last frame, scaled.
    pub target_level_dn: f64,
    /// Laser-off frames metered.
    pub frames: usize,
    /// A bright scene: the scan also captures laser-off frames.
    pub bright: bool,
}

/// The target's brightness in one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Level {
    /// 95th percentile of the brightest channel over the target's disc, DN.
    p95_dn: f64,
}

/// A level at or above this is clipped: the true level is unknown.
const CLIPPED_DN: f64 = 250.0;

/// Below this the level is too dark to scale from (noise and rounding).
const DARK_DN: f64 = 8.0;

/// The fraction of the radius prior metered: the disc stays on the fruit
/// despite the rough position's lateral error.
const DISC_FRACTION: f64 = 0.7;

/// Fewest pixels a target disc must have.
const MIN_DISC_PIXELS: usize = 12;

/// The target's level in `image`: the disc of the rough position and radius.
fn target_level(
    image: &RgbImage,
    camera: &Camera,
    rough_mm: &Point3<f64>,
    radius_mm: f64,
) -> Result<Level> {
    let outside = || {
        Error::InvalidInput(format!(
            "metering: the rough position ({:.1}, {:.1}, {:.1}) mm does not project into the {} x {} image; nothing to meter",
            rough_mm.x,
            rough_mm.y,
            rough_mm.z,
            image.width(),
            image.height()
        ))
    };
    let centre = camera.project(rough_mm).map_err(|_| outside())?;
    let radius_px = (camera.fx_px * DISC_FRACTION * radius_mm / rough_mm.z).max(2.0);
    let (width, height) = (f64::from(image.width()), f64::from(image.height()));
    let u_range =
        ((centre.x - radius_px).floor().max(0.0), (centre.x + radius_px).ceil().min(width - 1.0));
    let v_range =
        ((centre.y - radius_px).floor().max(0.0), (centre.y + radius_px).ceil().min(height - 1.0));
    let mut values = Vec::new();
    if u_range.0 <= u_range.1 && v_range.0 <= v_range.1 {
        for v in v_range.0 as u32..=v_range.1 as u32 {
            for u in u_range.0 as u32..=u_range.1 as u32 {
                let (du, dv) = (f64::from(u) - centre.x, f64::from(v) - centre.y);
                if du * du + dv * dv <= radius_px * radius_px {
                    let [r, g, b] = image.get_pixel(u, v).0;
                    values.push(r.max(g).max(b));
                }
            }
        }
    }
    if values.len() < MIN_DISC_PIXELS {
        return Err(outside());
    }
    let rank = (values.len() * 95 / 100).min(values.len() - 1);
    let (_, p95, _) = values.select_nth_unstable(rank);
    Ok(Level { p95_dn: f64::from(*p95) })
}

/// Meters the targets (rough centres in the ALACS camera frame and radius
/// priors) with the laser off and leaves the camera at the chosen exposure
/// and gain. Several targets are metered in the same frames; the brightest
/// decides, so that none clips.
pub(crate) fn meter(
    metering: &Metering,
    rig: &mut Rig<'_>,
    targets: &[(Point3<f64>, f64)],
    capture_timeout: Duration,
) -> Result<MeteredExposure> {
    let at = |e: Error| e.at(Step::Metering);
    rig.laser.set(false).map_err(at)?;
    let (low, high) = metering.exposure_range_us;
    // The exposure time and gain for a light-gathering product t g (us):
    // the time first, the gain past the longest time.
    let split = |wanted_us: f64| {
        if wanted_us <= high {
            (wanted_us.max(low), 0.0)
        } else {
            (high, (20.0 * (wanted_us / high).log10()).min(metering.max_gain_db))
        }
    };
    let mut gain_db = rig.camera.set_gain_db(0.0).map_err(at)?;
    let mut exposure_us = rig.camera.set_exposure_us(metering.start_exposure_us).map_err(at)?;
    for frame in 1..=metering.max_frames {
        let image = rig.camera.capture(capture_timeout).map_err(at)?;
        let mut level_dn = 0.0f64;
        for (rough_mm, radius_mm) in targets {
            level_dn =
                level_dn.max(target_level(&image, &metering.camera, rough_mm, *radius_mm)?.p95_dn);
        }
        let product_us = exposure_us * 10f64.powf(gain_db / 20.0);
        // Clipped: a quarter of the light; dark: 16 times; otherwise one
        // linear step to the target level (a linear sensor: the level
        // scales with t g).
        let clipped = level_dn >= CLIPPED_DN;
        let dark = level_dn < DARK_DN;
        let (next_us, next_gain_db) = split(if clipped {
            product_us / 4.0
        } else if dark {
            product_us * 16.0
        } else {
            product_us * metering.target_dn / level_dn
        });
        let unchanged = (next_us - exposure_us).abs() <= 1e-9 * exposure_us
            && (next_gain_db - gain_db).abs() < 1e-9;
        if !unchanged {
            exposure_us = rig.camera.set_exposure_us(next_us).map_err(at)?;
            gain_db = rig.camera.set_gain_db(next_gain_db).map_err(at)?;
        }
        // At a limit (or already there), or one unclipped look, which
        // fixes a linear sensor's exposure.
        if unchanged || !(clipped || dark) {
            let scale = exposure_us * 10f64.powf(gain_db / 20.0) / product_us;
            return Ok(MeteredExposure {
                exposure_us,
                gain_db,
                target_level_dn: level_dn * scale,
                frames: frame,
                bright: exposure_us < metering.bright_below_us,
            });
        }
    }
    Err(Error::Metering {
        frames: metering.max_frames,
        exposure_us,
        detail: "the target stayed clipped or dark".into(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

    use super::*;

    #[test]
    fn the_level_is_the_discs_bright_end() {
        let camera = Camera::blackfly_s_5mp().scaled(0.25);
        let mut image =
            RgbImage::from_pixel(camera.width_px, camera.height_px, image::Rgb([10, 10, 10]));
        let rough = Point3::new(0.0, 0.0, 800.0);
        let centre = camera.project(&rough).unwrap();
        for v in 0..camera.height_px {
            for u in 0..camera.width_px {
                let d =
                    ((f64::from(u) - centre.x).powi(2) + (f64::from(v) - centre.y).powi(2)).sqrt();
                if d < 20.0 {
                    image.put_pixel(u, v, image::Rgb([120, 30, 20]));
                }
            }
        }
        let level = target_level(&image, &camera, &rough, 40.0).unwrap();
        assert_eq!(level.p95_dn, 120.0);
        let away = Point3::new(5000.0, 0.0, 800.0);
        assert!(matches!(target_level(&image, &camera, &away, 40.0), Err(Error::InvalidInput(_))));
    }
}
