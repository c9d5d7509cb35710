//! Fruit as circles: the fruit-coloured pixels' distance map, its peaks,
//! the circles they make, and the roundness test (crate docs, steps 2-3).

use image::{GrayImage, Luma, RgbImage};
use imageproc::distance_transform::{Norm, euclidean_squared_distance_transform};
use imageproc::morphology::close_mut;
use nalgebra::Point2;

use crate::colour::{self, fruit_at, fruit_mask};
use crate::depth::RoughPosition;
use crate::{Error, Result};

/// Settings of [`detect`].
#[derive(Debug, Clone, PartialEq)]
pub struct DetectOptions {
    /// Smallest fruit radius in the image, px: smaller round patches are
    /// too few pixels to tell from noise and skin-coloured specks.
    pub min_radius_px: f64,
    /// Largest fruit radius in the image, px; `None`: a quarter of the
    /// image's shorter side (an apple filling half the frame is no orchard
    /// view).
    pub max_radius_px: Option<f64>,
    /// Least roundness ([`Detection::score`]): the fraction of the ring just
    /// outside the circle that is not fruit-coloured. 1 for a fruit on its
    /// own; a touching neighbour takes a quarter or so. (A branch or trunk,
    /// which continues through the ring, is refused by its distance map's
    /// ridge before this.)
    pub min_roundness: f64,
    /// Most detections returned, strongest first.
    pub max_detections: usize,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            min_radius_px: 6.0,
            max_radius_px: None,
            min_roundness: 0.6,
            max_detections: 200,
        }
    }
}

impl DetectOptions {
    fn validate(&self) -> Result<()> {
        let ok = self.min_radius_px.is_finite()
            && self.min_radius_px >= 1.0
            && self.max_radius_px.is_none_or(|m| m.is_finite() && m >= self.min_radius_px)
            && (0.0..=1.0).contains(&self.min_roundness);
        if ok {
            Ok(())
        } else {
            Err(Error::InvalidInput(format!(
                "detector options out of range: min radius {} px (at least 1), max radius {:?} px (at least the min), roundness {} (0-1)",
                self.min_radius_px, self.max_radius_px, self.min_roundness
            )))
        }
    }
}

/// One fruit in the colour image.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    /// The fruit's centre, px (pixel (0, 0) is the top-left pixel's centre).
    pub centre_px: Point2<f64>,
    /// Its radius, px.
    pub radius_px: f64,
    /// Its roundness, 0-1, higher is surer (see
    /// [`DetectOptions::min_roundness`]).
    pub score: f64,
    /// The rough 3-D position, where a depth image gave one
    /// ([`crate::locate_detections`]).
    pub rough: Option<RoughPosition>,
}

impl Detection {
    /// The circle's box `[u_min, v_min, u_max, v_max]`, px.
    pub fn bbox_px(&self) -> [f64; 4] {
        let (c, r) = (self.centre_px, self.radius_px);
        [c.x - r, c.y - r, c.x + r, c.y + r]
    }
}

/// Ring of the roundness test: this factor of the radius, plus
/// [`RING_GAP_PX`], so the fruit's own anti-aliased edge is not in it.
const RING_FACTOR: f64 = 1.15;

/// ... plus this, px.
const RING_GAP_PX: f64 = 1.5;

/// The boundary pixels a circle is refitted to lie within these factors of
/// the inscribed radius: the fruit's own edge, not a neighbour's.
const EDGE_BAND: (f64, f64) = (0.85, 1.6);

/// The fruit in `image`, strongest first (see the crate docs).
pub fn detect(image: &RgbImage, options: &DetectOptions) -> Result<Vec<Detection>> {
    options.validate()?;
    let mut mask = fruit_mask(image);
    // Skin whose colour the test refuses (a red apple's yellow-green ground
    // colour, a highlight, a stem cavity's shadow) leaves gaps and holes in
    // its fruit's mask: ground colour that touches the fruit joins it,
    // narrow gaps close, and small holes fill. (Large holes stay: two
    // branches and a fruit can enclose a patch of leaves.)
    grow_into_ground_colour(&mut mask, image);
    close_mut(&mut mask, Norm::L2, CLOSING_PX);
    let largest_hole = std::f64::consts::PI * (HOLE_RADII * options.min_radius_px).powi(2);
    fill_holes(&mut mask, largest_hole as usize);
    Ok(detect_in_mask(&mask, options))
}

