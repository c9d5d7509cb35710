//! Orchard scans (FORMATS.md): five frames of a target apple with the laser
//! line stepping across it, as the seed paper's scanner takes them, with
//! scan.yaml, camera.yaml, laser.yaml and the ground truth in truth.json.
//!
//! The rough position the scanner starts from is the true fruit centre with
//! RGB-D-like error: up to 2 % of the depth along the line of sight (the
//! RealSense D435i's datasheet accuracy the paper quotes) and a couple of
//! millimetres across it. The slide positions follow the seed's strategy
//! ([`ScanStrategy`]): the first frame puts the laser on the left half of the
//! fruit, then 4 steps of 10 mm, shifted into the 0-200 mm stroke. By
//! default only fruit the plan reaches unshifted are placed
//! ([`ScanOptions::within_reach`]).
//!
//! [`ScanOptions::randomize`] draws per scan what real rigs and fruit vary
//! in ([`RigVariation`]): the same scene, other looks, sensor, calibration
//! errors and rough-position error.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use alacs_model::io::OutputDir;
use alacs_model::{
    Camera, FrameExposure, LaserModel, Ray, SCAN_FILE, Scan, ScanFrameSpec, ScanPlan, ScanStrategy,
    ScanTarget,
};
use image::RgbImage;
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde_json::json;

use crate::error::{check_scale, save_json};
use crate::orchard::{CameraRayGrid, Hit, OrchardOptions, OrchardScene, orchard_scene};
use crate::progress::ImageWriter;
use crate::render::{
    AmbientCache, Exposure, LaserLight, LaserStripe, Lighting, RayMap, RenderOptions, Scene,
    Sensor, SurfaceHit, mix_seed,
};
use crate::variation::{RigVariation, TakeOut};
use crate::{Error, Result, SlideError, camera_to_json, laser_to_json};

/// How to simulate a scan. `Default`: an unoccluded apple at 0.6-1.2 m in
/// diffuse light, the seed's 5-frame strategy, full resolution, PNG.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanOptions {
    /// The fruit and its surroundings (depth, radius, occlusion, clutter).
    pub orchard: OrchardOptions,
    /// Frames, step and stroke of the scan.
    pub strategy: ScanStrategy,
    /// Largest error of the rough position along the line of sight, as a
    /// fraction of the depth (uniform; the paper's RGB-D camera: 2 %).
    pub rough_depth_error: f64,
    /// Standard deviation of the rough position's error across the line of sight, mm.
    pub rough_lateral_sigma_mm: f64,
    /// Direct sunlight (a strong directional light) instead of diffuse shade.
    pub sun: bool,
    /// Also render each frame with the laser off (`frameN_off.png`).
    pub laser_off: bool,
    /// Render the camera resized by this factor ([`Camera::scaled`]).
    pub scale: f64,
    /// Supersampling, laser look and sensor; the lighting is set by `sun`.
    pub render: RenderOptions,
    /// Write JPEG frames of this quality (1-100) instead of PNG.
    pub jpeg_quality: Option<u8>,
    /// Place only fruit the scanner can sweep as planned: redraw the scene
    /// while the seed's plan for the rough position would have to be shifted
    /// into the stroke (the laser may then never cross the fruit). A
    /// harvester brings its scanner within reach of the fruit it picks.
    pub within_reach: bool,
    /// Name the cluster's other apples ([`OrchardOptions::cluster`]) in
    /// scan.yaml's `targets` too, each with a rough position of its own,
    /// and sweep them all ([`ScanStrategy::plan_sweep`]). The scene and
    /// lighting of a seed do not change.
    pub neighbours_as_targets: bool,
    /// Seed: same seed, same scene and same bytes.
    pub seed: u64,
    /// The slide's own error (scale and axis angle); the default is the
    /// seed's perfect slide.
    pub slide: SlideError,
    /// Draw the rig, fruit colour and camera per scan ([`RigVariation`],
    /// from the seed): laser look, subsurface glow, materials, sky, sensor,
    /// calibration errors (camera.yaml and laser.yaml stay the calibration
    /// given, the images show the drawn errors) and the rough position's
    /// error (replacing `rough_depth_error` and `rough_lateral_sigma_mm`).
    /// The scene, its lighting and the fruit are the same either way.
    pub randomize: bool,
    /// With `randomize`, causes of error rendered without, to measure what
    /// each costs ([`TakeOut`]; none by default).
    pub take_out: TakeOut,
}

