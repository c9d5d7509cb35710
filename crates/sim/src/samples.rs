//! Calibration samples like the seed paper's: a board at `n_views` random
//! poses, `points_per_view` laser points on each, depth noise, outliers.

use std::path::Path;

use alacs_model::io::OutputDir;
use alacs_model::{Camera, LaserModel};
use alacs_model::{LaserSample, write_samples};
use nalgebra::{Point2, Point3, Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::error::{MAX_SAMPLES, check_positive_range, check_slides, save_json};
use crate::{Error, Result, camera_to_json, laser_to_json};

/// How to generate samples. `Default` is the seed paper's experiment:
/// 10 views at 0.6-1.2 m, 3 points each, 0.5 mm depth noise, no outliers.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleOptions {
    /// Board poses.
    pub n_views: usize,
    /// Laser points taken per view.
    pub points_per_view: usize,
    /// Range of board distances (depth of the laser line's centre), mm.
    pub depth_mm: (f64, f64),
    /// Largest board tilt from facing the camera, degrees.
    pub max_tilt_deg: f64,
    /// Half-size of the board: points farther from its centre are not on it, mm.
    pub board_half_size_mm: f64,
    /// Standard deviation of the Gaussian noise added to each measured depth, mm.
    pub depth_noise_mm: f64,
    /// Fraction of samples turned into outliers (0 to 1).
    pub outlier_fraction: f64,
    /// Range of an outlier's depth error (random sign), mm.
    pub outlier_error_mm: (f64, f64),
    /// Slide positions, cycled over the views (the paper calibrates at d = 0).
    pub slides_mm: Vec<f64>,
    /// Seed: same seed, same samples.
    pub seed: u64,
}

impl Default for SampleOptions {
    fn default() -> Self {
        Self {
            n_views: 10,
            points_per_view: 3,
            depth_mm: (600.0, 1200.0),
            max_tilt_deg: 30.0,
            board_half_size_mm: 150.0,
            depth_noise_mm: 0.5,
            outlier_fraction: 0.0,
            outlier_error_mm: (5.0, 50.0),
            slides_mm: vec![0.0],
            seed: 0,
        }
    }
}

/// Samples with their ground truth.
#[derive(Debug, Clone)]
pub struct SimulatedSamples {
    /// The samples, as samples.csv holds them.
    pub samples: Vec<LaserSample>,
    /// The noise-free depth of each sample.
    pub true_depth_mm: Vec<f64>,
    /// Indices of the rows made outliers, ascending.
    pub outliers: Vec<usize>,
    /// The camera the pixels were taken with.
    pub camera: Camera,
    /// The true laser.
    pub laser: LaserModel,
}

/// Tries per point before a view is declared infeasible.
const MAX_TRIES: usize = 1000;

