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
//! Several fruit in one scan: `targets` instead of `rough_position_mm`,
//! each with its `rough_position_mm` and optional `fruit_radius_mm`.
//!
//! Image paths are relative to the folder that holds scan.yaml. Unknown keys
//! are ignored. This module is the one reader and writer of scan.yaml: the
//! scan controller and the simulator write their scan folders with
//! [`Scan::write_yaml`].

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The scan file's name inside a scan folder.
pub const SCAN_FILE: &str = "scan.yaml";

/// The radius prior when scan.yaml gives none: the middle of the seed
/// paper's 35-45 mm apples.
pub const DEFAULT_FRUIT_RADIUS_MM: f64 = 40.0;

/// The fruit radius priors accepted, mm: from a cherry tomato to a large
/// melon. A radius outside is a typing or unit error (metres, or 1e308),
/// not a fruit.
pub const FRUIT_RADIUS_RANGE_MM: (f64, f64) = (2.0, 250.0);

/// The largest |slide_mm| accepted: 10 m, far beyond any slide's stroke
/// (the seed's is 200 mm), so a value beyond it is a unit or typing error.
pub const MAX_ABS_SLIDE_MM: f64 = 10_000.0;

/// The largest distance of a rough position accepted: 100 m, beyond the
/// reach of any RGB-D camera.
pub const MAX_ROUGH_DISTANCE_MM: f64 = 100_000.0;

/// Most fruit one scan.yaml may name in `targets`: a cluster and its
/// neighbours within one 200 mm sweep, with room to spare. Each is
/// localized from every frame.
pub const MAX_SCAN_TARGETS: usize = 16;

/// One fruit a scan looks for: what the RGB-D camera said about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanTarget {
    /// The rough fruit centre in the ALACS camera frame, mm.
    pub rough_position_mm: Point3<f64>,
    /// The fruit radius prior, mm.
    pub fruit_radius_mm: f64,
    /// The rough position as the RGB-D camera gave it, in its own frame
    /// (extra key written by the scan controller).
    pub rough_position_in_rgbd_mm: Option<Point3<f64>>,
}

/// One frame of a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFrameSpec {
    /// The laser-on image, relative to the scan folder as written.
    pub image: PathBuf,
    /// Slide travel d when the frame was taken.
    pub slide_mm: f64,
    /// The same view with the laser off, where the scan has one.
    pub image_laser_off: Option<PathBuf>,
    /// Where the scan plan put the slide (extra key written by the scan
    /// controller; `slide_mm` is where the slide settled).
    pub planned_slide_mm: Option<f64>,
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
    /// The rough position as the RGB-D camera gave it, in its own frame
    /// (extra key written by the scan controller).
    pub rough_position_in_rgbd_mm: Option<Point3<f64>>,
    /// The fruit after the first when scan.yaml names several (`targets`);
    /// the first is `rough_position_mm`, `fruit_radius_mm` and
    /// `rough_position_in_rgbd_mm` above. Empty for a scan of one fruit.
    pub more_targets: Vec<ScanTarget>,
    /// Whether the scan plan was shifted to fit the slide's stroke (extra
    /// key written by the scan controller and the simulator).
    pub plan_shifted_into_stroke: Option<bool>,
    /// The camera's exposure time and gain over the frames, when the
    /// writer knew them (extra keys `exposure_us`, `gain_db` written by the
    /// scan controller after metering).
    pub exposure: Option<FrameExposure>,
    /// The speed of a continuous sweep, mm/s (extra key written by the scan
    /// controller): the frames were taken with the slide moving, each at
    /// the slide's position at mid-exposure. `None`: the slide stood still
    /// for every frame (stop-and-go), or the writer does not say.
    pub sweep_speed_mm_per_s: Option<f64>,
}

/// The exposure the frames of a scan were taken at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameExposure {
    /// Exposure time, microseconds.
    pub exposure_us: f64,
    /// Analogue gain, dB.
    pub gain_db: f64,
}

/// Longest exposure time scan.yaml may name, microseconds (10 s).
const MAX_EXPOSURE_US: f64 = 10.0e6;

