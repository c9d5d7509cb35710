//! Orchard scenes for scans: a target apple (a sphere or a slightly
//! ellipsoidal fruit, textured red and green, with a specular highlight;
//! randomized rigs give it an apple's form, [`AppleForm`]),
//! leaves that hide a chosen fraction of it, branches, and a wall of
//! background foliage. Geometry and materials only; the renderer shades them.

use alacs_model::Ray;
use nalgebra::{Point3, Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::error::check_positive_range;
use crate::{Error, Result};

/// How a surface reflects light: Lambertian albedo per channel plus a Phong
/// highlight. `laser_reflectance` is the albedo at the laser's red
/// wavelength (650 nm): high on a red apple, low on chlorophyll.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Diffuse albedo, linear RGB in 0..1.
    pub albedo_rgb: [f64; 3],
    /// Diffuse albedo at the laser wavelength.
    pub laser_reflectance: f64,
    /// Strength of the specular highlight (0 = matte).
    pub specular: f64,
    /// Phong exponent of the highlight.
    pub shininess: f64,
    /// Whether laser light enters the surface and glows around the line
    /// (fruit flesh: [`crate::LaserLight::subsurface_sigma_mm`]).
    pub translucent: bool,
}

/// The colours and gloss of a scene's materials: one fruit cultivar (the
/// target and its cluster), its leaves and the background foliage.
/// `Default`: a bicolour apple, the scene's look without randomization.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Appearance {
    /// The fruit's blush (linear RGB albedo), in patches of a few cm.
    pub fruit_blush_rgb: [f64; 3],
    /// The fruit's ground colour under the blush.
    pub fruit_ground_rgb: [f64; 3],
    /// How much of the fruit the blush covers: blush = clamp(1.6 n + this)
    /// for value noise n in 0..1 (-0.3: about half; below -1.6: none).
    pub fruit_blush_offset: f64,
    /// Strength of the fruit's waxy highlight.
    pub fruit_specular: f64,
    /// Phong exponent of the fruit's highlight.
    pub fruit_shininess: f64,
    /// Leaf albedo (linear RGB), before its +-25 % shading.
    pub leaf_rgb: [f64; 3],
    /// Leaf albedo at the laser's 650 nm.
    pub leaf_laser_reflectance: f64,
    /// Strength of a leaf's highlight.
    pub leaf_specular: f64,
    /// Phong exponent of a leaf's highlight.
    pub leaf_shininess: f64,
    /// Background foliage albedo (linear RGB), before its patches of shade.
    pub background_rgb: [f64; 3],
    /// Background foliage albedo at 650 nm.
    pub background_laser_reflectance: f64,
}

impl Default for Appearance {
    fn default() -> Self {
        Self {
            fruit_blush_rgb: [0.55, 0.06, 0.05],
            fruit_ground_rgb: [0.42, 0.55, 0.12],
            fruit_blush_offset: -0.3,
            fruit_specular: 0.25,
            fruit_shininess: 40.0,
            leaf_rgb: [0.06, 0.22, 0.05],
            leaf_laser_reflectance: 0.08,
            leaf_specular: 0.08,
            leaf_shininess: 15.0,
            background_rgb: [0.07, 0.2, 0.06],
            background_laser_reflectance: 0.07,
        }
    }
}

/// Where a ray meets a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// The point, in the camera frame (mm).
    pub point: Point3<f64>,
    /// Unit surface normal, facing the ray's origin.
    pub normal: Vector3<f64>,
    /// The surface's material at the point.
    pub material: Material,
    /// Which object was hit (index into [`OrchardScene::objects`]).
    pub object: usize,
}

/// How an apple departs from an ellipsoid, in its body frame scaled to the
/// unit sphere (the stem along +z), every term inward so that the apple
/// stays within its ellipsoid: the surface lies at
/// `|q| = 1 - taper ((1 - q.z) / 2)^2 - lopsided ((1 - q.e) / 2)^2 - stem cavity - calyx cavity`
/// for the direction `q` from the centre: the calyx end narrower than the
/// stem end (a conic apple), one cheek flatter than the other (`e` points
/// to the fuller one), and each cavity a Gaussian dimple around its pole.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AppleForm {
    /// How much narrower the calyx end is, a fraction of the radius at the
    /// calyx pole (a quarter of it at the equator).
    pub taper: f64,
    /// How much flatter the cheek opposite `lopsided_axis` is, a fraction
    /// of the radius there.
    pub lopsided: f64,
    /// The unit direction of the fuller cheek, across the stem axis (body frame).
    pub lopsided_axis: [f64; 3],
    /// Depth of the stem cavity around +z, a fraction of the radius.
    pub stem_cavity_depth: f64,
    /// Its angular half-width (the dimple's Gaussian sigma), radians.
    pub stem_cavity_width_rad: f64,
    /// Depth of the calyx basin around -z, a fraction of the radius.
    pub calyx_cavity_depth: f64,
    /// Its angular half-width, radians.
    pub calyx_cavity_width_rad: f64,
}

/// Body-scaled steps of the search for an apple's surface along a ray: 0.8
/// mm on a 40 mm apple, a sixth of the narrowest cavity's sigma (0.12 of
/// the radius, `RigVariation::CALYX_CAVITY_WIDTH_RAD`): a ray steps over
/// the surface only where it grazes a cavity's rim within a step.
const APPLE_STEP: f64 = 0.02;

/// Bisections of a crossing: 2^-40 of a step.
const APPLE_BISECTIONS: usize = 40;

impl AppleForm {
    /// No departure from the ellipsoid.
    pub const NONE: AppleForm = AppleForm {
        taper: 0.0,
        lopsided: 0.0,
        lopsided_axis: [1.0, 0.0, 0.0],
        stem_cavity_depth: 0.0,
        stem_cavity_width_rad: 1.0,
        calyx_cavity_depth: 0.0,
        calyx_cavity_width_rad: 1.0,
    };

    /// The surface's distance from the centre in the direction `unit` (body
    /// frame, scaled to the unit sphere).
    fn radius(&self, unit: &Vector3<f64>) -> f64 {
        let axis = Vector3::from(self.lopsided_axis);
        let away = |m: f64| (0.5 * (1.0 - m)).powi(2);
        let dimple = |m: f64, depth: f64, width: f64| {
            let angle = m.clamp(-1.0, 1.0).acos();
            depth * (-0.5 * (angle / width.max(1e-6)).powi(2)).exp()
        };
        1.0 - self.taper * away(unit.z)
            - self.lopsided * away(unit.dot(&axis))
            - dimple(unit.z, self.stem_cavity_depth, self.stem_cavity_width_rad)
            - dimple(-unit.z, self.calyx_cavity_depth, self.calyx_cavity_width_rad)
    }

