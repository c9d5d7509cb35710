//! The ROS 2 messages the node speaks, as serde structs in the fields' .msg
//! order (CDR, XCDR1, is positional: names are ours, order and types are
//! the wire). The standard ones mirror `std_msgs`, `geometry_msgs`,
//! `sensor_msgs`, `visualization_msgs`, `tf2_msgs`, `diagnostic_msgs` and
//! `vision_msgs` 4.x
//! (identical in Humble and Jazzy); the action is `alacs_msgs`'s
//! `LocalizeFruit`, checked field by field against
//! `ros/alacs_msgs/action/LocalizeFruit.action` ([`LOCALIZE_FRUIT_ACTION`]).
//! Units are ROS's (REP 103): metres, radians, seconds.

use ros2_client::builtin_interfaces::{Duration, Time};
use ros2_client::{Message, MessageTypeName};
use serde::{Deserialize, Serialize};

/// The action definition, as ROS 2 users build it (`ros/alacs_msgs`).
pub const LOCALIZE_FRUIT_ACTION: &str =
    include_str!("../../../ros/alacs_msgs/action/LocalizeFruit.action");

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Acquisition time.
    pub stamp: Time,
    /// The coordinate frame (REP 105 style names).
    pub frame_id: String,
}

impl Header {
    /// A header stamped `stamp` in `frame_id`.
    pub fn new(stamp: Time, frame_id: &str) -> Self {
        Self { stamp, frame_id: frame_id.to_string() }
    }
}

/// `geometry_msgs/Point`, metres.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// z, m.
    pub z: f64,
}

/// `geometry_msgs/Vector3`.
pub type Vector3 = Point;

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }
    }
}

/// `geometry_msgs/PointStamped`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointStamped {
    /// Time and frame.
    pub header: Header,
    /// The point, m.
    pub point: Point,
}
impl Message for PointStamped {}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseWithCovariance`: the covariance row-major over
/// (x, y, z, rotation about x, y, z), m^2 and rad^2.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// 6 x 6, row by row (on the wire the 36 float64 of `float64[36]`:
    /// fixed arrays carry no length, so rows of six are the same bytes).
    pub covariance: [[f64; 6]; 6],
}

/// `vision_msgs/ObjectHypothesis` (vision_msgs 4.x).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectHypothesis {
    /// The class ("apple").
    pub class_id: String,
    /// Its probability or score.
    pub score: f64,
}

/// `vision_msgs/ObjectHypothesisWithPose`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectHypothesisWithPose {
    /// The class and score.
    pub hypothesis: ObjectHypothesis,
    /// Where the object is, with the covariance.
    pub pose: PoseWithCovariance,
}

/// `vision_msgs/BoundingBox3D`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoundingBox3D {
    /// The box's centre and orientation.
    pub center: Pose,
    /// Its size along its axes, m.
    pub size: Vector3,
}

/// `vision_msgs/Detection3D` (vision_msgs 4.x: no source data).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection3D {
    /// Time and frame.
    pub header: Header,
    /// The hypotheses (one: the fruit).
    pub results: Vec<ObjectHypothesisWithPose>,
    /// The box around it.
    pub bbox: BoundingBox3D,
    /// The same object across messages, where tracked; may be empty.
    pub id: String,
}

/// `vision_msgs/Detection3DArray`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection3DArray {
    /// Time and frame.
    pub header: Header,
    /// The detections.
    pub detections: Vec<Detection3D>,
}
impl Message for Detection3DArray {}

/// `vision_msgs/Point2D` (vision_msgs 4.x), px in image messages.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point2D {
    /// Column, px.
    pub x: f64,
    /// Row, px.
    pub y: f64,
}

/// `vision_msgs/Pose2D` (vision_msgs 4.x; geometry_msgs/Pose2D before).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose2D {
    /// The box's centre, px.
    pub position: Point2D,
    /// Its rotation, rad.
    pub theta: f64,
}

/// `vision_msgs/BoundingBox2D`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct BoundingBox2D {
    /// The box's centre and rotation.
    pub center: Pose2D,
    /// Width, px.
    pub size_x: f64,
    /// Height, px.
    pub size_y: f64,
}

/// `vision_msgs/Detection2D` (vision_msgs 4.x: no source image).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection2D {
    /// Time and frame (the image's).
    pub header: Header,
    /// The class hypotheses (their poses unused in 2-D).
    pub results: Vec<ObjectHypothesisWithPose>,
    /// The box in the image.
    pub bbox: BoundingBox2D,
    /// The same object across messages, where tracked; may be empty.
    pub id: String,
}

/// `vision_msgs/Detection2DArray`: another detector's output on the
/// colour image (`<ns>/detections_2d`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection2DArray {
    /// Time and frame: the colour image's.
    pub header: Header,
    /// The detections.
    pub detections: Vec<Detection2D>,
}
impl Message for Detection2DArray {}

/// `std_srvs/srv/Trigger`'s request: empty, so ROS 2's IDL gives it one
/// placeholder byte (`structure_needs_at_least_one_field`, 0).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// ROS 2's placeholder for an empty message.
    pub structure_needs_at_least_one_field: u8,
}
impl Message for TriggerRequest {}

/// `std_srvs/srv/Trigger`'s response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// Whether the job ran.
    pub success: bool,
    /// One line for whoever called.
    pub message: String,
}
impl Message for TriggerResponse {}

/// `geometry_msgs/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation, m.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/TransformStamped`: `child_frame_id`'s pose in `header.frame_id`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Time and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// parent_from_child.
    pub transform: Transform,
}

/// `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}
impl Message for TfMessage {}

