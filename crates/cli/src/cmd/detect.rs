//! `alacs detect`: fruit in an RGB-D camera's colour image, and with its
//! aligned depth and camera their rough 3-D positions.

use alacs::detect::{
    DepthImage, DepthModel, DetectOptions, detect, detections_json, locate_detections,
};
use alacs::model::Camera;
use alacs::vision::{read_colour_image, read_depth_png};

use crate::args::DetectArgs;
use crate::failure::CmdResult;
use crate::output;

/// Runs `alacs detect`.
pub fn run(args: &DetectArgs) -> CmdResult {
    let options = DetectOptions { min_radius_px: args.min_radius_px, ..DetectOptions::default() };
    #[cfg(not(feature = "onnx"))]
    if let Some(model) = &args.model {
        return learned(model).map(|_| ());
    }
    // Every input is read before the work.
    let camera = args.camera.as_deref().map(Camera::from_yaml_file).transpose()?;
    let image = read_colour_image(&args.image, false)?;
    let depth = args.depth.as_deref().map(read_depth_png).transpose()?;
    #[cfg(feature = "onnx")]
    let mut detections = match &args.model {
        Some(model) => learned(model, args, &image)?,
        None => detect(&image, &options)?,
    };
    #[cfg(not(feature = "onnx"))]
    let mut detections = detect(&image, &options)?;
    if let (Some(depth), Some(camera)) = (depth, &camera) {
        let depth = DepthImage::Millimetres(depth);
        locate_detections(&mut detections, &image, &depth, camera, &DepthModel::default())?;
    }
    if args.json {
        return output::print_json(&detections_json(&detections));
    }
    if detections.is_empty() {
        outln!("no fruit in {}", args.image.display());
    }
    for (k, d) in detections.iter().enumerate() {
        let mut line = format!(
            "fruit {}: centre ({:.1}, {:.1}) px, radius {:.1} px, score {:.2}",
            k + 1,
            d.centre_px.x,
            d.centre_px.y,
            d.radius_px,
            d.score
        );
        match &d.rough {
            Some(r) => {
                let p = r.position_mm;
                let sigma = r.position_cov_mm2.symmetric_eigenvalues().max().max(0.0).sqrt();
                line += &format!(
                    "; at ({:.1}, {:.1}, {:.1}) mm in the colour camera's optical frame, radius {:.1} mm, sigma {:.1} mm",
                    p.x, p.y, p.z, r.radius_mm, sigma
                );
            }
            None if camera.is_some() => line += "; no depth on it",
            None => {}
        }
        outln!("{line}");
    }
    Ok(())
}

/// The fruit a YOLO-style ONNX model finds (feature `onnx`).
#[cfg(feature = "onnx")]
fn learned(
    model: &std::path::Path,
    args: &DetectArgs,
    image: &image::RgbImage,
) -> CmdResult<Vec<alacs::detect::Detection>> {
    let options = alacs::detect::OnnxOptions {
        fruit_classes: args.fruit_classes.clone(),
        score_threshold: args.min_score,
        ..alacs::detect::OnnxOptions::new(args.classes.clone())
    };
    let detector = alacs::detect::OnnxDetector::load(model, options)?;
    Ok(detector.detect(image)?)
}

/// Without the feature, --model says how to get it.
#[cfg(not(feature = "onnx"))]
fn learned(model: &std::path::Path) -> CmdResult {
    Err(crate::failure::Failure::bad_input(anyhow::anyhow!(
        "--model {}: this alacs was built without ONNX models; build it with `cargo build --release --features onnx`",
        model.display()
    )))
}
