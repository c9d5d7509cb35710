//! A scan's laser points as a point cloud file (docs/FORMATS.md, "Point
//! clouds"): every triangulated stripe point of every frame in the ALACS
//! camera frame, with its frame and whether it is on the fruit, and the
//! fitted centre. Binary PLY (Open3D, CloudCompare, MeshLab, plyfile) or
//! binary PCD v0.7 (PCL, Open3D); written atomically.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::types::Localization;
use crate::{Error, Result};

/// The point cloud formats, by file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloudFormat {
    /// Binary little-endian PLY 1.0 (`.ply`).
    Ply,
    /// Binary PCD v0.7 (`.pcd`).
    Pcd,
}

impl CloudFormat {
    /// The format of `path`'s extension (`.ply`, `.pcd`, any case).
    pub fn from_path(path: &Path) -> Result<Self> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("ply") => Ok(Self::Ply),
            Some("pcd") => Ok(Self::Pcd),
            _ => Err(Error::InvalidInput(format!(
                "{}: a point cloud is written as .ply or .pcd (by its extension)",
                path.display()
            ))),
        }
    }
}

/// One point of the cloud.
struct CloudPoint {
    xyz_mm: [f32; 3],
    frame: u32,
    fruit: u8,
}

fn cloud_points(localization: &Localization) -> Vec<CloudPoint> {
    let mut points = Vec::new();
    for (frame, result) in localization.frames.iter().enumerate() {
        for (stripe_index, p) in &result.points_in_camera {
            points.push(CloudPoint {
                xyz_mm: [p.x as f32, p.y as f32, p.z as f32],
                frame: u32::try_from(frame).unwrap_or(u32::MAX),
                fruit: u8::from(result.fruit.contains(stripe_index)),
            });
        }
    }
    points
}

/// The header comments: units, frame, and the answer.
fn comments(localization: &Localization) -> Vec<String> {
    let mut lines = vec![
        "alacs laser points of one scan".to_string(),
        "units: millimetres; frame: ALACS camera optical frame (x right, y down, z forward)"
            .to_string(),
        "frame: the scan's frame index from 0; fruit: 1 on the fruit, 0 elsewhere".to_string(),
    ];
    match (localization.position_mm, localization.radius_mm) {
        (Some(c), Some(r)) => lines.push(format!(
            "fruit centre mm {:.3} {:.3} {:.3} radius mm {:.3} ({})",
            c.x,
            c.y,
            c.z,
            r,
            localization.method.as_str()
        )),
        _ => lines.push(format!("fruit not found: {}", one_line(&localization.reason))),
    }
    lines
}

/// A header comment stays on its line.
fn one_line(text: &str) -> String {
    text.replace(['\n', '\r'], " ")
}

/// Where `--points FILE` puts the cloud of fruit `k` of a scan naming
/// several: `FILE` with `.targetK` before its extension (`cloud.ply` ->
/// `cloud.target0.ply`, `cloud.target1.ply`, ...).
pub fn target_cloud_path(path: &Path, k: usize) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.target{k}.{}", ext.to_string_lossy()),
        None => format!("{stem}.target{k}"),
    };
    path.with_file_name(name)
}

/// Writes the scan's laser points of `localization` to `path` (.ply or .pcd).
pub fn write_points(path: &Path, localization: &Localization) -> Result<()> {
    let format = CloudFormat::from_path(path)?;
    let points = cloud_points(localization);
    let comments = comments(localization);
    let centre = localization.position_mm.zip(localization.radius_mm);
    alacs_model::io::write_atomic(path, |out| match format {
        CloudFormat::Ply => write_ply(out, &points, &comments, centre),
        CloudFormat::Pcd => write_pcd(out, &points, &comments),
    })?;
    Ok(())
}

/// The points as both formats store them: x y z (f32, little endian),
/// frame (u32), fruit (u8), 17 bytes a point.
fn write_records(out: &mut dyn Write, points: &[CloudPoint]) -> std::io::Result<()> {
    for p in points {
        for c in p.xyz_mm {
            out.write_all(&c.to_le_bytes())?;
        }
        out.write_all(&p.frame.to_le_bytes())?;
        out.write_all(&[p.fruit])?;
    }
    Ok(())
}

fn write_ply(
    out: &mut dyn Write,
    points: &[CloudPoint],
    comments: &[String],
    centre: Option<(nalgebra::Point3<f64>, f64)>,
) -> std::io::Result<()> {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    for line in comments {
        header += &format!("comment {line}\n");
    }
    header += &format!(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uint frame\nproperty uchar fruit\n",
        points.len()
    );
    header += &format!(
        "element fruit_centre {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float radius\nend_header\n",
        usize::from(centre.is_some())
    );
    out.write_all(header.as_bytes())?;
    write_records(out, points)?;
    if let Some((c, r)) = centre {
        for v in [c.x, c.y, c.z, r] {
            out.write_all(&(v as f32).to_le_bytes())?;
        }
    }
    Ok(())
}

fn write_pcd(
    out: &mut dyn Write,
    points: &[CloudPoint],
    comments: &[String],
) -> std::io::Result<()> {
    let mut header = String::from("# .PCD v0.7 - Point Cloud Data file format\n");
    for line in comments {
        header += &format!("# {line}\n");
    }
    header += &format!(
        "VERSION 0.7\nFIELDS x y z frame fruit\nSIZE 4 4 4 4 1\nTYPE F F F U U\n\
         COUNT 1 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n",
        n = points.len()
    );
    out.write_all(header.as_bytes())?;
    write_records(out, points)?;
    Ok(())
}
