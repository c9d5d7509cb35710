//! `alacs triangulate`: pixels -> normalized (eq. (3)) -> points (eqs. (7)-(8)).

use alacs::model::{TriangulateOutput, read_pixels_csv};
use alacs::{Camera, LaserModel};
use anyhow::anyhow;

use crate::args::TriangulateArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs triangulate`.
pub fn run(args: &TriangulateArgs) -> CmdResult {
    if !args.slide_mm.is_finite() {
        return Err(Failure::bad_input(anyhow!("--slide-mm must be a finite number")));
    }
    let camera = Camera::from_yaml_file(&args.camera)?;
    let laser = LaserModel::from_yaml_file(&args.laser)?;
    let pixels = read_pixels_csv(&args.pixels)?;

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
                    errln!("warning: {}, row {}: {e}", args.pixels.display(), row + 1);
                    None
                }
            }
        })
        .collect();

    if args.json {
        let value = serde_json::to_value(TriangulateOutput { points_mm: points })
            .map_err(Failure::job_failed)?;
        output::print_json(&value)?;
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
