//! `alacs`: the command-line program of the Active LAser-Camera Scanner.
//!
//! The definition of the command-line interface plus glue: every computation
//! lives in the library crates. Exit codes follow FORMATS.md: 0 success, 1 the
//! input was readable but the job failed, 2 bad usage or unreadable input.

mod args;
#[macro_use]
mod output;
mod cmd;
mod failure;
mod ros_args;
mod values;

use std::process::ExitCode;

fn main() -> ExitCode {
    // Past a file-size limit (`ulimit -f`), a write fails with EFBIG instead
    // of the process being killed by SIGXFSZ: the writer then removes its
    // temporary file and the error names the output.
    let _ = signal_hook::flag::register(
        signal_hook::consts::SIGXFSZ,
        std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
    );
    let cli = match parse() {
        Ok(cli) => cli,
        Err(error) => return usage_error(&error),
    };
    // `ros` handles SIGINT and SIGTERM itself (its summary, the contract's
    // JSON); every other command removes what it was writing.
    if !matches!(cli.command, args::Command::Ros(_)) {
        remove_temporaries_on_signals();
    }
    let json = cli.command.json();
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        // A closed pipe (`alacs ... | head -1`) is no failure: the reader has
        // what it wanted (as ripgrep does).
        Err(failure) if failure.is_broken_pipe() => ExitCode::SUCCESS,
        Err(failure) => {
            // One line, whatever the message holds (a newline in a path).
            let message = format!("{:#}", failure.error);
            let one_line: String = message
                .trim_end()
                .chars()
                .flat_map(|c| {
                    let escaped: Vec<char> =
                        if c.is_control() { c.escape_default().collect() } else { vec![c] };
                    escaped
                })
                .collect();
            errln!("error: {one_line}");
            if json {
                // Standard output may itself be what failed; nothing more to do then.
                let _ = output::print_json(&failure.to_json());
            }
            ExitCode::from(failure.code)
        }
    }
}

/// On SIGINT, SIGTERM or SIGHUP: the temporary files and scratch folders
/// being written are removed (every target keeps its old contents), one
/// line says so, and the process exits as a shell reports the signal
/// (128 + its number: 130, 143, 129).
fn remove_temporaries_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            alacs::model::io::remove_temporaries();
            errln!("error: interrupted by signal {signal}; no file was left half-written");
            std::process::exit(128 + signal);
        }
    });
}

/// docs/FORMATS.md, the contract, for users of the binary alone.
const FORMATS: &str = include_str!("../../../docs/FORMATS.md");

/// Under every `--help`: the exit codes, and where the rest of the
/// contract is (built into the binary: `alacs formats`).
const CONTRACT: &str = "Exit codes: 0 ok (a fruit not found is an answer), 1 the job failed, \
     2 bad input. Files and --json objects: `alacs formats`";

/// The command line, with [`CONTRACT`] under every command's help.
fn parse() -> Result<args::Cli, clap::Error> {
    use clap::{CommandFactory as _, FromArgMatches as _};
    fn with_contract(command: clap::Command) -> clap::Command {
        command
            .after_help(CONTRACT)
            // A value that starts with a hyphen (`--slide-mm -5`, `--roi
            // -5,0,9,9`, `--threshold-mm -inf`) is the option's value, which
            // the option's own check takes or refuses naming the option,
            // never clap's "unexpected argument '-5'" that names none.
            .mut_args(|arg| {
                if arg.get_action().takes_values() { arg.allow_hyphen_values(true) } else { arg }
            })
            .mut_subcommands(with_contract)
    }
    let command = with_contract(args::Cli::command());
    // `alacs ros ... --ros-args ...` as a ROS 2 launch gives it: turned into
    // the node's own options first.
    let ros_options: Vec<String> = command
        .find_subcommand("ros")
        .map(|ros| {
            ros.get_arguments().filter_map(|a| a.get_long()).map(|l| format!("--{l}")).collect()
        })
        .unwrap_or_default();
    let argv =
        ros_args::expand(std::env::args_os().collect(), &ros_options).map_err(|message| {
            clap::Error::raw(clap::error::ErrorKind::ValueValidation, message + "\n")
        })?;
    let mut command = command;
    let matches = command.try_get_matches_from_mut(argv)?;
    let mut cli = args::Cli::from_arg_matches(&matches)?;
    // The node's options, as its ROS 2 parameters.
    if let (args::Command::Ros(ros), Some(ros_matches), Some(ros_command)) =
        (&mut cli.command, matches.subcommand_matches("ros"), command.find_subcommand("ros"))
    {
        ros.parameters = ros_args::parameters(ros_command, ros_matches);
    }
    Ok(cli)
}

