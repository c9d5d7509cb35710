//! `alacs rig check` and `alacs scan --rig` against an emulated GRBL 1.1
//! controller on a pseudo-terminal (`devices/grbl_emulator.py`) and the
//! simulator's camera; rig.toml's errors. Needs `python3` (or
//! `ALACS_PYTHON`).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

/// The emulator, stopped when dropped.
struct Emulator {
    child: Child,
    port: String,
    log: PathBuf,
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn emulator(dir: &Path, options: &[&str]) -> Emulator {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../devices/grbl_emulator.py");
    let python = std::env::var("ALACS_PYTHON").unwrap_or_else(|_| "python3".into());
    let log = dir.join("received.log");
    let mut child = Command::new(python)
        .arg(script)
        .args(["--time-scale", "0.2", "--log"])
        .arg(&log)
        .args(options)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3 runs the GRBL emulator");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    Emulator { child, port: first.trim().to_string(), log }
}

/// rig.toml for a GRBL slide and laser on `port` and a simulated camera.
fn rig_toml(dir: &Path, port: &str) -> PathBuf {
    let path = dir.join("rig.toml");
    std::fs::write(
        &path,
        format!(
            "[slide]\ndriver = \"grbl\"\nport = \"{port}\"\nfeed_mm_per_min = 6000.0\n\
             command_timeout_s = 0.5\nmove_timeout_s = 2.0\n\
             [laser]\ndriver = \"grbl-spindle\"\n\
             [camera]\ndriver = \"sim\"\n"
        ),
    )
    .unwrap();
    path
}

fn alacs(args: &[&str]) -> Output {
    Command::new(ALACS).args(args).output().expect("alacs runs")
}

fn json(output: &Output) -> Value {
    let text = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("{e}: {text}"))
}

#[test]
fn rig_check_against_an_emulated_grbl_reports_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let grbl = emulator(dir.path(), &[]);
    let rig = rig_toml(dir.path(), &grbl.port);
    let output =
        alacs(&["rig", "check", "--rig", rig.to_str().unwrap(), "--scale", "0.25", "--json"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    let report = json(&output);
    assert_eq!(report["passed"], true);
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 10, "{report}");
    for step in steps {
        assert_eq!(step["ok"], true, "{step}");
        assert!(step["seconds"].as_f64().unwrap() >= 0.0);
        assert!(!step["detail"].as_str().unwrap().is_empty());
    }
    assert_eq!(steps[1]["step"], "home");
    assert_eq!(steps[9]["device"], "camera");
}

