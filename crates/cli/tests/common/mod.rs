//! Helpers shared by the `alacs` program's tests: scratch folders and the
//! command lines several tests run.

// Each test binary uses some of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh, empty folder `name` under the tests' temporary folder.
pub fn scratch(name: impl AsRef<Path>) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `contents` to the file `name` in `dir`, returning its path.
pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

/// A command-line value: a path, or any text.
pub type Arg<'a> = &'a dyn AsRef<Path>;

/// A path (or any text) as a command-line argument.
pub fn arg(value: &(impl AsRef<Path> + ?Sized)) -> String {
    value.as_ref().to_str().unwrap().to_owned()
}

/// The arguments of `template`, split at whitespace, with each `{}` replaced
/// by the next of `values` (which may hold spaces): `cmdline("stripe --image
/// {}", &[&image])`.
pub fn cmdline(template: &str, values: &[Arg]) -> Vec<String> {
    let mut values = values.iter();
    let args: Vec<String> = template
        .split_whitespace()
        .map(|word| match word {
            "{}" => arg(*values.next().expect("a value for every {}")),
            _ => word.to_owned(),
        })
        .collect();
    assert!(values.next().is_none(), "more values than {{}} in `{template}`");
    args
}

/// `alacs triangulate` of pixels.csv with camera.yaml and laser.yaml.
pub fn triangulate(camera: Arg, laser: Arg, slide_mm: &str, pixels: Arg) -> Vec<String> {
    let template = "triangulate --camera {} --laser {} --slide-mm {} --pixels {}";
    cmdline(template, &[camera, laser, &slide_mm, pixels])
}

/// `alacs localize` of a scan folder with camera.yaml and laser.yaml.
pub fn localize(scan: Arg, camera: Arg, laser: Arg) -> Vec<String> {
    cmdline("localize --scan {} --camera {} --laser {}", &[scan, camera, laser])
}

/// `alacs report scan` of a scan folder with camera.yaml and laser.yaml into `out`.
pub fn report_scan(scan: Arg, camera: Arg, laser: Arg, out: Arg) -> Vec<String> {
    cmdline("report scan --scan {} --camera {} --laser {} --out {}", &[scan, camera, laser, out])
}

/// `args` followed by `extra`.
pub fn with(mut args: Vec<String>, extra: &[&str]) -> Vec<String> {
    args.extend(extra.iter().map(|a| (*a).to_owned()));
    args
}

/// `alacs evaluate calibration` of samples.csv into `out`.
pub fn evaluate_calibration(samples: Arg, out: Arg) -> Vec<String> {
    cmdline("evaluate calibration --samples {} --out {}", &[samples, out])
}
