//! Laser-stripe extraction: a red-laser score per pixel, one peak per image
//! row inside a region, and its sub-pixel centre across the stripe.
//!
//! The ALACS laser plane contains (nearly) the camera's y axis, so its line
//! runs down the image: one peak per row finds it, and the centre is found
//! across the line along the row.
//!
//! Score (DN, 0-255 scale):
//! - with a laser-off image of the same pose: `R_on - R_off`, clamped at 0;
//!   the scene cancels, only the laser's added light remains;
//! - without: `R - max(G, B)`, clamped at 0: zero on grey and white surfaces
//!   (a checkerboard), positive where red light dominates;
//! - without, under a line detector ([`StripeOptions::local_background`]):
//!   `R - max(G, B)` signed. The detector measures the laser's red against
//!   the surface beside it, and on a green or yellow-green surface (a green
//!   apple's skin, a leaf) that surface scores below zero: clamped, a line
//!   whose red stays below the skin's green would vanish.

use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::Point2;
use rayon::prelude::*;

use crate::{Error, Result};

/// A laser score per pixel (DN).
pub type ScoreImage = ImageBuffer<Luma<f32>, Vec<f32>>;

/// How the sub-pixel centre across the stripe is found from the scores
/// around a row's peak.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PeakMethod {
    /// Centre of gravity of the background-subtracted scores over the stripe
    /// (its half-maximum extent, widened each side by its width).
    CentreOfGravity,
    /// A Gaussian through the peak and its two neighbours (a parabola
    /// through their logarithms).
    Gaussian,
    /// A parabola through the peak and its two neighbours.
    Parabola,
    /// Steger's line centre (C. Steger, "An unbiased detector of curvilinear
    /// structures", IEEE TPAMI 20(2), 1998): the zero of the first
    /// derivative of the Gaussian-smoothed profile, from its first and
    /// second derivatives at a pixel, `t = -g' / g''`, accepted where
    /// `g'' < 0` and `|t| <= 0.5` px.
    ///
    /// One-dimensional, along the row: the ALACS line runs down the image,
    /// so the row crosses it and a straight line's profile along the row is
    /// its normal profile stretched by 1 / cos(tilt), with the same centre.
    /// The smoothing sigma is `w / sqrt(3)` for the stripe's half-width `w`
    /// (half its width at half maximum), the smallest for which Steger's
    /// bar-shaped line keeps a single maximum, and no less than 0.7 px.
    ///
    /// The default: measured against the simulator's truth, the most
    /// accurate of the four on orchard scans and on calibration boards
    /// (docs/calibration.md, "Sub-pixel stripe centre").
    #[default]
    Steger,
}

/// Smallest smoothing sigma of [`PeakMethod::Steger`], px: below it the
/// sampled derivative kernels no longer smooth the pixel noise.
const STEGER_MIN_SIGMA_PX: f64 = 0.7;

/// [`PeakMethod::Steger`]'s smoothing sigma for a stripe `width_px` wide at
/// half maximum: `w / sqrt(3)` for its half-width `w`, at least
/// [`STEGER_MIN_SIGMA_PX`].
fn steger_sigma(width_px: f64) -> f64 {
    (width_px / (2.0 * 3.0_f64.sqrt())).max(STEGER_MIN_SIGMA_PX)
}

/// Pixels Steger's derivative kernels of `sigma` reach each side of a
/// pixel: 4 sigma, rounded up.
fn steger_reach(sigma: f64) -> usize {
    (4.0 * sigma + 0.5).ceil() as usize
}

/// Settings of [`extract_stripe`].
#[derive(Debug, Clone, PartialEq)]
pub struct StripeOptions {
    /// Smallest peak score that counts as laser (DN).
    pub min_strength: f32,
    /// Widest stripe accepted at half maximum (px): a wider peak is a
    /// saturated blob or a red surface, not a line.
    pub max_width_px: f64,
    /// With one peak per row: a row is ambiguous, and skipped, when a
    /// second peak away from the first reaches this fraction of it. With
    /// several: peaks weaker than this fraction of the row's strongest are
    /// dropped.
    pub ambiguity_ratio: f32,
    /// Peaks kept per row. 1 for a board, where the line is the only red
    /// thing; more for orchard frames, where a leaf edge or the fruit's red
    /// rim can outshine the line on a sunlit fruit and the 3-D shape test
    /// downstream tells them apart.
    pub max_peaks_per_row: usize,
    /// The sub-pixel method.
    pub method: PeakMethod,
    /// Subtract the local background along the row before the peak search
    /// (a line detector); `None` takes the scores as they are.
    pub local_background: Option<LocalBackground>,
    /// Red at or above this value (DN) is clipped. A peak inside a clipped
    /// run wider than the stripe is a saturated patch where the line cannot
    /// be seen, and is skipped; a line whose top alone is clipped keeps its
    /// symmetric profile and is kept ([`extract_stripe_rgb`] only).
    pub saturation_dn: Option<u8>,
    /// Skip colour-score peaks where the green channel dips ([`extract_stripe_rgb`]
    /// without a laser-off image only): surface colour, not laser light.
    pub green_check: bool,
}

/// A line detector along the row: each score minus the larger of the mean
/// scores in two windows, one each side, `gap_px` away. A thin line keeps
/// its height; a smooth surface (a red apple's body under the
/// colour-contrast score) and a step (the apple's edge) go to zero or below.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LocalBackground {
    /// Distance from the pixel to the near end of each window, px.
    pub gap_px: usize,
    /// Length of each window, px.
    pub window_px: usize,
}

/// The line detector of [`StripeOptions::orchard`]: the stripe's Gaussian
/// cross-section (sigma about 1.5 px) lies within the 5 px gap.
const ORCHARD_BACKGROUND: LocalBackground = LocalBackground { gap_px: 5, window_px: 4 };

impl LocalBackground {
    /// Pixels the detector looks at each side of a pixel.
    fn reach(&self) -> usize {
        self.gap_px + self.window_px
    }
}

impl Default for StripeOptions {
    fn default() -> Self {
        StripeOptions {
            min_strength: 12.0,
            max_width_px: 12.0,
            ambiguity_ratio: 0.5,
            method: PeakMethod::Steger,
            max_peaks_per_row: 1,
            local_background: None,
            saturation_dn: None,
            green_check: false,
        }
    }
}

impl StripeOptions {
    /// Whether the colour score is signed: under a line detector with
    /// windows (see the module docs).
    fn signed_score(&self) -> bool {
        self.local_background.is_some_and(|b| b.window_px > 0)
    }

    /// Settings for orchard frames: a red line on a red, sunlit, textured
    /// fruit among leaves. The local background removes the fruit's own
    /// colour contrast (the stripe's Gaussian cross-section, sigma about
    /// 1.5 px, lies within the 5 px gap); clipped peaks are skipped.
    pub fn orchard() -> StripeOptions {
        StripeOptions {
            min_strength: 10.0,
            local_background: Some(ORCHARD_BACKGROUND),
            saturation_dn: Some(250),
            green_check: true,
            max_peaks_per_row: 3,
            ambiguity_ratio: 0.2,
            ..StripeOptions::default()
        }
    }
}

/// One point of the stripe: its centre on an image row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripePoint {
    /// Sub-pixel column of the centre.
    pub u_px: f64,
    /// The row.
    pub v_px: f64,
    /// Peak score (DN).
    pub strength: f32,
    /// Width at half maximum (px).
    pub width_px: f64,
}

/// The pixels a search covers: an inclusive column span per row.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// (row, first column, last column), rows increasing.
    spans: Vec<(u32, u32, u32)>,
}

impl Region {
    /// The whole image.
    pub fn full(width: u32, height: u32) -> Region {
        Region::rect(0, 0, width.saturating_sub(1), height.saturating_sub(1), width, height)
    }

    /// The rectangle u0..=u1, v0..=v1, clipped to the image.
    pub fn rect(u0: u32, v0: u32, u1: u32, v1: u32, width: u32, height: u32) -> Region {
        let (u1, v1) = (u1.min(width.saturating_sub(1)), v1.min(height.saturating_sub(1)));
        let spans = if width == 0 || height == 0 || u0 > u1 || v0 > v1 {
            Vec::new()
        } else {
            (v0..=v1).map(|v| (v, u0, u1)).collect()
        };
        Region { spans }
    }

    /// The spans: (row, first column, last column), rows increasing.
    pub fn spans(&self) -> &[(u32, u32, u32)] {
        &self.spans
    }

    /// The pixels whose centres lie inside a convex polygon (vertices in
    /// order, either direction), shrunk by `margin_px`, clipped to the image.
    pub fn convex_polygon(
        vertices: &[Point2<f64>],
        margin_px: f64,
        width: u32,
        height: u32,
    ) -> Region {
        if vertices.len() < 3 || vertices.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Region { spans: Vec::new() };
        }
        let (v_min, v_max) = vertices
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.y), hi.max(p.y)));
        let first = v_min.ceil().max(0.0) as u32;
        let last = (v_max.floor().min(f64::from(height) - 1.0)).max(-1.0);
        let mut spans = Vec::new();
        if last < 0.0 {
            return Region { spans };
        }
        let n = vertices.len();
        // Orientation: the polygon's signed area.
        let area: f64 = (0..n)
            .map(|i| {
                let (a, b) = (vertices[i], vertices[(i + 1) % n]);
                a.x * b.y - b.x * a.y
            })
            .sum();
        let sign = if area >= 0.0 { 1.0 } else { -1.0 };
        for v in first..=last as u32 {
            let y = f64::from(v);
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            let mut inside = true;
            for i in 0..n {
                let (a, b) = (vertices[i], vertices[(i + 1) % n]);
                // Inside: sign * cross(b - a, p - a) >= margin * |b - a|, linear in x.
                let (ex, ey) = (b.x - a.x, b.y - a.y);
                let length = (ex * ex + ey * ey).sqrt();
                if length == 0.0 {
                    continue;
                }
                // cross = ex * (y - a.y) - ey * (x - a.x) = c0 - ey * x
                let c0 = ex * (y - a.y) + ey * a.x;
                let (slope, offset) = (-ey * sign, c0 * sign - margin_px * length);
                // slope * x + offset >= 0
                if slope.abs() < 1e-12 {
                    if offset < 0.0 {
                        inside = false;
                    }
                } else if slope > 0.0 {
                    lo = lo.max(-offset / slope);
                } else {
                    hi = hi.min(-offset / slope);
                }
            }
            let lo = lo.ceil().max(0.0);
            let hi = hi.floor().min(f64::from(width) - 1.0);
            if inside && lo <= hi {
                spans.push((v, lo as u32, hi as u32));
            }
        }
        Region { spans }
    }

    /// Number of pixels covered.
    pub fn pixel_count(&self) -> usize {
        self.spans.iter().map(|&(_, a, b)| (b - a + 1) as usize).sum()
    }

    /// Whether pixel (u, v) (rounded) lies in the region.
    pub fn contains(&self, u: f64, v: f64) -> bool {
        let (u, v) = (u.round(), v.round());
        self.spans
            .iter()
            .any(|&(row, a, b)| f64::from(row) == v && f64::from(a) <= u && u <= f64::from(b))
    }
}

