//! Reading images with errors that name the file.

use std::path::Path;

use image::{DynamicImage, ImageFormat, RgbImage};

use crate::{Error, Result};

/// The largest image file read: 512 MiB (a 5 MP RGB PNG takes about 15 MB,
/// a 100 MP one 300 MB). The decoder's own allocation limit (the `image`
/// crate's default, 512 MiB) bounds what a small file can ask for.
pub const MAX_IMAGE_FILE_BYTES: u64 = 512 << 20;

/// Opens and decodes an image (PNG or JPEG, by content). A missing,
/// oversized, truncated or non-image file gives [`Error::Image`] naming it:
/// a JPEG must end its last scan with the end-of-image marker (a truncated
/// JPEG otherwise decodes silently, its missing rows grey).
pub fn read_image(path: &Path) -> Result<DynamicImage> {
    let error = |message: String| Error::Image { path: path.to_path_buf(), message };
    let bytes = alacs_model::io::read_bytes_bounded(path, MAX_IMAGE_FILE_BYTES).map_err(|e| {
        error(match e {
            alacs_model::Error::Io { error, .. } => error.to_string(),
            _ => format!(
                "larger than {MAX_IMAGE_FILE_BYTES} bytes, the most alacs reads for an image"
            ),
        })
    })?;
    let format =
        image::guess_format(&bytes).map_err(|_| error("not a PNG or JPEG image".into()))?;
    if !matches!(format, ImageFormat::Png | ImageFormat::Jpeg) {
        return Err(error(format!("a {format:?} image; alacs reads PNG and JPEG")));
    }
    if format == ImageFormat::Jpeg && !jpeg_is_complete(&bytes) {
        return Err(error(
            "truncated JPEG: no end-of-image marker after the last scan (the file was cut short)"
                .into(),
        ));
    }
    image::load_from_memory_with_format(&bytes, format)
        .map_err(|e| error(format!("cannot decode: {e}")))
}

/// Whether a JPEG's last start-of-scan marker (FF DA) is followed by an
/// end-of-image marker (FF D9). Entropy-coded data stuffs every FF byte
/// (FF 00), so an FF D9 after the last scan is the real end; an embedded
/// thumbnail's own end marker comes before the main image's scans.
fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let last_scan = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]);
    let last_end = bytes.windows(2).rposition(|w| w == [0xFF, 0xD9]);
    matches!((last_scan, last_end), (Some(scan), Some(end)) if end > scan)
}

/// [`read_image`] for the laser stripe's colour score, which needs colour:
/// a greyscale image (by its colour type, or RGB with every sampled pixel
/// grey) is refused naming the file, unless `differencing` (a laser-off
/// image is given, and the difference of the red channels needs no colour).
pub fn read_colour_image(path: &Path, differencing: bool) -> Result<RgbImage> {
    let image = read_image(path)?;
    let grey_type = !image.color().has_color();
    let rgb = image.into_rgb8();
    if !differencing && (grey_type || looks_grey(&rgb)) {
        return Err(Error::Image {
            path: path.to_path_buf(),
            message: "a greyscale image: the red laser stripe is found by its colour, so it needs \
                      an RGB image (or a laser-off image of the same view for differencing)"
                .into(),
        });
    }
    Ok(rgb)
}

/// A depth image: a 16-bit greyscale PNG of millimetres, 0 where there is
/// no data (REP 118's 16UC1, as RealSense and most RGB-D drivers save
/// their aligned depth).
pub fn read_depth_png(path: &Path) -> Result<image::ImageBuffer<image::Luma<u16>, Vec<u16>>> {
    match read_image(path)? {
        DynamicImage::ImageLuma16(depth) => Ok(depth),
        other => Err(Error::Image {
            path: path.to_path_buf(),
            message: format!(
                "a {:?} image; a depth image is a 16-bit greyscale PNG of millimetres (0: no data)",
                other.color()
            ),
        }),
    }
}

/// The laser-off image of a frame whose laser image `on` was read from
/// `on_path`: the same size, and in colour when `on` is (the difference of
/// the red channels means nothing between a colour and a grey image).
/// Errors name both files.
pub fn read_laser_off_image(path: &Path, on: &RgbImage, on_path: &Path) -> Result<RgbImage> {
    let image = read_image(path)?;
    let grey = !image.color().has_color();
    let off = image.into_rgb8();
    let error = |message: String| Err(Error::Image { path: path.to_path_buf(), message });
    if off.dimensions() != on.dimensions() {
        return error(format!(
            "the laser-off image is {} x {} px, the laser image {} is {} x {} px",
            off.width(),
            off.height(),
            on_path.display(),
            on.width(),
            on.height()
        ));
    }
    if (grey || looks_grey(&off)) && !looks_grey(on) {
        return error(format!(
            "a greyscale laser-off image for the colour laser image {}: the stripe is the \
             difference of the red channels, so both must be colour (or both grey)",
            on_path.display()
        ));
    }
    Ok(off)
}