/// Bad usage: clap's message on standard error (exit 2), and with `--json`
/// the error object on standard output. `--help` and `--version` print as
/// usual and exit 0.
fn usage_error(error: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(error.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        // A full standard output is exit 2 with its error, as for every
        // command's output (`alacs --help > /dev/full`).
        return match output::print_text(&error.render().to_string()) {
            Err(failure) if !failure.is_broken_pipe() => {
                errln!("error: {:#}", failure.error);
                ExitCode::from(failure.code)
            }
            _ => ExitCode::SUCCESS,
        };
    }
    let _ = error.print();
    if std::env::args().any(|a| a == "--json") {
        // clap's first line, without its "error: " and styling.
        let rendered = error.render().to_string();
        let first = rendered.lines().next().unwrap_or("invalid command line");
        let message = first.trim_start_matches("error: ").to_string();
        let failure = failure::Failure::bad_input(anyhow::anyhow!(message));
        let _ = output::print_json(&failure.to_json());
    }
    ExitCode::from(failure::BAD_INPUT)
}

fn run(command: args::Command) -> failure::CmdResult {
    use args::{CalibrateCommand, Command, EvaluateCommand, ReportCommand, SimulateCommand};
    match command {
        Command::Calibrate(CalibrateCommand::Laser(a)) => cmd::calibrate::laser(&a),
        Command::Calibrate(CalibrateCommand::Camera(a)) => cmd::calibrate::camera(&a),
        Command::Calibrate(CalibrateCommand::Rgbd(a)) => cmd::calibrate::rgbd(&a),
        Command::Evaluate(EvaluateCommand::Calibration(a)) => cmd::evaluate::calibration(&a),
        Command::Evaluate(EvaluateCommand::Accuracy(a)) => cmd::evaluate::accuracy(&a),
        Command::Report(ReportCommand::Calibration(a)) => cmd::report::calibration(&a),
        Command::Report(ReportCommand::Scan(a)) => cmd::report::scan(&a),
        Command::Triangulate(a) => cmd::triangulate::run(&a),
        Command::Stripe(a) => cmd::stripe::run(&a),
        Command::Localize(a) => cmd::localize::run(&a),
        Command::Detect(a) => cmd::detect::run(&a),
        Command::Simulate(SimulateCommand::Samples(a)) => cmd::simulate::samples(&a),
        Command::Simulate(SimulateCommand::Session(a)) => cmd::simulate::session(&a),
        Command::Simulate(SimulateCommand::Scan(a)) => cmd::simulate::scan(&a),
        Command::Simulate(SimulateCommand::Rgbd(a)) => cmd::simulate::rgbd(&a),
        Command::Demo(a) => cmd::demo::run(&a),
        Command::Scan(a) => cmd::scan::run(&a),
        Command::Session(args::SessionCommand::Init(a)) => cmd::session::init(&a),
        Command::Ros(a) => cmd::ros::run(&a),
        Command::Rig(args::RigCommand::Check(a)) => cmd::rig::check(&a),
        Command::Bag(args::BagCommand::Export(a)) => cmd::bag::export(&a),
        Command::Bag(args::BagCommand::Import(a)) => cmd::bag::import(&a),
        Command::Convert(args::ConvertCommand::Camera(a)) => cmd::convert::camera(&a),
        Command::Formats => output::print_text(FORMATS),
    }
}
