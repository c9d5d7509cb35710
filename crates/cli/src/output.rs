//! What commands print: FORMATS.md's JSON objects and readable tables.

use std::fmt::Write as _;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

use alacs::LaserCalibration;
use alacs::locate::{Localization, LocalizeOutput, Prior, Status, TargetsOutput};
use alacs::model::{Fidelity, PlusMinus};
use serde_json::Value;

use crate::failure::{CmdResult, Failure};

pub use alacs::eval::table_1;

/// One calibration as FORMATS.md's `calibrate laser --json` object
/// (alacs-calib's [`alacs::calib::CalibrationOutput`]).
pub fn calibration_json(c: &LaserCalibration) -> Value {
    serde_json::to_value(c.to_output()).unwrap_or(Value::Null)
}

/// `print!` to standard output through [`print_text`]: returns from the
/// calling command with its failure when standard output cannot be written.
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::output::print_text(&format!($($arg)*))?
    };
}

/// `println!` to standard output through [`print_text`], as [`out!`].
macro_rules! outln {
    () => {
        $crate::output::print_text("\n")?
    };
    ($($arg:tt)*) => {
        $crate::output::print_text(&format!("{}\n", format_args!($($arg)*)))?
    };
}

/// `errln!` through [`print_err`]: a line on standard error that never
/// panics and never stops the command.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::output::print_err(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// Writes `text` to standard error, ignoring a closed or full stream: a
/// message that cannot be shown must not lose the work it is about
/// (`alacs scan ... 2>&1 | head -1`, `2>/dev/full`).
pub fn print_err(text: &str) {
    use std::io::Write as _;
    let mut stderr = std::io::stderr().lock();
    let _ = stderr.write_all(text.as_bytes()).and_then(|()| stderr.flush());
}

/// Prints `value` as the one JSON object on standard output.
pub fn print_json(value: &Value) -> CmdResult {
    print_text(&format!("{value}\n"))
}

/// Writes `text` to standard output and flushes it. A closed pipe
/// (`alacs ... | head`) comes back as an error that `main` ends quietly
/// with exit 0; any other write error (a full disk) is exit 2.
pub fn print_text(text: &str) -> CmdResult {
    use std::io::Write as _;
    let mut stdout = std::io::stdout().lock();
    stdout
        .write_all(text.as_bytes())
        .and_then(|()| stdout.flush())
        .map_err(|e| Failure::bad_input(anyhow::Error::new(e).context("standard output")))
}

/// A readable summary of one calibration, with standard deviations.
pub fn summary(c: &LaserCalibration) -> String {
    let threshold_mm = c.threshold_mm;
    let mut out = String::new();
    let _ =
        write!(out, "Method {} ({}): {} samples", c.method.number(), c.method.name(), c.n_samples);
    match c.ransac_iterations {
        Some(k) => {
            let _ = writeln!(
                out,
                ", {} inliers within {threshold_mm:.2} mm ({k} RANSAC hypotheses)",
                c.inliers.len()
            );
        }
        None => out.push('\n'),
    }
    let std = c.std_dev;
    // Each value to its sigma's two significant figures (PlusMinus).
    let pm = |value: f64, sigma: Option<f64>, decimals: usize| {
        PlusMinus { value, sigma, decimals }.to_string()
    };
    let _ = writeln!(out, "  alpha = {} deg", pm(c.laser.alpha_deg(), std.map(|s| s.alpha_deg), 4));
    let _ = writeln!(out, "  L0    = {} mm", pm(c.laser.l0_mm, std.map(|s| s.l0_mm), 3));
    if c.laser.fidelity == Fidelity::High {
        let _ = writeln!(
            out,
            "  beta  = {} deg",
            pm(c.laser.beta_deg(), std.and_then(|s| s.beta_deg), 4)
        );
    }
    if c.slide_scale_fitted {
        let _ = writeln!(
            out,
            "  k     = {} (slide scale: L = L0 - k d)",
            pm(c.laser.slide_scale, std.and_then(|s| s.slide_scale), 5)
        );
    } else {
        // Said, so that a session at one slide position is not mistaken
        // for one that measured k = 1.
        let _ = writeln!(
            out,
            "  k     = {:.5} held, not fitted (slide scale; fitting it needs views at 3 or more slide positions, and no --hold-slide-scale)",
            c.laser.slide_scale
        );
    }
    if let Some(s) = std {
        let _ = writeln!(out, "  +- one standard deviation: {}", s.source.describe());
    }
    let _ = writeln!(
        out,
        "  mean |z - z_hat| = {:.3} mm over the fitted samples, {:.3} mm over all ({} residual)",
        c.mean_abs_error_mm,
        c.mean_abs_error_all_mm,
        c.residual.as_str()
    );
    out
}

