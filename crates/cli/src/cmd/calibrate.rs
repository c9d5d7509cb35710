//! `alacs calibrate laser` and `alacs calibrate camera`.

use std::path::Path;

use alacs::calib::{
    CalibrationOptions, FixedIntrinsics, IntrinsicsOptions, LaserSessionOptions, Method, Residual,
    calibrate_camera_session, calibrate_laser_session, read_samples_csv, write_samples_csv,
};
use alacs::model::{DistortionModel, PlusMinus};
use alacs::{Camera, Session};
use anyhow::anyhow;
use serde_json::json;

use crate::args::{
    CalibrateCameraArgs, CalibrateLaserArgs, CalibrateRgbdArgs, CameraControlArgs, DistortionArg,
    FixArg, ResidualArg,
};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Validated options from the command line.
fn options(args: &CalibrateLaserArgs) -> CmdResult<CalibrationOptions> {
    if !(args.threshold_mm > 0.0 && args.threshold_mm.is_finite()) {
        return Err(Failure::bad_input(anyhow!(
            "--threshold-mm must be a positive number of mm, got {}",
            args.threshold_mm
        )));
    }
    if args.max_iterations == 0 {
        return Err(Failure::bad_input(anyhow!("--max-iterations must be at least 1")));
    }
    Ok(CalibrationOptions {
        residual: match args.residual {
            ResidualArg::Depth => Residual::Depth,
            ResidualArg::Plane => Residual::PlaneDistance,
        },
        threshold_mm: args.threshold_mm,
        max_iterations: args.max_iterations,
        seed: args.seed,
        fit_slide_scale: !args.hold_slide_scale,
        ..CalibrationOptions::default()
    })
}

/// Runs `alacs calibrate laser`.
pub fn laser(args: &CalibrateLaserArgs) -> CmdResult {
    let options = options(args)?;
    let method = Method::from_number(args.method)
        .ok_or_else(|| Failure::bad_input(anyhow!("--method must be 1, 2, 3 or 4")))?;
    let (samples, session_fit, source) = match (&args.samples, &args.session, &args.camera) {
        (Some(path), _, _) => (read_samples_csv(path)?, None, path.display().to_string()),
        (None, Some(dir), Some(camera)) => {
            let (samples, fit) = session_samples(args, dir, camera, &options)?;
            (samples, Some(fit), dir.display().to_string())
        }
        _ => {
            return Err(Failure::bad_input(anyhow!(
                "give --samples FILE or --session DIR --camera FILE"
            )));
        }
    };
    let context = |e: alacs::calib::Error| {
        let code = Failure::from(e);
        Failure { error: code.error.context(source.clone()), ..code }
    };

    // A session's calibration of --method is the one with the session's
    // uncertainties (its camera and board poses); --compare adds the others.
    // --compare: one method that cannot fit is a row with its reason; the
    // chosen method must fit.
    let (chosen, results, failed) = match (args.compare, session_fit) {
        (true, session_fit) => {
            let alacs::Comparison { fitted: mut results, failed } =
                alacs::compare(&samples, &options).map_err(context)?;
            let Some(chosen) = results.iter().position(|c| c.method == method) else {
                let reason = failed
                    .iter()
                    .find(|(m, _)| *m == method)
                    .map_or_else(String::new, |(_, r)| r.clone());
                return Err(Failure::job_failed(anyhow!(
                    "{source}: Method {} cannot fit the samples: {reason}",
                    method.number()
                )));
            };
            if let Some(fit) = session_fit {
                results[chosen] = fit;
            }
            (chosen, results, failed)
        }
        (false, Some(fit)) => (0, vec![fit], Vec::new()),
        (false, None) => {
            (0, vec![alacs::calibrate(&samples, method, &options).map_err(context)?], Vec::new())
        }
    };
    let fit = &results[chosen];

    if let Some(path) = &args.output {
        let header = format!(
            "laser-camera extrinsics by alacs {}: method {} ({}), {} of {} samples from {}, mean |z - z_hat| {:.3} mm",
            env!("CARGO_PKG_VERSION"),
            fit.method.number(),
            fit.method.name(),
            fit.inliers.len(),
            fit.n_samples,
            source,
            fit.mean_abs_error_mm
        ) + if fit.slide_scale_fitted {
            ""
        } else {
            "; slide_scale is held, not fitted (samples at one slide position, or --hold-slide-scale)"
        };
        let std = fit.std_dev.as_ref().map(|s| s.to_laser_std());
        fit.laser.to_yaml_file(path, &header, std.as_ref())?;
    }

    if args.json {
        let value = if args.compare {
            json!({
                "methods": results.iter().map(output::calibration_json).collect::<Vec<_>>(),
                "failed": alacs::eval::failed_json(&failed),
            })
        } else {
            output::calibration_json(fit)
        };
        output::print_json(&value)?;
    } else {
        if args.compare {
            out!("{}", output::table_1(&results, &failed));
            outln!();
        }
        out!("{}", output::summary(fit));
    }
    if let Some(path) = &args.output {
        errln!("wrote {}", path.display());
    }
    Ok(())
}

