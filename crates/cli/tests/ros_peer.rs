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

/// The simulated scene every test's node builds: its seed and options.
const SCENE: [&str; 4] = ["--seed", "4", "--scale", "0.25"];

/// The scene's truth, from `alacs simulate scan` with the same options.
struct Truth {
    centre_mm: [f64; 3],
    rough_mm: [f64; 3],
    radius_m: f64,
}

fn scene_truth(dir: &Path) -> Truth {
    let truth_dir = dir.join("truth");
    let status = Command::new(ALACS)
        .args(["simulate", "scan", "--out", truth_dir.to_str().unwrap()])
        .args(SCENE)
        .status()
        .unwrap();
    assert!(status.success());
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(truth_dir.join("truth.json")).unwrap())
            .unwrap();
    let triple = |v: &Value| -> [f64; 3] { std::array::from_fn(|i| v[i].as_f64().unwrap()) };
    Truth {
        centre_mm: triple(&truth["fruit"]["position_mm"]),
        rough_mm: triple(&truth["rough_position_mm"]),
        radius_m: truth["fruit"]["radius_mm"].as_f64().unwrap() / 1000.0,
    }
}

/// What one run of the node and the peer left.
struct Run {
    /// The peer's summary (its JSON on standard output).
    peer: Value,
    /// The node's `--json` summary when it stopped.
    node: Value,
    node_exit: i32,
    /// Everything, for failure messages.
    context: String,
}

/// Runs `alacs ros --sim` (the scene, `node_args`) and the peer
/// (`peer_args`; `$node` is the node's process id) in a network namespace
/// of their own, and waits for both.
fn run(dir: &Path, truth: &Truth, node_args: &str, peer_args: &str, peer_exit: i32) -> Run {
    let python = std::env::var("ALACS_PEER_PYTHON").unwrap();
    let peer = repo().join("ros/peer/localize_fruit_peer.py");
    let node_log = dir.join("node.log");
    let node_json = dir.join("node.json");
    let script = format!(
        "ip link set lo up || exit 90\n\
         {alacs} ros --sim {scene} --no-images --namespace /alacs_left --json {node_args} \
           > {out} 2> {log} &\n\
         node=$!\n\
         {python} {peer} /alacs_left --rough {x} {y} {z} --radius {radius_m} \
           --discovery-timeout 60 --timeout 120 {peer_args}\n\
         peer=$?\n\
         wait $node\n\
         echo \"NODE_EXIT $?\" >&2\n\
         exit $peer\n",
        alacs = q(ALACS),
        scene = SCENE.join(" "),
        out = q(node_json.to_str().unwrap()),
        log = q(node_log.to_str().unwrap()),
        python = q(&python),
        peer = q(peer.to_str().unwrap()),
        x = truth.rough_mm[0] / 1000.0,
        y = truth.rough_mm[1] / 1000.0,
        z = truth.rough_mm[2] / 1000.0,
        radius_m = truth.radius_m,
    );
    let output = run_in_namespace(&script);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let log = std::fs::read_to_string(&node_log).unwrap_or_default();
    let node = std::fs::read_to_string(&node_json).unwrap_or_default();
    let context = format!(
        "peer stdout:\n{stdout}\npeer stderr:\n{stderr}\nnode log:\n{log}\nnode json:\n{node}"
    );
    assert_eq!(output.status.code(), Some(peer_exit), "the peer's exit\n{context}");
    let node_exit = stderr
        .lines()
        .find_map(|l| l.strip_prefix("NODE_EXIT "))
        .and_then(|c| c.trim().parse().ok())
        .unwrap_or(-1);
    let peer: Value = serde_json::from_str(stdout.trim()).unwrap_or(Value::Null);
    let node: Value = serde_json::from_str(node.trim()).unwrap_or(Value::Null);
    Run { peer, node, node_exit, context }
}

/// A JSON array of numbers.
fn floats(array: &Value) -> Vec<f64> {
    array.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
}

