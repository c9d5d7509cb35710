//! What `alacs` writes, removes and prints around its results (issue
//! "Nothing outside the output folder is ever touched", items 1-3): each
//! test is named for the defect it pins. Everything happens in a scratch
//! folder under the target directory, never on a system path, also when
//! CI runs the suite as root (a device node is made there with mknod).

// Test helpers outside #[test] functions may fail loudly too.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::os::unix::fs::{FileTypeExt as _, PermissionsExt as _};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{arg, scratch};

mod common;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn alacs(args: &[&str]) -> Output {
    Command::new(ALACS).args(args).stdin(Stdio::null()).output().unwrap()
}

fn context(output: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        output.status.code(),
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// A small simulated samples folder in `dir/name`; its samples.csv.
fn samples(dir: &Path, name: &str) -> PathBuf {
    let out = dir.join(name);
    let o = alacs(&["simulate", "samples", "--out", &arg(&out), "--views", "4"]);
    assert!(o.status.success(), "{}", context(&o));
    out.join("samples.csv")
}

/// `calibrate laser --samples S -o TARGET`.
fn calibrate_to(samples: &Path, target: &Path) -> Output {
    alacs(&["calibrate", "laser", "--samples", &arg(samples), "-o", &arg(target)])
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

#[test]
fn output_over_a_device_or_fifo_is_refused_and_the_node_kept() {
    let dir = scratch("outputs-device");
    let samples = samples(&dir, "sim");
    let fifo = dir.join("fifo.yaml");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let mut targets = vec![(fifo.clone(), "a FIFO")];
    // As root (CI): a null device of our own, in the scratch folder.
    let null = dir.join("null");
    if is_root()
        && Command::new("mknod").arg(&null).args(["c", "1", "3"]).status().unwrap().success()
    {
        targets.push((null.clone(), "a device"));
    }
    let folder = dir.join("folder.yaml");
    std::fs::create_dir(&folder).unwrap();
    targets.push((folder.clone(), "a folder"));
    for (target, what) in &targets {
        let o = calibrate_to(&samples, target);
        assert_eq!(o.status.code(), Some(2), "{}", context(&o));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(stderr.contains(what) && stderr.contains(&arg(target)), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
    }
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    if targets.len() == 3 {
        assert!(std::fs::symlink_metadata(&null).unwrap().file_type().is_char_device());
    }
    assert!(folder.is_dir());
    assert!(names(&dir).iter().all(|n| !n.starts_with(".alacs-")), "{:?}", names(&dir));
}

#[test]
fn output_to_a_symlink_writes_its_target_and_keeps_the_link() {
    let dir = scratch("outputs-symlink");
    let samples = samples(&dir, "sim");
    std::fs::create_dir(dir.join("calibrations")).unwrap();
    let real = dir.join("calibrations/laser.yaml");
    std::fs::write(&real, "old").unwrap();
    let link = dir.join("laser.yaml");
    std::os::unix::fs::symlink("calibrations/laser.yaml", &link).unwrap();
    let o = calibrate_to(&samples, &link);
    assert!(o.status.success(), "{}", context(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(&real).unwrap().contains("alpha"));
}

#[test]
fn in_place_convert_keeps_the_files_mode_and_owner() {
    let dir = scratch("outputs-mode");
    let sim = dir.join("scan");
    let o = alacs(&["simulate", "scan", "--out", &arg(&sim), "--scale", "0.2", "--seed", "1"]);
    assert!(o.status.success(), "{}", context(&o));
    let camera = dir.join("camera.yaml");
    std::fs::copy(sim.join("camera.yaml"), &camera).unwrap();
    std::fs::set_permissions(&camera, std::fs::Permissions::from_mode(0o640)).unwrap();
    let o = alacs(&["convert", "camera", "--input", &arg(&camera), "-o", &arg(&camera)]);
    assert!(o.status.success(), "{}", context(&o));
    let mode = std::fs::metadata(&camera).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o640, "mode {mode:o}");
    // As root (CI): a file another user owns stays theirs.
    if is_root()
        && Command::new("chown").args(["1234:1234", &arg(&camera)]).status().unwrap().success()
    {
        let o = alacs(&["convert", "camera", "--input", &arg(&camera), "-o", &arg(&camera)]);
        assert!(o.status.success(), "{}", context(&o));
        use std::os::unix::fs::MetadataExt as _;
        let meta = std::fs::metadata(&camera).unwrap();
        assert_eq!((meta.uid(), meta.gid()), (1234, 1234));
        assert_eq!(meta.permissions().mode() & 0o777, 0o640);
    }
}

#[test]
fn a_crafted_manifest_deletes_nothing_outside_the_output_folder() {
    let dir = scratch("outputs-manifest");
    let victims = dir.join("victimdir");
    std::fs::create_dir(&victims).unwrap();
    let victim = victims.join("victim.txt");
    std::fs::write(&victim, "keep").unwrap();
    let out = dir.join("out");
    samples(&dir, "out");
    std::os::unix::fs::symlink(&victims, out.join("sub")).unwrap();
    let manifest = out.join(".alacs-output");
    for entry in [
        "../victimdir/victim.txt".to_owned(),
        arg(&victim),
        "sub/victim.txt".to_owned(),
        "sub".to_owned(),
    ] {
        std::fs::write(&manifest, format!("# alacs simulate samples\n{entry}\n")).unwrap();
        for force in [false, true] {
            let mut args = vec!["simulate", "samples", "--out", out.to_str().unwrap()];
            args.extend(force.then_some("--force"));
            let o = alacs(&args);
            assert_eq!(o.status.code(), Some(2), "{entry}: {}", context(&o));
            assert!(String::from_utf8_lossy(&o.stderr).contains(&entry), "{}", context(&o));
        }
    }
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
    assert_eq!(names(&victims), ["victim.txt"]);
}

#[test]
fn another_commands_output_folder_is_refused_without_force() {
    let dir = scratch("outputs-other-command");
    let scan = dir.join("scan");
    let o = alacs(&["simulate", "scan", "--out", &arg(&scan), "--scale", "0.2", "--seed", "2"]);
    assert!(o.status.success(), "{}", context(&o));
    let before = names(&scan);
    let o = alacs(&["simulate", "samples", "--out", &arg(&scan)]);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("simulate scan") && stderr.contains("--force"), "{stderr}");
    assert_eq!(names(&scan), before, "the scan folder is left as it was");
}

#[test]
fn a_folder_being_written_is_locked_against_a_second_writer() {
    let dir = scratch("outputs-lock");
    let out = dir.join("scan");
    std::fs::create_dir(&out).unwrap();
    // This process holds the lock, as a running `alacs` would.
    let lock = std::fs::File::create(out.join(".alacs-lock")).unwrap();
    lock.try_lock().unwrap();
    std::fs::write(out.join(".alacs-lock"), format!("{}\n", std::process::id())).unwrap();
    let o = alacs(&["simulate", "samples", "--out", &arg(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(&std::process::id().to_string()),
        "{}",
        context(&o)
    );
    assert_eq!(names(&out), [".alacs-lock"]);
    // The holder is gone: its lock file is taken over.
    drop(lock);
    let o = alacs(&["simulate", "samples", "--out", &arg(&out)]);
    assert!(o.status.success(), "{}", context(&o));
    assert_eq!(names(&out), [".alacs-output", "samples.csv", "truth.json"]);
}

#[test]
fn two_simulations_into_one_folder_never_mix() {
    let dir = scratch("outputs-race");
    let out = dir.join("scan");
    let start = |seed: &str| {
        Command::new(ALACS)
            .args(["simulate", "scan", "--out", &arg(&out), "--scale", "0.2", "--seed", seed])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (start("3"), start("4"));
    let (a, b) = (a.wait_with_output().unwrap(), b.wait_with_output().unwrap());
    let codes = [a.status.code(), b.status.code()];
    // Either both ran one after the other, or the second was refused; the
    // folder is whole either way: its truth matches its scan.yaml.
    assert!(codes.iter().all(|c| matches!(c, Some(0 | 2))), "{codes:?}");
    let scan_yaml = std::fs::read_to_string(out.join("scan.yaml")).unwrap();
    let manifest = std::fs::read_to_string(out.join(".alacs-output")).unwrap();
    assert!(manifest.starts_with("# alacs simulate scan\n"), "{manifest}");
    for line in manifest.lines().skip(1) {
        assert!(out.join(line).is_file(), "{line} listed and missing");
    }
    assert!(scan_yaml.contains("frames"), "{scan_yaml}");
    assert!(!out.join(".alacs-lock").exists());
}

#[test]
fn a_full_or_closed_standard_error_loses_no_work() {
    let dir = scratch("outputs-stderr");
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    // `simulate scan` notes its progress on standard error.
    let out = dir.join("scan");
    let o = Command::new(ALACS)
        .args(["simulate", "scan", "--out", &arg(&out), "--scale", "0.2", "--seed", "5"])
        .stderr(Stdio::from(full))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stdout));
    assert!(out.join("scan.yaml").is_file());
    // Closed: a reader that went away (`2>&1 | head -1`). A bad command
    // line (exit 2) and a calibration's warning both write there.
    let samples = samples(&dir, "sim");
    for args in [
        vec!["calibrate".to_owned(), "laser".to_owned(), "--samples".to_owned(), arg(&samples)],
        vec!["calibrate".to_owned(), "laser".to_owned(), "--no-such-option".to_owned()],
    ] {
        let mut child = Command::new(ALACS)
            .args(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stderr.take());
        let status = child.wait().unwrap();
        assert!(matches!(status.code(), Some(0 | 2)), "{args:?}: {status:?}");
    }
}

#[test]
fn a_file_size_limit_fails_the_write_and_leaves_no_temporary_file() {
    let dir = scratch("outputs-ulimit");
    let samples = samples(&dir, "sim");
    let target = dir.join("laser.yaml");
    std::fs::write(&target, "old").unwrap();
    let script = format!(
        "ulimit -f 0; exec {} calibrate laser --samples {} -o {}",
        ALACS,
        arg(&samples),
        arg(&target)
    );
    let o = Command::new("sh").args(["-c", &script]).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("laser.yaml"), "{}", context(&o));
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
    assert!(names(&dir).iter().all(|n| !n.starts_with(".alacs-")), "{:?}", names(&dir));
}

/// A signal in the middle of a write (SIGTERM while frames are being
/// encoded) leaves no temporary file behind and exits 143 (128 + 15).
#[test]
fn a_signal_mid_write_leaves_no_temporary_file() {
    let dir = scratch("outputs-signal");
    let out = dir.join("scan");
    let mut child = Command::new(ALACS)
        .args(["simulate", "scan", "--scale", "1", "--out", &arg(&out)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for a frame being written (its temporary file), then stop it.
    let writing =
        |d: &Path| names(d).iter().any(|n| n.starts_with(".alacs-") && n.ends_with(".tmp"));
    let start = std::time::Instant::now();
    while !(out.is_dir() && writing(&out)) {
        assert!(start.elapsed().as_secs() < 60, "no temporary file seen in {}", out.display());
        assert!(child.try_wait().unwrap().is_none(), "the scan ended before a frame was seen");
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let pid = child.id().to_string();
    assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(143), "{}", context(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("interrupted"), "{}", context(&o));
    assert!(!writing(&out), "{:?}", names(&out));
}

/// Issue 43 item 10: an error is one line on standard error whatever its
/// text holds: a newline in a path is escaped, a rig.toml syntax error
/// names its line and column instead of quoting the file over five lines.
#[test]
fn an_error_is_one_line_even_with_a_newline_in_a_path() {
    let dir = scratch("one_line_errors");
    let odd = dir.join("a\nb");
    std::fs::create_dir_all(&odd).unwrap();
    let o = alacs(&["localize", "--scan", &arg(&odd), "--camera", "c.yaml", "--laser", "l.yaml"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    assert_eq!(stderr.trim_end().lines().count(), 1, "{}", context(&o));
    assert!(stderr.contains("a\\nb"), "{}", context(&o));
    let rig = dir.join("rig.toml");
    std::fs::write(&rig, "[slide]\ndriver = \"grbl\"\nport = \n").unwrap();
    let o = alacs(&["rig", "check", "--rig", &arg(&rig)]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{}", context(&o));
    assert_eq!(stderr.trim_end().lines().count(), 1, "{}", context(&o));
    assert!(stderr.contains("line 3, column"), "{}", context(&o));
}
