//! The renderer: one ray per sub-pixel through the real camera model, a
//! Lambertian scene under ambient and directional light, the ALACS line
//! laser with a Gaussian cross-section and shadows, and a sensor with an
//! exposure time and gain, shot and read noise, a full well and 8-bit
//! quantization.
//!
//! The rays come from a [`RayMap`], computed once per camera with
//! [`Camera::undistort_pixel`] (eq. (3)) and reused for every view: the
//! renderer never approximates the lens. A pixel's value is the mean
//! radiance of its `s x s` sub-pixel rays (a box filter), then the sensor.
//!
//! # Units: what the numbers stand for
//!
//! Radiance is linear and counted in one unit per colour channel: the
//! radiance of a white Lambertian surface (albedo 1) under an irradiance of
//! [`IRRADIANCE_UNIT_W_PER_M2`] = 100 W/m^2 in that channel's band. For the
//! red channel (about 600-700 nm on a Bayer sensor) that is the scale of the
//! sun: ASTM G173's direct normal solar spectrum carries about 1.3
//! W/m^2/nm at 650 nm, some 130 W/m^2 over the red band. Light strengths
//! ([`Lighting`]) and the laser's peak irradiance ([`LaserLight::power`])
//! are in this unit; the orchard's sun is 1.3 (direct) + 0.35 (sky), its
//! shade 0.6 (diffuse daylight) + 0.2.
//!
//! The laser's unit follows from its power and line geometry: a 100 mW,
//! 650 nm line laser with a 40 deg fan spreads its power over a line 0.65 m
//! long at 0.9 m, and a Gaussian cross-section of sigma 0.6 mm (1.5 px of
//! the 5 MP camera at 0.9 m) puts P / (length sqrt(2 pi) sigma) = 100 W/m^2
//! at the line's centre: power 1.0. The simulator holds the peak constant
//! over the working range (a real line's falls as 1 / range, +-33 % over
//! 0.6-1.2 m; the scanner meters each scan, so this does not change what
//! it does).
//!
//! The sensor ([`Sensor`]) is linear (machine-vision cameras apply no
//! gamma). At the reference exposure [`REFERENCE_EXPOSURE_US`] = 1 ms and 0 dB
//! one radiance unit fills the pixel to [`Sensor::exposure_dn`] = 255 DN,
//! its full well of 10,200 electrons: a 3.45 um pixel (Sony IMX264-like,
//! the 5 MP camera) behind an f/8 lens sees E rho / (4 N^2) of a
//! Lambertian surface's irradiance E, 0.39 W/m^2 at 100 W/m^2, about
//! 1.5e7 photons/s at 650 nm, 9,000 electrons per ms at a quantum
//! efficiency of 0.6 (the model takes the full well, 12 % more: within
//! what the albedo, the lens's transmission and the quantum efficiency
//! are known to). Light scales with the exposure time, the gain
//! multiplies electrons into DN (and the noise with them); a pixel whose
//! electrons exceed the full well reads 255 (clipped), as does any value
//! the gain pushes past 255.

use std::fmt;

use alacs_model::{Camera, LaserModel, Plane, Ray};
use image::RgbImage;
use nalgebra::{Matrix2, Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use crate::orchard::value_noise;
use crate::{Error, Result};

/// Where a camera ray meets a surface of a [`Scene`], and how the surface
/// reflects there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// The point, in the camera frame (mm).
    pub point: Point3<f64>,
    /// Unit surface normal, facing the ray's origin.
    pub normal: Vector3<f64>,
    /// Lambertian albedo, linear RGB in 0..1.
    pub albedo_rgb: [f64; 3],
    /// Lambertian albedo at the laser's wavelength (red, 650 nm), 0..1.
    pub laser_reflectance: f64,
    /// Strength of a white Blinn-Phong highlight of the directional light
    /// (0 for a matte surface).
    pub specular: f64,
    /// Blinn-Phong exponent of the highlight (larger is tighter).
    pub shininess: f64,
    /// Whether the laser's light enters the surface and glows around the
    /// line ([`LaserLight::subsurface_sigma_mm`]): fruit flesh.
    pub translucent: bool,
}

/// What the renderer needs of a scene: the first surface along a ray, and
/// whether a segment is blocked (for the laser's shadows).
pub trait Scene: Sync {
    /// The nearest surface along `ray` at a positive ray parameter, if any.
    fn intersect(&self, ray: &Ray) -> Option<SurfaceHit>;

    /// [`Scene::intersect`] for the camera ray through undistorted
    /// normalized coordinates (x_n, y_n), i.e. from the optical centre along
    /// (x_n, y_n, 1). The renderer calls this once per sub-pixel; scenes may
    /// override it with a faster path that gives the same hit.
    fn intersect_camera_ray(&self, x_n: f64, y_n: f64) -> Option<SurfaceHit> {
        self.intersect(&Ray::through_normalized(x_n, y_n))
    }

    /// The hits of one pixel's sub-pixel camera rays, for scenes that can
    /// find them faster together than one by one: `hits[k]` for the ray
    /// through undistorted normalized coordinates `rays[k]`, as
    /// [`Scene::intersect_camera_ray`] gives it (for instance sharing a
    /// texture that is smooth at the scale of a pixel), and true. The
    /// renderer draws rays that are not finite (sub-pixels the lens model
    /// could not undistort) black, whatever their hit. The default returns
    /// false and leaves `hits` alone: the renderer then calls
    /// [`Scene::intersect_camera_ray`] for each ray.
    #[inline]
    fn intersect_camera_pixel(&self, rays: &[[f32; 2]], hits: &mut [Option<SurfaceHit>]) -> bool {
        let _ = (rays, hits);
        false
    }

    /// Whether a surface lies strictly between `from` and `to` (both in the
    /// camera frame, mm). A surface through `to` itself (the shaded point)
    /// does not count.
    fn blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool;
}

/// A camera's sub-pixel rays: for each pixel, `s x s` undistorted
/// normalized coordinates (u_n, v_n) at the sub-pixel offsets of a
/// [`SubpixelPattern`] around the pixel centre (pixel (0, 0) is the centre
/// of the top-left pixel), solved with the camera model's eq. (3) (see
/// [`RayMap::new`]).
///
/// Stored as f32 pairs, row-major by pixel and then by sample: f32 keeps
/// (u_n, v_n) to about 6e-8, 1.4e-4 px at f = 2320 px, and halves the memory
/// (a 5 MP camera at s = 3 takes 360 MB). A sub-pixel the model cannot
/// undistort (beyond a fold of the distortion) holds NaN and renders black.
pub struct RayMap {
    camera: Camera,
    supersampling: usize,
    pattern: SubpixelPattern,
    offsets: Vec<(f64, f64)>,
    rays: Vec<[f32; 2]>,
    failed: usize,
}

impl fmt::Debug for RayMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("RayMap")
            .field("camera", &self.camera.name)
            .field("width_px", &self.camera.width_px)
            .field("height_px", &self.camera.height_px)
            .field("supersampling", &self.supersampling)
            .field("pattern", &self.pattern)
            .field("failed", &self.failed)
            .finish()
    }
}