/// The laser score of a frame (see the module docs) as `options` search
/// it (signed under a line detector), optionally against a laser-off image
/// of the same pose.
pub fn laser_score(
    on: &RgbImage,
    off: Option<&RgbImage>,
    options: &StripeOptions,
) -> Result<ScoreImage> {
    let (width, height) = on.dimensions();
    let data: Vec<f32> = match off {
        Some(off) => {
            check_same_size(on, off)?;
            on.pixels().zip(off.pixels()).map(|(a, b)| difference_score(a[0], b[0])).collect()
        }
        None if options.signed_score() => {
            on.pixels().map(|p| f32::from(signed_colour_score(p[0], p[1], p[2]))).collect()
        }
        None => on.pixels().map(|p| colour_score(p[0], p[1], p[2])).collect(),
    };
    Ok(ScoreImage::from_raw(width, height, data).unwrap_or_else(|| ScoreImage::new(width, height)))
}

/// Whether the red channel is clipped over more than the stripe itself at
/// `point`: a saturated patch (sunlit red fruit) rather than a line whose
/// top is clipped. A clipped line keeps a symmetric profile and its centre;
/// in a clipped patch the line cannot be seen at all.
fn saturated(row_rgb: &[u8], point: &StripePoint, limit: u8) -> bool {
    let width = row_rgb.len() / 3;
    let centre = point.u_px.round() as usize;
    let red = |u: usize| row_rgb[3 * u];
    if centre >= width || red(centre) < limit {
        return false;
    }
    let (mut left, mut right) = (centre, centre);
    while left > 0 && red(left - 1) >= limit {
        left -= 1;
    }
    while right + 1 < width && red(right + 1) >= limit {
        right += 1;
    }
    (right - left + 1) as f64 > point.width_px + 2.0
}

