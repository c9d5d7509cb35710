//! The folders eval writes into. Every file goes through `alacs-model`'s
//! [`OutputDir`] (atomic writes, a manifest, the earlier run's stale files
//! removed); [`open_output`] adds which command owns the folder, so that
//! one command's report does not replace another's (a scan report over a
//! calibration report's `index.html`, say).

use std::path::Path;

use alacs_model::io::{MANIFEST_FILE, OutputDir};

use crate::Result;

/// The file (listed in the manifest) naming the command that owns a folder.
pub const KIND_FILE: &str = ".alacs-kind";

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
    /// The command's name, as written in [`KIND_FILE`].
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
/// `force`) with [`alacs_model::Error::OutputNotEmpty`] when it holds files
/// the command did not write: files of no alacs command, or those of
/// another command (another kind, or no kind recorded).
pub fn open_output(dir: &Path, kind: OutputKind, force: bool) -> Result<OutputDir> {
    if !force {
        let earlier: Vec<String> = std::fs::read_to_string(dir.join(MANIFEST_FILE))
            .map(|text| text.lines().filter(|l| !l.is_empty()).map(str::to_owned).collect())
            .unwrap_or_default();
        let owner = std::fs::read_to_string(dir.join(KIND_FILE)).unwrap_or_default();
        let theirs: Vec<&String> = earlier.iter().filter(|name| *name != KIND_FILE).collect();
        if owner.trim() != kind.as_str() && !theirs.is_empty() {
            return Err(alacs_model::Error::OutputNotEmpty {
                path: dir.to_path_buf(),
                example: theirs[0].clone(),
                count: theirs.len(),
            }
            .into());
        }
    }
    let mut out = OutputDir::create(dir, force)?;
    out.write(KIND_FILE, format!("{}\n", kind.as_str()))?;
    Ok(out)
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
        assert!(refused.to_string().contains("index.html"), "{refused}");
        let mut out = open_output(&dir, OutputKind::ReportScan, true).unwrap();
        out.write("index.html", "scan").unwrap();
        out.finish().unwrap();
        assert_eq!(std::fs::read_to_string(dir.join(KIND_FILE)).unwrap(), "report scan\n");
        std::fs::remove_dir_all(&dir).ok();
    }

    fn tempfile_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("alacs-eval-{name}-{}", std::process::id()));
        std::fs::remove_dir_all(&dir).ok();
        dir
    }
}
