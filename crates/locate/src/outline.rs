//! The fruit's outline in the image, and a sphere fitted to it and to the
//! laser points together: a hypothesis for the estimator
//! (the `estimate` module), which matters most where the laser shows too
//! little of a fruit (mostly hidden, or in the laser's shadow) for a fit
//! from the laser alone; and the silhouette that refines the accepted
//! sphere to the fruit's ellipsoid ([`crate::fit::fit_ellipsoid_with_rays`]
//! takes its rays: it fixes the fruit's size across the line of sight).
//!
//! 1. **Fruit colour.** The frames of a scan share one view, and the laser
//!    only adds light, so the per-pixel minimum over the frames is the view
//!    without the stripe. A pixel is fruit-coloured when red is not far
//!    below green (an apple's red blush or its yellow-green ground; foliage
//!    has green well above red) and blue is low (bark, sky and specular
//!    highlights are not). Once a sphere is accepted, the fruit's own
//!    colours are learned from the pixels its laser points lie on, against
//!    its surround's ([`LearnedColours`]), and added to the test's: a green
//!    apple, which the fixed test takes for a leaf, is then told from the
//!    leaves around it.
//! 2. **Outline.** The edges between fruit-coloured pixels and the rest
//!    whose two sides differ in colour beyond the sensor's noise (a dark
//!    background's noisy chromaticity speckles the mask with edges of no
//!    silhouette), each with its outward direction, and a RANSAC circle through them
//!    whose edges face outwards: the fruit's silhouette. Leaf edges that
//!    cut across the fruit do not lie on one circle with it.
//! 3. **Sphere.** Every camera ray through the outline touches the sphere:
//!    its distance from the centre is the radius. With the outline's
//!    angular radius theta, the spheres that fit it are one family, centre
//!    s d and radius s sin(theta) along the outline's central ray d; every
//!    laser point on a fruit-coloured pixel (a leaf in front of the fruit
//!    is not one, though its points may lie on some sphere of the family)
//!    votes for the s that puts it on the surface, and the
//!    densest vote starts a joint least-squares fit of the centre and
//!    radius to the outline's rays and the laser points that agree.

use alacs_model::Camera;
use alacs_model::ransac::{Estimator, RansacOptions, ransac_refit};
use image::RgbImage;
use nalgebra::{Matrix4, Point2, Point3, Vector2, Vector3, Vector4};

use crate::fit::{Circle, Sphere, circle_through, fit_circle, rms_mm};

/// The fruit's silhouette found in the frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Outline {
    /// Centre of the outline's circle, pixels.
    pub centre_px: Point2<f64>,
    /// Radius of the outline's circle, pixels.
    pub radius_px: f64,
    /// The edge points on the circle, pixels: where the pixels across an
    /// edge of the fruit-coloured ones are half fruit (up to 2.5 px from
    /// the border of the colour mask).
    pub edges_px: Vec<Point2<f64>>,
    /// Fraction of the circle's circumference the edges cover.
    pub support: f64,
    /// Fraction of the pixels inside the circle (and the searched box) that
    /// are fruit-coloured.
    pub fill: f64,
}

/// Darkest channel maximum (8-bit) of a fruit-coloured pixel: deep shade is
/// too noisy to classify.
const MIN_FRUIT_DN: u8 = 20;

/// A fruit-coloured pixel has red at least this fraction of green (an
/// apple's yellow-green ground: about 0.75; foliage: about 0.3).
const MIN_RED_OVER_GREEN: f32 = 0.55;

/// A fruit-coloured pixel has blue at most this fraction of its brightest
/// channel (apples: under 0.25; sunlit bark 0.4-0.5; highlights and sky
/// near 1).
const MAX_BLUE_FRACTION: f32 = 0.35;

/// Edge points per pixel of circumference along a circle's outline (the
/// mean of |cos| + |sin| over a turn: 4 / pi).
const EDGES_PER_PX: f64 = 4.0 / std::f64::consts::PI;

/// An outline must cover at least this fraction of its circle.
const MIN_SUPPORT: f64 = 0.25;

/// At least this fraction of the pixels inside the outline must be
/// fruit-coloured.
const MIN_FILL: f64 = 0.3;

/// An edge lies on the outline's circle within this, pixels.
const EDGE_THRESHOLD_PX: f64 = 1.5;

/// Whether a pixel is fruit-coloured (module docs, step 1).
fn is_fruit_colour(rgb: [u8; 3]) -> bool {
    let [r, g, b] = rgb.map(f32::from);
    let max = r.max(g).max(b);
    max >= f32::from(MIN_FRUIT_DN) && r >= MIN_RED_OVER_GREEN * g && b <= MAX_BLUE_FRACTION * max
}

/// Which pixels are the fruit's: the fixed colour test (module docs, step
/// 1), or one fruit's colours learned from the view ([`LearnedColours`]).
#[derive(Debug, Clone)]
pub(crate) enum FruitColours {
    /// Any apple's colour: red blush or yellow-green ground, not foliage.
    Apple,
    /// Any apple's colour, or the colours of the fruit the laser lies on
    /// against its surround's: the learned colours add a green apple's
    /// skin, and leave every pixel the fixed test knows for an apple's.
    Learned(LearnedColours),
}

