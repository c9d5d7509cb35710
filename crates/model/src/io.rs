//! The one way alacs touches the file system for its outputs, and bounded
//! reads for its inputs (docs/FORMATS.md, "Files and folders written").
//!
//! - [`write_atomic`] / [`OutputFile`]: a file the user named (`-o FILE`) is
//!   written to a temporary file beside its real target (a symbolic link is
//!   followed), flushed, given the old file's mode and owner, and renamed
//!   over it, so a failure (disk full, a file-size limit, a crash) leaves the
//!   old file whole and never a half-written one. Anything that is not a
//!   regular file (a device such as `/dev/null`, a FIFO, a socket, a folder)
//!   is refused, never replaced: the program may run as root.
//! - [`OutputDir`]: a folder one command fills. It is locked while written
//!   ([`LOCK_FILE`]), it records the command and the files it wrote
//!   ([`MANIFEST_FILE`]), a folder holding files the command did not write
//!   or another command's output is refused unless forced, and a later run
//!   removes what it does not write again, only plain files inside the
//!   folder: a manifest naming `..`, an absolute path or a link is refused.
//! - [`read_bounded`]: an input read whole, refused past a size limit, and
//!   refused when it is not a regular file (a FIFO would block forever).

use std::collections::BTreeSet;
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Component, Path, PathBuf};

use crate::{Error, Result};

/// The manifest an [`OutputDir`] keeps: the command that wrote the folder
/// (first line, `# alacs <command>`) and the files it wrote, one relative
/// name a line.
pub const MANIFEST_FILE: &str = ".alacs-output";

/// The lock an [`OutputDir`] holds while it is written: an advisory lock
/// (`flock`) on this file, which names the writer's process id. The
/// operating system drops the lock when the process dies, so a lock left by
/// a crashed run is taken over.
pub const LOCK_FILE: &str = ".alacs-lock";

/// Largest text input (YAML, CSV, JSON) read: 256 MiB, far beyond any
/// session, scan or samples file (10 million samples take about 800 MB as
/// CSV and are refused; a million take 80 MB).
pub const MAX_TEXT_INPUT_BYTES: u64 = 256 << 20;

/// Largest manifest read: 16 MiB holds far more names than any command
/// writes (a 64-frame scan lists about 70).
const MAX_MANIFEST_BYTES: u64 = 16 << 20;

/// Symbolic links followed to an output's real file before giving up (as
/// Linux's own limit, `MAXSYMLINKS`).
const MAX_LINK_HOPS: usize = 40;

/// The manifest's first line before the command's name.
const MANIFEST_HEADER: &str = "# alacs ";

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |error| Error::Io { path: path.to_path_buf(), error }
}