/// Where a pixel's `s x s` samples lie. Both put one sample in each cell of
/// an `s x s` grid over the pixel (stratified) and are symmetric about the
/// pixel centre, so the box filter is unbiased on smooth images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SubpixelPattern {
    /// The regular grid: sample (i, j) at `((i + 0.5) / s - 0.5, (j + 0.5) / s - 0.5)`.
    /// An edge that runs along a pixel axis then moves in steps of 1/s px,
    /// which biases it by up to 1/(2s) px: 0.17 px at s = 3.
    Grid,
    /// N-rooks (the canonical multi-jittered pattern of Chiu, Shirley and
    /// Wang): sample (i, j) at `((i s + j + 0.5) / s^2 - 0.5, (j s + i +
    /// 0.5) / s^2 - 0.5)`, still one per grid cell, but every sample in its
    /// own column and row of an `s^2 x s^2` grid, so an axis-aligned edge
    /// moves in steps of 1/s^2 px (bias at most 0.056 px at s = 3). The
    /// default: checkerboard edges are nearly axis-aligned, and on the test
    /// poses it cuts the worst rendered-corner error from 0.16 to 0.06 px
    /// at the same cost.
    #[default]
    NRooks,
}

impl SubpixelPattern {
    /// The offsets `(du, dv)` from the pixel centre of the `s x s` samples,
    /// px, sample k = j s + i in the grid cell of column i, row j.
    pub fn offsets_px(self, s: usize) -> Vec<(f64, f64)> {
        let n = (s * s) as f64;
        (0..s * s)
            .map(|k| {
                let (i, j) = (k % s, k / s);
                match self {
                    SubpixelPattern::Grid => {
                        ((i as f64 + 0.5) / s as f64 - 0.5, (j as f64 + 0.5) / s as f64 - 0.5)
                    }
                    SubpixelPattern::NRooks => {
                        (((i * s + j) as f64 + 0.5) / n - 0.5, ((j * s + i) as f64 + 0.5) / n - 0.5)
                    }
                }
            })
            .collect()
    }
}

/// Largest supersampling factor accepted: 16 x 16 rays per pixel is far past
/// the point where the box filter has converged.
pub const MAX_SUPERSAMPLING: usize = 16;

impl RayMap {
    /// [`RayMap::with_pattern`] with the default [`SubpixelPattern`].
    pub fn new(camera: &Camera, supersampling: usize) -> Result<RayMap> {
        Self::with_pattern(camera, supersampling, SubpixelPattern::default())
    }

    /// Computes every sub-pixel's ray of `camera`, `supersampling` x
    /// `supersampling` per pixel placed by `pattern`, in parallel over rows.
    /// Along each row of samples, Newton's method on w(p_bar) = K^-1 m
    /// ([`Camera::distort`], [`Camera::distort_jacobian`]) starts from the
    /// previous sample's solution and converges in one step; the first
    /// sample of a row, and any that does not converge at once, go through
    /// [`Camera::undistort_pixel`] itself. Both stop at its tolerance (a
    /// forward residual of 1e-15), so the rays are the model's to rounding.
    ///
    /// Fails for an invalid camera or a supersampling outside
    /// 1..=[`MAX_SUPERSAMPLING`].
    pub fn with_pattern(
        camera: &Camera,
        supersampling: usize,
        pattern: SubpixelPattern,
    ) -> Result<RayMap> {
        camera.validate()?;
        if !(1..=MAX_SUPERSAMPLING).contains(&supersampling) {
            return Err(Error::InvalidOptions(format!(
                "supersampling {supersampling} must lie in 1..={MAX_SUPERSAMPLING}"
            )));
        }
        let (width, height) = (camera.width_px as usize, camera.height_px as usize);
        let per_pixel = supersampling * supersampling;
        let mut rays = vec![[f32::NAN; 2]; width * height * per_pixel];
        let offsets = pattern.offsets_px(supersampling);
        let checked_r2 = RowMarch::image_checked_r2(camera);
        let failed: usize = rays
            .par_chunks_mut(width * per_pixel)
            .enumerate()
            .map(|(v, row)| {
                let mut failed = 0;
                for (k, &(offset_u, offset_v)) in offsets.iter().enumerate() {
                    let mut march = RowMarch::new(camera, checked_r2);
                    for u in 0..width {
                        let sub = Point2::new(u as f64 + offset_u, v as f64 + offset_v);
                        match march.undistort(&sub) {
                            Some(normalized) => {
                                row[u * per_pixel + k] = [normalized.x as f32, normalized.y as f32];
                            }
                            None => failed += 1,
                        }
                    }
                }
                failed
            })
            .sum();
        Ok(RayMap { camera: camera.clone(), supersampling, pattern, offsets, rays, failed })
    }

    /// The camera the rays belong to.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Sub-pixel rays per pixel along each axis.
    pub fn supersampling(&self) -> usize {
        self.supersampling
    }

    /// How many sub-pixels the camera model could not undistort (they render black).
    pub fn failed(&self) -> usize {
        self.failed
    }

    /// The sub-pixel sampling pattern.
    pub fn pattern(&self) -> SubpixelPattern {
        self.pattern
    }

    /// The samples' offsets `(du, dv)` from the pixel centre, px, in the
    /// order [`RayMap::normalized`] indexes them.
    pub fn offsets_px(&self) -> &[(f64, f64)] {
        &self.offsets
    }

    /// The undistorted normalized coordinates of sample `k` (0..s^2, see
    /// [`RayMap::offsets_px`]) of pixel `(u, v)`; None outside the image or
    /// where the model could not undistort.
    pub fn normalized(&self, u: u32, v: u32, k: usize) -> Option<Point2<f64>> {
        let per_pixel = self.supersampling * self.supersampling;
        if u >= self.camera.width_px || v >= self.camera.height_px || k >= per_pixel {
            return None;
        }
        let pixel = v as usize * self.camera.width_px as usize + u as usize;
        let [x, y] = self.rays[pixel * per_pixel + k];
        (x.is_finite() && y.is_finite()).then(|| Point2::new(f64::from(x), f64::from(y)))
    }

    /// Renders `scene` under `lighting` (and the laser stripe, if any) and
    /// records it with `sensor`; `noise_seed` seeds the sensor noise (same
    /// seed, same bytes, whatever the number of threads: each image row
    /// draws from its own generator seeded by `noise_seed` and the row).
    pub fn render(
        &self,
        scene: &impl Scene,
        lighting: &Lighting,
        laser: Option<&LaserStripe>,
        sensor: &Sensor,
        noise_seed: u64,
    ) -> RgbImage {
        self.render_with(scene, lighting, laser, sensor, noise_seed, None)
    }

    /// [`RayMap::render`] for the frames of one scene, byte for byte: the
    /// light without the laser is kept in `cache` from the first render,
    /// and later renders (the laser at another slide position, or off)
    /// shade again only the pixels the laser may reach: those with a
    /// sub-pixel hit within the stripe's cutoff of its plane. The cache is
    /// rebuilt when the lighting, the exposure, or the laser plane's
    /// direction or width changes; it must not be shared between scenes or
    /// ray maps.
    pub fn render_cached(
        &self,
        cache: &mut AmbientCache,
        scene: &impl Scene,
        lighting: &Lighting,
        laser: Option<&LaserStripe>,
        sensor: &Sensor,
        noise_seed: u64,
    ) -> RgbImage {
        self.render_with(scene, lighting, laser, sensor, noise_seed, Some(cache))
    }