/// Whether the green channel dips at `point` against its surroundings (the
/// same windows as the line detector): the laser adds light (a red laser
/// leaks a little into green), it never takes green away, so a "line"
/// where green drops is the surface's own colour, such as the red rim of a
/// yellow-green fruit, not the laser.
fn green_dips(row_rgb: &[u8], point: &StripePoint, background: Option<LocalBackground>) -> bool {
    let width = row_rgb.len() / 3;
    let background = background.unwrap_or(ORCHARD_BACKGROUND);
    let centre = point.u_px.round() as i64;
    let green =
        |u: i64| (0..width as i64).contains(&u).then(|| f32::from(row_rgb[3 * u as usize + 1]));
    let mean = |from: i64, to: i64| {
        let (sum, count) =
            (from..to).filter_map(green).fold((0.0_f32, 0_u32), |(s, n), g| (s + g, n + 1));
        (count > 0).then(|| sum / count as f32)
    };
    let Some(at) = mean(centre - 1, centre + 2) else { return false };
    let (gap, reach) = (background.gap_px as i64, background.reach() as i64);
    let level =
        match (mean(centre - reach, centre - gap + 1), mean(centre + gap, centre + reach + 1)) {
            (Some(a), Some(b)) => a.max(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return false,
        };
    at - level < -(GREEN_DIP_FRACTION * point.strength).max(GREEN_NOISE_DN)
}

/// A line whose green falls below its surroundings by more than this
/// fraction of its (red) strength is surface colour, not laser ...
const GREEN_DIP_FRACTION: f32 = 0.25;

/// ... and by more than this, in DN: the noise of a 3-pixel mean against
/// 4-pixel windows stays well inside it.
const GREEN_NOISE_DN: f32 = 6.0;

/// `R_on - R_off`, clamped at 0, as an integer.
#[inline]
fn difference_score_u8(red_on: u8, red_off: u8) -> u8 {
    red_on.saturating_sub(red_off)
}

/// `R - max(G, B)`, clamped at 0, as an integer.
#[inline]
fn colour_score_u8(red: u8, green: u8, blue: u8) -> u8 {
    red.saturating_sub(green.max(blue))
}

/// `R - max(G, B)`, signed: the score under a line detector.
#[inline]
fn signed_colour_score(red: u8, green: u8, blue: u8) -> i16 {
    i16::from(red) - i16::from(green.max(blue))
}

/// [`difference_score_u8`] as the score image holds it.
#[inline]
fn difference_score(red_on: u8, red_off: u8) -> f32 {
    f32::from(difference_score_u8(red_on, red_off))
}

/// [`colour_score_u8`] as the score image holds it.
#[inline]
fn colour_score(red: u8, green: u8, blue: u8) -> f32 {
    f32::from(colour_score_u8(red, green, blue))
}

fn check_same_size(on: &RgbImage, off: &RgbImage) -> Result<()> {
    if off.dimensions() == on.dimensions() {
        return Ok(());
    }
    Err(Error::Mismatch {
        message: format!(
            "the laser-off image is {} x {} px, the laser image {} x {} px",
            off.width(),
            off.height(),
            on.width(),
            on.height()
        ),
    })
}

/// The stripe: at most [`StripeOptions::max_peaks_per_row`] points per row
/// of the region, rows increasing (see [`StripeOptions`] for what is skipped).
pub fn extract_stripe(
    score: &ScoreImage,
    region: &Region,
    options: &StripeOptions,
) -> Vec<StripePoint> {
    let width = score.width() as usize;
    let data = score.as_raw();
    let mut buffer = Vec::new();
    let mut points = Vec::new();
    for &(v, u0, u1) in &region.spans {
        let row_start = v as usize * width;
        let Some(row) = data.get(row_start..row_start + width) else {
            continue;
        };
        // The columns the line detector reads, as the colour pass holds them.
        let reach = options.local_background.map_or(0, |b| b.reach());
        let valid = ((u0 as usize).saturating_sub(reach), (u1 as usize + reach).min(width - 1));
        span_peaks(row, valid, (v, u0, u1), options, &mut buffer, &mut points);
    }
    points
}

/// [`laser_score`] and [`extract_stripe`] in one pass over the region: the
/// scores are computed only there (plus the local background's reach), and
/// clipped peaks are skipped per [`StripeOptions::saturation_dn`].
///
/// The same points as [`laser_score`] then [`extract_stripe`], faster: the
/// scores are integers (`u8`, saturating), never a frame-sized buffer, and
/// the rows run in parallel. With one peak per row and no line detector
/// (a board), the peak and the ambiguity test's rival are found on the
/// integer scores, loops the compiler vectorises.
pub fn extract_stripe_rgb(
    on: &RgbImage,
    off: Option<&RgbImage>,
    region: &Region,
    options: &StripeOptions,
) -> Result<Vec<StripePoint>> {
    let (width, height) = on.dimensions();
    if let Some(off) = off {
        check_same_size(on, off)?;
    }
    let reach = options.local_background.map_or(0, |b| b.reach());
    let (on_raw, off_raw) = (on.as_raw().as_slice(), off.map(|o| o.as_raw().as_slice()));
    let width = width as usize;
    let rows: Vec<Vec<StripePoint>> = region
        .spans
        .par_iter()
        .with_min_len(ROWS_PER_TASK)
        .map_init(RowScratch::default, |scratch, &(v, u0, u1)| {
            if v >= height || u1 as usize >= width {
                return Vec::new();
            }
            let row_start = 3 * v as usize * width;
            let row_pixels = &on_raw[row_start..row_start + 3 * width];
            let keep = |p: &StripePoint| {
                let clipped =
                    options.saturation_dn.is_some_and(|limit| saturated(row_pixels, p, limit));
                let colour = off.is_none()
                    && options.green_check
                    && green_dips(row_pixels, p, options.local_background);
                !(clipped || colour)
            };
            if options.local_background.is_none() && options.max_peaks_per_row <= 1 {
                let bytes = 3 * u0 as usize..3 * (u1 as usize + 1);
                let on_span = &row_pixels[bytes.clone()];
                let off_span = off_raw.map(|off| &off[row_start..row_start + 3 * width][bytes]);
                let point =
                    single_peak_u8(on_span, off_span, (v, u0), options, &mut scratch.interleaved);
                return point.filter(keep).into_iter().collect();
            }
            let first = (u0 as usize).saturating_sub(reach);
            let last = (u1 as usize + reach).min(width - 1);
            if off.is_none() && options.signed_score() {
                let mut points =
                    signed_span_peaks(row_pixels, (v, u0, u1), (first, last), options, scratch);
                points.retain(keep);
                return points;
            }
            scratch.scores.resize(width, 0);
            let pixels = &row_pixels[3 * first..3 * (last + 1)];
            let off_pixels =
                off_raw.map(|off| &off[row_start + 3 * first..row_start + 3 * (last + 1)]);
            // The scores on whole vectors of interleaved bytes, then every third byte.
            interleaved_scores(pixels, off_pixels, &mut scratch.interleaved);
            // No value of the line detector exceeds its pixel's score, so a
            // span whose scores all fall short of `min_strength` has no peak.
            let span_bytes = 3 * (u0 as usize - first)..3 * (u1 as usize - first + 1);
            if f32::from(scratch.interleaved.get(span_bytes).map_or(0, max_u8))
                < options.min_strength
            {
                return Vec::new();
            }
            let mut points = Vec::new();
            match options.local_background {
                Some(background) if (1..=MAX_I16_WINDOW_PX).contains(&background.window_px) => {
                    // With several peaks, the line detector only around the
                    // pixels that can be peaks (see `candidate_windows`); one
                    // peak's rival check reads the whole span.
                    let windows = if options.max_peaks_per_row > 1 {
                        candidate_windows(&scratch.interleaved, first, (u0, u1), options)
                    } else {
                        vec![(u0 as usize, u1 as usize)]
                    };
                    let (n, value) =
                        ((u1 - u0) as usize + 1, ScaledValue::new(background.window_px));
                    scratch.profile.clear();
                    scratch.profile.resize(n, 0);
                    for (lo, hi) in windows {
                        // The scores the detector reads: the window and its reach.
                        let (from, to) =
                            (lo.saturating_sub(reach).max(first), (hi + reach).min(last));
                        deinterleave(
                            &mut scratch.scores[from..=to],
                            &scratch.interleaved[3 * (from - first)..],
                        );
                        let (sums, excess) = (&mut scratch.sums, &mut scratch.excess);
                        local_contrast_i16(&scratch.scores, lo, hi, background, sums, excess);
                        let start = lo - u0 as usize;
                        scratch.profile[start..start + excess.len()].copy_from_slice(excess);
                    }
                    let mut profile = Scaled { excess: &mut scratch.profile, value };
                    profile_peaks(&mut profile, (v, u0), options, &mut points);
                    if points.iter().any(|p| reaches_windows(p, background)) {
                        // The centres again on the scores (the detector ran
                        // only where peaks could be: the whole span now).
                        deinterleave(&mut scratch.scores[first..=last], &scratch.interleaved);
                        for point in &mut points {
                            refine_on_linear_background(
                                &scratch.scores,
                                (first, last),
                                background,
                                point,
                            );
                        }
                    }
                }
                _ => {
                    deinterleave(&mut scratch.scores[first..=last], &scratch.interleaved);
                    span_peaks(
                        &scratch.scores,
                        (first, last),
                        (v, u0, u1),
                        options,
                        &mut scratch.buffer,
                        &mut points,
                    );
                }
            }
            points.retain(keep);
            points
        })
        .collect();
    Ok(rows.concat())
}

/// The peaks of one span under the line detector on the signed colour
/// score ([`signed_colour_score`]) of the row's pixels `first..=last` (the
/// span and the detector's reach). A row whose scores nowhere rise
/// `min_strength` above the lower of 0 and their least has no peak: no
/// detector value exceeds its pixel's score less the lower of the window
/// means (or 0 where neither window fits).
fn signed_span_peaks(
    row_pixels: &[u8],
    (v, u0, u1): (u32, u32, u32),
    (first, last): (usize, usize),
    options: &StripeOptions,
    scratch: &mut RowScratch,
) -> Vec<StripePoint> {
    let width = row_pixels.len() / 3;
    scratch.signed.resize(width, 0);
    for (score, pixel) in scratch.signed[first..=last]
        .iter_mut()
        .zip(row_pixels[3 * first..3 * (last + 1)].chunks_exact(3))
    {
        *score = signed_colour_score(pixel[0], pixel[1], pixel[2]);
    }
    let scores = &scratch.signed[first..=last];
    let (least, most) =
        scores.iter().fold((0_i16, i16::MIN), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    let mut points = Vec::new();
    if f32::from(most) - f32::from(least) < options.min_strength {
        return points;
    }
    span_peaks(
        &scratch.signed,
        (first, last),
        (v, u0, u1),
        options,
        &mut scratch.buffer,
        &mut points,
    );
    points
}

/// Rows of a region one parallel task takes at least: a row of a 5 MP
/// frame is a few microseconds of work.
const ROWS_PER_TASK: usize = 16;

/// One thread's buffers for [`extract_stripe_rgb`]: a row's integer scores
/// (image-wide, valid over the span and its reach) and the span's scores as
/// `f32` for the line detector's path, or the interleaved scores of
/// [`single_peak_u8`].
#[derive(Default)]
struct RowScratch {
    scores: Vec<u8>,
    /// A row's signed colour scores ([`signed_span_peaks`]).
    signed: Vec<i16>,
    /// The span's line-detector profile (integer path): the detector's
    /// values in the windows it ran in, 0 elsewhere.
    profile: Vec<i16>,
    buffer: Vec<f32>,
    excess: Vec<i16>,
    sums: Vec<i16>,
    interleaved: Vec<u8>,
}

/// Bytes of one block of [`interleaved_scores`]: 16 pixels, three 16-byte
/// vectors.
const BLOCK_BYTES: usize = 48;

/// Keeps the red byte of each pixel in a block.
const RED_BYTES: [u8; BLOCK_BYTES] = {
    let mut mask = [0_u8; BLOCK_BYTES];
    let mut i = 0;
    while i < BLOCK_BYTES {
        mask[i] = 0xFF;
        i += 3;
    }
    mask
};

/// The scores of a span of RGB pixels (`on`, and `off` of the same span),
/// computed on the interleaved bytes: `out[3 u]` is pixel u's score
/// (`R - max(G, B)` or `R_on - R_off`, saturating), the green and blue
/// bytes' places hold 0. Every byte is computed and the others masked
/// away, so the loop runs on whole vectors with no shuffling (SSE2 has
/// none for bytes).
fn interleaved_scores(on: &[u8], off: Option<&[u8]>, out: &mut Vec<u8>) {
    let len = on.len() - on.len() % 3;
    // Every byte below is written (the tails' too), so the buffer is not
    // cleared between rows: no zero-fill of a row's bytes each time.
    out.resize(len, 0);
    let mut base = 0;
    match off {
        None => {
            // Byte t + 2 of a block is read: the last block stops 2 bytes early.
            while base + BLOCK_BYTES + 2 <= len {
                let (Ok(bytes), Ok(scores)) = (
                    <&[u8; BLOCK_BYTES + 2]>::try_from(&on[base..base + BLOCK_BYTES + 2]),
                    <&mut [u8; BLOCK_BYTES]>::try_from(&mut out[base..base + BLOCK_BYTES]),
                ) else {
                    break;
                };
                for t in 0..BLOCK_BYTES {
                    scores[t] =
                        bytes[t].saturating_sub(bytes[t + 1].max(bytes[t + 2])) & RED_BYTES[t];
                }
                base += BLOCK_BYTES;
            }
            for j in (base..len).step_by(3) {
                out[j..j + 3].copy_from_slice(&[
                    colour_score_u8(on[j], on[j + 1], on[j + 2]),
                    0,
                    0,
                ]);
            }
        }
        Some(off) => {
            while base + BLOCK_BYTES <= len.min(off.len()) {
                let (Ok(bytes), Ok(dark), Ok(scores)) = (
                    <&[u8; BLOCK_BYTES]>::try_from(&on[base..base + BLOCK_BYTES]),
                    <&[u8; BLOCK_BYTES]>::try_from(&off[base..base + BLOCK_BYTES]),
                    <&mut [u8; BLOCK_BYTES]>::try_from(&mut out[base..base + BLOCK_BYTES]),
                ) else {
                    break;
                };
                for t in 0..BLOCK_BYTES {
                    scores[t] = bytes[t].saturating_sub(dark[t]) & RED_BYTES[t];
                }
                base += BLOCK_BYTES;
            }
            for j in (base..len.min(off.len())).step_by(3) {
                out[j..j + 3].copy_from_slice(&[difference_score_u8(on[j], off[j]), 0, 0]);
            }
            // Bytes past a shorter laser-off span score 0.
            out[len.min(off.len())..].fill(0);
        }
    }
}

/// The largest byte (0 for none), in a loop the compiler vectorises
/// (`iter().max()` compares references, one byte at a time).
fn max_u8(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |m, &b| m.max(b))
}

/// `scores[i]` = byte `3 i` of `interleaved` (the scores of
/// [`interleaved_scores`], pixel by pixel).
fn deinterleave(scores: &mut [u8], interleaved: &[u8]) {
    for (score, &s) in scores.iter_mut().zip(interleaved.iter().step_by(3)) {
        *score = s;
    }
}

/// Where the several-peaks search needs the line detector in the span
/// `u0..=u1` of a row whose interleaved scores (pixel `first` at byte 0)
/// are `interleaved`: the blocks of 16 pixels where one scores at least
/// `min_strength`, each grown by [`candidate_margin_px`] (within the span),
/// merged where they touch; sorted. No detector value exceeds its pixel's
/// score, so a peak lies in such a block; its width and centre read no
/// farther than the margin, and the search keeps the strongest and those
/// within `ambiguity_ratio` of it without looking for rivals (which would
/// read the whole row), so the profile outside the windows, below
/// `min_strength` everywhere, may be 0: the peaks are those of the whole
/// span's profile (test
/// `the_several_peaks_search_in_candidate_windows_finds_the_whole_rows_peaks`).
fn candidate_windows(
    interleaved: &[u8],
    first: usize,
    (u0, u1): (u32, u32),
    options: &StripeOptions,
) -> Vec<(usize, usize)> {
    let (u0, u1) = (u0 as usize, u1 as usize);
    let margin = candidate_margin_px(options);
    // The least integer score at least `min_strength` (scores are bytes).
    let threshold = options.min_strength.max(0.0).ceil();
    let mut windows: Vec<(usize, usize)> = Vec::new();
    if threshold > 255.0 {
        return windows;
    }
    let threshold = threshold as u8;
    let span = &interleaved[3 * (u0 - first)..3 * (u1 - first + 1)];
    // Per block of 16 pixels: a block holding a score of at least the
    // threshold is grown by the margin (a superset of its pixels' windows
    // does as well: the profile is exact in the windows).
    // Groups of eight blocks short of the threshold are skipped first.
    const GROUP_BYTES: usize = 8 * BLOCK_BYTES;
    for (g, group) in span.chunks(GROUP_BYTES).enumerate() {
        if max_u8(group) < threshold {
            continue;
        }
        for (b, block) in group.chunks(BLOCK_BYTES).enumerate() {
            if max_u8(block) < threshold {
                continue;
            }
            let start = u0 + (g * GROUP_BYTES + b * BLOCK_BYTES) / 3;
            let end = start + block.len().div_ceil(3) - 1;
            let (lo, hi) = (start.saturating_sub(margin).max(u0), (end + margin).min(u1));
            match windows.last_mut() {
                Some(last) if lo <= last.1 + 1 => last.1 = last.1.max(hi),
                _ => windows.push((lo, hi)),
            }
        }
    }
    windows
}

/// How far from a peak [`peak_at`] reads the profile (px): the walk to
/// half maximum, which ends by `max_width_px` + 1 on each side or the peak
/// is too wide, a pixel past it, and the Steger kernel's reach (4 sigma of
/// the widest accepted line) or the centre of gravity's margin beyond.
fn candidate_margin_px(options: &StripeOptions) -> usize {
    // Without a finite bound on the width the walk has none: the whole span.
    if options.max_width_px.is_nan() || options.max_width_px >= 1e6 {
        return usize::MAX / 4;
    }
    let width = options.max_width_px.max(0.0).ceil() as usize;
    let steger = steger_reach(steger_sigma(width as f64));
    (width + 2) + steger.max(width.max(2)) + 2
}

/// The one peak of a span (no line detector): what [`span_peaks`] finds
/// there, searched on the interleaved integer scores of the span's pixels
/// (`on`, `off`: the span's RGB bytes). The last of equal maxima, as
/// [`profile_peak`]'s choice.
fn single_peak_u8(
    on: &[u8],
    off: Option<&[u8]>,
    (v, u0): (u32, u32),
    options: &StripeOptions,
    interleaved: &mut Vec<u8>,
) -> Option<StripePoint> {
    interleaved_scores(on, off, interleaved);
    let scores = interleaved.as_slice();
    if scores.is_empty() {
        return None;
    }
    let peak = max_u8(scores);
    if f32::from(peak) < options.min_strength {
        return None;
    }
    let k = last_index_by_key(scores, |&s| s, peak)? / 3;
    // The strongest score more than `guard` pixels from the peak.
    let rival = |guard: usize| {
        let left = scores.get(..3 * k.saturating_sub(guard)).map_or(0, max_u8);
        let right = scores.get(3 * (k + guard + 1)..).map_or(0, max_u8);
        f32::from(left.max(right))
    };
    let (u, strength, width_px) = peak_at(&EveryThird(scores), k, options, rival)?;
    Some(StripePoint { u_px: f64::from(u0) + u, v_px: f64::from(v), strength, width_px })
}

/// The peaks of one span of a row, appended to `points`: `row` holds the
/// whole image row's scores, valid over the columns `valid` (at least the
/// span and the local background's reach).
fn span_peaks<T: Summable>(
    row: &[T],
    valid: (usize, usize),
    (v, u0, u1): (u32, u32, u32),
    options: &StripeOptions,
    buffer: &mut Vec<f32>,
    points: &mut Vec<StripePoint>,
) {
    let (first, last) = (u0 as usize, u1 as usize);
    let Some(span) = row.get(first..=last) else { return };
    let start = points.len();
    match options.local_background {
        None => {
            buffer.clear();
            // Scores are f32, u8 or i16: each converts exactly.
            buffer.extend(span.iter().map(|&s| s.into() as f32));
            profile_peaks(buffer.as_mut_slice(), (v, u0), options, points);
        }
        Some(background) => {
            local_contrast(row, first, last, background, buffer);
            profile_peaks(buffer.as_mut_slice(), (v, u0), options, points);
            for point in &mut points[start..] {
                refine_on_linear_background(row, valid, background, point);
            }
        }
    }
}

/// A Gaussian's full width at half maximum in sigmas, 2 sqrt(2 ln 2).
const FWHM_PER_SIGMA: f64 = 2.354_820_045;

/// Whether `point`'s stripe reaches the line detector's windows: a
/// Gaussian (sigma = FWHM / 2.355) that ends, at 3 sigma, before they begin
/// leaves them to the background alone, where the detector is unbiased
/// (0.004 px at sigma 1.5 px on 2 DN/px).
fn reaches_windows(point: &StripePoint, background: LocalBackground) -> bool {
    background.window_px > 0 && 3.0 * point.width_px / FWHM_PER_SIGMA > background.gap_px as f64
}

/// Steger's centre of `point` again, on the scores less a linear
/// background: each pixel's score less the mean of its two detector
/// windows (the background's value there where it is linear). The line
/// detector subtracts the larger window instead, which keeps a step (an
/// apple's edge) from looking like a line but, where the background slopes
/// under a wide stripe, moves the centre towards the lower side (0.24 px
/// for a stripe of sigma 2.5 px on a slope of 2 DN/px): this removes that.
/// Only a stripe wide enough to reach the windows is biased, and only it
/// is refined. The point keeps its centre where the profile's reach leaves `valid`
/// (columns of `row` that hold scores), where this profile has no maximum
/// near it, or where the centre would move more than a tenth of the
/// stripe's width (a slope moves it less, 0.06 of the width at sigma 3 px
/// on 2 DN/px: a larger move is a step beside the line, not a slope).
fn refine_on_linear_background<T: Copy + Into<f64>>(
    row: &[T],
    (valid_first, valid_last): (usize, usize),
    background: LocalBackground,
    point: &mut StripePoint,
) {
    let (gap, window, reach) = (background.gap_px, background.window_px, background.reach());
    if !reaches_windows(point, background) || !point.u_px.is_finite() || point.u_px < 0.0 {
        return;
    }
    let sigma = steger_sigma(point.width_px);
    // Pixels each side of the peak: Steger's kernel from anywhere within
    // the stripe's width.
    let half = steger_reach(sigma) + point.width_px.ceil() as usize + 1;
    let k = point.u_px.round() as usize;
    let Some(first) = k.checked_sub(half) else { return };
    let last = k + half;
    if first < valid_first + reach || last + reach > valid_last.min(row.len().saturating_sub(1)) {
        return;
    }
    let mean = |a: usize| row[a..a + window].iter().map(|&s| s.into()).sum::<f64>() / window as f64;
    let profile: Vec<f32> = (first..=last)
        .map(|i| (row[i].into() - 0.5 * (mean(i - reach) + mean(i + gap + 1))) as f32)
        .collect();
    let within = point.width_px.ceil() as usize;
    let local = k - first;
    let Some(centre) = steger_centre(&profile[..], local, local - within, local + within, sigma)
    else {
        return;
    };
    let centre = first as f64 + centre;
    if (centre - point.u_px).abs() <= 0.1 * point.width_px {
        point.u_px = centre;
    }
}

/// The peaks of one span's profile (pixel 0 at column `u0` of row `v`),
/// appended to `points`: with one peak per row, the strongest if it passes
/// [`peak_at`]'s tests; with several, the strongest, then the next outside
/// its flanks, down to `ambiguity_ratio` of the strongest (the profile is
/// cleared around each peak found).
fn profile_peaks<P: PeakProfile + ?Sized>(
    profile: &mut P,
    (v, u0): (u32, u32),
    options: &StripeOptions,
    points: &mut Vec<StripePoint>,
) {
    let point = |(u, strength, width_px): (f64, f32, f64)| StripePoint {
        u_px: f64::from(u0) + u,
        v_px: f64::from(v),
        strength,
        width_px,
    };
    if options.max_peaks_per_row <= 1 {
        if let Some(peak) = profile_peak(profile, options) {
            points.push(point(peak));
        }
        return;
    }
    let single = StripeOptions { ambiguity_ratio: f32::INFINITY, ..options.clone() };
    let mut strongest = None;
    for _ in 0..options.max_peaks_per_row {
        let Some(peak) = profile_peak(profile, &single) else { break };
        let floor = *strongest.get_or_insert(peak.1) * options.ambiguity_ratio;
        if peak.1 < floor {
            break;
        }
        points.push(point(peak));
        let guard = (2.0 * peak.2).ceil() + 2.0;
        let lo = (peak.0 - guard).floor().max(0.0) as usize;
        let hi = ((peak.0 + guard).ceil() as usize).min(profile.pixels().saturating_sub(1));
        profile.clear(lo, hi);
    }
}

/// A score the line detector sums: its window sums' type (u32 for the
/// integer scores, exact; f64 for `f32` scores, which hold integers).
trait Summable: Copy + Into<f64> {
    /// The window sums' type.
    type Sum: Copy
        + Default
        + PartialOrd
        + std::ops::Add<Output = Self::Sum>
        + std::ops::Sub<Output = Self::Sum>
        + std::ops::Mul<Output = Self::Sum>
        + Into<f64>;
    /// The score as a term of the sums.
    fn widen(self) -> Self::Sum;
    /// A window's length as a factor of the sums.
    fn count(pixels: usize) -> Self::Sum;
    /// A sum (at most 255 x 4096 for integer scores) as an `f32`, exactly.
    fn sum_to_f32(sum: Self::Sum) -> f32;
}

impl Summable for u8 {
    type Sum = u32;
    fn widen(self) -> u32 {
        u32::from(self)
    }
    fn count(pixels: usize) -> u32 {
        pixels as u32
    }
    fn sum_to_f32(sum: u32) -> f32 {
        // Through i32: one vector conversion (SSE2 has none from u32).
        sum as i32 as f32
    }
}

impl Summable for i16 {
    type Sum = i32;
    fn widen(self) -> i32 {
        i32::from(self)
    }
    fn count(pixels: usize) -> i32 {
        pixels as i32
    }
    fn sum_to_f32(sum: i32) -> f32 {
        sum as f32
    }
}

impl Summable for f32 {
    type Sum = f64;
    fn widen(self) -> f64 {
        f64::from(self)
    }
    fn count(pixels: usize) -> f64 {
        pixels as f64
    }
    fn sum_to_f32(sum: f64) -> f32 {
        sum as f32
    }
}

/// Longest window of [`LocalBackground`] (px) the line detector's sums
/// hold exactly (255 x this in a u32 with room to spare; in a `f32`
/// profile value, integers below 2^24).
const MAX_BACKGROUND_WINDOW_PX: usize = 4096;

/// The line detector of [`LocalBackground`] over `row[first..=last]`,
/// written to `out`: each score less the larger of its two window means,
/// clamped at 0. A window that the row's end cuts does not count (one side
/// then sets the level; neither, at a row shorter than a window each side
/// of the pixel, and the level is 0).
///
/// The value is `(window x score - larger window sum) / window` from
/// window sums in `T::Sum` (exact integers for `u8` scores), the score
/// less the larger mean exactly for a power-of-two window, as the
/// orchard's 4 px, else to an `f32`'s last bit; the same values as
/// [`local_contrast_i16`] gives in units of `1 / window`. The sums and the
/// values are loops over slices the compiler vectorises.
fn local_contrast<T: Summable>(
    row: &[T],
    first: usize,
    last: usize,
    background: LocalBackground,
    out: &mut Vec<f32>,
) {
    let (gap, window, reach) = (background.gap_px, background.window_px, background.reach());
    out.clear();
    if window == 0 {
        // Windows of no pixels: no background, the scores as they are.
        out.extend(row[first..=last].iter().map(|&s| s.into() as f32));
        return;
    }
    let lo = first.saturating_sub(reach);
    let hi = (last + reach).min(row.len() - 1);
    let size = T::count(window);
    let to_value = ScaledValue::new(window);
    let sum = |a: usize| row[a..a + window].iter().fold(T::Sum::default(), |s, &x| s + x.widen());
    let excess = |value: T, level: Option<T::Sum>| -> f32 {
        let (scaled, level) = (value.widen() * size, level.unwrap_or_default());
        to_value.of(T::sum_to_f32(if scaled > level { scaled - level } else { T::Sum::default() }))
    };
    let at_edge = |u: usize| {
        let left = (u >= lo + reach).then(|| sum(u - reach));
        let right = (u + reach <= hi).then(|| sum(u + gap + 1));
        let level = match (left, right) {
            (Some(a), Some(b)) => Some(if a > b { a } else { b }),
            (a, b) => a.or(b),
        };
        excess(row[u], level)
    };
    // Where both windows lie whole inside lo..=hi (most of a row).
    let (inner_first, inner_last) = (first.max(lo + reach), last.min(hi.saturating_sub(reach)));
    if window > MAX_BACKGROUND_WINDOW_PX || inner_first > inner_last {
        out.extend((first..=last).map(at_edge));
        return;
    }
    out.extend((first..inner_first).map(at_edge));
    // sums[i]: the window starting at pixel base + i. Pixel u's left window
    // starts at u - reach (sums[u - inner_first]), its right one at
    // u + gap + 1 (sums[u - inner_first + reach + gap + 1]).
    let n = inner_last - inner_first + 1;
    let (base, count) = (inner_first - reach, n + reach + gap + 1);
    let mut sums: Vec<T::Sum> = row[base..base + count].iter().map(|&s| s.widen()).collect();
    for j in 1..window {
        for (sum, &s) in sums.iter_mut().zip(&row[base + j..base + j + count]) {
            *sum = *sum + s.widen();
        }
    }
    let (left, right) = (&sums[..n], &sums[reach + gap + 1..reach + gap + 1 + n]);
    let values = &row[inner_first..=inner_last];
    let start = out.len();
    out.resize(start + n, 0.0);
    for (((out, &value), &left), &right) in out[start..].iter_mut().zip(values).zip(left).zip(right)
    {
        *out = excess(value, Some(if left > right { left } else { right }));
    }
    out.extend((inner_last + 1..=last).map(at_edge));
}

/// Longest window of [`LocalBackground`] (px) [`local_contrast_i16`] takes:
/// 255 x 128 and its sums fit an `i16`.
const MAX_I16_WINDOW_PX: usize = 128;

/// [`local_contrast`] of integer scores in units of `1 / window`, as
/// `i16` (`window` at most [`MAX_I16_WINDOW_PX`]): `window x score - larger
/// window sum`, clamped at 0, over whole vectors of eight or sixteen
/// lanes. [`Scaled`] reads them as [`local_contrast`]'s values, to the bit.
fn local_contrast_i16(
    row: &[u8],
    first: usize,
    last: usize,
    background: LocalBackground,
    sums: &mut Vec<i16>,
    out: &mut Vec<i16>,
) {
    let (gap, window, reach) = (background.gap_px, background.window_px, background.reach());
    let lo = first.saturating_sub(reach);
    let hi = (last + reach).min(row.len() - 1);
    let size = window as i16;
    let sum = |a: usize| row[a..a + window].iter().fold(0_i16, |s, &x| s + i16::from(x));
    let at_edge = |u: usize| {
        let left = (u >= lo + reach).then(|| sum(u - reach));
        let right = (u + reach <= hi).then(|| sum(u + gap + 1));
        let level = match (left, right) {
            (Some(a), Some(b)) => a.max(b),
            (a, b) => a.or(b).unwrap_or(0),
        };
        (size * i16::from(row[u]) - level).max(0)
    };
    out.clear();
    let (inner_first, inner_last) = (first.max(lo + reach), last.min(hi.saturating_sub(reach)));
    if window == 0 || inner_first > inner_last {
        out.extend((first..=last).map(at_edge));
        return;
    }
    out.extend((first..inner_first).map(at_edge));
    let n = inner_last - inner_first + 1;
    let (base, count) = (inner_first - reach, n + reach + gap + 1);
    sums.clear();
    sums.extend(row[base..base + count].iter().map(|&s| i16::from(s)));
    for j in 1..window {
        for (sum, &s) in sums.iter_mut().zip(&row[base + j..base + j + count]) {
            *sum += i16::from(s);
        }
    }
    let (left, right) = (&sums[..n], &sums[reach + gap + 1..reach + gap + 1 + n]);
    let values = &row[inner_first..=inner_last];
    out.extend(
        values
            .iter()
            .zip(left)
            .zip(right)
            .map(|((&value, &left), &right)| (size * i16::from(value) - left.max(right)).max(0)),
    );
    out.extend((inner_last + 1..=last).map(at_edge));
}

/// `excess / window` as the line detector's value: a multiplication by
/// `1 / window` where that is exact (a power of two), else the division.
#[derive(Clone, Copy)]
struct ScaledValue {
    inverse: Option<f32>,
    size: f32,
}

impl ScaledValue {
    fn new(window: usize) -> ScaledValue {
        let size = window.max(1) as f32;
        ScaledValue { inverse: window.is_power_of_two().then(|| 1.0 / size), size }
    }

    #[inline]
    fn of(self, excess: f32) -> f32 {
        match self.inverse {
            Some(inverse) => excess * inverse,
            None => excess / self.size,
        }
    }
}

/// Scores along a row as the sub-pixel step reads them: an `f32` row, or
/// every third byte of the interleaved integer scores of [`single_peak_u8`].
trait Profile {
    /// Number of pixels.
    fn pixels(&self) -> usize;
    /// The score of pixel `i` (< `pixels()`).
    fn at(&self, i: usize) -> f32;
}

impl Profile for [f32] {
    fn pixels(&self) -> usize {
        self.len()
    }

    fn at(&self, i: usize) -> f32 {
        self[i]
    }
}

/// Pixel `i`'s score at byte `3 i` (the bytes between are 0).
struct EveryThird<'a>(&'a [u8]);