/// A progress bar on standard error (hidden under `--json`, so standard
/// output holds only the JSON), spinning with `message` until its length is known.
pub fn progress_bar(json: bool, message: &'static str) -> ProgressBar {
    use std::io::IsTerminal as _;
    let bar = if json {
        ProgressBar::hidden()
    } else if std::io::stderr().is_terminal() {
        ProgressBar::new_spinner()
    } else {
        // Standard error into a file or a pipe (a robot's log): one line
        // per change instead of nothing, so long work is seen to go on.
        let target = ProgressDrawTarget::term_like_with_hz(Box::new(LineLog::default()), 2);
        let bar = ProgressBar::with_draw_target(None, target)
            .with_style(ProgressStyle::default_spinner());
        // Drawn now and then, so a stage that began in the quiet seconds is
        // logged once they are over.
        bar.enable_steady_tick(std::time::Duration::from_millis(500));
        bar
    };
    bar.set_message(message);
    bar
}

/// A progress bar's drawing as log lines on standard error: each state
/// once (the spinner's frame ignored), no cursor movement, and nothing in
/// a job's first [`QUIET_SECONDS`]: short commands log nothing.
#[derive(Debug)]
struct LineLog {
    last: std::sync::Mutex<String>,
    started: std::time::Instant,
}

impl Default for LineLog {
    fn default() -> Self {
        LineLog { last: std::sync::Mutex::new(String::new()), started: std::time::Instant::now() }
    }
}

/// Seconds of work before a progress bar logs to a standard error that is
/// no terminal.
const QUIET_SECONDS: f64 = 2.0;

impl LineLog {
    fn log(&self, text: &str) -> std::io::Result<()> {
        if self.started.elapsed().as_secs_f64() < QUIET_SECONDS {
            return Ok(());
        }
        // The spinner's frame is the first character of a drawn line.
        let text = text.trim();
        let state = text.chars().skip(1).collect::<String>().trim().to_owned();
        if state.is_empty() {
            return Ok(());
        }
        let Ok(mut last) = self.last.lock() else { return Ok(()) };
        if *last != state {
            print_err(&format!("{state}\n"));
            *last = state;
        }
        Ok(())
    }
}