    fn render_with(
        &self,
        scene: &impl Scene,
        lighting: &Lighting,
        laser: Option<&LaserStripe>,
        sensor: &Sensor,
        noise_seed: u64,
        cache: Option<&mut AmbientCache>,
    ) -> RgbImage {
        let (width, height) = (self.camera.width_px, self.camera.height_px);
        let per_pixel = self.supersampling * self.supersampling;
        // Light in DN at 0 dB for this exposure time; the gain comes after the noise.
        let scale_dn = sensor.exposure_dn * sensor.exposure.time_factor() / per_pixel as f64;
        let gain = sensor.exposure.gain_factor();
        let noisy = sensor.gain_dn_per_electron > 0.0 || sensor.read_noise_dn > 0.0;
        let read_variance = sensor.read_noise_dn * sensor.read_noise_dn;
        let row_rays = width as usize * per_pixel;
        // The light on a pixel, in DN before noise: the mean of its sub-pixel
        // rays, lit by `laser`. `hits` is scratch space for the pixel's s x s
        // hits. With `reach`, also the laser plane offsets that could light
        // one of the hits ([`AmbientCache`]).
        let pixel_light = |rays: &[[f32; 2]],
                           hits: &mut [Option<SurfaceHit>],
                           laser: Option<&LaserStripe>,
                           reach: Option<(&Reach, &mut [f32; 2])>| {
            let mut sum = [0.0; 3];
            let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut add = |x_n: f64, y_n: f64, hit: Option<&SurfaceHit>| {
                if let (Some((reach, _)), Some(hit)) = (&reach, hit)
                    && x_n.is_finite()
                    && y_n.is_finite()
                {
                    (low, high) = reach.widen(low, high, hit);
                }
                let radiance = shade(lighting, laser, scene, x_n, y_n, hit);
                for (channel, value) in sum.iter_mut().zip(radiance) {
                    *channel += value * scale_dn;
                }
            };
            if scene.intersect_camera_pixel(rays, hits) {
                for (&[x, y], hit) in rays.iter().zip(hits.iter()) {
                    add(f64::from(x), f64::from(y), hit.as_ref());
                }
            } else {
                for &[x, y] in rays {
                    let (x_n, y_n) = (f64::from(x), f64::from(y));
                    let finite = x_n.is_finite() && y_n.is_finite();
                    let hit = if finite { scene.intersect_camera_ray(x_n, y_n) } else { None };
                    add(x_n, y_n, hit.as_ref());
                }
            }
            if let Some((_, out)) = reach {
                *out = Reach::rounded_out(low, high);
            }
            sum
        };
        // Per row of the cache: whether it is being built, the light
        // without the laser, the offsets that reach each pixel.
        let reach = laser.map(Reach::of);
        let n_pixels = width as usize * height as usize;
        // The key of a cache being built is set once it is full.
        let mut built: Option<(&mut Option<CacheKey>, CacheKey)> = None;
        let cache_rows: Vec<Option<CacheRow>> = match cache {
            Some(cache) => {
                let building = cache.prepare(lighting, scale_dn, reach.as_ref(), n_pixels);
                let AmbientCache { key, ambient, offsets } = cache;
                if let Some(new_key) = building {
                    built = Some((key, new_key));
                }
                let w = width as usize;
                ambient
                    .chunks_mut(w)
                    .zip(offsets.chunks_mut(w))
                    .map(|(ambient, offsets)| Some((building.is_some(), ambient, offsets)))
                    .collect()
            }
            None => (0..height).map(|_| None).collect(),
        };
        // Row `v`'s light into `out`.
        let row_light = |v: usize,
                         hits: &mut [Option<SurfaceHit>],
                         cached: Option<CacheRow>,
                         out: &mut [[f64; 3]]| {
            let rays = &self.rays[v * row_rays..(v + 1) * row_rays];
            let pixels = rays.chunks_exact(per_pixel).zip(out.iter_mut());
            let Some((building, ambient, offsets)) = cached else {
                for (pixel, light) in pixels {
                    *light = pixel_light(pixel, hits, laser, None);
                }
                return;
            };
            for ((pixel, light), (ambient, offsets)) in
                pixels.zip(ambient.iter_mut().zip(offsets.iter_mut()))
            {
                if building {
                    *ambient =
                        pixel_light(pixel, hits, None, reach.as_ref().map(|r| (r, &mut *offsets)));
                }
                *light = match laser {
                    Some(stripe) if Reach::may_light(offsets, stripe) => {
                        pixel_light(pixel, hits, laser, None)
                    }
                    _ => *ambient,
                };
            }
        };
        // The full well clips; below it shot noise (Poisson, Gaussian
        // approximation) plus read noise, then the gain, then 8 bits. Every
        // channel draws its normal, clipped or not, so that one pixel's
        // clipping does not shift the next pixels' noise.
        let record = |light_dn: [f64; 3], out: &mut [u8], rng: &mut ChaCha8Rng| {
            for (value, signal_dn) in out.iter_mut().zip(light_dn) {
                let mut signal_dn = signal_dn;
                let normal: f64 = if noisy { StandardNormal.sample(rng) } else { 0.0 };
                if signal_dn >= FULL_WELL_DN {
                    *value = u8::MAX;
                    continue;
                }
                if noisy {
                    let variance = sensor.gain_dn_per_electron * signal_dn.max(0.0) + read_variance;
                    signal_dn += variance.sqrt() * normal;
                }
                *value = quantize(signal_dn * gain);
            }
        };
        let mut image = RgbImage::new(width, height);
        let width = width as usize;
        if sensor.blur_sigma_px > 0.0 {
            // The lens blurs the light before the sensor records it: light
            // first, then the blur, then the noise. The blur is separable:
            // each row is shaded and blurred along itself, then each output
            // row is blurred down the columns, noised and quantized.
            let kernel = GaussianKernel::new(sensor.blur_sigma_px);
            let mut light = vec![[0.0f32; 3]; width * height as usize];
            light.par_chunks_mut(width).zip(cache_rows).enumerate().for_each_init(
                || (vec![None; per_pixel], vec![[0.0f64; 3]; width], vec![[0.0f32; 3]; width]),
                |(hits, row, sharp), (v, (out, cached))| {
                    row_light(v, hits, cached, row);
                    for (s, l) in sharp.iter_mut().zip(row.iter()) {
                        *s = l.map(|c| c as f32);
                    }
                    kernel.blur_row(sharp, out);
                },
            );
            image.par_chunks_mut(width * 3).enumerate().for_each_init(
                || vec![[0.0f32; 3]; width],
                |blurred, (v, row)| {
                    kernel.blur_column_rows(&light, width, v, blurred);
                    let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(noise_seed, v as u64));
                    for (pixel, out) in blurred.iter().zip(row.chunks_exact_mut(3)) {
                        record(pixel.map(f64::from), out, &mut rng);
                    }
                },
            );
        } else {
            // No blur: shade and record each row in one pass.
            image.par_chunks_mut(width * 3).zip(cache_rows).enumerate().for_each_init(
                || (vec![None; per_pixel], vec![[0.0f64; 3]; width]),
                |(hits, light), (v, (row, cached))| {
                    let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(noise_seed, v as u64));
                    row_light(v, hits, cached, light);
                    for (pixel, out) in light.iter().zip(row.chunks_exact_mut(3)) {
                        record(*pixel, out, &mut rng);
                    }
                },
            );
        }
        if let Some((key, new_key)) = built {
            *key = Some(new_key);
        }
        if sensor.bayer {
            crate::bayer::mosaic_and_demosaic(&mut image);
        }
        image
    }
}

/// One image row of an [`AmbientCache`]: whether it is being built, the
/// light without the laser, and the laser plane offsets that reach each pixel.
type CacheRow<'a> = (bool, &'a mut [[f64; 3]], &'a mut [[f32; 2]]);

/// The light of a scene without the laser, per pixel, kept between the
/// renders of one scene's frames ([`RayMap::render_cached`]), and for each
/// pixel the range of laser plane offsets that could light one of its
/// sub-pixel hits. Only valid for the lighting, exposure and laser plane
/// direction it was built with; it rebuilds itself when they change.
#[derive(Default)]
pub struct AmbientCache {
    key: Option<CacheKey>,
    ambient: Vec<[f64; 3]>,
    offsets: Vec<[f32; 2]>,
}