/// The distance of a result's position (m) from the true centre, mm.
fn error_mm(result: &Value, truth: &Truth) -> f64 {
    (0..3)
        .map(|i| (result["position"][i].as_f64().unwrap() * 1000.0 - truth.centre_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn a_cyclone_dds_client_gets_the_fruit_from_alacs_ros_sim() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    let bag = dir.path().join("node.mcap");
    let node_args = format!("--max-goals 1 --record {}", q(bag.to_str().unwrap()));
    let r = run(dir.path(), &truth, &node_args, "--expect-status SUCCEEDED --require-cloud", 0);
    let context = &r.context;
    assert_eq!(r.node_exit, 0, "the node did not stop cleanly\n{context}");
    let result = &r.peer["result"];
    assert_eq!(result["status"], "ok", "{context}");
    assert_eq!(result["frame_id"], "alacs_camera_optical_frame");
    let error_mm = error_mm(result, &truth);
    assert!(error_mm < 15.0, "{error_mm:.1} mm from the truth\n{context}");
    // The position covariance in m^2, as the Cyclone peer decoded it: a
    // symmetric matrix with variances of a few mm^2 (not ROS's "unknown", -1).
    let covariance = floats(&result["position_covariance"]);
    assert_eq!(covariance.len(), 9);
    for i in 0..3 {
        let sigma_mm = covariance[4 * i].sqrt() * 1000.0;
        assert!((0.05..20.0).contains(&sigma_mm), "sigma {sigma_mm} mm\n{context}");
        for k in 0..3 {
            assert!((covariance[3 * i + k] - covariance[3 * k + i]).abs() < 1e-15);
        }
    }
    let feedback = r.peer["feedback"].as_array().unwrap();
    assert_eq!(feedback.len(), 5, "one feedback per frame\n{context}");
    assert!(
        feedback
            .iter()
            .all(|f| f["n_frames"] == 5 && f["slide_position_m"].as_f64().unwrap() > 0.0)
    );
    // One static transform: the camera mounted on alacs_link, rotated as a
    // camera's optical frame (REP 103); the RGB-D camera's frame has no
    // parent from this node.
    let tf = r.peer["tf_static"].as_array().unwrap();
    assert_eq!(tf.len(), 1, "{context}");
    assert_eq!(tf[0]["parent"], "alacs_link", "{context}");
    assert_eq!(tf[0]["child"], "alacs_camera_optical_frame", "{context}");
    let q = floats(&tf[0]["rotation"]);
    for (got, want) in q.iter().zip([-0.5, 0.5, -0.5, 0.5]) {
        assert!((got - want).abs() < 1e-9, "{q:?}\n{context}");
    }
    let cloud = &r.peer["clouds"][0];
    assert_eq!(cloud["fields"], serde_json::json!(["x", "y", "z", "frame", "fruit"]));
    assert!(cloud["width"].as_u64().unwrap() > 50, "{context}");
    // <ns>/fruit as vision_msgs 4.x: the result's centre and covariance,
    // class "apple", a box of the fruit's diameter.
    let fruit = r.peer["fruit"].as_array().unwrap();
    assert_eq!(fruit.len(), 1, "{context}");
    let fruit = &fruit[0];
    assert_eq!(fruit["class_id"], "apple", "{context}");
    assert_eq!(fruit["frame_id"], "alacs_camera_optical_frame", "{context}");
    for i in 0..3 {
        let got = fruit["position"][i].as_f64().unwrap();
        assert!((got - result["position"][i].as_f64().unwrap()).abs() < 1e-12, "{context}");
        for k in 0..3 {
            let variance = fruit["covariance"][6 * i + k].as_f64().unwrap();
            assert!((variance - covariance[3 * i + k]).abs() < 1e-15, "{context}");
        }
        let size = fruit["size"][i].as_f64().unwrap();
        assert!((size - 2.0 * result["radius_m"].as_f64().unwrap()).abs() < 1e-12, "{context}");
    }
    assert!(context.contains("the laser is off"), "{context}");
    assert_eq!(r.node["found"], 1, "{context}");
    // The node recorded the goal's scan: it localizes from the bag to the
    // answer the client got (the simulation's camera and laser, as the node).
    let scene = dir.path().join("truth");
    let output = Command::new(ALACS)
        .args(["localize", "--json", "--bag", bag.to_str().unwrap(), "--camera"])
        .arg(scene.join("camera.yaml"))
        .arg("--laser")
        .arg(scene.join("laser.yaml"))
        .output()
        .unwrap();
    assert!(output.status.success(), "{}\n{context}", String::from_utf8_lossy(&output.stderr));
    let replay: Value = serde_json::from_slice(&output.stdout).unwrap();
    for i in 0..3 {
        let replayed_m = replay["position_mm"][i].as_f64().unwrap() / 1000.0;
        let answered_m = result["position"][i].as_f64().unwrap();
        assert!((replayed_m - answered_m).abs() < 1e-9, "{replay}\n{context}");
    }
}

#[test]
fn a_goal_in_base_link_is_answered_in_base_link_through_tf() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    // The robot's tree (as its state publisher would put it on /tf):
    // base_link -> the camera's optical frame, 0.4, -0.1, 1.2 m away,
    // turned 90 deg about x, so that camera (x, y, z) is base (x, -z, y).
    let base_from_camera_m = |p: [f64; 3]| [p[0] + 0.4, -p[2] - 0.1, p[1] + 1.2];
    let rough = base_from_camera_m(truth.rough_mm.map(|v| v / 1000.0));
    let centre = base_from_camera_m(truth.centre_mm.map(|v| v / 1000.0));
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let r = run(
        dir.path(),
        &truth,
        // The camera's only parent is the robot's base_link.
        "--max-goals 1 --no-static-tf",
        &format!(
            "--frame-id base_link --rough {} {} {} --tf base_link alacs_camera_optical_frame 0.4 -0.1 1.2 {half} 0 0 {half}",
            rough[0], rough[1], rough[2]
        ),
        0,
    );
    let context = &r.context;
    let result = &r.peer["result"];
    assert_eq!(result["status"], "ok", "{context}");
    assert_eq!(result["frame_id"], "base_link", "{context}");
    let off_mm = (0..3)
        .map(|i| (result["position"][i].as_f64().unwrap() - centre[i]).powi(2))
        .sum::<f64>()
        .sqrt()
        * 1000.0;
    assert!(off_mm < 15.0, "{off_mm:.1} mm from the truth in base_link\n{context}");
    // The covariance turned with the frame: base y is the camera's depth,
    // the worst-known axis of a laser scanner.
    let c = floats(&result["position_covariance"]);
    assert!(c[4] > c[0] && c[4] > c[8], "{c:?}\n{context}");
}

#[test]
fn a_goal_in_continuous_sweep_mode_reports_each_frame_where_the_slide_was() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    // The scan mode and the mount as a ROS launch gives them: --ros-args.
    let node_args =
        "--max-goals 1 --ros-args -p scan_mode:=continuous -p mount_frame:=left_arm_tool0";
    let r = run(dir.path(), &truth, node_args, "--expect-status SUCCEEDED", 0);
    let context = &r.context;
    assert_eq!(r.node_exit, 0, "the node did not stop cleanly\n{context}");
    assert_eq!(r.peer["tf_static"][0]["parent"], "left_arm_tool0", "{context}");
    let result = &r.peer["result"];
    assert_eq!(result["status"], "ok", "{context}");
    let error_mm = error_mm(result, &truth);
    assert!(error_mm < 15.0, "{error_mm:.1} mm from the truth\n{context}");
    // One feedback per laser frame (the sweep's laser-off reference frame
    // is none), each at the slide's reported position, in the sweep's order.
    let feedback = r.peer["feedback"].as_array().unwrap();
    assert_eq!(feedback.len(), 5, "one feedback per frame\n{context}");
    let slides: Vec<f64> =
        feedback.iter().map(|f| f["slide_position_m"].as_f64().unwrap()).collect();
    let ascending = slides.windows(2).all(|w| w[0] < w[1]);
    let descending = slides.windows(2).all(|w| w[0] > w[1]);
    assert!(ascending || descending, "{slides:?}\n{context}");
    assert!(context.contains("the laser is off"), "{context}");
}