impl Profile for EveryThird<'_> {
    fn pixels(&self) -> usize {
        self.0.len() / 3
    }

    fn at(&self, i: usize) -> f32 {
        f32::from(self.0[3 * i])
    }
}

/// [`local_contrast_i16`]'s values in units of `1 / window`, read as
/// [`local_contrast`]'s `f32` values.
struct Scaled<'a> {
    excess: &'a mut [i16],
    value: ScaledValue,
}

impl Profile for Scaled<'_> {
    fn pixels(&self) -> usize {
        self.excess.len()
    }

    fn at(&self, i: usize) -> f32 {
        self.value.of(f32::from(self.excess[i]))
    }
}

/// A profile the peak search runs on: its last largest value, the largest
/// in a range, and clearing a range.
trait PeakProfile: Profile {
    /// The index of the last largest value (`max_by`'s choice).
    fn last_max_index(&self) -> Option<usize>;
    /// The largest value in `range`, at least 0.
    fn max_in(&self, range: std::ops::Range<usize>) -> f32;
    /// Sets `lo..=hi` to 0.
    fn clear(&mut self, lo: usize, hi: usize);
}

impl PeakProfile for [f32] {
    fn last_max_index(&self) -> Option<usize> {
        last_max_index(self)
    }

    fn max_in(&self, range: std::ops::Range<usize>) -> f32 {
        self.get(range).map_or(0.0, max_at_least_zero)
    }

