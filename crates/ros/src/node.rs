//! The ROS 2 node: the action `<ns>/localize_fruit`, the RGB-D front end
//! (`<ns>/fruit_rough`), the service `<ns>/scan_detected` that scans every
//! detected fruit in one sweep, their topics, and the loop that serves one
//! job at a time while the rig works on a thread of its own.

use std::collections::VecDeque;
use std::net::{IpAddr, Ipv4Addr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use futures::FutureExt as _;
use ros2_client::action::{
    ActionServerQosPolicies, AsyncActionServer, ExecutingGoalHandle, GoalEndStatus, GoalError,
};
use ros2_client::builtin_interfaces::Time;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::parameters::ParameterValue;
use ros2_client::qos::{Durability, History, QosProfile};
use ros2_client::service::RmwRequestId;
use ros2_client::{
    ActionTypeName, Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    ServiceTypeName,
};
use smol::future::FutureExt as _;

use alacs_model::MAX_SCAN_TARGETS;

use crate::bag::BagWriter;
use crate::convert::{
    Frames, GoalFrame, camera_from_info, camera_info, depth_image, detections_from_2d,
    error_result, fruit_array, fruit_detections, fruit_marker, image_message, job_request,
    laser_cloud, localization_result, point_m, rgb_image, rough_detections, static_transform,
};
use crate::env::RosEnvironment;
use crate::job::{JobContext, JobRequest, Outcome, Progress, ScanRig, run_job};
use crate::msgs::{
    CameraInfo, Detection2DArray, Detection3DArray, DiagnosticArray, DiagnosticStatus, Header,
    Image, KeyValue, LocalizeFruitFeedback, LocalizeFruitGoal, LocalizeFruitResult, Marker,
    PointCloud2, TfMessage, TriggerRequest, TriggerResponse,
};
use crate::params::{NodeParameter, ParameterServices, Parameters};
use crate::tf::TfTree;
use crate::{Error, Result};

/// The action server of `alacs_msgs/action/LocalizeFruit`.
type Server = AsyncActionServer<LocalizeFruitGoal, LocalizeFruitResult, LocalizeFruitFeedback>;

/// The server of `<ns>/scan_detected` (std_srvs/srv/Trigger).
type SweepServer = ros2_client::Server<TriggerRequest, TriggerResponse>;

/// How long a finished goal's result waits for the client to ask for it.
const RESULT_WAIT: Duration = Duration::from_secs(30);

/// How often the loop looks at the stop flag and publishes diagnostics.
const TICK: Duration = Duration::from_millis(100);

/// How long a stopping node waits for its last results to reach their
/// clients.
const EXIT_RESULT_WAIT: Duration = Duration::from_secs(2);

/// Diagnostics are published this often when nothing happens.
const DIAGNOSTICS_PERIOD: Duration = Duration::from_secs(1);

/// The node's settings.
#[derive(Debug, Clone)]
pub struct NodeConfig {
    /// The namespace of the node, its action and topics (`/alacs`; two
    /// units on one robot: `/alacs_left`, `/alacs_right`).
    pub namespace: String,
    /// The node's name.
    pub node_name: String,
    /// The frames it names.
    pub frames: Frames,
    /// Publish every captured frame on `<ns>/image` (5 MP rgb8 is 15 MB).
    pub publish_images: bool,
    /// Stop after this many goals (tests and soaks); `None`: run until stopped.
    pub max_goals: Option<u64>,
    /// Record every localized goal's scan in this bag (MCAP), whole when
    /// the node stops.
    pub record: Option<std::path::PathBuf>,
    /// Where the ALACS camera is mounted: its optical frame is published on
    /// /tf_static as a child of this frame at this pose (mm); `None`: no
    /// static transform (the robot's URDF publishes it).
    pub mount: Option<(String, nalgebra::Isometry3<f64>)>,
    /// The node's topics and action under other names, as `--ros-args -r
    /// FROM:=TO` gives them: FROM the relative name (`fruit`) or the full
    /// one (`/alacs/fruit`), TO relative to the namespace or absolute.
    pub remaps: Vec<(String, String)>,
    /// The RGB-D camera's namespace (realsense-ros' names under it:
    /// `color/image_raw`, `aligned_depth_to_color/image_raw`,
    /// `color/camera_info`): its frames are searched for fruit and each
    /// pair's fruit published on `<ns>/fruit_rough`; `None`: no front end.
    pub rgbd_ns: Option<String>,
    /// Where the front end's fruit come from.
    pub detector: FruitDetector,
    /// The files the rig and the calibration came from, by what they are
    /// (`rig`, `camera`, `laser`): named in `/diagnostics` with their age.
    pub sources: Vec<(String, std::path::PathBuf)>,
    /// The node's options as ROS 2 parameters (the parameter services);
    /// [`RUNTIME_PARAMETERS`] may be set while it runs, the rest are
    /// read-only.
    pub parameters: Vec<NodeParameter>,
}

/// The parameters `ros2 param set` changes while the node runs; each
/// applies from the next job. The others are read at start (the rig, the
/// calibration, names and topics).
pub const RUNTIME_PARAMETERS: [&str; 3] =
    ["no_images", "rough_depth_error", "rough_lateral_error_mm"];

/// Where the RGB-D front end's fruit come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FruitDetector {
    /// alacs-detect's classical detector, on each colour image.
    Builtin,
    /// Another detector's vision_msgs/Detection2DArray on
    /// `<ns>/detections_2d` (on the colour image, stamped as it): its
    /// boxes of these classes, placed with the depth image of that stamp.
    Topic {
        /// The class ids that are fruit (`apple`; any case).
        classes: Vec<String>,
    },
}

impl Default for NodeConfig {
    fn default() -> Self {
        Self {
            namespace: "/alacs".into(),
            node_name: "alacs".into(),
            frames: Frames::default(),
            publish_images: true,
            max_goals: None,
            record: None,
            mount: Some(("alacs_link".into(), crate::convert::body_from_optical())),
            remaps: Vec::new(),
            rgbd_ns: Some(DEFAULT_RGBD_NS.into()),
            detector: FruitDetector::Builtin,
            sources: Vec::new(),
            parameters: Vec::new(),
        }
    }
}

/// realsense-ros 4.x's default namespace and name: `/camera/camera`.
pub const DEFAULT_RGBD_NS: &str = "/camera/camera";

/// Colour and depth images kept while waiting for their pair (by stamp).
const RGBD_QUEUE: usize = 5;

