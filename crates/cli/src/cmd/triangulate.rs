//! `alacs triangulate`: pixels -> normalized (eq. (3)) -> points (eqs. (7)-(8)).
//!
//! Streams: the pixels are read twice (once to check the whole file, so a
//! bad row fails before anything is printed, then to triangulate) and each
//! point is written as it is found, so memory stays the same whatever the
//! file's size.

use std::io::Write as _;

use alacs::model::{TriangulateJsonWriter, for_each_pixel};
use alacs::{Camera, LaserModel};
use anyhow::anyhow;

use crate::args::TriangulateArgs;
use crate::failure::{CmdResult, Failure};

/// Rows without a point named one by one on standard error; the rest are
/// counted.
const MAX_ROW_WARNINGS: u64 = 20;

/// Runs `alacs triangulate`.
pub fn run(args: &TriangulateArgs) -> CmdResult {
    if !args.slide_mm.is_finite() {
        return Err(Failure::bad_input(anyhow!("--slide-mm must be a finite number")));
    }
    let camera = Camera::from_yaml_file(&args.camera)?;
    let laser = LaserModel::from_yaml_file(&args.laser)?;
    // The whole file is checked first: a bad row is an error before any output.
    for_each_pixel(&args.pixels, |_| Ok(()))?;

    let stdout = std::io::stdout().lock();
    let out = std::io::BufWriter::with_capacity(1 << 16, stdout);
    let output_error =
        |e: std::io::Error| Failure::bad_input(anyhow::Error::new(e).context("standard output"));
    let (mut row, mut missed) = (0_u64, 0_u64);
    let mut point_of = |pixel: &nalgebra::Point2<f64>| {
        row += 1;
        let point = camera
            .undistort_pixel(pixel)
            .and_then(|normalized| laser.triangulate(&normalized, args.slide_mm));
        match point {
            Ok(p) => Some([p.x, p.y, p.z]),
            Err(e) => {
                missed += 1;
                if missed <= MAX_ROW_WARNINGS {
                    errln!("warning: {}, row {row}: {e}", args.pixels.display());
                }
                None
            }
        }
    };
    // An error writing standard output ends the reading (kept here, since
    // the reader's own error type cannot carry it).
    let mut write_error = None;
    let mut stop = |e: std::io::Error| {
        write_error = Some(e);
        alacs::model::Error::InvalidParameters { what: "output", message: String::new() }
    };
    let read = if args.json {
        let mut writer = TriangulateJsonWriter::new(out).map_err(output_error)?;
        let read =
            for_each_pixel(&args.pixels, |pixel| writer.push(point_of(&pixel)).map_err(&mut stop));
        if read.is_ok() {
            writer.finish().map_err(output_error)?;
        }
        read
    } else {
        let mut out = out;
        let header = writeln!(out, "u_px,v_px,x_mm,y_mm,z_mm").map_err(output_error);
        header?;
        let read = for_each_pixel(&args.pixels, |pixel| {
            let line = match point_of(&pixel) {
                Some([x, y, z]) => writeln!(out, "{},{},{x:.4},{y:.4},{z:.4}", pixel.x, pixel.y),
                None => writeln!(out, "{},{},,,", pixel.x, pixel.y),
            };
            line.map_err(&mut stop)
        });
        if read.is_ok() {
            out.flush().map_err(output_error)?;
        }
        read
    };
    if let Some(e) = write_error {
        return Err(output_error(e));
    }
    read?;
    if missed > MAX_ROW_WARNINGS {
        errln!(
            "warning: {} more rows of {} gave no point ({missed} of {row} in all)",
            missed - MAX_ROW_WARNINGS,
            args.pixels.display()
        );
    }
    Ok(())
}
