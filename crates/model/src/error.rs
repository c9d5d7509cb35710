//! The one error type of `alacs-model`.

use std::path::PathBuf;

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Whether an error is about the input or about the job, as docs/FORMATS.md's
/// exit codes tell them apart. Every crate's error enum says it once, in its
/// `class` method; the program maps it to the exit code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorClass {
    /// Bad usage, unreadable or invalid input, or an output that cannot be
    /// written (exit code 2).
    BadInput,
    /// The input was readable but the job failed on it (exit code 1).
    JobFailed,
}

/// Everything that can go wrong in the camera and laser models and their files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        error: std::io::Error,
    },
    /// An input is larger than alacs reads.
    #[error("{path}: larger than {limit} bytes, the most alacs reads for such a file")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The limit in bytes.
        limit: u64,
    },
    /// An output folder holds files that the command did not write.
    #[error(
        "{path}: the output folder holds {count} file(s) this command did not write (`{example}`); choose an empty folder or pass --force"
    )]
    OutputNotEmpty {
        /// The folder.
        path: PathBuf,
        /// One of the files, the first by name.
        example: String,
        /// How many there are.
        count: usize,
    },
    /// An output exists and is not a regular file (a device, a FIFO, a
    /// socket, a folder, or a link inside an output folder): never replaced.
    #[error("{path}: is {what}, not a regular file; alacs writes only regular files")]
    NotRegularFile {
        /// The output.
        path: PathBuf,
        /// What it is ("a device", ...).
        what: &'static str,
    },
    /// An input is not a regular file (a FIFO, a device, a folder).
    #[error("{path}: is {what}, not a regular file; give a file")]
    NotRegularInput {
        /// The input.
        path: PathBuf,
        /// What it is ("a FIFO", ...).
        what: &'static str,
    },
    /// An output folder's manifest names something alacs does not remove:
    /// a path outside the folder, an absolute path, a link.
    #[error(
        "{path}: names `{entry}`, {reason}; alacs removes only plain files it wrote inside the folder (delete the manifest if the folder is yours)"
    )]
    UnsafeManifest {
        /// The manifest.
        path: PathBuf,
        /// The entry.
        entry: String,
        /// What is wrong with it.
        reason: String,
    },
    /// An output folder holds another command's output.
    #[error(
        "{path}: holds the output of `alacs {owner}`, not of `alacs {command}`; choose another folder or pass --force"
    )]
    OutputOfAnotherCommand {
        /// The folder.
        path: PathBuf,
        /// The command that wrote it.
        owner: String,
        /// The command writing now.
        command: String,
    },
    /// Another process is writing an output folder.
    #[error(
        "{path}: another alacs ({}) is writing this folder; wait for it or choose another folder",
        if holder.is_empty() { "process unknown".to_owned() } else { format!("process {holder}") }
    )]
    OutputLocked {
        /// The folder.
        path: PathBuf,
        /// The process id the lock file names.
        holder: String,
    },
    /// A CSV file (samples.csv, pixels.csv) is malformed: a missing or
    /// duplicated column, a value that is not a number, NaN or infinite, or
    /// a value out of range.
    #[error("{path}{}: {message}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line number, where known.
        line: Option<u64>,
        /// What is wrong.
        message: String,
    },
    /// An in-memory calibration sample is unusable (non-finite value,
    /// non-positive depth).
    #[error("sample {index}: {message}")]
    InvalidSample {
        /// 0-based index of the sample.
        index: usize,
        /// What is wrong.
        message: String,
    },
    /// A YAML file (camera.yaml, laser.yaml) is malformed or misses a key.
    #[error("{path}: {message}")]
    Parse {
        /// The file, or `<string>` for text parsed from memory.
        path: PathBuf,
        /// What is wrong, naming the key.
        message: String,
    },
    /// Parameters that do not describe a usable camera or laser.
    #[error("invalid {what}: {message}")]
    InvalidParameters {
        /// `camera` or `laser`.
        what: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The iterative undistortion did not converge for this pixel.
    #[error(
        "undistortion did not converge for pixel ({u_px:.3}, {v_px:.3}): residual {residual:.3e} after {iterations} iterations"
    )]
    UndistortNotConverged {
        /// Pixel column.
        u_px: f64,
        /// Pixel row.
        v_px: f64,
        /// Remaining residual in normalized units.
        residual: f64,
        /// Iterations spent.
        iterations: usize,
    },
    /// A point that cannot be projected (behind the camera or not finite).
    #[error("point ({x_mm:.3}, {y_mm:.3}, {z_mm:.3}) mm cannot be projected: {reason}")]
    NotProjectable {
        /// x in the camera frame.
        x_mm: f64,
        /// y in the camera frame.
        y_mm: f64,
        /// z in the camera frame.
        z_mm: f64,
        /// Why.
        reason: &'static str,
    },
    /// The camera ray through a pixel does not meet the laser plane in front of the camera.
    #[error(
        "the ray through normalized ({u_n:.6}, {v_n:.6}) does not meet the laser plane in front of the camera (denominator {denominator:.3e})"
    )]
    NoIntersection {
        /// Normalized x.
        u_n: f64,
        /// Normalized y.
        v_n: f64,
        /// sin(alpha) - u_n cos(alpha) - v_n tan(beta): must be positive.
        denominator: f64,
    },
}