#[test]
fn a_second_goal_while_one_runs_is_rejected_and_the_first_still_succeeds() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    let r = run(dir.path(), &truth, "--max-goals 1", "--second-goal --expect-status SUCCEEDED", 0);
    let context = &r.context;
    assert_eq!(r.peer["accepted"], true, "{context}");
    assert_eq!(r.peer["second_goal_accepted"], false, "{context}");
    assert_eq!(r.peer["result"]["status"], "ok", "{context}");
    assert!(context.contains("goal rejected: busy"), "{context}");
    assert_eq!(r.node["rejected"], 1, "{context}");
    assert_eq!(r.node["found"], 1, "{context}");
    assert_eq!(r.node_exit, 0, "{context}");
}

#[test]
fn a_cancelled_goal_ends_canceled_with_the_laser_off() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    let r =
        run(dir.path(), &truth, "--max-goals 1", "--cancel-after 0.05 --expect-status CANCELED", 0);
    let context = &r.context;
    // The server answered the cancel request with the goal (ERROR_NONE).
    assert_eq!(r.peer["cancel"]["return_code"], 0, "{context}");
    assert_eq!(r.peer["cancel"]["goals_canceling"].as_array().unwrap().len(), 1, "{context}");
    assert_eq!(r.peer["result"]["status"], "error", "{context}");
    assert!(context.contains("goal cancelled"), "{context}");
    assert!(context.contains("the laser is off"), "{context}");
    assert_eq!(r.node["cancelled"], 1, "{context}");
    // A cancelled scan publishes no point cloud.
    assert_eq!(r.peer["clouds"].as_array().unwrap().len(), 0, "{context}");
    assert_eq!(r.node_exit, 0, "{context}");
}

