//! `alacs simulate samples`.

use alacs::sim::{SampleOptions, simulate_samples};
use alacs::{Camera, Fidelity, LaserModel};
use anyhow::anyhow;
use serde_json::json;

use crate::args::SimulateSamplesArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Parses a comma-separated list of numbers for option `name`.
pub fn parse_list(text: &str, name: &str) -> CmdResult<Vec<f64>> {
    text.split(',')
        .map(|item| {
            item.trim().parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                Failure::bad_input(anyhow!("{name}: `{}` is not a finite number", item.trim()))
            })
        })
        .collect()
}

/// Parses `MIN,MAX` for option `name`.
fn parse_range(text: &str, name: &str) -> CmdResult<(f64, f64)> {
    match parse_list(text, name)?.as_slice() {
        [min, max] => Ok((*min, *max)),
        _ => Err(Failure::bad_input(anyhow!("{name} takes MIN,MAX, got `{text}`"))),
    }
}

/// Runs `alacs simulate samples`.
pub fn samples(args: &SimulateSamplesArgs) -> CmdResult {
    let camera = match &args.camera {
        Some(path) => Camera::from_yaml_file(path)?,
        None => Camera::blackfly_s_5mp(),
    };
    let laser = match &args.laser {
        Some(path) => LaserModel::from_yaml_file(path)?,
        None => LaserModel::from_degrees(Fidelity::High, args.alpha_deg, args.beta_deg, args.l0_mm),
    };
    let options = SampleOptions {
        n_views: args.views,
        points_per_view: args.points_per_view,
        depth_mm: parse_range(&args.depth_mm, "--depth-mm")?,
        depth_noise_mm: args.noise_mm,
        outlier_fraction: args.outliers,
        slides_mm: parse_list(&args.slides, "--slides")?,
        seed: args.seed,
        ..SampleOptions::default()
    };
    let sim = simulate_samples(&camera, &laser, &options)?;
    sim.write(&args.out)?;
    if args.json {
        output::print_json(&json!({
            "out": args.out.display().to_string(),
            "n_samples": sim.samples.len(),
            "outliers": sim.outliers,
        }));
    } else {
        println!(
            "wrote {} samples ({} outliers) to {} (samples.csv, truth.json)",
            sim.samples.len(),
            sim.outliers.len(),
            args.out.display()
        );
    }
    Ok(())
}