    /// The volume centroid of the body-scaled apple (the unit sphere's
    /// is its centre): the cavities move it away from their poles. By
    /// quadrature over the directions, `int r^4 / 4 w dw / int r^3 / 3 dw`.
    pub fn centroid(&self) -> Vector3<f64> {
        const POLAR: usize = 90;
        const AZIMUTH: usize = 180;
        let (mut moment, mut volume) = (Vector3::zeros(), 0.0);
        for i in 0..POLAR {
            let theta = (i as f64 + 0.5) * std::f64::consts::PI / POLAR as f64;
            let weight = theta.sin();
            for j in 0..AZIMUTH {
                let phi = (j as f64 + 0.5) * std::f64::consts::TAU / AZIMUTH as f64;
                let unit =
                    Vector3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
                let r = self.radius(&unit);
                moment += unit * (weight * r.powi(4) / 4.0);
                volume += weight * r.powi(3) / 3.0;
            }
        }
        moment / volume
    }

    /// Positive outside the surface, negative inside, at body-scaled `q`.
    fn level(&self, q: &Vector3<f64>) -> f64 {
        let norm = q.norm();
        if norm < 1e-12 {
            return -1.0;
        }
        norm - self.radius(&(q / norm))
    }
}

/// The nearest crossing of an apple's surface beyond `t_min` along the
/// body-scaled ray `o + t d` (`d` not unit), and the level's gradient there.
fn apple_crossing(
    form: &AppleForm,
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    t_min: f64,
) -> Option<(f64, Vector3<f64>)> {
    // Within a sphere a step larger than the ellipsoid (every term of the
    // form is inward), so the search begins outside the surface.
    let bound = 1.0 + APPLE_STEP;
    let (a, b, c) = (d.dot(d), o.dot(d), o.dot(o) - bound * bound);
    let disc = b * b - a * c;
    if disc < 0.0 || a <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let (t0, t1) = ((-b - root) / a, (-b + root) / a);
    if t1 <= t_min {
        return None;
    }
    let start = t0.max(t_min);
    let step = APPLE_STEP / a.sqrt();
    let level = |t: f64| form.level(&(o + d * t));
    // A start on the surface (a shadow ray leaving it at `t_min`) takes
    // the side the ray goes to.
    let mut previous = (start, level(start));
    if t_min > t0 && previous.1.abs() < 1e-9 {
        let next = (start + step).min(t1);
        previous = (next, level(next));
    }
    let mut t = previous.0;
    while t < t1 {
        t = (t + step).min(t1);
        let value = level(t);
        if value.signum() != previous.1.signum() {
            let (mut low, mut high) = (previous.0, t);
            let outside_low = previous.1 > 0.0;
            for _ in 0..APPLE_BISECTIONS {
                let mid = 0.5 * (low + high);
                if (level(mid) > 0.0) == outside_low {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            let hit = 0.5 * (low + high);
            let q = o + d * hit;
            let h = 1e-6;
            let gradient = Vector3::new(
                form.level(&(q + Vector3::x() * h)) - form.level(&(q - Vector3::x() * h)),
                form.level(&(q + Vector3::y() * h)) - form.level(&(q - Vector3::y() * h)),
                form.level(&(q + Vector3::z() * h)) - form.level(&(q - Vector3::z() * h)),
            );
            return Some((hit, gradient));
        }
        previous = (t, value);
    }
    None
}

/// The kinds of object in an orchard scene.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// An ellipsoid: centre, rotation (body to camera) and semi-axes.
    Ellipsoid {
        /// Centre in the camera frame, mm.
        centre: Point3<f64>,
        /// Rotation from the body frame to the camera frame.
        rotation: Rotation3<f64>,
        /// Semi-axes along the body frame's x, y, z, mm.
        semi_axes_mm: Vector3<f64>,
    },
    /// An apple: an ellipsoid given an apple's form ([`AppleForm`]).
    Apple {
        /// The ellipsoid's centre in the camera frame, mm (the apple's
        /// volume centroid lies at `rotation * (semi_axes * form.centroid())` from it).
        centre: Point3<f64>,
        /// Rotation from the body frame to the camera frame; the stem points
        /// along the body's +z.
        rotation: Rotation3<f64>,
        /// Semi-axes along the body frame's x, y, z, mm.
        semi_axes_mm: Vector3<f64>,
        /// How it departs from the ellipsoid.
        form: AppleForm,
    },
    /// A flat elliptical leaf.
    Leaf {
        /// Centre in the camera frame, mm.
        centre: Point3<f64>,
        /// Unit normal of the leaf's plane.
        normal: Unit<Vector3<f64>>,
        /// Unit direction of the leaf's long axis (perpendicular to `normal`).
        along: Unit<Vector3<f64>>,
        /// Half length along `along`, mm.
        half_length_mm: f64,
        /// Half width across, mm.
        half_width_mm: f64,
    },
    /// A straight branch: a cylinder between two points.
    Branch {
        /// One end, mm.
        start: Point3<f64>,
        /// The other end, mm.
        end: Point3<f64>,
        /// Radius, mm.
        radius_mm: f64,
    },
    /// An infinite plane (the background foliage wall).
    Wall {
        /// A point on the wall, mm.
        point: Point3<f64>,
        /// Unit normal.
        normal: Unit<Vector3<f64>>,
    },
}

/// What an object is, which decides its material.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The target fruit.
    Fruit,
    /// A leaf.
    Leaf,
    /// A branch.
    Branch,
    /// Background foliage.
    Background,
}

/// One object of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Its geometry.
    pub shape: Shape,
    /// What it is.
    pub kind: Kind,
    /// Seed of its texture.
    pub texture_seed: u64,
}

/// A target fruit and its surroundings.
#[derive(Debug, Clone, PartialEq)]
pub struct OrchardScene {
    /// Every object; the target fruit is `objects[0]`.
    pub objects: Vec<Object>,
    /// The fruit's centre in the camera frame, mm.
    pub fruit_centre: Point3<f64>,
    /// The fruit's equal-volume radius, mm (FORMATS.md's `radius_mm`).
    pub fruit_radius_mm: f64,
    /// Fraction of the fruit's silhouette hidden by leaves and branches, as built.
    pub occlusion: f64,
    /// The materials' colours and gloss.
    pub appearance: Appearance,
}