    fn clear(&mut self, lo: usize, hi: usize) {
        for s in self.iter_mut().take(hi + 1).skip(lo) {
            *s = 0.0;
        }
    }
}

impl PeakProfile for Scaled<'_> {
    fn last_max_index(&self) -> Option<usize> {
        last_max_by_key(self.excess, |&x| x)
    }

    fn max_in(&self, range: std::ops::Range<usize>) -> f32 {
        let largest = self.excess.get(range).map_or(0, |r| r.iter().fold(0, |m, &x| m.max(x)));
        self.value.of(f32::from(largest))
    }

    fn clear(&mut self, lo: usize, hi: usize) {
        for s in self.excess.iter_mut().take(hi + 1).skip(lo) {
            *s = 0;
        }
    }
}

/// The sub-pixel peak of a profile: (column within it, peak score, width
/// at half maximum), at its last largest value.
fn profile_peak<P: PeakProfile + ?Sized>(
    profile: &P,
    options: &StripeOptions,
) -> Option<(f64, f32, f64)> {
    let k = profile.last_max_index()?;
    // A second peak clear of this one's flanks makes the row ambiguous.
    let rival = |guard: usize| {
        let left = profile.max_in(0..k.saturating_sub(guard));
        let right = profile.max_in(k + guard + 1..profile.pixels());
        left.max(right)
    };
    peak_at(profile, k, options, rival)
}