impl TermLike for LineLog {
    fn width(&self) -> u16 {
        200
    }
    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.log(s)
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.log(s)
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Turns a spinner into a bar of `len` steps, showing `message`.
pub fn start_progress(bar: &ProgressBar, len: usize, message: &'static str) {
    bar.set_length(len as u64);
    if let Ok(style) = ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message(message);
}

/// FORMATS.md's `localize --json` object for `answer`: its owner,
/// [`LocalizeOutput`], serialized.
pub fn localization_json(answer: &Localization) -> Value {
    // Serializing fails only for maps with keys that are not strings; the
    // object has none.
    serde_json::to_value(LocalizeOutput::from(answer)).unwrap_or(Value::Null)
}

/// The `localize --json` object of a scan naming several fruit.
pub fn targets_json(answers: &[Localization], priors: &[Prior]) -> Value {
    serde_json::to_value(TargetsOutput::new(answers, priors)).unwrap_or(Value::Null)
}

/// A readable summary per fruit of a scan naming several.
pub fn targets_summary(answers: &[Localization], priors: &[Prior]) -> String {
    let found = answers.iter().filter(|a| a.status == Status::Ok).count();
    let mut out = format!("{found} of {} fruit found\n", answers.len());
    for (k, (answer, prior)) in answers.iter().zip(priors).enumerate() {
        let r = &prior.rough_position_mm;
        let _ = writeln!(
            out,
            "\ntarget {k} (rough position ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, radius prior {:.1} mm): {}",
            r.x,
            r.y,
            r.z,
            prior.fruit_radius_mm,
            localization_summary(answer)
        );
    }
    out
}

/// A readable summary of a localization.
pub fn localization_summary(answer: &Localization) -> String {
    let mut out = String::new();
    match (answer.status, answer.position_mm) {
        (Status::Ok, Some(p)) => {
            let _ = writeln!(
                out,
                "fruit at ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, radius {:.1} mm ({}: {})",
                p.x,
                p.y,
                p.z,
                answer.radius_mm.unwrap_or(f64::NAN),
                answer.method.as_str(),
                answer.reason
            );
        }
        _ => {
            let _ = writeln!(out, "not found: {}", answer.reason);
        }
    }
    let _ = writeln!(
        out,
        "{:>5} {:>9} {:>7} {:>6}  {:<28} {:>7}",
        "frame", "slide_mm", "stripe", "fruit", "candidate (mm)", "score"
    );
    for (k, frame) in answer.frames.iter().enumerate() {
        let candidate = answer.candidates.iter().find(|c| c.frame == k);
        let (position, score) = match candidate {
            Some(c) => (
                format!("({:.1}, {:.1}, {:.1})", c.position_mm.x, c.position_mm.y, c.position_mm.z),
                format!("{:.2}", c.score),
            ),
            None => (frame.rejected.clone().unwrap_or_default(), String::new()),
        };
        let _ = writeln!(
            out,
            "{:>5} {:>9.1} {:>7} {:>6}  {:<28} {:>7}",
            k,
            frame.slide_mm,
            frame.stripe.len(),
            frame.fruit.len(),
            position,
            score
        );
    }
    out
}

/// The accuracy evaluation per slide position, as a table: the z errors'
/// median, quartile range and extremes, their spread within views against
/// the predicted noise floor, and the x and y errors' medians and ranges.
pub fn accuracy_table(eval: &alacs::eval::AccuracyEvaluation) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>6} {:>6} {:>6} {:>7} | {:>7} {:>6} {:>7} {:>7} | {:>8} {:>9} | {:>13} {:>13}",
        "d (mm)",
        "L (mm)",
        "points",
        "depth",
        "z med",
        "IQR",
        "min",
        "max",
        "sigma_z",
        "predicted",
        "x med / IQR",
        "y med / IQR"
    );
    for s in &eval.slides {
        let [x, y, z] = &s.error_mm;
        let _ = writeln!(
            out,
            "{:>6.0} {:>6.0} {:>6} {:>7.0} | {:>7.3} {:>6.3} {:>7.2} {:>7.2} | {:>8.3} {:>9.3} | {:>6.3} {:>6.3} {:>6.3} {:>6.3}",
            s.slide_mm,
            s.laser_distance_mm,
            z.n,
            s.median_depth_mm,
            z.median,
            z.iqr(),
            z.min,
            z.max,
            s.within_view_sigma_z_mm,
            s.predicted_sigma_z_mm,
            x.median,
            x.iqr(),
            y.median,
            y.iqr()
        );
    }
    let _ = writeln!(
        out,
        "(errors: triangulated - on the board plane by its pose, mm; sigma_z: the depth error's spread within each view (1.4826 MAD),\n\
         predicted: z^2 cos(alpha) sigma_px / (f L) at the median depth with sigma_px {:.3} px{})",
        eval.sigma_px,
        if eval.sigma_px_measured { ", measured from the session" } else { ", given" }
    );
    out
}

/// "wrote N files to DIR (a, b, ...)".
pub fn files_written(dir: &std::path::Path, files: &[std::path::PathBuf]) -> String {
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default())
        .collect();
    format!("wrote {} files to {} ({})", files.len(), dir.display(), names.join(", "))
}