/// How to build an orchard scene. `Default`: a 35-45 mm apple, slightly
/// ellipsoidal, 0.6-1.2 m away, no occlusion.
#[derive(Debug, Clone, PartialEq)]
pub struct OrchardOptions {
    /// Range of the fruit's distance from the camera, mm.
    pub depth_mm: (f64, f64),
    /// Range of the fruit's equal-volume radius, mm.
    pub radius_mm: (f64, f64),
    /// Largest relative deviation of a semi-axis from the mean radius (0 = sphere).
    pub max_ellipticity: f64,
    /// Fraction of the fruit's silhouette to hide behind leaves (0 to 1).
    pub occlusion: f64,
    /// Leaves around the fruit that do not hide it (clutter).
    pub clutter_leaves: usize,
    /// Branches crossing the scene behind or beside the fruit.
    pub branches: usize,
    /// Other apples touching the target, beside or behind it (a cluster of
    /// 1 + `cluster` apples; 0-3).
    pub cluster: usize,
    /// Branches crossing in front of the fruit, across its silhouette.
    pub front_branches: usize,
    /// Distance of the background foliage behind the fruit, mm.
    pub background_behind_mm: f64,
    /// Largest angle of the fruit's direction from the optical axis, degrees.
    pub max_off_axis_deg: f64,
    /// Seed: same seed, same scene.
    pub seed: u64,
}

impl Default for OrchardOptions {
    fn default() -> Self {
        Self {
            depth_mm: (600.0, 1200.0),
            radius_mm: (35.0, 45.0),
            max_ellipticity: 0.08,
            occlusion: 0.0,
            clutter_leaves: 12,
            branches: 2,
            cluster: 0,
            front_branches: 0,
            background_behind_mm: 400.0,
            max_off_axis_deg: 6.0,
            seed: 0,
        }
    }
}

/// A branch is built of this many collinear cylinders ...
const BRANCH_PIECES: usize = 8;
/// ... each this long (with the direction's z slope, a bit longer): 800 mm in all.
const BRANCH_PIECE_MM: f64 = 100.0;

/// Rays per side of the grid that measures how much of the fruit is hidden.
const OCCLUSION_GRID: usize = 48;
/// Leaves tried before the requested occlusion counts as unreachable.
const MAX_OCCLUDING_LEAVES: usize = 200;

impl Shape {
    /// Ray parameter and outward normal of the nearest hit with t > `t_min`.
    pub fn intersect(&self, ray: &Ray, t_min: f64) -> Option<(f64, Vector3<f64>)> {
        match self {
            Shape::Ellipsoid { centre, rotation, semi_axes_mm } => {
                // In the body frame scaled to the unit sphere: |o + t d|^2 = 1.
                let body_from_camera = rotation.inverse();
                let o = (body_from_camera * (ray.origin - centre)).component_div(semi_axes_mm);
                let d = (body_from_camera * ray.direction).component_div(semi_axes_mm);
                let (a, b, c) = (d.dot(&d), o.dot(&d), o.dot(&o) - 1.0);
                let disc = b * b - a * c;
                if disc < 0.0 || a <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                let t = [(-b - root) / a, (-b + root) / a].into_iter().find(|&t| t > t_min)?;
                let local = o + d * t; // on the unit sphere
                let gradient = local.component_div(semi_axes_mm);
                Some((t, (rotation * gradient).normalize()))
            }
            Shape::Apple { centre, rotation, semi_axes_mm, form } => {
                let body_from_camera = rotation.inverse();
                let o = (body_from_camera * (ray.origin - centre)).component_div(semi_axes_mm);
                let d = (body_from_camera * ray.direction).component_div(semi_axes_mm);
                let (t, gradient) = apple_crossing(form, &o, &d, t_min)?;
                // The level's gradient in the camera frame (q = R^T (p - c) / s).
                Some((t, (rotation * gradient.component_div(semi_axes_mm)).normalize()))
            }
            Shape::Leaf { centre, normal, along, half_length_mm, half_width_mm } => {
                let t = plane_hit(ray, centre, normal, t_min)?;
                let offset = ray.at(t) - centre;
                let across = normal.cross(along);
                let (s, w) =
                    (offset.dot(along) / half_length_mm, offset.dot(&across) / half_width_mm);
                (s * s + w * w <= 1.0).then_some((t, normal.into_inner()))
            }
            Shape::Branch { start, end, radius_mm } => {
                let axis = end - start;
                let length = axis.norm();
                if length <= 0.0 {
                    return None;
                }
                let axis = axis / length;
                // Components perpendicular to the axis: |o_perp + t d_perp| = r.
                let o = ray.origin - start;
                let o_perp = o - axis * o.dot(&axis);
                let d_perp = ray.direction - axis * ray.direction.dot(&axis);
                let (a, b, c) = (
                    d_perp.dot(&d_perp),
                    o_perp.dot(&d_perp),
                    o_perp.dot(&o_perp) - radius_mm * radius_mm,
                );
                let disc = b * b - a * c;
                if disc < 0.0 || a <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                [(-b - root) / a, (-b + root) / a].into_iter().find_map(|t| {
                    let along = (ray.at(t) - start).dot(&axis);
                    (t > t_min && (0.0..=length).contains(&along)).then(|| {
                        let radial = ray.at(t) - (start + axis * along);
                        (t, radial.normalize())
                    })
                })
            }
            Shape::Wall { point, normal } => {
                plane_hit(ray, point, normal, t_min).map(|t| (t, normal.into_inner()))
            }
        }
    }
}

impl Shape {
    /// A sphere (centre, radius in mm) that contains the shape, or `None` for
    /// an unbounded shape.
    pub fn bounding_sphere(&self) -> Option<(Point3<f64>, f64)> {
        match self {
            Shape::Ellipsoid { centre, semi_axes_mm, .. } => Some((*centre, semi_axes_mm.max())),
            // Within its ellipsoid (every term of the form is inward).
            Shape::Apple { centre, semi_axes_mm, .. } => Some((*centre, semi_axes_mm.max())),
            Shape::Leaf { centre, half_length_mm, half_width_mm, .. } => {
                Some((*centre, half_length_mm.max(*half_width_mm)))
            }
            Shape::Branch { start, end, radius_mm } => {
                Some((nalgebra::center(start, end), (end - start).norm() / 2.0 + radius_mm))
            }
            Shape::Wall { .. } => None,
        }
    }
}

/// An object's index and its (x_n, y_n) ranges on the normalized image plane.
type ObjectBox = (usize, (f64, f64), (f64, f64));

/// Cells per side of [`CameraRayGrid`].
const GRID_CELLS: usize = 96;

/// A grid over the normalized image plane listing, per cell, the objects a
/// camera ray through that cell can hit: rays from the optical centre test a
/// few objects instead of all of them. Built from each object's bounding
/// sphere, so it never drops a hit.
#[derive(Debug, Clone)]
pub struct CameraRayGrid {
    min: (f64, f64),
    cell: (f64, f64),
    cells: Vec<Vec<usize>>,
    always: Vec<usize>,
    /// Every object's shape, prepared for camera rays.
    shapes: Vec<CameraShape>,
}

