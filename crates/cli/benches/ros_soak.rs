//! The ROS node's soak: N goals in a row, the goal-to-result overhead on
//! top of the scan and the localization (issue "ROS 2 node": under 20 ms on
//! loopback) and the node's memory (peak RSS growth under 10 %).
//!
//!     ALACS_PEER_PYTHON=/path/to/python cargo bench -p alacs-cli --bench ros_soak
//!     ALACS_SOAK_GOALS=1000 ALACS_PEER_PYTHON=... cargo bench -p alacs-cli --bench ros_soak
//!
//! Runs the real `alacs ros --sim` and the Cyclone DDS peer
//! (`ros/peer/localize_fruit_peer.py`, a Python with `cyclonedds`) in a
//! network namespace of their own (`unshare --net`: root), loopback only.
//! The peer sends N goals one after the other (`--soak`, N from
//! `ALACS_SOAK_GOALS`, default 100) and times each from sending the goal
//! request to receiving the result; the node logs how long each goal's scan
//! and localization took (the simulated rig renders the frames: that is the
//! rig's time, not the node's). The overhead of a goal is the difference:
//! the goal and result services, accepting the goal, handing it to the job's
//! thread, the feedback, the point cloud, the marker and the result's
//! serialization, and DDS on loopback both ways. Prints the median, the
//! 95th percentile and the maximum, and the node's resident memory after 10
//! goals and after the last (read by the peer from /proc); fails if it grew
//! 10 % or more.

// A benchmark program: failing loudly is its error handling.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().unwrap()
}

/// Shell-quotes `s`.
fn q(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// The numbers after `prefix` and before " ms" in each line that has them.
fn millis_after(text: &str, prefix: &str) -> Vec<f64> {
    text.lines()
        .filter_map(|l| {
            let rest = &l[l.find(prefix)? + prefix.len()..];
            rest.split(" ms").next()?.trim().rsplit(' ').next()?.parse().ok()
        })
        .collect()
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn main() {
    // `cargo bench` passes `--bench`; a filter that is not ours skips us.
    if std::env::args().skip(1).any(|a| !a.starts_with("--") && !"ros_soak".contains(&a)) {
        return;
    }
    let Ok(python) = std::env::var("ALACS_PEER_PYTHON") else {
        eprintln!(
            "ros_soak: set ALACS_PEER_PYTHON to a Python with cyclonedds \
             (pip install -r ros/peer/requirements.txt); skipped"
        );
        return;
    };
    let goals: usize =
        std::env::var("ALACS_SOAK_GOALS").ok().and_then(|n| n.parse().ok()).unwrap_or(100);
    let dir = tempfile::tempdir().unwrap();
    let scene = ["--seed", "4", "--scale", "0.25"];
    let truth_dir = dir.path().join("truth");
    let status = Command::new(ALACS)
        .args(["simulate", "scan", "--out", truth_dir.to_str().unwrap()])
        .args(scene)
        .output()
        .unwrap();
    assert!(status.status.success());
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(truth_dir.join("truth.json")).unwrap())
            .unwrap();
    let rough: Vec<String> = (0..3)
        .map(|i| (truth["rough_position_mm"][i].as_f64().unwrap() / 1000.0).to_string())
        .collect();
    let node_log = dir.path().join("node.log");
    let cyclone = format!("file://{}", repo().join("ros/dds/cyclonedds-loopback.xml").display());
    let script = format!(
        "ip link set lo up || exit 90\n\
         {alacs} ros --sim {scene} --no-images --max-goals {goals} 2> {log} > /dev/null &\n\
         node=$!\n\
         {python} {peer} /alacs --soak {goals} --watch-pid $node --latencies --rough {rough} --radius 0.04 \
           --discovery-timeout 60 --timeout 120\n\
         peer=$?\n\
         wait $node\n\
         exit $peer\n",
        alacs = q(ALACS),
        scene = scene.join(" "),
        log = q(node_log.to_str().unwrap()),
        python = q(&python),
        peer = q(repo().join("ros/peer/localize_fruit_peer.py").to_str().unwrap()),
        rough = rough.join(" "),
    );
    eprintln!("ros_soak: {goals} goals to `alacs ros --sim` from the Cyclone DDS peer ...");
    let output = Command::new("unshare")
        .args(["--net", "sh", "-c", &script])
        .env("ROS_LOCALHOST_ONLY", "1")
        .env("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
        .env("ROS_DOMAIN_ID", "29")
        .env("CYCLONEDDS_URI", cyclone)
        .output()
        .expect("unshare (util-linux) runs");
    let peer_log = String::from_utf8_lossy(&output.stderr);
    let log = std::fs::read_to_string(&node_log).unwrap_or_default();
    assert!(
        output.status.success(),
        "the soak failed\npeer:\n{peer_log}\n{}\nnode:\n{log}",
        String::from_utf8_lossy(&output.stdout)
    );
    let per_goal: String =
        peer_log.lines().filter(|l| l.starts_with("latency ")).map(|l| format!("{l}\n")).collect();
    let latencies = millis_after(&per_goal, "latency ");
    let jobs = millis_after(&log, "scan and localization took ");
    assert_eq!(latencies.len(), goals, "one latency per goal\n{peer_log}");
    assert_eq!(jobs.len(), goals, "one scan time per goal\n{log}");
    let mut overhead: Vec<f64> = latencies.iter().zip(&jobs).map(|(l, j)| l - j).collect();
    overhead.sort_by(f64::total_cmp);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let soak: Value = serde_json::from_str(stdout.trim()).expect("the peer's JSON summary");
    let mut jobs = jobs;
    jobs.sort_by(f64::total_cmp);
    println!(
        "ros_soak: {goals} goals on loopback (Cyclone DDS peer, rmw_cyclonedds mapping), \
         statuses {}\n  \
         scan and localization (simulated rig): median {:.1} ms\n  \
         goal-to-result overhead: median {:.2} ms, p95 {:.2} ms, max {:.2} ms\n  \
         node resident memory: {:.1} MiB after 10 goals, {:.1} MiB after {goals} \
         ({:+.1} %), peak {:.1} MiB",
        soak["statuses"],
        quantile(&jobs, 0.5),
        quantile(&overhead, 0.5),
        quantile(&overhead, 0.95),
        quantile(&overhead, 1.0),
        soak["node_rss_mib_after_10"].as_f64().unwrap_or(f64::NAN),
        soak["node_rss_mib_after_all"].as_f64().unwrap_or(f64::NAN),
        soak["rss_growth_percent"].as_f64().unwrap_or(f64::NAN),
        soak["node_peak_rss_mib"].as_f64().unwrap_or(f64::NAN),
    );
}