/// Fastest sweep scan.yaml may name, mm/s (a slide's stroke in 20 ms).
const MAX_SWEEP_SPEED_MM_PER_S: f64 = 10_000.0;

/// Largest gain scan.yaml may name, dB.
const MAX_GAIN_DB: f64 = 60.0;

#[derive(Deserialize, Serialize)]
struct ScanFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rough_position_mm: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rough_position_in_rgbd_mm: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fruit_radius_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    targets: Option<Vec<TargetFile>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    plan_shifted_into_stroke: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    exposure_us: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gain_db: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sweep_speed_mm_per_s: Option<f64>,
    frames: Vec<FrameFile>,
}

#[derive(Deserialize, Serialize)]
struct TargetFile {
    rough_position_mm: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fruit_radius_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rough_position_in_rgbd_mm: Option<Vec<f64>>,
}

impl TargetFile {
    fn of(target: &ScanTarget) -> Self {
        TargetFile {
            rough_position_mm: xyz(&target.rough_position_mm),
            fruit_radius_mm: Some(target.fruit_radius_mm),
            rough_position_in_rgbd_mm: target.rough_position_in_rgbd_mm.as_ref().map(xyz),
        }
    }
}

#[derive(Deserialize, Serialize)]
struct FrameFile {
    image: String,
    slide_mm: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    image_laser_off: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    planned_slide_mm: Option<f64>,
}

fn xyz(p: &Point3<f64>) -> Vec<f64> {
    vec![p.x, p.y, p.z]
}

/// A rough position as every reader of a scan holds it (scan.yaml, a bag's
/// goal): `[x, y, z]` in mm, each within [`MAX_ROUGH_DISTANCE_MM`], and in
/// front of the camera (`z > 0`) where `in_front` (the ALACS camera's frame;
/// the RGB-D camera's may differ). The error completes "`key` ...".
pub fn checked_rough_position_mm(
    values: &[f64],
    in_front: bool,
) -> std::result::Result<Point3<f64>, String> {
    match *values {
        [x, y, z]
            if [x, y, z].iter().all(|c| c.abs() <= MAX_ROUGH_DISTANCE_MM)
                && (z > 0.0 || !in_front) =>
        {
            Ok(Point3::new(x, y, z))
        }
        _ => Err(format!(
            "must be [x, y, z] in mm, each within +-{MAX_ROUGH_DISTANCE_MM} mm{}, got [{}]",
            if in_front { ", with z > 0 (in front of the camera)" } else { "" },
            values.iter().map(|v| crate::Num(*v).to_string()).collect::<Vec<_>>().join(", "),
        )),
    }
}

/// A fruit radius prior as every reader of a scan holds it: within
/// [`FRUIT_RADIUS_RANGE_MM`]. The error completes "`key` ...".
pub fn checked_fruit_radius_mm(radius_mm: f64) -> std::result::Result<f64, String> {
    let (low, high) = FRUIT_RADIUS_RANGE_MM;
    if (low..=high).contains(&radius_mm) {
        Ok(radius_mm)
    } else {
        Err(format!(
            "is {} mm; a fruit radius prior must lie within {low}-{high} mm",
            crate::Num(radius_mm)
        ))
    }
}

impl Scan {
    /// Reads `dir/scan.yaml`. Checks every value; does not open the images.
    pub fn read(dir: &Path) -> Result<Scan> {
        let path = dir.join(SCAN_FILE);
        let text = crate::io::read_text(&path)?;
        Self::parse(&text, dir, &path)
    }