impl FruitColours {
    /// Whether `rgb` (a pixel of the view without the stripe) is the fruit's.
    fn contains(&self, rgb: [u8; 3]) -> bool {
        match self {
            FruitColours::Apple => is_fruit_colour(rgb),
            FruitColours::Learned(learned) => is_fruit_colour(rgb) || learned.contains(rgb),
        }
    }
}

/// Bins per axis of a [`LearnedColours`] histogram over chromaticity
/// (r, g) / (r + g + b). A bin of 1/32 holds a pixel's chromaticity noise
/// (about 0.01 at 60 DN with a few DN of sensor noise) three times over,
/// and is a third of what sets a green apple's skin apart from a leaf
/// (chromaticity about (0.3, 0.57) against (0.2, 0.65), alacs-sim's
/// albedos after Saeys et al. 2008); the histograms are smoothed over one
/// bin.
const CHROMA_BINS: usize = 32;

/// Fewest laser points on the fruit (each read with its 8 neighbours), and
/// fewest surround pixels, a [`LearnedColours`] is learned from: a
/// histogram of fewer says little beyond the noise.
const MIN_COLOUR_SAMPLES: usize = 30;

/// One fruit's colours against its surround's, learned from the view: a
/// pixel is the fruit's where its chromaticity is more common on the fruit
/// (the pixels the laser points on the fruit lie on) than around it
/// (histogram back-projection, Swain and Ballard 1991, as a likelihood
/// ratio of the two classes at equal odds). Chromaticity is the same in
/// shade and in light, so the fruit's own shading does not split it; a
/// fruit the fixed test takes for a leaf (a green apple: red well below
/// green) is told from the leaves around it by the colours this scene
/// shows of each.
#[derive(Debug, Clone)]
pub(crate) struct LearnedColours {
    /// The fruit's chromaticity density, smoothed, row-major (r, g).
    fruit: Vec<f32>,
    /// The surround's chromaticity density, smoothed, row-major (r, g).
    surround: Vec<f32>,
}

impl LearnedColours {
    /// The model from the view's colours at `fruit_px` (with their
    /// 8-neighbours) and at `surround_px`; `None` where fewer than
    /// [`MIN_COLOUR_SAMPLES`] of either are bright enough to read.
    pub(crate) fn learn(
        images: &[&RgbImage],
        fruit_px: &[Point2<f64>],
        surround_px: impl Iterator<Item = (u32, u32)>,
    ) -> Option<LearnedColours> {
        let around = |px: &Point2<f64>| {
            let (u, v) = (px.x.round(), px.y.round());
            (-1..=1)
                .flat_map(move |du| (-1..=1).map(move |dv| (u + f64::from(du), v + f64::from(dv))))
        };
        let (fruit, n_fruit) = chroma_histogram(images, fruit_px.iter().flat_map(around));
        let (surround, n_surround) =
            chroma_histogram(images, surround_px.map(|(u, v)| (f64::from(u), f64::from(v))));
        // Nine samples a laser point (its pixel and 8 neighbours).
        if n_fruit < 9 * MIN_COLOUR_SAMPLES || n_surround < MIN_COLOUR_SAMPLES {
            return None;
        }
        Some(LearnedColours {
            fruit: smoothed_density(&fruit, n_fruit),
            surround: smoothed_density(&surround, n_surround),
        })
    }

    /// Whether `rgb` is more likely the fruit's than its surround's.
    fn contains(&self, rgb: [u8; 3]) -> bool {
        chroma_bin(rgb).is_some_and(|bin| self.fruit[bin] > self.surround[bin])
    }
}

/// The histogram over chromaticity bins of the view's pixels at `pixels`
/// (their colours in the per-pixel minimum of `images`), and how many were
/// bright enough to count.
fn chroma_histogram(
    images: &[&RgbImage],
    pixels: impl Iterator<Item = (f64, f64)>,
) -> (Vec<f32>, usize) {
    let mut counts = vec![0.0f32; CHROMA_BINS * CHROMA_BINS];
    let mut n = 0;
    for (u, v) in pixels {
        if let Some(bin) = least_at_px(images, u, v).and_then(chroma_bin) {
            counts[bin] += 1.0;
            n += 1;
        }
    }
    (counts, n)
}

/// The chromaticity bin of a pixel, `None` where it is too dark to read
/// ([`MIN_FRUIT_DN`]).
fn chroma_bin(rgb: [u8; 3]) -> Option<usize> {
    let [r, g, b] = rgb.map(f32::from);
    if r.max(g).max(b) < f32::from(MIN_FRUIT_DN) {
        return None;
    }
    let sum = r + g + b;
    let bin = |x: f32| ((x / sum * CHROMA_BINS as f32) as usize).min(CHROMA_BINS - 1);
    Some(bin(r) * CHROMA_BINS + bin(g))
}