/// ... and while waiting for another detector's boxes: half a second at
/// 30 Hz, a CPU detector's latency (at 1280 x 720, about 70 MB of images).
const RGBD_QUEUE_FOR_DETECTIONS: usize = 15;

/// The RGB-D camera's streams the front end reads (sensor-data QoS).
struct RgbdInput {
    color: ros2_client::Subscription<Image>,
    depth: ros2_client::Subscription<Image>,
    info: ros2_client::Subscription<CameraInfo>,
}

impl RgbdInput {
    fn new(node: &mut Node, rgbd_ns: &str) -> Result<Self> {
        let ns = rgbd_ns.trim_end_matches('/');
        let topic = |node: &mut Node, base: &str, type_name: &str| {
            let full = format!("{ns}/{base}");
            let name = Name::parse(&full).map_err(|e| {
                Error::InvalidInput(format!("rgbd_ns `{rgbd_ns}`: `{full}` is no ROS name ({e:?})"))
            })?;
            node.create_topic(&name, MessageTypeName::new("sensor_msgs", type_name), &sensor_data())
                .map_err(|e| Error::dds("topic", e))
        };
        let color = topic(node, "color/image_raw", "Image")?;
        let depth = topic(node, "aligned_depth_to_color/image_raw", "Image")?;
        let info = topic(node, "color/camera_info", "CameraInfo")?;
        let failed = |e| Error::dds("subscription", e);
        Ok(Self {
            color: node.create_subscription(&color, Some(sensor_data())).map_err(failed)?,
            depth: node.create_subscription(&depth, Some(sensor_data())).map_err(failed)?,
            info: node.create_subscription(&info, Some(sensor_data())).map_err(failed)?,
        })
    }
}

/// The next message of `subscription`; never, without one.
async fn next_message<M>(subscription: Option<&ros2_client::Subscription<M>>) -> Option<M>
where
    M: 'static + serde::de::DeserializeOwned,
{
    match subscription {
        Some(s) => s.async_take().await.ok().map(|(message, _)| message),
        None => futures::future::pending().await,
    }
}

/// Why no job can start now, for a goal and a `scan_detected` call alike:
/// one is `running`, or the node is stopping.
fn cannot_start(running: bool, stop: &AtomicBool) -> Option<String> {
    if running {
        Some("busy: one job at a time, and one is running".to_string())
    } else if stop.load(Ordering::Relaxed) {
        Some("the node is shutting down".to_string())
    } else {
        None
    }
}

/// Keeps `image` among the last `capacity` of its stream.
fn queue(images: &mut VecDeque<Image>, image: Image, capacity: usize) {
    if images.len() >= capacity {
        images.pop_front();
    }
    images.push_back(image);
}

/// The newest boxes whose colour and depth images have come, with them;
/// older boxes and images are taken out too. `None`, and nothing taken,
/// while no boxes have their pair.
fn take_boxed(
    boxes: &mut VecDeque<Detection2DArray>,
    colors: &mut VecDeque<Image>,
    depths: &mut VecDeque<Image>,
) -> Option<(Detection2DArray, Image, Image)> {
    let (bi, ci, di) = boxes.iter().enumerate().rev().find_map(|(bi, b)| {
        Some((bi, stamped(colors, b.header.stamp)?, stamped(depths, b.header.stamp)?))
    })?;
    Some((take_through(boxes, bi)?, take_through(colors, ci)?, take_through(depths, di)?))
}

/// The newest colour and depth images with one stamp, taken out with
/// everything older (realsense-ros stamps an aligned pair alike).
fn take_pair(colors: &mut VecDeque<Image>, depths: &mut VecDeque<Image>) -> Option<(Image, Image)> {
    let (ci, di) = colors
        .iter()
        .enumerate()
        .rev()
        .find_map(|(ci, c)| Some((ci, stamped(depths, c.header.stamp)?)))?;
    Some((take_through(colors, ci)?, take_through(depths, di)?))
}

/// Where the image stamped `stamp` waits in `images`.
fn stamped(images: &VecDeque<Image>, stamp: Time) -> Option<usize> {
    images.iter().position(|i| i.header.stamp == stamp)
}

/// The entry at `index` of `queue`, taken out with everything older.
fn take_through<T>(queue: &mut VecDeque<T>, index: usize) -> Option<T> {
    queue.drain(..=index).next_back()
}

/// The fruit of one colour and depth pair, with the colour image's header.
type RoughFound = (Header, std::result::Result<Vec<alacs_detect::Detection>, String>);

/// Detects the fruit in a colour image and places them with its depth
/// image and camera (alacs-detect's classical detector and depth model).
/// With `boxes`, another detector's fruit are placed instead.
fn detect_rough(
    color: Image,
    depth: &Image,
    camera: &alacs_model::Camera,
    boxes: Option<Vec<alacs_detect::Detection>>,
) -> std::result::Result<Vec<alacs_detect::Detection>, String> {
    let depth = depth_image(depth)?;
    let image = rgb_image(color)?;
    let mut detections = match boxes {
        Some(boxes) => boxes,
        None => alacs_detect::detect(&image, &alacs_detect::DetectOptions::default())
            .map_err(|e| e.to_string())?,
    };
    alacs_detect::locate_detections(
        &mut detections,
        &image,
        &depth,
        camera,
        &alacs_detect::DepthModel::default(),
    )
    .map_err(|e| e.to_string())?;
    Ok(detections)
}

impl NodeConfig {
    /// Checks the namespace and node name as ROS 2 names.
    pub fn validate(&self) -> Result<()> {
        validate_namespace(&self.namespace)?;
        NodeName::new(&self.namespace, &self.node_name).map_err(|e| {
            Error::InvalidInput(format!(
                "namespace `{}` / node name `{}`: {e:?} (a namespace starts with `/`, e.g. /alacs_left)",
                self.namespace, self.node_name
            ))
        })?;
        Ok(())
    }
}