/// Holes up to the area of a circle of this many least fruit radii are
/// filled: a highlight or a calyx on a fruit, not a patch of leaves.
const HOLE_RADII: f64 = 2.0;

/// Adds to the mask the ground-coloured pixels ([`colour::is_ground_coloured`])
/// connected to it: a bicolour or red apple's yellow-green skin beside its
/// blush.
fn grow_into_ground_colour(mask: &mut GrayImage, image: &RgbImage) {
    let (width, height) = mask.dimensions();
    let mut stack: Vec<(u32, u32)> =
        mask.enumerate_pixels().filter(|(_, _, p)| p[0] != 0).map(|(u, v, _)| (u, v)).collect();
    while let Some((x, y)) = stack.pop() {
        let neighbours = [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)];
        for (nx, ny) in neighbours {
            if nx < width
                && ny < height
                && mask.get_pixel(nx, ny)[0] == 0
                && colour::is_ground_coloured(image.get_pixel(nx, ny).0)
            {
                mask.put_pixel(nx, ny, Luma([255]));
                stack.push((nx, ny));
            }
        }
    }
}

/// Gaps in a fruit's mask narrower than twice this (px) are closed.
const CLOSING_PX: u8 = 2;

/// Sets every non-fruit region that does not reach the image's border and
/// holds at most `max_pixels` pixels to fruit.
fn fill_holes(mask: &mut GrayImage, max_pixels: usize) {
    let (width, height) = mask.dimensions();
    let index = |u: u32, v: u32| (v * width + u) as usize;
    let mut seen = vec![false; (width * height) as usize];
    let mut stack = Vec::new();
    for v in 0..height {
        for u in 0..width {
            if seen[index(u, v)] || mask.get_pixel(u, v)[0] != 0 {
                continue;
            }
            // One non-fruit region, by flood fill.
            let mut region = Vec::new();
            let mut border = false;
            seen[index(u, v)] = true;
            stack.push((u, v));
            while let Some((x, y)) = stack.pop() {
                region.push((x, y));
                border |= x == 0 || y == 0 || x + 1 == width || y + 1 == height;
                let neighbours =
                    [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)];
                for (nx, ny) in neighbours {
                    if nx < width
                        && ny < height
                        && !seen[index(nx, ny)]
                        && mask.get_pixel(nx, ny)[0] == 0
                    {
                        seen[index(nx, ny)] = true;
                        stack.push((nx, ny));
                    }
                }
            }
            if !border && region.len() <= max_pixels {
                for (x, y) in region {
                    mask.put_pixel(x, y, Luma([255]));
                }
            }
        }
    }
}