/// A [`Shape`] prepared for camera rays (rays from the optical centre):
/// the terms of [`Shape::intersect`] that do not depend on the ray's
/// direction, computed once per scene. The rest is the same arithmetic in
/// the same order, so the hits are the same to the last bit; the normal is
/// only worked out for the nearest hit.
#[derive(Debug, Clone)]
enum CameraShape {
    Ellipsoid {
        rotation: Rotation3<f64>,
        body_from_camera: Rotation3<f64>,
        semi_axes_mm: Vector3<f64>,
        /// The optical centre in the body frame scaled to the unit sphere.
        origin: Vector3<f64>,
        /// |origin|^2 - 1.
        c: f64,
    },
    Leaf {
        centre: Point3<f64>,
        normal: Unit<Vector3<f64>>,
        /// (centre - optical centre) . normal.
        offset: f64,
        along: Unit<Vector3<f64>>,
        across: Vector3<f64>,
        half_length_mm: f64,
        half_width_mm: f64,
    },
    Branch {
        start: Point3<f64>,
        /// Unit axis, and the length along it.
        axis: Vector3<f64>,
        length: f64,
        /// The optical centre relative to `start`, across the axis.
        origin_across: Vector3<f64>,
        /// |origin_across|^2 - radius^2.
        c: f64,
    },
    Wall {
        normal: Unit<Vector3<f64>>,
        /// (point - optical centre) . normal.
        offset: f64,
    },
    /// A shape without a camera-ray shortcut (an apple): [`Shape::intersect`].
    General(Box<Shape>),
    /// A degenerate shape (a branch of length 0): never hit.
    Nothing,
}

impl CameraShape {
    fn new(shape: &Shape) -> Self {
        let origin = Point3::origin();
        match shape {
            Shape::Apple { .. } => CameraShape::General(Box::new(shape.clone())),
            Shape::Ellipsoid { centre, rotation, semi_axes_mm } => {
                let body_from_camera = rotation.inverse();
                let o = (body_from_camera * (origin - centre)).component_div(semi_axes_mm);
                CameraShape::Ellipsoid {
                    rotation: *rotation,
                    body_from_camera,
                    semi_axes_mm: *semi_axes_mm,
                    origin: o,
                    c: o.dot(&o) - 1.0,
                }
            }
            Shape::Leaf { centre, normal, along, half_length_mm, half_width_mm } => {
                CameraShape::Leaf {
                    centre: *centre,
                    normal: *normal,
                    offset: (centre - origin).dot(normal),
                    along: *along,
                    across: normal.cross(along),
                    half_length_mm: *half_length_mm,
                    half_width_mm: *half_width_mm,
                }
            }
            Shape::Branch { start, end, radius_mm } => {
                let axis = end - start;
                let length = axis.norm();
                if length <= 0.0 {
                    return CameraShape::Nothing;
                }
                let axis = axis / length;
                let o = origin - start;
                let origin_across = o - axis * o.dot(&axis);
                CameraShape::Branch {
                    start: *start,
                    axis,
                    length,
                    origin_across,
                    c: origin_across.dot(&origin_across) - radius_mm * radius_mm,
                }
            }
            Shape::Wall { point, normal } => {
                CameraShape::Wall { normal: *normal, offset: (point - origin).dot(normal) }
            }
        }
    }

    /// [`Shape::intersect`]'s ray parameter for a camera ray, `t_min` = 0.
    #[inline]
    fn parameter(&self, ray: &Ray) -> Option<f64> {
        match self {
            CameraShape::Ellipsoid { body_from_camera, semi_axes_mm, origin, c, .. } => {
                let d = (body_from_camera * ray.direction).component_div(semi_axes_mm);
                let (a, b) = (d.dot(&d), origin.dot(&d));
                let disc = b * b - a * c;
                if disc < 0.0 || a <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                [(-b - root) / a, (-b + root) / a].into_iter().find(|&t| t > 0.0)
            }
            CameraShape::Leaf {
                centre,
                normal,
                offset,
                along,
                across,
                half_length_mm,
                half_width_mm,
            } => {
                let t = camera_plane_hit(ray, normal, *offset)?;
                let offset = ray.at(t) - centre;
                let (s, w) =
                    (offset.dot(along) / half_length_mm, offset.dot(across) / half_width_mm);
                (s * s + w * w <= 1.0).then_some(t)
            }
            CameraShape::Branch { start, axis, length, origin_across, c } => {
                let d_across = ray.direction - axis * ray.direction.dot(axis);
                let (a, b) = (d_across.dot(&d_across), origin_across.dot(&d_across));
                let disc = b * b - a * c;
                if disc < 0.0 || a <= 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                [(-b - root) / a, (-b + root) / a].into_iter().find(|&t| {
                    let along = (ray.at(t) - start).dot(axis);
                    t > 0.0 && (0.0..=*length).contains(&along)
                })
            }
            CameraShape::Wall { normal, offset } => camera_plane_hit(ray, normal, *offset),
            CameraShape::General(shape) => shape.intersect(ray, 0.0).map(|(t, _)| t),
            CameraShape::Nothing => None,
        }
    }

    /// [`Shape::intersect`]'s outward normal at the hit of `ray` at `t`.
    fn normal(&self, ray: &Ray, t: f64) -> Vector3<f64> {
        match self {
            CameraShape::Ellipsoid { rotation, body_from_camera, semi_axes_mm, origin, .. } => {
                let d = (body_from_camera * ray.direction).component_div(semi_axes_mm);
                let local = origin + d * t;
                let gradient = local.component_div(semi_axes_mm);
                (rotation * gradient).normalize()
            }
            CameraShape::Leaf { normal, .. } | CameraShape::Wall { normal, .. } => {
                normal.into_inner()
            }
            CameraShape::Branch { start, axis, .. } => {
                let along = (ray.at(t) - start).dot(axis);
                let radial = ray.at(t) - (start + axis * along);
                radial.normalize()
            }
            CameraShape::General(shape) => {
                // The hit again, from just before it.
                let back = (1e-6 * t).max(1e-9);
                shape.intersect(ray, t - back).map_or_else(Vector3::zeros, |(_, normal)| normal)
            }
            CameraShape::Nothing => Vector3::zeros(),
        }
    }
}

