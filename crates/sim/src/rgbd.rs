//! What the simulator's RGB-D camera sees of a scan's scene: a colour image
//! and a depth image aligned to it, with that camera's depth errors, and
//! every apple's truth in its frame. The scene is the one the ALACS camera
//! scans (same seed, same scene); the RGB-D camera sits at
//! `alacs_from_rgbd` in the ALACS camera's frame.
//!
//! Depth errors, per image ([`RgbdErrors`]): a stereo camera's per-pixel
//! noise growing with z^2, a scale error of the whole image, holes and
//! flying pixels at depth edges, and scattered dropouts.

use alacs_model::{Camera, Ray, io::OutputDir};
use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::{Isometry3, Point3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde_json::json;

use crate::Result;
use crate::error::{save_image, save_json};
use crate::orchard::{Hit, Kind, OrchardScene};
use crate::render::{Lighting, RayMap, Scene, SurfaceHit, mix_seed};
use crate::scan::{SimulatedScan, surface_hit};

/// A depth image in millimetres, 0 where there is no data (REP 118's 16UC1).
pub type DepthMillimetres = ImageBuffer<Luma<u16>, Vec<u16>>;

/// The RGB-D camera's depth errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RgbdErrors {
    /// Per-pixel noise, mm per m^2 of depth: a D435 at 848 x 480 (f about
    /// 430 px, baseline 50 mm, subpixel 0.08) has z^2 x 0.08 / (f x
    /// baseline), 3.7 mm/m^2 (Grunnet-Jepsen et al., Intel, "Tuning depth
    /// cameras for best performance"; ../shared/REFERENCES.md).
    pub noise_mm_per_m2: f64,
    /// The image's scale error is drawn uniformly within this fraction
    /// (Intel's D400 datasheet: at most 2 % at 2 m; a unit after its
    /// on-chip self-calibration about 1 %).
    pub scale_error: f64,
    /// Neighbours whose depths differ by more than this, mm, are a depth
    /// edge: there a stereo camera leaves holes or mixes the two surfaces
    /// (flying pixels).
    pub edge_jump_mm: f64,
    /// Chance that an edge pixel is a hole (else it is a flying pixel).
    pub edge_hole: f64,
    /// Chance that any pixel has no data (texture-less or specular spots).
    pub dropout: f64,
    /// Farthest depth measured, mm.
    pub max_depth_mm: f64,
}

impl Default for RgbdErrors {
    fn default() -> Self {
        RgbdErrors {
            noise_mm_per_m2: 3.7,
            scale_error: 0.01,
            edge_jump_mm: 40.0,
            edge_hole: 0.5,
            dropout: 0.005,
            max_depth_mm: 6000.0,
        }
    }
}

/// One apple as the RGB-D camera sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdApple {
    /// Its centre in the RGB-D camera's frame, mm.
    pub centre_mm: Point3<f64>,
    /// Its equal-volume radius, mm.
    pub radius_mm: f64,
    /// The fraction of its silhouette in the colour image that other
    /// objects hide (1 where none of it is in the image).
    pub hidden: f64,
    /// Whether it is the scan's target.
    pub target: bool,
}

/// What the RGB-D camera saw.
#[derive(Debug, Clone)]
pub struct RgbdView {
    /// The colour camera.
    pub camera: Camera,
    /// The colour image.
    pub colour: RgbImage,
    /// The depth, aligned to the colour image.
    pub depth_mm: DepthMillimetres,
    /// Every apple, the target first.
    pub apples: Vec<RgbdApple>,
    /// The scale error drawn for this image.
    pub scale_error: f64,
    /// The camera's pose in the ALACS camera frame.
    pub alacs_from_rgbd: Isometry3<f64>,
}

/// The scene as the RGB-D camera sees it: rays in its frame, moved into the
/// ALACS camera's, where the scene is.
struct PosedScene<'a> {
    scene: &'a OrchardScene,
    alacs_from_rgbd: Isometry3<f64>,
}

