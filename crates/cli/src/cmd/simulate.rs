//! `alacs simulate samples`, `alacs simulate session` and `alacs simulate scan`.

use alacs::sim::{
    Checkerboard, Exposure, LaserLight, OrchardOptions, RenderOptions, RgbdOptions, SampleOptions,
    ScanOptions, Sensor, SessionOptions, SlideError, simulate_samples, simulate_scan,
    simulate_session,
};
use alacs::{Camera, Fidelity, LaserModel};
use anyhow::anyhow;
use serde_json::json;

use alacs::model::io::OutputDir;

use crate::args::{
    RenderArgs, SceneArgs, SimulateRgbdArgs, SimulateSamplesArgs, SimulateScanArgs,
    SimulateSessionArgs, TruthArgs,
};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Checks `--slides`: at most [`alacs::sim::MAX_SLIDE_POSITIONS`], each slide travel d with the laser
/// in front of the camera's baseline (0 <= d < L0, so that L = L0 - d > 0).
fn check_slides(slides: &[f64], laser: &LaserModel) -> CmdResult<Vec<f64>> {
    let max = alacs::sim::MAX_SLIDE_POSITIONS;
    if slides.len() > max {
        return Err(Failure::bad_input(anyhow!(
            "--slides: {} positions, more than {max}",
            slides.len()
        )));
    }
    let l0_mm = laser.l0_mm;
    match slides.iter().find(|&&d| !(0.0..l0_mm).contains(&d)) {
        Some(d) => Err(Failure::bad_input(anyhow!(
            "--slides: {d} mm is outside 0 <= d < L0 = {l0_mm} mm (L = L0 - d must stay positive)"
        ))),
        None => Ok(slides.to_vec()),
    }
}

impl TruthArgs {
    /// The camera of `--camera FILE`, or the default 5 MP camera, and the
    /// laser of `--laser FILE` or of `--alpha-deg`, `--beta-deg`, `--l0-mm`.
    fn camera_and_laser(&self) -> CmdResult<(Camera, LaserModel)> {
        let camera = match &self.camera {
            Some(path) => Camera::from_yaml_file(path)?,
            None => Camera::blackfly_s_5mp(),
        };
        let laser = match &self.laser {
            Some(path) => LaserModel::from_yaml_file(path)?,
            None => {
                LaserModel::from_degrees(Fidelity::High, self.alpha_deg, self.beta_deg, self.l0_mm)
            }
        };
        Ok((camera, laser))
    }
}

impl RenderArgs {
    /// `defaults` with the command line's supersampling, stripe width and noise.
    fn options(&self, defaults: RenderOptions) -> RenderOptions {
        RenderOptions {
            supersampling: self.supersampling,
            laser: LaserLight { stripe_sigma_px: self.stripe_sigma_px, ..defaults.laser },
            sensor: if self.no_noise { Sensor::noiseless() } else { defaults.sensor },
            ..defaults
        }
    }
}

impl SceneArgs {
    /// The simulator's scan options for this scene (defaults elsewhere).
    pub fn options(&self) -> CmdResult<ScanOptions> {
        if self.all_targets && self.cluster == 0 {
            return Err(Failure::bad_input(anyhow!(
                "--all-targets names the cluster's other apples: give --cluster N (1-3)"
            )));
        }
        let defaults = ScanOptions::default();
        Ok(ScanOptions {
            orchard: OrchardOptions {
                depth_mm: self.depth_mm,
                occlusion: self.occlusion,
                cluster: usize::from(self.cluster),
                front_branches: usize::from(self.front_branches),
                ..defaults.orchard.clone()
            },
            sun: self.sun,
            scale: self.scale,
            neighbours_as_targets: self.all_targets,
            seed: self.seed,
            randomize: self.randomize,
            ..defaults
        })
    }
}

/// Runs `alacs simulate samples`.
pub fn samples(args: &SimulateSamplesArgs) -> CmdResult {
    let (camera, laser) = args.truth.camera_and_laser()?;
    let n_samples = u64::from(args.views) * u64::from(args.points_per_view);
    if n_samples > alacs::sim::MAX_SAMPLES as u64 {
        return Err(Failure::bad_input(anyhow!(
            "--views {} x --points-per-view {} is {n_samples} samples, more than {}",
            args.views,
            args.points_per_view,
            alacs::sim::MAX_SAMPLES
        )));
    }
    let options = SampleOptions {
        n_views: args.views as usize,
        points_per_view: args.points_per_view as usize,
        depth_mm: args.depth_mm,
        depth_noise_mm: args.noise_mm,
        outlier_fraction: args.outliers,
        slides_mm: check_slides(&args.slides, &laser)?,
        seed: args.seed,
        ..SampleOptions::default()
    };
    let sim = simulate_samples(&camera, &laser, &options)?;
    sim.write(&args.out, args.folder.force)?;
    if args.json {
        output::print_json(&json!({
            "out": args.out.display().to_string(),
            "n_samples": sim.samples.len(),
            "outliers": sim.outliers,
        }))?;
    }
    errln!(
        "wrote {} samples ({} outliers) to {} (samples.csv, truth.json)",
        sim.samples.len(),
        sim.outliers.len(),
        args.out.display()
    );
    Ok(())
}

/// The simulated board: the default checkerboard, with markers of
/// `dictionary` (`--charuco`) if given.
fn charuco_board(dictionary: Option<alacs::model::ArucoDictionary>) -> Checkerboard {
    dictionary.map_or_else(Checkerboard::default, Checkerboard::charuco)
}