impl Default for ScanOptions {
    fn default() -> Self {
        Self {
            orchard: OrchardOptions::default(),
            strategy: ScanStrategy::default(),
            rough_depth_error: 0.02,
            rough_lateral_sigma_mm: 2.0,
            sun: false,
            laser_off: false,
            scale: 1.0,
            render: RenderOptions {
                supersampling: SCAN_SUPERSAMPLING,
                laser: LaserLight {
                    power: SCAN_LASER_POWER,
                    speckle_contrast: SCAN_SPECKLE_CONTRAST,
                    ..LaserLight::default()
                },
                sensor: Sensor { blur_sigma_px: SCAN_BLUR_SIGMA_PX, ..Sensor::default() },
                ..RenderOptions::default()
            },
            jpeg_quality: None,
            within_reach: true,
            neighbours_as_targets: false,
            seed: 0,
            slide: SlideError::default(),
            randomize: false,
            take_out: TakeOut::default(),
        }
    }
}

/// Scenes drawn at most for one scan with [`ScanOptions::within_reach`].
const MAX_SCENE_DRAWS: usize = 200;

/// Laser power for scans: 2.5 times the calibration sessions' (a scan
/// exposes for a fruit in daylight, so the line must stand out against it),
/// 100 W/m^2 at the line's centre (a 100 mW line laser, see
/// [`crate::render`]), peaking near 0.55 on a red apple, as bright as the
/// apple itself in shade.
const SCAN_LASER_POWER: f64 = 1.0;

/// Rays per pixel along each axis for scans: 2 x 2 (n-rooks) resolves the
/// stripe's sub-pixel centre; the 3 x 3 of sessions is for board corners
/// to 0.1 px, which a scan has none of.
const SCAN_SUPERSAMPLING: usize = 2;

/// Laser speckle on the fruit and leaves: +-30 % grain, pixel-sized.
const SCAN_SPECKLE_CONTRAST: f64 = 0.3;

/// The lens's slight blur on orchard frames (sigma, pixels): a camera
/// focused on the fruit, with leaves and foliage at other depths.
const SCAN_BLUR_SIGMA_PX: f64 = 0.5;

/// Diffuse light in the shade of the canopy: 60 W/m^2 of diffuse daylight
/// in the red band (an overcast sky, or the open side of a canopy) and a
/// weak 20 W/m^2 from above (units: [`crate::render`]).
fn shade_lighting() -> Lighting {
    Lighting {
        ambient: 0.6,
        directional: 0.2,
        to_light_in_camera: Vector3::new(-0.2, -0.9, -0.4).normalize(),
        background: 0.3,
    }
}

/// Direct sun from above and behind the camera, 130 W/m^2 in the red band
/// (the direct normal solar spectrum, see [`crate::render`]) plus 35 W/m^2
/// of sky and canopy light: at the reference exposure a sunlit red apple
/// alone nearly fills the red channel and with the laser it clips, the
/// hard case for a red laser; a shorter exposure keeps both below the full
/// well, the laser adding about 60 % to the apple's red.
fn sun_lighting(rng: &mut ChaCha8Rng) -> Lighting {
    let heading: f64 = rng.random_range(-0.8..=0.8);
    let to_light = Vector3::new(heading.sin() * 0.6, -0.7, -0.5 - 0.3 * heading.cos()).normalize();
    Lighting { ambient: 0.35, directional: 1.3, to_light_in_camera: to_light, background: 0.9 }
}

/// One frame of a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFrame {
    /// File name of the laser-on image.
    pub image: String,
    /// File name of the laser-off image, if rendered.
    pub image_laser_off: Option<String>,
    /// Slide travel d, mm.
    pub slide_mm: f64,
}