impl fmt::Debug for AmbientCache {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("AmbientCache")
            .field("key", &self.key)
            .field("pixels", &self.ambient.len())
            .finish()
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct CacheKey {
    lighting: Lighting,
    scale_dn: f64,
    /// The laser plane's unit normal and the stripe's half width per mm
    /// of depth the offsets were found for (`None`: built without a laser).
    reach: Option<Reach>,
}

impl AmbientCache {
    /// Readies the cache for a render: `Some(key)` when this render must
    /// fill it, the key to set once it is full (until then it has none).
    fn prepare(
        &mut self,
        lighting: &Lighting,
        scale_dn: f64,
        reach: Option<&Reach>,
        n_pixels: usize,
    ) -> Option<CacheKey> {
        let same_light =
            self.key.is_some_and(|k| k.lighting == *lighting && k.scale_dn == scale_dn)
                && self.ambient.len() == n_pixels;
        // A render without the laser needs only the light; one with it needs
        // the offsets found for its plane's direction and width.
        let usable = same_light
            && match reach {
                None => true,
                Some(reach) => self.key.and_then(|k| k.reach) == Some(*reach),
            };
        if usable {
            return None;
        }
        self.key = None;
        self.ambient.clear();
        self.ambient.resize(n_pixels, [0.0; 3]);
        self.offsets.clear();
        self.offsets.resize(n_pixels, [f32::NEG_INFINITY, f32::INFINITY]);
        Some(CacheKey { lighting: *lighting, scale_dn, reach: reach.copied() })
    }
}

/// What decides whether a laser plane may light a surface point: the
/// plane's unit normal n and the stripe's cutoff half width per mm of
/// depth. [`LaserStripe::irradiance`] is zero unless |n . p - offset| <
/// cutoff sigma(z), so a plane lights p only with its offset within
/// n . p +- cutoff sigma(z).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Reach {
    normal: Vector3<f64>,
    half_width_per_depth: f64,
    /// Added to the half width on translucent surfaces, mm (the glow).
    glow_mm: f64,
}

/// Margin added to each side of a pixel's offset range, mm: far more than
/// the rounding of its arithmetic and of f32 storage (6e-5 mm at 1 m).
const REACH_MARGIN_MM: f64 = 0.01;

impl Reach {
    fn of(stripe: &LaserStripe) -> Reach {
        Reach {
            normal: stripe.plane.normal,
            half_width_per_depth: STRIPE_CUTOFF_SIGMAS * stripe.sigma_per_depth,
            glow_mm: stripe.glow_reach_mm(),
        }
    }

    /// The range (low, high) widened to hold the offsets that light `hit`
    /// (everything, where that is not finite).
    fn widen(&self, low: f64, high: f64, hit: &SurfaceHit) -> (f64, f64) {
        let centre = self.normal.dot(&hit.point.coords);
        let mut half = self.half_width_per_depth * hit.point.z.abs();
        if hit.translucent {
            half += self.glow_mm;
        }
        if centre.is_finite() && half.is_finite() {
            (low.min(centre - half), high.max(centre + half))
        } else {
            (f64::NEG_INFINITY, f64::INFINITY)
        }
    }

    /// The range as stored, rounded outwards by [`REACH_MARGIN_MM`] and more.
    fn rounded_out(low: f64, high: f64) -> [f32; 2] {
        let margin = |v: f64| REACH_MARGIN_MM + 1e-6 * v.abs();
        [(low - margin(low)) as f32, (high + margin(high)) as f32]
    }

    /// Whether `stripe`'s plane may light a pixel whose range is `offsets`.
    fn may_light(offsets: &[f32; 2], stripe: &LaserStripe) -> bool {
        let (offset, h) = (stripe.plane.offset_mm, stripe.half_sweep_mm);
        // NaN offsets light nothing (as in `LaserStripe::irradiance`); a
        // sweeping plane lights the pixel if any of its offsets would.
        f64::from(offsets[0]) < offset + h && offset - h < f64::from(offsets[1])
    }
}

/// Newton steps a warm-started undistortion may take before it falls back
/// to [`Camera::undistort_pixel`]; from the neighbour's solution it needs one.
const MARCH_MAX_STEPS: usize = 4;

/// The forward residual |w(p_bar) - m_n| (normalized units) at which a
/// warm-started undistortion stops: [`Camera::undistort_pixel`]'s target,
/// a few units in the last place.
const MARCH_TARGET_RESIDUAL: f64 = 1e-15;

/// Undistortion along one row of sub-pixels, warm-started from the previous
/// sub-pixel: the same Newton iteration on w(p_bar) = K^-1 m as
/// [`Camera::undistort_pixel`] (eq. (3)), started from the neighbour's
/// solution plus its Jacobian times the step, so it converges in one step
/// instead of several from the distorted point. The first sub-pixel of a
/// row, and any that does not converge at once, go through
/// `undistort_pixel` itself; the results agree to its tolerance (1e-15).
struct RowMarch<'a> {
    camera: &'a Camera,
    /// The previous sub-pixel's distorted normalized point, its solution,
    /// and the inverse of w's Jacobian there.
    previous: Option<(Point2<f64>, Point2<f64>, Matrix2<f64>)>,
    /// Largest r^2 = |p_bar|^2 at which the full invertibility check
    /// ([`Camera::is_distortion_invertible_at`]) has passed: the radial
    /// profile is then increasing up to it, so closer points only need the
    /// Jacobian's determinant checked.
    checked_r2: f64,
}

impl<'a> RowMarch<'a> {
    fn new(camera: &'a Camera, checked_r2: f64) -> Self {
        Self { camera, previous: None, checked_r2 }
    }

    /// The largest r^2 among the image corners' solutions where the full
    /// invertibility check passes (0 if none): a head start for every row.
    fn image_checked_r2(camera: &Camera) -> f64 {
        let (right, bottom) = (f64::from(camera.width_px) - 0.5, f64::from(camera.height_px) - 0.5);
        [(-0.5, -0.5), (right, -0.5), (-0.5, bottom), (right, bottom)]
            .iter()
            .filter_map(|&(u, v)| camera.undistort_pixel(&Point2::new(u, v)).ok())
            .filter(|x| camera.is_distortion_invertible_at(x))
            .map(|x| x.coords.norm_squared())
            .fold(0.0, f64::max)
    }

    /// K^-1 m without undoing the distortion (as the camera does internally).
    fn distorted_normalized(&self, pixel: &Point2<f64>) -> Point2<f64> {
        let c = self.camera;
        let y = (pixel.y - c.cy_px) / c.fy_px;
        Point2::new((pixel.x - c.cx_px - c.skew_px * y) / c.fx_px, y)
    }

    fn undistort(&mut self, pixel: &Point2<f64>) -> Option<Point2<f64>> {
        let target = self.distorted_normalized(pixel);
        self.previous = self.warm_newton(&target).or_else(|| {
            let exact = self.camera.undistort_pixel(pixel).ok()?;
            self.checked_r2 = self.checked_r2.max(exact.coords.norm_squared());
            let inverse = self.camera.distort_jacobian(&exact).try_inverse()?;
            Some((target, exact, inverse))
        });
        self.previous.map(|(_, solution, _)| solution)
    }