/// [`plane_hit`] for a camera ray with `t_min` = 0, `offset` the plane's
/// (point - optical centre) . normal.
#[inline]
fn camera_plane_hit(ray: &Ray, normal: &Unit<Vector3<f64>>, offset: f64) -> Option<f64> {
    let along = normal.dot(&ray.direction);
    if along.abs() < 1e-12 {
        return None;
    }
    let t = offset / along;
    (t > 0.0).then_some(t)
}

impl CameraRayGrid {
    /// The grid of `scene`'s objects.
    pub fn new(scene: &OrchardScene) -> Self {
        // Conservative normalized-coordinate boxes of the bounding spheres.
        let mut boxes = Vec::new();
        let mut always = Vec::new();
        for (index, object) in scene.objects.iter().enumerate() {
            match object.shape.bounding_sphere() {
                Some((c, r)) if c.z - r > 1e-6 => {
                    let (near, far) = (c.z - r, c.z + r);
                    let range = |low: f64, high: f64| {
                        let candidates = [low / near, low / far, high / near, high / far];
                        let min = candidates.iter().copied().fold(f64::INFINITY, f64::min);
                        let max = candidates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        (min, max)
                    };
                    let (x, y) = (range(c.x - r, c.x + r), range(c.y - r, c.y + r));
                    boxes.push((index, x, y));
                }
                _ => always.push(index),
            }
        }
        let bound = |f: fn(&ObjectBox) -> (f64, f64)| {
            boxes
                .iter()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| (lo.min(a), hi.max(b)))
        };
        let (x_range, y_range) = if boxes.is_empty() {
            ((0.0, 1.0), (0.0, 1.0))
        } else {
            (bound(|b| b.1), bound(|b| b.2))
        };
        let cell = (
            ((x_range.1 - x_range.0) / GRID_CELLS as f64).max(1e-9),
            ((y_range.1 - y_range.0) / GRID_CELLS as f64).max(1e-9),
        );
        let mut cells = vec![Vec::new(); GRID_CELLS * GRID_CELLS];
        let to_cell = |value: f64, min: f64, size: f64| {
            (((value - min) / size).floor().max(0.0) as usize).min(GRID_CELLS - 1)
        };
        for (index, (x0, x1), (y0, y1)) in boxes {
            for j in to_cell(y0, y_range.0, cell.1)..=to_cell(y1, y_range.0, cell.1) {
                for i in to_cell(x0, x_range.0, cell.0)..=to_cell(x1, x_range.0, cell.0) {
                    cells[j * GRID_CELLS + i].push(index);
                }
            }
        }
        let shapes = scene.objects.iter().map(|object| CameraShape::new(&object.shape)).collect();
        Self { min: (x_range.0, y_range.0), cell, cells, always, shapes }
    }

    /// The nearest hit of the camera ray through normalized (x_n, y_n)
    /// among the objects of the scene the grid was built for: the ray
    /// parameter, the unit normal facing the camera, and the object; the
    /// same as [`OrchardScene::first_hit_among`] the grid's candidates.
    pub(crate) fn nearest(&self, x_n: f64, y_n: f64) -> Option<(f64, Vector3<f64>, usize)> {
        let ray = Ray::through_normalized(x_n, y_n);
        let mut best: Option<(f64, usize)> = None;
        for index in self.candidates(x_n, y_n) {
            if let Some(t) = self.shapes[index].parameter(&ray)
                && best.is_none_or(|(best_t, _)| t < best_t)
            {
                best = Some((t, index));
            }
        }
        let (t, index) = best?;
        let normal = self.shapes[index].normal(&ray, t);
        let normal = if normal.dot(&ray.direction) > 0.0 { -normal } else { normal };
        Some((t, normal, index))
    }

    /// The objects a camera ray through normalized (x_n, y_n) can hit.
    pub fn candidates(&self, x_n: f64, y_n: f64) -> impl Iterator<Item = usize> + '_ {
        let i = (x_n - self.min.0) / self.cell.0;
        let j = (y_n - self.min.1) / self.cell.1;
        let inside = (0.0..GRID_CELLS as f64).contains(&i) && (0.0..GRID_CELLS as f64).contains(&j);
        let cell: &[usize] =
            if inside { &self.cells[j as usize * GRID_CELLS + i as usize] } else { &[] };
        cell.iter().chain(&self.always).copied()
    }
}

/// Ray parameter where `ray` meets the plane through `point` with `normal`.
fn plane_hit(
    ray: &Ray,
    point: &Point3<f64>,
    normal: &Unit<Vector3<f64>>,
    t_min: f64,
) -> Option<f64> {
    let along = normal.dot(&ray.direction);
    if along.abs() < 1e-12 {
        return None;
    }
    let t = (point - ray.origin).dot(normal) / along;
    (t > t_min).then_some(t)
}

/// Smooth value noise in 0..1 over 3-D points (mm), with features of about
/// `scale_mm`; deterministic in `seed`. Trilinear interpolation (with
/// smoothstep weights) of hashed values on an integer lattice.
pub fn value_noise(point: &Point3<f64>, scale_mm: f64, seed: u64) -> f64 {
    let p = point.coords / scale_mm;
    let (fx, fy, fz) = (p.x.floor(), p.y.floor(), p.z.floor());
    let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
    let smooth = |f: f64| f * f * (3.0 - 2.0 * f);
    let (sx, sy, sz) = (smooth(p.x - fx), smooth(p.y - fy), smooth(p.z - fz));
    let corner = |dx: i64, dy: i64, dz: i64| lattice_value(ix + dx, iy + dy, iz + dz, seed);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = lerp(corner(0, 0, 0), corner(1, 0, 0), sx);
    let x10 = lerp(corner(0, 1, 0), corner(1, 1, 0), sx);
    let x01 = lerp(corner(0, 0, 1), corner(1, 0, 1), sx);
    let x11 = lerp(corner(0, 1, 1), corner(1, 1, 1), sx);
    lerp(lerp(x00, x10, sy), lerp(x01, x11, sy), sz)
}

/// [`value_noise`] over the x-y plane only (half the work), for surfaces
/// that face the camera such as the background wall.
pub fn value_noise_xy(point: &Point3<f64>, scale_mm: f64, seed: u64) -> f64 {
    let (x, y) = (point.x / scale_mm, point.y / scale_mm);
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let smooth = |f: f64| f * f * (3.0 - 2.0 * f);
    let (sx, sy) = (smooth(x - fx), smooth(y - fy));
    let corner = |dx: i64, dy: i64| lattice_value(ix + dx, iy + dy, 0, seed);
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    lerp(lerp(corner(0, 0), corner(1, 0), sx), lerp(corner(0, 1), corner(1, 1), sx), sy)
}

