//! `alacs ros --sim` against a DDS peer this project did not write: Eclipse
//! Cyclone DDS (PyPI `cyclonedds`) as a stand-in ROS 2 action client that
//! speaks rmw_cyclonedds_cpp's wire conventions (`ros/peer/`). The peer
//! sends a goal, reads the feedback, the result and the PointCloud2; the
//! result must lie within 15 mm of the simulator's truth.
//!
//! Both run in a network namespace of their own (`unshare --net`, only
//! loopback up), and both are configured for loopback anyway: the node by
//! `ROS_LOCALHOST_ONLY=1`, the peer by `ros/dds/cyclonedds-loopback.xml`.
//!
//! Needs root (for `unshare --net`) and a Python with cyclonedds:
//! `ALACS_PEER_PYTHON=/path/to/python`. `.ci/run` installs it and sets the
//! variable; without it the test says so and passes without running.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().unwrap()
}

/// The peer's Python, or `None` (with a note) when this machine has none.
fn peer_python() -> Option<String> {
    match std::env::var("ALACS_PEER_PYTHON") {
        Ok(python) if !python.is_empty() => Some(python),
        _ => {
            eprintln!(
                "SKIPPED: set ALACS_PEER_PYTHON to a Python with cyclonedds \
                 (pip install -r ros/peer/requirements.txt); .ci/run does"
            );
            None
        }
    }
}

fn run_in_namespace(script: &str) -> std::process::Output {
    let cyclone = format!("file://{}", repo().join("ros/dds/cyclonedds-loopback.xml").display());
    Command::new("unshare")
        .args(["--net", "sh", "-c", script])
        .env("ROS_LOCALHOST_ONLY", "1")
        .env("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
        .env("ROS_DOMAIN_ID", "17")
        .env("CYCLONEDDS_URI", cyclone)
        .output()
        .expect("unshare (util-linux) runs")
}

/// Shell-quotes `s`.
fn q(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

#[test]
fn a_cyclone_dds_client_gets_the_fruit_from_alacs_ros_sim() {
    let Some(python) = peer_python() else { return };
    let dir = tempfile::tempdir().unwrap();
    // The same scene the node builds (same seed and options): its truth.
    let truth_dir = dir.path().join("truth");
    let scene = ["--seed", "4", "--scale", "0.25"];
    let status = Command::new(ALACS)
        .args(["simulate", "scan", "--out", truth_dir.to_str().unwrap()])
        .args(scene)
        .status()
        .unwrap();
    assert!(status.success());
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(truth_dir.join("truth.json")).unwrap())
            .unwrap();
    let centre: Vec<f64> =
        (0..3).map(|i| truth["fruit"]["position_mm"][i].as_f64().unwrap()).collect();
    let rough: Vec<f64> = (0..3).map(|i| truth["rough_position_mm"][i].as_f64().unwrap()).collect();
    let radius_m = truth["fruit"]["radius_mm"].as_f64().unwrap() / 1000.0;

    let peer = repo().join("ros/peer/localize_fruit_peer.py");
    let node_log = dir.path().join("node.log");
    let script = format!(
        "ip link set lo up || exit 90\n\
         {alacs} ros --sim {scene} --max-goals 1 --no-images --namespace /alacs_left --json > {out} 2> {log} &\n\
         node=$!\n\
         {python} {peer} /alacs_left --rough {x} {y} {z} --radius {radius_m} \
           --expect-status SUCCEEDED --require-cloud --discovery-timeout 60 --timeout 120\n\
         peer=$?\n\
         wait $node\n\
         node_rc=$?\n\
         echo \"NODE_EXIT $node_rc\"\n\
         exit $peer\n",
        alacs = q(ALACS),
        scene = scene.join(" "),
        out = q(dir.path().join("node.json").to_str().unwrap()),
        log = q(node_log.to_str().unwrap()),
        python = q(&python),
        peer = q(peer.to_str().unwrap()),
        x = rough[0] / 1000.0,
        y = rough[1] / 1000.0,
        z = rough[2] / 1000.0,
    );
    let output = run_in_namespace(&script);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let log = std::fs::read_to_string(&node_log).unwrap_or_default();
    let context = format!("peer stdout:\n{stdout}\npeer stderr:\n{stderr}\nnode log:\n{log}");
    assert!(output.status.success(), "the peer failed ({:?})\n{context}", output.status);
    assert!(stdout.contains("NODE_EXIT 0"), "the node did not stop cleanly\n{context}");
    let json_end = stdout.rfind('}').unwrap();
    let summary: Value = serde_json::from_str(&stdout[..=json_end]).unwrap();
    let result = &summary["result"];
    assert_eq!(result["status"], "ok", "{context}");
    assert_eq!(result["frame_id"], "alacs_camera_optical_frame");
    let error_mm: f64 = (0..3)
        .map(|i| (result["position"][i].as_f64().unwrap() * 1000.0 - centre[i]).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(error_mm < 15.0, "{error_mm:.1} mm from the truth\n{context}");
    let feedback = summary["feedback"].as_array().unwrap();
    assert_eq!(feedback.len(), 5, "one feedback per frame\n{context}");
    assert!(
        feedback
            .iter()
            .all(|f| f["n_frames"] == 5 && f["slide_position_m"].as_f64().unwrap() > 0.0)
    );
    let cloud = &summary["clouds"][0];
    assert_eq!(cloud["fields"], serde_json::json!(["x", "y", "z", "frame", "fruit"]));
    assert!(cloud["width"].as_u64().unwrap() > 50, "{context}");
    assert!(log.contains("the laser is off"), "{context}");
}
