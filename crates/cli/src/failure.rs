//! A failed command: the error and the exit code FORMATS.md gives it.

/// Exit code 1: the input was readable but the job failed.
pub const JOB_FAILED: u8 = 1;
/// Exit code 2: bad usage or unreadable input.
pub const BAD_INPUT: u8 = 2;

/// A command's failure.
pub struct Failure {
    /// Process exit code.
    pub code: u8,
    /// What went wrong, printed with its context chain.
    pub error: anyhow::Error,
}

/// Result of a command.
pub type CmdResult<T = ()> = Result<T, Failure>;

impl Failure {
    /// This failure with `context` (a file or folder) in front of its message.
    pub fn with_context(self, context: &std::path::Path) -> Self {
        Self { error: self.error.context(context.display().to_string()), ..self }
    }

    /// Unreadable or invalid input (exit 2).
    pub fn bad_input(error: impl Into<anyhow::Error>) -> Self {
        Self { code: BAD_INPUT, error: error.into() }
    }

    /// A job that failed on readable input (exit 1).
    pub fn job_failed(error: impl Into<anyhow::Error>) -> Self {
        Self { code: JOB_FAILED, error: error.into() }
    }
}

impl From<alacs::calib::Error> for Failure {
    fn from(error: alacs::calib::Error) -> Self {
        if error.is_bad_input() { Self::bad_input(error) } else { Self::job_failed(error) }
    }
}

impl From<alacs::vision::Error> for Failure {
    fn from(error: alacs::vision::Error) -> Self {
        alacs::calib::Error::from(error).into()
    }
}

impl From<alacs::model::Error> for Failure {
    fn from(error: alacs::model::Error) -> Self {
        use alacs::model::Error as E;
        match error {
            E::Io { .. } | E::Parse { .. } | E::InvalidParameters { .. } => Self::bad_input(error),
            _ => Self::job_failed(error),
        }
    }
}

impl From<alacs::sim::Error> for Failure {
    fn from(error: alacs::sim::Error) -> Self {
        use alacs::sim::Error as E;
        match error {
            E::Model(e) => e.into(),
            E::Calib(e) => e.into(),
            E::InvalidOptions(_) => Self::bad_input(error),
            _ => Self::job_failed(error),
        }
    }
}

impl From<alacs::locate::Error> for Failure {
    fn from(error: alacs::locate::Error) -> Self {
        use alacs::locate::Error as E;
        match error {
            E::Model(e) => e.into(),
            E::Vision(e) => e.into(),
            _ => Self::bad_input(error),
        }
    }
}

impl From<alacs::scanner::Error> for Failure {
    fn from(error: alacs::scanner::Error) -> Self {
        use alacs::scanner::Error as E;
        match error {
            E::Sim(e) => e.into(),
            E::InvalidInput(_) => Self::bad_input(error),
            E::Locate(ref e) if e.is_bad_input() => Self::bad_input(error),
            // Devices that failed, outputs that could not be written.
            _ => Self::job_failed(error),
        }
    }
}

impl From<alacs::eval::Error> for Failure {
    fn from(error: alacs::eval::Error) -> Self {
        use alacs::eval::Error as E;
        match error {
            E::Calib(e) => e.into(),
            E::Model(e) => e.into(),
            e if e.is_bad_input() => Self::bad_input(e),
            e => Self::job_failed(e),
        }
    }
}