/// A simulated scan: the scene, the plan, and how to render its frames.
#[derive(Debug)]
pub struct SimulatedScan {
    /// The camera's calibration (scaled), camera.yaml: what a localizer is
    /// given. The images show [`SimulatedScan::rendered_camera`].
    pub camera: Camera,
    /// The laser's calibration, laser.yaml: the laser given, with the
    /// slide's k (see [`SlideError`]). The images show
    /// [`SimulatedScan::rendered_laser`].
    pub laser: LaserModel,
    /// The camera the images are taken with: [`SimulatedScan::camera`]
    /// unless [`ScanOptions::randomize`] drew calibration errors.
    pub rendered_camera: Camera,
    /// The laser the images show: [`SimulatedScan::laser`] unless
    /// [`ScanOptions::randomize`] drew calibration errors.
    pub rendered_laser: LaserModel,
    /// What [`ScanOptions::randomize`] drew, if on.
    pub variation: Option<RigVariation>,
    /// The slide's own error.
    pub slide: SlideError,
    /// The orchard scene; the fruit is `scene.objects[0]`.
    pub scene: OrchardScene,
    /// The rough fruit position the scan started from (camera frame, mm).
    pub rough_position_mm: Point3<f64>,
    /// With [`ScanOptions::neighbours_as_targets`], the rough positions of
    /// the cluster's other apples, in [`OrchardScene::neighbours`]' order.
    pub more_targets: Vec<Point3<f64>>,
    /// The slide plan.
    pub plan: ScanPlan,
    /// The frames.
    pub frames: Vec<ScanFrame>,
    /// The lighting used.
    pub lighting: Lighting,
    render: RenderOptions,
    ray_map: RayMap,
    grid: CameraRayGrid,
    /// The light without the laser, shared by the frames' renders.
    cache: Mutex<AmbientCache>,
    jpeg_quality: Option<u8>,
    pub(crate) seed: u64,
}

/// An orchard scene with its [`CameraRayGrid`]: what the renderer draws.
struct GriddedScene<'a> {
    scene: &'a OrchardScene,
    grid: &'a CameraRayGrid,
}

pub(crate) fn surface_hit(hit: Hit) -> SurfaceHit {
    SurfaceHit {
        point: hit.point,
        normal: hit.normal,
        albedo_rgb: hit.material.albedo_rgb,
        laser_reflectance: hit.material.laser_reflectance,
        specular: hit.material.specular,
        shininess: hit.material.shininess,
        translucent: hit.material.translucent,
    }
}

impl Scene for GriddedScene<'_> {
    fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        self.scene.first_hit(ray, 0.0).map(surface_hit)
    }

    fn intersect_camera_ray(&self, x_n: f64, y_n: f64) -> Option<SurfaceHit> {
        let (t, normal, index) = self.grid.nearest(x_n, y_n)?;
        let point = Ray::through_normalized(x_n, y_n).at(t);
        let material = self.scene.objects[index].material_at(&point, &self.scene.appearance);
        Some(surface_hit(Hit { t, point, normal, material, object: index }))
    }

    /// Where every ray of the pixel meets the same object, its texture is
    /// evaluated once, at the mean of the hit points: the orchard's textures
    /// vary over millimetres (2.5 mm and up), a pixel spans well under one
    /// at these depths, so this is the box filter of a texture that is
    /// linear across the pixel. The geometry, the lighting, the laser and
    /// its pixel-sized speckle stay per ray. Pixels on an object's edge take
    /// the per-ray path.
    fn intersect_camera_pixel(&self, rays: &[[f32; 2]], hits: &mut [Option<SurfaceHit>]) -> bool {
        let mut object = None;
        let mut uniform = true;
        let mut sum = Vector3::zeros();
        for (&[x, y], hit) in rays.iter().zip(hits.iter_mut()) {
            let (x_n, y_n) = (f64::from(x), f64::from(y));
            let found =
                if x_n.is_finite() && y_n.is_finite() { self.grid.nearest(x_n, y_n) } else { None };
            let Some((t, normal, index)) = found else {
                uniform = false;
                break;
            };
            uniform &= object.is_none_or(|first| first == index);
            object = Some(index);
            let point = Ray::through_normalized(x_n, y_n).at(t);
            sum += point.coords;
            // The material follows below.
            *hit = Some(SurfaceHit {
                point,
                normal,
                albedo_rgb: [0.0; 3],
                laser_reflectance: 0.0,
                specular: 0.0,
                shininess: 1.0,
                translucent: false,
            });
        }
        match object {
            Some(index) if uniform => {
                let centre = Point3::from(sum / rays.len() as f64);
                let material =
                    self.scene.objects[index].material_at(&centre, &self.scene.appearance);
                for hit in hits.iter_mut().flatten() {
                    hit.albedo_rgb = material.albedo_rgb;
                    hit.laser_reflectance = material.laser_reflectance;
                    hit.specular = material.specular;
                    hit.shininess = material.shininess;
                    hit.translucent = material.translucent;
                }
            }
            _ => {
                for (&[x, y], hit) in rays.iter().zip(hits) {
                    let (x_n, y_n) = (f64::from(x), f64::from(y));
                    *hit = if x_n.is_finite() && y_n.is_finite() {
                        self.intersect_camera_ray(x_n, y_n)
                    } else {
                        None
                    };
                }
            }
        }
        true
    }

    fn blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        self.scene.segment_blocked(from, to)
    }
}