/// Checks `namespace` by ROS 2's rules for a node's namespace
/// (rmw_validate_namespace): absolute, tokens of letters, digits and `_`
/// that do not start with a digit, no empty token, at most 255 characters.
/// The node and `bag import --namespace` both take only such names.
pub fn validate_namespace(namespace: &str) -> Result<()> {
    let problem = if !namespace.starts_with('/') {
        Some("it must start with `/`")
    } else if namespace.len() > MAX_NAMESPACE_CHARS {
        Some("it is longer than 255 characters")
    } else if namespace == "/" {
        None
    } else if namespace.ends_with('/') || namespace.contains("//") {
        Some("it has an empty token (`//` or a trailing `/`)")
    } else if !namespace.chars().all(|c| c == '/' || c == '_' || c.is_ascii_alphanumeric()) {
        Some("it may hold only letters, digits, `_` and `/`")
    } else if namespace.split('/').any(|token| token.starts_with(|c: char| c.is_ascii_digit())) {
        Some("a token starts with a digit")
    } else {
        None
    };
    match problem {
        Some(problem) => Err(Error::InvalidInput(format!(
            "namespace `{namespace}`: {problem} (e.g. /alacs_left)"
        ))),
        None => Ok(()),
    }
}

/// The longest namespace ROS 2 takes (rmw's RMW_NAMESPACE_MAX_LENGTH).
const MAX_NAMESPACE_CHARS: usize = 255;

/// What a node did, when it stops.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeSummary {
    /// Goals accepted.
    pub goals: u64,
    /// Goals that found the fruit.
    pub found: u64,
    /// Goals rejected (busy, bad goal).
    pub rejected: u64,
    /// Goals that ended in "error" (device faults).
    pub errors: u64,
    /// Goals cancelled.
    pub cancelled: u64,
    /// Goals aborted because the node was stopped (SIGINT, SIGTERM) while
    /// they ran.
    pub stopped: u64,
    /// `scan_detected` calls that ran a sweep (their fruit found count in
    /// `found`).
    pub sweeps: u64,
}

/// Messages from the job's thread.
enum JobMessage {
    Progress(Progress),
    Done(Outcome),
}

/// Who waits for the running job's answer.
enum Client {
    /// A LocalizeFruit goal, and the frame of the robot's tree it is
    /// answered in (none: the camera's).
    Goal(ExecutingGoalHandle<LocalizeFruitGoal>, Option<GoalFrame>),
    /// A `scan_detected` call: its request, and how many fruit the RGB-D
    /// camera saw beyond the ones scanned ([`MAX_SCAN_TARGETS`] per sweep).
    Sweep { request: RmwRequestId, detected: usize, beyond_limit: usize },
}

/// The job being worked on.
struct Running {
    client: Client,
    cancel: Arc<AtomicBool>,
    /// Why the job was told to stop, if it was.
    stop_reason: Option<StopReason>,
    messages: smol::channel::Receiver<JobMessage>,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// Why a running goal was told to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StopReason {
    /// Its client cancelled it.
    Cancelled,
    /// The node is shutting down (SIGINT, SIGTERM).
    Shutdown,
}

/// The publishers of the node.
struct Topics {
    fruit: Publisher<Detection3DArray>,
    fruit_rough: Publisher<Detection3DArray>,
    laser_points: Publisher<PointCloud2>,
    marker: Publisher<Marker>,
    image: Publisher<Image>,
    camera_info: Publisher<CameraInfo>,
    tf_static: Publisher<TfMessage>,
    diagnostics: Publisher<DiagnosticArray>,
}

/// The DDS participant as ROS 2's environment asks: its domain, and on
/// loopback only when discovery is limited to this host.
fn context(env: &RosEnvironment) -> Result<Context> {
    let mut builder = DomainParticipantBuilder::new(env.domain_id);
    if env.localhost_only {
        builder = builder.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
    }
    let participant = builder.build().map_err(|e| Error::dds("participant", e))?;
    Context::from_domain_participant(participant).map_err(|e| Error::dds("context", e))
}

/// A topic's QoS: reliable, volatile, the last `depth` samples.
fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// ROS 2's sensor-data QoS (rmw_qos_profile_sensor_data): best effort,
/// volatile, the last 5.
fn sensor_data() -> QosProfile {
    QosProfile::subscription_default()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 5 })
}

fn publisher<M: serde::Serialize>(
    node: &mut Node,
    name: &Name,
    (package, type_name): (&str, &str),
    qos: &QosProfile,
) -> Result<Publisher<M>> {
    let topic = node
        .create_topic(name, MessageTypeName::new(package, type_name), qos)
        .map_err(|e| Error::dds("topic", e))?;
    node.create_publisher(&topic, None).map_err(|e| Error::dds("publisher", e))
}

fn name(namespace: &str, base: &str) -> Result<Name> {
    Name::new(namespace, base)
        .map_err(|e| Error::InvalidInput(format!("ROS name {namespace}/{base}: {e:?}")))
}

/// The name `base` in `namespace` after the remaps ([`NodeConfig::remaps`]).
fn remapped(namespace: &str, base: &str, remaps: &[(String, String)]) -> Result<Name> {
    let full = if namespace.ends_with('/') {
        format!("{namespace}{base}")
    } else {
        format!("{namespace}/{base}")
    };
    let Some((_, to)) = remaps.iter().find(|(from, _)| from == base || *from == full) else {
        return name(namespace, base);
    };
    let target = if to.starts_with('/') { to.clone() } else { format!("{namespace}/{to}") };
    let target = target.replace("//", "/");
    Name::parse(&target).map_err(|e| {
        Error::InvalidInput(format!("remap {base}:={to}: `{target}` is no ROS name ({e:?})"))
    })
}

impl Topics {
    fn new(node: &mut Node, ns: &str, remaps: &[(String, String)]) -> Result<Self> {
        let name = |namespace: &str, base: &str| remapped(namespace, base, remaps);
        let latched = QosProfile::publisher_default()
            .durability(Durability::TransientLocal)
            .history(History::KeepLast { depth: 1 });
        Ok(Self {
            fruit: publisher(
                node,
                &name(ns, "fruit")?,
                ("vision_msgs", "Detection3DArray"),
                &reliable(10),
            )?,
            fruit_rough: publisher(
                node,
                &name(ns, "fruit_rough")?,
                ("vision_msgs", "Detection3DArray"),
                &reliable(10),
            )?,
            laser_points: publisher(
                node,
                &name(ns, "laser_points")?,
                ("sensor_msgs", "PointCloud2"),
                &reliable(1),
            )?,
            marker: publisher(
                node,
                &name(ns, "fruit_marker")?,
                ("visualization_msgs", "Marker"),
                &reliable(10),
            )?,
            image: publisher(node, &name(ns, "image")?, ("sensor_msgs", "Image"), &sensor_data())?,
            camera_info: publisher(
                node,
                &name(ns, "camera_info")?,
                ("sensor_msgs", "CameraInfo"),
                &sensor_data(),
            )?,
            tf_static: publisher(
                node,
                &name("/", "tf_static")?,
                ("tf2_msgs", "TFMessage"),
                &latched,
            )?,
            diagnostics: publisher(
                node,
                &name("/", "diagnostics")?,
                ("diagnostic_msgs", "DiagnosticArray"),
                &reliable(10),
            )?,
        })
    }
}