impl PosedScene<'_> {
    /// A ray of the RGB-D camera's frame in the scene's (the ALACS camera's).
    fn in_scene(&self, ray: &Ray) -> Ray {
        Ray {
            origin: self.alacs_from_rgbd * ray.origin,
            direction: self.alacs_from_rgbd * ray.direction,
        }
    }

    fn hit(&self, ray: &Ray) -> Option<Hit> {
        self.scene.first_hit(&self.in_scene(ray), 0.0)
    }
}

impl Scene for PosedScene<'_> {
    fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let mut hit = surface_hit(self.hit(ray)?);
        let rgbd_from_alacs = self.alacs_from_rgbd.inverse();
        hit.point = rgbd_from_alacs * hit.point;
        hit.normal = rgbd_from_alacs * hit.normal;
        Some(hit)
    }

    fn blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        self.scene.segment_blocked(&(self.alacs_from_rgbd * from), &(self.alacs_from_rgbd * to))
    }
}

/// Noise stream of the RGB-D colour image (the ALACS frames use their index).
const RGBD_COLOUR_STREAM: u64 = 1 << 40;

/// Stream of the depth image's errors.
const RGBD_DEPTH_STREAM: u64 = (1 << 40) + 1;

impl SimulatedScan {
    /// What an RGB-D camera (`camera`, at `alacs_from_rgbd`) sees of this
    /// scan's scene (see the module docs).
    pub fn render_rgbd(
        &self,
        camera: &Camera,
        alacs_from_rgbd: &Isometry3<f64>,
        errors: &RgbdErrors,
    ) -> Result<RgbdView> {
        camera.validate()?;
        let scene = PosedScene { scene: &self.scene, alacs_from_rgbd: *alacs_from_rgbd };
        let rotation = alacs_from_rgbd.rotation;
        let lighting = Lighting {
            to_light_in_camera: rotation.inverse() * self.lighting.to_light_in_camera,
            ..self.lighting
        };
        let options = self.render_options();
        let ray_map = RayMap::with_pattern(camera, options.supersampling, options.pattern)?;
        let colour = ray_map.render(
            &scene,
            &lighting,
            None,
            &options.sensor,
            mix_seed(self.seed, RGBD_COLOUR_STREAM),
        );
        let (width, height) = (camera.width_px, camera.height_px);
        // Each pixel centre's ray in the scene's frame, once, and its first
        // hit: its depth and object.
        let rays: Vec<Option<Ray>> = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let pixel = nalgebra::Point2::new(f64::from(i % width), f64::from(i / width));
                let n = camera.undistort_pixel(&pixel).ok()?;
                Some(scene.in_scene(&Ray::through_normalized(n.x, n.y)))
            })
            .collect();
        let rgbd_from_alacs = alacs_from_rgbd.inverse();
        let hits: Vec<Option<(f64, usize)>> = rays
            .par_iter()
            .map(|ray| {
                let hit = self.scene.first_hit(ray.as_ref()?, 0.0)?;
                Some(((rgbd_from_alacs * hit.point).z, hit.object))
            })
            .collect();
        let apples = self.rgbd_apples(&rgbd_from_alacs, &rays, &hits);
        let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(self.seed, RGBD_DEPTH_STREAM));
        let scale_error = rng.random_range(-errors.scale_error..=errors.scale_error);
        let depth_mm = depth_image(&hits, (width, height), scale_error, errors, &mut rng);
        Ok(RgbdView {
            camera: camera.clone(),
            colour,
            depth_mm,
            apples,
            scale_error,
            alacs_from_rgbd: *alacs_from_rgbd,
        })
    }

    /// Every apple in the RGB-D camera's frame, with the fraction of its
    /// silhouette the first hits show to be another object.
    fn rgbd_apples(
        &self,
        rgbd_from_alacs: &Isometry3<f64>,
        rays: &[Option<Ray>],
        hits: &[Option<(f64, usize)>],
    ) -> Vec<RgbdApple> {
        let fruit: Vec<usize> = (0..self.scene.objects.len())
            .filter(|&i| self.scene.objects[i].kind == Kind::Fruit)
            .collect();
        fruit
            .iter()
            .zip(self.scene.apples())
            .map(|(&object, (centre, radius_mm))| {
                let (silhouette, seen) = rays
                    .par_iter()
                    .zip(hits)
                    .filter_map(|(ray, hit)| {
                        self.scene.first_hit_among(ray.as_ref()?, 0.0, object..object + 1)?;
                        Some((1usize, usize::from(hit.is_some_and(|(_, o)| o == object))))
                    })
                    .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
                RgbdApple {
                    centre_mm: rgbd_from_alacs * centre,
                    radius_mm,
                    hidden: if silhouette == 0 {
                        1.0
                    } else {
                        1.0 - seen as f64 / silhouette as f64
                    },
                    target: object == 0,
                }
            })
            .collect()
    }
}