/// Simulates a scan of a fruit in an orchard scene per `options`.
pub fn simulate_scan(
    camera: &Camera,
    laser: &LaserModel,
    options: &ScanOptions,
) -> Result<SimulatedScan> {
    check_options(options)?;
    laser.validate()?;
    options.slide.validate()?;
    let laser = &options.slide.apply(laser);
    laser.validate()?;
    let camera = camera.scaled(options.scale);
    camera.validate()?;
    options.render.validate()?;
    let variation =
        options.randomize.then(|| RigVariation::for_seed(options.seed).without(options.take_out));
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut draws = 0;
    let (scene, rough_position_mm, plan) = loop {
        let scene =
            orchard_scene(&OrchardOptions { seed: rng.random(), ..options.orchard.clone() })?;
        let rough_position_mm = rough_position(&scene.fruit_centre, options, &mut rng)?;
        // The scanner knows the radius prior, not the fruit's true radius.
        let plan = options.strategy.plan(laser, &rough_position_mm, FRUIT_RADIUS_PRIOR_MM);
        draws += 1;
        if !(options.within_reach && plan.shifted) {
            break (scene, rough_position_mm, plan);
        }
        if draws == MAX_SCENE_DRAWS {
            return Err(Error::InvalidOptions(format!(
                "no fruit within the slide's reach in {MAX_SCENE_DRAWS} scenes: the depth range {:?} mm and off-axis angle {} deg do not suit this laser (or turn off within_reach)",
                options.orchard.depth_mm, options.orchard.max_off_axis_deg
            )));
        }
    };
    // The neighbours' rough positions from a generator of their own: the
    // lighting drawn next is the seed's either way.
    let mut more_targets = Vec::new();
    let (mut rough_position_mm, mut plan) = (rough_position_mm, plan);
    // The rough position's error drawn again, with the variation's bounds,
    // from a generator of its own: the scene above is the seed's either way.
    // With `within_reach`, drawn until the plan is unshifted (the scene's
    // first rough position was), at most MAX_SCENE_DRAWS times.
    let rough_options = match &variation {
        Some(v) => ScanOptions {
            rough_depth_error: v.rough_depth_error,
            rough_lateral_sigma_mm: v.rough_lateral_sigma_mm,
            ..options.clone()
        },
        None => options.clone(),
    };
    if variation.is_some() {
        let mut rough_rng = ChaCha8Rng::seed_from_u64(options.seed ^ VARIED_ROUGH_SEED);
        for _ in 0..MAX_SCENE_DRAWS {
            rough_position_mm =
                rough_position(&scene.fruit_centre, &rough_options, &mut rough_rng)?;
            plan = options.strategy.plan(laser, &rough_position_mm, FRUIT_RADIUS_PRIOR_MM);
            if !(options.within_reach && plan.shifted) {
                break;
            }
        }
    }
    if options.neighbours_as_targets {
        let mut neighbour_rng = ChaCha8Rng::seed_from_u64(options.seed ^ NEIGHBOUR_ROUGH_SEED);
        for (centre, _) in scene.neighbours() {
            more_targets.push(rough_position(&centre, &rough_options, &mut neighbour_rng)?);
        }
        let fruit: Vec<(Point3<f64>, f64)> = std::iter::once(rough_position_mm)
            .chain(more_targets.iter().copied())
            .map(|p| (p, FRUIT_RADIUS_PRIOR_MM))
            .collect();
        plan = options.strategy.plan_sweep(laser, &fruit);
    }
    let extension = if options.jpeg_quality.is_some() { "jpg" } else { "png" };
    let frames = plan
        .slides_mm
        .iter()
        .enumerate()
        .map(|(k, &slide_mm)| ScanFrame {
            image: format!("frame{k}.{extension}"),
            image_laser_off: options.laser_off.then(|| format!("frame{k}_off.{extension}")),
            slide_mm,
        })
        .collect();
    let lighting = if options.sun { sun_lighting(&mut rng) } else { shade_lighting() };
    let (mut scene, mut lighting, mut render) = (scene, lighting, options.render);
    let (mut rendered_camera, mut rendered_laser) = (camera.clone(), *laser);
    if let Some(v) = &variation {
        scene.appearance = v.appearance;
        if let Some(target) = scene.objects.first_mut() {
            target.shape = v.apple_shape(&target.shape);
        }
        lighting = v.lighting(&lighting);
        render = v.render_options(&render);
        render.validate()?;
        rendered_camera = v.rendered_camera(&camera, options.scale);
        rendered_camera.validate()?;
        rendered_laser = v.rendered_laser(laser);
        rendered_laser.validate()?;
    }
    let ray_map = RayMap::new(&rendered_camera, render.supersampling)?;
    let grid = CameraRayGrid::new(&scene);
    Ok(SimulatedScan {
        camera,
        laser: *laser,
        rendered_camera,
        rendered_laser,
        variation,
        slide: options.slide,
        scene,
        rough_position_mm,
        more_targets,
        plan,
        frames,
        lighting,
        render,
        ray_map,
        grid,
        cache: Mutex::new(AmbientCache::default()),
        jpeg_quality: options.jpeg_quality,
        seed: options.seed,
    })
}