/// [`detect`] on a fruit mask (255 fruit-coloured, 0 not).
pub(crate) fn detect_in_mask(mask: &GrayImage, options: &DetectOptions) -> Vec<Detection> {
    let (width, height) = mask.dimensions();
    if width < 3 || height < 3 {
        return Vec::new();
    }
    let max_radius = options
        .max_radius_px
        .unwrap_or(f64::from(width.min(height)) / 4.0)
        .max(options.min_radius_px);
    // Distance of each fruit pixel to the nearest other pixel: the
    // transform measures to the nearest non-zero pixel, so it runs on the
    // mask's complement.
    let complement = GrayImage::from_fn(width, height, |u, v| {
        Luma([if mask.get_pixel(u, v)[0] == 0 { 255 } else { 0 }])
    });
    let distance2 = euclidean_squared_distance_transform(&complement);
    let d2 = |u: u32, v: u32| distance2.get_pixel(u, v)[0];
    let least = options.min_radius_px * options.min_radius_px;
    // Peaks: at least the least radius, and no smaller than any neighbour.
    let mut peaks: Vec<(f64, u32, u32)> = Vec::new();
    for v in 1..height - 1 {
        for u in 1..width - 1 {
            let here = d2(u, v);
            if here < least {
                continue;
            }
            let peak = (v - 1..=v + 1)
                .all(|y| (u - 1..=u + 1).all(|x| (x == u && y == v) || d2(x, y) <= here));
            if peak {
                peaks.push((here, u, v));
            }
        }
    }
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    // Circles taken (kept or refused): a peak inside one is the same blob.
    let mut taken: Vec<(Point2<f64>, f64)> = Vec::new();
    let mut detections = Vec::new();
    for (here, u, v) in peaks {
        let centre = Point2::new(f64::from(u), f64::from(v));
        if taken.iter().any(|(c, r)| (centre - c).norm() < *r) {
            continue;
        }
        let inscribed = here.sqrt();
        taken.push((centre, inscribed));
        if inscribed > max_radius {
            continue;
        }
        if is_ridge(&d2, (width, height), centre, inscribed) {
            continue;
        }
        let (centre, radius) = refit_to_edge(mask, centre, inscribed);
        let score = roundness(mask, centre, radius);
        if score >= options.min_roundness {
            detections.push(Detection { centre_px: centre, radius_px: radius, score, rough: None });
        }
    }
    detections
        .sort_by(|a, b| b.score.total_cmp(&a.score).then(b.radius_px.total_cmp(&a.radius_px)));
    detections.truncate(options.max_detections);
    detections
}

/// A peak of the distance map whose value stays above this fraction of the
/// inscribed radius one radius away, on two opposite sides, is on a ridge:
/// a bar (a branch, a trunk, a post) keeps its width both ways along
/// itself, so its distances there stay within the noise of its edges (10 %
/// or so) of the peak's; a round fruit's fall to its edge, an elongated
/// one's (semi-axes 1.15 : 1) to a sixth; a neighbour that overlaps a fruit
/// keeps them up on its own side only.
const RIDGE_FRACTION: f64 = 0.85;

/// Two directions are opposite within this angle of each other's reverse.
const OPPOSITE_WITHIN_RAD: f64 = std::f64::consts::FRAC_PI_4;

/// Whether the peak at `centre` with distance `inscribed` lies on a ridge
/// ([`RIDGE_FRACTION`]).
fn is_ridge(
    d2: &impl Fn(u32, u32) -> f64,
    (width, height): (u32, u32),
    centre: Point2<f64>,
    inscribed: f64,
) -> bool {
    let samples = ((2.0 * std::f64::consts::PI * inscribed).ceil() as usize).max(16);
    let limit = (RIDGE_FRACTION * inscribed).powi(2);
    let angles: Vec<f64> = (0..samples)
        .map(|k| 2.0 * std::f64::consts::PI * k as f64 / samples as f64)
        .filter(|t| {
            let (u, v) = (centre.x + inscribed * t.cos(), centre.y + inscribed * t.sin());
            u >= 0.0
                && v >= 0.0
                && u <= f64::from(width - 1)
                && v <= f64::from(height - 1)
                && d2(u.round() as u32, v.round() as u32) >= limit
        })
        .collect();
    angles.iter().any(|a| {
        angles.iter().any(|b| {
            let apart = (a - b).rem_euclid(2.0 * std::f64::consts::PI);
            (apart - std::f64::consts::PI).abs() <= OPPOSITE_WITHIN_RAD
        })
    })
}

