//! `alacs`: the command-line program of the Active LAser-Camera Scanner.
//!
//! The definition of the command-line interface plus glue: every computation
//! lives in the library crates. Exit codes follow FORMATS.md: 0 success, 1 the
//! input was readable but the job failed, 2 bad usage or unreadable input.

mod args;
mod cmd;
mod failure;
mod output;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = args::Cli::parse();
    let result = match cli.command {
        args::Command::Calibrate(args::CalibrateCommand::Laser(a)) => cmd::calibrate::laser(&a),
        args::Command::Calibrate(args::CalibrateCommand::Camera(a)) => cmd::calibrate::camera(&a),
        args::Command::Evaluate(args::EvaluateCommand::Calibration(a)) => {
            cmd::evaluate::calibration(&a)
        }
        args::Command::Evaluate(args::EvaluateCommand::Accuracy(a)) => cmd::evaluate::accuracy(&a),
        args::Command::Report(args::ReportCommand::Calibration(a)) => cmd::report::calibration(&a),
        args::Command::Report(args::ReportCommand::Scan(a)) => cmd::report::scan(&a),
        args::Command::Triangulate(a) => cmd::triangulate::run(&a),
        args::Command::Stripe(a) => cmd::stripe::run(&a),
        args::Command::Localize(a) => cmd::localize::run(&a),
        args::Command::Simulate(args::SimulateCommand::Samples(a)) => cmd::simulate::samples(&a),
        args::Command::Simulate(args::SimulateCommand::Session(a)) => cmd::simulate::session(&a),
        args::Command::Simulate(args::SimulateCommand::Scan(a)) => cmd::simulate::scan(&a),
        args::Command::Demo(a) => cmd::demo::run(&a),
        args::Command::Scan(a) => cmd::scan::run(&a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            eprintln!("error: {:#}", failure.error);
            ExitCode::from(failure.code)
        }
    }
}