/// Seeds the generator of the neighbours' rough positions (with the scan's seed).
const NEIGHBOUR_ROUGH_SEED: u64 = 0x6e65_6967_6862_6f75;

/// Seeds the generator of the target's rough position with
/// [`ScanOptions::randomize`] (with the scan's seed).
const VARIED_ROUGH_SEED: u64 = 0x726f_7567_6876_6172;

/// A rough position for a fruit centred at `truth`: the RGB-D camera's
/// error, uniform along the line of sight (a fraction of the depth) and
/// normal across it.
fn rough_position(
    truth: &Point3<f64>,
    options: &ScanOptions,
    rng: &mut ChaCha8Rng,
) -> Result<Point3<f64>> {
    let line_of_sight = truth.coords.normalize();
    let along = rng.random_range(-options.rough_depth_error..=options.rough_depth_error) * truth.z;
    let lateral = Normal::new(0.0, options.rough_lateral_sigma_mm)
        .map_err(|e| Error::InvalidOptions(format!("rough lateral error: {e}")))?;
    let across = Vector3::new(lateral.sample(rng), lateral.sample(rng), 0.0);
    let across = across - line_of_sight * across.dot(&line_of_sight);
    Ok(truth + line_of_sight * along + across)
}

fn check_options(options: &ScanOptions) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidOptions(m));
    check_scale(options.scale)?;
    if !(0.0..0.5).contains(&options.rough_depth_error) {
        return invalid(format!(
            "rough depth error {} must lie in 0..0.5",
            options.rough_depth_error
        ));
    }
    if !(options.rough_lateral_sigma_mm >= 0.0 && options.rough_lateral_sigma_mm.is_finite()) {
        return invalid("rough lateral error must be non-negative".into());
    }
    if options.strategy.frames == 0 || !(options.strategy.step_mm.is_finite()) {
        return invalid("a scan needs at least one frame and a finite step".into());
    }
    if options.jpeg_quality.is_some_and(|q| !(1..=100).contains(&q)) {
        return invalid("JPEG quality must lie in 1..100".into());
    }
    Ok(())
}

/// The radius prior written to scan.yaml: the middle of the seed's 35-45 mm
/// apples (the scanner does not know the true radius).
const FRUIT_RADIUS_PRIOR_MM: f64 = 40.0;

/// Noise stream of laser-off frames (laser-on frames use their index).
const LASER_OFF_STREAM: u64 = 1 << 32;

impl SimulatedScan {
    /// Renders frame `index` of the plan with the laser on (`laser = true`) or off.
    pub fn render_frame(&self, index: usize, laser: bool) -> Result<RgbImage> {
        let frame = self.frames.get(index).ok_or_else(|| {
            Error::InvalidOptions(format!(
                "frame {index} does not exist ({} frames)",
                self.frames.len()
            ))
        })?;
        self.render_at(frame.slide_mm, laser, index as u64)
    }