/// A hash of an integer lattice point to 0..1: the coordinates mixed with
/// large odd constants, then a 64-bit finalizer (from SplitMix64).
fn lattice_value(x: i64, y: i64, z: i64, seed: u64) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (z as u64).wrapping_mul(0x1656_67B1_9E37_79F9)
        ^ seed;
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^= h >> 31;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

impl Object {
    /// The material at `point` on this object, coloured per `look`.
    pub fn material_at(&self, point: &Point3<f64>, look: &Appearance) -> Material {
        match self.kind {
            Kind::Fruit => {
                // Blush over the ground colour, in patches of a few cm.
                let blush = (value_noise(point, 18.0, self.texture_seed) * 1.6
                    + look.fruit_blush_offset)
                    .clamp(0.0, 1.0);
                let speckle = value_noise(point, 2.5, self.texture_seed ^ 1) * 0.1;
                let (red, ground) = (&look.fruit_blush_rgb, &look.fruit_ground_rgb);
                let mix =
                    |i: usize| (blush * red[i] + (1.0 - blush) * ground[i]) * (0.95 + speckle);
                Material {
                    albedo_rgb: [mix(0), mix(1), mix(2)],
                    laser_reflectance: mix(0),
                    specular: look.fruit_specular,
                    shininess: look.fruit_shininess,
                    translucent: true,
                }
            }
            Kind::Leaf => {
                let shade = 0.75 + 0.5 * value_noise(point, 8.0, self.texture_seed);
                let rgb = &look.leaf_rgb;
                Material {
                    albedo_rgb: [rgb[0] * shade, rgb[1] * shade, rgb[2] * shade],
                    laser_reflectance: look.leaf_laser_reflectance * shade,
                    specular: look.leaf_specular,
                    shininess: look.leaf_shininess,
                    translucent: false,
                }
            }
            Kind::Branch => {
                let shade = 0.8 + 0.4 * value_noise(point, 6.0, self.texture_seed);
                Material {
                    albedo_rgb: [0.22 * shade, 0.16 * shade, 0.10 * shade],
                    laser_reflectance: 0.3 * shade,
                    specular: 0.0,
                    shininess: 1.0,
                    translucent: false,
                }
            }
            Kind::Background => {
                // Out-of-focus foliage: leaf-sized patches of light and shade.
                let patches = value_noise_xy(point, 25.0, self.texture_seed);
                let shade = 0.25 + 1.1 * patches * patches;
                let rgb = &look.background_rgb;
                Material {
                    albedo_rgb: [rgb[0] * shade, rgb[1] * shade, rgb[2] * shade],
                    laser_reflectance: look.background_laser_reflectance * shade,
                    specular: 0.0,
                    shininess: 1.0,
                    translucent: false,
                }
            }
        }
    }
}

impl OrchardScene {
    /// The other apples of the target's cluster ([`OrchardOptions::cluster`]):
    /// each one's centre and equal-volume radius, mm; empty without a cluster.
    pub fn neighbours(&self) -> Vec<(Point3<f64>, f64)> {
        self.objects
            .iter()
            .skip(1)
            .filter(|o| o.kind == Kind::Fruit)
            .filter_map(|o| match o.shape {
                Shape::Ellipsoid { centre, semi_axes_mm, .. } => {
                    Some((centre, (semi_axes_mm.x * semi_axes_mm.y * semi_axes_mm.z).cbrt()))
                }
                _ => None,
            })
            .collect()
    }

    /// The target, then [`OrchardScene::neighbours`]: each apple's centre
    /// and equal-volume radius, mm.
    pub fn apples(&self) -> Vec<(Point3<f64>, f64)> {
        std::iter::once((self.fruit_centre, self.fruit_radius_mm))
            .chain(self.neighbours())
            .collect()
    }

    /// The nearest hit along `ray` beyond `t_min`.
    pub fn first_hit(&self, ray: &Ray, t_min: f64) -> Option<Hit> {
        self.first_hit_among(ray, t_min, 0..self.objects.len())
    }

    /// [`Self::first_hit`] among the objects `candidates` only.
    pub fn first_hit_among(
        &self,
        ray: &Ray,
        t_min: f64,
        candidates: impl Iterator<Item = usize>,
    ) -> Option<Hit> {
        let mut best: Option<(f64, Vector3<f64>, usize)> = None;
        for index in candidates {
            let object = &self.objects[index];
            if let Some((t, normal)) = object.shape.intersect(ray, t_min)
                && best.is_none_or(|(best_t, _, _)| t < best_t)
            {
                best = Some((t, normal, index));
            }
        }
        let (t, normal, object) = best?;
        let point = ray.at(t);
        let normal = if normal.dot(&ray.direction) > 0.0 { -normal } else { normal };
        let material = self.objects[object].material_at(&point, &self.appearance);
        Some(Hit { t, point, normal, material, object })
    }

    /// Whether the straight segment from `from` to `to` is blocked by any
    /// object (a shadow test; the ends themselves do not count).
    pub fn segment_blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        let direction = to - from;
        let ray = Ray { origin: *from, direction };
        // t runs 0..1 along the segment; a small margin keeps the end surfaces out.
        const MARGIN: f64 = 1e-6;
        self.objects.iter().any(|object| {
            object.shape.intersect(&ray, MARGIN).is_some_and(|(t, _)| t < 1.0 - MARGIN)
        })
    }

    /// Fraction of the fruit's silhouette, seen from the camera centre,
    /// hidden by other objects (a grid of rays over its bounding disc).
    pub fn fruit_occlusion(&self) -> f64 {
        let (mut on_fruit, mut hidden) = (0usize, 0usize);
        let Some(fruit) = self.objects.first() else { return 0.0 };
        let centre = self.fruit_centre;
        let extent = self.fruit_radius_mm * 1.2 / centre.z;
        for i in 0..OCCLUSION_GRID {
            for j in 0..OCCLUSION_GRID {
                let s = (i as f64 + 0.5) / OCCLUSION_GRID as f64 * 2.0 - 1.0;
                let r = (j as f64 + 0.5) / OCCLUSION_GRID as f64 * 2.0 - 1.0;
                let ray = Ray::through_normalized(
                    centre.x / centre.z + s * extent,
                    centre.y / centre.z + r * extent,
                );
                if fruit.shape.intersect(&ray, 0.0).is_some() {
                    on_fruit += 1;
                    if self.first_hit(&ray, 0.0).is_some_and(|hit| hit.object != 0) {
                        hidden += 1;
                    }
                }
            }
        }
        if on_fruit == 0 { 0.0 } else { hidden as f64 / on_fruit as f64 }
    }
}