/// What a file system entry is, in words, for a refusal.
fn kind_of(file_type: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if file_type.is_char_device() || file_type.is_block_device() {
            return "a device";
        }
        if file_type.is_fifo() {
            return "a FIFO";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() {
        "a folder"
    } else if file_type.is_symlink() {
        "a symbolic link"
    } else {
        "not a regular file"
    }
}

/// A scratch folder ([`OutputDir::scratch`]), removed when dropped.
#[derive(Debug)]
pub struct ScratchDir {
    dir: tempfile::TempDir,
    _registered: Temporary,
}

impl ScratchDir {
    /// The folder.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
}

/// Temporary files and scratch folders being written now, which
/// [`remove_temporaries`] removes when a signal ends the process.
static TEMPORARIES: std::sync::Mutex<std::collections::BTreeSet<PathBuf>> =
    std::sync::Mutex::new(std::collections::BTreeSet::new());

/// A temporary file or folder registered in [`TEMPORARIES`] while it lives.
#[derive(Debug)]
struct Temporary(PathBuf);

impl Temporary {
    fn register(path: &Path) -> Self {
        if let Ok(mut set) = TEMPORARIES.lock() {
            set.insert(path.to_path_buf());
        }
        Self(path.to_path_buf())
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        if let Ok(mut set) = TEMPORARIES.lock() {
            set.remove(&self.0);
        }
    }
}

/// Removes every temporary file and scratch folder being written now: for
/// a signal handler that then ends the process, so that an interrupted
/// write leaves nothing behind (the targets keep their old contents).
pub fn remove_temporaries() {
    let paths: Vec<PathBuf> = match TEMPORARIES.lock() {
        Ok(set) => set.iter().cloned().collect(),
        Err(poisoned) => poisoned.into_inner().iter().cloned().collect(),
    };
    for path in paths {
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_dir()) {
            let _ = std::fs::remove_dir_all(&path);
        } else {
            let _ = std::fs::remove_file(&path);
        }
    }
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

/// The real file behind `path` (symbolic links followed) and what is there
/// now: `None` when nothing is.
fn resolve_links(path: &Path) -> Result<(PathBuf, Option<std::fs::Metadata>)> {
    let mut real = path.to_path_buf();
    for _ in 0..MAX_LINK_HOPS {
        match std::fs::symlink_metadata(&real) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let target = std::fs::read_link(&real).map_err(io_error(path))?;
                real = match real.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            Ok(meta) => return Ok((real, Some(meta))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((real, None)),
            Err(error) => return Err(Error::Io { path: path.to_path_buf(), error }),
        }
    }
    Err(Error::Io {
        path: path.to_path_buf(),
        error: std::io::Error::other(format!("more than {MAX_LINK_HOPS} symbolic links")),
    })
}

/// Whether an existing output may be replaced: only a regular file.
fn check_replaceable(path: &Path, meta: Option<&std::fs::Metadata>) -> Result<()> {
    match meta {
        Some(meta) if !meta.is_file() => {
            Err(Error::NotRegularFile { path: path.to_path_buf(), what: kind_of(meta.file_type()) })
        }
        _ => Ok(()),
    }
}

/// One output file being written: a temporary file beside the target's real
/// file, put in its place by [`OutputFile::commit`]; dropped without a
/// commit, the temporary file is removed and the target left as it was.
#[derive(Debug)]
pub struct OutputFile {
    /// The path the caller named, for messages.
    path: PathBuf,
    /// The file that is replaced (the named path with its links followed).
    real: PathBuf,
    temp: BufWriter<tempfile::NamedTempFile>,
    /// The temporary file's registration for [`remove_temporaries`].
    _registered: Temporary,
}

impl OutputFile {
    /// Starts writing `path`, the user's output: a symbolic link is
    /// followed to its real file; an existing real file keeps its mode and
    /// (where the process may set it) its owner; anything but a regular
    /// file is refused with [`Error::NotRegularFile`].
    pub fn create(path: &Path) -> Result<Self> {
        let (real, meta) = resolve_links(path)?;
        Self::create_resolved(path, real, meta.as_ref())
    }

    /// Starts writing `path` inside an output folder: nothing is followed,
    /// and an existing entry that is not a regular file (a link among them)
    /// is refused, so a link planted in the folder cannot send a write
    /// outside it.
    fn create_in_folder(path: &Path) -> Result<Self> {
        let meta = match std::fs::symlink_metadata(path) {
            Ok(meta) => Some(meta),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(error) => return Err(Error::Io { path: path.to_path_buf(), error }),
        };
        Self::create_resolved(path, path.to_path_buf(), meta.as_ref())
    }

    fn create_resolved(
        path: &Path,
        real: PathBuf,
        meta: Option<&std::fs::Metadata>,
    ) -> Result<Self> {
        check_replaceable(path, meta)?;
        let dir = match real.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let temp = temp_file_in(dir, ".tmp").map_err(io_error(path))?;
        let registered = Temporary::register(temp.path());
        if let Some(meta) = meta {
            keep_mode_and_owner(temp.as_file(), meta).map_err(io_error(path))?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            real,
            temp: BufWriter::new(temp),
            _registered: registered,
        })
    }

    /// The path the caller named.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes and syncs the temporary file and renames it over the target.
    pub fn commit(self) -> Result<()> {
        let path = self.path;
        let temp = self
            .temp
            .into_inner()
            .map_err(|e| Error::Io { path: path.clone(), error: e.into_error() })?;
        temp.as_file().sync_all().map_err(io_error(&path))?;
        temp.persist(&self.real).map_err(|e| Error::Io { path: path.clone(), error: e.error })?;
        Ok(())
    }
}

impl std::io::Seek for OutputFile {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.temp.seek(pos)
    }
}

impl Write for OutputFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.temp.write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.temp.flush()
    }
}