/// `sensor_msgs/PointField`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointField {
    /// Field name.
    pub name: String,
    /// Byte offset in a point.
    pub offset: u32,
    /// Data type ([`PointField::FLOAT32`], ...).
    pub datatype: u8,
    /// Elements.
    pub count: u32,
}

impl PointField {
    /// `sensor_msgs/PointField.UINT8`.
    pub const UINT8: u8 = 2;
    /// `sensor_msgs/PointField.UINT32`.
    pub const UINT32: u8 = 6;
    /// `sensor_msgs/PointField.FLOAT32`.
    pub const FLOAT32: u8 = 7;
}

/// `sensor_msgs/PointCloud2`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    /// Time and frame.
    pub header: Header,
    /// Rows (1: unordered).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The fields of a point.
    pub fields: Vec<PointField>,
    /// Byte order of `data`.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// No invalid points.
    pub is_dense: bool,
}
impl Message for PointCloud2 {}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Time and frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding ("rgb8").
    pub encoding: String,
    /// Byte order.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}
impl Message for Image {}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionOfInterest {
    /// Left, px.
    pub x_offset: u32,
    /// Top, px.
    pub y_offset: u32,
    /// Height, px.
    pub height: u32,
    /// Width, px.
    pub width: u32,
    /// Whether to rectify.
    pub do_rectify: bool,
}

/// `sensor_msgs/CameraInfo`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// Time and frame.
    pub header: Header,
    /// Image height, px.
    pub height: u32,
    /// Image width, px.
    pub width: u32,
    /// "plumb_bob" or "rational_polynomial".
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsics, row-major.
    pub k: [f64; 9],
    /// Rectification, row-major.
    pub r: [f64; 9],
    /// Projection, row-major 3 x 4.
    pub p: [f64; 12],
    /// Binning.
    pub binning_x: u32,
    /// Binning.
    pub binning_y: u32,
    /// Region of interest.
    pub roi: RegionOfInterest,
}
impl Message for CameraInfo {}

/// `std_msgs/ColorRGBA`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRgba {
    /// Red, 0-1.
    pub r: f32,
    /// Green, 0-1.
    pub g: f32,
    /// Blue, 0-1.
    pub b: f32,
    /// Alpha, 0-1.
    pub a: f32,
}

/// `visualization_msgs/UVCoordinate`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UvCoordinate {
    /// u.
    pub u: f32,
    /// v.
    pub v: f32,
}

/// `sensor_msgs/CompressedImage`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Time and frame.
    pub header: Header,
    /// "jpeg", "png".
    pub format: String,
    /// The image.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `visualization_msgs/MeshFile`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// Its name.
    pub filename: String,
    /// Its bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `visualization_msgs/Marker` (Humble and Jazzy layout).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Marker {
    /// Time and frame.
    pub header: Header,
    /// Namespace of the marker.
    pub ns: String,
    /// Id within the namespace.
    pub id: i32,
    /// [`Marker::SPHERE`], ...
    pub r#type: i32,
    /// [`Marker::ADD`], ...
    pub action: i32,
    /// Pose in the header's frame.
    pub pose: Pose,
    /// Size, m (a sphere's diameters).
    pub scale: Vector3,
    /// Colour.
    pub color: ColorRgba,
    /// 0: forever.
    pub lifetime: Duration,
    /// Re-transform every frame.
    pub frame_locked: bool,
    /// Points (line and point markers).
    pub points: Vec<Point>,
    /// Per-point colours.
    pub colors: Vec<ColorRgba>,
    /// Texture resource.
    pub texture_resource: String,
    /// Texture.
    pub texture: CompressedImage,
    /// Texture coordinates.
    pub uv_coordinates: Vec<UvCoordinate>,
    /// Text markers.
    pub text: String,
    /// Mesh resource.
    pub mesh_resource: String,
    /// Embedded mesh.
    pub mesh_file: MeshFile,
    /// Mesh materials.
    pub mesh_use_embedded_materials: bool,
}
impl Message for Marker {}

