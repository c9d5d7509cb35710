//! alacs's side of the OpenCV peer benchmark (`benches/peers/run.sh`): the
//! same jobs on the same files, timed the same way, one JSON line per file.
//!
//! ```text
//! peer_timing stripe REPEATS FILE...            laser stripe, whole frame, one peak per row
//! peer_timing board REPEATS COLS ROWS FILE...   checkerboard corners (inner corners COLS x ROWS)
//! ```
//!
//! Decoding is not timed (the frames are in memory, as on a camera); each
//! job runs REPEATS times per file and the median is printed in ms.
#![allow(missing_docs)]

use std::process::ExitCode;
use std::time::Instant;

use alacs_board::{board_gray, detect_checkerboard};
use alacs_model::BoardSpec;
use alacs_vision::{Region, StripeOptions, extract_stripe_rgb, read_image};

fn median_ms(repeats: usize, mut job: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..repeats.max(1))
        .map(|_| {
            let start = Instant::now();
            job();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn run(args: &[String]) -> Result<(), String> {
    let usage = "usage: peer_timing stripe REPEATS FILE... | board REPEATS COLS ROWS FILE...";
    let number = |s: Option<&String>, what: &str| -> Result<usize, String> {
        s.ok_or(usage)?.parse().map_err(|e| format!("{what} {s:?}: {e}"))
    };
    let job = args.first().ok_or(usage)?;
    let repeats = number(args.get(1), "REPEATS")?;
    match job.as_str() {
        "stripe" => {
            for file in &args[2..] {
                let image = read_image(std::path::Path::new(file))
                    .map_err(|e| format!("{file}: {e}"))?
                    .to_rgb8();
                let region = Region::full(image.width(), image.height());
                let options = StripeOptions::default();
                let mut points = 0;
                let ms = median_ms(repeats, || {
                    points = extract_stripe_rgb(&image, None, &region, &options)
                        .map(|p| p.len())
                        .unwrap_or(0);
                });
                let line =
                    serde_json::json!({"job": "stripe", "file": file, "ms": ms, "rows": points});
                println!("{line}");
            }
        }
        "board" => {
            let cols = number(args.get(2), "COLS")?;
            let rows = number(args.get(3), "ROWS")?;
            let board = BoardSpec::checkerboard(cols, rows, 1.0, 1.0);
            for file in &args[4..] {
                let image =
                    read_image(std::path::Path::new(file)).map_err(|e| format!("{file}: {e}"))?;
                let gray = board_gray(&image);
                let mut found = false;
                let ms = median_ms(repeats, || {
                    found = detect_checkerboard(&gray, &board).is_ok();
                });
                let line =
                    serde_json::json!({"job": "board", "file": file, "ms": ms, "found": found});
                println!("{line}");
            }
        }
        _ => return Err(usage.into()),
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("peer_timing: {e}");
            ExitCode::from(2)
        }
    }
}