/// A histogram over chromaticity bins as a density, smoothed by [1 2 1] / 4
/// along each axis.
fn smoothed_density(counts: &[f32], n: usize) -> Vec<f32> {
    let at = |i: usize, j: usize| counts[i * CHROMA_BINS + j];
    let mut out = vec![0.0f32; counts.len()];
    for i in 0..CHROMA_BINS {
        for j in 0..CHROMA_BINS {
            let mut sum = 0.0;
            for (di, a) in [(-1i32, 1.0f32), (0, 2.0), (1, 1.0)] {
                for (dj, b) in [(-1i32, 1.0f32), (0, 2.0), (1, 1.0)] {
                    let (ii, jj) = (i as i32 + di, j as i32 + dj);
                    if (0..CHROMA_BINS as i32).contains(&ii)
                        && (0..CHROMA_BINS as i32).contains(&jj)
                    {
                        sum += a * b * at(ii as usize, jj as usize);
                    }
                }
            }
            out[i * CHROMA_BINS + j] = sum / (16.0 * n as f32);
        }
    }
    out
}

/// A pixel box `[u0, v0, u1, v1)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PixelBox {
    pub u0: u32,
    pub v0: u32,
    pub u1: u32,
    pub v1: u32,
}

impl PixelBox {
    /// The pixels within `half_px` of `centre_px` along each axis, clipped
    /// to the camera's image.
    pub(crate) fn around(centre_px: &Point2<f64>, half_px: f64, camera: &Camera) -> PixelBox {
        Self::within(centre_px, half_px, (camera.width_px, camera.height_px))
    }

    /// [`PixelBox::around`] in an image of `(width, height)` pixels.
    fn within(centre_px: &Point2<f64>, half_px: f64, (width, height): (u32, u32)) -> PixelBox {
        let clip = |x: f64, size: u32| x.clamp(0.0, f64::from(size)) as u32;
        PixelBox {
            u0: clip(centre_px.x - half_px, width),
            v0: clip(centre_px.y - half_px, height),
            u1: clip(centre_px.x + half_px + 1.0, width),
            v1: clip(centre_px.y + half_px + 1.0, height),
        }
    }

    /// Every pixel of the box, row by row.
    pub(crate) fn pixels(self) -> impl Iterator<Item = (u32, u32)> {
        (self.v0..self.v1).flat_map(move |v| (self.u0..self.u1).map(move |u| (u, v)))
    }

    /// Too small (or outside the image) to hold an outline.
    fn is_empty(&self) -> bool {
        self.u1 <= self.u0 + 2 || self.v1 <= self.v0 + 2
    }
}

/// An edge between a fruit-coloured pixel and its neighbour: where, and
/// the unit direction from fruit to not fruit.
struct Edge {
    at_px: Point2<f64>,
    outward: Vector2<f64>,
}

/// The fruit mask of the box: the per-pixel minimum over `images`
/// classified by colour, row-major.
fn fruit_mask(images: &[&RgbImage], area: PixelBox, colours: &FruitColours) -> Vec<bool> {
    let (w, h) = (area.u1 - area.u0, area.v1 - area.v0);
    let mut mask = Vec::with_capacity((w * h) as usize);
    for v in area.v0..area.v1 {
        for u in area.u0..area.u1 {
            mask.push(colours.contains(least_at(images, u, v)));
        }
    }
    mask
}

/// The per-pixel minimum of `images` at the pixel (u, v), `None` outside
/// any of them.
pub(crate) fn least_at_px(images: &[&RgbImage], u: f64, v: f64) -> Option<[u8; 3]> {
    let inside = |image: &&RgbImage| {
        (0.0..f64::from(image.width())).contains(&u)
            && (0.0..f64::from(image.height())).contains(&v)
    };
    (!images.is_empty() && images.iter().all(inside)).then(|| least_at(images, u as u32, v as u32))
}

/// The per-pixel minimum of `images` at (u, v), inside every image.
fn least_at(images: &[&RgbImage], u: u32, v: u32) -> [u8; 3] {
    let mut least = [u8::MAX; 3];
    for image in images {
        let p = image.get_pixel(u, v).0;
        for c in 0..3 {
            least[c] = least[c].min(p[c]);
        }
    }
    least
}

/// Whether the pixel nearest `px` is fruit-coloured in the per-pixel
/// minimum of `images` (module docs, step 1); false outside any of them.
pub(crate) fn is_fruit_coloured_at(images: &[&RgbImage], px: &Point2<f64>) -> bool {
    least_at_px(images, px.x.round(), px.y.round()).is_some_and(is_fruit_colour)
}