/// `f32::total_cmp`'s order as an integer: a key whose `i32` order is
/// that order.
#[inline]
fn total_order_key(x: f32) -> i32 {
    let bits = x.to_bits() as i32;
    bits ^ (((bits >> 31) as u32) >> 1) as i32
}

/// The index of the last largest value in `f32::total_cmp`'s order, as
/// `iter().enumerate().max_by(total_cmp)` finds it, in loops the compiler
/// vectorises (integer keys; the last match searched a chunk at a time
/// from the end).
fn last_max_index(row: &[f32]) -> Option<usize> {
    last_max_by_key(row, |&x| total_order_key(x))
}

/// The index of the last value with the largest `key`.
fn last_max_by_key<T, K: Ord + Copy>(values: &[T], key: impl Fn(&T) -> K) -> Option<usize> {
    let best = values.iter().map(&key).max()?;
    last_index_by_key(values, key, best)
}

/// The index of the last value whose `key` is `best`, the largest key,
/// searched from the end a chunk at a time: the chunk's largest key (a
/// loop the compiler vectorises for integer keys), then the match in it.
fn last_index_by_key<T, K: Ord + Copy>(
    values: &[T],
    key: impl Fn(&T) -> K,
    best: K,
) -> Option<usize> {
    const CHUNK: usize = 64;
    let mut end = values.len();
    while end > 0 {
        let start = end.saturating_sub(CHUNK);
        let chunk = &values[start..end];
        let largest = chunk.iter().map(&key).fold(key(&chunk[0]), K::max);
        if largest >= best
            && let Some(i) = chunk.iter().rposition(|x| key(x) == best)
        {
            return Some(start + i);
        }
        end = start;
    }
    None
}

/// The largest value, and at least 0: `fold(0.0, f32::max)` for the
/// profiles here, which hold no NaN (a non-negative `f32`'s bits order as
/// its value; a negative one's, as an `i32`, fall below 0's).
fn max_at_least_zero(values: &[f32]) -> f32 {
    let bits = values.iter().fold(0_i32, |m, &x| m.max(x.to_bits() as i32));
    f32::from_bits(bits as u32)
}

/// [`profile_peak`] at the profile's maximum `k`: the strength, width and
/// ambiguity tests and the sub-pixel centre. `rival(guard)` is the
/// strongest score more than `guard` pixels from `k`.
fn peak_at<P: Profile + ?Sized>(
    row: &P,
    k: usize,
    options: &StripeOptions,
    rival: impl FnOnce(usize) -> f32,
) -> Option<(f64, f32, f64)> {
    let peak = (k < row.pixels()).then(|| row.at(k))?;
    if peak.is_nan() || peak < options.min_strength {
        return None;
    }
    let half = peak / 2.0;
    let mut left = k;
    while left > 0 && row.at(left - 1) > half {
        left -= 1;
    }
    let mut right = k;
    while right + 1 < row.pixels() && row.at(right + 1) > half {
        right += 1;
    }
    // Width at half maximum, interpolated at both flanks.
    let flank = |inside: usize, outside: Option<usize>| -> f64 {
        match outside {
            Some(o) => {
                let (a, b) = (row.at(inside), row.at(o));
                if a > b { f64::from((a - half) / (a - b)) } else { 0.5 }
            }
            None => 0.5,
        }
    };
    let width_px = (right - left) as f64
        + flank(left, left.checked_sub(1))
        + flank(right, (right + 1 < row.pixels()).then_some(right + 1));
    if width_px > options.max_width_px {
        return None;
    }
    // A second peak clear of this one's flanks makes the row ambiguous.
    let guard = (2.0 * width_px).ceil() as usize + 2;
    // An infinite ratio (the several-peaks search) admits any rival: no
    // need to look for one.
    if options.ambiguity_ratio.is_finite() && rival(guard) > options.ambiguity_ratio * peak {
        return None;
    }
    let centre = match options.method {
        PeakMethod::CentreOfGravity => {
            let margin = (width_px.ceil() as usize).max(2);
            let lo = left.saturating_sub(margin);
            let hi = (right + margin).min(row.pixels() - 1);
            let background = row.at(lo).min(row.at(hi));
            let (mut sum, mut weighted) = (0.0_f64, 0.0_f64);
            for i in lo..=hi {
                let w = f64::from((row.at(i) - background).max(0.0));
                sum += w;
                weighted += w * i as f64;
            }
            if sum <= 0.0 {
                return None;
            }
            weighted / sum
        }
        PeakMethod::Gaussian | PeakMethod::Parabola => {
            if k == 0 || k + 1 >= row.pixels() {
                return None;
            }
            let transform = |s: f32| match options.method {
                PeakMethod::Gaussian => f64::from(s.max(1e-3)).ln(),
                _ => f64::from(s),
            };
            let (a, b, c) =
                (transform(row.at(k - 1)), transform(row.at(k)), transform(row.at(k + 1)));
            let denominator = a - 2.0 * b + c;
            let offset = if denominator < 0.0 { 0.5 * (a - c) / denominator } else { 0.0 };
            k as f64 + offset.clamp(-0.5, 0.5)
        }
        PeakMethod::Steger => steger_centre(row, k, left, right, steger_sigma(width_px))?,
    };
    Some((centre, peak, width_px))
}

/// Steger's centre of the line in `row` (see [`PeakMethod::Steger`]),
/// starting at the peak pixel `k` and moving one pixel at a time towards
/// the zero of the derivative, within `left..=right` (the stripe above half
/// maximum). Where two neighbours each point at the other (the zero on the
/// border between them, to rounding), the one with the smaller offset
/// wins. `None` where the smoothed profile is not a maximum on the way.
///
/// Steger's offset is one Newton step from the pixel centre, exact for a
/// parabolic profile; on a Gaussian stripe it overshoots by up to 0.04 px
/// half a pixel away. One more step, from the sub-pixel centre (the
/// kernels are analytic, so the derivatives are as easy to take there),
/// removes that to under 0.003 px.
fn steger_centre<P: Profile + ?Sized>(
    row: &P,
    k: usize,
    left: usize,
    right: usize,
    sigma: f64,
) -> Option<f64> {
    let offset_at = |x: f64| {
        let (first, second) = smoothed_derivatives(row, x, sigma);
        // Written so that NaN counts as no maximum.
        (second < 0.0).then(|| -first / second)
    };
    let mut pixel = k;
    let mut t = offset_at(pixel as f64)?;
    while t.abs() > 0.5 {
        let next = if t > 0.0 { pixel + 1 } else { pixel.checked_sub(1)? };
        if !(left..=right).contains(&next) {
            return None;
        }
        let t_next = offset_at(next as f64)?;
        if t_next.signum() != t.signum() {
            // The zero lies between the two pixels.
            if t_next.abs() < t.abs() {
                (pixel, t) = (next, t_next);
            }
            break;
        }
        (pixel, t) = (next, t_next);
    }
    let centre = pixel as f64 + t;
    Some(match offset_at(centre) {
        Some(step) if step.abs() <= 0.5 => centre + step,
        _ => centre,
    })
}