/// The node's state for diagnostics.
struct State {
    rig: String,
    /// The rig's and the calibration's files, with when they were last
    /// written (`None`: unknown).
    sources: Vec<(String, std::path::PathBuf, Option<std::time::SystemTime>)>,
    /// `stop_and_go` or `continuous`.
    scan_mode: &'static str,
    summary: NodeSummary,
    scanning: bool,
    last_scan_s: Option<f64>,
    last_error: Option<String>,
    last_rejection: Option<String>,
}

impl State {
    fn diagnostics(&self, node_name: &str) -> DiagnosticArray {
        let level =
            if self.last_error.is_some() { DiagnosticStatus::WARN } else { DiagnosticStatus::OK };
        let message = match (&self.scanning, &self.last_error) {
            (true, _) => "scanning".to_string(),
            (false, Some(error)) => format!("idle; the last goal failed: {error}"),
            (false, None) => "idle".to_string(),
        };
        let s = &self.summary;
        let value = |key: &str, value: String| KeyValue { key: key.into(), value };
        DiagnosticArray {
            header: Header::new(Time::now(), ""),
            status: vec![DiagnosticStatus {
                level,
                name: format!("alacs: {node_name}"),
                message,
                hardware_id: self.rig.clone(),
                values: vec![
                    value("rig", self.rig.clone()),
                    value("scan_mode", self.scan_mode.into()),
                    value("state", if self.scanning { "scanning" } else { "idle" }.into()),
                    value("goals", s.goals.to_string()),
                    value("sweeps", s.sweeps.to_string()),
                    value("found", s.found.to_string()),
                    value("rejected", s.rejected.to_string()),
                    value("errors", s.errors.to_string()),
                    value("cancelled", s.cancelled.to_string()),
                    value("stopped", s.stopped.to_string()),
                    value(
                        "last_scan_time_s",
                        self.last_scan_s.map_or_else(String::new, |t| format!("{t:.3}")),
                    ),
                    value("last_error", self.last_error.clone().unwrap_or_default()),
                    value("last_rejection", self.last_rejection.clone().unwrap_or_default()),
                ]
                .into_iter()
                .chain(self.sources.iter().flat_map(|(what, path, written)| {
                    let age = written.and_then(|t| t.elapsed().ok()).map_or_else(
                        || "unknown".to_string(),
                        |a| format!("{:.1}", a.as_secs_f64() / 86_400.0),
                    );
                    [
                        value(&format!("{what}_file"), path.display().to_string()),
                        value(&format!("{what}_file_age_days"), age),
                    ]
                }))
                .collect(),
            }],
        }
    }
}