#[test]
fn sigterm_mid_goal_aborts_it_answers_the_client_and_stops_with_the_laser_off() {
    if peer_python().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let truth = scene_truth(dir.path());
    // No --max-goals: only the signal stops the node.
    let r = run(
        dir.path(),
        &truth,
        "",
        "--signal-after 0.05 --signal-pid $node --expect-status ABORTED",
        0,
    );
    let context = &r.context;
    assert_eq!(r.peer["signalled"], "SIGTERM", "{context}");
    assert_eq!(r.peer["result"]["status"], "error", "{context}");
    assert!(r.peer["result"]["reason"].as_str().unwrap().contains("stopped"), "{context}");
    assert!(context.contains("stopped; the laser is off"), "{context}");
    assert_eq!(r.node["stopped"], 1, "{context}");
    assert_eq!(r.node_exit, 0, "{context}");
}

#[test]
fn a_signal_in_the_nodes_first_moments_ends_it_with_its_summary() {
    // Regression: SIGTERM or SIGINT before the node's handlers were set (its
    // first 80 ms: the simulated scene is built first) exited 143 or 130
    // without the JSON summary. No peer needed: the node is stopped at once.
    if Command::new("unshare").args(["--net", "true"]).status().map_or(true, |s| !s.success()) {
        eprintln!("SKIPPED: unshare --net needs root (CI runs as root)");
        return;
    }
    // Each delay counts from the exec of alacs (a signal before it reaches
    // the shell's child is the shell's).
    for (signal, delay) in [("TERM", "0.01"), ("INT", "0.03"), ("TERM", "0.08")] {
        let script = format!(
            "ip link set lo up || exit 90\n\
             {alacs} ros --sim {scene} --no-images --json 2>/dev/null &\n\
             node=$!\n\
             i=0\n\
             until [ \"$(readlink /proc/$node/exe)\" = {alacs} ] || [ $i -ge 2000 ]; do\n\
               i=$((i + 1)); sleep 0.001\n\
             done\n\
             sleep {delay}\n\
             kill -{signal} $node\n\
             wait $node\n\
             echo \"NODE_EXIT $?\" >&2\n",
            alacs = q(ALACS),
            scene = SCENE.join(" "),
        );
        let output = run_in_namespace(&script);
        let stdout = String::from_utf8_lossy(&output.stdout);
        let stderr = String::from_utf8_lossy(&output.stderr);
        let context = format!("SIG{signal} after {delay} s\nstdout: {stdout}\nstderr: {stderr}");
        assert!(stderr.contains("NODE_EXIT 0"), "{context}");
        let summary: Value = serde_json::from_str(stdout.trim()).expect(&context);
        assert_eq!(summary["goals"], 0, "{context}");
    }
}