    /// Renders the scene with the slide at any travel `slide_mm` (not only
    /// the plan's), the laser on or off: what a scan controller's camera
    /// sees. `frame_index_for_noise` picks the sensor noise: frame k of the
    /// plan is `render_at(slides_mm[k], laser, k)`, byte for byte, and the
    /// laser-on and laser-off images of one index have independent noise.
    pub fn render_at(
        &self,
        slide_mm: f64,
        laser_on: bool,
        frame_index_for_noise: u64,
    ) -> Result<RgbImage> {
        self.render_exposed(slide_mm, laser_on, frame_index_for_noise, self.render.sensor.exposure)
    }

    /// [`SimulatedScan::render_at`] with the camera's exposure time and
    /// gain set to `exposure` (what a scan controller chose), instead of
    /// the scan's own.
    pub fn render_exposed(
        &self,
        slide_mm: f64,
        laser_on: bool,
        frame_index_for_noise: u64,
        exposure: Exposure,
    ) -> Result<RgbImage> {
        self.render_moving([slide_mm, slide_mm], laser_on, frame_index_for_noise, exposure)
    }

    /// [`SimulatedScan::render_exposed`] with the slide moving at constant
    /// speed during the exposure, from `slide_mm[0]` where the exposure
    /// begins to `slide_mm[1]` where it ends (a continuous sweep): the
    /// stripe is the laser's mean over the exposure, smeared along the
    /// slide's travel ([`LaserStripe::sweeping`]). Equal ends render
    /// [`SimulatedScan::render_exposed`]'s bytes.
    pub fn render_moving(
        &self,
        slide_mm: [f64; 2],
        laser_on: bool,
        frame_index_for_noise: u64,
        exposure: Exposure,
    ) -> Result<RgbImage> {
        let sensor = Sensor { exposure, ..self.render.sensor };
        RenderOptions { sensor, ..self.render }.validate()?;
        if let Some(d) = slide_mm.iter().find(|d| !d.is_finite()) {
            return Err(Error::InvalidOptions(format!("slide travel {d} mm is not finite")));
        }
        let stripe_at = |slide_mm: f64| {
            let (laser, fx_px) = (&self.rendered_laser, self.rendered_camera.fx_px);
            let mut stripe = LaserStripe::new(laser, slide_mm, &self.render.laser, fx_px);
            stripe.origin = self.slide.origin_in_camera(laser, slide_mm);
            stripe
        };
        let stripe = if slide_mm[0] == slide_mm[1] {
            stripe_at(slide_mm[0])
        } else {
            LaserStripe::sweeping(&stripe_at(slide_mm[0]), &stripe_at(slide_mm[1]))
        };
        let stream = if laser_on {
            frame_index_for_noise
        } else {
            LASER_OFF_STREAM.wrapping_add(frame_index_for_noise)
        };
        // A cache a panicking render left half full has no key: rebuilt.
        let mut cache = self.cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        Ok(self.ray_map.render_cached(
            &mut cache,
            &GriddedScene { scene: &self.scene, grid: &self.grid },
            &self.lighting,
            laser_on.then_some(&stripe),
            &sensor,
            mix_seed(self.seed, stream),
        ))
    }

    /// The render options (supersampling, laser look, sensor), as drawn
    /// with [`ScanOptions::randomize`].
    pub fn render_options(&self) -> &RenderOptions {
        &self.render
    }

    /// scan.yaml (FORMATS.md).
    pub fn scan_yaml(&self) -> String {
        let scan = Scan {
            dir: PathBuf::new(),
            rough_position_mm: self.rough_position_mm,
            fruit_radius_mm: FRUIT_RADIUS_PRIOR_MM,
            frames: self
                .frames
                .iter()
                .map(|f| ScanFrameSpec {
                    image: PathBuf::from(&f.image),
                    slide_mm: f.slide_mm,
                    image_laser_off: f.image_laser_off.as_ref().map(PathBuf::from),
                    planned_slide_mm: None,
                })
                .collect(),
            rough_position_in_rgbd_mm: None,
            more_targets: self
                .more_targets
                .iter()
                .map(|&rough_position_mm| ScanTarget {
                    rough_position_mm,
                    fruit_radius_mm: FRUIT_RADIUS_PRIOR_MM,
                    rough_position_in_rgbd_mm: None,
                })
                .collect(),
            plan_shifted_into_stroke: Some(self.plan.shifted),
            sweep_speed_mm_per_s: None,
            exposure: Some(FrameExposure {
                exposure_us: self.render.sensor.exposure.exposure_us,
                gain_db: self.render.sensor.exposure.gain_db,
            }),
        };
        scan.to_yaml_string(&format!(
            "Simulated by alacs-sim (seed {}); ground truth in truth.json.",
            self.seed
        ))
    }