/// Gives the temporary file the mode and owner of the file it replaces. An
/// owner the process may not give (an unprivileged user replacing another's
/// file) is left as the process's own; the mode is kept without the
/// set-id bits then.
fn keep_mode_and_owner(temp: &File, old: &std::fs::Metadata) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt as _, PermissionsExt as _};
        let owned = std::os::unix::fs::fchown(temp, Some(old.uid()), Some(old.gid())).is_ok();
        let mode = if owned { old.mode() & 0o7777 } else { old.mode() & 0o777 };
        temp.set_permissions(std::fs::Permissions::from_mode(mode))?;
    }
    #[cfg(not(unix))]
    temp.set_permissions(old.permissions())?;
    Ok(())
}

/// Writes `path` atomically: `write` fills an [`OutputFile`], which replaces
/// the target only when everything succeeded. On any error the temporary
/// file is removed and an existing `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let mut file = OutputFile::create(path)?;
    write(&mut file).map_err(io_error(path))?;
    file.commit()
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

/// Opens an input that must be a regular file (links followed): a FIFO, a
/// device or a folder is refused before it is opened, since opening or
/// reading a FIFO blocks until a writer comes.
pub fn open_input(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(io_error(path))?;
    if !meta.is_file() {
        return Err(Error::NotRegularInput {
            path: path.to_path_buf(),
            what: kind_of(meta.file_type()),
        });
    }
    File::open(path).map_err(io_error(path))
}

/// [`open_input`], refusing a file larger than `max_bytes` (naming the
/// file and the limit).
pub fn open_bounded(path: &Path, max_bytes: u64) -> Result<File> {
    let file = open_input(path)?;
    if file.metadata().is_ok_and(|m| m.len() > max_bytes) {
        return Err(Error::TooLarge { path: path.to_path_buf(), limit: max_bytes });
    }
    Ok(file)
}

/// Reads a binary input whole (an image), refusing one larger than
/// `max_bytes` or one that is not a regular file.
pub fn read_bytes_bounded(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let file = open_bounded(path, max_bytes)?;
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

/// Why a manifest entry is not a plain relative name inside its folder,
/// or `None` when it is one.
fn unsafe_entry(name: &str) -> Option<&'static str> {
    let path = Path::new(name);
    if name.is_empty() {
        return Some("empty");
    }
    if path.is_absolute() || path.has_root() {
        return Some("an absolute path");
    }
    for component in path.components() {
        match component {
            Component::Normal(_) => {}
            Component::ParentDir => return Some("a path out of the folder (`..`)"),
            Component::CurDir => return Some("not a plain name (`.`)"),
            Component::RootDir | Component::Prefix(_) => return Some("an absolute path"),
        }
    }
    None
}

/// Checks that `name`'s parent folders inside `dir` are real folders, not
/// links (a link would lead a write or a removal out of the folder).
fn check_parents(dir: &Path, name: &str, manifest: bool) -> Result<()> {
    let mut at = dir.to_path_buf();
    let components: Vec<_> = Path::new(name).components().collect();
    for component in components.iter().take(components.len().saturating_sub(1)) {
        at.push(component);
        match std::fs::symlink_metadata(&at) {
            Ok(meta) if meta.is_dir() => {}
            Ok(meta) => {
                let what = kind_of(meta.file_type());
                return Err(if manifest {
                    Error::UnsafeManifest {
                        path: dir.join(MANIFEST_FILE),
                        entry: name.to_owned(),
                        reason: format!("behind {what} ({})", at.display()),
                    }
                } else {
                    Error::NotRegularFile { path: at, what }
                });
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(error) => return Err(Error::Io { path: at, error }),
        }
    }
    Ok(())
}

/// The command and the files an earlier run recorded in a folder's manifest.
#[derive(Debug, Default)]
struct Manifest {
    /// The command that wrote it; `None` for a manifest without a header.
    command: Option<String>,
    files: BTreeSet<String>,
}

impl Manifest {
    /// Reads `dir`'s manifest (an empty one where there is none), refusing
    /// one that is a link or names anything but plain files inside `dir`.
    fn read(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST_FILE);
        match std::fs::symlink_metadata(&path) {
            Ok(meta) if !meta.is_file() => {
                return Err(Error::UnsafeManifest {
                    path,
                    entry: MANIFEST_FILE.to_owned(),
                    reason: kind_of(meta.file_type()).to_owned(),
                });
            }
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Self::default()),
            Err(error) => return Err(Error::Io { path, error }),
        }
        let text = read_bounded(&path, MAX_MANIFEST_BYTES)?;
        let mut manifest = Self::default();
        for (k, line) in text.lines().enumerate() {
            if k == 0
                && let Some(command) = line.strip_prefix(MANIFEST_HEADER)
            {
                manifest.command = Some(command.trim().to_owned());
                continue;
            }
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            if let Some(reason) = unsafe_entry(line) {
                return Err(Error::UnsafeManifest {
                    path,
                    entry: line.to_owned(),
                    reason: reason.to_owned(),
                });
            }
            check_parents(dir, line, true)?;
            if let Ok(meta) = std::fs::symlink_metadata(dir.join(line))
                && !meta.is_file()
            {
                return Err(Error::UnsafeManifest {
                    path,
                    entry: line.to_owned(),
                    reason: kind_of(meta.file_type()).to_owned(),
                });
            }
            manifest.files.insert(line.to_owned());
        }
        Ok(manifest)
    }
}