    /// Newton from the previous solution: the solution and the inverse of
    /// w's Jacobian at the last Newton iterate (within about 1e-8 of the
    /// solution, close enough to predict the next sub-pixel and to tell the
    /// orientation), or None (then the caller falls back).
    fn warm_newton(
        &mut self,
        target: &Point2<f64>,
    ) -> Option<(Point2<f64>, Point2<f64>, Matrix2<f64>)> {
        let (previous_target, previous, mut inverse) = self.previous?;
        let tolerance = MARCH_TARGET_RESIDUAL * target.coords.norm().max(1.0);
        let mut x = previous + inverse * (target - previous_target);
        for _ in 0..MARCH_MAX_STEPS {
            let residual = self.camera.distort(&x) - target;
            if residual.norm() <= tolerance {
                let r2 = x.coords.norm_squared();
                let invertible = if r2 <= self.checked_r2 {
                    inverse.determinant() > 0.0
                } else {
                    self.camera.is_distortion_invertible_at(&x)
                };
                if !invertible {
                    return None;
                }
                self.checked_r2 = self.checked_r2.max(r2);
                return Some((*target, x, inverse));
            }
            inverse = self.camera.distort_jacobian(&x).try_inverse()?;
            x -= inverse * residual;
        }
        None
    }
}

/// A normalized, sampled Gaussian for the lens blur, cut off at 3 sigma,
/// applied separably (rows, then columns) with clamped edges.
struct GaussianKernel {
    radius: usize,
    /// Weights of offsets -radius..=radius, summing to 1.
    weights: Vec<f32>,
}

impl GaussianKernel {
    fn new(sigma_px: f64) -> Self {
        let radius = (3.0 * sigma_px).ceil() as isize;
        let weights: Vec<f32> = (-radius..=radius)
            .map(|k| (-0.5 * (k as f64 / sigma_px).powi(2)).exp() as f32)
            .collect();
        let total: f32 = weights.iter().sum();
        let weights = weights.iter().map(|w| w / total).collect();
        Self { radius: radius as usize, weights }
    }

    /// Blurs `row` along itself into `out` (same length).
    fn blur_row(&self, row: &[[f32; 3]], out: &mut [[f32; 3]]) {
        let (r, n) = (self.radius, row.len());
        let tap = |u: usize| {
            let mut sum = [0.0f32; 3];
            for (k, w) in self.weights.iter().enumerate() {
                let s = row[(u + k).saturating_sub(r).min(n - 1)];
                for c in 0..3 {
                    sum[c] += w * s[c];
                }
            }
            sum
        };
        if n <= 2 * r {
            for (u, pixel) in out.iter_mut().enumerate() {
                *pixel = tap(u);
            }
            return;
        }
        for (u, pixel) in out.iter_mut().enumerate().take(r) {
            *pixel = tap(u);
        }
        for (u, pixel) in out.iter_mut().enumerate().skip(n - r) {
            *pixel = tap(u);
        }
        // The interior needs no clamping: tap k of pixel u is pixel u + k - r,
        // so each tap adds a shifted copy of the row, channels interleaved.
        let interior = out[r..n - r].as_flattened_mut();
        interior.fill(0.0);
        let row = row.as_flattened();
        for (k, w) in self.weights.iter().enumerate() {
            for (sum, s) in interior.iter_mut().zip(&row[3 * k..]) {
                *sum += w * s;
            }
        }
    }

    /// Row `v` of the row-major `image` (`width` pixels wide) blurred down
    /// its columns, into `out`.
    fn blur_column_rows(&self, image: &[[f32; 3]], width: usize, v: usize, out: &mut [[f32; 3]]) {
        let height = image.len() / width.max(1);
        let out = out.as_flattened_mut();
        out.fill(0.0);
        for (k, w) in self.weights.iter().enumerate() {
            let source = (v + k).saturating_sub(self.radius).min(height - 1);
            let source = image[source * width..][..width].as_flattened();
            for (sum, s) in out.iter_mut().zip(source) {
                *sum += w * s;
            }
        }
    }
}

/// 8-bit quantization: round to the nearest digital number, saturate at 0 and 255.
fn quantize(signal_dn: f64) -> u8 {
    // Clamped first, so adding 0.5 and truncating rounds half up without a
    // libm call; NaN maps to 0 through the saturating cast.
    (signal_dn.clamp(0.0, 255.0) + 0.5) as u8
}

/// The radiance seen along the camera ray through normalized (x_n, y_n),
/// which meets the scene at `hit`.
#[inline]
fn shade(
    lighting: &Lighting,
    laser: Option<&LaserStripe>,
    scene: &impl Scene,
    x_n: f64,
    y_n: f64,
    hit: Option<&SurfaceHit>,
) -> [f64; 3] {
    if !(x_n.is_finite() && y_n.is_finite()) {
        return [0.0; 3];
    }
    let Some(hit) = hit else {
        return [lighting.background; 3];
    };
    let facing = hit.normal.dot(&lighting.to_light_in_camera);
    let diffuse = lighting.directional * facing.max(0.0);
    let light = lighting.ambient + diffuse;
    let mut radiance = hit.albedo_rgb.map(|albedo| albedo * light);
    if hit.specular > 0.0 && facing > 0.0 {
        // Blinn-Phong: the half vector between the light and the camera.
        let to_camera = -Vector3::new(x_n, y_n, 1.0).normalize();
        let half = (lighting.to_light_in_camera + to_camera).normalize();
        let highlight = lighting.directional
            * hit.specular
            * hit.normal.dot(&half).max(0.0).powf(hit.shininess);
        radiance = radiance.map(|channel| channel + highlight);
    }
    if let Some(laser) = laser {
        let irradiance = laser.irradiance(scene, hit);
        if irradiance > 0.0 {
            let mut laser_radiance = irradiance * hit.laser_reflectance;
            if laser.speckle_contrast > 0.0 {
                let grain_mm = laser.grain_per_depth * hit.point.z.abs();
                let n = value_noise(&hit.point, grain_mm, SPECKLE_SEED);
                laser_radiance *= (1.0 + laser.speckle_contrast * (2.0 * n - 1.0)).max(0.0);
            }
            for (channel, weight) in radiance.iter_mut().zip(laser.rgb) {
                *channel += weight * laser_radiance;
            }
        }
    }
    radiance
}

/// Ambient and directional light (white), and the radiance of rays that
/// hit nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lighting {
    /// Ambient light strength (radiance of a white surface under it alone).
    pub ambient: f64,
    /// Directional light strength, times the cosine of incidence (Lambert).
    pub directional: f64,
    /// Unit direction from a surface towards the directional light, camera frame.
    pub to_light_in_camera: Vector3<f64>,
    /// Radiance of a ray that hits nothing (a dim, uniform background).
    pub background: f64,
}

impl Default for Lighting {
    /// Light from above, left and in front of the camera: a white surface
    /// (albedo 1) facing the camera has radiance 0.25 + 0.45 * 0.86 = 0.64.
    fn default() -> Self {
        Self {
            ambient: 0.25,
            directional: 0.45,
            to_light_in_camera: Vector3::new(-0.3, -0.5, -1.0).normalize(),
            background: 0.1,
        }
    }
}

/// How the laser looks: power, colour and the stripe's width in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserLight {
    /// Peak irradiance at the centre of the stripe (radiance units of a white surface).
    pub power: f64,
    /// How the laser's radiance splits over the sensor's R, G, B channels
    /// (a red 650 nm laser: mostly red, some leakage into G and B).
    pub rgb: [f64; 3],
    /// Standard deviation of the Gaussian cross-section, in pixels of the
    /// rendered image (converted to mm at each point's depth).
    pub stripe_sigma_px: f64,
    /// Amplitude of laser speckle: the laser's radiance is multiplied by
    /// 1 + c (2 n - 1) for a pixel-sized granular pattern n in 0..1 fixed on
    /// the surface. 0 turns it off.
    pub speckle_contrast: f64,
    /// Subsurface scattering on translucent surfaces ([`SurfaceHit::translucent`]):
    /// light entering the flesh leaves it around the line, a Gaussian of
    /// this sigma (mm, along the surface) added in quadrature to the
    /// line's cross-section, the light's total kept. 0 turns it off.
    pub subsurface_sigma_mm: f64,
    /// How far the glow's centre moves along the surface in the beam's
    /// direction, per mm of [`LaserLight::subsurface_sigma_mm`] and per unit
    /// of the sine of the beam's incidence across the line (light entering
    /// obliquely travels on before it scatters back out).
    pub subsurface_shift: f64,
    /// The line's cross-section from Gaussian (0: a single-mode diode's
    /// TEM00 beam) to flat-topped (1/sqrt 2, the most a symmetric pair
    /// of Gaussians keeps one peak): a multimode diode's line is not
    /// Gaussian across. Two Gaussians at +-f sigma, each of sigma
    /// sqrt(1 - f^2) sigma, so the cross-section's power and second moment
    /// stay those of the Gaussian of [`LaserLight::stripe_sigma_px`].
    /// Must lie in 0..1.
    pub profile_flatness: f64,
}

