//! Overlays on report images: a view cut from a frame (optionally
//! downscaled), marks drawn in the frame's pixel coordinates with
//! imageproc, written as JPEG.

use std::path::Path;

use image::codecs::jpeg::JpegEncoder;
use image::{Rgb, RgbImage, imageops};
use imageproc::drawing::{draw_filled_circle_mut, draw_hollow_circle_mut, draw_line_segment_mut};
use nalgebra::Point2;

use crate::{Error, Result};

/// JPEG quality of report images: small files, marks still crisp.
const JPEG_QUALITY: u8 = 85;

/// Corner marks (detected board corners).
pub const GREEN: Rgb<u8> = Rgb([0, 230, 0]);
/// Stripe points that do not agree (outliers, points off the fruit).
pub const BLUE: Rgb<u8> = Rgb([40, 140, 255]);
/// Fruit points (the laser on a red fruit is red already).
pub const LIME: Rgb<u8> = Rgb([120, 255, 0]);
/// Search regions.
pub const YELLOW: Rgb<u8> = Rgb([255, 230, 0]);
/// Fitted spheres' silhouettes; board corners a pose puts where none was detected.
pub const MAGENTA: Rgb<u8> = Rgb([255, 0, 255]);
/// Outlines in the image; calibration samples beyond the threshold.
pub const ORANGE: Rgb<u8> = Rgb([255, 150, 0]);
/// Candidates; calibration samples within the threshold (not red: the laser is).
pub const CYAN: Rgb<u8> = Rgb([0, 240, 240]);
/// The answer.
pub const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
/// Grid lines.
pub const GREY: Rgb<u8> = Rgb([110, 110, 110]);

/// Colours told apart at a glance, for one thing each (views of a session).
const PALETTE: [Rgb<u8>; 12] = [
    Rgb([230, 25, 75]),
    Rgb([60, 180, 75]),
    Rgb([255, 225, 25]),
    Rgb([67, 99, 216]),
    Rgb([245, 130, 49]),
    Rgb([145, 30, 180]),
    Rgb([66, 212, 244]),
    Rgb([240, 50, 230]),
    Rgb([191, 239, 69]),
    Rgb([250, 190, 212]),
    Rgb([70, 153, 144]),
    Rgb([220, 190, 255]),
];

/// The `index`-th colour of a cycle of twelve.
pub fn palette(index: usize) -> Rgb<u8> {
    PALETTE[index % PALETTE.len()]
}

/// A mark's half-size as a share of the canvas's width: 6 px on a
/// 1200 px page image, 12 px on a 5 MP frame at full size.
const MARK_SHARE: f64 = 1.0 / 200.0;

/// The smallest half-size of a mark, canvas pixels: smaller crosses are
/// lost on a textured image.
const MIN_MARK_PX: f64 = 4.0;

/// A region of a frame to draw on: frame pixel (u, v) maps to canvas
/// ((u - u0 + 1/2) scale - 1/2, (v - v0 + 1/2) scale - 1/2).
pub struct Canvas {
    image: RgbImage,
    u0_px: f64,
    v0_px: f64,
    scale: f64,
}

impl Canvas {
    /// The frame's pixels `u0..u0 + width`, `v0..v0 + height` (clamped to the
    /// frame), scaled to `min_width_px..=max_width_px` wide (enlarged pixels
    /// stay sharp squares, so that a small crop's marks do not hide it).
    pub fn crop(frame: &RgbImage, rect: [u32; 4], min_width_px: u32, max_width_px: u32) -> Self {
        let [u0, v0, width, height] = rect;
        let u0 = u0.min(frame.width().saturating_sub(1));
        let v0 = v0.min(frame.height().saturating_sub(1));
        let width = width.min(frame.width() - u0).max(1);
        let height = height.min(frame.height() - v0).max(1);
        let cut = imageops::crop_imm(frame, u0, v0, width, height).to_image();
        let (image, scale) = if width > max_width_px {
            let scale = f64::from(max_width_px) / f64::from(width);
            let new_height = ((f64::from(height) * scale).round() as u32).max(1);
            (imageops::thumbnail(&cut, max_width_px, new_height), scale)
        } else if width < min_width_px {
            let factor = min_width_px.div_ceil(width);
            let enlarged = imageops::resize(
                &cut,
                width * factor,
                height * factor,
                imageops::FilterType::Nearest,
            );
            (enlarged, f64::from(factor))
        } else {
            (cut, 1.0)
        };
        Self { image, u0_px: f64::from(u0), v0_px: f64::from(v0), scale }
    }

    /// The whole frame, downscaled to at most `max_width_px` wide.
    pub fn whole(frame: &RgbImage, max_width_px: u32) -> Self {
        Self::crop(frame, [0, 0, frame.width(), frame.height()], 0, max_width_px)
    }

    /// Canvas pixels per frame pixel.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Half-size of a mark (a cross, a circle around a point), canvas
    /// pixels: [`MARK_SHARE`] of the canvas's width, at least
    /// [`MIN_MARK_PX`], so that a mark covers the same share of the picture
    /// in a thumbnail as at full size.
    pub fn mark_px(&self) -> f64 {
        (f64::from(self.image.width()) * MARK_SHARE).max(MIN_MARK_PX)
    }

    /// Radius of a dot (a stripe sample, an edge pixel), canvas pixels: a
    /// fifth of [`Canvas::mark_px`], at least one.
    pub fn dot_px(&self) -> i32 {
        ((self.mark_px() / 5.0).round() as i32).max(1)
    }

    /// The canvas position of frame pixel `p`.
    /// Pixel centres map to pixel centres: a canvas pixel covers 1 / scale
    /// frame pixels.
    fn at(&self, p: &Point2<f64>) -> (f64, f64) {
        ((p.x - self.u0_px + 0.5) * self.scale - 0.5, (p.y - self.v0_px + 0.5) * self.scale - 0.5)
    }

