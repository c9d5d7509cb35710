//! The folders eval writes into. Every file goes through `alacs-model`'s
//! [`OutputDir`] (atomic writes, a lock, a manifest naming the command, the
//! earlier run's stale files removed), so that one command's report does
//! not replace another's (a scan report over a calibration report's
//! `index.html`, say).

use std::path::Path;

use alacs_model::io::{MANIFEST_FILE, OutputDir};

use crate::Result;

/// Which command fills a folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum OutputKind {
    /// `evaluate calibration`.
    EvaluateCalibration,
    /// `evaluate accuracy`.
    EvaluateAccuracy,
    /// `report calibration`.
    ReportCalibration,
    /// `report scan`.
    ReportScan,
    /// `demo` (its two reports in sub-folders of their own kinds).
    Demo,
}

impl OutputKind {
    /// The command's name, as its folder's manifest records it.
    pub fn as_str(self) -> &'static str {
        match self {
            OutputKind::EvaluateCalibration => "evaluate calibration",
            OutputKind::EvaluateAccuracy => "evaluate accuracy",
            OutputKind::ReportCalibration => "report calibration",
            OutputKind::ReportScan => "report scan",
            OutputKind::Demo => "demo",
        }
    }
}

/// Opens `dir` for the output of the command `kind`: refused (unless
/// `force`) when it holds files the command did not write, those of no
/// alacs command or of another command ([`OutputDir::create`]).
pub fn open_output(dir: &Path, kind: OutputKind, force: bool) -> Result<OutputDir> {
    Ok(OutputDir::create(dir, kind.as_str(), force)?)
}

/// Opens the sub-folder `name` of `parent` for the command `kind`, as
/// [`open_output`]; `parent` lists the sub-folder's manifest, so that it
/// counts the sub-folder as its own.
pub fn open_sub_output(
    parent: &mut OutputDir,
    name: &str,
    kind: OutputKind,
    force: bool,
) -> Result<OutputDir> {
    parent.file(&format!("{name}/{MANIFEST_FILE}"))?;
    open_output(&parent.path().join(name), kind, force)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_folder_of_another_command_is_refused_unless_forced() {
        let dir = tempfile_dir("kinds");
        let mut out = open_output(&dir, OutputKind::ReportCalibration, false).unwrap();
        out.write("index.html", "calibration").unwrap();
        out.finish().unwrap();
        // The same command may rewrite its folder; another may not.
        open_output(&dir, OutputKind::ReportCalibration, false).unwrap();
        let refused = open_output(&dir, OutputKind::ReportScan, false).unwrap_err();
        assert!(refused.is_bad_input(), "{refused}");
        assert!(refused.to_string().contains("report calibration"), "{refused}");
        let mut out = open_output(&dir, OutputKind::ReportScan, true).unwrap();
        out.write("index.html", "scan").unwrap();
        out.finish().unwrap();
        let manifest = std::fs::read_to_string(dir.join(MANIFEST_FILE)).unwrap();
        assert!(manifest.starts_with("# alacs report scan\n"), "{manifest}");
        std::fs::remove_dir_all(&dir).ok();
    }

    fn tempfile_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("alacs-eval-{name}-{}", std::process::id()));
        std::fs::remove_dir_all(&dir).ok();
        dir
    }
}