/// Runs the node until `stop` is set (SIGINT, SIGTERM) or
/// `config.max_goals` goals are done, serving one goal at a time on `rig`.
/// `log` receives one line per event (goal accepted, rejected, done).
pub fn run_node(
    config: &NodeConfig,
    env: &RosEnvironment,
    job: JobContext,
    rig: Box<dyn ScanRig>,
    stop: Arc<AtomicBool>,
    log: &(dyn Fn(&str) + Sync),
) -> Result<NodeSummary> {
    config.validate()?;
    // A recording that cannot be opened stops the node before it starts.
    let mut recorder = config
        .record
        .as_deref()
        .map(|path| BagWriter::create(path, &config.namespace, &config.frames, false))
        .transpose()?;
    let mapping = env.service_mapping()?;
    let ctx = context(env)?;
    let mut node = ctx
        .new_node(
            NodeName::new(&config.namespace, &config.node_name)
                .map_err(|e| Error::InvalidInput(format!("{e:?}")))?,
            // Parameter services would use one fixed mapping, not the RMW's.
            NodeOptions::new().enable_rosout(true).start_parameter_services(false),
        )
        .map_err(|e| Error::dds("node", e))?;
    let ns = config.namespace.as_str();
    let service = reliable(10);
    let qos = ActionServerQosPolicies {
        goal_service: service.clone(),
        result_service: service.clone(),
        cancel_service: service.clone(),
        feedback_publisher: service,
        status_publisher: QosProfile::publisher_default()
            .durability(Durability::TransientLocal)
            .history(History::KeepLast { depth: 1 }),
    };
    let server: Arc<Server> = Arc::new(AsyncActionServer::new(
        node.create_action_server(
            mapping,
            &remapped(ns, "localize_fruit", &config.remaps)?,
            &ActionTypeName::new("alacs_msgs", "LocalizeFruit"),
            qos,
        )
        .map_err(|e| Error::dds("action server", e))?,
    ));
    let sweep_server: SweepServer = node
        .create_server(
            mapping,
            &remapped(ns, "scan_detected", &config.remaps)?,
            &ServiceTypeName::new("std_srvs", "Trigger"),
            reliable(10),
            reliable(10),
        )
        .map_err(|e| Error::dds("service server", e))?;
    let parameter_services = ParameterServices::new(&mut node, mapping, &reliable(100))?;
    let mut parameters = Parameters::new(
        config
            .parameters
            .iter()
            .map(|p| NodeParameter {
                read_only: !RUNTIME_PARAMETERS.contains(&p.name.as_str()),
                ..p.clone()
            })
            .collect(),
    );
    let mut publish_images = config.publish_images;
    let topics = Topics::new(&mut node, ns, &config.remaps)?;
    let rgbd =
        config.rgbd_ns.as_deref().map(|rgbd_ns| RgbdInput::new(&mut node, rgbd_ns)).transpose()?;
    let (boxes_2d, classes, image_queue) = match (&config.detector, &rgbd) {
        (FruitDetector::Topic { classes }, Some(_)) => {
            let topic = node
                .create_topic(
                    &remapped(ns, "detections_2d", &config.remaps)?,
                    MessageTypeName::new("vision_msgs", "Detection2DArray"),
                    &sensor_data(),
                )
                .map_err(|e| Error::dds("topic", e))?;
            // Best effort reads reliable and best-effort publishers alike.
            let subscription = node
                .create_subscription::<Detection2DArray>(&topic, Some(sensor_data()))
                .map_err(|e| Error::dds("subscription", e))?;
            (Some(subscription), classes.clone(), RGBD_QUEUE_FOR_DETECTIONS)
        }
        _ => (None, Vec::new(), RGBD_QUEUE),
    };
    // The robot's frames, for goals in any of them.
    let tf_qos = reliable(100);
    let tf_static_qos = reliable(100).durability(Durability::TransientLocal);
    let tf_topic = |node: &mut Node, base: &str, qos: &QosProfile| {
        node.create_topic(&name("/", base)?, MessageTypeName::new("tf2_msgs", "TFMessage"), qos)
            .map_err(|e| Error::dds("topic", e))
    };
    let tf_topics =
        (tf_topic(&mut node, "tf", &tf_qos)?, tf_topic(&mut node, "tf_static", &tf_static_qos)?);
    let tf_reader = node
        .create_subscription::<TfMessage>(&tf_topics.0, Some(tf_qos))
        .map_err(|e| Error::dds("subscription", e))?;
    let tf_static_reader = node
        .create_subscription::<TfMessage>(&tf_topics.1, Some(tf_static_qos))
        .map_err(|e| Error::dds("subscription", e))?;
    let mut tf_tree = TfTree::new();
    let rig_name = rig.describe();
    let rig = Arc::new(Mutex::new(rig));
    let mut job = Arc::new(job);
    let frames = config.frames.clone();
    if let Some((mount_frame, mount_from_camera)) = &config.mount {
        tf_tree.insert_mm(mount_frame, &frames.camera, *mount_from_camera);
        topics
            .tf_static
            .publish(static_transform(mount_from_camera, mount_frame, &frames, Time::now()))
            .map_err(|e| Error::dds("/tf_static", e))?;
    }
    log(&format!(
        "node {}/{} serving {ns}/localize_fruit and {ns}/scan_detected on DDS domain {} ({}, {}) with the {rig_name}",
        if ns == "/" { "" } else { ns },
        config.node_name,
        env.domain_id,
        env.rmw_implementation,
        if env.localhost_only { "localhost only" } else { "all interfaces" },
    ));
    let mut state = State {
        rig: rig_name,
        sources: config
            .sources
            .iter()
            .map(|(what, path)| {
                let written = std::fs::metadata(path).and_then(|m| m.modified()).ok();
                (what.clone(), path.clone(), written)
            })
            .collect(),
        scan_mode: job.config.mode.name(),
        summary: NodeSummary::default(),
        scanning: false,
        last_scan_s: None,
        last_error: None,
        last_rejection: None,
    };
    let node_name = config.node_name.clone();
    smol::block_on(async {
        let mut running: Option<Running> = None;
        // Results on their way to clients; the node waits for them before
        // it exits, so a goal stopped by a signal still gets its answer.
        let mut results: Vec<smol::Task<()>> = Vec::new();
        let mut last_diagnostics = Instant::now() - DIAGNOSTICS_PERIOD;
        // The RGB-D front end: images waiting for their pair, the colour
        // camera, and one detection at a time (frames that come meanwhile
        // are dropped: the freshest pair is searched next).
        let mut colors: VecDeque<Image> = VecDeque::new();
        let mut depths: VecDeque<Image> = VecDeque::new();
        let mut rgbd_camera: Option<alacs_model::Camera> = None;
        let (rough_sender, rough_receiver) = smol::channel::unbounded::<RoughFound>();
        let mut detecting = false;
        let mut last_rgbd_problem: Option<String> = None;
        // The fruit of the latest fruit_rough (RGB-D frame, mm, best first)
        // and its header: what scan_detected scans.
        let mut latest_rough: Option<(Header, Vec<nalgebra::Point3<f64>>)> = None;
        // Another detector's boxes waiting for the images of their stamp.
        let mut pending_boxes: VecDeque<Detection2DArray> = VecDeque::new();
        loop {
            let finished = config.max_goals.is_some_and(|max| state.summary.goals >= max);
            if running.is_none() && (stop.load(Ordering::Relaxed) || finished) {
                break;
            }
            if stop.load(Ordering::Relaxed)
                && let Some(r) = running.as_mut()
                && r.stop_reason.is_none()
            {
                log("stopping: the running goal is aborted, the slide stops, laser off");
                r.cancel.store(true, Ordering::Relaxed);
                r.stop_reason = Some(StopReason::Shutdown);
            }
            results.retain(|task| !task.is_finished());
            if !detecting && let Some(camera) = &rgbd_camera {
                // The built-in detector searches the newest pair; another
                // detector's boxes wait for the pair of their stamp.
                let job = match boxes_2d {
                    None => take_pair(&mut colors, &mut depths).map(|(c, d)| (c, d, None)),
                    Some(_) => take_boxed(&mut pending_boxes, &mut colors, &mut depths)
                        .map(|(b, c, d)| (c, d, Some(detections_from_2d(&b, &classes)))),
                };
                if let Some((color, depth, boxes)) = job {
                    detecting = true;
                    let (sender, camera) = (rough_sender.clone(), camera.clone());
                    std::thread::spawn(move || {
                        let header = color.header.clone();
                        let found = detect_rough(color, &depth, &camera, boxes);
                        let _ = sender.send_blocking((header, found));
                    });
                }
            }
            if last_diagnostics.elapsed() >= DIAGNOSTICS_PERIOD {
                let _ = topics.diagnostics.publish(state.diagnostics(&node_name));
                last_diagnostics = Instant::now();
            }
            let job_message = async {
                match &running {
                    Some(r) => r.messages.recv().await.ok(),
                    None => futures::future::pending().await,
                }
            };
            futures::select! {
                goal = server.receive_new_goal().fuse() => {
                    let Ok(handle) = goal else { continue };
                    let Some(goal) = server.get_new_goal(handle.clone()) else { continue };
                    let request = match cannot_start(running.is_some(), &stop) {
                        Some(reason) => Err(reason),
                        None => job_request(&goal, &frames, &tf_tree),
                    };
                    let (request, goal_frame) = match request {
                        Ok(request) => request,
                        Err(reason) => {
                            log(&format!("goal rejected: {reason}"));
                            state.summary.rejected += 1;
                            state.last_rejection = Some(reason);
                            let _ = server.reject_goal(handle).await;
                            continue;
                        }
                    };
                    let Ok(accepted) = server.accept_goal(handle).await else { continue };
                    let Ok(executing) = server.start_executing_goal(accepted).await else { continue };
                    state.summary.goals += 1;
                    state.scanning = true;
                    let rough = request.rough_positions_mm[0];
                    log(&format!(
                        "goal {}: rough position ({:.1}, {:.1}, {:.1}) mm in the {} frame{}",
                        state.summary.goals,
                        rough.x,
                        rough.y,
                        rough.z,
                        if request.in_rgbd { &frames.rgbd } else { &frames.camera },
                        goal_frame.as_ref().map_or_else(String::new, |f| format!(" (the goal's {}, through tf2)", f.frame_id)),
                    ));
                    running = Some(start_job(Client::Goal(executing, goal_frame), request, &rig, &job));
                }
                call = sweep_server.async_receive_request().fuse() => {
                    let Ok((request_id, _)) = call else { continue };
                    let refusal = cannot_start(running.is_some(), &stop).or_else(|| {
                        match &latest_rough {
                            None => Some(match &config.rgbd_ns {
                                Some(rgbd_ns) => format!("no fruit_rough yet: no colour and depth pair with camera_info has come from {rgbd_ns}"),
                                None => "the RGB-D front end is off (no rgbd_ns): there is no fruit_rough to scan".to_string(),
                            }),
                            Some((_, roughs)) if roughs.is_empty() => Some("the latest fruit_rough holds no fruit".to_string()),
                            Some(_) => None,
                        }
                    });
                    if let Some(reason) = refusal {
                        log(&format!("scan_detected refused: {reason}"));
                        state.summary.rejected += 1;
                        state.last_rejection = Some(reason.clone());
                        let _ = sweep_server.async_send_response(request_id, TriggerResponse { success: false, message: reason }).await;
                        continue;
                    }
                    let Some((header, roughs)) = &latest_rough else { continue };
                    let detected = roughs.len();
                    let request = JobRequest {
                        rough_positions_mm: roughs.iter().take(MAX_SCAN_TARGETS).copied().collect(),
                        in_rgbd: true,
                        fruit_radius_mm: job.config.fruit_radius_mm,
                        leave_out_of_reach: true,
                    };
                    state.summary.sweeps += 1;
                    state.scanning = true;
                    log(&format!(
                        "scan_detected {}: {} fruit of the fruit_rough at {:.3} s in one sweep",
                        state.summary.sweeps,
                        request.rough_positions_mm.len(),
                        seconds(header.stamp),
                    ));
                    let beyond_limit = detected - request.rough_positions_mm.len();
                    let client = Client::Sweep { request: request_id, detected, beyond_limit };
                    running = Some(start_job(client, request, &rig, &job));
                }
                message = job_message.fuse() => {
                    let Some(r) = running.as_mut() else { continue };
                    match message {
                        Some(JobMessage::Progress(Progress::Frame { frame, n_frames, slide_mm, stripe_points, image })) => {
                            let header = Header::new(Time::now(), &frames.camera);
                            if let Client::Goal(handle, _) = &r.client {
                                let _ = server.publish_feedback(handle.clone(), LocalizeFruitFeedback {
                                    frame: u32::try_from(frame + 1).unwrap_or(u32::MAX),
                                    n_frames: u32::try_from(n_frames).unwrap_or(u32::MAX),
                                    slide_position_m: slide_mm / 1000.0,
                                    stripe_points: u32::try_from(stripe_points).unwrap_or(u32::MAX),
                                }).await;
                            }
                            if publish_images {
                                let _ = topics.image.publish(image_message(&image, header.clone()));
                            }
                            let _ = topics.camera_info.publish(camera_info(&job.camera, header));
                        }
                        Some(JobMessage::Done(outcome)) => {
                            let Some(mut r) = running.take() else { continue };
                            if let Some(thread) = r.thread.take() {
                                let _ = thread.join();
                            }
                            let header = Header::new(Time::now(), &frames.camera);
                            state.scanning = false;
                            match r.client {
                                Client::Goal(handle, goal_frame) => {
                                    let (end, result) = conclude(&outcome, r.stop_reason, &header, &topics, &mut state, log);
                                    let result = match &goal_frame {
                                        Some(frame) => frame.answer(result),
                                        None => result,
                                    };
                                    if let (Some(bag), Outcome::Localized { localizations, scan, .. }) = (recorder.as_mut(), &outcome)
                                        && let Err(e) = bag.write_scan(scan, Some(&job.camera), localizations.first())
                                    {
                                        log(&format!("recording: {e}"));
                                    }
                                    results.push(send_result(&server, handle, end, result));
                                }
                                Client::Sweep { request, detected, beyond_limit } => {
                                    if recorder.is_some() && matches!(outcome, Outcome::Localized { .. }) {
                                        log("recording: a sweep is not recorded (a bag holds one fruit per scan)");
                                    }
                                    let response = conclude_sweep(&outcome, (detected, beyond_limit), r.stop_reason, &header, &topics, &mut state, log);
                                    let _ = sweep_server.async_send_response(request, response).await;
                                }
                            }
                            let _ = topics.diagnostics.publish(state.diagnostics(&node_name));
                        }
                        None => {
                            // The job's thread ended without a word (it panicked).
                            let Some(mut r) = running.take() else { continue };
                            if let Some(thread) = r.thread.take() {
                                let _ = thread.join();
                            }
                            state.scanning = false;
                            state.summary.errors += 1;
                            let reason = "the scan's thread ended without a result".to_string();
                            state.last_error = Some(reason.clone());
                            let header = Header::new(Time::now(), &frames.camera);
                            match r.client {
                                Client::Goal(handle, _) => results.push(send_result(&server, handle, GoalEndStatus::Aborted, error_result("error", &reason, header))),
                                Client::Sweep { request, .. } => {
                                    let _ = sweep_server.async_send_response(request, TriggerResponse { success: false, message: reason }).await;
                                }
                            }
                        }
                    }
                }
                cancel = server.receive_cancel_request().fuse() => {
                    let Ok(cancel) = cancel else { continue };
                    match running.as_mut() {
                        Some(Running { client: Client::Goal(handle, _), cancel: stop_job, stop_reason, .. })
                            if cancel.contains_goal(&handle.goal_id()) =>
                        {
                            log("cancel requested: stopping the slide, laser off");
                            stop_job.store(true, Ordering::Relaxed);
                            stop_reason.get_or_insert(StopReason::Cancelled);
                            let goal = handle.goal_id();
                            let _ = server.respond_to_cancel_requests(&cancel, std::iter::once(goal)).await;
                        }
                        _ => {
                            let _ = server.respond_to_cancel_requests(&cancel, std::iter::empty()).await;
                        }
                    }
                }
                color = next_message(rgbd.as_ref().map(|r| &r.color)).fuse() => {
                    if let Some(color) = color {
                        queue(&mut colors, color, image_queue);
                    }
                }
                depth = next_message(rgbd.as_ref().map(|r| &r.depth)).fuse() => {
                    if let Some(depth) = depth {
                        queue(&mut depths, depth, image_queue);
                    }
                }
                info = next_message(rgbd.as_ref().map(|r| &r.info)).fuse() => {
                    match info.map(|info| camera_from_info(&info, "the RGB-D camera")) {
                        Some(Ok(camera)) => rgbd_camera = Some(camera),
                        Some(Err(problem)) if last_rgbd_problem.as_ref() != Some(&problem) => {
                            log(&format!("RGB-D camera_info: {problem}"));
                            last_rgbd_problem = Some(problem);
                        }
                        Some(Err(_)) | None => {}
                    }
                }
                boxes = next_message(boxes_2d.as_ref()).fuse() => {
                    // Matched with their images at the top of the loop (either may come first).
                    let Some(boxes) = boxes else { continue };
                    if pending_boxes.len() >= image_queue
                        && let Some(old) = pending_boxes.pop_front()
                    {
                        let problem = match rgbd_camera {
                            None => "detections_2d come, and no camera_info from the RGB-D camera".to_string(),
                            Some(_) => format!(
                                "detections_2d at {:.3} s: no colour and depth image with that stamp came",
                                seconds(old.header.stamp)
                            ),
                        };
                        if last_rgbd_problem.as_ref() != Some(&problem) {
                            log(&format!("RGB-D front end: {problem}"));
                            last_rgbd_problem = Some(problem);
                        }
                    }
                    pending_boxes.push_back(boxes);
                }
                request = parameter_services.next().fuse() => {
                    let changed = parameter_services.answer(request, &mut parameters).await;
                    for name in changed {
                        let value = parameters.get(&name).map(|p| p.value.clone());
                        log(&format!("parameter {name} set to {value:?}; it applies from the next job"));
                        match (name.as_str(), value) {
                            ("no_images", Some(ParameterValue::Boolean(off))) => publish_images = !off,
                            ("rough_depth_error", Some(ParameterValue::Double(v))) => {
                                Arc::make_mut(&mut job).locate.rough_depth_error = v;
                            }
                            ("rough_lateral_error_mm", Some(ParameterValue::Double(v))) => {
                                Arc::make_mut(&mut job).locate.rough_lateral_error_mm = v;
                            }
                            _ => {}
                        }
                    }
                }
                transforms = next_message(Some(&tf_reader)).fuse() => {
                    if let Some(transforms) = transforms {
                        tf_tree.insert(&transforms);
                    }
                }
                transforms = next_message(Some(&tf_static_reader)).fuse() => {
                    if let Some(transforms) = transforms {
                        tf_tree.insert(&transforms);
                    }
                }
                found = rough_receiver.recv().fuse() => {
                    detecting = false;
                    match found {
                        Ok((header, Ok(detections))) => {
                            let roughs = detections.iter().filter_map(|d| d.rough.as_ref().map(|r| r.position_mm)).collect();
                            latest_rough = Some((header.clone(), roughs));
                            let _ = topics.fruit_rough.publish(rough_detections(&detections, header));
                        }
                        Ok((_, Err(problem))) => {
                            if last_rgbd_problem.as_ref() != Some(&problem) {
                                log(&format!("RGB-D images: {problem}"));
                                last_rgbd_problem = Some(problem);
                            }
                        }
                        Err(_) => {}
                    }
                }
                _ = smol::Timer::after(TICK).fuse() => {}
            }
        }
        let flushed = async {
            for task in results {
                task.await;
            }
        };
        flushed
            .or(async {
                smol::Timer::after(EXIT_RESULT_WAIT).await;
            })
            .await;
    });
    // The laser is off at exit, whatever happened before.
    let mut rig = rig.lock().unwrap_or_else(PoisonError::into_inner);
    let laser_off = rig.rig().laser.set(false).map_err(Error::Scanner);
    if let Some(bag) = recorder {
        let scans = bag.scans();
        match bag.finish() {
            Ok(path) => log(&format!("recorded {scans} scans in {}", path.display())),
            Err(e) => log(&format!("recording: {e}")),
        }
    }
    laser_off?;
    log("stopped; the laser is off");
    Ok(state.summary)
}