/// Builds an orchard scene per `options`.
pub fn orchard_scene(options: &OrchardOptions) -> Result<OrchardScene> {
    check_options(options)?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    // The fruit: a direction within the field of view and a depth.
    let depth = rng.random_range(options.depth_mm.0..=options.depth_mm.1);
    let off_axis = options.max_off_axis_deg.to_radians();
    let (x_n, y_n) = (
        rng.random_range(-off_axis..=off_axis).tan(),
        rng.random_range(-off_axis..=off_axis).tan(),
    );
    let fruit_centre = Point3::new(x_n * depth, y_n * depth, depth);
    let radius = rng.random_range(options.radius_mm.0..=options.radius_mm.1);
    let e = options.max_ellipticity;
    let mut semi_axes = Vector3::new(
        radius * (1.0 + rng.random_range(-e..=e)),
        radius * (1.0 + rng.random_range(-e..=e)),
        radius * (1.0 + rng.random_range(-e..=e)),
    );
    // Rescale to the drawn equal-volume radius.
    semi_axes *= radius / (semi_axes.x * semi_axes.y * semi_axes.z).cbrt();
    let rotation = random_rotation(&mut rng);
    let mut objects = vec![Object {
        shape: Shape::Ellipsoid { centre: fruit_centre, rotation, semi_axes_mm: semi_axes },
        kind: Kind::Fruit,
        texture_seed: rng.random(),
    }];

    // Background foliage behind the fruit, facing the camera.
    objects.push(Object {
        shape: Shape::Wall {
            point: Point3::new(0.0, 0.0, depth + options.background_behind_mm),
            normal: Vector3::z_axis(),
        },
        kind: Kind::Background,
        texture_seed: rng.random(),
    });

    // Branches: long cylinders passing near the fruit, behind or beside it.
    for _ in 0..options.branches {
        let through = fruit_centre
            + Vector3::new(
                rng.random_range(-150.0..=150.0),
                rng.random_range(-150.0..=150.0),
                rng.random_range(radius + 30.0..=radius + 200.0),
            );
        let heading: f64 = rng.random_range(0.0..std::f64::consts::PI);
        let direction = Vector3::new(heading.cos(), heading.sin(), rng.random_range(-0.3..=0.3));
        let radius_mm = rng.random_range(6.0..=15.0);
        let texture_seed = rng.random();
        objects.extend(branch_pieces(&through, &direction, radius_mm, texture_seed));
    }

    // Clutter leaves around the fruit, placed so that they do not cover it.
    let mut scene = OrchardScene {
        objects,
        fruit_centre,
        fruit_radius_mm: radius,
        occlusion: 0.0,
        appearance: Appearance::default(),
    };
    let mut placed = 0;
    for _ in 0..options.clutter_leaves * 20 {
        if placed == options.clutter_leaves {
            break;
        }
        let leaf = random_leaf(&mut rng, &fruit_centre, radius, 60.0..=220.0);
        scene.objects.push(leaf);
        if scene.fruit_occlusion() > 0.0 {
            scene.objects.pop();
        } else {
            placed += 1;
        }
    }

    // Occluding leaves in front of the fruit until the requested fraction is hidden.
    let mut tries = 0;
    let mut occlusion = scene.fruit_occlusion();
    while occlusion < options.occlusion {
        tries += 1;
        if tries > MAX_OCCLUDING_LEAVES {
            return Err(Error::Infeasible(format!(
                "could not hide {:.0} % of the fruit with {MAX_OCCLUDING_LEAVES} leaves",
                options.occlusion * 100.0
            )));
        }
        let leaf = random_leaf(&mut rng, &fruit_centre, radius, 0.0..=radius * 1.1);
        scene.objects.push(leaf);
        let after = scene.fruit_occlusion();
        // Keep leaves that add cover without overshooting the target by much.
        if after <= occlusion || after > options.occlusion + 0.1 {
            scene.objects.pop();
        } else {
            occlusion = after;
        }
    }
    // The cluster and the branches in front draw from their own generator:
    // the rest of the scene is that of the same seed without them.
    let mut cluster_rng = ChaCha8Rng::seed_from_u64(options.seed ^ CLUSTER_SEED);
    for _ in 0..options.cluster {
        if let Some(neighbour) = touching_apple(&mut cluster_rng, &scene, options) {
            scene.objects.push(neighbour);
        }
    }
    for _ in 0..options.front_branches {
        scene.objects.extend(front_branch(&mut cluster_rng, &fruit_centre, radius));
    }
    scene.occlusion = if options.cluster + options.front_branches > 0 {
        scene.fruit_occlusion()
    } else {
        occlusion
    };
    Ok(scene)
}

/// Seed offset of the cluster's and the front branches' generator.
const CLUSTER_SEED: u64 = 0xC1A5_7E25;

/// Most apples a cluster adds to the target.
pub const MAX_CLUSTER: usize = 3;

/// An apple touching the target (0-2 mm apart) or another apple of its
/// cluster, beside or behind it (its centre no more than 17 deg in front of
/// the target's side: a neighbour in front would only hide the target), not
/// overlapping any apple; `None` when 100 draws found no place.
fn touching_apple(
    rng: &mut ChaCha8Rng,
    scene: &OrchardScene,
    options: &OrchardOptions,
) -> Option<Object> {
    let target = scene.fruit_centre;
    let toward_camera = -target.coords.normalize();
    let apples: Vec<(Point3<f64>, f64)> = scene
        .objects
        .iter()
        .filter(|o| o.kind == Kind::Fruit)
        .filter_map(|o| match o.shape {
            Shape::Ellipsoid { centre, semi_axes_mm, .. } => Some((centre, semi_axes_mm.max())),
            _ => None,
        })
        .collect();
    for _ in 0..100 {
        let radius = rng.random_range(options.radius_mm.0..=options.radius_mm.1);
        let (touched, touched_radius) = apples[rng.random_range(0..apples.len())];
        let direction = random_direction(rng).into_inner();
        if direction.dot(&toward_camera) > 0.3 {
            continue;
        }
        let gap = rng.random_range(0.0..=2.0);
        let centre = touched + direction * (touched_radius + radius + gap);
        let overlaps = apples.iter().any(|(c, r)| (centre - c).norm() < r + radius);
        if overlaps || centre.z <= radius {
            continue;
        }
        return Some(Object {
            shape: Shape::Ellipsoid {
                centre,
                rotation: random_rotation(rng),
                semi_axes_mm: Vector3::repeat(radius),
            },
            kind: Kind::Fruit,
            texture_seed: rng.random(),
        });
    }
    None
}