/// The depth image of the first hits, with the camera's errors.
fn depth_image(
    hits: &[Option<(f64, usize)>],
    (width, height): (u32, u32),
    scale_error: f64,
    errors: &RgbdErrors,
    rng: &mut ChaCha8Rng,
) -> DepthMillimetres {
    let z = |u: u32, v: u32| hits[(v * width + u) as usize].map(|h| h.0);
    let mut depth = DepthMillimetres::new(width, height);
    for v in 0..height {
        for u in 0..width {
            let Some(here) = z(u, v) else { continue };
            // A depth edge: the farthest-differing neighbour.
            let neighbours = [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)];
            let other = neighbours
                .iter()
                .filter_map(|(du, dv)| {
                    let (x, y) = (i64::from(u) + du, i64::from(v) + dv);
                    (x >= 0 && y >= 0 && x < i64::from(width) && y < i64::from(height))
                        .then(|| z(x as u32, y as u32).unwrap_or(errors.max_depth_mm))
                })
                .max_by(|a, b| (a - here).abs().total_cmp(&(b - here).abs()));
            let mut value = here;
            if let Some(other) = other.filter(|o| (o - here).abs() > errors.edge_jump_mm) {
                if rng.random::<f64>() < errors.edge_hole {
                    continue;
                }
                value = here + rng.random::<f64>() * (other - here);
            }
            if rng.random::<f64>() < errors.dropout {
                continue;
            }
            let sigma = errors.noise_mm_per_m2 * (value / 1000.0).powi(2);
            let noise: f64 = StandardNormal.sample(rng);
            let measured = (value * (1.0 + scale_error) + sigma * noise).round();
            if measured > 0.0 && measured <= errors.max_depth_mm.min(f64::from(u16::MAX)) {
                depth.put_pixel(u, v, Luma([measured as u16]));
            }
        }
    }
    depth
}

impl RgbdView {
    /// truth.json of `alacs simulate rgbd`: every apple's centre and radius
    /// in the RGB-D camera's frame, how much of it is hidden, which is the
    /// target; the camera's pose and the depth's scale error.
    pub fn truth_json(&self) -> serde_json::Value {
        let apples: Vec<serde_json::Value> = self
            .apples
            .iter()
            .map(|a| {
                let c = a.centre_mm;
                json!({"position_mm": [c.x, c.y, c.z], "radius_mm": a.radius_mm, "hidden": a.hidden, "target": a.target})
            })
            .collect();
        let rows = crate::truth::matrix_rows(&self.alacs_from_rgbd);
        json!({
            "frame": "the RGB-D colour camera's optical frame, mm",
            "apples": apples,
            "alacs_from_rgbd": rows,
            "depth_scale_error": self.scale_error,
        })
    }

    /// Writes color.png, depth.png (16-bit, mm), camera.yaml (the colour
    /// camera) and truth.json into `out`.
    pub fn write_into(&self, out: &mut OutputDir) -> Result<()> {
        save_image(out, "color.png", &self.colour, None)?;
        out.write_with("depth.png", |w| {
            use image::ImageEncoder as _;
            let (width, height) = self.depth_mm.dimensions();
            // The encoder takes 16-bit samples in native byte order (PNG stores them big-endian).
            let bytes: Vec<u8> =
                self.depth_mm.as_raw().iter().flat_map(|d| d.to_ne_bytes()).collect();
            image::codecs::png::PngEncoder::new(w)
                .write_image(&bytes, width, height, image::ExtendedColorType::L16)
                .map_err(std::io::Error::other)
        })?;
        out.write("camera.yaml", self.camera.to_yaml_string())?;
        save_json(out, "truth.json", &self.truth_json())
    }
}