impl Default for LaserLight {
    /// Power 0.4: on a white square (albedo 0.85) the stripe adds up to
    /// 0.4 * 0.85 * cos(incidence) = 0.32 of the exposure, about 80 DN, so
    /// with the default lighting (the square itself at about 140 DN) the red
    /// channel peaks near 220 DN without saturating; on a black square
    /// (albedo 0.05) it adds only about 5 DN.
    fn default() -> Self {
        Self {
            power: 0.4,
            rgb: [1.0, 0.08, 0.05],
            stripe_sigma_px: 1.5,
            speckle_contrast: 0.0,
            subsurface_sigma_mm: 0.0,
            subsurface_shift: 0.0,
            profile_flatness: 0.0,
        }
    }
}

/// Seed of the speckle pattern (fixed: speckle belongs to the surface and
/// the laser, not to the frame's noise).
const SPECKLE_SEED: u64 = 0x5EC1_E000;

/// Gaussian cross-sections beyond this many sigmas contribute nothing (e^-18).
const STRIPE_CUTOFF_SIGMAS: f64 = 6.0;

/// The laser of one view: the ALACS laser plane and origin at a slide
/// position, with its look.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserStripe {
    /// The laser plane in the camera frame, with a unit normal.
    pub plane: Plane,
    /// The laser's origin in the camera frame (mm), for shadows.
    pub origin: Point3<f64>,
    /// Peak irradiance.
    pub power: f64,
    /// Colour of the laser's radiance on the sensor.
    pub rgb: [f64; 3],
    /// Stripe sigma in mm per mm of depth: sigma_mm = this * z.
    pub sigma_per_depth: f64,
    /// Speckle amplitude (see [`LaserLight::speckle_contrast`]).
    pub speckle_contrast: f64,
    /// Size of a speckle grain in mm per mm of depth: one pixel, 1 / fx.
    pub grain_per_depth: f64,
    /// Half the distance the plane travels along its normal during the
    /// exposure, mm: a laser on a moving slide ([`LaserStripe::sweeping`]).
    /// `plane` is then where it stands at mid-exposure. 0 for a still slide.
    pub half_sweep_mm: f64,
    /// Subsurface glow on translucent surfaces, mm ([`LaserLight::subsurface_sigma_mm`]).
    pub subsurface_sigma_mm: f64,
    /// The glow's shift per mm of its sigma ([`LaserLight::subsurface_shift`]).
    pub subsurface_shift: f64,
    /// The cross-section's flatness ([`LaserLight::profile_flatness`]).
    pub profile_flatness: f64,
}

impl LaserStripe {
    /// The stripe of `laser` at slide travel `slide_mm`, seen by a camera
    /// with focal length `fx_px`: sigma_mm = stripe_sigma_px * z / fx_px.
    pub fn new(laser: &LaserModel, slide_mm: f64, look: &LaserLight, fx_px: f64) -> LaserStripe {
        let plane = laser.plane_in_camera(slide_mm);
        let norm = plane.normal.norm();
        LaserStripe {
            plane: Plane { normal: plane.normal / norm, offset_mm: plane.offset_mm / norm },
            origin: laser.origin_in_camera(slide_mm),
            power: look.power,
            rgb: look.rgb,
            sigma_per_depth: look.stripe_sigma_px / fx_px,
            speckle_contrast: look.speckle_contrast,
            grain_per_depth: 1.0 / fx_px,
            half_sweep_mm: 0.0,
            subsurface_sigma_mm: look.subsurface_sigma_mm,
            subsurface_shift: look.subsurface_shift,
            profile_flatness: look.profile_flatness,
        }
    }

    /// The stripe of a laser whose plane moves at constant speed during the
    /// exposure, from `start`'s plane to `end`'s (the stripes at the slide
    /// positions where the exposure begins and ends): the plane where it
    /// stands at mid-exposure, its travel along the normal in
    /// [`LaserStripe::half_sweep_mm`], the origin (for shadows) at
    /// mid-exposure. The slide translates the laser without turning it, so
    /// both planes share their normal.
    pub fn sweeping(start: &LaserStripe, end: &LaserStripe) -> LaserStripe {
        let normal = start.plane.normal;
        let end_offset_mm = end.plane.offset_mm * end.plane.normal.dot(&normal);
        LaserStripe {
            plane: Plane { normal, offset_mm: 0.5 * (start.plane.offset_mm + end_offset_mm) },
            origin: start.origin + 0.5 * (end.origin - start.origin),
            half_sweep_mm: 0.5 * (end_offset_mm - start.plane.offset_mm).abs(),
            ..*start
        }
    }

    /// The laser irradiance at a hit, before the surface's reflectance:
    /// power * exp(-d^2 / (2 sigma^2)) * cos(incidence), d the point's
    /// distance from the laser plane; 0 where the lit side faces away from
    /// the laser origin or something in `scene` shadows the point.
    ///
    /// On a translucent surface with [`LaserStripe::subsurface_sigma_mm`]
    /// the cross-section is the subsurface glow's: wider, its centre moved.
    #[inline]
    pub fn irradiance(&self, scene: &impl Scene, hit: &SurfaceHit) -> f64 {
        let sigma_mm = self.sigma_per_depth * hit.point.z.abs();
        let distance_mm = self.plane.normal.dot(&hit.point.coords) - self.plane.offset_mm;
        if hit.translucent && self.subsurface_sigma_mm > 0.0 {
            let (distance_mm, glow_sigma_mm) = self.glow(hit, distance_mm, sigma_mm);
            let near =
                distance_mm.abs() < STRIPE_CUTOFF_SIGMAS * glow_sigma_mm + self.half_sweep_mm;
            if !near {
                return 0.0;
            }
            // The glow spreads the light, it does not add any.
            let spread = sigma_mm / glow_sigma_mm;
            return spread * self.lit(scene, hit, distance_mm, glow_sigma_mm, sigma_mm);
        }
        // Written so that NaN distances count as far.
        let near = distance_mm.abs() < STRIPE_CUTOFF_SIGMAS * sigma_mm + self.half_sweep_mm;
        if !near {
            return 0.0;
        }
        self.lit(scene, hit, distance_mm, sigma_mm, sigma_mm)
    }

    /// The irradiance at `distance_mm` from the plane through a cross-section
    /// of `sigma_mm` (the line's own `beam_sigma_mm`, or wider where the
    /// flesh glows), where the point faces the laser and nothing shadows it.
    #[inline]
    fn lit(
        &self,
        scene: &impl Scene,
        hit: &SurfaceHit,
        distance_mm: f64,
        sigma_mm: f64,
        beam_sigma_mm: f64,
    ) -> f64 {
        let to_origin = self.origin - hit.point;
        let cosine = hit.normal.dot(&to_origin) / to_origin.norm();
        let faces_laser = cosine > 0.0;
        if !faces_laser || scene.blocked(&self.origin, &hit.point) {
            return 0.0;
        }
        self.power * self.profile(distance_mm, sigma_mm, beam_sigma_mm) * cosine
    }