/// Every edge of the mask (4-neighbours), at the pixels' shared border.
fn mask_edges(mask: &[bool], area: PixelBox) -> Vec<Edge> {
    let (w, h) = ((area.u1 - area.u0) as usize, (area.v1 - area.v0) as usize);
    let mut edges = Vec::new();
    let at = |x: usize, y: usize| mask[y * w + x];
    for y in 0..h {
        for x in 0..w {
            let here = at(x, y);
            let (u, v) = (f64::from(area.u0) + x as f64, f64::from(area.v0) + y as f64);
            if x + 1 < w && here != at(x + 1, y) {
                let sign = if here { 1.0 } else { -1.0 };
                edges.push(Edge {
                    at_px: Point2::new(u + 0.5, v),
                    outward: Vector2::new(sign, 0.0),
                });
            }
            if y + 1 < h && here != at(x, y + 1) {
                let sign = if here { 1.0 } else { -1.0 };
                edges.push(Edge {
                    at_px: Point2::new(u, v + 0.5),
                    outward: Vector2::new(0.0, sign),
                });
            }
        }
    }
    edges
}

/// Pixels on either side of an edge where the fruit's and the neighbour's
/// own colours are read: beyond the blur of a real lens (0.3-1 px, see
/// alacs-sim's `RigVariation`), the pixel the edge cuts and the mask's own
/// offset (up to about a pixel and a half along a row or column where the
/// silhouette crosses it obliquely).
const EDGE_SIDE_PX: i32 = 4;

/// Least colour difference (8-bit, Euclidean over RGB) between the two
/// sides of an edge: below it the sensor's noise (a few DN) would move the
/// crossing by a pixel, and the edge is more likely the colour test's
/// noise than a silhouette (a dark pixel's chromaticity is mostly the
/// sensor's, and speckles a dark background with "fruit"), so it is not
/// one of the outline's.
const MIN_EDGE_CONTRAST: f64 = 12.0;

/// Where along its axis an edge of the mask lies at half coverage: the
/// pixels across it are mixtures of the fruit's colour (read
/// [`EDGE_SIDE_PX`] inside) and its neighbour's (as far outside), and the
/// silhouette lies where the mixture is half and half. The colour test that
/// made the mask calls a pixel fruit from a fifth of fruit in it or less
/// (red over green is a ratio, and a little red lifts it), which puts the
/// mask's border up to a pixel outside the silhouette. `contrast` is the
/// edge's [`contrast_across`]. `None` where the profile does not cross half
/// at least a pixel and a half from where the two sides are read.
fn half_coverage_px(
    images: &[&RgbImage],
    edge: &Edge,
    contrast: &Vector3<f64>,
) -> Option<Point2<f64>> {
    let outside = colour_across(images, edge, EDGE_SIDE_PX + 1)?;
    let coverage = |k: i32| {
        colour_across(images, edge, k)
            .map(|c| (c - outside).dot(contrast) / contrast.norm_squared())
    };
    let mut best: Option<f64> = None;
    for k in -EDGE_SIDE_PX..=EDGE_SIDE_PX {
        let (a, b) = (coverage(k)?, coverage(k + 1)?);
        if a >= 0.5 && b < 0.5 {
            let at = f64::from(k) + (a - 0.5) / (a - b);
            if best.is_none_or(|x| (at - 0.5).abs() < (x - 0.5).abs()) {
                best = Some(at);
            }
        }
    }
    let at = best?;
    ((at - 0.5).abs() <= f64::from(EDGE_SIDE_PX) - 1.5)
        .then(|| edge.at_px + edge.outward * (at - 0.5))
}

/// The view's colour (RGB) `k` pixels outwards from the fruit pixel of
/// `edge` (0: that pixel; 1: its neighbour across the edge), `None`
/// outside the frames.
fn colour_across(images: &[&RgbImage], edge: &Edge, k: i32) -> Option<Vector3<f64>> {
    let p = edge.at_px + edge.outward * (f64::from(k) - 0.5);
    let rgb = least_at_px(images, p.x.round(), p.y.round())?;
    Some(Vector3::new(f64::from(rgb[0]), f64::from(rgb[1]), f64::from(rgb[2])))
}

/// The fruit's colour minus its neighbour's across `edge`, each read
/// [`EDGE_SIDE_PX`] from it.
fn contrast_across(images: &[&RgbImage], edge: &Edge) -> Option<Vector3<f64>> {
    Some(
        colour_across(images, edge, -EDGE_SIDE_PX)?
            - colour_across(images, edge, EDGE_SIDE_PX + 1)?,
    )
}

/// The fruit mask of `area` and its edges, each moved to half coverage
/// ([`half_coverage_px`]) where it can be; an edge whose two sides differ
/// by less than [`MIN_EDGE_CONTRAST`] is left out.
fn edges_at_half_coverage(
    images: &[&RgbImage],
    area: PixelBox,
    colours: &FruitColours,
) -> (Vec<bool>, Vec<Edge>) {
    let mask = fruit_mask(images, area, colours);
    let edges = mask_edges(&mask, area)
        .into_iter()
        .filter_map(|mut edge| match contrast_across(images, &edge) {
            // Its sides beyond the frames: where the mask put it.
            None => Some(edge),
            // Two sides the colours hardly tell apart: the colour test's
            // noise (a dark pixel's chromaticity is mostly the sensor's),
            // not a silhouette.
            Some(contrast) if contrast.norm() < MIN_EDGE_CONTRAST => None,
            Some(contrast) => {
                edge.at_px = half_coverage_px(images, &edge, &contrast).unwrap_or(edge.at_px);
                Some(edge)
            }
        })
        .collect();
    (mask, edges)
}