/// A stamp in seconds since the epoch (for the log).
fn seconds(stamp: Time) -> f64 {
    stamp.to_nanos() as f64 * 1e-9
}

/// Starts `request` on the rig's thread for `client`.
fn start_job(
    client: Client,
    request: JobRequest,
    rig: &Arc<Mutex<Box<dyn ScanRig>>>,
    job: &Arc<JobContext>,
) -> Running {
    let (sender, receiver) = smol::channel::unbounded();
    let cancel = Arc::new(AtomicBool::new(false));
    let thread = {
        let (rig, job, cancel) = (Arc::clone(rig), Arc::clone(job), Arc::clone(&cancel));
        std::thread::spawn(move || {
            let mut rig = rig.lock().unwrap_or_else(PoisonError::into_inner);
            let progress = sender.clone();
            let mut report = |p: Progress| {
                let _ = progress.send_blocking(JobMessage::Progress(p));
            };
            let outcome = run_job(rig.as_mut(), &job, &request, &cancel, &mut report);
            let _ = sender.send_blocking(JobMessage::Done(outcome));
        })
    };
    Running { client, cancel, stop_reason: None, messages: receiver, thread: Some(thread) }
}

/// Publishes a finished sweep's fruit (`<ns>/fruit`: the ones found, in
/// the ALACS camera's frame) and its laser points, and says in one line
/// what became of each detected fruit. `counts`: the fruit detected, and
/// how many of them lay beyond [`MAX_SCAN_TARGETS`]; a sweep is stopped
/// only when the node is.
fn conclude_sweep(
    outcome: &Outcome,
    (detected, beyond_limit): (usize, usize),
    stop_reason: Option<StopReason>,
    header: &Header,
    topics: &Topics,
    state: &mut State,
    log: &(dyn Fn(&str) + Sync),
) -> TriggerResponse {
    let (success, message) = match outcome {
        Outcome::Localized { localizations, scan, elapsed, out_of_reach } => {
            state.last_scan_s = Some(elapsed.as_secs_f64());
            state.last_error = None;
            let fruit = fruit_array(localizations, header.clone());
            let found = fruit.detections.len();
            state.summary.found += found as u64;
            for localization in localizations {
                let _ = topics.laser_points.publish(laser_cloud(localization, header.clone()));
            }
            let _ = topics.fruit.publish(fruit);
            let mut reasons: Vec<String> = localizations
                .iter()
                .filter(|l| l.status != alacs_locate::Status::Ok)
                .map(|l| l.reason.clone())
                .collect();
            reasons.dedup();
            let mut message = format!(
                "{found} of {detected} detected fruit found in one sweep of {} frames ({:.1} s)",
                scan.frames.len(),
                elapsed.as_secs_f64()
            );
            let not_found = localizations.len() - found;
            if not_found > 0 {
                message += &format!("; {not_found} not found ({})", reasons.join("; "));
            }
            if *out_of_reach > 0 {
                message += &format!("; {out_of_reach} beyond the slide's reach");
            }
            if beyond_limit > 0 {
                message += &format!(
                    "; {beyond_limit} left for the next call (a sweep scans at most {MAX_SCAN_TARGETS})"
                );
            }
            (true, message)
        }
        Outcome::Cancelled | Outcome::Failed(_) if stop_reason.is_some() => {
            state.summary.stopped += 1;
            (false, "the node was stopped (SIGINT or SIGTERM) during the sweep".to_string())
        }
        Outcome::Cancelled => (false, "the sweep was cancelled".to_string()),
        Outcome::Failed(reason) => {
            state.summary.errors += 1;
            state.last_error = Some(reason.clone());
            (false, format!("the sweep failed: {reason}"))
        }
    };
    log(&format!("scan_detected: {message}; the laser is off"));
    TriggerResponse { success, message }
}