    /// Subsurface scattering in plane-distance terms: the point's distance
    /// from the glow's centre and the glow's sigma, both along the plane's
    /// normal. The surface's tangent plane holds the direction across the
    /// line, `across` = n_plane - n (n . n_plane), along which the plane
    /// distance grows by |across| per mm of surface: the glow's sigma
    /// (mm of surface) adds sigma_s |across| in quadrature, and its centre
    /// moves by shift sigma_s sin(i) along the surface, sin(i) the beam's
    /// direction along `across` (0 at normal incidence).
    fn glow(&self, hit: &SurfaceHit, distance_mm: f64, sigma_mm: f64) -> (f64, f64) {
        let n_plane = self.plane.normal;
        let across = n_plane - hit.normal * hit.normal.dot(&n_plane);
        let stretch = across.norm();
        let glow_mm = self.subsurface_sigma_mm * stretch;
        let sigma = (sigma_mm * sigma_mm + glow_mm * glow_mm).sqrt();
        let beam = hit.point - self.origin;
        let beam_norm = beam.norm();
        if !(stretch > 1e-9 && beam_norm > 0.0) {
            return (distance_mm, sigma);
        }
        let sin_incidence = beam.dot(&across) / (beam_norm * stretch);
        let shift_mm = self.subsurface_shift * self.subsurface_sigma_mm * sin_incidence;
        (distance_mm - shift_mm * stretch, sigma)
    }

    /// How far beyond the line's own cutoff (mm) the glow of a translucent
    /// surface may reach: its sigma at most adds `subsurface_sigma_mm`, its
    /// centre moves at most `|subsurface_shift| subsurface_sigma_mm`.
    fn glow_reach_mm(&self) -> f64 {
        if self.subsurface_sigma_mm > 0.0 {
            self.subsurface_sigma_mm * (STRIPE_CUTOFF_SIGMAS + self.subsurface_shift.abs())
        } else {
            0.0
        }
    }

    /// The stripe's cross-section at `distance_mm` from the plane, of the
    /// power of a Gaussian of `sigma_mm`: that Gaussian, or where the line is
    /// flat-topped ([`LaserLight::profile_flatness`] f) two at +-f times the
    /// line's own `beam_sigma_mm`, each as much narrower as keeps the second
    /// moment sigma_mm^2 (a glow widens both alike).
    fn profile(&self, distance_mm: f64, sigma_mm: f64, beam_sigma_mm: f64) -> f64 {
        let f = self.profile_flatness;
        if f <= 0.0 {
            return self.gaussian(distance_mm, sigma_mm);
        }
        let offset = f * beam_sigma_mm;
        let component = (sigma_mm * sigma_mm - offset * offset).max(0.0).sqrt();
        0.5 * sigma_mm / component
            * (self.gaussian(distance_mm - offset, component)
                + self.gaussian(distance_mm + offset, component))
    }

    /// A Gaussian cross-section at `distance_mm` from the plane, 1 at the
    /// centre of a still stripe: exp(-x^2 / (2 sigma^2)), or for a plane
    /// sweeping +-h during the exposure its mean over the exposure, the
    /// Gaussian convolved with a box of width 2h:
    /// sigma sqrt(pi / 2) / (2h) (erf((x + h) / (sigma sqrt 2)) - erf((x - h) / (sigma sqrt 2))).
    fn gaussian(&self, distance_mm: f64, sigma_mm: f64) -> f64 {
        let h = self.half_sweep_mm;
        // Below a thousandth of sigma the box changes the profile by less
        // than 1e-7: the still stripe's formula, without the cancellation.
        if h <= 1e-3 * sigma_mm {
            let ratio = distance_mm / sigma_mm;
            return (-0.5 * ratio * ratio).exp();
        }
        let scale = sigma_mm * std::f64::consts::SQRT_2;
        let mass = libm::erf((distance_mm + h) / scale) - libm::erf((distance_mm - h) / scale);
        sigma_mm * (std::f64::consts::PI / 2.0).sqrt() / (2.0 * h) * mass
    }
}

/// The exposure the sensor's [`Sensor::exposure_dn`] is given for, microseconds
/// (see the module's units).
pub const REFERENCE_EXPOSURE_US: f64 = 1000.0;

/// The irradiance one unit of [`Lighting`] and [`LaserLight::power`] stands
/// for, W/m^2 in a colour channel's band (see the module's units).
pub const IRRADIANCE_UNIT_W_PER_M2: f64 = 100.0;

/// The full well in DN at 0 dB: the 8-bit range matches it, so a pixel
/// reads 255 exactly when its electrons fill the well (and, above 0 dB,
/// also when the gain pushes it there).
const FULL_WELL_DN: f64 = 255.0;

/// A camera's exposure time and analogue gain: what the scan controller
/// sets through its camera (`FrameCamera::set_exposure_us`, `set_gain_db`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    /// Exposure time, microseconds.
    pub exposure_us: f64,
    /// Analogue gain, dB (amplitude: 10^(dB / 20)).
    pub gain_db: f64,
}

impl Default for Exposure {
    /// The reference exposure, 0 dB.
    fn default() -> Self {
        Self { exposure_us: REFERENCE_EXPOSURE_US, gain_db: 0.0 }
    }
}

impl Exposure {
    /// The light collected, relative to the reference exposure.
    pub fn time_factor(&self) -> f64 {
        self.exposure_us / REFERENCE_EXPOSURE_US
    }

    /// The gain as a factor on DN.
    pub fn gain_factor(&self) -> f64 {
        10f64.powf(self.gain_db / 20.0)
    }
}

/// The sensor: linear radiance to 8-bit digital numbers (DN) through an
/// exposure time, a full well, shot and read noise and a gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// DN at 0 dB per unit of radiance (a white surface under unit light)
    /// at the reference exposure [`REFERENCE_EXPOSURE_US`]; 255 DN is the full well.
    pub exposure_dn: f64,
    /// DN per photo-electron: shot noise has variance `gain * signal_dn`
    /// (Poisson statistics of the electrons, as a Gaussian). 0 turns it off.
    pub gain_dn_per_electron: f64,
    /// Standard deviation of the Gaussian read noise, DN. 0 turns it off.
    pub read_noise_dn: f64,
    /// Standard deviation of the lens's Gaussian blur, pixels, applied to
    /// the light before the sensor's noise. 0 turns it off.
    pub blur_sigma_px: f64,
    /// Exposure time and gain of the frame.
    pub exposure: Exposure,
    /// A colour sensor's RGGB Bayer filter with bilinear demosaicing: each
    /// pixel records one colour, the other two are interpolated (false: a
    /// value of every colour at every pixel).
    pub bayer: bool,
}

impl Default for Sensor {
    /// Exposure 255 DN per unit radiance (a white square, albedo 0.85, at
    /// about 140 DN under the default light), 0.025 DN per electron (a
    /// 10,200-electron full well over 255 DN: 2 DN shot noise at 160 DN)
    /// and 0.5 DN read noise (20 electrons); no blur (the supersampled
    /// pixels are sharp); the reference exposure.
    fn default() -> Self {
        Self {
            exposure_dn: 255.0,
            gain_dn_per_electron: 0.025,
            read_noise_dn: 0.5,
            blur_sigma_px: 0.0,
            exposure: Exposure::default(),
            bayer: false,
        }
    }
}

impl Sensor {
    /// The default sensor without noise (only quantization remains).
    pub fn noiseless() -> Sensor {
        Sensor { gain_dn_per_electron: 0.0, read_noise_dn: 0.0, ..Sensor::default() }
    }
}