    /// truth.json (FORMATS.md): the camera and laser the images show, the
    /// fruit's centre and equal-volume radius, plus how the scene was built
    /// and, with [`ScanOptions::randomize`], `variation`: every drawn value
    /// ([`RigVariation::to_json`]; camera.yaml and laser.yaml hold the
    /// calibration).
    pub fn truth_json(&self) -> serde_json::Value {
        let c = &self.scene.fruit_centre;
        let mut truth = json!({
            "camera": camera_to_json(&self.rendered_camera),
            "laser": laser_to_json(&self.rendered_laser),
            "slide": self.slide.to_json(),
            "fruit": {"position_mm": [c.x, c.y, c.z], "radius_mm": self.scene.fruit_radius_mm},
            "occlusion": self.scene.occlusion,
            "rough_position_mm": [self.rough_position_mm.x, self.rough_position_mm.y, self.rough_position_mm.z],
            "slides_mm": self.plan.slides_mm,
            "plan_shifted_into_stroke": self.plan.shifted,
            "sun": self.lighting.directional > 1.0,
            "neighbours": self.scene.neighbours().iter().map(|(c, r)| json!({
                "position_mm": [c.x, c.y, c.z], "radius_mm": r,
            })).collect::<Vec<_>>(),
            "exposure_us": self.render.sensor.exposure.exposure_us,
            "gain_db": self.render.sensor.exposure.gain_db,
            "targets": self.targets_json(),
            "seed": self.seed,
        });
        if let (Some(v), Some(map)) = (&self.variation, truth.as_object_mut()) {
            map.insert("variation".into(), v.to_json());
        }
        truth
    }

    /// truth.json's `targets`: per fruit of scan.yaml's `targets` (the
    /// target, then the neighbours named with it), its true centre and
    /// radius and its rough position; `null` for a scan of one fruit.
    fn targets_json(&self) -> serde_json::Value {
        if self.more_targets.is_empty() {
            return serde_json::Value::Null;
        }
        self.scene
            .apples()
            .into_iter()
            .zip(self.rough_positions())
            .map(|((c, r), p)| {
                json!({"position_mm": [c.x, c.y, c.z], "radius_mm": r, "rough_position_mm": [p.x, p.y, p.z]})
            })
            .collect()
    }

    /// The rough position of every fruit scan.yaml names: the target's,
    /// then [`SimulatedScan::more_targets`] (the same order as
    /// [`OrchardScene::apples`]).
    pub fn rough_positions(&self) -> Vec<Point3<f64>> {
        std::iter::once(self.rough_position_mm).chain(self.more_targets.iter().copied()).collect()
    }

    /// How many images [`SimulatedScan::write`] renders and writes.
    pub fn image_count(&self) -> usize {
        self.frames.iter().map(|f| 1 + usize::from(f.image_laser_off.is_some())).sum()
    }

    /// Writes scan.yaml, camera.yaml, laser.yaml, truth.json and every frame
    /// into `dir`, creating it ([`OutputDir`]: a folder holding files this
    /// did not write is refused); `progress(done, total)` after each image.
    pub fn write(&self, dir: &Path, progress: impl FnMut(usize, usize)) -> Result<()> {
        OutputDir::fill(dir, "simulate scan", false, |out| self.write_into(out, progress)).map(drop)
    }

    /// [`SimulatedScan::write`] into an open output folder (the caller may
    /// add files and then finishes it).
    pub fn write_into(
        &self,
        out: &mut OutputDir,
        progress: impl FnMut(usize, usize),
    ) -> Result<()> {
        let mut images = ImageWriter::new(out, self.image_count(), self.jpeg_quality, progress);
        for (index, frame) in self.frames.iter().enumerate() {
            images.save(&frame.image, &self.render_frame(index, true)?)?;
            if let Some(off) = &frame.image_laser_off {
                images.save(off, &self.render_frame(index, false)?)?;
            }
        }
        out.write(SCAN_FILE, self.scan_yaml())?;
        out.write("camera.yaml", self.camera.to_yaml_string())?;
        let comment = if self.variation.is_some() {
            "calibrated laser of the simulated scan (truth.json: the laser the images show)"
        } else {
            "true laser of the simulated scan"
        };
        self.laser.to_yaml_file(&out.file("laser.yaml")?, comment, None)?;
        save_json(out, "truth.json", &self.truth_json())
    }
}