/// The RGB-D front end: a stand-in camera driver (Cyclone DDS) publishes
/// `alacs simulate rgbd`'s colour and depth images and camera under
/// realsense-ros' names; the node answers on `<ns>/fruit_rough` with the
/// apple, class "apple", within 15 mm of the simulator's truth (in the
/// RGB-D frame), stamped and framed as the colour image.
/// What `simulate rgbd` saw of a scene: its folder, the colour camera
/// and its truth (RGB-D frame, mm; `alacs_from_rgbd`).
struct RgbdView {
    scene: &'static [&'static str],
    dir: PathBuf,
    camera: alacs::Camera,
    camera_json: PathBuf,
    truth: Value,
}

fn rgbd_view(dir: &Path, scene: &'static [&'static str]) -> RgbdView {
    let view = dir.join("rgbd");
    let status = Command::new(ALACS)
        .args(["simulate", "rgbd", "--out", view.to_str().unwrap()])
        .args(scene)
        .status()
        .unwrap();
    assert!(status.success());
    let camera = alacs::Camera::from_yaml_file(&view.join("camera.yaml")).unwrap();
    let (model, d) = camera.distortion.ros_model();
    let camera_json = dir.join("camera.json");
    let k = [
        camera.fx_px,
        camera.skew_px,
        camera.cx_px,
        0.0,
        camera.fy_px,
        camera.cy_px,
        0.0,
        0.0,
        1.0,
    ];
    std::fs::write(
        &camera_json,
        serde_json::json!({"width": camera.width_px, "height": camera.height_px, "k": k,
                           "d": d, "distortion_model": model})
        .to_string(),
    )
    .unwrap();
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(view.join("truth.json")).unwrap()).unwrap();
    RgbdView { scene, dir: view, camera, camera_json, truth }
}

impl RgbdView {
    /// The simulated apple the scan aims at.
    fn target(&self) -> &Value {
        self.truth["apples"].as_array().unwrap().iter().find(|a| a["target"] == true).unwrap()
    }

    /// Runs `alacs ros --sim` with `node_args` and rgbd_peer.py with
    /// `peer_args` in a network namespace; the peer's JSON and the logs.
    fn run(&self, python: &str, node_args: &str, peer_args: &str) -> (Value, String) {
        let peer = format!(
            "{python} {peer} /alacs_left --color {color} --depth {depth} --camera {camera} --timeout 90 {peer_args}",
            python = q(python),
            peer = q(repo().join("ros/peer/rgbd_peer.py").to_str().unwrap()),
            color = q(self.dir.join("color.png").to_str().unwrap()),
            depth = q(self.dir.join("depth.png").to_str().unwrap()),
            camera = q(self.camera_json.to_str().unwrap()),
        );
        let (stdout, context) = node_and_peer(&self.dir, self.scene, node_args, &peer);
        (serde_json::from_str(stdout.trim()).unwrap(), context)
    }
}

/// Runs `alacs ros --sim SCENE --no-images --namespace /alacs_left
/// {node_args}` (its log in `dir`) and the shell command `peer` in a
/// network namespace of their own, then stops the node; asserts the peer
/// exits 0 and gives its standard output and everything for failure
/// messages.
fn node_and_peer(dir: &Path, scene: &[&str], node_args: &str, peer: &str) -> (String, String) {
    let node_log = dir.join("node.log");
    let script = format!(
        "ip link set lo up || exit 90\n\
         {alacs} ros --sim {scene} --no-images --namespace /alacs_left {node_args} > /dev/null 2> {log} &\n\
         node=$!\n\
         {peer}\n\
         peer=$?\n\
         kill -TERM $node; wait $node\n\
         exit $peer\n",
        alacs = q(ALACS),
        scene = scene.join(" "),
        log = q(node_log.to_str().unwrap()),
    );
    let output = run_in_namespace(&script);
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    let context = format!(
        "peer stdout:\n{stdout}\npeer stderr:\n{}\nnode log:\n{}",
        String::from_utf8_lossy(&output.stderr),
        std::fs::read_to_string(&node_log).unwrap_or_default()
    );
    assert_eq!(output.status.code(), Some(0), "{context}");
    (stdout, context)
}