#[test]
fn a_controller_that_stops_answering_mid_scan_exits_1_naming_the_slide_with_m5_last() {
    let dir = tempfile::tempdir().unwrap();
    // Line 1 $H, 2 $$ (the laser's settings checked), 3 M5 (laser off at
    // connect), 4 the first move, 5 M5 (metering there with the laser off),
    // 6 its M3: silent from then on, so the second move never ends.
    let grbl = emulator(dir.path(), &["--silent-after", "6"]);
    let rig = rig_toml(dir.path(), &grbl.port);
    let out = dir.path().join("scan");
    let output = alacs(&[
        "scan",
        "--rig",
        rig.to_str().unwrap(),
        "--scale",
        "0.25",
        "--seed",
        "4",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    let message = json(&output)["error"]["message"].as_str().unwrap().to_string();
    assert!(message.starts_with("slide error at frame 1"), "{message}");
    assert!(message.contains(&grbl.port), "{message}");
    let received = std::fs::read_to_string(&grbl.log).unwrap();
    assert_eq!(received.lines().last(), Some("M5"), "{received}");
    assert!(!out.exists(), "no scan folder for a failed scan");
}

#[test]
fn rig_check_names_the_device_and_step_that_failed() {
    let dir = tempfile::tempdir().unwrap();
    // Line 1 $H, 2 $$, 3 M5, 4 the move to 0 mm, 5 the move to 100 mm:
    // silent after its `ok`, so it never reports standing there.
    let grbl = emulator(dir.path(), &["--silent-after", "5"]);
    let rig = rig_toml(dir.path(), &grbl.port);
    let output =
        alacs(&["rig", "check", "--rig", rig.to_str().unwrap(), "--scale", "0.25", "--json"]);
    assert_eq!(output.status.code(), Some(1));
    let report = json(&output);
    assert_eq!(report["passed"], false);
    let message = report["error"]["message"].as_str().unwrap();
    assert!(message.contains("the slide failed at `move to 100 mm`"), "{message}");
    let steps = report["steps"].as_array().unwrap();
    let last = steps.last().unwrap();
    assert_eq!(last["step"], "switch off after the failure", "{report}");
}

#[test]
fn rig_check_refuses_a_controller_in_laser_mode_naming_the_setting() {
    // $32=1: GRBL powers the spindle output (the laser) only while the axes
    // move, so every frame at a standing slide would be dark.
    let dir = tempfile::tempdir().unwrap();
    let grbl = emulator(dir.path(), &["--setting", "32=1"]);
    let rig = rig_toml(dir.path(), &grbl.port);
    let output =
        alacs(&["rig", "check", "--rig", rig.to_str().unwrap(), "--scale", "0.25", "--json"]);
    assert_eq!(output.status.code(), Some(1), "{}", String::from_utf8_lossy(&output.stderr));
    let report = json(&output);
    assert_eq!(report["passed"], false);
    let message = report["error"]["message"].as_str().unwrap();
    assert!(message.contains("$32=1") && message.contains("$32=0"), "{message}");
}

#[test]
fn a_bad_rig_toml_exits_2_naming_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("[slide]\ndriver = \"grbl\"\n", "[slide] port"),
        ("[slide]\ndriver = \"stepper\"\n", "unknown variant `stepper`"),
        ("[slide]\ndriver = \"sim\"\nstroke_mm = -5.0\n", "[slide] stroke_mm"),
        ("[slide]\ndriver = \"sim\"\nstroke_mn = 5.0\n", "unknown field `stroke_mn`"),
        ("[slide]\ndriver = \"sim\"\n[laser]\ndriver = \"grbl-spindle\"\n", "[laser] driver"),
        (
            "[slide]\ndriver = \"sim\"\n[laser]\ndriver = \"sim\"\noff_command = \"M5\\n$H\"\n",
            "[laser] off_command",
        ),
        ("[slide]\ndriver = \"sim\"\n[rgbd]\nalacs_from_rgbd = [0, 0, 1e9, 0, 0, 0]\n", "[rgbd]"),
        ("[slide]\ndriver = \"sim\"\n[scan]\nmode = \"zigzag\"\n", "unknown variant `zigzag`"),
        (
            "[slide]\ndriver = \"sim\"\n[scan]\nsweep_speed_mm_per_s = 0.0\n",
            "[scan] sweep_speed_mm_per_s",
        ),
        ("[slide]\ndriver = \"sim\"\n[scan]\nmax_smear_px = nan\n", "[scan] max_smear_px"),
        ("[laser]\ndriver = \"sim\"\n", "missing field `slide`"),
        ("not toml at all [", "rig.toml"),
    ];
    for (text, expected) in cases {
        let path = dir.path().join("rig.toml");
        std::fs::write(&path, text).unwrap();
        for args in [
            vec!["rig", "check", "--rig", path.to_str().unwrap()],
            vec!["scan", "--rig", path.to_str().unwrap()],
        ] {
            let output = alacs(&args);
            let stderr = String::from_utf8_lossy(&output.stderr);
            assert_eq!(output.status.code(), Some(2), "{text:?}: {stderr}");
            assert!(stderr.contains("rig.toml"), "{text:?}: {stderr}");
            assert!(stderr.contains(expected), "{text:?}: expected `{expected}` in {stderr}");
        }
    }
}
