//! `alacs triangulate`: pixels -> normalized (eq. (3)) -> points (eqs. (7)-(8)).

use std::path::Path;

use alacs::{Camera, LaserModel};
use anyhow::anyhow;
use nalgebra::Point2;
use serde_json::{Value, json};

use crate::args::TriangulateArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Reads a pixels CSV (header `u_px,v_px`; extra columns ignored).
fn read_pixels(path: &Path) -> CmdResult<Vec<Point2<f64>>> {
    let bad = |line: Option<u64>, message: String| {
        let at = line.map(|l| format!(", line {l}")).unwrap_or_default();
        Failure::bad_input(anyhow!("{}{at}: {message}", path.display()))
    };
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_path(path)
        .map_err(|e| bad(None, e.to_string()))?;
    let headers = reader.headers().map_err(|e| bad(Some(1), e.to_string()))?.clone();
    let column = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| {
            bad(Some(1), format!("missing column `{name}` (header must be u_px,v_px)"))
        })
    };
    let (i_u, i_v) = (column("u_px")?, column("v_px")?);
    let mut pixels = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| bad(e.position().map(|p| p.line()), e.to_string()))?;
        let line = record.position().map(|p| p.line());
        let value = |i: usize, name: &str| {
            let text = record.get(i).unwrap_or("");
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(bad(line, format!("column `{name}`: `{text}` is not a finite number"))),
            }
        };
        pixels.push(Point2::new(value(i_u, "u_px")?, value(i_v, "v_px")?));
    }
    Ok(pixels)
}

/// Runs `alacs triangulate`.
pub fn run(args: &TriangulateArgs) -> CmdResult {
    if !args.slide_mm.is_finite() {
        return Err(Failure::bad_input(anyhow!("--slide-mm must be a finite number")));
    }
    let camera = Camera::from_yaml_file(&args.camera)?;
    let laser = LaserModel::from_yaml_file(&args.laser)?;
    let pixels = read_pixels(&args.pixels)?;

    let points: Vec<Option<[f64; 3]>> = pixels
        .iter()
        .enumerate()
        .map(|(row, pixel)| {
            let point = camera
                .undistort_pixel(pixel)
                .and_then(|normalized| laser.triangulate(&normalized, args.slide_mm));
            match point {
                Ok(p) => Some([p.x, p.y, p.z]),
                Err(e) => {
                    eprintln!("warning: {}, row {}: {e}", args.pixels.display(), row + 1);
                    None
                }
            }
        })
        .collect();

    if args.json {
        let points: Vec<Value> = points.iter().map(|p| json!(p)).collect();
        output::print_json(&json!({ "points_mm": points }))?;
    } else {
        outln!("u_px,v_px,x_mm,y_mm,z_mm");
        for (pixel, point) in pixels.iter().zip(&points) {
            match point {
                Some([x, y, z]) => outln!("{},{},{x:.4},{y:.4},{z:.4}", pixel.x, pixel.y),
                None => outln!("{},{},,,", pixel.x, pixel.y),
            }
        }
    }
    Ok(())
}