/// Whether every sampled pixel (about 10,000 over the image) has R = G = B
/// and some are lit: an all-black RGB frame (the laser met nothing, the
/// exposure was too short) is a frame without a stripe, not a grey image.
fn looks_grey(image: &RgbImage) -> bool {
    let n = image.as_raw().len() / 3;
    let step = (n / 10_000).max(1);
    let mut lit = false;
    let grey = image.as_raw().chunks_exact(3).step_by(step).all(|p| {
        lit |= p[0] > 0;
        p[0] == p[1] && p[1] == p[2]
    });
    grey && lit
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn jpeg(rgb: &RgbImage) -> Vec<u8> {
        let mut bytes = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
            .encode_image(rgb)
            .unwrap();
        bytes
    }

    #[test]
    fn a_truncated_jpeg_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let rgb = RgbImage::from_fn(64, 48, |u, v| image::Rgb([(u * 4) as u8, (v * 5) as u8, 7]));
        let bytes = jpeg(&rgb);
        let whole = dir.path().join("whole.jpg");
        std::fs::write(&whole, &bytes).unwrap();
        assert!(read_image(&whole).is_ok());
        let cut = dir.path().join("cut.jpg");
        std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
        let message = read_image(&cut).unwrap_err().to_string();
        assert!(message.contains("cut.jpg") && message.contains("truncated"), "{message}");
    }

    #[test]
    fn a_grey_frame_is_refused_for_the_colour_score() {
        let dir = tempfile::tempdir().unwrap();
        let grey = image::GrayImage::from_fn(32, 32, |u, _| image::Luma([u as u8 * 8]));
        let path = dir.path().join("grey.png");
        grey.save(&path).unwrap();
        let message = read_colour_image(&path, false).unwrap_err().to_string();
        assert!(message.contains("grey.png") && message.contains("greyscale"), "{message}");
        assert!(read_colour_image(&path, true).is_ok(), "differencing needs no colour");
        let as_rgb = dir.path().join("grey_rgb.png");
        DynamicImage::ImageLuma8(grey).into_rgb8().save(&as_rgb).unwrap();
        assert!(read_colour_image(&as_rgb, false).is_err());
    }

    #[test]
    fn an_all_black_rgb_frame_is_a_frame_without_a_stripe_not_a_grey_image() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame2.png");
        RgbImage::new(64, 48).save(&path).unwrap();
        let image = read_colour_image(&path, false).unwrap();
        assert_eq!(image.dimensions(), (64, 48));
    }

    #[test]
    fn a_greyscale_laser_off_image_for_a_colour_frame_is_refused_naming_both() {
        // Regression: `alacs stripe --laser-off grey.png` on a colour frame
        // subtracted a grey level from the red channel and exited 0.
        let dir = tempfile::tempdir().unwrap();
        let on = RgbImage::from_fn(32, 32, |u, _| image::Rgb([200, u as u8, 10]));
        let on_path = dir.path().join("frame0.png");
        let grey = dir.path().join("grey_off.png");
        image::GrayImage::from_pixel(32, 32, image::Luma([40])).save(&grey).unwrap();
        let message = read_laser_off_image(&grey, &on, &on_path).unwrap_err().to_string();
        assert!(message.contains("grey_off.png") && message.contains("frame0.png"), "{message}");
        let small = dir.path().join("small_off.png");
        RgbImage::from_pixel(16, 32, image::Rgb([9, 8, 7])).save(&small).unwrap();
        let message = read_laser_off_image(&small, &on, &on_path).unwrap_err().to_string();
        assert!(message.contains("small_off.png") && message.contains("16 x 32"), "{message}");
        let colour = dir.path().join("off.png");
        RgbImage::from_pixel(32, 32, image::Rgb([30, 20, 10])).save(&colour).unwrap();
        assert!(read_laser_off_image(&colour, &on, &on_path).is_ok());
        // Both grey: the difference of the channels still works.
        let grey_on = RgbImage::from_pixel(32, 32, image::Rgb([90, 90, 90]));
        assert!(read_laser_off_image(&grey, &grey_on, &on_path).is_ok());
    }
}