    /// scan.yaml's text for this scan, after `header` (comment lines
    /// without the `#`, may be empty).
    pub fn to_yaml_string(&self, header: &str) -> String {
        // One fruit keeps the original form; several are a `targets` list.
        let (first, targets) = if self.more_targets.is_empty() {
            (Some(TargetFile::of(&self.target())), None)
        } else {
            (None, Some(self.targets().iter().map(TargetFile::of).collect()))
        };
        let file = ScanFile {
            rough_position_mm: first.as_ref().map(|t| t.rough_position_mm.clone()),
            rough_position_in_rgbd_mm: first
                .as_ref()
                .and_then(|t| t.rough_position_in_rgbd_mm.clone()),
            fruit_radius_mm: first.as_ref().and_then(|t| t.fruit_radius_mm),
            targets,
            plan_shifted_into_stroke: self.plan_shifted_into_stroke,
            exposure_us: self.exposure.map(|e| e.exposure_us),
            gain_db: self.exposure.map(|e| e.gain_db),
            sweep_speed_mm_per_s: self.sweep_speed_mm_per_s,
            frames: self
                .frames
                .iter()
                .map(|f| FrameFile {
                    image: f.image.to_string_lossy().into_owned(),
                    slide_mm: f.slide_mm,
                    image_laser_off: f
                        .image_laser_off
                        .as_ref()
                        .map(|p| p.to_string_lossy().into_owned()),
                    planned_slide_mm: f.planned_slide_mm,
                })
                .collect(),
        };
        let mut text: String = header.lines().map(|l| format!("# {l}\n")).collect();
        // Serializing plain strings, numbers and lists cannot fail.
        text.push_str(&serde_saphyr::to_string(&file).unwrap_or_default());
        text
    }

    /// Writes `dir/scan.yaml` atomically ([`crate::io::write_file`]).
    pub fn write_yaml(&self, header: &str) -> Result<PathBuf> {
        let path = self.dir.join(SCAN_FILE);
        crate::io::write_file(&path, self.to_yaml_string(header))?;
        Ok(path)
    }

