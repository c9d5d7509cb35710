//! `alacs localize`: the fruit's centre from a scan folder.

use alacs::locate::{locate_scan_targets, priors_of, target_cloud_path};
use alacs::ros::bag::localize_scan;
use alacs::{Camera, LaserModel, Scan};

use crate::args::LocalizeArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs localize`. `not_found` is an answer (exit 0), per FORMATS.md.
pub fn run(args: &LocalizeArgs) -> CmdResult {
    if let Some(path) = &args.points {
        // A bad extension is refused before the long work.
        alacs::locate::CloudFormat::from_path(path)?;
    }
    let options = args.rough_error.locate_options(args.method.method());
    let (answers, priors) = match (&args.scan, &args.bag) {
        (Some(dir), _) => {
            let scan = Scan::read(dir)?;
            let camera = Camera::from_yaml_file(&args.camera)?;
            let laser = LaserModel::from_yaml_file(&args.laser)?;
            alacs::locate::check_camera_fits(&scan, &camera)
                .map_err(|e| Failure::from(e).with_context(&args.camera))?;
            let bar = output::progress_bar(args.json, "frames");
            output::start_progress(&bar, scan.frames.len(), "frames read");
            let answers = locate_scan_targets(&scan, &camera, &laser, &options, |_, _| bar.inc(1));
            bar.finish_and_clear();
            (answers?, priors_of(&scan))
        }
        (None, Some(bag)) => {
            let camera = Camera::from_yaml_file(&args.camera)?;
            let laser = LaserModel::from_yaml_file(&args.laser)?;
            let bar = output::progress_bar(args.json, "reading the recording");
            let answer = localize_scan(bag, args.bag_scan, &camera, &laser, &options, |done| {
                bar.set_message(format!("{done} frames read"));
            });
            bar.finish_and_clear();
            let (answer, prior) = answer?;
            (vec![answer], vec![prior])
        }
        (None, None) => {
            return Err(Failure::bad_input(anyhow::anyhow!("--scan DIR or --bag FILE.mcap")));
        }
    };
    if let [answer] = answers.as_slice() {
        // One fruit: the contract's localize object.
        if let Some(path) = &args.points {
            alacs::locate::write_points(path, answer)?;
            errln!("wrote the laser points and the fitted centre to {}", path.display());
        }
        if args.json {
            output::print_json(&output::localization_json(answer))?;
        } else {
            output::print_text(&output::localization_summary(answer))?;
        }
        return Ok(());
    }
    if let Some(path) = &args.points {
        for (k, answer) in answers.iter().enumerate() {
            let file = target_cloud_path(path, k);
            alacs::locate::write_points(&file, answer)?;
            errln!("wrote fruit {k}'s laser points and fitted centre to {}", file.display());
        }
    }
    if args.json {
        output::print_json(&output::targets_json(&answers, &priors))?;
    } else {
        output::print_text(&output::targets_summary(&answers, &priors))?;
    }
    Ok(())
}