/// The dense laser samples of a session and its calibration by `--method`
/// (with the quality gate's warnings on standard error), the samples
/// exported where asked.
fn session_samples(
    args: &CalibrateLaserArgs,
    dir: &Path,
    camera_path: &Path,
    calibration: &CalibrationOptions,
) -> CmdResult<(Vec<alacs::LaserSample>, alacs::LaserCalibration)> {
    let session = Session::read(dir)?;
    let camera = Camera::from_yaml_file(camera_path)?;
    let method = Method::from_number(args.method).unwrap_or(Method::HighFidelityRansac);
    let options = LaserSessionOptions {
        calibration: *calibration,
        method: Some(method),
        camera_uncertainty: !args.camera_exact,
        ..LaserSessionOptions::default()
    };
    let bar = output::progress_bar(args.json, "laser samples");
    output::start_progress(&bar, session.views.len(), "views: board pose and laser stripe");
    let result = calibrate_laser_session(&session, &camera, &options, &|| bar.inc(1));
    bar.finish_and_clear();
    let result = result.map_err(|e| {
        let code = Failure::from(e);
        Failure { error: code.error.context(dir.display().to_string()), ..code }
    })?;
    for view in &result.views {
        match &view.rejected {
            Some(reason) => errln!("warning: {}: not used: {reason}", view.image),
            None if !args.json => errln!(
                "{}: slide {:.1} mm, {} samples, board pose RMS {:.3} px",
                view.image,
                view.slide_mm,
                view.n_samples,
                view.pose_rms_px.unwrap_or(f64::NAN)
            ),
            None => {}
        }
    }
    for warning in &result.warnings {
        errln!("warning: {warning}");
    }
    if let Some(path) = &args.export_samples {
        write_samples_csv(path, &result.samples)?;
        errln!("wrote {} ({} samples)", path.display(), result.samples.len());
    }
    Ok((result.samples, result.calibration))
}

/// The camera calibration's controls from the command line.
pub(crate) fn intrinsics_options(args: &CameraControlArgs) -> CmdResult<IntrinsicsOptions> {
    let initial = args.initial.as_deref().map(Camera::from_yaml_file).transpose()?;
    let distortion = match (args.distortion, &initial) {
        (Some(DistortionArg::PlumbBob), _) => DistortionModel::PlumbBob,
        (Some(DistortionArg::RationalPolynomial), _) => DistortionModel::RationalPolynomial,
        (None, Some(camera)) => camera.distortion.model(),
        (None, None) => DistortionModel::PlumbBob,
    };
    let fixed = FixedIntrinsics {
        k3: args.fix.contains(&FixArg::K3),
        tangential: args.fix.contains(&FixArg::Tangential),
        aspect: args.fix.contains(&FixArg::Aspect),
        principal_point: args.fix.contains(&FixArg::PrincipalPoint),
    };
    Ok(IntrinsicsOptions { distortion, fixed, initial, ..IntrinsicsOptions::default() })
}