/// Generates samples per `options`.
pub fn simulate_samples(
    camera: &Camera,
    laser: &LaserModel,
    options: &SampleOptions,
) -> Result<SimulatedSamples> {
    check_options(options)?;
    camera.validate()?;
    laser.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let noise = Normal::new(0.0, options.depth_noise_mm)
        .map_err(|e| Error::InvalidOptions(format!("depth noise: {e}")))?;
    // The normalized rows the image covers, for choosing where along the line to sample.
    let v_top = camera.undistort_pixel(&Point2::new(camera.cx_px, -0.5))?.y;
    let v_bottom =
        camera.undistort_pixel(&Point2::new(camera.cx_px, f64::from(camera.height_px) - 0.5))?.y;

    let mut samples = Vec::new();
    let mut true_depth_mm = Vec::new();
    for view in 0..options.n_views {
        let slide_mm = options.slides_mm[view % options.slides_mm.len()];
        let laser_plane = laser.plane_in_camera(slide_mm);
        // Board centre: where the laser crosses the optical axis row (v_n = 0) at a random depth.
        let z_mm = rng.random_range(options.depth_mm.0..=options.depth_mm.1);
        let u_n = (laser.alpha_rad.sin() - laser.laser_distance_mm(slide_mm) / z_mm)
            / laser.alpha_rad.cos();
        let centre = Point3::new(u_n * z_mm, 0.0, z_mm);
        let board_normal =
            random_tilt(&mut rng, options.max_tilt_deg) * Vector3::new(0.0, 0.0, -1.0);
        // The laser line on the board: the two planes' intersection.
        let direction = board_normal.cross(&laser_plane.normal);
        if direction.norm() < 1e-9 {
            return Err(Error::Infeasible(format!(
                "view {view}: board parallel to the laser plane"
            )));
        }
        let direction = direction.normalize();
        for _ in 0..options.points_per_view {
            let point = (0..MAX_TRIES)
                .find_map(|_| {
                    // A random image row, then the line's point seen on that row.
                    let v_n = rng.random_range(v_top..v_bottom);
                    let t = (v_n * centre.z - centre.y) / (direction.y - v_n * direction.z);
                    let point = centre + direction * t;
                    let on_board = t.abs() <= options.board_half_size_mm;
                    let visible = point.z > 0.0
                        && camera.project(&point).is_ok_and(|px| camera.contains_pixel(&px));
                    (on_board && visible).then_some(point)
                })
                .ok_or_else(|| {
                    Error::Infeasible(format!(
                        "view {view}: the laser line on the board is not in the image at {z_mm:.0} mm"
                    ))
                })?;
            true_depth_mm.push(point.z);
            samples.push(LaserSample {
                u_n: point.x / point.z,
                v_n: point.y / point.z,
                z_mm: point.z + noise.sample(&mut rng),
                slide_mm,
                pose: u32::try_from(view).ok(),
            });
        }
    }

    let n_outliers = (options.outlier_fraction * samples.len() as f64).round() as usize;
    let mut outliers = rand::seq::index::sample(&mut rng, samples.len(), n_outliers).into_vec();
    outliers.sort_unstable();
    for &i in &outliers {
        let magnitude = rng.random_range(options.outlier_error_mm.0..=options.outlier_error_mm.1);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        samples[i].z_mm = (samples[i].z_mm + sign * magnitude).max(1.0);
    }
    Ok(SimulatedSamples { samples, true_depth_mm, outliers, camera: camera.clone(), laser: *laser })
}

fn check_options(options: &SampleOptions) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidOptions(m));
    check_positive_range("depth range", options.depth_mm)?;
    if options.n_views == 0 || options.points_per_view == 0 {
        return invalid("need at least one view and one point per view".into());
    }
    if options.n_views.saturating_mul(options.points_per_view) > MAX_SAMPLES {
        return invalid(format!(
            "{} views x {} points per view is more than {MAX_SAMPLES} samples",
            options.n_views, options.points_per_view
        ));
    }
    if !(0.0..=1.0).contains(&options.outlier_fraction) {
        return invalid(format!("outlier fraction {} must lie in 0..1", options.outlier_fraction));
    }
    let (lo, hi) = options.outlier_error_mm;
    if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
        return invalid(format!(
            "outlier error range {lo}..{hi} mm must be non-negative and ordered"
        ));
    }
    if !(options.depth_noise_mm >= 0.0 && options.depth_noise_mm.is_finite()) {
        return invalid(format!("depth noise {} mm must be non-negative", options.depth_noise_mm));
    }
    check_slides(&options.slides_mm)?;
    if !(0.0..90.0).contains(&options.max_tilt_deg) {
        return invalid(format!("tilt {} deg must lie in 0..90", options.max_tilt_deg));
    }
    Ok(())
}

/// A rotation by a random angle up to `max_tilt_deg` about a random axis in the image plane.
pub(crate) fn random_tilt(rng: &mut ChaCha8Rng, max_tilt_deg: f64) -> Rotation3<f64> {
    let heading: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let tilt = rng.random_range(0.0..=max_tilt_deg.to_radians());
    let axis = Unit::new_normalize(Vector3::new(heading.cos(), heading.sin(), 0.0));
    Rotation3::from_axis_angle(&axis, tilt)
}

impl SimulatedSamples {
    /// Writes `samples.csv` and `truth.json` (FORMATS.md) into `dir`,
    /// creating it ([`OutputDir`]: a folder holding files this did not
    /// write is refused unless `force`).
    pub fn write(&self, dir: &Path, force: bool) -> Result<()> {
        let truth = serde_json::json!({
            "camera": camera_to_json(&self.camera),
            "laser": laser_to_json(&self.laser),
            "outliers": self.outliers,
            "true_depth_mm": self.true_depth_mm,
        });
        OutputDir::fill(dir, "simulate samples", force, |out| {
            out.write_with("samples.csv", |w| write_samples(w, &self.samples))?;
            save_json(out, "truth.json", &truth)
        })
        .map(drop)
    }
}
