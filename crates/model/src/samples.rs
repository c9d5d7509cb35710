//! Calibration samples s_i = [u_n, v_n, z] (seed paper, Section 3.2) and
//! their CSV file (FORMATS.md: `u_n,v_n,z_mm[,slide_mm]`).

use std::path::Path;

use nalgebra::Point2;

use crate::{Error, Result};

/// Largest |u_n| or |v_n| accepted: tan(89.9 deg) is about 573, so no real
/// lens sees beyond this.
const MAX_NORMALIZED: f64 = 1e3;

/// Largest depth accepted: 1 km, far beyond any laser-line sensor's reach.
const MAX_DEPTH_MM: f64 = 1e6;

/// One calibration sample: a laser pixel's normalized, undistorted
/// coordinates, the depth measured for it (from the board pose), and the
/// slide travel when it was taken.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LaserSample {
    /// Normalized x (x/z) of the laser pixel, eq. (1).
    pub u_n: f64,
    /// Normalized y (y/z) of the laser pixel, eq. (1).
    pub v_n: f64,
    /// Measured depth z in the camera frame.
    pub z_mm: f64,
    /// Slide travel d when the sample was taken (L = L0 - d).
    #[serde(default)]
    pub slide_mm: f64,
    /// The board pose the sample was measured on, where known: samples of
    /// one pose share that pose's error, so uncertainties are estimated
    /// over poses, not samples (samples.csv's optional `pose` column).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<u32>,
}

impl LaserSample {
    /// The normalized coordinates as a point.
    pub fn normalized(&self) -> Point2<f64> {
        Point2::new(self.u_n, self.v_n)
    }

    /// The measured 3-D point z (u_n, v_n, 1) in the camera frame.
    pub fn point_in_camera(&self) -> nalgebra::Point3<f64> {
        nalgebra::Point3::new(self.u_n * self.z_mm, self.v_n * self.z_mm, self.z_mm)
    }

    /// What is wrong with the sample, if anything.
    fn problem(&self) -> Option<String> {
        for (name, value) in
            [("u_n", self.u_n), ("v_n", self.v_n), ("z_mm", self.z_mm), ("slide_mm", self.slide_mm)]
        {
            if !value.is_finite() {
                return Some(format!("{name} is {}, not a finite number", crate::Num(value)));
            }
        }
        if self.z_mm <= 0.0 {
            return Some(format!("z_mm is {}, depth must be positive", self.z_mm));
        }
        if self.u_n.abs() > MAX_NORMALIZED || self.v_n.abs() > MAX_NORMALIZED {
            return Some(format!(
                "normalized coordinates ({:e}, {:e}) lie beyond {MAX_NORMALIZED} (a ray more than 89.9 deg off the optical axis): not a camera pixel",
                self.u_n, self.v_n
            ));
        }
        if self.slide_mm.abs() > crate::MAX_ABS_SLIDE_MM {
            return Some(format!(
                "slide_mm is {:e} mm, beyond +-{} mm: no slide travels that far",
                self.slide_mm,
                crate::MAX_ABS_SLIDE_MM
            ));
        }
        (self.z_mm > MAX_DEPTH_MM).then(|| {
            format!("z_mm is {:e} mm, beyond {MAX_DEPTH_MM} mm: not a laser point", self.z_mm)
        })
    }
}

/// Checks every sample for finite values and positive depth.
pub fn validate_samples(samples: &[LaserSample]) -> Result<()> {
    for (index, sample) in samples.iter().enumerate() {
        if let Some(message) = sample.problem() {
            return Err(Error::InvalidSample { index, message });
        }
    }
    Ok(())
}

/// Reads samples.csv: header `u_n,v_n,z_mm`, optional `slide_mm` (missing = 0)
/// and `pose` (a board pose number, 0 or more; missing = unknown), extra
/// columns ignored. Every value must be a finite number and every
/// depth positive; errors name the file, line and column.
/// Files larger than [`crate::io::MAX_TEXT_INPUT_BYTES`] are refused.
pub fn read_samples_csv(path: &Path) -> Result<Vec<LaserSample>> {
    let text = crate::io::read_text(path)?;
    parse_samples_csv(text.as_bytes(), path)
}

/// [`read_samples_csv`] from any reader; `path` names the input in errors.
pub fn parse_samples_csv(reader: impl std::io::Read, path: &Path) -> Result<Vec<LaserSample>> {
    let mut samples = Vec::new();
    let columns = ["slide_mm", "pose"];
    read_numeric_csv(reader, path, &["u_n", "v_n", "z_mm"], &columns, |line, values| {
        let pose = match values[4] {
            None => None,
            Some(p) if p >= 0.0 && p.fract() == 0.0 && p <= f64::from(u32::MAX) => Some(p as u32),
            Some(p) => {
                return Err(csv_error(
                    path,
                    line,
                    format!("column `pose`: `{p}` is not a board pose number (0, 1, 2, ...)"),
                ));
            }
        };
        let sample = LaserSample {
            u_n: values[0].unwrap_or_default(),
            v_n: values[1].unwrap_or_default(),
            z_mm: values[2].unwrap_or_default(),
            slide_mm: values[3].unwrap_or(0.0),
            pose,
        };
        if let Some(message) = sample.problem() {
            return Err(csv_error(path, line, message));
        }
        samples.push(sample);
        Ok(())
    })?;
    if samples.is_empty() {
        return Err(csv_error(path, None, "no samples (the file has a header but no rows)".into()));
    }
    Ok(samples)
}

