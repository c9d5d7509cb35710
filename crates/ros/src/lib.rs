//! `alacs-ros`: the ALACS scanner on a ROS 2 graph, in pure Rust
//! (ros2-client + RustDDS; no ROS installation needed to build or run it).
//!
//! The node serves the action `<ns>/localize_fruit`
//! (`alacs_msgs/action/LocalizeFruit`, `ros/alacs_msgs` in the repository)
//! one goal at a time: the seed's 5-frame scan on a rig ([`ScanRig`]),
//! feedback per frame, the localization as the result in metres in the
//! ALACS camera frame or the goal's (any frame [`tf::TfTree`] can place,
//! from `/tf` and `/tf_static`). The RGB-D front end publishes
//! `<ns>/fruit_rough` and the service `<ns>/scan_detected` scans them in
//! one sweep. It publishes `<ns>/fruit`, `<ns>/laser_points`,
//! `<ns>/fruit_marker`, `<ns>/image`, `<ns>/camera_info`, `/tf_static` and
//! `/diagnostics`, and follows ROS 2's environment ([`RosEnvironment`]:
//! `ROS_DOMAIN_ID`, `ROS_AUTOMATIC_DISCOVERY_RANGE` / `ROS_LOCALHOST_ONLY`,
//! and `RMW_IMPLEMENTATION` for the service wire mapping).

pub mod bag;
mod convert;
mod env;
mod error;
mod job;
pub mod msgs;
mod node;
pub mod params;
pub mod tf;

pub use convert::{
    CLOUD_POINT_STEP, FRUIT_CLASS, Frames, GoalFrame, body_from_optical, camera_from_info,
    fruit_detections, job_request, laser_cloud, localization_result,
};
pub use env::{DEFAULT_RMW, MAX_DOMAIN_ID, RosEnvironment};
pub use error::{Error, Result};
pub use job::{CANCELLED, JobContext, JobRequest, Outcome, Progress, ScanRig, run_job};
pub use node::{
    FruitDetector, NodeConfig, NodeSummary, RUNTIME_PARAMETERS, run_node, validate_namespace,
};
pub use params::NodeParameter;
pub use ros2_client::parameters::ParameterValue;
