//! laser.yaml with its `std_dev` block (FORMATS.md) reads back in alacs and
//! in a third-party YAML reader: ruamel.yaml, which rosbags brings into
//! `ALACS_PEER_PYTHON` (`.ci/run` installs it: `.ci/peers.txt`); without it
//! the alacs side still runs and the peer's side is skipped.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

use alacs::model::{LaserModel, LaserStdDev};

#[test]
fn the_std_dev_block_reads_back_in_alacs_and_in_ruamel_yaml() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("laser.yaml");
    let laser = LaserModel::seed_paper().with_slide_scale(0.9995);
    let std = LaserStdDev {
        alpha_deg: 0.009462790094289995,
        beta_deg: Some(0.0025806251163478346),
        l0_mm: 0.039710656994184974,
        slide_scale: Some(5.4039993894502285e-05),
        // Characters a plain YAML scalar would misread.
        source: "bootstrap over 6 board poses (200 replicates: \"camera\" re-calibrated # each)"
            .into(),
    };
    laser.to_yaml_file(&path, "a test: of the header", Some(&std)).unwrap();
    let (back, back_std) = LaserModel::from_yaml_file_with_std(&path).unwrap();
    assert_eq!(back, laser);
    assert_eq!(back_std.as_ref(), Some(&std));
    // The reader that ignores the block gives the same laser.
    assert_eq!(LaserModel::from_yaml_file(&path).unwrap(), laser);

    // A negative sigma is refused naming the file.
    let bad = dir.path().join("bad.yaml");
    let text = std::fs::read_to_string(&path).unwrap().replace("l0_mm: 0.0397", "l0_mm: -0.0397");
    std::fs::write(&bad, text).unwrap();
    let error = LaserModel::from_yaml_file_with_std(&bad).unwrap_err().to_string();
    assert!(error.contains("bad.yaml") && error.contains("std_dev"), "{error}");

    let Ok(python) = std::env::var("ALACS_PEER_PYTHON") else {
        eprintln!("SKIPPED ruamel.yaml: set ALACS_PEER_PYTHON (.ci/peers.txt)");
        return;
    };
    let script = r#"
import json, sys
from ruamel.yaml import YAML
with open(sys.argv[1]) as f:
    print(json.dumps(YAML(typ="safe").load(f)))
"#;
    let output = Command::new(python)
        .args(["-c", script])
        .arg(&path)
        .output()
        .expect("the peer Python runs");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let read: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(read["alpha_deg"].as_f64(), Some(laser.alpha_deg()));
    assert_eq!(read["slide_scale"].as_f64(), Some(laser.slide_scale));
    let block = &read["std_dev"];
    assert_eq!(block["alpha_deg"].as_f64(), Some(std.alpha_deg));
    assert_eq!(block["beta_deg"].as_f64(), std.beta_deg);
    assert_eq!(block["l0_mm"].as_f64(), Some(std.l0_mm));
    assert_eq!(block["slide_scale"].as_f64(), std.slide_scale);
    assert_eq!(block["source"].as_str(), Some(std.source.as_str()));
}