/// The distance, mm, from a detection's position (m) to `point_mm`.
fn distance_mm(detection: &Value, point_mm: &[f64]) -> f64 {
    (0..3)
        .map(|i| (detection["position"][i].as_f64().unwrap() * 1000.0 - point_mm[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// An apple's truth position, mm.
fn position_mm(apple: &Value) -> Vec<f64> {
    (0..3).map(|i| apple["position_mm"][i].as_f64().unwrap()).collect()
}

#[test]
fn the_rgbd_front_end_publishes_fruit_rough_and_scan_detected_finds_the_fruit() {
    let Some(python) = peer_python() else { return };
    let dir = tempfile::tempdir().unwrap();
    // Three apples touching (one 16 % hidden, one 34 %): the RGB-D camera
    // sees two, and one sweep scans both.
    let view = rgbd_view(dir.path(), &["--seed", "6", "--scale", "0.25", "--cluster", "2"]);
    let (rough, context) = view.run(&python, "", "--scan");
    let truth = &view.truth;
    let target = view.target();
    assert_eq!(rough["frame_id"], "camera_color_optical_frame", "{context}");
    let detections = rough["detections"].as_array().unwrap();
    assert!(detections.iter().all(|d| d["class_id"] == "apple"), "{context}");
    let nearest_mm = detections
        .iter()
        .map(|d| distance_mm(d, &position_mm(target)))
        .fold(f64::INFINITY, f64::min);
    assert!(nearest_mm < 15.0, "the nearest detection is {nearest_mm:.1} mm off\n{context}");

    // scan_detected: one sweep over those detections; the fruit found are in
    // the ALACS camera's frame, the target among them, none wrong.
    let scan = &rough["scan"];
    assert_eq!(scan["success"], true, "{context}");
    assert_eq!(scan["fruit"]["frame_id"], "alacs_camera_optical_frame", "{context}");
    let pose = &truth["alacs_from_rgbd"];
    let in_alacs = |apple: &Value| -> Vec<f64> {
        let p = position_mm(apple);
        (0..3)
            .map(|r| {
                (0..3).map(|c| pose[r][c].as_f64().unwrap() * p[c]).sum::<f64>()
                    + pose[r][3].as_f64().unwrap()
            })
            .collect()
    };
    let apples: Vec<Vec<f64>> = truth["apples"].as_array().unwrap().iter().map(in_alacs).collect();
    let fruit = scan["fruit"]["detections"].as_array().unwrap();
    for d in fruit {
        let nearest = apples.iter().map(|a| distance_mm(d, a)).fold(f64::INFINITY, f64::min);
        assert!(nearest < 15.0, "a fruit {nearest:.1} mm from every apple\n{context}");
    }
    let target_in_alacs = in_alacs(target);
    let target_mm =
        fruit.iter().map(|d| distance_mm(d, &target_in_alacs)).fold(f64::INFINITY, f64::min);
    assert!(target_mm < 15.0, "the target is {target_mm:.1} mm from the nearest fruit\n{context}");
    let message = scan["message"].as_str().unwrap();
    assert!(
        message.starts_with(&format!(
            "{} of {} detected fruit found in one sweep",
            fruit.len(),
            detections.len()
        )),
        "{context}"
    );
}

#[test]
fn another_detectors_boxes_on_detections_2d_are_placed_with_the_depth() {
    let Some(python) = peer_python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let view = rgbd_view(dir.path(), &SCENE);
    // A YOLO-style detector's boxes: the target as an apple, every other
    // apple as another class (which the node must leave out).
    let boxes: Vec<Value> = view.truth["apples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|apple| {
            let c = position_mm(apple);
            let centre = nalgebra::Point3::new(c[0], c[1], c[2]);
            let px = view.camera.project(&centre).unwrap();
            let side = 2.0 * view.camera.fx_px * apple["radius_mm"].as_f64().unwrap() / c[2];
            let class = if apple["target"] == true { "Apple" } else { "sports ball" };
            serde_json::json!([px.x, px.y, side, side, class, 0.8])
        })
        .collect();
    let boxes = serde_json::to_string(&boxes).unwrap();
    let (rough, context) =
        view.run(&python, "--rgbd-detector topic", &format!("--boxes {}", q(&boxes)));
    let detections = rough["detections"].as_array().unwrap();
    assert_eq!(detections.len(), 1, "only the box of class apple\n{context}");
    assert_eq!(detections[0]["class_id"], "apple", "{context}");
    assert_eq!(detections[0]["score"], 0.8, "the detector's score\n{context}");
    let off_mm = distance_mm(&detections[0], &position_mm(view.target()));
    assert!(off_mm < 15.0, "the boxed apple is placed {off_mm:.1} mm off\n{context}");
}

#[test]
fn ros2_param_lists_gets_and_sets_the_nodes_parameters() {
    let Some(python) = peer_python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let peer = format!(
        "{python} {peer} /alacs_left/unit --set no_images:=false --set rough_lateral_error_mm:=12.5 \
         --set seed:=5 --set rough_depth_error:=oops --set nope:=1",
        python = q(&python),
        peer = q(repo().join("ros/peer/param_peer.py").to_str().unwrap()),
    );
    let node_args =
        "--ros-args -r __node:=unit -p rough_depth_error:=0.05 -p detection_classes:=[apple,pear]";
    let (stdout, context) = node_and_peer(dir.path(), &SCENE, node_args, &peer);
    let p: Value = serde_json::from_str(stdout.trim()).unwrap();
    // Every option is a parameter, typed as ROS 2 types it (1 bool,
    // 2 integer, 3 double, 4 string, 9 string array).
    for name in ["camera_frame", "seed", "sim", "rough_depth_error", "rgbd_ns", "no_images"] {
        assert!(p["names"].as_array().unwrap().iter().any(|n| n == name), "{name}\n{context}");
    }
    assert_eq!(p["values"]["seed"], 4, "{context}");
    assert_eq!(p["types"]["seed"], 2, "{context}");
    assert_eq!(p["values"]["sim"], true, "{context}");
    assert_eq!(p["values"]["rough_depth_error"], 0.05, "-p reaches the parameter\n{context}");
    assert_eq!(p["types"]["rough_depth_error"], 3, "{context}");
    assert_eq!(p["values"]["camera_frame"], "alacs_camera_optical_frame", "{context}");
    assert_eq!(p["values"]["detection_classes"], serde_json::json!(["apple", "pear"]), "{context}");
    assert_eq!(p["read_only"]["seed"], true, "{context}");
    assert_eq!(p["read_only"]["no_images"], false, "{context}");
    // Set: the runtime ones change, the rest say why not.
    let set = p["set"].as_array().unwrap();
    let result = |name: &str| set.iter().find(|r| r["name"] == name).unwrap();
    assert_eq!(result("no_images")["successful"], true, "{context}");
    assert_eq!(result("rough_lateral_error_mm")["successful"], true, "{context}");
    assert_eq!(result("seed")["successful"], false, "{context}");
    assert!(result("seed")["reason"].as_str().unwrap().contains("restart"), "{context}");
    assert!(
        result("rough_depth_error")["reason"].as_str().unwrap().contains("double"),
        "{context}"
    );
    assert!(result("nope")["reason"].as_str().unwrap().contains("`nope`"), "{context}");
    assert_eq!(p["after"]["no_images"], false, "{context}");
    assert_eq!(p["after"]["rough_lateral_error_mm"], 12.5, "{context}");
    assert_eq!(p["after"]["seed"], 4, "{context}");
}
