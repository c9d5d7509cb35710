//! pixels.csv (docs/FORMATS.md): laser pixels `u_px,v_px` to triangulate,
//! and the `triangulate --json` object, `{"points_mm": [[x, y, z] | null]}`.

use std::path::Path;

use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use crate::samples::read_numeric_csv;
use crate::{Error, Result};

/// Reads pixels.csv: header `u_px,v_px` (extra columns ignored), each value
/// a finite number; errors name the file, line and column. Files larger
/// than [`crate::io::MAX_TEXT_INPUT_BYTES`] are refused.
pub fn read_pixels_csv(path: &Path) -> Result<Vec<Point2<f64>>> {
    let mut pixels = Vec::new();
    for_each_pixel(path, |pixel| {
        pixels.push(pixel);
        Ok(())
    })?;
    Ok(pixels)
}

/// [`read_pixels_csv`] one pixel at a time, in the rows' order, without
/// holding the file or its pixels: memory stays the same whatever the
/// file's size. `f` may stop the reading with an error.
pub fn for_each_pixel(path: &Path, mut f: impl FnMut(Point2<f64>) -> Result<()>) -> Result<()> {
    let limit = crate::io::MAX_TEXT_INPUT_BYTES;
    let file = crate::io::open_input(path)?;
    if file.metadata().is_ok_and(|m| m.len() > limit) {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit });
    }
    let reader = std::io::BufReader::new(std::io::Read::take(file, limit + 1));
    read_numeric_csv(reader, path, &["u_px", "v_px"], &[], |line, values| {
        let (u, v) = (values[0].unwrap_or_default(), values[1].unwrap_or_default());
        if !(u.is_finite() && v.is_finite()) {
            return Err(Error::Csv {
                path: path.to_path_buf(),
                line,
                message: format!("pixel ({u}, {v}) is not finite"),
            });
        }
        f(Point2::new(u, v))
    })
}

/// Writes the `triangulate --json` object ([`TriangulateOutput`]) point by
/// point: the same bytes as serializing it whole, followed by a newline,
/// without holding the points.
pub struct TriangulateJsonWriter<W: std::io::Write> {
    out: W,
    first: bool,
}

impl<W: std::io::Write> TriangulateJsonWriter<W> {
    /// Starts the object on `out`.
    pub fn new(mut out: W) -> std::io::Result<Self> {
        out.write_all(b"{\"points_mm\":[")?;
        Ok(Self { out, first: true })
    }

    /// Writes the next point (`None`: `null`).
    pub fn push(&mut self, point: Option<[f64; 3]>) -> std::io::Result<()> {
        if !self.first {
            self.out.write_all(b",")?;
        }
        self.first = false;
        serde_json::to_writer(&mut self.out, &point).map_err(std::io::Error::other)
    }

    /// Ends the object and the line, and flushes.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.out.write_all(b"]}\n")?;
        self.out.flush()
    }
}

/// The `alacs triangulate --json` object: one point per pixel row, in the
/// camera frame (mm), `None` (`null`) where the pixel's ray misses the
/// laser plane or cannot be undistorted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TriangulateOutput {
    /// The points, in the rows' order.
    pub points_mm: Vec<Option<[f64; 3]>>,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_streaming_writer_writes_the_objects_bytes() {
        let points = vec![Some([1.5, -2.0, 1e-7]), None, Some([0.1, 0.2, 830.25])];
        let mut streamed = Vec::new();
        let mut writer = TriangulateJsonWriter::new(&mut streamed).unwrap();
        for p in &points {
            writer.push(*p).unwrap();
        }
        writer.finish().unwrap();
        let whole = serde_json::to_string(&TriangulateOutput { points_mm: points }).unwrap() + "\n";
        assert_eq!(String::from_utf8(streamed).unwrap(), whole);
        let mut empty = Vec::new();
        TriangulateJsonWriter::new(&mut empty).unwrap().finish().unwrap();
        assert_eq!(empty, b"{\"points_mm\":[]}\n");
    }

    #[test]
    fn a_duplicated_column_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pixels.csv");
        std::fs::write(&path, "u_px,v_px,u_px\n1,2,3\n").unwrap();
        let error = read_pixels_csv(&path).unwrap_err().to_string();
        assert!(error.contains("`u_px` appears twice"), "{error}");
        std::fs::write(&path, "# laser pixels\nv_px,u_px,extra\n2,1,x\n4.5,3,\n").unwrap();
        let pixels = read_pixels_csv(&path).unwrap();
        assert_eq!(pixels, vec![Point2::new(1.0, 2.0), Point2::new(3.0, 4.5)]);
        std::fs::write(&path, "u_px,v_px\n1,inf\n").unwrap();
        assert!(read_pixels_csv(&path).unwrap_err().to_string().contains("line 2"));
    }
}