fn csv_error(path: &Path, line: Option<u64>, message: String) -> Error {
    Error::Csv { path: path.to_path_buf(), line, message }
}

/// Reads a CSV table of numbers, the one reader of samples.csv and
/// pixels.csv: a header naming each column once, `#` comments, values
/// trimmed. `row(line, values)` gets each row's values of the `required`
/// columns, then of the `optional` ones (`None` where the column is absent
/// or the cell empty; a required cell is never `None`); other columns are
/// ignored. Errors name the file, line and column.
pub(crate) fn read_numeric_csv(
    reader: impl std::io::Read,
    path: &Path,
    required: &[&str],
    optional: &[&str],
    mut row: impl FnMut(Option<u64>, &[Option<f64>]) -> Result<()>,
) -> Result<()> {
    let mut reader =
        csv::ReaderBuilder::new().trim(csv::Trim::All).comment(Some(b'#')).from_reader(reader);
    let headers = reader.headers().map_err(|e| csv_error(path, Some(1), e.to_string()))?.clone();
    check_unique_columns(&headers).map_err(|m| csv_error(path, Some(1), m))?;
    let column = |name: &str| headers.iter().position(|h| h == name);
    let mut columns = Vec::with_capacity(required.len() + optional.len());
    for name in required {
        columns.push(Some(column(name).ok_or_else(|| {
            csv_error(
                path,
                Some(1),
                format!(
                    "missing column `{name}` (header must be {}{}; found `{}`)",
                    required.join(","),
                    optional.iter().map(|o| format!("[,{o}]")).collect::<String>(),
                    headers.iter().collect::<Vec<_>>().join(",")
                ),
            )
        })?));
    }
    columns.extend(optional.iter().map(|name| column(name)));
    let names: Vec<&str> = required.iter().chain(optional).copied().collect();
    let mut values = vec![None; columns.len()];
    for record in reader.records() {
        let record =
            record.map_err(|e| csv_error(path, e.position().map(|p| p.line()), e.to_string()))?;
        let line = record.position().map(|p| p.line());
        for (k, index) in columns.iter().enumerate() {
            let text = index.and_then(|i| record.get(i)).unwrap_or("");
            values[k] = if text.is_empty() && k >= required.len() {
                None
            } else {
                Some(text.parse::<f64>().map_err(|_| {
                    csv_error(
                        path,
                        line,
                        format!("column `{}`: `{text}` is not a number", names[k]),
                    )
                })?)
            };
        }
        row(line, &values)?;
    }
    Ok(())
}

/// A header that names a column twice is refused: which of the two is meant
/// cannot be known.
pub(crate) fn check_unique_columns(headers: &csv::StringRecord) -> std::result::Result<(), String> {
    for (i, name) in headers.iter().enumerate() {
        if headers.iter().take(i).any(|earlier| earlier == name) {
            return Err(format!("column `{name}` appears twice in the header"));
        }
    }
    Ok(())
}

/// Writes samples.csv with all four columns, and `pose` where any sample
/// knows its board pose (shortest round-trip floats), atomically.
pub fn write_samples_csv(path: &Path, samples: &[LaserSample]) -> Result<()> {
    crate::io::write_atomic(path, |w| write_samples(w, samples))
}

/// Writes the rows of samples.csv, header first, to `writer`.
pub fn write_samples(
    writer: &mut dyn std::io::Write,
    samples: &[LaserSample],
) -> std::io::Result<()> {
    let with_pose = samples.iter().any(|s| s.pose.is_some());
    writeln!(writer, "u_n,v_n,z_mm,slide_mm{}", if with_pose { ",pose" } else { "" })?;
    for s in samples {
        write!(writer, "{},{},{},{}", s.u_n, s.v_n, s.z_mm, s.slide_mm)?;
        match (with_pose, s.pose) {
            (false, _) => writeln!(writer)?,
            (true, Some(pose)) => writeln!(writer, ",{pose}")?,
            (true, None) => writeln!(writer, ",")?,
        }
    }
    Ok(())
}

/// The text of samples.csv for `samples`.
pub fn samples_csv_string(samples: &[LaserSample]) -> String {
    let mut text = Vec::new();
    // Writing to memory cannot fail.
    let _ = write_samples(&mut text, samples);
    String::from_utf8_lossy(&text).into_owned()
}
