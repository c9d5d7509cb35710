//! scan.yaml (FORMATS.md): the input of fruit localization, the rough fruit
//! position from the RGB-D camera and the frames the active scan took.
//!
//! ```yaml
//! rough_position_mm: [x, y, z]    # camera frame of the ALACS camera
//! fruit_radius_mm: 40.0           # optional prior
//! frames:
//!   - image: frame0.png
//!     slide_mm: 30.0
//!     image_laser_off: frame0_off.png   # optional
//! ```
//!
//! Image paths are relative to the folder that holds scan.yaml. Unknown keys
//! are ignored.

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::Deserialize;

use crate::{Error, Result};

/// The scan file's name inside a scan folder.
pub const SCAN_FILE: &str = "scan.yaml";

/// The radius prior when scan.yaml gives none: the middle of the seed
/// paper's 35-45 mm apples.
pub const DEFAULT_FRUIT_RADIUS_MM: f64 = 40.0;

/// One frame of a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFrameSpec {
    /// The laser-on image, relative to the scan folder as written.
    pub image: PathBuf,
    /// Slide travel d when the frame was taken.
    pub slide_mm: f64,
    /// The same view with the laser off, where the scan has one.
    pub image_laser_off: Option<PathBuf>,
}

/// A scan as read from scan.yaml.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// The folder holding scan.yaml; image paths are relative to it.
    pub dir: PathBuf,
    /// The rough fruit centre in the ALACS camera frame, mm.
    pub rough_position_mm: Point3<f64>,
    /// The fruit radius prior, mm ([`DEFAULT_FRUIT_RADIUS_MM`] when the file gives none).
    pub fruit_radius_mm: f64,
    /// The frames, in file order.
    pub frames: Vec<ScanFrameSpec>,
}

#[derive(Deserialize)]
struct ScanFile {
    rough_position_mm: Vec<f64>,
    #[serde(default)]
    fruit_radius_mm: Option<f64>,
    frames: Vec<FrameFile>,
}

#[derive(Deserialize)]
struct FrameFile {
    image: String,
    slide_mm: f64,
    #[serde(default)]
    image_laser_off: Option<String>,
}

impl Scan {
    /// Reads `dir/scan.yaml`. Checks every value; does not open the images.
    pub fn read(dir: &Path) -> Result<Scan> {
        let path = dir.join(SCAN_FILE);
        let text = std::fs::read_to_string(&path)
            .map_err(|error| Error::Io { path: path.clone(), error })?;
        Self::parse(&text, dir, &path)
    }

    /// Parses scan.yaml text; `dir` is the folder the image paths are
    /// relative to, `path` names the file in errors.
    pub fn parse(text: &str, dir: &Path, path: &Path) -> Result<Scan> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: ScanFile = serde_saphyr::from_str(text)
            .map_err(|e| parse_error(e.without_snippet().to_string()))?;
        let rough_position_mm = match file.rough_position_mm.as_slice() {
            &[x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) && z > 0.0 => {
                Point3::new(x, y, z)
            }
            other => {
                return Err(parse_error(format!(
                    "`rough_position_mm` must be [x, y, z], finite, with z > 0 (in front of the camera), got {other:?}"
                )));
            }
        };
        let fruit_radius_mm = file.fruit_radius_mm.unwrap_or(DEFAULT_FRUIT_RADIUS_MM);
        if !(fruit_radius_mm.is_finite() && fruit_radius_mm > 0.0) {
            return Err(parse_error(format!(
                "`fruit_radius_mm` must be positive and finite, got {fruit_radius_mm}"
            )));
        }
        if file.frames.is_empty() {
            return Err(parse_error("`frames` is empty".into()));
        }
        let mut frames = Vec::with_capacity(file.frames.len());
        for (i, frame) in file.frames.into_iter().enumerate() {
            if frame.image.trim().is_empty() {
                return Err(parse_error(format!("frames[{i}]: `image` is empty")));
            }
            if !frame.slide_mm.is_finite() {
                return Err(parse_error(format!(
                    "frames[{i}] ({}): `slide_mm` is {}; it must be finite",
                    frame.image, frame.slide_mm
                )));
            }
            frames.push(ScanFrameSpec {
                image: PathBuf::from(frame.image),
                slide_mm: frame.slide_mm,
                image_laser_off: frame.image_laser_off.map(PathBuf::from),
            });
        }
        Ok(Scan { dir: dir.to_path_buf(), rough_position_mm, fruit_radius_mm, frames })
    }

    /// The full path of an image named in the scan.
    pub fn path_of(&self, image: &Path) -> PathBuf {
        self.dir.join(image)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(text: &str) -> Result<Scan> {
        Scan::parse(text, Path::new("/data/s"), Path::new("/data/s/scan.yaml"))
    }

    #[test]
    fn reads_the_formats_example() {
        let scan = parse(
            "rough_position_mm: [10, -5, 800]\nfruit_radius_mm: 38.0\nframes:\n  - image: frame0.png\n    slide_mm: 30.0\n  - image: frame1.png\n    slide_mm: 40.0\n    image_laser_off: frame1_off.png\n",
        )
        .unwrap();
        assert_eq!(scan.rough_position_mm, Point3::new(10.0, -5.0, 800.0));
        assert_eq!(scan.fruit_radius_mm, 38.0);
        assert_eq!(scan.frames.len(), 2);
        assert_eq!(scan.frames[1].image_laser_off, Some(PathBuf::from("frame1_off.png")));
        assert_eq!(scan.path_of(&scan.frames[0].image), PathBuf::from("/data/s/frame0.png"));
        let scan =
            parse("rough_position_mm: [0, 0, 700]\nframes: [{image: a.png, slide_mm: 0}]").unwrap();
        assert_eq!(scan.fruit_radius_mm, DEFAULT_FRUIT_RADIUS_MM);
    }

    #[test]
    fn bad_files_name_the_key() {
        for (text, key) in [
            ("rough_position_mm: [1, 2]\nframes: [{image: a, slide_mm: 0}]", "rough_position_mm"),
            (
                "rough_position_mm: [1, 2, -3]\nframes: [{image: a, slide_mm: 0}]",
                "rough_position_mm",
            ),
            (
                "rough_position_mm: [1, 2, 3]\nfruit_radius_mm: 0\nframes: [{image: a, slide_mm: 0}]",
                "fruit_radius_mm",
            ),
            ("rough_position_mm: [1, 2, 3]\nframes: []", "frames"),
            ("rough_position_mm: [1, 2, 3]\nframes: [{image: a, slide_mm: .nan}]", "slide_mm"),
            ("rough_position_mm: [1, 2, 3]\nframes: [{image: a}]", "slide_mm"),
            ("frames: [{image: a, slide_mm: 0}]", "rough_position_mm"),
        ] {
            let message = parse(text).unwrap_err().to_string();
            assert!(message.contains(key), "{message} should name {key}");
            assert!(message.contains("scan.yaml"), "{message}");
        }
    }
}