/// The held intrinsics' names, as `--fix` takes them.
fn fixed_names(fixed: &FixedIntrinsics) -> Vec<&'static str> {
    [
        (fixed.k3, "k3"),
        (fixed.tangential, "tangential"),
        (fixed.aspect, "aspect"),
        (fixed.principal_point, "principal-point"),
    ]
    .into_iter()
    .filter_map(|(held, name)| held.then_some(name))
    .collect()
}

/// Runs `alacs calibrate camera`.
pub fn camera(args: &CalibrateCameraArgs) -> CmdResult {
    let session = Session::read(&args.session)?;
    let options = intrinsics_options(&args.controls)?;
    let bar = output::progress_bar(args.json, "board corners");
    output::start_progress(&bar, session.views.len(), "views: board corners");
    let fit = calibrate_camera_session(&session, &options, &|| bar.inc(1));
    bar.finish_and_clear();
    let mut fit = fit.map_err(|e| {
        let code = Failure::from(e);
        Failure { error: code.error.context(args.session.display().to_string()), ..code }
    })?;
    fit.camera.name = session
        .dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "camera".into());
    let rejected: Vec<&str> =
        fit.views.iter().filter(|v| v.rejected.is_some()).map(|v| v.name.as_str()).collect();
    if let Some(path) = &args.output {
        fit.camera.to_yaml_file_as(path, args.format.into())?;
    }
    let c = &fit.camera;
    let (model, dist) = c.distortion.ros_model();
    if args.json {
        output::print_json(&json!({
            "fx_px": c.fx_px, "fy_px": c.fy_px, "cx_px": c.cx_px, "cy_px": c.cy_px,
            "distortion_model": model, "dist": dist,
            "rms_px": fit.rms_px, "views_used": fit.views_used(), "views_rejected": rejected,
            "board_poses": fit.views_used(), "images": fit.images,
            "width_px": c.width_px, "height_px": c.height_px,
            "fx_std_px": fit.std_dev.as_ref().map(|s| s[0]), "fy_std_px": fit.std_dev.as_ref().map(|s| s[1]),
            "cx_std_px": fit.std_dev.as_ref().map(|s| s[2]), "cy_std_px": fit.std_dev.as_ref().map(|s| s[3]),
            "dist_std": fit.std_dev.as_ref().map(|s| s[4..].to_vec()),
            "fixed": fixed_names(&options.fixed),
            "views": fit.views.iter().map(|v| json!({
                "image": v.name, "rms_px": v.rms_px, "rejected": v.rejected,
            })).collect::<Vec<_>>(),
        }))?;
    } else {
        let held = [
            false,
            options.fixed.aspect,
            options.fixed.principal_point,
            options.fixed.principal_point,
        ];
        // Each intrinsic with its sigma to two significant figures (PlusMinus).
        let value = |i: usize, px: f64| {
            if i == 1 && held[1] {
                return format!("{px:.2} (fx x {:.5}: aspect held)", c.fy_px / c.fx_px);
            }
            if held[i] {
                return format!("{px:.2} (held)");
            }
            let sigma = fit.std_dev.as_ref().map(|s| s[i]);
            PlusMinus { value: px, sigma, decimals: 2 }.to_string()
        };
        outln!(
            "camera {} x {} px from {} board poses ({} images; views rejected: {})",
            c.width_px,
            c.height_px,
            fit.views_used(),
            fit.images,
            rejected.len()
        );
        outln!("  fx {} px, fy {} px", value(0, c.fx_px), value(1, c.fy_px));
        outln!("  cx {} px, cy {} px", value(2, c.cx_px), value(3, c.cy_px));
        outln!("  {model} {:?}", dist.iter().map(|d| (d * 1e5).round() / 1e5).collect::<Vec<_>>());
        let fixed = fixed_names(&options.fixed);
        if !fixed.is_empty() {
            outln!("  held: {}", fixed.join(", "));
        }
        outln!("  reprojection RMS {:.3} px", fit.rms_px);
        for view in &fit.views {
            let rms = view.rms_px.map(|r| format!("{r:.3} px")).unwrap_or_else(|| "-".into());
            match &view.rejected {
                None => outln!("  {:<24} {rms}", view.name),
                Some(reason) => outln!("  {:<24} {rms} rejected: {reason}", view.name),
            }
        }
    }
    if let Some(path) = &args.output {
        errln!("wrote {}", path.display());
    }
    Ok(())
}