/// A simulated scan with every frame of its plan rendered with the laser on:
/// what a localization is tested, swept and benchmarked on
/// ([`simulate_rendered_scan`]).
#[derive(Debug)]
pub struct RenderedScan {
    /// The scan: camera, laser, scene with the truth, rough position, plan.
    pub scan: SimulatedScan,
    /// The laser-on image of each of `scan.frames`, in order.
    pub images: Vec<RgbImage>,
}

impl RenderedScan {
    /// Each laser-on image with its slide travel in mm, in the plan's order.
    pub fn frames(&self) -> impl Iterator<Item = (&RgbImage, f64)> {
        self.images.iter().zip(&self.scan.frames).map(|(image, f)| (image, f.slide_mm))
    }
}

/// [`simulate_scan`], then every frame rendered with the laser on
/// ([`SimulatedScan::render_frame`]).
pub fn simulate_rendered_scan(
    camera: &Camera,
    laser: &LaserModel,
    options: &ScanOptions,
) -> Result<RenderedScan> {
    let scan = simulate_scan(camera, laser, options)?;
    let images =
        (0..scan.frames.len()).map(|i| scan.render_frame(i, true)).collect::<Result<_>>()?;
    Ok(RenderedScan { scan, images })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The frames of a scan rendered with the cache of the light without
    /// the laser ([`RayMap::render_cached`]) are the uncached renders, byte
    /// for byte, in any order, with the laser on and off and across an
    /// exposure change: sun, leaves, a cluster and branches in front;
    /// randomized too (the fruit's subsurface glow reaches farther).
    #[test]
    fn cached_frames_are_the_uncached_frames_byte_for_byte() {
        for randomize in [false, true] {
            cached_frames_match(randomize);
        }
    }

    fn cached_frames_match(randomize: bool) {
        let options = ScanOptions {
            orchard: OrchardOptions {
                occlusion: 0.3,
                cluster: 2,
                front_branches: 1,
                ..OrchardOptions::default()
            },
            sun: true,
            scale: 0.2,
            seed: 11,
            randomize,
            ..ScanOptions::default()
        };
        let scan =
            simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options).unwrap();
        let uncached = |slide_mm: f64, laser_on: bool, stream: u64, exposure: Exposure| {
            let sensor = Sensor { exposure, ..scan.render.sensor };
            let (laser, fx_px) = (&scan.rendered_laser, scan.rendered_camera.fx_px);
            let mut stripe = LaserStripe::new(laser, slide_mm, &scan.render.laser, fx_px);
            stripe.origin = scan.slide.origin_in_camera(laser, slide_mm);
            let stream = if laser_on { stream } else { LASER_OFF_STREAM.wrapping_add(stream) };
            scan.ray_map.render(
                &GriddedScene { scene: &scan.scene, grid: &scan.grid },
                &scan.lighting,
                laser_on.then_some(&stripe),
                &sensor,
                mix_seed(scan.seed, stream),
            )
        };
        let reference = scan.render.sensor.exposure;
        let short = Exposure { exposure_us: 250.0, gain_db: 3.0 };
        let slides = &scan.plan.slides_mm;
        let order = [
            (4, true, reference),
            (0, true, reference),
            (2, false, reference),
            (1, true, short),
            (3, true, short),
            (1, false, short),
            (0, true, reference),
        ];
        for (k, laser_on, exposure) in order {
            let cached = scan.render_exposed(slides[k], laser_on, k as u64, exposure).unwrap();
            assert!(
                cached == uncached(slides[k], laser_on, k as u64, exposure),
                "frame {k}, laser {laser_on}, {exposure:?}"
            );
        }
        // The laser lights pixels at all, and only a few need shading again.
        let lit = scan.render_frame(2, true).unwrap();
        let dark = scan.render_frame(2, false).unwrap();
        assert!(lit != dark);
    }
}
