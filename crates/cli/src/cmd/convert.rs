//! `alacs convert camera`: a camera file rewritten in the ROS or the OpenCV
//! layout (`alacs_model::Camera` reads every layout it knows and writes
//! both).

use alacs::model::{Camera, CameraFileFormat};
use serde_json::json;

use crate::args::ConvertCameraArgs;
use crate::failure::CmdResult;
use crate::output;

/// Runs `alacs convert camera`.
pub fn camera(args: &ConvertCameraArgs) -> CmdResult {
    let camera = Camera::from_yaml_file(&args.input)?;
    let format = CameraFileFormat::from(args.format);
    camera.to_yaml_file_as(&args.output, format)?;
    let layout = match format {
        CameraFileFormat::Ros => "ros",
        CameraFileFormat::OpenCv => "opencv",
    };
    if args.json {
        output::print_json(&json!({
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "format": layout,
            "width_px": camera.width_px, "height_px": camera.height_px,
            "distortion_model": camera.distortion.ros_model().0,
        }))?;
    }
    errln!(
        "wrote {} ({layout} layout): {} x {} px, {}",
        args.output.display(),
        camera.width_px,
        camera.height_px,
        camera.distortion.ros_model().0
    );
    Ok(())
}