/// The lock on an output folder, held while it is written and released
/// when dropped (the lock file is removed then).
#[derive(Debug)]
struct FolderLock {
    file: File,
    path: PathBuf,
}

impl FolderLock {
    /// Takes `dir`'s lock, or refuses with [`Error::OutputLocked`] naming
    /// the process that holds it.
    fn take(dir: &Path) -> Result<Self> {
        let path = dir.join(LOCK_FILE);
        // A lock file removed by its holder between our open and our lock
        // is a stale inode: open again (a few times; each round is a race
        // another writer won).
        for _ in 0..8 {
            if let Ok(meta) = std::fs::symlink_metadata(&path)
                && !meta.is_file()
            {
                return Err(Error::NotRegularFile { path, what: kind_of(meta.file_type()) });
            }
            let mut file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io_error(&path))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    let mut holder = String::new();
                    let _ = (&file).take(64).read_to_string(&mut holder);
                    return Err(Error::OutputLocked {
                        path: dir.to_path_buf(),
                        holder: holder.trim().to_owned(),
                    });
                }
                Err(std::fs::TryLockError::Error(error)) => return Err(Error::Io { path, error }),
            }
            if !same_file(&file, &path) {
                continue;
            }
            file.set_len(0).map_err(io_error(&path))?;
            writeln!(file, "{}", std::process::id()).map_err(io_error(&path))?;
            return Ok(Self { file, path });
        }
        Err(Error::OutputLocked { path: dir.to_path_buf(), holder: String::new() })
    }
}