/// The fraction of the ring just outside the circle that is not fruit
/// (samples outside the image do not count; none inside: 0).
fn roundness(mask: &GrayImage, centre: Point2<f64>, radius: f64) -> f64 {
    let ring = RING_FACTOR * radius + RING_GAP_PX;
    let samples = ((2.0 * std::f64::consts::PI * ring).ceil() as usize).max(32);
    let (mut inside, mut outside) = (0usize, 0usize);
    for k in 0..samples {
        let t = 2.0 * std::f64::consts::PI * k as f64 / samples as f64;
        let (u, v) = (centre.x + ring * t.cos(), centre.y + ring * t.sin());
        if u < 0.0 || v < 0.0 || u > f64::from(mask.width() - 1) || v > f64::from(mask.height() - 1)
        {
            continue;
        }
        inside += 1;
        if !fruit_at(mask, u.round() as i64, v.round() as i64) {
            outside += 1;
        }
    }
    if inside == 0 { 0.0 } else { outside as f64 / inside as f64 }
}

/// The circle through the fruit's own edge: the mask's boundary pixels
/// within [`EDGE_BAND`] of the inscribed circle, the circle through most of
/// them (RANSAC over triples, then least squares on its inliers). A fruit
/// partly hidden shows its outline where it is seen, and a leaf's straight
/// edge where it is not; the inscribed circle alone sits in the visible
/// part and is too small. The fit is kept where it contains the inscribed
/// circle, stays within the band and runs along at least
/// [`MIN_EDGE_SUPPORT`] of its circumference; else the inscribed circle.
fn refit_to_edge(mask: &GrayImage, centre: Point2<f64>, inscribed: f64) -> (Point2<f64>, f64) {
    let fallback = (centre, inscribed);
    let reach = (EDGE_BAND.1 * inscribed).ceil() as i64 + 1;
    let (cu, cv) = (centre.x as i64, centre.y as i64);
    let mut points: Vec<Point2<f64>> = Vec::new();
    for v in cv - reach..=cv + reach {
        for u in cu - reach..=cu + reach {
            if !fruit_at(mask, u, v) {
                continue;
            }
            let boundary = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .any(|(du, dv)| !fruit_at(mask, u + du, v + dv));
            let p = Point2::new(u as f64, v as f64);
            let d = (p - centre).norm();
            if boundary && d >= EDGE_BAND.0 * inscribed && d <= EDGE_BAND.1 * inscribed {
                points.push(p);
            }
        }
    }
    if points.len() < 8 {
        return fallback;
    }
    let acceptable = |(c, r): (Point2<f64>, f64)| {
        r.is_finite() && (c - centre).norm() + inscribed <= r + 1.0 && r <= EDGE_BAND.1 * inscribed
    };
    let inliers = |(c, r): (Point2<f64>, f64)| -> Vec<Point2<f64>> {
        points.iter().copied().filter(|p| ((p - c).norm() - r).abs() <= EDGE_INLIER_PX).collect()
    };
    // Triples from a fixed xorshift stream: the same image, the same fit.
    let mut state = 0x9E37_79B9_7F4A_7C15_u64 ^ points.len() as u64;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    let mut best: Option<(usize, (Point2<f64>, f64))> = None;
    for _ in 0..EDGE_RANSAC_TRIALS {
        let (a, b, c) =
            (points[next(points.len())], points[next(points.len())], points[next(points.len())]);
        let Some(circle) = circle_through(a, b, c) else { continue };
        if !acceptable(circle) {
            continue;
        }
        let count = inliers(circle).len();
        if best.is_none_or(|(n, _)| count > n) {
            best = Some((count, circle));
        }
    }
    let Some((_, circle)) = best else { return fallback };
    let Some(refined) = kasa(&inliers(circle)) else { return fallback };
    let support = inliers(refined).len() as f64 / (2.0 * std::f64::consts::PI * refined.1);
    if acceptable(refined) && support >= MIN_EDGE_SUPPORT { refined } else { fallback }
}

/// A boundary pixel lies on a circle within this, px.
const EDGE_INLIER_PX: f64 = 1.5;

/// Triples the edge fit draws: with half the boundary on the circle, the
/// chance that none of 100 triples is all on it is 0.875^100, under 1e-5.
const EDGE_RANSAC_TRIALS: usize = 100;

