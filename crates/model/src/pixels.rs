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
    let text = crate::io::read_text(path)?;
    let mut pixels = Vec::new();
    read_numeric_csv(text.as_bytes(), path, &["u_px", "v_px"], &[], |line, values| {
        let (u, v) = (values[0].unwrap_or_default(), values[1].unwrap_or_default());
        if !(u.is_finite() && v.is_finite()) {
            return Err(Error::Csv {
                path: path.to_path_buf(),
                line,
                message: format!("pixel ({u}, {v}) is not finite"),
            });
        }
        pixels.push(Point2::new(u, v));
        Ok(())
    })?;
    Ok(pixels)
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