impl Marker {
    /// `visualization_msgs/Marker.SPHERE`.
    pub const SPHERE: i32 = 2;
    /// `visualization_msgs/Marker.ADD`.
    pub const ADD: i32 = 0;
}

/// `diagnostic_msgs/KeyValue`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeyValue {
    /// Key.
    pub key: String,
    /// Value.
    pub value: String,
}

/// `diagnostic_msgs/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`], ...
    pub level: u8,
    /// Component name.
    pub name: String,
    /// What is up.
    pub message: String,
    /// Hardware id.
    pub hardware_id: String,
    /// Details.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// OK.
    pub const OK: u8 = 0;
    /// WARN.
    pub const WARN: u8 = 1;
    /// ERROR.
    pub const ERROR: u8 = 2;
}

/// `diagnostic_msgs/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Time.
    pub header: Header,
    /// Statuses.
    pub status: Vec<DiagnosticStatus>,
}
impl Message for DiagnosticArray {}

/// `sensor_msgs/JointState`: the slide as joint "slide", metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, m (prismatic joints).
    pub position: Vec<f64>,
    /// Velocities, m/s (may be empty).
    pub velocity: Vec<f64>,
    /// Efforts, N (may be empty).
    pub effort: Vec<f64>,
}
impl Message for JointState {}

/// `std_msgs/Bool`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bool {
    /// The value.
    pub data: bool,
}
impl Message for Bool {}

/// The goal of `alacs_msgs/action/LocalizeFruit`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizeFruitGoal {
    /// The rough fruit centre, in the ALACS camera frame or the RGB-D frame, m.
    pub rough_position: PointStamped,
    /// The fruit radius prior, m; 0: unknown (the default prior).
    pub fruit_radius_m: f64,
}
impl Message for LocalizeFruitGoal {}

/// The result of `alacs_msgs/action/LocalizeFruit`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizeFruitResult {
    /// "ok" | "not_found" | "error".
    pub status: String,
    /// Why not ok (empty when ok).
    pub reason: String,
    /// The fruit centre in the ALACS camera frame, m.
    pub position: PointStamped,
    /// The fruit radius, m.
    pub radius_m: f64,
    /// Position covariance, m^2, row-major; element 0 is -1 where it was
    /// not estimated (not found, the holistic method).
    pub position_covariance: [f64; 9],
    /// The frame whose candidate was chosen; -1: the fused fit.
    pub selected_frame: i32,
    /// Laser points on the fruit.
    pub n_points: u32,
}
impl Message for LocalizeFruitResult {}

/// The feedback of `alacs_msgs/action/LocalizeFruit`: one per captured frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizeFruitFeedback {
    /// Frames captured so far (1-based).
    pub frame: u32,
    /// Frames of the scan.
    pub n_frames: u32,
    /// Where the slide stood for this frame, m.
    pub slide_position_m: f64,
    /// Stripe points found in this frame (0 until localization).
    pub stripe_points: u32,
}
impl Message for LocalizeFruitFeedback {}

/// The fields of the action's three parts in .action order, as (ROS type,
/// name): what a test compares with [`LOCALIZE_FRUIT_ACTION`].
pub const LOCALIZE_FRUIT_FIELDS: [&[(&str, &str)]; 3] = [
    &[("geometry_msgs/PointStamped", "rough_position"), ("float64", "fruit_radius_m")],
    &[
        ("string", "status"),
        ("string", "reason"),
        ("geometry_msgs/PointStamped", "position"),
        ("float64", "radius_m"),
        ("float64[9]", "position_covariance"),
        ("int32", "selected_frame"),
        ("uint32", "n_points"),
    ],
    &[
        ("uint32", "frame"),
        ("uint32", "n_frames"),
        ("float64", "slide_position_m"),
        ("uint32", "stripe_points"),
    ],
];

/// The DDS type names of the messages the node publishes.
pub fn type_name(package: &str, name: &str) -> MessageTypeName {
    MessageTypeName::new(package, name)
}