impl Error {
    /// Bad input (exit 2) or a failed job (exit 1).
    pub fn class(&self) -> ErrorClass {
        match self {
            Error::Io { .. }
            | Error::TooLarge { .. }
            | Error::OutputNotEmpty { .. }
            | Error::NotRegularFile { .. }
            | Error::NotRegularInput { .. }
            | Error::UnsafeManifest { .. }
            | Error::OutputOfAnotherCommand { .. }
            | Error::OutputLocked { .. }
            | Error::Csv { .. }
            | Error::InvalidSample { .. }
            | Error::Parse { .. }
            | Error::InvalidParameters { .. } => ErrorClass::BadInput,
            Error::UndistortNotConverged { .. }
            | Error::NotProjectable { .. }
            | Error::NoIntersection { .. } => ErrorClass::JobFailed,
        }
    }

    /// Whether [`Error::class`] is [`ErrorClass::BadInput`].
    pub fn is_bad_input(&self) -> bool {
        self.class() == ErrorClass::BadInput
    }
}

/// The message of a YAML parse error as a user reads it: one line with the
/// parser's location, in the parser's wording for users, without its advice
/// to programmers (which names the parser's own options).
pub fn yaml_message(error: &serde_saphyr::Error) -> String {
    let text = error.without_snippet().render_with_formatter(&serde_saphyr::UserMessageFormatter);
    text.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join("; ")
}

/// Significant digits of a number in engineering notation: enough for any
/// value a message quotes from a file or an option.
const NUM_SIGNIFICANT_DIGITS: i32 = 6;

/// A number as a message shows it: as written for everyday magnitudes, in
/// engineering notation beyond them (a mantissa of 1 to 999 and an exponent
/// that is a multiple of three), so that a value like 1e300 in a file reads
/// `1e300` in its error and not as 301 digits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let x = self.0;
        if !x.is_finite() || x == 0.0 || (1e-4..1e7).contains(&x.abs()) {
            return write!(f, "{x}");
        }
        let mut exponent = (x.abs().log10() / 3.0).floor() as i32 * 3;
        let mut mantissa = x / 10f64.powi(exponent);
        let integer_digits = |m: f64| {
            if m.abs() >= 100.0 {
                3
            } else if m.abs() >= 10.0 {
                2
            } else {
                1
            }
        };
        let mut decimals = (NUM_SIGNIFICANT_DIGITS - integer_digits(mantissa)).max(0) as usize;
        let mut text = format!("{mantissa:.decimals$}");
        // Rounding may carry the mantissa to 1000: one step up.
        if text.trim_start_matches('-').starts_with("1000") {
            exponent += 3;
            mantissa /= 1000.0;
            decimals = (NUM_SIGNIFICANT_DIGITS - 1) as usize;
            text = format!("{mantissa:.decimals$}");
        }
        if text.contains('.') {
            text = text.trim_end_matches('0').trim_end_matches('.').to_string();
        }
        write!(f, "{text}e{exponent}")
    }
}

/// A value with its standard deviation, `value +- sigma`, both to the
/// decimals that give the sigma two significant figures (a sigma known to
/// 10 % shows no more): `19.07012 +- 0.00040`, `412.5 +- 1.5`, `412 +- 15`.
/// Without a finite, positive sigma, the value alone to `decimals`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlusMinus {
    /// The value.
    pub value: f64,
    /// Its standard deviation, if known.
    pub sigma: Option<f64>,
    /// Decimals of the value when there is no sigma to size them.
    pub decimals: usize,
}

impl std::fmt::Display for PlusMinus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let value = self.value;
        match self.sigma.filter(|s| s.is_finite() && *s > 0.0) {
            Some(sigma) => {
                // Two significant figures; at most 9 decimals (a sigma below
                // 1e-9 of any unit here is a rounding error, not a measurement).
                let decimals = (1.0 - sigma.log10().floor()).clamp(0.0, 9.0) as usize;
                write!(f, "{value:.decimals$} +- {sigma:.decimals$}")
            }
            None => write!(f, "{value:.*}", self.decimals),
        }
    }
}

#[cfg(test)]
mod num_tests {
    use super::Num;

    #[test]
    fn a_huge_or_tiny_number_prints_in_engineering_notation() {
        assert_eq!(Num(1e300).to_string(), "1e300");
        assert_eq!(Num(1e301).to_string(), "10e300");
        assert_eq!(Num(-2.5e-9).to_string(), "-2.5e-9");
        assert_eq!(Num(1.23456789e8).to_string(), "123.457e6");
        assert_eq!(Num(999_999_999.0).to_string(), "1e9");
        assert_eq!(Num(4.5e-5).to_string(), "45e-6");
        assert_eq!(Num(412.5).to_string(), "412.5");
        assert_eq!(Num(0.0).to_string(), "0");
        assert_eq!(Num(f64::NAN).to_string(), "NaN");
    }

    #[test]
    fn a_sigma_shows_two_significant_figures_and_its_value_as_many_decimals() {
        use super::PlusMinus;
        let pm = |value, sigma, decimals| PlusMinus { value, sigma, decimals }.to_string();
        assert_eq!(pm(19.07012, Some(0.0004), 3), "19.07012 +- 0.00040");
        assert_eq!(pm(19.07012, Some(0.05), 3), "19.070 +- 0.050");
        assert_eq!(pm(412.5, Some(1.5), 3), "412.5 +- 1.5");
        assert_eq!(pm(412.7, Some(15.3), 3), "413 +- 15");
        assert_eq!(pm(1.0, None, 2), "1.00");
        assert_eq!(pm(1.0, Some(0.0), 2), "1.00");
    }
}

#[cfg(test)]
mod yaml_tests {
    #![allow(clippy::unwrap_used)]

    #[test]
    fn a_duplicate_key_is_named_without_the_parsers_advice() {
        let error = serde_saphyr::from_str::<serde_json::Value>("a: 1\na: 2\n").unwrap_err();
        let message = super::yaml_message(&error);
        assert!(message.contains("duplicate"), "{message}");
        assert!(!message.contains("Options") && !message.contains('\n'), "{message}");
    }
}
