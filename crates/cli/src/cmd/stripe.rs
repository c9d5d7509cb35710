//! `alacs stripe`: the laser stripe of one frame.

use alacs::vision::{
    Region, StripeOptions, extract_stripe_rgb, read_colour_image, read_laser_off_image,
};
use anyhow::anyhow;
use serde_json::json;

use crate::args::StripeArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs stripe`.
pub fn run(args: &StripeArgs) -> CmdResult {
    let mut options =
        if args.orchard { StripeOptions::orchard() } else { StripeOptions::default() };
    if let Some(min_strength) = args.min_strength {
        if !(min_strength.is_finite() && min_strength > 0.0) {
            return Err(Failure::bad_input(anyhow!(
                "--min-strength must be a positive number, got {min_strength}"
            )));
        }
        options.min_strength = min_strength;
    }
    // The command line is checked before any image is read.
    let roi = args.roi;
    let on = read_colour_image(&args.image, args.laser_off.is_some())?;
    let off = match &args.laser_off {
        Some(path) => Some(read_laser_off_image(path, &on, &args.image)?),
        None => None,
    };
    let (width, height) = on.dimensions();
    let region = match roi {
        Some([u0, v0, u1, v1]) => {
            if u0 >= width || v0 >= height {
                return Err(Failure::bad_input(anyhow!(
                    "--roi {u0},{v0},{u1},{v1} starts outside the {width} x {height} px image"
                )));
            }
            Region::rect(u0, v0, u1, v1, width, height)
        }
        None => Region::full(width, height),
    };
    let points = extract_stripe_rgb(&on, off.as_ref(), &region, &options)?;
    if args.json {
        output::print_json(&json!({
            "image": args.image.display().to_string(),
            "width_px": width,
            "height_px": height,
            "points": points.iter().map(|p| json!({
                "u_px": p.u_px, "v_px": p.v_px, "strength": p.strength, "width_px": p.width_px,
            })).collect::<Vec<_>>(),
        }))?;
    } else {
        outln!("u_px,v_px,strength");
        for p in &points {
            outln!("{:.3},{},{:.1}", p.u_px, p.v_px, p.strength);
        }
    }
    Ok(())
}