    /// Draws the part of the segment a-b (canvas pixels) on the canvas:
    /// clipped first (Liang-Barsky), so that a point projected far outside
    /// costs nothing (imageproc walks every pixel of a segment).
    fn segment(&mut self, a: (f64, f64), b: (f64, f64), colour: Rgb<u8>) {
        if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
            return;
        }
        let (lo, hi_x, hi_y) =
            (-2.0, f64::from(self.image.width()) + 2.0, f64::from(self.image.height()) + 2.0);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, q) in [(-dx, a.0 - lo), (dx, hi_x - a.0), (-dy, a.1 - lo), (dy, hi_y - a.1)] {
            if p == 0.0 {
                if q < 0.0 {
                    return;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        if t0 <= t1 {
            let start = ((a.0 + t0 * dx) as f32, (a.1 + t0 * dy) as f32);
            let end = ((a.0 + t1 * dx) as f32, (a.1 + t1 * dy) as f32);
            draw_line_segment_mut(&mut self.image, start, end, colour);
        }
    }

    /// A cross of half-size `half_px` (canvas pixels) at frame pixel `p`.
    pub fn cross(&mut self, p: &Point2<f64>, half_px: f64, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        self.segment((x - half_px, y), (x + half_px, y), colour);
        self.segment((x, y - half_px), (x, y + half_px), colour);
    }

    /// A diagonal cross (an x) of half-size `half_px` at frame pixel `p`.
    pub fn x_mark(&mut self, p: &Point2<f64>, half_px: f64, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        for offset in [-0.5, 0.0, 0.5] {
            self.segment(
                (x - half_px + offset, y - half_px),
                (x + half_px + offset, y + half_px),
                colour,
            );
            self.segment(
                (x - half_px + offset, y + half_px),
                (x + half_px + offset, y - half_px),
                colour,
            );
        }
    }

    /// A filled dot of `radius_px` (canvas pixels) at frame pixel `p`.
    pub fn dot(&mut self, p: &Point2<f64>, radius_px: i32, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        if self.near(x, y, f64::from(radius_px)) {
            draw_filled_circle_mut(
                &mut self.image,
                (x.round() as i32, y.round() as i32),
                radius_px,
                colour,
            );
        }
    }

    /// A circle of `radius_px` frame pixels around frame pixel `centre`.
    pub fn circle(&mut self, centre: &Point2<f64>, radius_px: f64, colour: Rgb<u8>) {
        let (x, y) = self.at(centre);
        let r = (radius_px * self.scale).round() as i32;
        if r > 0 && self.near(x, y, f64::from(r)) {
            draw_hollow_circle_mut(
                &mut self.image,
                (x.round() as i32, y.round() as i32),
                r,
                colour,
            );
        }
    }

    /// Whether a mark of `reach_px` around canvas position (x, y) can touch the canvas.
    fn near(&self, x: f64, y: f64, reach_px: f64) -> bool {
        x.is_finite()
            && y.is_finite()
            && x > -reach_px
            && y > -reach_px
            && x < f64::from(self.image.width()) + reach_px
            && y < f64::from(self.image.height()) + reach_px
    }

    /// A polyline through frame pixels, closed if `closed`.
    pub fn polyline(&mut self, points: &[Point2<f64>], closed: bool, colour: Rgb<u8>) {
        let n = points.len();
        let segments = if closed { n } else { n.saturating_sub(1) };
        for i in 0..segments {
            let (a, b) = (self.at(&points[i]), self.at(&points[(i + 1) % n]));
            self.segment(a, b, colour);
        }
    }

    /// The canvas encoded as a JPEG in memory (written later, atomically,
    /// so that a failed encoding leaves no empty file); `path` names it in
    /// an error.
    pub fn jpeg(&self, path: &Path) -> Result<Vec<u8>> {
        let mut bytes = Vec::new();
        JpegEncoder::new_with_quality(&mut bytes, JPEG_QUALITY)
            .encode_image(&self.image)
            .map_err(|e| Error::Image { path: path.to_path_buf(), message: e.to_string() })?;
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_far_outside_are_clipped_not_walked() {
        let frame = RgbImage::new(40, 30);
        let mut canvas = Canvas::whole(&frame, 100);
        let far = [Point2::new(-1e12, 5.0), Point2::new(1e12, 5.0), Point2::new(1e12, 1e12)];
        canvas.polyline(&far, true, MAGENTA);
        canvas.circle(&Point2::new(1e12, 0.0), 1e3, MAGENTA);
        canvas.dot(&Point2::new(f64::NAN, 0.0), 2, MAGENTA);
        // The horizontal segment through the image is drawn, and only it.
        assert_eq!(canvas.image.get_pixel(20, 5), &MAGENTA);
        assert_eq!(canvas.image.get_pixel(20, 20), &Rgb([0, 0, 0]));
    }

    #[test]
    fn marks_cover_the_same_share_of_a_thumbnail_and_of_the_full_frame() {
        let frame = RgbImage::new(2448, 2048);
        let (thumbnail, full) = (Canvas::whole(&frame, 1224), Canvas::whole(&frame, 2448));
        let share = |c: &Canvas| c.mark_px() / f64::from(c.image.width());
        assert!((share(&thumbnail) - share(&full)).abs() < 1e-12);
        assert_eq!((thumbnail.dot_px(), full.dot_px()), (1, 2));
        // A small canvas keeps marks large enough to see.
        assert_eq!(Canvas::whole(&RgbImage::new(100, 80), 100).mark_px(), MIN_MARK_PX);
    }
}