/// Least fraction of the refitted circle's circumference its edge pixels
/// cover (a pixel per pixel of arc): a quarter of the outline seen.
const MIN_EDGE_SUPPORT: f64 = 0.25;

/// The circle through three points, if they are not on a line.
fn circle_through(a: Point2<f64>, b: Point2<f64>, c: Point2<f64>) -> Option<(Point2<f64>, f64)> {
    let d = 2.0 * (a.x * (b.y - c.y) + b.x * (c.y - a.y) + c.x * (a.y - b.y));
    if d.abs() < 1e-9 {
        return None;
    }
    let (a2, b2, c2) = (a.coords.norm_squared(), b.coords.norm_squared(), c.coords.norm_squared());
    let ux = (a2 * (b.y - c.y) + b2 * (c.y - a.y) + c2 * (a.y - b.y)) / d;
    let uy = (a2 * (c.x - b.x) + b2 * (a.x - c.x) + c2 * (b.x - a.x)) / d;
    let centre = Point2::new(ux, uy);
    Some((centre, (a - centre).norm()))
}

/// The least-squares circle (Kasa: u^2 + v^2 = 2 a u + 2 b v + c) through
/// `points`, if they fix one.
fn kasa(points: &[Point2<f64>]) -> Option<(Point2<f64>, f64)> {
    if points.len() < 3 {
        return None;
    }
    let origin = points[0];
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for p in points {
        let (x, y) = (p.x - origin.x, p.y - origin.y);
        let row = nalgebra::Vector3::new(2.0 * x, 2.0 * y, 1.0);
        ata += row * row.transpose();
        atb += row * (x * x + y * y);
    }
    let solution = ata.try_inverse()? * atb;
    let (a, b) = (solution[0], solution[1]);
    let r2 = solution[2] + a * a + b * b;
    (r2.is_finite() && r2 > 0.0).then(|| (Point2::new(origin.x + a, origin.y + b), r2.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(mask: &mut GrayImage, (cu, cv): (f64, f64), r: f64) {
        for (u, v, p) in mask.enumerate_pixels_mut() {
            if (f64::from(u) - cu).hypot(f64::from(v) - cv) <= r {
                *p = Luma([255]);
            }
        }
    }

    #[test]
    fn touching_discs_are_two_fruit_a_bar_is_none() {
        let mut mask = GrayImage::new(300, 200);
        disc(&mut mask, (80.0, 100.0), 30.0);
        disc(&mut mask, (135.0, 100.0), 28.0);
        // A trunk: a long bar 40 px wide.
        for (u, _, p) in mask.enumerate_pixels_mut() {
            if (220..260).contains(&u) {
                *p = Luma([255]);
            }
        }
        let found = detect_in_mask(&mask, &DetectOptions::default());
        assert_eq!(found.len(), 2, "{found:?}");
        for (c, r) in [((80.0, 100.0), 30.0), ((135.0, 100.0), 28.0)] {
            let d = found
                .iter()
                .find(|d| (d.centre_px - Point2::new(c.0, c.1)).norm() < 4.0)
                .unwrap_or_else(|| panic!("no detection near {c:?}: {found:?}"));
            assert!((d.radius_px - r).abs() < 4.0, "{d:?}");
        }
    }

    #[test]
    fn a_fruit_half_hidden_keeps_its_outline() {
        let mut mask = GrayImage::new(200, 200);
        disc(&mut mask, (100.0, 100.0), 40.0);
        // A leaf over its right part.
        for (u, _, p) in mask.enumerate_pixels_mut() {
            if u > 115 {
                *p = Luma([0]);
            }
        }
        let found = detect_in_mask(&mask, &DetectOptions::default());
        assert_eq!(found.len(), 1, "{found:?}");
        let d = &found[0];
        assert!((d.centre_px - Point2::new(100.0, 100.0)).norm() < 5.0, "{d:?}");
        assert!((d.radius_px - 40.0).abs() < 5.0, "{d:?}");
    }
}
