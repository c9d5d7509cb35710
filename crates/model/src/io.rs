//! The one way alacs touches the file system for its outputs, and bounded
//! reads for its inputs (docs/FORMATS.md, "Files and folders").
//!
//! - [`write_atomic`]: every file is written to a temporary file in the same
//!   folder, flushed to disk and renamed over the target, so a failure (disk
//!   full, a file-size limit, a crash) leaves the old file whole and never a
//!   half-written or empty one.
//! - [`OutputDir`]: a folder a command fills. A folder that holds files the
//!   command did not write is refused unless forced; a command's own earlier
//!   files (listed in the folder's manifest, [`MANIFEST_FILE`]) are replaced,
//!   and those it does not write again are removed, so no stale file stays.
//! - [`read_bounded`]: a text input read whole, refused past a size limit
//!   (`/dev/zero` or a mistyped path to a video is an error, not an abort).

use std::collections::BTreeSet;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The manifest an [`OutputDir`] keeps of the files it wrote, one name a line.
pub const MANIFEST_FILE: &str = ".alacs-output";

/// Largest text input (YAML, CSV, JSON) read: 256 MiB, far beyond any
/// session, scan or samples file (10 million samples take about 800 MB as
/// CSV and are refused; a million take 80 MB).
pub const MAX_TEXT_INPUT_BYTES: u64 = 256 << 20;

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |error| Error::Io { path: path.to_path_buf(), error }
}

/// A temporary file in `dir` for an output that will be renamed into place:
/// readable by everyone, as files a program writes usually are (tempfile's
/// own default, 0600, would keep a recording or a report from the user
/// a robot's other programs run as).
pub fn temp_file_in(dir: &Path, suffix: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".alacs-").suffix(suffix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    builder.tempfile_in(dir)
}

/// Writes `path` atomically: `write` fills a temporary file beside it, which
/// is flushed, synced and renamed over `path` only when everything
/// succeeded. On any error the temporary file is removed and an existing
/// `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let temp = temp_file_in(dir, ".tmp").map_err(io_error(path))?;
    let mut writer = BufWriter::new(temp);
    write(&mut writer).map_err(io_error(path))?;
    let temp = writer
        .into_inner()
        .map_err(|e| Error::Io { path: path.to_path_buf(), error: e.into_error() })?;
    temp.as_file().sync_all().map_err(io_error(path))?;
    temp.persist(path).map_err(|e| Error::Io { path: path.to_path_buf(), error: e.error })?;
    Ok(())
}

/// [`write_atomic`] of a whole byte string.
pub fn write_file(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    write_atomic(path, |w| w.write_all(contents.as_ref()))
}

/// Reads a text input whole, refusing one larger than `max_bytes` (naming
/// the file and the limit) instead of filling memory.
pub fn read_bounded(path: &Path, max_bytes: u64) -> Result<String> {
    let bytes = read_bytes_bounded(path, max_bytes)?;
    String::from_utf8(bytes).map_err(|_| Error::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"),
    })
}

/// Reads a binary input whole (an image), refusing one larger than
/// `max_bytes` as [`read_bounded`] does.
pub fn read_bytes_bounded(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let file = std::fs::File::open(path).map_err(io_error(path))?;
    // A regular file says its size: refused before a byte is read. Others
    // (a pipe, /dev/zero) are read up to the limit.
    if file.metadata().is_ok_and(|m| m.is_file() && m.len() > max_bytes) {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit: max_bytes });
    }
    let mut bytes = Vec::new();
    let read = file.take(max_bytes + 1).read_to_end(&mut bytes).map_err(io_error(path))?;
    if read as u64 > max_bytes {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit: max_bytes });
    }
    Ok(bytes)
}

/// [`read_bounded`] with [`MAX_TEXT_INPUT_BYTES`].
pub fn read_text(path: &Path) -> Result<String> {
    read_bounded(path, MAX_TEXT_INPUT_BYTES)
}

/// A folder that one command fills with its files (a report, a simulated
/// session, a scan folder).
///
/// [`OutputDir::create`] refuses a folder with files the command did not
/// write (exit 2 in docs/FORMATS.md) unless `force`. The command then
/// writes each file with [`OutputDir::write`] or [`OutputDir::write_with`]
/// (atomically), and [`OutputDir::finish`] removes what an earlier run
/// wrote and this one did not, and records the new manifest.
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    earlier: BTreeSet<String>,
    written: BTreeSet<String>,
}

impl OutputDir {
    /// Opens (creating it if needed) `dir` for a command's output. A folder
    /// holding anything but this project's earlier outputs (per its
    /// manifest) is refused with [`Error::OutputNotEmpty`] unless `force`.
    pub fn create(dir: &Path, force: bool) -> Result<Self> {
        if dir.exists() && !dir.is_dir() {
            return Err(Error::Io {
                path: dir.to_path_buf(),
                error: std::io::Error::other("exists and is not a folder"),
            });
        }
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
        let manifest = dir.join(MANIFEST_FILE);
        let earlier: BTreeSet<String> = match std::fs::read_to_string(&manifest) {
            Ok(text) => text.lines().filter(|l| !l.is_empty()).map(str::to_owned).collect(),
            Err(_) => BTreeSet::new(),
        };
        if !force {
            let mut foreign = Vec::new();
            for entry in std::fs::read_dir(dir).map_err(io_error(dir))? {
                let entry = entry.map_err(io_error(dir))?;
                let name = entry.file_name().to_string_lossy().into_owned();
                // `.alacs-*` files are alacs' own bookkeeping (the manifest, a
                // folder's owner, a temporary file a crash left behind).
                let ours = name.starts_with(".alacs-")
                    || earlier.contains(&name)
                    || earlier.iter().any(|e| e.starts_with(&format!("{name}/")));
                if !ours {
                    foreign.push(name);
                }
            }
            if !foreign.is_empty() {
                foreign.sort();
                return Err(Error::OutputNotEmpty {
                    path: dir.to_path_buf(),
                    example: foreign[0].clone(),
                    count: foreign.len(),
                });
            }
        }
        Ok(Self { dir: dir.to_path_buf(), earlier, written: BTreeSet::new() })
    }