/// Runs `alacs simulate session`.
pub fn session(args: &SimulateSessionArgs) -> CmdResult {
    let (camera, laser) = args.truth.camera_and_laser()?;
    let render = args.render.options(RenderOptions::default());
    let board = charuco_board(args.charuco);
    let options = SessionOptions {
        n_views: args.views as usize,
        slides_mm: check_slides(&args.slides, &laser)?,
        depth_mm: args.depth_mm,
        max_tilt_deg: args.max_tilt_deg,
        laser_off: args.laser_off,
        scale: args.scale,
        render,
        seed: args.seed,
        rgbd: args.rgbd_pose.map(|alacs_from_rgbd| RgbdOptions {
            camera: RgbdOptions::colour_camera_720p(),
            alacs_from_rgbd,
        }),
        slide: SlideError::from(&args.slide),
        board,
        cut_by_border: args.cut_by_border,
        second_board: args.second_board.then(|| Checkerboard::second_charuco(&board)),
        ..SessionOptions::default()
    };
    let bar = output::progress_bar(args.json, "computing the camera's rays");
    let session = simulate_session(&camera, &laser, &options)?;
    output::start_progress(&bar, session.image_count(), "rendering");
    OutputDir::fill(&args.out, "simulate session", args.folder.force, |out| {
        session.write_into(out, |done, _| bar.set_position(done as u64))
    })?;
    bar.finish_and_clear();
    let images: Vec<&str> = session.views.iter().map(|view| view.image.as_str()).collect();
    if args.json {
        output::print_json(&json!({
            "out": args.out.display().to_string(),
            "n_views": session.views.len(),
            "n_images": session.image_count(),
            "image_width": session.camera.width_px,
            "image_height": session.camera.height_px,
            "images": images,
        }))?;
    }
    errln!(
        "wrote {} views ({} images, {} x {} px) to {} (session.yaml, camera.yaml, truth.json, {}{})",
        session.views.len(),
        session.image_count(),
        session.camera.width_px,
        session.camera.height_px,
        args.out.display(),
        images.first().copied().unwrap_or_default(),
        if images.len() > 1 { ", ..." } else { "" },
    );
    Ok(())
}

/// Runs `alacs simulate scan`.
pub fn scan(args: &SimulateScanArgs) -> CmdResult {
    let (camera, laser) = args.truth.camera_and_laser()?;
    let defaults = args.scene.options()?;
    let mut render = args.render.options(defaults.render);
    render.sensor.exposure = Exposure { exposure_us: args.exposure_us, gain_db: args.gain_db };
    let options = ScanOptions {
        laser_off: args.laser_off,
        render,
        jpeg_quality: args.jpeg,
        within_reach: !args.anywhere,
        slide: SlideError::from(&args.slide),
        ..defaults
    };
    let bar = output::progress_bar(args.json, "building the scene and the camera's rays");
    let scan = simulate_scan(&camera, &laser, &options)?;
    output::start_progress(&bar, scan.image_count(), "rendering");
    OutputDir::fill(&args.out, "simulate scan", args.folder.force, |out| {
        scan.write_into(out, |done, _| bar.set_position(done as u64))
    })?;
    bar.finish_and_clear();
    let c = scan.scene.fruit_centre;
    if args.json {
        output::print_json(&json!({
            "out": args.out.display().to_string(),
            "n_frames": scan.frames.len(),
            "slides_mm": scan.plan.slides_mm,
            "fruit": {"position_mm": [c.x, c.y, c.z], "radius_mm": scan.scene.fruit_radius_mm},
            "occlusion": scan.scene.occlusion,
        }))?;
    }
    errln!(
        "wrote {} frames ({} x {} px, slides {} mm) of a {:.1} mm apple at ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, {:.0} % hidden, to {} (scan.yaml, camera.yaml, laser.yaml, truth.json)",
        scan.frames.len(),
        scan.camera.width_px,
        scan.camera.height_px,
        scan.plan.slides_mm.iter().map(|d| format!("{d:.1}")).collect::<Vec<_>>().join(", "),
        scan.scene.fruit_radius_mm,
        c.x,
        c.y,
        c.z,
        scan.scene.occlusion * 100.0,
        args.out.display()
    );
    Ok(())
}

/// Runs `alacs simulate rgbd`.
pub fn rgbd(args: &SimulateRgbdArgs) -> CmdResult {
    if args.scene.randomize {
        return Err(Failure::bad_input(anyhow!(
            "--randomize draws the laser scanner's rig; the RGB-D camera's view is rendered without it"
        )));
    }
    let options = args.scene.options()?;
    let alacs_from_rgbd = args.alacs_from_rgbd;
    let bar = output::progress_bar(args.json, "building the scene");
    // The scene of `scan --sim --seed N`: the rig's camera and laser.
    let scan = simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options)?;
    bar.set_message("rendering the RGB-D camera's view");
    let camera = RgbdOptions::colour_camera_720p();
    let view = scan.render_rgbd(&camera, &alacs_from_rgbd, &alacs::sim::RgbdErrors::default())?;
    OutputDir::fill(&args.out, "simulate rgbd", args.folder.force, |out| view.write_into(out))?;
    bar.finish_and_clear();
    if args.json {
        output::print_json(
            &json!({"out": args.out.display().to_string(), "truth": view.truth_json()}),
        )?;
    }
    let target = view.apples.iter().find(|a| a.target);
    errln!(
        "wrote the RGB-D view ({} x {} px) of {} apple(s){} to {} (color.png, depth.png, camera.yaml, truth.json)",
        camera.width_px,
        camera.height_px,
        view.apples.len(),
        target.map_or(String::new(), |t| format!(
            ", the target at ({:.1}, {:.1}, {:.1}) mm in the RGB-D camera frame",
            t.centre_mm.x, t.centre_mm.y, t.centre_mm.z
        )),
        args.out.display()
    );
    Ok(())
}
