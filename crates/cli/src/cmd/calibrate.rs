//! `alacs calibrate laser`.

use alacs::calib::{CalibrationOptions, Method, Residual, read_samples_csv};
use anyhow::anyhow;
use serde_json::json;

use crate::args::{CalibrateLaserArgs, ResidualArg};
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
        ..CalibrationOptions::default()
    })
}

/// Runs `alacs calibrate laser`.
pub fn laser(args: &CalibrateLaserArgs) -> CmdResult {
    let options = options(args)?;
    let method = Method::from_number(args.method)
        .ok_or_else(|| Failure::bad_input(anyhow!("--method must be 1, 2, 3 or 4")))?;
    let samples = read_samples_csv(&args.samples)?;
    let context = |e: alacs::calib::Error| {
        let code = Failure::from(e);
        Failure { error: code.error.context(format!("{}", args.samples.display())), ..code }
    };

    let (chosen, results) = if args.compare {
        let results = alacs::compare(&samples, &options).map_err(context)?;
        let chosen = results.iter().position(|c| c.method == method).unwrap_or(3);
        (chosen, results)
    } else {
        (0, vec![alacs::calibrate(&samples, method, &options).map_err(context)?])
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
            args.samples.display(),
            fit.mean_abs_error_mm
        );
        fit.laser.to_yaml_file(path, &header)?;
    }

    if args.json {
        let value = if args.compare {
            json!({"methods": results.iter().map(output::calibration_json).collect::<Vec<_>>()})
        } else {
            output::calibration_json(fit)
        };
        output::print_json(&value);
    } else {
        if args.compare {
            print!("{}", output::table_1(&results));
            println!();
        }
        print!("{}", output::summary(fit, options.threshold_mm));
        if let Some(path) = &args.output {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}