/// The largest analogue gain a simulated sensor takes, dB (machine-vision
/// cameras reach 24-48 dB).
pub const MAX_GAIN_DB: f64 = 48.0;

/// Everything about how a view is rendered, apart from the scene and the laser model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Sub-pixel rays per pixel along each axis (s; s x s rays per pixel).
    pub supersampling: usize,
    /// Where the sub-pixel rays lie.
    pub pattern: SubpixelPattern,
    /// Ambient and directional light.
    pub lighting: Lighting,
    /// The laser's power, colour and stripe width.
    pub laser: LaserLight,
    /// Exposure and noise.
    pub sensor: Sensor,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            supersampling: 3,
            pattern: SubpixelPattern::default(),
            lighting: Lighting::default(),
            laser: LaserLight::default(),
            sensor: Sensor::default(),
        }
    }
}

impl RenderOptions {
    /// Checks that the options describe a renderable image.
    pub fn validate(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::InvalidOptions(m));
        if !(1..=MAX_SUPERSAMPLING).contains(&self.supersampling) {
            return invalid(format!(
                "supersampling {} must lie in 1..={MAX_SUPERSAMPLING}",
                self.supersampling
            ));
        }
        let l = &self.lighting;
        let non_negative = [
            ("ambient light", l.ambient),
            ("directional light", l.directional),
            ("background", l.background),
            ("laser power", self.laser.power),
            ("exposure_dn", self.sensor.exposure_dn),
            ("gain_dn_per_electron", self.sensor.gain_dn_per_electron),
            ("read_noise_dn", self.sensor.read_noise_dn),
            ("blur_sigma_px", self.sensor.blur_sigma_px),
            ("exposure_us", self.sensor.exposure.exposure_us),
            ("speckle contrast", self.laser.speckle_contrast),
            ("subsurface sigma", self.laser.subsurface_sigma_mm),
            ("subsurface shift", self.laser.subsurface_shift),
            ("profile flatness", self.laser.profile_flatness),
        ];
        let laser_rgb = self.laser.rgb.iter().map(|&c| ("laser colour", c));
        if let Some((name, value)) = non_negative
            .into_iter()
            .chain(laser_rgb)
            .find(|(_, value)| !(value.is_finite() && *value >= 0.0))
        {
            return invalid(format!("{name} must be finite and non-negative, got {value}"));
        }
        let gain_db = self.sensor.exposure.gain_db;
        if !(gain_db.is_finite() && (0.0..=MAX_GAIN_DB).contains(&gain_db)) {
            return invalid(format!("gain {gain_db} dB must lie within 0-{MAX_GAIN_DB} dB"));
        }
        if self.laser.profile_flatness >= 1.0 {
            return invalid(format!(
                "profile flatness {} must lie in 0..1",
                self.laser.profile_flatness
            ));
        }
        if !(self.laser.stripe_sigma_px.is_finite() && self.laser.stripe_sigma_px > 0.0) {
            return invalid(format!(
                "stripe sigma {} px must be positive",
                self.laser.stripe_sigma_px
            ));
        }
        let to_light = l.to_light_in_camera.norm();
        let unit = (to_light - 1.0).abs() < 1e-6;
        if !unit {
            return invalid(format!(
                "light direction must be a unit vector, has length {to_light}"
            ));
        }
        Ok(())
    }
}

/// Mixes a seed with a stream index into a new seed (SplitMix64's
/// finalizer): independent-looking seeds for each image and each row.
pub fn mix_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed ^ stream.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stripe(half_sweep_mm: f64) -> LaserStripe {
        LaserStripe {
            plane: Plane { normal: Vector3::x(), offset_mm: 0.0 },
            origin: Point3::origin(),
            power: 1.0,
            rgb: [1.0, 0.0, 0.0],
            sigma_per_depth: 1e-3,
            speckle_contrast: 0.0,
            grain_per_depth: 1e-3,
            half_sweep_mm,
            subsurface_sigma_mm: 0.0,
            subsurface_shift: 0.0,
            profile_flatness: 0.0,
        }
    }

    #[test]
    fn a_sweeping_stripe_is_the_mean_of_the_still_stripes_it_passes() {
        let sigma_mm = 0.8;
        for half_sweep_mm in [0.1, 0.8, 3.0] {
            let moving = stripe(half_sweep_mm);
            let still = stripe(0.0);
            for x in [-6.0, -2.0, -0.5, 0.0, 0.3, 1.7, 4.0] {
                // The mean over the exposure by the midpoint rule.
                let n = 20_000;
                let mean = (0..n)
                    .map(|i| {
                        let s = -half_sweep_mm + (i as f64 + 0.5) * 2.0 * half_sweep_mm / n as f64;
                        still.profile(x - s, sigma_mm, sigma_mm)
                    })
                    .sum::<f64>()
                    / n as f64;
                let profile = moving.profile(x, sigma_mm, sigma_mm);
                assert!(
                    (profile - mean).abs() < 1e-6,
                    "h {half_sweep_mm} x {x}: {profile} vs {mean}"
                );
            }
        }
        // No sweep: the still stripe's formula.
        assert_eq!(stripe(0.0).profile(0.4, sigma_mm, sigma_mm), (-0.125f64).exp());
    }

    /// A flat-topped line keeps the Gaussian's power and second moment, is
    /// flat at its centre at 1/sqrt 2, and a glow widens it as it does the
    /// Gaussian (the same power, the glow's second moment).
    #[test]
    fn a_flat_topped_line_keeps_the_gaussians_power_and_width() {
        let beam_mm = 0.8;
        let moments = |flatness: f64, sigma_mm: f64, half_sweep_mm: f64| {
            let line = LaserStripe { profile_flatness: flatness, ..stripe(half_sweep_mm) };
            let (step, mut power, mut second) = (1e-3, 0.0, 0.0);
            for i in -20_000..=20_000 {
                let x = f64::from(i) * step;
                let value = line.profile(x, sigma_mm, beam_mm) * step;
                power += value;
                second += value * x * x;
            }
            (power, second / power)
        };
        let glow_mm = (beam_mm * beam_mm + 1.5f64.powi(2)).sqrt();
        for sigma_mm in [beam_mm, glow_mm] {
            let (gaussian_power, gaussian_second) = moments(0.0, sigma_mm, 0.0);
            assert!((gaussian_power - sigma_mm * (std::f64::consts::TAU).sqrt()).abs() < 1e-6);
            for flatness in [0.3, 0.5, std::f64::consts::FRAC_1_SQRT_2, 0.9] {
                let (power, second) = moments(flatness, sigma_mm, 0.0);
                assert!((power - gaussian_power).abs() < 1e-6, "{flatness}: {power}");
                assert!((second - gaussian_second).abs() < 1e-6, "{flatness}: {second}");
                // A sweep spreads it without changing its power.
                let (swept, _) = moments(flatness, sigma_mm, 0.6);
                assert!((swept - gaussian_power).abs() < 1e-6, "{flatness}: {swept}");
            }
        }
        // At 1/sqrt 2 the centre is flat: its curvature vanishes, where a
        // Gaussian's is -1 / sigma^2.
        let curvature = |flatness: f64| {
            let line = LaserStripe { profile_flatness: flatness, ..stripe(0.0) };
            let (h, p) = (1e-3, |x: f64| line.profile(x, beam_mm, beam_mm));
            (p(h) - 2.0 * p(0.0) + p(-h)) / (h * h)
        };
        assert!((curvature(0.0) + 1.0 / (beam_mm * beam_mm)).abs() < 1e-4);
        assert!(curvature(std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-4);
    }
}