/// Circles through edge points whose edges face outwards, for RANSAC.
struct OutlineEstimator<'a> {
    edges: &'a [Edge],
    points: Vec<Point2<f64>>,
    radius_range_px: (f64, f64),
}

impl Estimator for OutlineEstimator<'_> {
    type Model = Circle;

    fn len(&self) -> usize {
        self.edges.len()
    }

    fn sample_size(&self) -> usize {
        3
    }

    fn fit_minimal(&self, indices: &[usize]) -> Option<Circle> {
        let [a, b, c] = indices else { return None };
        let circle = circle_through(&self.points[*a], &self.points[*b], &self.points[*c])?;
        let (lo, hi) = self.radius_range_px;
        (lo..=hi).contains(&circle.radius_mm).then_some(circle)
    }

    fn residual(&self, circle: &Circle, index: usize) -> f64 {
        let edge = &self.edges[index];
        let radial = edge.at_px - circle.centre;
        // An edge whose fruit side faces away from the centre is no part of
        // this silhouette.
        if radial.dot(&edge.outward) <= 0.0 {
            return f64::INFINITY;
        }
        circle.distance_mm(&edge.at_px)
    }

    fn refit(&self, indices: &[usize]) -> Option<Circle> {
        fit_circle(&indices.iter().map(|&i| self.points[i]).collect::<Vec<_>>())
    }
}

/// The fruit's outline in `area` of the frames (module docs, steps 1-2):
/// a circle of radius within `radius_range_px` whose centre passes
/// `centre_ok`, or why there is none.
pub(crate) fn find_outline(
    images: &[&RgbImage],
    area: PixelBox,
    colours: &FruitColours,
    radius_range_px: (f64, f64),
    centre_ok: impl Fn(&Point2<f64>) -> bool,
    seed: u64,
) -> std::result::Result<Outline, String> {
    if images.is_empty() || area.is_empty() {
        return Err("the search region is outside the image".into());
    }
    let (mask, edges) = edges_at_half_coverage(images, area, colours);
    let estimator = OutlineEstimator {
        points: edges.iter().map(|e| e.at_px).collect(),
        edges: &edges,
        radius_range_px,
    };
    let options = RansacOptions {
        threshold: EDGE_THRESHOLD_PX,
        confidence: 0.999,
        max_iterations: 2000,
        seed,
    };
    let Some(outcome) = ransac_refit(&estimator, &options, 2) else {
        return Err("no fruit-coloured outline in the search region".into());
    };
    let (circle, inliers) = (outcome.model, outcome.inliers);
    let radius_px = circle.radius_mm;
    if !centre_ok(&circle.centre) {
        return Err(format!(
            "the fruit-coloured outline centred at ({:.0}, {:.0}) px is not the fruit near the rough position",
            circle.centre.x, circle.centre.y
        ));
    }
    if !(radius_range_px.0..=radius_range_px.1).contains(&radius_px) {
        return Err(format!("the outline's radius {radius_px:.0} px is out of range"));
    }
    let support = inliers.len() as f64 / (EDGES_PER_PX * std::f64::consts::TAU * radius_px);
    if support < MIN_SUPPORT {
        return Err(format!(
            "the fruit-coloured outline covers {:.0} % of its circle, less than {:.0} %",
            100.0 * support,
            100.0 * MIN_SUPPORT
        ));
    }
    let w = (area.u1 - area.u0) as usize;
    let (mut inside, mut fruit) = (0usize, 0usize);
    for (i, &is_fruit) in mask.iter().enumerate() {
        let p =
            Point2::new(f64::from(area.u0) + (i % w) as f64, f64::from(area.v0) + (i / w) as f64);
        if (p - circle.centre).norm() < radius_px {
            inside += 1;
            fruit += usize::from(is_fruit);
        }
    }
    let fill = if inside == 0 { 0.0 } else { fruit as f64 / inside as f64 };
    if fill < MIN_FILL {
        return Err(format!(
            "{:.0} % of the outline's inside is fruit-coloured, less than {:.0} %",
            100.0 * fill,
            100.0 * MIN_FILL
        ));
    }
    Ok(Outline {
        centre_px: circle.centre,
        radius_px,
        edges_px: inliers.iter().map(|&i| estimator.points[i]).collect(),
        support: support.min(1.0),
        fill,
    })
}

/// A sphere fitted to an outline's rays and the laser points that agree
/// with it (module docs, step 3).
#[derive(Debug, Clone)]
pub(crate) struct OutlineSphere {
    pub sphere: Sphere,
    /// Indices into the laser points of those on the sphere.
    pub inliers: Vec<usize>,
    /// RMS distance of those points from the sphere, mm.
    pub rms_mm: f64,
    /// RMS of the outline rays' distances from the sphere's surface, mm.
    pub outline_rms_mm: f64,
}

