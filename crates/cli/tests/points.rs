//! `alacs localize --points FILE.ply|.pcd` read back by third-party
//! readers: PyPI `plyfile` (PLY) and `pypcd4` (PCD), in the Python of
//! `ALACS_PEER_PYTHON` (`.ci/run` installs them: `.ci/peers.txt`). Without
//! that variable the reader checks say so and pass without running.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

#[test]
fn localize_points_are_read_by_plyfile_and_pypcd4_with_the_fruit_and_its_centre() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("scan");
    let status = Command::new(ALACS)
        .args(["simulate", "scan", "--seed", "4", "--scale", "0.25", "--out"])
        .arg(&scan)
        .output()
        .unwrap();
    assert!(status.status.success());
    let mut clouds = Vec::new();
    let mut answer = Value::Null;
    for name in ["points.ply", "points.PCD"] {
        let cloud = dir.path().join(name);
        let output = Command::new(ALACS)
            .arg("localize")
            .arg("--scan")
            .arg(&scan)
            .arg("--camera")
            .arg(scan.join("camera.yaml"))
            .arg("--laser")
            .arg(scan.join("laser.yaml"))
            .arg("--points")
            .arg(&cloud)
            .arg("--json")
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
        answer = serde_json::from_slice(&output.stdout).unwrap();
        clouds.push(cloud);
    }
    let fruit_points: u64 = answer["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["fruit_points"].as_u64().unwrap())
        .sum();
    assert!(fruit_points > 20, "{answer}");
    let centre: Vec<f64> = (0..3).map(|i| answer["position_mm"][i].as_f64().unwrap()).collect();

    let Ok(python) = std::env::var("ALACS_PEER_PYTHON") else {
        eprintln!("SKIPPED the third-party readers: set ALACS_PEER_PYTHON (.ci/peers.txt)");
        return;
    };
    let script = r#"
import json, sys
from plyfile import PlyData
from pypcd4 import PointCloud
ply = PlyData.read(sys.argv[1])
v = ply["vertex"]
c = ply["fruit_centre"][0]
pcd = PointCloud.from_path(sys.argv[2]).numpy()
print(json.dumps({
    "ply_points": len(v), "ply_fruit": int(v["fruit"].sum()),
    "ply_frames": sorted(set(int(f) for f in v["frame"])),
    "ply_centre": [float(c["x"]), float(c["y"]), float(c["z"])],
    "ply_comments": ply.comments,
    "pcd_points": int(pcd.shape[0]), "pcd_fruit": int(pcd[:, 4].sum()),
    "pcd_first": [float(x) for x in pcd[0, :3]], "ply_first": [float(v["x"][0]), float(v["y"][0]), float(v["z"][0])],
}))
"#;
    let output = Command::new(python)
        .args(["-c", script])
        .arg(&clouds[0])
        .arg(&clouds[1])
        .output()
        .expect("the peer Python runs");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let read: Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(read["ply_fruit"].as_u64(), Some(fruit_points), "{read}");
    assert_eq!(read["pcd_fruit"].as_u64(), Some(fruit_points), "{read}");
    assert_eq!(read["ply_points"], read["pcd_points"]);
    assert_eq!(read["ply_first"], read["pcd_first"]);
    assert!(read["ply_frames"].as_array().unwrap().len() >= 3, "{read}");
    for i in 0..3 {
        let c = read["ply_centre"][i].as_f64().unwrap();
        assert!((c - centre[i]).abs() < 1e-3, "{read} vs {answer}");
    }
    let comments = read["ply_comments"].to_string();
    assert!(comments.contains("units: millimetres"), "{comments}");
}

#[test]
fn a_points_file_of_another_kind_is_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let output = Command::new(ALACS)
        .args(["localize", "--scan", "no_such_scan", "--camera", "c.yaml", "--laser", "l.yaml"])
        .arg("--points")
        .arg(dir.path().join("cloud.xyz"))
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("cloud.xyz") && stderr.contains(".ply or .pcd"), "{stderr}");
}