/// Sends a finished goal's result when its client asks for it (at most
/// [`RESULT_WAIT`]), without holding up the loop.
fn send_result(
    server: &Arc<Server>,
    handle: ExecutingGoalHandle<LocalizeFruitGoal>,
    end: GoalEndStatus,
    result: LocalizeFruitResult,
) -> smol::Task<()> {
    let server = Arc::clone(server);
    smol::spawn(async move {
        let _ = server
            .send_result_response(handle, end, result)
            .or(async {
                smol::Timer::after(RESULT_WAIT).await;
                Err(GoalError::NoSuchGoal)
            })
            .await;
    })
}

/// Publishes a finished goal's topics and says how it ends.
fn conclude(
    outcome: &Outcome,
    stop_reason: Option<StopReason>,
    header: &Header,
    topics: &Topics,
    state: &mut State,
    log: &(dyn Fn(&str) + Sync),
) -> (GoalEndStatus, LocalizeFruitResult) {
    match outcome {
        Outcome::Localized { localizations, elapsed, .. } => {
            let Some(localization) = localizations.first() else {
                // A goal names one fruit and the job answers for each.
                let reason = "the scan gave no answer";
                state.summary.errors += 1;
                return (GoalEndStatus::Aborted, error_result("error", reason, header.clone()));
            };
            state.last_scan_s = Some(elapsed.as_secs_f64());
            state.last_error = None;
            let result = localization_result(localization, header.clone());
            let _ = topics.laser_points.publish(laser_cloud(localization, header.clone()));
            match (&localization.position_mm, localization.radius_mm) {
                (Some(centre), Some(radius)) if result.status == "ok" => {
                    state.summary.found += 1;
                    let p = point_m(centre);
                    log(&format!(
                        "found the fruit at ({:.4}, {:.4}, {:.4}) m; scan and localization took {:.1} ms",
                        p.x,
                        p.y,
                        p.z,
                        elapsed.as_secs_f64() * 1000.0
                    ));
                    if let Some(detections) = fruit_detections(localization, header.clone()) {
                        let _ = topics.fruit.publish(detections);
                    }
                    let _ = topics.marker.publish(fruit_marker(centre, radius, header.clone()));
                }
                _ => log(&format!(
                    "not found: {}; scan and localization took {:.1} ms",
                    localization.reason,
                    elapsed.as_secs_f64() * 1000.0
                )),
            }
            (GoalEndStatus::Succeeded, result)
        }
        Outcome::Cancelled | Outcome::Failed(_) if stop_reason == Some(StopReason::Shutdown) => {
            state.summary.stopped += 1;
            let reason = "the node was stopped (SIGINT or SIGTERM) during the scan";
            log(&format!("goal aborted: {reason}; the laser is off"));
            (GoalEndStatus::Aborted, error_result("error", reason, header.clone()))
        }
        Outcome::Cancelled => {
            state.summary.cancelled += 1;
            log("goal cancelled; the laser is off");
            (
                GoalEndStatus::Canceled,
                error_result("error", "the goal was cancelled", header.clone()),
            )
        }
        Outcome::Failed(reason) if stop_reason == Some(StopReason::Cancelled) => {
            state.summary.cancelled += 1;
            log(&format!("goal cancelled ({reason}); the laser is off"));
            (GoalEndStatus::Canceled, error_result("error", reason, header.clone()))
        }
        Outcome::Failed(reason) => {
            state.summary.errors += 1;
            state.last_error = Some(reason.clone());
            log(&format!("goal aborted: {reason}; the laser is off"));
            (GoalEndStatus::Aborted, error_result("error", reason, header.clone()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagnostics_name_the_calibration_files_and_their_age() {
        let dir = tempfile::tempdir().unwrap();
        let camera = dir.path().join("camera.yaml");
        std::fs::write(&camera, "x").unwrap();
        let state = State {
            rig: "simulated rig".into(),
            sources: vec![
                (
                    "camera".into(),
                    camera.clone(),
                    std::fs::metadata(&camera).unwrap().modified().ok(),
                ),
                ("laser".into(), dir.path().join("gone.yaml"), None),
            ],
            scan_mode: "stop_and_go",
            summary: NodeSummary::default(),
            scanning: false,
            last_scan_s: None,
            last_error: None,
            last_rejection: None,
        };
        let values = &state.diagnostics("alacs").status[0].values;
        let get = |key: &str| values.iter().find(|v| v.key == key).map(|v| v.value.clone());
        assert_eq!(get("camera_file"), Some(camera.display().to_string()));
        assert_eq!(get("camera_file_age_days").as_deref(), Some("0.0"));
        assert_eq!(get("laser_file_age_days").as_deref(), Some("unknown"));
    }
}