/// The unit ray from the camera's centre through pixel `px`.
fn ray_through(camera: &Camera, px: &Point2<f64>) -> Option<Vector3<f64>> {
    let n = camera.undistort_pixel(px).ok()?;
    Some(Vector3::new(n.x, n.y, 1.0).normalize())
}

/// The silhouette around `outline` where the fruit is not a circle: every
/// edge of the fruit-coloured pixels (at half coverage) within `band_px`
/// of the outline's circle whose fruit side faces its centre. An apple's
/// silhouette departs from a circle by its semi-axes' spread (a few
/// pixels), more than the circle's own inlier band.
pub(crate) fn silhouette_edges(
    images: &[&RgbImage],
    outline: &Outline,
    colours: &FruitColours,
    band_px: f64,
) -> Vec<Point2<f64>> {
    let size = images.first().map_or((0, 0), |i| i.dimensions());
    let reach = outline.radius_px + band_px + f64::from(EDGE_SIDE_PX);
    let c = outline.centre_px;
    let area = PixelBox::within(&c, reach, size);
    if area.is_empty() {
        return Vec::new();
    }
    edges_at_half_coverage(images, area, colours)
        .1
        .into_iter()
        .filter_map(|edge| {
            let radial = edge.at_px - c;
            (radial.dot(&edge.outward) > 0.0 && (radial.norm() - outline.radius_px).abs() < band_px)
                .then_some(edge.at_px)
        })
        .collect()
}

/// The rays through the outline's edge points, which touch the fruit.
pub(crate) fn outline_rays(camera: &Camera, outline: &Outline) -> Vec<Vector3<f64>> {
    rays_through(camera, &outline.edges_px)
}

/// The rays through image points `edges_px`.
pub(crate) fn rays_through(camera: &Camera, edges_px: &[Point2<f64>]) -> Vec<Vector3<f64>> {
    edges_px.iter().filter_map(|px| ray_through(camera, px)).collect()
}

/// Weight of the outline's rays against the laser points: the outline is
/// a pixel's edge (about 0.4 mm at 1 m) and a fruit is not a perfect
/// sphere, so a ray counts as a quarter of a laser point.
pub(crate) const OUTLINE_WEIGHT: f64 = 0.25;