/// First and second derivatives at `x` (px, within the row) of `row`
/// smoothed by a Gaussian of `sigma` px. The kernels are the Gaussian's
/// derivatives integrated over each pixel, as Steger (1998) samples them
/// (a pixel holds the mean of the continuous profile over its width), cut
/// at 4 sigma; the row's end pixels repeat beyond it.
fn smoothed_derivatives<P: Profile + ?Sized>(row: &P, x: f64, sigma: f64) -> (f64, f64) {
    let reach = steger_reach(sigma) as i64;
    let (nearest, last) = (x.round() as i64, row.pixels() as i64 - 1);
    // The Gaussian g and its slope g' at distance d from x; the normalisation,
    // 1 / (sqrt(2 pi) sigma), cancels in -g' / g'' and keeps the sign of
    // g'', so it is left out.
    let at = |d: f64| {
        let g = (-0.5 * (d / sigma).powi(2)).exp();
        (g, -d / (sigma * sigma) * g)
    };
    let (mut first, mut second) = (0.0_f64, 0.0_f64);
    // Pixel i covers x - i - 0.5 ..= x - i + 0.5 of the kernel's argument:
    // its lower end is the next pixel's upper end.
    let mut upper = at(x - (nearest - reach) as f64 + 0.5);
    for i in nearest - reach..=nearest + reach {
        let lower = at(x - i as f64 - 0.5);
        let value = f64::from(row.at(i.clamp(0, last) as usize));
        first += value * (upper.0 - lower.0);
        second += value * (upper.1 - lower.1);
        upper = lower;
    }
    (first, second)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The sub-pixel peak of one row's scores: (column within the row,
    /// peak score, width at half maximum).
    fn row_peak(row: &[f32], options: &StripeOptions) -> Option<(f64, f32, f64)> {
        profile_peak(row, options)
    }

    /// A row with a Gaussian stripe of sigma 1.5 px at `centre` over a background.
    fn gaussian_row(centre: f64, n: usize) -> Vec<f32> {
        (0..n)
            .map(|i| {
                (3.0 + 100.0 * (-((i as f64 - centre).powi(2)) / (2.0 * 1.5 * 1.5)).exp()) as f32
            })
            .collect()
    }

    /// A wide stripe (sigma 2.5 px, as a defocused line gives) on a
    /// background that slopes 1.5 DN per px (a shaded fruit), each pixel
    /// the mean over its width, red on a grey ground.
    fn wide_stripe_on_a_slope(centre: f64, with_stripe: bool) -> RgbImage {
        let (width, height) = (121_u32, 4_u32);
        RgbImage::from_fn(width, height, |u, _| {
            let red = (0..20)
                .map(|j| {
                    let x = f64::from(u) - 0.5 + (f64::from(j) + 0.5) / 20.0;
                    let stripe = if with_stripe {
                        70.0 * (-((x - centre).powi(2)) / (2.0 * 2.5 * 2.5)).exp()
                    } else {
                        0.0
                    };
                    100.0 + 1.5 * (x - 60.0) + stripe
                })
                .sum::<f64>()
                / 20.0;
            image::Rgb([red.round() as u8, 30, 30])
        })
    }

    #[test]
    fn a_wide_stripe_on_a_sloping_background_keeps_its_centre() {
        let options = StripeOptions::orchard();
        for centre in [58.0, 60.3, 61.7] {
            let on = wide_stripe_on_a_slope(centre, true);
            let off = wide_stripe_on_a_slope(centre, false);
            let region = Region::full(on.width(), on.height());
            // The colour score (no laser-off image), the difference with
            // a laser-off image, and a score image.
            let colour = extract_stripe_rgb(&on, None, &region, &options).unwrap();
            let difference = extract_stripe_rgb(&on, Some(&off), &region, &options).unwrap();
            let score = laser_score(&on, None, &options).unwrap();
            let from_score = extract_stripe(&score, &region, &options);
            for (what, points) in
                [("colour", colour), ("difference", difference), ("score image", from_score)]
            {
                // One point per row on the stripe (the ramp's end at the
                // image's border may give another, far from it).
                let on_stripe: Vec<_> =
                    points.iter().filter(|p| (p.u_px - centre).abs() < 5.0).collect();
                assert_eq!(on_stripe.len(), 4, "{what}: {points:?}");
                for p in on_stripe {
                    assert!((p.u_px - centre).abs() < 0.05, "{what}: {} for {centre}", p.u_px);
                }
            }
        }
    }

    #[test]
    fn every_method_finds_a_gaussian_peak() {
        for method in [
            PeakMethod::CentreOfGravity,
            PeakMethod::Gaussian,
            PeakMethod::Parabola,
            PeakMethod::Steger,
        ] {
            let options = StripeOptions { method, ..StripeOptions::default() };
            for centre in [20.0, 20.25, 20.5, 20.8] {
                let (u, strength, width) = row_peak(&gaussian_row(centre, 41), &options).unwrap();
                let tolerance = if method == PeakMethod::Parabola { 0.1 } else { 0.01 };
                assert!((u - centre).abs() < tolerance, "{method:?}: {u} vs {centre}");
                assert!(strength > 90.0);
                assert!((width - 2.355 * 1.5).abs() < 0.3, "{width}");
            }
        }
    }

    #[test]
    fn steger_finds_box_filtered_and_flat_topped_stripes() {
        // Each pixel the mean of the continuous profile over its width, as a
        // camera records it (100 samples per pixel).
        let box_filtered = |profile: &dyn Fn(f64) -> f64| -> Vec<f32> {
            (0..41)
                .map(|i| {
                    let sum: f64 = (0..100)
                        .map(|j| profile(f64::from(i) - 0.5 + (f64::from(j) + 0.5) / 100.0))
                        .sum();
                    (sum / 100.0) as f32
                })
                .collect()
        };
        let options = StripeOptions { method: PeakMethod::Steger, ..StripeOptions::default() };
        for centre in [20.0, 20.1, 20.37, 20.5, 20.62, 20.9] {
            let gaussian = box_filtered(&|x| 100.0 * (-((x - centre).powi(2)) / 4.5).exp());
            let (u, _, _) = row_peak(&gaussian, &options).unwrap();
            assert!((u - centre).abs() < 0.005, "Gaussian: {u} vs {centre}");
            // A clipped stripe: a flat top 6 px wide with Gaussian shoulders.
            let flat = box_filtered(&|x| {
                let outside = ((x - centre).abs() - 3.0).max(0.0);
                200.0 * (-(outside * outside) / 4.5).exp()
            });
            let (u, _, width) = row_peak(&flat, &options).unwrap();
            assert!((u - centre).abs() < 0.005, "flat top: {u} vs {centre}");
            assert!(width > 8.0, "{width}");
        }
    }

    #[test]
    fn weak_wide_and_ambiguous_rows_are_skipped() {
        let options = StripeOptions::default();
        let weak: Vec<f32> = gaussian_row(20.0, 41).iter().map(|s| s / 20.0).collect();
        assert!(row_peak(&weak, &options).is_none());
        let wide: Vec<f32> =
            (0..41).map(|i| if (5..30).contains(&i) { 200.0 } else { 0.0 }).collect();
        assert!(row_peak(&wide, &options).is_none());
        let mut two = gaussian_row(10.0, 41);
        for (s, t) in two.iter_mut().zip(gaussian_row(32.0, 41)) {
            *s += t * 0.8;
        }
        assert!(row_peak(&two, &options).is_none());
    }

    #[test]
    fn local_background_keeps_a_line_and_drops_a_step() {
        // A line of height 60 on a plateau of 80 that starts at column 30 (a
        // red apple's edge under the colour-contrast score).
        let mut row: Vec<f32> = (0..80).map(|i| if i >= 30 { 80.0 } else { 5.0 }).collect();
        for (s, t) in row.iter_mut().zip(gaussian_row(50.0, 80)) {
            *s += t * 0.6 - 1.8;
        }
        let background = LocalBackground { gap_px: 5, window_px: 4 };
        let mut out = Vec::new();
        local_contrast(&row, 0, 79, background, &mut out);
        let options =
            StripeOptions { local_background: Some(background), ..StripeOptions::orchard() };
        let (u, strength, _) = row_peak(&out, &options).unwrap();
        assert!((u - 50.0).abs() < 0.05, "{u}");
        assert!((strength - 60.0).abs() < 3.0, "{strength}");
        // The step alone gives nothing.
        let step: Vec<f32> = (0..80).map(|i| if i >= 30 { 80.0 } else { 5.0 }).collect();
        local_contrast(&step, 0, 79, background, &mut out);
        assert!(out.iter().all(|&s| s < 1.0), "{out:?}");
    }

    #[test]
    fn rgb_extraction_keeps_clipped_lines_and_skips_saturated_patches_and_colour() {
        // Row 0-2: a line on a red surface; row 3: the same line with its
        // top clipped at 255; row 4: inside a 20 px saturated patch; row 5:
        // a red band on a yellow surface (green dips: colour, not laser).
        let mut image = RgbImage::from_pixel(60, 6, image::Rgb([120, 30, 30]));
        for (u, t) in gaussian_row(30.0, 60).iter().enumerate() {
            let u = u as u32;
            for v in 0..3 {
                image.put_pixel(u, v, image::Rgb([(120.0 + t * 1.2) as u8, 30, 30]));
            }
            image.put_pixel(u, 3, image::Rgb([(120.0 + t * 3.0).min(255.0) as u8, 30, 30]));
            let patch = (20..40).contains(&u);
            let red = if patch { 255.0 } else { (120.0 + t * 1.2).min(255.0) };
            image.put_pixel(u, 4, image::Rgb([red as u8, 30, 30]));
            let green = 180.0 - t * 1.5;
            image.put_pixel(u, 5, image::Rgb([180, green.max(0.0) as u8, 30]));
        }
        let region = Region::full(60, 6);
        let options = StripeOptions::orchard();
        let points = extract_stripe_rgb(&image, None, &region, &options).unwrap();
        let rows: Vec<f64> = points.iter().map(|p| p.v_px).collect();
        assert_eq!(rows, [0.0, 1.0, 2.0, 3.0], "{points:?}");
        assert!(points.iter().all(|p| (p.u_px - 30.0).abs() < 0.1), "{points:?}");
        // Without the checks, the score-image path finds the same peaks in
        // the unclipped rows.
        let score = laser_score(&image, None, &options).unwrap();
        let again = extract_stripe(&score, &Region::full(60, 3), &options);
        assert_eq!(points[..3], again[..]);
    }

    /// A frame with noise, a red surface patch and a tilted laser line
    /// (with a ghost line in some rows), from a small integer hash.
    fn noisy_frame(width: u32, height: u32, seed: u32, laser: bool) -> RgbImage {
        let hash = |u: u32, v: u32, c: u32| {
            let mut h = u.wrapping_mul(374_761_393) ^ v.wrapping_mul(668_265_263) ^ c ^ seed;
            h = (h ^ (h >> 13)).wrapping_mul(1_274_126_177);
            (h ^ (h >> 16)) % 24
        };
        RgbImage::from_fn(width, height, |u, v| {
            let line = 40.0 + 0.3 * f64::from(v);
            let mut red = 60 + hash(u, v, 0);
            if (20..50).contains(&u) && (10..30).contains(&v) {
                red += 120;
            }
            if laser {
                let d = f64::from(u) - line;
                red += (150.0 * (-d * d / 4.5).exp()) as u32;
                if v % 7 == 0 {
                    let g = f64::from(u) - line - 25.0;
                    red += (100.0 * (-g * g / 4.5).exp()) as u32;
                }
            }
            image::Rgb([red.min(255) as u8, (50 + hash(u, v, 1)) as u8, (40 + hash(u, v, 2)) as u8])
        })
    }

    /// `extract_stripe_rgb` finds the points of the f32 score image
    /// (`laser_score` + `extract_stripe`), to the bit, for every region,
    /// set of options and peak method, with and without the laser-off
    /// image; each search finds more than `min_points`.
    fn assert_same_points_as_the_score_image(
        (on, off): (&RgbImage, &RgbImage),
        regions: &[Region],
        all_options: &[StripeOptions],
        methods: &[PeakMethod],
        min_points: usize,
    ) {
        for options in all_options {
            for &method in methods {
                let options = StripeOptions { method, ..options.clone() };
                for region in regions {
                    for off in [None, Some(off)] {
                        let score = laser_score(on, off, &options).unwrap();
                        let expected = extract_stripe(&score, region, &options);
                        let found = extract_stripe_rgb(on, off, region, &options).unwrap();
                        assert!(expected.len() > min_points, "{} points", expected.len());
                        assert_eq!(found, expected, "{options:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_integer_parallel_pass_finds_what_the_score_image_finds() {
        let (width, height) = (120, 90);
        let on = noisy_frame(width, height, 1, true);
        let off = noisy_frame(width, height, 2, false);
        let triangle = [Point2::new(10.0, 5.0), Point2::new(110.0, 20.0), Point2::new(30.0, 85.0)];
        let regions = [
            Region::full(width, height),
            Region::rect(30, 10, 100, 80, width, height),
            Region::convex_polygon(&triangle, 1.0, width, height),
        ];
        let orchard =
            StripeOptions { saturation_dn: None, green_check: false, ..StripeOptions::orchard() };
        // A window that is no power of two, one peak per row with a line
        // detector, and a window too long for the i16 path.
        let odd_window = StripeOptions {
            local_background: Some(LocalBackground { gap_px: 3, window_px: 5 }),
            ..orchard.clone()
        };
        let single = StripeOptions { max_peaks_per_row: 1, ..orchard.clone() };
        let long_window = StripeOptions {
            local_background: Some(LocalBackground { gap_px: 4, window_px: 130 }),
            min_strength: 3.0,
            ..orchard.clone()
        };
        let all = [StripeOptions::default(), orchard, odd_window, single, long_window];
        let methods = [PeakMethod::Steger, PeakMethod::CentreOfGravity];
        assert_same_points_as_the_score_image((&on, &off), &regions, &all, &methods, 20);
    }

    /// A wide frame whose scores are mostly under the orchard's
    /// `min_strength`: two lines (one near the right edge), a patch too
    /// wide for a line, a few lone bright pixels and background noise that
    /// reaches the threshold here and there.
    fn sparse_frame(width: u32, height: u32) -> RgbImage {
        let hash = |u: u32, v: u32, c: u32| {
            let mut h = u.wrapping_mul(2_654_435_761) ^ v.wrapping_mul(40_503) ^ c;
            h = (h ^ (h >> 15)).wrapping_mul(2_246_822_519);
            (h ^ (h >> 13)) % 23
        };
        RgbImage::from_fn(width, height, |u, v| {
            let mut red = 40 + hash(u, v, 0);
            let line = |centre: f64, height: f64| {
                let d = f64::from(u) - centre;
                (height * (-d * d / 4.5).exp()) as u32
            };
            red += line(300.0 + 0.5 * f64::from(v), 150.0) + line(f64::from(width) - 6.0, 90.0);
            if v % 3 == 0 {
                red += line(520.0, 60.0);
            }
            if (100..140).contains(&u) && (10..40).contains(&v) {
                red += 90;
            }
            if hash(u, v, 7) == 0 && hash(u, v, 8) < 3 {
                red += 80;
            }
            image::Rgb([red.min(255) as u8, (50 + hash(u, v, 1)) as u8, (40 + hash(u, v, 2)) as u8])
        })
    }

    #[test]
    fn the_several_peaks_search_in_candidate_windows_finds_the_whole_rows_peaks() {
        let (width, height) = (700, 60);
        let on = sparse_frame(width, height);
        let off = RgbImage::from_fn(width, height, |u, v| {
            let p = on.get_pixel(u, v);
            image::Rgb([p[1].saturating_sub(6), p[1], p[2]])
        });
        let regions = [Region::full(width, height), Region::rect(90, 5, 690, 55, width, height)];
        let orchard =
            StripeOptions { saturation_dn: None, green_check: false, ..StripeOptions::orchard() };
        let narrow = StripeOptions { max_width_px: 4.0, ..orchard.clone() };
        let methods = [PeakMethod::Steger, PeakMethod::CentreOfGravity, PeakMethod::Gaussian];
        assert_same_points_as_the_score_image(
            (&on, &off),
            &regions,
            &[orchard, narrow],
            &methods,
            60,
        );
        // Candidates cover a small part of a row here: the windows are
        // narrow, not the whole row.
        let mut interleaved = Vec::new();
        let row = &on.as_raw()[3 * 50 * width as usize..3 * 51 * width as usize];
        interleaved_scores(row, None, &mut interleaved);
        let windows = candidate_windows(&interleaved, 0, (0, width - 1), &StripeOptions::orchard());
        let covered: usize = windows.iter().map(|(lo, hi)| hi - lo + 1).sum();
        assert!(windows.len() > 1 && covered < 3 * width as usize / 4, "{windows:?}");
    }

    #[test]
    fn the_line_detector_subtracts_the_larger_window_mean() {
        let row: Vec<u8> = (0..90_u32).map(|i| ((i * 37 + i * i) % 251) as u8).collect();
        for (gap, window) in [(5, 4), (3, 3), (2, 5), (0, 1), (4, 8)] {
            let background = LocalBackground { gap_px: gap, window_px: window };
            let reach = gap + window;
            for (first, last) in [(0, 89), (3, 40), (9, 80), (50, 89), (0, 8), (20, 20)] {
                let mut out = Vec::new();
                local_contrast(&row, first, last, background, &mut out);
                let lo = first.saturating_sub(reach);
                let hi = (last + reach).min(89);
                // A window counts only where the row holds it whole.
                let mean = |a: i64, b: i64| {
                    let whole = a >= lo as i64 && b <= hi as i64 + 1;
                    whole.then(|| {
                        let values: Vec<f64> = (a..b).map(|i| f64::from(row[i as usize])).collect();
                        values.iter().sum::<f64>() / values.len() as f64
                    })
                };
                for (k, u) in (first..=last).enumerate() {
                    let u = u as i64;
                    let (gap, reach) = (gap as i64, reach as i64);
                    let left = mean(u - reach, u - gap);
                    let level = match (left, mean(u + gap + 1, u + reach + 1)) {
                        (Some(a), Some(b)) => a.max(b),
                        (Some(a), None) | (None, Some(a)) => a,
                        (None, None) => 0.0,
                    };
                    let expected = (f64::from(row[u as usize]) - level).max(0.0) as f32;
                    // Exact for a power-of-two window; else within an f32's last bit.
                    let tolerance =
                        if window.is_power_of_two() { 0.0 } else { f32::EPSILON * expected };
                    assert!(
                        (out[k] - expected).abs() <= tolerance,
                        "window {window}, span {first}..={last}, pixel {u}: {} vs {expected}",
                        out[k]
                    );
                }
            }
        }
    }

    #[test]
    fn a_line_detector_of_empty_windows_takes_the_scores_as_they_are() {
        let on = noisy_frame(120, 90, 1, true);
        let region = Region::full(120, 90);
        let plain = StripeOptions {
            saturation_dn: None,
            green_check: false,
            local_background: None,
            ..StripeOptions::orchard()
        };
        let empty = StripeOptions {
            local_background: Some(LocalBackground { gap_px: 5, window_px: 0 }),
            ..plain.clone()
        };
        let expected = extract_stripe_rgb(&on, None, &region, &plain).unwrap();
        assert!(expected.len() > 20, "{} points", expected.len());
        assert_eq!(extract_stripe_rgb(&on, None, &region, &empty).unwrap(), expected);
        let score = laser_score(&on, None, &empty).unwrap();
        assert_eq!(extract_stripe(&score, &region, &empty), expected);
    }

    #[test]
    fn the_last_largest_value_is_found_as_max_by_total_cmp_finds_it() {
        let rows: [&[f32]; 6] = [
            &[],
            &[0.0],
            &[1.0, 3.0, 2.0, 3.0, 0.5],
            &[-0.0, 0.0, -1.0],
            &[-2.0, -1.0, -3.0],
            &[f32::NAN, 5.0, 1.0],
        ];
        let long: Vec<f32> = (0..300).map(|i| ((i * 97) % 101) as f32 * 0.5).collect();
        for row in rows.into_iter().chain([long.as_slice()]) {
            let expected = row.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).map(|m| m.0);
            assert_eq!(last_max_index(row), expected, "{row:?}");
        }
        assert_eq!(max_at_least_zero(&[1.5, -4.0, 7.25, 0.0]), 7.25);
        assert_eq!(max_at_least_zero(&[-4.0, -0.0]), 0.0);
        assert_eq!(max_at_least_zero(&[]), 0.0);
    }

    #[test]
    fn polygon_region_holds_the_inside_pixels() {
        let square = [
            Point2::new(10.0, 10.0),
            Point2::new(20.0, 10.0),
            Point2::new(20.0, 20.0),
            Point2::new(10.0, 20.0),
        ];
        let region = Region::convex_polygon(&square, 0.0, 100, 100);
        assert_eq!(region.pixel_count(), 121);
        let reversed: Vec<_> = square.iter().rev().copied().collect();
        assert_eq!(Region::convex_polygon(&reversed, 0.0, 100, 100), region);
        let shrunk = Region::convex_polygon(&square, 2.0, 100, 100);
        assert_eq!(shrunk.pixel_count(), 49);
        assert!(region.contains(10.0, 20.0) && !shrunk.contains(11.0, 15.0));
        assert_eq!(Region::convex_polygon(&square, 0.0, 15, 15).pixel_count(), 25);
    }

    /// A red line on a green apple's skin, whose red stays below the skin's
    /// green, is found under the orchard's line detector (the signed
    /// score); a white line (a highlight, the same light in every channel)
    /// on the same skin is not: it leaves `R - max(G, B)` where it was.
    #[test]
    fn a_red_line_on_green_skin_is_found_a_white_one_is_not() {
        let row = gaussian_row(30.0, 60);
        let frame = |red_line: bool| {
            RgbImage::from_fn(60, 4, |u, _| {
                let t = f64::from(row[u as usize]) * 0.6;
                let (r, g, b) = (70.0, 150.0, 40.0);
                let (dr, dg) = if red_line { (t, 0.05 * t) } else { (t, t) };
                image::Rgb([(r + dr) as u8, (g + dg).min(255.0) as u8, (b + dg) as u8])
            })
        };
        let region = Region::full(60, 4);
        let options = StripeOptions::orchard();
        let red = extract_stripe_rgb(&frame(true), None, &region, &options).unwrap();
        assert_eq!(red.len(), 4, "{red:?}");
        assert!(red.iter().all(|p| (p.u_px - 30.0).abs() < 0.2), "{red:?}");
        // Clamped at 0, the same skin showed nothing: R < G at every pixel.
        let board = StripeOptions { local_background: None, ..options.clone() };
        assert!(extract_stripe_rgb(&frame(true), None, &region, &board).unwrap().is_empty());
        let white = extract_stripe_rgb(&frame(false), None, &region, &options).unwrap();
        assert!(white.is_empty(), "{white:?}");
    }
}