/// Whether the open `file` is still the file at `path`.
fn same_file(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt as _;
        match (file.metadata(), std::fs::symlink_metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, path);
        true
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        // Removed while still locked, so no writer takes a file about to go.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

/// A folder that one command fills with its files (a report, a simulated
/// session, a scan folder).
///
/// [`OutputDir::create`] locks the folder and refuses it (exit 2 in
/// docs/FORMATS.md) unless `force` when it holds files the command did not
/// write or another command's output. The command then writes each file
/// with [`OutputDir::write`] or [`OutputDir::write_with`] (atomically), and
/// [`OutputDir::finish`] removes what an earlier run wrote and this one did
/// not, records the new manifest and releases the lock.
#[derive(Debug)]
pub struct OutputDir {
    dir: PathBuf,
    command: String,
    earlier: BTreeSet<String>,
    written: BTreeSet<String>,
    _lock: FolderLock,
}

impl OutputDir {
    /// Opens (creating it if needed) `dir` for the output of `command` (its
    /// name, `simulate scan` say). Refused unless `force`: a folder holding
    /// anything but this command's earlier outputs
    /// ([`Error::OutputNotEmpty`]) or another command's output
    /// ([`Error::OutputOfAnotherCommand`]). Always refused: a folder another
    /// process is writing ([`Error::OutputLocked`]) and a manifest naming
    /// anything but plain files inside the folder ([`Error::UnsafeManifest`]).
    pub fn create(dir: &Path, command: &str, force: bool) -> Result<Self> {
        if let Ok(meta) = std::fs::metadata(dir)
            && !meta.is_dir()
        {
            return Err(Error::Io {
                path: dir.to_path_buf(),
                error: std::io::Error::other("exists and is not a folder"),
            });
        }
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
        let lock = FolderLock::take(dir)?;
        let manifest = Manifest::read(dir)?;
        if !force {
            if !manifest.files.is_empty() && manifest.command.as_deref() != Some(command) {
                return Err(Error::OutputOfAnotherCommand {
                    path: dir.to_path_buf(),
                    owner: manifest.command.unwrap_or_else(|| "an older alacs".to_owned()),
                    command: command.to_owned(),
                });
            }
            let mut foreign = Vec::new();
            for entry in std::fs::read_dir(dir).map_err(io_error(dir))? {
                let entry = entry.map_err(io_error(dir))?;
                let name = entry.file_name().to_string_lossy().into_owned();
                // `.alacs-*` files are alacs' own bookkeeping (the manifest,
                // the lock, a temporary file a crash left behind).
                let ours = name.starts_with(".alacs-")
                    || manifest.files.contains(&name)
                    || manifest.files.iter().any(|e| e.starts_with(&format!("{name}/")));
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
        Ok(Self {
            dir: dir.to_path_buf(),
            command: command.to_owned(),
            earlier: manifest.files,
            written: BTreeSet::new(),
            _lock: lock,
        })
    }

    /// Creates `dir` as [`OutputDir::create`] does, lets `write` fill it and
    /// finishes it; the files written, in name order. Errors of `write` (any
    /// error type that a model error converts into) come back unchanged,
    /// and the folder's earlier files are then left as they were.
    pub fn fill<E: From<Error>>(
        dir: &Path,
        command: &str,
        force: bool,
        write: impl FnOnce(&mut OutputDir) -> std::result::Result<(), E>,
    ) -> std::result::Result<Vec<PathBuf>, E> {
        let mut out = Self::create(dir, command, force)?;
        write(&mut out)?;
        Ok(out.finish()?)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.dir
    }

    /// A hidden scratch folder inside this one for intermediate files (a
    /// rendered session read back as a user's is), removed when dropped, on
    /// error paths too: work in progress stays inside the output folder.
    pub fn scratch(&self) -> Result<ScratchDir> {
        let dir = tempfile::Builder::new()
            .prefix(".scratch-")
            .tempdir_in(&self.dir)
            .map_err(io_error(&self.dir))?;
        let registered = Temporary::register(dir.path());
        Ok(ScratchDir { dir, _registered: registered })
    }

    /// The path of `name` (relative, `/`-separated, no `..`) inside the
    /// folder, creating its parent folders; a parent that is a link is refused.
    pub fn file(&mut self, name: &str) -> Result<PathBuf> {
        if let Some(reason) = unsafe_entry(name) {
            return Err(Error::Io {
                path: self.dir.join(name),
                error: std::io::Error::other(format!("not a file inside the folder: {reason}")),
            });
        }
        let path = self.dir.join(name);
        check_parents(&self.dir, name, false)?;
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(io_error(parent))?;
        }
        check_parents(&self.dir, name, false)?;
        self.written.insert(name.to_owned());
        Ok(path)
    }

    /// Starts writing `name` as an [`OutputFile`] (put in place by its
    /// `commit`); an existing entry that is not a regular file is refused.
    pub fn create_file(&mut self, name: &str) -> Result<OutputFile> {
        let path = self.file(name)?;
        OutputFile::create_in_folder(&path)
    }

    /// Writes `name` atomically with `write`.
    pub fn write_with(
        &mut self,
        name: &str,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<PathBuf> {
        let mut file = self.create_file(name)?;
        write(&mut file).map_err(io_error(file.path()))?;
        let path = file.path().to_path_buf();
        file.commit()?;
        Ok(path)
    }

    /// Writes `name` atomically with `contents`.
    pub fn write(&mut self, name: &str, contents: impl AsRef<[u8]>) -> Result<PathBuf> {
        self.write_with(name, |w| w.write_all(contents.as_ref()))
    }

    /// Removes the earlier run's files that this run did not write (plain
    /// files inside the folder only), records what this run wrote in the
    /// manifest and releases the folder. Returns the files written, in name
    /// order.
    pub fn finish(mut self) -> Result<Vec<PathBuf>> {
        let stale: Vec<String> = self.earlier.difference(&self.written).cloned().collect();
        for name in stale {
            // Checked when the manifest was read; again here, since the
            // folder may have changed while this run wrote.
            check_parents(&self.dir, &name, true)?;
            let path = self.dir.join(&name);
            match std::fs::symlink_metadata(&path) {
                Ok(meta) if meta.is_file() => {
                    std::fs::remove_file(&path).map_err(io_error(&path))?;
                }
                // Something else took the name since: not ours to remove.
                Ok(_) => continue,
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
        let mut manifest = format!("{MANIFEST_HEADER}{}\n", self.command);
        for name in &self.written {
            manifest.push_str(name);
            manifest.push('\n');
        }
        let path = self.dir.join(MANIFEST_FILE);
        let mut file = OutputFile::create_in_folder(&path)?;
        file.write_all(manifest.as_bytes()).map_err(io_error(&path))?;
        file.commit()?;
        self.earlier.clear();
        Ok(self.written.iter().map(|n| self.dir.join(n)).collect())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn an_oversized_file_is_refused_by_its_size_before_it_is_read() {
        // A sparse 1 TiB file takes no disk.
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
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("laser.yaml");
        write_file(&path, "alpha_deg: 19\n").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o044, 0o044, "mode {mode:o}");
    }

    #[cfg(unix)]
    #[test]
    fn rewriting_a_file_keeps_its_mode() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("camera.yaml");
        std::fs::write(&path, "old").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
        write_file(&path, "new").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o640, "mode {mode:o}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
    }

    #[cfg(unix)]
    #[test]
    fn writing_a_link_writes_its_target_and_keeps_the_link() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("real")).unwrap();
        let target = dir.path().join("real/laser.yaml");
        std::fs::write(&target, "old").unwrap();
        let link = dir.path().join("laser.yaml");
        std::os::unix::fs::symlink("real/laser.yaml", &link).unwrap();
        write_file(&link, "new").unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        // A dangling link: its target is created.
        std::fs::remove_file(&target).unwrap();
        write_file(&link, "created").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "created");
    }

    #[cfg(unix)]
    #[test]
    fn a_device_fifo_socket_or_folder_is_never_replaced() {
        // Only nodes of the test's own folder: never a system path such as
        // /dev/null, which a regression run as root would replace.
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("fifo");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let folder = dir.path().join("folder");
        std::fs::create_dir(&folder).unwrap();
        let socket = dir.path().join("socket.yaml");
        let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
        let mut targets = vec![
            (fifo.clone(), "a FIFO"),
            (folder.clone(), "a folder"),
            (socket.clone(), "a socket"),
        ];
        // As root (CI): a null device of the test's own, and a link to it.
        let null = dir.path().join("null");
        let made_device = std::process::Command::new("mknod")
            .arg(&null)
            .args(["c", "1", "3"])
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if made_device {
            let link_to_null = dir.path().join("null.yaml");
            std::os::unix::fs::symlink(&null, &link_to_null).unwrap();
            targets.push((null.clone(), "a device"));
            targets.push((link_to_null, "a device"));
        }
        for (path, what) in &targets {
            let error = write_file(path, "x").unwrap_err();
            assert!(matches!(error, Error::NotRegularFile { .. }), "{error}");
            assert!(error.is_bad_input());
            let text = error.to_string();
            assert!(text.contains(what) && text.contains(&path.display().to_string()), "{text}");
        }
        use std::os::unix::fs::FileTypeExt as _;
        assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
        assert!(std::fs::symlink_metadata(&socket).unwrap().file_type().is_socket());
        if made_device {
            assert!(std::fs::symlink_metadata(&null).unwrap().file_type().is_char_device());
        }
        assert!(folder.is_dir());
        // Nothing left behind in the folder but what was there.
        let expected = if made_device { 5 } else { 3 };
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), expected);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_as_input_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("camera.yaml");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let error = read_text(&fifo).unwrap_err();
        assert!(matches!(error, Error::NotRegularInput { .. }), "{error}");
        assert!(error.to_string().contains("a FIFO"), "{error}");
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
        let mut first = OutputDir::create(&out, "report scan", false).unwrap();
        first.write("index.html", "a").unwrap();
        first.write("images/frame00.jpg", "b").unwrap();
        first.write("images/frame01.jpg", "c").unwrap();
        first.finish().unwrap();
        // Its own earlier files: replaced; what is not written again goes.
        let mut second = OutputDir::create(&out, "report scan", false).unwrap();
        second.write("index.html", "a2").unwrap();
        second.write("images/frame00.jpg", "b2").unwrap();
        second.finish().unwrap();
        assert!(!out.join("images/frame01.jpg").exists());
        assert_eq!(std::fs::read_to_string(out.join("index.html")).unwrap(), "a2");
        // A file it did not write: refused, unless forced.
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let refused = OutputDir::create(&out, "report scan", false).unwrap_err();
        assert!(refused.to_string().contains("notes.txt"), "{refused}");
        assert!(OutputDir::create(&out, "report scan", true).is_ok());
        assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
        // Bookkeeping a crashed run left (a temporary file) is alacs' own.
        std::fs::remove_file(out.join("notes.txt")).unwrap();
        std::fs::write(out.join(".alacs-x.tmp"), "").unwrap();
        assert!(OutputDir::create(&out, "report scan", false).is_ok());
        // The lock is released and removed when the folder is done.
        assert!(!out.join(LOCK_FILE).exists());
    }

    #[test]
    fn another_commands_folder_is_refused_unless_forced() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("scan");
        OutputDir::fill(&out, "scan", false, |o| o.write("camera.yaml", "calibrated").map(drop))
            .unwrap();
        let refused = OutputDir::create(&out, "bag export", false).unwrap_err();
        assert!(matches!(refused, Error::OutputOfAnotherCommand { .. }), "{refused}");
        let text = refused.to_string();
        assert!(text.contains("`alacs scan`") && text.contains("--force"), "{text}");
        assert_eq!(std::fs::read_to_string(out.join("camera.yaml")).unwrap(), "calibrated");
        // An old manifest without its command is another command's too.
        std::fs::write(out.join(MANIFEST_FILE), "camera.yaml\n").unwrap();
        assert!(OutputDir::create(&out, "scan", false).is_err());
        assert!(OutputDir::create(&out, "scan", true).is_ok());
    }

    #[cfg(unix)]
    #[test]
    fn a_crafted_manifest_removes_nothing_outside_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let victims = dir.path().join("victimdir");
        std::fs::create_dir(&victims).unwrap();
        let victim = victims.join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::os::unix::fs::symlink(&victims, out.join("sub")).unwrap();
        std::os::unix::fs::symlink(&victim, out.join("link.txt")).unwrap();
        for entry in [
            "../victimdir/victim.txt".to_owned(),
            victim.display().to_string(),
            "sub/victim.txt".to_owned(),
            "link.txt".to_owned(),
        ] {
            std::fs::write(out.join(MANIFEST_FILE), format!("# alacs simulate samples\n{entry}\n"))
                .unwrap();
            for force in [false, true] {
                let refused = OutputDir::create(&out, "simulate samples", force).unwrap_err();
                assert!(matches!(refused, Error::UnsafeManifest { .. }), "{entry}: {refused}");
                assert!(refused.to_string().contains(&entry), "{refused}");
            }
        }
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        // A link planted where a file will be written is refused, not followed.
        std::fs::remove_file(out.join(MANIFEST_FILE)).unwrap();
        let mut forced = OutputDir::create(&out, "simulate samples", true).unwrap();
        assert!(forced.write("link.txt", "x").is_err());
        assert!(forced.write("sub/victim.txt", "x").is_err());
        drop(forced);
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
    }

    #[test]
    fn a_folder_being_written_is_locked_and_a_dead_writers_lock_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("scan");
        let first = OutputDir::create(&out, "simulate scan", false).unwrap();
        let refused = OutputDir::create(&out, "simulate scan", true).unwrap_err();
        assert!(matches!(refused, Error::OutputLocked { .. }), "{refused}");
        assert!(refused.to_string().contains(&std::process::id().to_string()), "{refused}");
        assert!(refused.is_bad_input());
        drop(first);
        // A lock file whose process is gone holds no lock: taken over.
        std::fs::write(out.join(LOCK_FILE), "999999999\n").unwrap();
        OutputDir::create(&out, "simulate scan", false).unwrap().finish().unwrap();
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