/// Fits a sphere to `outline` and the laser `points` (camera frame, mm):
/// the family along the outline's central ray, the densest vote of the
/// points, then Gauss-Newton on centre and radius with the points within
/// `threshold_mm`.
pub(crate) fn fit_outline_sphere(
    camera: &Camera,
    outline: &Outline,
    points: &[Point3<f64>],
    threshold_mm: f64,
) -> std::result::Result<OutlineSphere, String> {
    let rays = outline_rays(camera, outline);
    let Some(axis) = ray_through(camera, &outline.centre_px) else {
        return Err("the outline's centre does not undistort".into());
    };
    // The outline's angular radius: the mean angle of its rays from the axis.
    let theta = rays.iter().map(|r| r.dot(&axis).clamp(-1.0, 1.0).acos()).sum::<f64>()
        / rays.len().max(1) as f64;
    let (sin_t, cos_t) = theta.sin_cos();
    // Each point's s: |p - s d| = s sin(theta), the root on the near side.
    let mut votes: Vec<f64> = points
        .iter()
        .filter_map(|p| {
            let pd = p.coords.dot(&axis);
            let disc = pd * pd - cos_t * cos_t * p.coords.norm_squared();
            (disc >= 0.0).then(|| (pd + disc.sqrt()) / (cos_t * cos_t))
        })
        .filter(|s| s.is_finite() && *s > 0.0)
        .collect();
    votes.sort_by(f64::total_cmp);
    // The densest window: a change ds of s moves the surface by ds (1 - sin theta).
    let window = 2.0 * threshold_mm / (1.0 - sin_t).max(0.1);
    let mut best: Option<(usize, f64)> = None;
    let mut end = 0;
    for start in 0..votes.len() {
        while end < votes.len() && votes[end] - votes[start] <= window {
            end += 1;
        }
        if best.is_none_or(|(n, _)| end - start > n) {
            best = Some((end - start, 0.5 * (votes[start] + votes[end - 1])));
        }
    }
    let Some((_, s)) = best else {
        return Err("no laser point lies on a sphere within the outline".into());
    };
    let mut centre = Point3::from(axis * s);
    let mut radius = s * sin_t;
    let mut inliers = Vec::new();
    for _ in 0..3 {
        inliers = (0..points.len())
            .filter(|&i| ((points[i] - centre).norm() - radius).abs() <= threshold_mm)
            .collect();
        for _ in 0..10 {
            let mut jtj = Matrix4::<f64>::zeros();
            let mut jtr = Vector4::<f64>::zeros();
            let mut add = |j: Vector4<f64>, r: f64, w: f64| {
                jtj += j * j.transpose() * w;
                jtr += j * r * w;
            };
            for &i in &inliers {
                let d = points[i] - centre;
                let n = d.norm();
                if n > 0.0 {
                    let g = -d / n;
                    add(Vector4::new(g.x, g.y, g.z, -1.0), n - radius, 1.0);
                }
            }
            for r in &rays {
                // Distance of the centre from the ray: |(I - r r^T) c|.
                let off = centre.coords - r * r.dot(&centre.coords);
                let n = off.norm();
                if n > 0.0 {
                    let g = off / n;
                    add(Vector4::new(g.x, g.y, g.z, -1.0), n - radius, OUTLINE_WEIGHT);
                }
            }
            let Some(step) = jtj.lu().solve(&(-jtr)) else { break };
            centre += step.xyz();
            radius += step.w;
            if step.norm() < 1e-6 {
                break;
            }
        }
        if !(centre.coords.iter().all(|c| c.is_finite()) && radius.is_finite() && radius > 0.0) {
            return Err("the outline and the laser points do not fit one sphere".into());
        }
    }
    let sphere = Sphere { centre, radius_mm: radius };
    let rms = rms_mm(inliers.iter().map(|&i| sphere.distance_mm(&points[i])));
    let outline_rms_mm = rms_mm(rays.iter().map(|r| {
        let off = centre.coords - r * r.dot(&centre.coords);
        off.norm() - radius
    }));
    Ok(OutlineSphere { sphere, inliers, rms_mm: rms, outline_rms_mm })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fruit_colours_and_not() {
        assert!(is_fruit_colour([233, 98, 48]), "red blush");
        assert!(is_fruit_colour([148, 195, 44]), "yellow-green ground");
        assert!(!is_fruit_colour([41, 107, 38]), "leaf");
        assert!(!is_fruit_colour([130, 111, 89]), "bark");
        assert!(!is_fruit_colour([91, 68, 43]), "sunlit bark");
        assert!(!is_fruit_colour([250, 250, 245]), "highlight");
        assert!(!is_fruit_colour([10, 6, 2]), "deep shade");
    }

    /// A fruit's disk on leaves as a lens images it: each pixel the mixture
    /// of the two colours by the share of it the disk covers, then a blur.
    /// The colour test calls a pixel fruit from well under half of it, so
    /// the mask's border lies outside the silhouette; the edges at half
    /// coverage put the outline's radius within a tenth of a pixel.
    #[test]
    fn the_outline_lies_at_half_coverage_of_a_blurred_silhouette() {
        let (fruit, leaf) = ([200.0, 60.0, 40.0], [40.0, 95.0, 30.0]);
        let (cu, cv, radius) = (100.4, 95.7, 40.3);
        let (w, h) = (200u32, 200u32);
        let samples = 8;
        let mut coverage = vec![0.0f64; (w * h) as usize];
        for v in 0..h {
            for u in 0..w {
                let mut inside = 0;
                for i in 0..samples {
                    for j in 0..samples {
                        let x = f64::from(u) - 0.5 + (f64::from(i) + 0.5) / f64::from(samples);
                        let y = f64::from(v) - 0.5 + (f64::from(j) + 0.5) / f64::from(samples);
                        inside +=
                            usize::from((x - cu).powi(2) + (y - cv).powi(2) < radius * radius);
                    }
                }
                coverage[(v * w + u) as usize] = inside as f64 / f64::from(samples * samples);
            }
        }
        // A blur of about half a pixel: [1 2 1] / 4 along each axis.
        let at = |c: &[f64], u: i64, v: i64| {
            c[(v.clamp(0, i64::from(h) - 1) * i64::from(w) + u.clamp(0, i64::from(w) - 1)) as usize]
        };
        let mut blurred = coverage.clone();
        for v in 0..i64::from(h) {
            for u in 0..i64::from(w) {
                let mut sum = 0.0;
                for (dv, a) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                    for (du, b) in [(-1, 1.0), (0, 2.0), (1, 1.0)] {
                        sum += a * b * at(&coverage, u + du, v + dv);
                    }
                }
                blurred[(v * i64::from(w) + u) as usize] = sum / 16.0;
            }
        }
        let image = RgbImage::from_fn(w, h, |u, v| {
            let a = blurred[(v * w + u) as usize];
            image::Rgb(std::array::from_fn(|c| (a * fruit[c] + (1.0 - a) * leaf[c]).round() as u8))
        });
        let area = PixelBox { u0: 0, v0: 0, u1: w, v1: h };
        let outline =
            find_outline(&[&image], area, &FruitColours::Apple, (20.0, 80.0), |_| true, 1).unwrap();
        assert!((outline.radius_px - radius).abs() < 0.1, "{} px", outline.radius_px);
        assert!((outline.centre_px - Point2::new(cu, cv)).norm() < 0.1, "{:?}", outline.centre_px);
    }

    #[test]
    fn speckles_of_a_dark_background_make_no_outline() {
        // A dark background whose noise passes the colour test here and
        // there (a dark pixel's chromaticity is mostly noise), densely in a
        // ring just outside a half-hidden fruit: a circle through the
        // speckles' edges would cover more of itself than the fruit's does.
        let (background, speckle) = ([15, 30, 10], [22, 28, 5]);
        assert!(is_fruit_colour(speckle) && !is_fruit_colour(background));
        let (cu, cv, radius) = (100.3, 99.6, 40.0);
        let image = RgbImage::from_fn(200, 200, |u, v| {
            let (x, y) = (f64::from(u) - cu, f64::from(v) - cv);
            let r = x.hypot(y);
            let hash = (u64::from(u) * 7919 + u64::from(v) * 104_729)
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                >> 60;
            if r < radius && x > 0.0 {
                image::Rgb([200, 60, 40])
            } else if (44.0..54.0).contains(&r) && hash < 6 {
                image::Rgb(speckle)
            } else {
                image::Rgb(background)
            }
        });
        let area = PixelBox { u0: 0, v0: 0, u1: 200, v1: 200 };
        let outline =
            find_outline(&[&image], area, &FruitColours::Apple, (20.0, 80.0), |_| true, 1).unwrap();
        assert!((outline.radius_px - radius).abs() < 1.0, "{outline:?}");
        assert!((outline.centre_px - Point2::new(cu, cv)).norm() < 1.0, "{outline:?}");
    }

    #[test]
    fn outline_of_a_disk_half_hidden() {
        let mut image = RgbImage::from_pixel(200, 200, image::Rgb([30, 90, 25]));
        for (u, v, p) in image.enumerate_pixels_mut() {
            let (x, y) = (f64::from(u) - 90.3, f64::from(v) - 110.7);
            // A disk of radius 50 px with its left part behind a leaf.
            if x * x + y * y < 2500.0 && x > -10.0 {
                *p = image::Rgb([200, 60, 40]);
            }
        }
        let area = PixelBox { u0: 0, v0: 0, u1: 200, v1: 200 };
        let outline =
            find_outline(&[&image], area, &FruitColours::Apple, (20.0, 80.0), |_| true, 1).unwrap();
        assert!((outline.centre_px - Point2::new(90.3, 110.7)).norm() < 1.0, "{outline:?}");
        assert!((outline.radius_px - 50.0).abs() < 1.0);
        assert!(outline.support > 0.4 && outline.support < 0.8, "{}", outline.support);
    }

    /// A green apple among leaves: red well below green in both, so the
    /// fixed test sees no fruit; the colours learned from a stripe of
    /// pixels down the fruit's middle, against the box's corners, find its
    /// outline.
    #[test]
    fn a_green_fruits_outline_from_its_learned_colours() {
        let (fruit, leaf, light_leaf) = ([60, 130, 30], [25, 80, 20], [45, 120, 40]);
        let mut image = RgbImage::from_pixel(200, 200, image::Rgb(leaf));
        for (u, v, p) in image.enumerate_pixels_mut() {
            let (x, y) = (f64::from(u) - 100.4, f64::from(v) - 97.6);
            // Lighter leaves on the left, the fruit's shading across it.
            if u < 60 {
                *p = image::Rgb(light_leaf);
            }
            if x * x + y * y < 45.0 * 45.0 {
                let shade = 0.6 + 0.4 * (1.0 - (x * x + y * y) / 2025.0);
                *p = image::Rgb(fruit.map(|c| (f64::from(c) * shade) as u8));
            }
        }
        let area = PixelBox { u0: 30, v0: 27, u1: 171, v1: 168 };
        assert!(
            find_outline(&[&image], area, &FruitColours::Apple, (30.0, 60.0), |_| true, 1).is_err()
        );
        let on_fruit: Vec<Point2<f64>> =
            (60..140).map(|v| Point2::new(104.0, f64::from(v))).collect();
        let surround = area.pixels().filter(|&(u, v)| {
            (Point2::new(f64::from(u), f64::from(v)) - Point2::new(100.4, 97.6)).norm() > 60.0
        });
        let colours = LearnedColours::learn(&[&image], &on_fruit, surround).unwrap();
        let colours = FruitColours::Learned(colours);
        let outline = find_outline(&[&image], area, &colours, (30.0, 60.0), |_| true, 1).unwrap();
        assert!((outline.radius_px - 45.0).abs() < 1.0, "{outline:?}");
        assert!((outline.centre_px - Point2::new(100.4, 97.6)).norm() < 1.0, "{outline:?}");
    }

    #[test]
    fn no_outline_in_foliage() {
        let image = RgbImage::from_pixel(100, 100, image::Rgb([30, 90, 25]));
        let area = PixelBox { u0: 0, v0: 0, u1: 100, v1: 100 };
        assert!(
            find_outline(&[&image], area, &FruitColours::Apple, (10.0, 40.0), |_| true, 1).is_err()
        );
    }
}
