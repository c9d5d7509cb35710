//! `alacs bag export|import`: recorded scans (ROS 2 bags, MCAP) to and
//! from scan folders, and the scan of a bag for `localize --bag`.

use alacs::Camera;
use alacs::locate::read_scan_images;
use alacs::model::io::OutputDir;
use alacs::model::{Scan, ScanPlan};
use alacs::ros::Frames;
use alacs::ros::bag::{BagWriter, read_scan};
use alacs::scanner::{CapturedFrame, CapturedScan};
use serde_json::json;

use crate::args::{BagExportArgs, BagImportArgs};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs bag export`.
pub fn export(args: &BagExportArgs) -> CmdResult {
    let (scan, summary) = read_scan(&args.bag, args.scan_index)?;
    let mut out = OutputDir::create(&args.out, "bag export", args.folder.force)?;
    scan.write_into(&mut out)?;
    // The recorded CameraInfo: the camera the scan was localized with.
    if let Some(camera) = &summary.camera {
        out.write("camera.yaml", camera.to_yaml_string())?;
    }
    out.finish()?;
    if args.json {
        output::print_json(&json!({
            "bag": args.bag.display().to_string(),
            "scan": args.scan_index,
            "scans": summary.frames_per_scan.len(),
            "frames": scan.frames.len(),
            "out": args.out.display().to_string(),
            "camera": summary.camera.is_some(),
            "messages": summary.messages,
        }))?;
    }
    errln!(
        "wrote scan {} of {} ({} frames{}) to {}",
        args.scan_index,
        args.bag.display(),
        scan.frames.len(),
        if summary.camera.is_some() { ", camera.yaml from its CameraInfo" } else { "" },
        args.out.display()
    );
    Ok(())
}

/// The scan of a folder, its images read, as the scan controller would
/// have captured it.
pub fn captured_from_folder(scan: &Scan) -> CmdResult<CapturedScan> {
    if !scan.more_targets.is_empty() {
        // The action goal, and so a recorded scan, holds one rough position.
        return Err(Failure::bad_input(anyhow::anyhow!(
            "{}: names {} fruit (`targets`); a recording holds one fruit per scan (the goal's rough position)",
            scan.dir.join(alacs::model::SCAN_FILE).display(),
            1 + scan.more_targets.len()
        )));
    }
    let images = read_scan_images(scan, |_, _| {})?;
    let frames: Vec<CapturedFrame> = scan
        .frames
        .iter()
        .zip(images)
        .map(|(spec, (image, image_laser_off))| CapturedFrame {
            planned_slide_mm: spec.planned_slide_mm.unwrap_or(spec.slide_mm),
            slide_mm: spec.slide_mm,
            image,
            image_laser_off: image_laser_off.map(std::sync::Arc::new),
            captured_at: [None, None],
        })
        .collect();
    Ok(CapturedScan {
        rough_position_in_rgbd_mm: scan.rough_position_in_rgbd_mm.unwrap_or(scan.rough_position_mm),
        rough_position_mm: scan.rough_position_mm,
        fruit_radius_mm: scan.fruit_radius_mm,
        more_targets: Vec::new(),
        plan: ScanPlan {
            slides_mm: frames.iter().map(|f| f.planned_slide_mm).collect(),
            unclamped_start_mm: frames.first().map_or(0.0, |f| f.planned_slide_mm),
            shifted: scan.plan_shifted_into_stroke.unwrap_or(false),
        },
        frames,
        exposure: scan.exposure,
        sweep_speed_mm_per_s: scan.sweep_speed_mm_per_s,
    })
}

/// Runs `alacs bag import`.
pub fn import(args: &BagImportArgs) -> CmdResult {
    let scan = Scan::read(&args.scan)?;
    let camera_file = args.camera.clone().or_else(|| {
        let beside = args.scan.join("camera.yaml");
        beside.is_file().then_some(beside)
    });
    let camera = camera_file.as_deref().map(Camera::from_yaml_file).transpose()?;
    let captured = captured_from_folder(&scan)?;
    let mut writer = BagWriter::create(&args.bag, &args.namespace, &Frames::default(), args.force)?;
    writer.write_scan(&captured, camera.as_ref(), None)?;
    writer.finish()?;
    if args.json {
        output::print_json(&json!({
            "bag": args.bag.display().to_string(),
            "frames": captured.frames.len(),
            "images": captured.image_count(),
            "camera": camera_file.map(|p| p.display().to_string()),
        }))?;
    }
    errln!(
        "wrote {} ({} frames, {} images of {})",
        args.bag.display(),
        captured.frames.len(),
        captured.image_count(),
        args.scan.display()
    );
    Ok(())
}