/// A branch 8-15 mm thick crossing in front of the fruit, 20-100 mm in
/// front of its surface and through its silhouette.
fn front_branch(rng: &mut ChaCha8Rng, fruit_centre: &Point3<f64>, radius: f64) -> Vec<Object> {
    let toward_camera = -fruit_centre.coords.normalize();
    let in_front = radius + rng.random_range(20.0..=100.0);
    let offset = rng.random_range(-0.7..=0.7) * radius;
    let heading: f64 = rng.random_range(0.0..std::f64::consts::PI);
    let direction = Vector3::new(heading.cos(), heading.sin(), rng.random_range(-0.2..=0.2));
    let across = Vector3::new(-heading.sin(), heading.cos(), 0.0);
    let through = fruit_centre + toward_camera * in_front + across * offset;
    let radius_mm = rng.random_range(4.0..=7.5);
    let texture_seed = rng.random();
    branch_pieces(&through, &direction, radius_mm, texture_seed)
}

/// One straight branch through `through` along `direction`, as collinear
/// pieces: the same surface, but small bounding spheres keep the
/// camera-ray grid's cells short.
fn branch_pieces(
    through: &Point3<f64>,
    direction: &Vector3<f64>,
    radius_mm: f64,
    texture_seed: u64,
) -> Vec<Object> {
    let start = through - direction * (BRANCH_PIECES as f64 / 2.0 * BRANCH_PIECE_MM);
    (0..BRANCH_PIECES)
        .map(|piece| {
            let from = start + direction * (piece as f64 * BRANCH_PIECE_MM);
            Object {
                shape: Shape::Branch {
                    start: from,
                    end: from + direction * BRANCH_PIECE_MM,
                    radius_mm,
                },
                kind: Kind::Branch,
                texture_seed,
            }
        })
        .collect()
}

/// A leaf 30-120 mm in front of the fruit's front surface, its centre
/// `lateral_mm` from the fruit's line of sight.
fn random_leaf(
    rng: &mut ChaCha8Rng,
    fruit_centre: &Point3<f64>,
    radius: f64,
    lateral_mm: std::ops::RangeInclusive<f64>,
) -> Object {
    let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let lateral = rng.random_range(lateral_mm);
    let in_front = rng.random_range(radius + 30.0..=radius + 120.0);
    let toward_camera = -fruit_centre.coords.normalize();
    let centre = fruit_centre
        + toward_camera * in_front
        + Vector3::new(angle.cos() * lateral, angle.sin() * lateral, 0.0);
    // Mostly facing the camera, tilted up to 60 deg.
    let tilt = random_rotation_limited(rng, 60f64.to_radians());
    let normal = Unit::new_normalize(tilt * toward_camera);
    let reference = if normal.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let along = Unit::new_normalize(normal.cross(&reference));
    let spin = Rotation3::from_axis_angle(&normal, rng.random_range(0.0..std::f64::consts::PI));
    Object {
        shape: Shape::Leaf {
            centre,
            normal,
            along: Unit::new_normalize(spin * along.into_inner()),
            half_length_mm: rng.random_range(30.0..=45.0),
            half_width_mm: rng.random_range(14.0..=22.0),
        },
        kind: Kind::Leaf,
        texture_seed: rng.random(),
    }
}

/// A uniformly random rotation.
fn random_rotation(rng: &mut ChaCha8Rng) -> Rotation3<f64> {
    random_rotation_limited(rng, std::f64::consts::PI)
}

/// A rotation by up to `max_angle_rad` about a random axis.
fn random_rotation_limited(rng: &mut ChaCha8Rng, max_angle_rad: f64) -> Rotation3<f64> {
    let axis = random_direction(rng);
    Rotation3::from_axis_angle(&axis, rng.random_range(0.0..=max_angle_rad))
}

/// A uniformly random unit vector (rejection sampling in the unit ball).
fn random_direction(rng: &mut ChaCha8Rng) -> Unit<Vector3<f64>> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        );
        let norm = v.norm();
        if norm > 1e-3 && norm <= 1.0 {
            return Unit::new_normalize(v);
        }
    }
}

fn check_options(options: &OrchardOptions) -> Result<()> {
    let invalid = |m: String| Err(Error::InvalidOptions(m));
    check_positive_range("fruit depth range", options.depth_mm)?;
    check_positive_range("fruit radius range", options.radius_mm)?;
    if !(0.0..=0.5).contains(&options.max_ellipticity) {
        return invalid(format!("ellipticity {} must lie in 0..0.5", options.max_ellipticity));
    }
    if options.cluster > MAX_CLUSTER {
        return invalid(format!(
            "a cluster adds at most {MAX_CLUSTER} apples, not {}",
            options.cluster
        ));
    }
    if options.front_branches > 4 {
        return invalid(format!("at most 4 branches in front, not {}", options.front_branches));
    }
    if !(0.0..=1.0).contains(&options.occlusion) {
        return invalid(format!("occlusion {} must lie in 0..1", options.occlusion));
    }
    if !(0.0..45.0).contains(&options.max_off_axis_deg) {
        return invalid(format!(
            "off-axis angle {} deg must lie in 0..45",
            options.max_off_axis_deg
        ));
    }
    if !(options.background_behind_mm > 0.0 && options.background_behind_mm.is_finite()) {
        return invalid("background distance must be positive".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's camera-ray path finds the same hits, to the last bit, as
    /// the generic intersection over every object.
    #[test]
    fn camera_ray_grid_finds_the_first_hit() {
        for seed in 0..4 {
            let options = OrchardOptions { occlusion: 0.4, seed, ..OrchardOptions::default() };
            let scene = orchard_scene(&options).unwrap();
            let grid = CameraRayGrid::new(&scene);
            let centre = scene.fruit_centre;
            let (mut on_objects, mut rays) = (0, 0);
            for i in 0..301 {
                for j in 0..301 {
                    // A window around the fruit plus a sparse sweep of the view.
                    let spread = if (i + j) % 2 == 0 { 0.15 } else { 0.6 };
                    let x_n = centre.x / centre.z + spread * (f64::from(i) / 150.0 - 1.0);
                    let y_n = centre.y / centre.z + spread * (f64::from(j) / 150.0 - 1.0);
                    let ray = Ray::through_normalized(x_n, y_n);
                    let expected = scene.first_hit(&ray, 0.0);
                    let found = grid.nearest(x_n, y_n);
                    assert_eq!(
                        found,
                        expected.map(|hit| (hit.t, hit.normal, hit.object)),
                        "seed {seed}, ray ({x_n}, {y_n})"
                    );
                    rays += 1;
                    on_objects += usize::from(expected.is_some_and(|hit| hit.object != 1));
                }
            }
            // The sweep meets fruit, leaves and branches, not just the wall.
            assert!(on_objects > rays / 20, "seed {seed}: {on_objects} of {rays} rays");
        }
    }
}