    /// Parses scan.yaml text; `dir` is the folder the image paths are
    /// relative to, `path` names the file in errors.
    pub fn parse(text: &str, dir: &Path, path: &Path) -> Result<Scan> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: ScanFile = serde_saphyr::from_str(text)
            .map_err(|e| parse_error(crate::error::yaml_message(&e)))?;
        let point = |key: &str, values: &[f64], in_front: bool| {
            checked_rough_position_mm(values, in_front)
                .map_err(|e| parse_error(format!("`{key}` {e}")))
        };
        let radius = |key: &str, value: Option<f64>| {
            checked_fruit_radius_mm(value.unwrap_or(DEFAULT_FRUIT_RADIUS_MM))
                .map_err(|e| parse_error(format!("`{key}` {e}")))
        };
        let top_radius_mm = radius("fruit_radius_mm", file.fruit_radius_mm)?;
        let target = |key: &str, t: &TargetFile, default_radius_mm: f64| {
            Ok(ScanTarget {
                rough_position_mm: point(
                    &format!("{key}rough_position_mm"),
                    &t.rough_position_mm,
                    true,
                )?,
                fruit_radius_mm: match t.fruit_radius_mm {
                    Some(r) => radius(&format!("{key}fruit_radius_mm"), Some(r))?,
                    None => default_radius_mm,
                },
                rough_position_in_rgbd_mm: t
                    .rough_position_in_rgbd_mm
                    .as_deref()
                    .map(|v| point(&format!("{key}rough_position_in_rgbd_mm"), v, false))
                    .transpose()?,
            })
        };
        let mut targets = match (file.rough_position_mm, file.targets) {
            (Some(_), Some(_)) => {
                return Err(parse_error(
                    "both `rough_position_mm` and `targets`: one fruit or a list, not both".into(),
                ));
            }
            (None, None) => {
                return Err(parse_error(
                    "no `rough_position_mm` (or `targets`, a list of fruit): where is the fruit?"
                        .into(),
                ));
            }
            (Some(rough_position_mm), None) => {
                let first = TargetFile {
                    rough_position_mm,
                    fruit_radius_mm: None,
                    rough_position_in_rgbd_mm: file.rough_position_in_rgbd_mm,
                };
                vec![target("", &first, top_radius_mm)?]
            }
            (None, Some(list)) => {
                if list.is_empty() || list.len() > MAX_SCAN_TARGETS {
                    return Err(parse_error(format!(
                        "`targets` names {} fruit; a scan has 1-{MAX_SCAN_TARGETS}",
                        list.len()
                    )));
                }
                if file.rough_position_in_rgbd_mm.is_some() {
                    return Err(parse_error(
                        "`rough_position_in_rgbd_mm` belongs in each of `targets`".into(),
                    ));
                }
                list.iter()
                    .enumerate()
                    .map(|(k, t)| target(&format!("targets[{k}]."), t, top_radius_mm))
                    .collect::<Result<Vec<_>>>()?
            }
        };
        let first = targets.remove(0);
        let exposure = match (file.exposure_us, file.gain_db) {
            (None, None) => None,
            (None, Some(_)) => {
                return Err(parse_error("`gain_db` is given without `exposure_us`".into()));
            }
            (Some(exposure_us), gain_db) => {
                let gain_db = gain_db.unwrap_or(0.0);
                if !(exposure_us.is_finite() && exposure_us > 0.0 && exposure_us <= MAX_EXPOSURE_US)
                {
                    return Err(parse_error(format!(
                        "`exposure_us` is {exposure_us}; it must lie within 0-{MAX_EXPOSURE_US} us"
                    )));
                }
                if !(gain_db.is_finite() && (0.0..=MAX_GAIN_DB).contains(&gain_db)) {
                    return Err(parse_error(format!(
                        "`gain_db` is {gain_db}; it must lie within 0-{MAX_GAIN_DB} dB"
                    )));
                }
                Some(FrameExposure { exposure_us, gain_db })
            }
        };
        let sweep_speed_mm_per_s = file.sweep_speed_mm_per_s;
        if let Some(speed) = sweep_speed_mm_per_s
            && !(speed.is_finite() && speed > 0.0 && speed <= MAX_SWEEP_SPEED_MM_PER_S)
        {
            return Err(parse_error(format!(
                "`sweep_speed_mm_per_s` is {speed}; it must lie within 0-{MAX_SWEEP_SPEED_MM_PER_S} mm/s"
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
            for (key, value) in
                [("slide_mm", Some(frame.slide_mm)), ("planned_slide_mm", frame.planned_slide_mm)]
            {
                if let Some(value) = value.filter(|v| !v.is_finite() || v.abs() > MAX_ABS_SLIDE_MM)
                {
                    return Err(parse_error(format!(
                        "frames[{i}] ({}): `{key}` is {}; it must be finite and within +-{MAX_ABS_SLIDE_MM} mm",
                        frame.image,
                        crate::Num(value)
                    )));
                }
            }
            frames.push(ScanFrameSpec {
                image: PathBuf::from(frame.image),
                slide_mm: frame.slide_mm,
                image_laser_off: frame.image_laser_off.map(PathBuf::from),
                planned_slide_mm: frame.planned_slide_mm,
            });
        }
        Ok(Scan {
            dir: dir.to_path_buf(),
            rough_position_mm: first.rough_position_mm,
            fruit_radius_mm: first.fruit_radius_mm,
            frames,
            rough_position_in_rgbd_mm: first.rough_position_in_rgbd_mm,
            more_targets: targets,
            plan_shifted_into_stroke: file.plan_shifted_into_stroke,
            sweep_speed_mm_per_s,
            exposure,
        })
    }

    /// The first fruit (the only one of a scan of one fruit).
    pub fn target(&self) -> ScanTarget {
        ScanTarget {
            rough_position_mm: self.rough_position_mm,
            fruit_radius_mm: self.fruit_radius_mm,
            rough_position_in_rgbd_mm: self.rough_position_in_rgbd_mm,
        }
    }

    /// Every fruit the scan looks for, in scan.yaml's order.
    pub fn targets(&self) -> Vec<ScanTarget> {
        std::iter::once(self.target()).chain(self.more_targets.iter().copied()).collect()
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
    fn scan_yaml_round_trips_through_its_writer() {
        let mut scan = parse(
            "rough_position_mm: [10, -5, 800]\nframes:\n  - image: 'a b: \"c\".png'\n    slide_mm: 30.25\n    image_laser_off: off.png\n",
        )
        .unwrap();
        scan.frames[0].planned_slide_mm = Some(30.0);
        scan.rough_position_in_rgbd_mm = Some(Point3::new(1.5, -2.0, 3.0));
        scan.plan_shifted_into_stroke = Some(true);
        let text = scan.to_yaml_string("written by a test\nsecond line");
        assert!(text.starts_with("# written by a test\n# second line\n"), "{text}");
        assert_eq!(parse(&text).unwrap(), scan);
    }

    #[test]
    fn a_scan_of_several_fruit_reads_and_round_trips() {
        let text = "fruit_radius_mm: 35\ntargets:\n  - rough_position_mm: [10, -5, 800]\n  - rough_position_mm: [90, 0, 820]\n    fruit_radius_mm: 42\nframes: [{image: a.png, slide_mm: 0}]\n";
        let scan = parse(text).unwrap();
        assert_eq!(scan.rough_position_mm, Point3::new(10.0, -5.0, 800.0));
        assert_eq!(scan.fruit_radius_mm, 35.0, "the top-level prior is each target's default");
        let targets = scan.targets();
        assert_eq!(targets.len(), 2);
        assert_eq!(targets[1].rough_position_mm, Point3::new(90.0, 0.0, 820.0));
        assert_eq!(targets[1].fruit_radius_mm, 42.0);
        let written = scan.to_yaml_string("");
        assert!(
            written.contains("targets:") && !written.contains("\nrough_position_mm"),
            "{written}"
        );
        assert_eq!(parse(&written).unwrap(), scan);
        // One fruit is written in the original form.
        let one = parse("rough_position_mm: [1, 2, 3]\nframes: [{image: a, slide_mm: 0}]").unwrap();
        assert!(!one.to_yaml_string("").contains("targets"));
        assert_eq!(one.targets(), vec![one.target()]);
    }

    #[test]
    fn bad_target_lists_are_refused_naming_the_key() {
        let frames = "frames: [{image: a, slide_mm: 0}]";
        let many: String = (0..=MAX_SCAN_TARGETS)
            .map(|k| format!("  - rough_position_mm: [{k}, 0, 800]\n"))
            .collect();
        for (text, key) in [
            (
                format!(
                    "rough_position_mm: [1, 2, 3]\ntargets: [{{rough_position_mm: [1, 2, 3]}}]\n{frames}"
                ),
                "targets",
            ),
            (format!("targets: []\n{frames}"), "targets"),
            (format!("targets:\n{many}{frames}"), "17 fruit"),
            (
                format!(
                    "targets: [{{rough_position_mm: [1, 2, 3]}}, {{rough_position_mm: [1, 2, -3]}}]\n{frames}"
                ),
                "targets[1].rough_position_mm",
            ),
            (
                format!(
                    "targets: [{{rough_position_mm: [1, 2, 3], fruit_radius_mm: 900}}]\n{frames}"
                ),
                "targets[0].fruit_radius_mm",
            ),
            (
                format!(
                    "rough_position_in_rgbd_mm: [1, 2, 3]\ntargets: [{{rough_position_mm: [1, 2, 3]}}]\n{frames}"
                ),
                "rough_position_in_rgbd_mm",
            ),
        ] {
            let message = parse(&text).unwrap_err().to_string();
            assert!(message.contains(key), "{message} should name {key}");
        }
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
            // Regression: 1e308 was accepted and the reason then said
            // "fewer than 18446744073709551615".
            (
                "rough_position_mm: [1, 2, 3]\nfruit_radius_mm: 1e308\nframes: [{image: a, slide_mm: 0}]",
                "fruit_radius_mm",
            ),
            ("rough_position_mm: [1, 2, 3]\nframes: [{image: a, slide_mm: 1e9}]", "slide_mm"),
            (
                "rough_position_mm: [1, 2, 1e12]\nframes: [{image: a, slide_mm: 0}]",
                "rough_position_mm",
            ),
            ("frames: [{image: a, slide_mm: 0}]", "rough_position_mm"),
        ] {
            let message = parse(text).unwrap_err().to_string();
            assert!(message.contains(key), "{message} should name {key}");
            assert!(message.contains("scan.yaml"), "{message}");
        }
    }
}
