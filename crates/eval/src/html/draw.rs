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
/// Stripe points that agree (inliers, fruit points).
pub const RED: Rgb<u8> = Rgb([255, 40, 40]);
/// Stripe points that do not agree (outliers, points off the fruit).
pub const BLUE: Rgb<u8> = Rgb([40, 140, 255]);
/// Fruit points (the laser on a red fruit is red already).
pub const LIME: Rgb<u8> = Rgb([120, 255, 0]);
/// Search regions.
pub const YELLOW: Rgb<u8> = Rgb([255, 230, 0]);
/// Fitted spheres' silhouettes.
pub const MAGENTA: Rgb<u8> = Rgb([255, 0, 255]);
/// Outlines in the image.
pub const ORANGE: Rgb<u8> = Rgb([255, 150, 0]);
/// Candidates.
pub const CYAN: Rgb<u8> = Rgb([0, 240, 240]);
/// The answer.
pub const WHITE: Rgb<u8> = Rgb([255, 255, 255]);

/// A region of a frame to draw on: frame pixel (u, v) maps to canvas
/// ((u - u0) * scale, (v - v0) * scale).
pub struct Canvas {
    image: RgbImage,
    u0_px: f64,
    v0_px: f64,
    scale: f64,
}

impl Canvas {
    /// The frame's pixels `u0..u0 + width`, `v0..v0 + height` (clamped to the
    /// frame), downscaled to at most `max_width_px` wide.
    pub fn crop(frame: &RgbImage, rect: [u32; 4], max_width_px: u32) -> Self {
        let [u0, v0, width, height] = rect;
        let u0 = u0.min(frame.width().saturating_sub(1));
        let v0 = v0.min(frame.height().saturating_sub(1));
        let width = width.clamp(1, frame.width() - u0);
        let height = height.clamp(1, frame.height() - v0);
        let cut = imageops::crop_imm(frame, u0, v0, width, height).to_image();
        let (image, scale) = if width > max_width_px {
            let scale = f64::from(max_width_px) / f64::from(width);
            let new_height = ((f64::from(height) * scale).round() as u32).max(1);
            (imageops::thumbnail(&cut, max_width_px, new_height), scale)
        } else {
            (cut, 1.0)
        };
        Self { image, u0_px: f64::from(u0), v0_px: f64::from(v0), scale }
    }

    /// The whole frame, downscaled to at most `max_width_px` wide.
    pub fn whole(frame: &RgbImage, max_width_px: u32) -> Self {
        Self::crop(frame, [0, 0, frame.width(), frame.height()], max_width_px)
    }

    /// Canvas pixels per frame pixel.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The canvas position of frame pixel `p`.
    fn at(&self, p: &Point2<f64>) -> (f32, f32) {
        (((p.x - self.u0_px) * self.scale) as f32, ((p.y - self.v0_px) * self.scale) as f32)
    }

    /// A cross of half-size `half_px` (canvas pixels) at frame pixel `p`.
    pub fn cross(&mut self, p: &Point2<f64>, half_px: f32, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        draw_line_segment_mut(&mut self.image, (x - half_px, y), (x + half_px, y), colour);
        draw_line_segment_mut(&mut self.image, (x, y - half_px), (x, y + half_px), colour);
    }

    /// A diagonal cross (an x) of half-size `half_px` at frame pixel `p`.
    pub fn x_mark(&mut self, p: &Point2<f64>, half_px: f32, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        for offset in [-0.5f32, 0.0, 0.5] {
            draw_line_segment_mut(
                &mut self.image,
                (x - half_px + offset, y - half_px),
                (x + half_px + offset, y + half_px),
                colour,
            );
            draw_line_segment_mut(
                &mut self.image,
                (x - half_px + offset, y + half_px),
                (x + half_px + offset, y - half_px),
                colour,
            );
        }
    }

    /// A filled dot of `radius_px` (canvas pixels) at frame pixel `p`.
    pub fn dot(&mut self, p: &Point2<f64>, radius_px: i32, colour: Rgb<u8>) {
        let (x, y) = self.at(p);
        if x.is_finite() && y.is_finite() {
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
        if x.is_finite() && y.is_finite() && r > 0 {
            draw_hollow_circle_mut(
                &mut self.image,
                (x.round() as i32, y.round() as i32),
                r,
                colour,
            );
        }
    }

    /// A polyline through frame pixels, closed if `closed`.
    pub fn polyline(&mut self, points: &[Point2<f64>], closed: bool, colour: Rgb<u8>) {
        let n = points.len();
        let segments = if closed { n } else { n.saturating_sub(1) };
        for i in 0..segments {
            let (a, b) = (self.at(&points[i]), self.at(&points[(i + 1) % n]));
            if a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite() {
                draw_line_segment_mut(&mut self.image, a, b, colour);
            }
        }
    }

    /// Writes the canvas as a JPEG.
    pub fn write_jpeg(&self, path: &Path) -> Result<()> {
        let file = std::fs::File::create(path)
            .map_err(|error| Error::Io { path: path.to_path_buf(), error })?;
        let mut writer = std::io::BufWriter::new(file);
        JpegEncoder::new_with_quality(&mut writer, JPEG_QUALITY)
            .encode_image(&self.image)
            .map_err(|e| Error::Image { path: path.to_path_buf(), message: e.to_string() })
    }
}
