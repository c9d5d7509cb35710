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
    /// With `--json`: what the command found before it failed (an object
    /// whose keys go beside "error"), e.g. the steps of `alacs rig check`.
    pub report: Option<serde_json::Value>,
}

/// Result of a command.
pub type CmdResult<T = ()> = Result<T, Failure>;

impl Failure {
    /// Whether standard output was closed under us (its reader ended): an
    /// `io::ErrorKind::BrokenPipe` anywhere in the error's chain.
    pub fn is_broken_pipe(&self) -> bool {
        self.error.chain().any(|cause| {
            cause
                .downcast_ref::<std::io::Error>()
                .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
        })
    }

    /// docs/FORMATS.md's failure object for `--json`:
    /// `{"error": {"exit_code": N, "message": "..."}}`.
    pub fn to_json(&self) -> serde_json::Value {
        let error =
            serde_json::json!({"exit_code": self.code, "message": format!("{:#}", self.error)});
        let mut object = match &self.report {
            Some(serde_json::Value::Object(report)) => report.clone(),
            _ => serde_json::Map::new(),
        };
        object.insert("error".into(), error);
        serde_json::Value::Object(object)
    }

    /// This failure with `context` (a file or folder) in front of its
    /// message, unless the message names it already ("ro/s: ro/s: ..." says
    /// nothing more).
    pub fn with_context(self, context: &std::path::Path) -> Self {
        let name = context.display().to_string();
        if format!("{:#}", self.error).contains(&name) {
            return self;
        }
        Self { error: self.error.context(name), ..self }
    }

    /// Unreadable or invalid input (exit 2).
    pub fn bad_input(error: impl Into<anyhow::Error>) -> Self {
        Self { code: BAD_INPUT, error: error.into(), report: None }
    }

    /// A job that failed on readable input (exit 1).
    pub fn job_failed(error: impl Into<anyhow::Error>) -> Self {
        Self { code: JOB_FAILED, error: error.into(), report: None }
    }
}

/// A library error that knows whether it is bad input or a failed job.
pub trait Classified: std::error::Error + Send + Sync + 'static {
    /// Its class, as the library says it.
    fn class(&self) -> alacs::model::ErrorClass;
}

macro_rules! classified {
    ($($error:ty),*) => {$(
        impl Classified for $error {
            fn class(&self) -> alacs::model::ErrorClass {
                <$error>::class(self)
            }
        }
    )*};
}

classified!(
    alacs::model::Error,
    alacs::vision::Error,
    alacs::board::Error,
    alacs::detect::Error,
    alacs::calib::Error,
    alacs::sim::Error,
    alacs::locate::Error,
    alacs::scanner::Error,
    alacs::eval::Error,
    alacs::ros::Error,
    alacs::rig::Error
);

impl<E: Classified> From<E> for Failure {
    fn from(error: E) -> Self {
        match error.class() {
            alacs::model::ErrorClass::BadInput => Self::bad_input(error),
            alacs::model::ErrorClass::JobFailed => Self::job_failed(error),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Failure;

    #[test]
    fn a_path_the_message_names_is_not_repeated_in_front_of_it() {
        let path = std::path::Path::new("ro/s");
        let named =
            Failure::bad_input(anyhow::anyhow!("ro/s: Permission denied")).with_context(path);
        assert_eq!(format!("{:#}", named.error), "ro/s: Permission denied");
        let unnamed = Failure::bad_input(anyhow::anyhow!("Permission denied")).with_context(path);
        assert_eq!(format!("{:#}", unnamed.error), "ro/s: Permission denied");
    }
}