/// Runs `alacs calibrate rgbd`.
pub fn rgbd(args: &CalibrateRgbdArgs) -> CmdResult {
    let session = Session::read(&args.session)?;
    let camera = Camera::from_yaml_file(&args.camera)?;
    let rgbd_camera = Camera::from_yaml_file(&args.rgbd_camera)?;
    let bar = output::progress_bar(args.json, "finding the board in both cameras' images");
    let result = alacs::calib::calibrate_rgbd(&session, &camera, &rgbd_camera);
    bar.finish_and_clear();
    let result = result.map_err(|e| Failure::from(e).with_context(&args.session))?;
    let pose = &result.alacs_from_rgbd;
    let t = pose.translation.vector;
    let (roll, pitch, yaw) = pose.rotation.euler_angles();
    let rpy = [roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees()];
    let flag =
        format!("{:.3},{:.3},{:.3},{:.4},{:.4},{:.4}", t.x, t.y, t.z, rpy[0], rpy[1], rpy[2]);
    if args.json {
        let matrix = pose.to_homogeneous();
        let rows: Vec<Vec<f64>> =
            (0..4).map(|r| (0..4).map(|c| matrix[(r, c)]).collect()).collect();
        let poses: Vec<_> = result
            .poses
            .iter()
            .map(|p| {
                json!({
                    "image": p.image,
                    "image_rgbd": p.image_rgbd,
                    "rms_px": p.rms_px,
                    "rotation_deviation_deg": p.rotation_deviation_deg,
                    "translation_deviation_mm": p.translation_deviation_mm,
                })
            })
            .collect();
        let rejected: Vec<_> = result
            .rejected
            .iter()
            .map(|(image, reason)| json!({"image_rgbd": image, "reason": reason}))
            .collect();
        output::print_json(&json!({
            "alacs_from_rgbd": {"xyz_mm": [t.x, t.y, t.z], "rpy_deg": rpy, "matrix": rows},
            "alacs_from_rgbd_flag": flag,
            "poses": poses,
            "rejected": rejected,
            "rotation_rms_deg": result.rotation_rms_deg,
            "translation_rms_mm": result.translation_rms_mm,
        }))?;
    } else {
        outln!(
            "alacs_from_rgbd from {} board poses ({} rejected): translation ({:.2}, {:.2}, {:.2}) mm, \
             roll {:.3} pitch {:.3} yaw {:.3} deg; the poses agree within {:.3} deg and {:.2} mm (RMS)",
            result.poses.len(),
            result.rejected.len(),
            t.x,
            t.y,
            t.z,
            rpy[0],
            rpy[1],
            rpy[2],
            result.rotation_rms_deg,
            result.translation_rms_mm
        );
        outln!("  --alacs-from-rgbd {flag}");
        outln!(
            "  rig.toml: [rgbd] alacs_from_rgbd = [{:.3}, {:.3}, {:.3}, {:.4}, {:.4}, {:.4}]",
            t.x,
            t.y,
            t.z,
            rpy[0],
            rpy[1],
            rpy[2]
        );
        for (_, reason) in &result.rejected {
            outln!("  rejected: {reason}");
        }
    }
    Ok(())
}