    /// Creates `dir` as [`OutputDir::create`] does, lets `write` fill it and
    /// finishes it; the files written, in name order. Errors of `write` (any
    /// error type that a model error converts into) come back unchanged,
    /// and the folder's earlier files are then left as they were.
    pub fn fill<E: From<Error>>(
        dir: &Path,
        force: bool,
        write: impl FnOnce(&mut OutputDir) -> std::result::Result<(), E>,
    ) -> std::result::Result<Vec<PathBuf>, E> {
        let mut out = Self::create(dir, force)?;
        write(&mut out)?;
        Ok(out.finish()?)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// The path of `name` (relative, `/`-separated) inside the folder,
    /// creating its parent folders.
    pub fn file(&mut self, name: &str) -> Result<PathBuf> {
        let path = self.dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io_error(parent))?;
        }
        self.written.insert(name.to_owned());
        Ok(path)
    }

    /// Writes `name` atomically with `write`.
    pub fn write_with(
        &mut self,
        name: &str,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<PathBuf> {
        let path = self.file(name)?;
        write_atomic(&path, write)?;
        Ok(path)
    }

    /// Writes `name` atomically with `contents`.
    pub fn write(&mut self, name: &str, contents: impl AsRef<[u8]>) -> Result<PathBuf> {
        self.write_with(name, |w| w.write_all(contents.as_ref()))
    }

    /// Removes the earlier run's files that this run did not write, and
    /// records what this run wrote in the manifest. Returns the files
    /// written, in name order.
    pub fn finish(self) -> Result<Vec<PathBuf>> {
        for stale in self.earlier.difference(&self.written) {
            let path = self.dir.join(stale);
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(error) => return Err(Error::Io { path, error }),
            }
            // Folders the stale file leaves empty go too (never the output folder).
            let mut parent = path.parent();
            while let Some(p) = parent {
                if p == self.dir || std::fs::remove_dir(p).is_err() {
                    break;
                }
                parent = p.parent();
            }
        }
        let mut manifest = String::new();
        for name in &self.written {
            manifest.push_str(name);
            manifest.push('\n');
        }
        write_file(&self.dir.join(MANIFEST_FILE), manifest)?;
        Ok(self.written.iter().map(|n| self.dir.join(n)).collect())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn an_oversized_file_is_refused_by_its_size_before_it_is_read() {
        // Regression: a 300 MB scan.yaml was read up to the 256 MiB limit
        // (260 MiB peak RSS, crates/cli/benches/peak_memory.rs) before
        // it was refused. A sparse 1 TiB file takes no disk.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.yaml");
        std::fs::File::create(&path).unwrap().set_len(1 << 40).unwrap();
        let error = read_text(&path).unwrap_err();
        assert!(matches!(error, Error::TooLarge { .. }), "{error}");
        assert!(error.to_string().contains("huge.yaml"), "{error}");
    }

    #[cfg(unix)]
    #[test]
    fn written_files_are_readable_by_others_not_only_their_owner() {
        // Regression: every output (reports, scan folders, calibrations,
        // manifests) was created 0600, tempfile's default, so a robot's
        // other users could not read it.
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("laser.yaml");
        write_file(&path, "alpha_deg: 19\n").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o044, 0o044, "mode {mode:o}");
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("laser.yaml");
        write_file(&path, "old\n").unwrap();
        let failed = write_atomic(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(matches!(failed, Err(Error::Io { .. })));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "no temporary file left behind");
    }

    #[test]
    fn output_dir_refuses_foreign_files_and_removes_its_stale_ones() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("report");
        let mut first = OutputDir::create(&out, false).unwrap();
        first.write("index.html", "a").unwrap();
        first.write("images/frame00.jpg", "b").unwrap();
        first.write("images/frame01.jpg", "c").unwrap();
        first.finish().unwrap();
        // Its own earlier files: replaced; what is not written again goes.
        let mut second = OutputDir::create(&out, false).unwrap();
        second.write("index.html", "a2").unwrap();
        second.write("images/frame00.jpg", "b2").unwrap();
        second.finish().unwrap();
        assert!(!out.join("images/frame01.jpg").exists());
        assert_eq!(std::fs::read_to_string(out.join("index.html")).unwrap(), "a2");
        // A file it did not write: refused, unless forced.
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let refused = OutputDir::create(&out, false).unwrap_err();
        assert!(refused.to_string().contains("notes.txt"), "{refused}");
        assert!(OutputDir::create(&out, true).is_ok());
        assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
        // Regression: a failed run's bookkeeping (written before the manifest)
        // made the next run refuse the folder.
        std::fs::remove_file(out.join("notes.txt")).unwrap();
        std::fs::write(out.join(".alacs-kind"), "report scan\n").unwrap();
        assert!(OutputDir::create(&out, false).is_ok());
    }

    #[test]
    fn bounded_reads_refuse_large_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.csv");
        std::fs::write(&path, vec![b'1'; 100]).unwrap();
        assert!(read_bounded(&path, 100).is_ok());
        let error = read_bounded(&path, 99).unwrap_err();
        assert!(matches!(error, Error::TooLarge { limit: 99, .. }), "{error}");
    }
}
