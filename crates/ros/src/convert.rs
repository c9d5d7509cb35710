//! Between the library (mm, nalgebra, `Localization`) and ROS messages
//! (metres, REP 103 / 105 frames). Every unit conversion of the node is here.

use alacs_detect::{DepthImage, Detection};
use alacs_locate::{Localization, Method, Status};
use alacs_model::{Camera, DEFAULT_FRUIT_RADIUS_MM, FRUIT_RADIUS_RANGE_MM};
use image::RgbImage;
use nalgebra::{Isometry3, Point3};
use ros2_client::builtin_interfaces::{Duration, Time};

use crate::job::JobRequest;
use crate::msgs::{
    BoundingBox3D, CameraInfo, ColorRgba, CompressedImage, Detection2DArray, Detection3D,
    Detection3DArray, Header, Image, LocalizeFruitGoal, LocalizeFruitResult, Marker, MeshFile,
    ObjectHypothesis, ObjectHypothesisWithPose, Point, PointCloud2, PointField, PointStamped, Pose,
    PoseWithCovariance, Quaternion, RegionOfInterest, TfMessage, Transform, TransformStamped,
    Vector3,
};
use crate::tf::TfTree;

/// Millimetres per metre.
pub(crate) const MM_PER_M: f64 = 1000.0;

/// The frames the node names (REP 105 style; configurable).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frames {
    /// The ALACS camera's optical frame: results, clouds, images.
    pub camera: String,
    /// The RGB-D camera's optical frame: where rough positions may come from.
    pub rgbd: String,
}

impl Default for Frames {
    fn default() -> Self {
        Self {
            camera: "alacs_camera_optical_frame".into(),
            rgbd: "rgbd_camera_optical_frame".into(),
        }
    }
}

/// A goal as the job takes it, or why it is rejected.
pub fn job_request(
    goal: &LocalizeFruitGoal,
    frames: &Frames,
    tf: &TfTree,
) -> Result<(JobRequest, Option<GoalFrame>), String> {
    let frame_id = goal.rough_position.header.frame_id.trim();
    let p = goal.rough_position.point;
    if ![p.x, p.y, p.z].iter().all(|c| c.is_finite()) {
        return Err(format!("rough_position ({}, {}, {}) m is not finite", p.x, p.y, p.z));
    }
    let point_mm = Point3::new(p.x, p.y, p.z) * MM_PER_M;
    // The camera's and the RGB-D camera's frames are the calibration's;
    // any other comes through the robot's tree.
    let (rough_mm, in_rgbd, goal_frame) = if frame_id.is_empty() || frame_id == frames.camera {
        (point_mm, false, None)
    } else if frame_id == frames.rgbd {
        (point_mm, true, None)
    } else {
        let camera_from_goal = tf.lookup(&frames.camera, frame_id).map_err(|e| {
            format!(
                "rough_position.header.frame_id `{frame_id}` is neither `{}` nor `{}`, and tf2 cannot place it: {e}",
                frames.camera, frames.rgbd
            )
        })?;
        let goal_frame = GoalFrame {
            frame_id: frame_id.to_owned(),
            frame_from_camera_mm: camera_from_goal.inverse(),
        };
        (camera_from_goal * point_mm, false, Some(goal_frame))
    };
    let fruit_radius_mm = if goal.fruit_radius_m == 0.0 {
        DEFAULT_FRUIT_RADIUS_MM
    } else {
        let radius_mm = goal.fruit_radius_m * MM_PER_M;
        let (low, high) = FRUIT_RADIUS_RANGE_MM;
        if !(low..=high).contains(&radius_mm) {
            return Err(format!(
                "fruit_radius_m {} must be 0 (unknown) or from {} to {} m",
                goal.fruit_radius_m,
                low / MM_PER_M,
                high / MM_PER_M
            ));
        }
        radius_mm
    };
    let request = JobRequest {
        rough_positions_mm: vec![rough_mm],
        in_rgbd,
        fruit_radius_mm,
        leave_out_of_reach: false,
    };
    Ok((request, goal_frame))
}

/// A goal asked in a frame of the robot's tree (not the camera's or the
/// RGB-D camera's): its result is answered there.
#[derive(Debug, Clone, PartialEq)]
pub struct GoalFrame {
    /// The goal's frame.
    pub frame_id: String,
    /// That frame from the ALACS camera's, mm, when the goal came.
    pub frame_from_camera_mm: Isometry3<f64>,
}

impl GoalFrame {
    /// `result` (in the camera's frame) in the goal's frame: the position
    /// moved, the covariance turned (R C R^T); a position of a fruit not
    /// found stays zero.
    pub fn answer(&self, mut result: LocalizeFruitResult) -> LocalizeFruitResult {
        result.position.header.frame_id.clone_from(&self.frame_id);
        if result.status == "ok" {
            let p = result.position.point;
            let moved = self.frame_from_camera_mm * (Point3::new(p.x, p.y, p.z) * MM_PER_M);
            result.position.point = point_m(&moved);
            if result.position_covariance[0] >= 0.0 {
                let r = self.frame_from_camera_mm.rotation.to_rotation_matrix();
                let c = nalgebra::Matrix3::from_row_slice(&result.position_covariance);
                let turned = r.matrix() * c * r.matrix().transpose();
                result.position_covariance = std::array::from_fn(|i| turned[(i / 3, i % 3)]);
            }
        }
        result
    }
}

/// A point in mm as a ROS point in m.
pub fn point_m(point_mm: &Point3<f64>) -> Point {
    Point { x: point_mm.x / MM_PER_M, y: point_mm.y / MM_PER_M, z: point_mm.z / MM_PER_M }
}

/// The result of a localization, in the camera frame, metres.
pub fn localization_result(localization: &Localization, header: Header) -> LocalizeFruitResult {
    let ok = localization.status == Status::Ok;
    let selected_frame = match (localization.method, localization.selected) {
        (Method::Holistic, Some(i)) => {
            localization.candidates.get(i).map_or(-1, |c| i32::try_from(c.frame).unwrap_or(-1))
        }
        _ => -1,
    };
    let n_points = match (localization.method, localization.selected) {
        (Method::Holistic, Some(i)) => localization.candidates.get(i).map_or(0, |c| c.n_points),
        _ => localization.fused.as_ref().map_or(0, |f| f.n_points),
    };
    LocalizeFruitResult {
        status: if ok { "ok" } else { "not_found" }.into(),
        reason: if ok { String::new() } else { localization.reason.clone() },
        position: PointStamped {
            header,
            point: localization.position_mm.as_ref().map(point_m).unwrap_or_default(),
        },
        radius_m: localization.radius_mm.unwrap_or(0.0) / MM_PER_M,
        position_covariance: position_covariance_m2(localization),
        selected_frame,
        n_points: u32::try_from(n_points).unwrap_or(u32::MAX),
    }
}

/// A covariance that was not estimated: element 0 is -1 (ROS's convention,
/// as in sensor_msgs/Imu).
const UNKNOWN_COVARIANCE: [f64; 9] = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

/// The position covariance in m^2, row-major, in the point's frame (the
/// camera's optical frame, whose axes are the ALACS camera frame's). Where
/// there is none (not found, the holistic method), element 0 is -1: ROS's
/// "not estimated" (as sensor_msgs/Imu).
pub fn position_covariance_m2(localization: &Localization) -> [f64; 9] {
    match (localization.status, localization.position_cov_mm2) {
        (Status::Ok, Some(c)) => std::array::from_fn(|i| c[(i / 3, i % 3)] / (MM_PER_M * MM_PER_M)),
        _ => UNKNOWN_COVARIANCE,
    }
}

/// The class every fruit is published as.
pub const FRUIT_CLASS: &str = "apple";

/// The variance of a sphere's rotation, rad^2: a fruit located as a sphere
/// has no orientation; a large variance says so to filters that read the
/// whole 6 x 6 (robot_localization's convention for what is not measured).
const UNKNOWN_ROTATION_VARIANCE: f64 = 1e3;

/// An `ok` localization as vision_msgs/Detection3DArray (`<ns>/fruit`): one
/// detection, class [`FRUIT_CLASS`], score 1 (it passed the acceptance
/// test), its centre in metres with the position covariance (where the
/// method gives one; else -1 in the first element, "not estimated"),
/// and a box the fruit's diameter on each side. `None` when not found.
pub fn fruit_detections(localization: &Localization, header: Header) -> Option<Detection3DArray> {
    let array = fruit_array(std::slice::from_ref(localization), header);
    (!array.detections.is_empty()).then_some(array)
}

/// The fruit found (status `ok`) among `localizations`, one detection each
/// in the order given; fruit not found are left out.
pub fn fruit_array(localizations: &[Localization], header: Header) -> Detection3DArray {
    let detections = localizations
        .iter()
        .filter_map(|l| match (l.status, l.position_mm, l.radius_mm) {
            (Status::Ok, Some(centre), Some(radius_mm)) => {
                Some(detection_3d(&header, &centre, position_covariance_m2(l), radius_mm, 1.0))
            }
            _ => None,
        })
        .collect();
    Detection3DArray { header, detections }
}

/// Another detector's fruit (`<ns>/detections_2d`) as detections for the
/// depth image to place: each box whose best hypothesis is one of
/// `classes` (any case; a box without hypotheses is a one-class
/// detector's and kept, score 1), as the circle of its longer side (a
/// fruit cut by a leaf or the image's border keeps its diameter in the
/// other), strongest first. Boxes with a non-finite or empty size are
/// dropped.
pub fn detections_from_2d(array: &Detection2DArray, classes: &[String]) -> Vec<Detection> {
    let mut detections: Vec<Detection> = array
        .detections
        .iter()
        .filter_map(|d| {
            let best =
                d.results.iter().max_by(|a, b| a.hypothesis.score.total_cmp(&b.hypothesis.score));
            let score = match best {
                None => 1.0,
                Some(h)
                    if classes
                        .iter()
                        .any(|c| c.eq_ignore_ascii_case(h.hypothesis.class_id.trim())) =>
                {
                    h.hypothesis.score
                }
                Some(_) => return None,
            };
            let (centre, radius_px) =
                (d.bbox.center.position, 0.5 * d.bbox.size_x.max(d.bbox.size_y));
            let finite = [centre.x, centre.y, radius_px, score].iter().all(|v| v.is_finite());
            (finite && radius_px > 0.0).then(|| Detection {
                centre_px: nalgebra::Point2::new(centre.x, centre.y),
                radius_px,
                score,
                rough: None,
            })
        })
        .collect();
    detections.sort_by(|a, b| b.score.total_cmp(&a.score));
    detections
}

/// An Image message as an RGB image: rgb8, bgr8 or mono8.
pub(crate) fn rgb_image(image: Image) -> std::result::Result<RgbImage, String> {
    let (w, h) = (image.width, image.height);
    let channels = match image.encoding.as_str() {
        "rgb8" | "bgr8" => 3,
        "mono8" => 1,
        other => return Err(format!("image encoding `{other}`: rgb8, bgr8 or mono8 are read")),
    };
    check_layout(&image, channels, "")?;
    let data = match image.encoding.as_str() {
        "rgb8" => image.data,
        "bgr8" => image.data.chunks_exact(3).flat_map(|p| [p[2], p[1], p[0]]).collect(),
        _ => image.data.iter().flat_map(|&v| [v, v, v]).collect(),
    };
    RgbImage::from_raw(w, h, data).ok_or_else(|| "image size and data disagree".to_string())
}

/// Checks that `image` holds `bytes_per_pixel` bytes a pixel, rows of its
/// step, and is not empty; `what` prefixes "image" in the message.
fn check_layout(
    image: &Image,
    bytes_per_pixel: u64,
    what: &str,
) -> std::result::Result<(), String> {
    let (w, h) = (image.width, image.height);
    let row = u64::from(w) * bytes_per_pixel;
    if u64::from(image.step) != row
        || image.data.len() as u64 != row * u64::from(h)
        || w == 0
        || h == 0
    {
        return Err(format!(
            "a {w} x {h} {} {what}image with step {} holds {} bytes",
            image.encoding,
            image.step,
            image.data.len()
        ));
    }
    Ok(())
}

/// A depth Image message aligned to colour (REP 118): `16UC1` (or `mono16`)
/// millimetres, 0 for no data; `32FC1` metres, NaN for no data.
pub(crate) fn depth_image(image: &Image) -> std::result::Result<DepthImage, String> {
    let (w, h) = (image.width, image.height);
    let bytes = match image.encoding.as_str() {
        "16UC1" | "mono16" => 2,
        "32FC1" => 4,
        other => {
            return Err(format!("depth encoding `{other}`: 16UC1 (mm) or 32FC1 (m) are read"));
        }
    };
    check_layout(image, bytes, "depth ")?;
    let big = image.is_bigendian != 0;
    let bad = || "depth image size and data disagree".to_string();
    if bytes == 2 {
        let values: Vec<u16> = image
            .data
            .chunks_exact(2)
            .map(|b| {
                if big {
                    u16::from_be_bytes([b[0], b[1]])
                } else {
                    u16::from_le_bytes([b[0], b[1]])
                }
            })
            .collect();
        Ok(DepthImage::Millimetres(image::ImageBuffer::from_raw(w, h, values).ok_or_else(bad)?))
    } else {
        let values: Vec<f32> = image
            .data
            .chunks_exact(4)
            .map(|b| {
                let b = [b[0], b[1], b[2], b[3]];
                if big { f32::from_be_bytes(b) } else { f32::from_le_bytes(b) }
            })
            .collect();
        Ok(DepthImage::Metres(image::ImageBuffer::from_raw(w, h, values).ok_or_else(bad)?))
    }
}

/// The RGB-D camera's detections with a rough position as
/// vision_msgs/Detection3DArray (`<ns>/fruit_rough`), stamped and framed as
/// the colour image (`header`): per fruit class [`FRUIT_CLASS`], the
/// detector's score, the centre (m) with its covariance (m^2), a box of its
/// diameter.
pub fn rough_detections(detections: &[Detection], header: Header) -> Detection3DArray {
    let detections = detections
        .iter()
        .filter_map(|d| {
            let rough = d.rough.as_ref()?;
            let c = rough.position_cov_mm2;
            let cov_m2: [f64; 9] =
                std::array::from_fn(|i| c[(i / 3, i % 3)] / (MM_PER_M * MM_PER_M));
            Some(detection_3d(&header, &rough.position_mm, cov_m2, rough.radius_mm, d.score))
        })
        .collect();
    Detection3DArray { header, detections }
}

/// One fruit as a vision_msgs/Detection3D: class [`FRUIT_CLASS`], `score`,
/// its centre (mm in, m out) with the position covariance (m^2, row-major)
/// in the pose's top-left 3 x 3, and a box of its diameter.
fn detection_3d(
    header: &Header,
    centre_mm: &Point3<f64>,
    position_cov_m2: [f64; 9],
    radius_mm: f64,
    score: f64,
) -> Detection3D {
    let mut covariance = [[0.0; 6]; 6];
    for (i, row) in covariance.iter_mut().enumerate() {
        if i < 3 {
            row[..3].copy_from_slice(&position_cov_m2[3 * i..3 * i + 3]);
        } else {
            row[i] = UNKNOWN_ROTATION_VARIANCE;
        }
    }
    let pose = Pose { position: point_m(centre_mm), orientation: Quaternion::default() };
    let diameter_m = 2.0 * radius_mm / MM_PER_M;
    Detection3D {
        header: header.clone(),
        results: vec![ObjectHypothesisWithPose {
            hypothesis: ObjectHypothesis { class_id: FRUIT_CLASS.into(), score },
            pose: PoseWithCovariance { pose, covariance },
        }],
        bbox: BoundingBox3D {
            center: pose,
            size: Vector3 { x: diameter_m, y: diameter_m, z: diameter_m },
        },
        id: String::new(),
    }
}

/// The result of a goal that failed (a device fault, a cancel).
pub fn error_result(status: &str, reason: &str, header: Header) -> LocalizeFruitResult {
    LocalizeFruitResult {
        status: status.into(),
        reason: reason.into(),
        position: PointStamped { header, point: Point::default() },
        radius_m: 0.0,
        position_covariance: UNKNOWN_COVARIANCE,
        selected_frame: -1,
        n_points: 0,
    }
}

/// Bytes per point of [`laser_cloud`]: x, y, z (float32, m), frame
/// (uint32), fruit (uint8: 1 on the fruit), padded to 4 bytes.
pub const CLOUD_POINT_STEP: u32 = 20;

/// Every triangulated laser point of a scan as an unordered PointCloud2 in
/// the camera frame: x y z in metres, the frame index, and whether the
/// point is on the fruit.
pub fn laser_cloud(localization: &Localization, header: Header) -> PointCloud2 {
    let mut data = Vec::new();
    for (frame, result) in localization.frames.iter().enumerate() {
        for (stripe_index, p) in &result.points_in_camera {
            let fruit = result.fruit.contains(stripe_index);
            for c in [p.x, p.y, p.z] {
                data.extend_from_slice(&((c / MM_PER_M) as f32).to_le_bytes());
            }
            data.extend_from_slice(&u32::try_from(frame).unwrap_or(u32::MAX).to_le_bytes());
            data.extend_from_slice(&[u8::from(fruit), 0, 0, 0]);
        }
    }
    let width = u32::try_from(data.len() / CLOUD_POINT_STEP as usize).unwrap_or(u32::MAX);
    let field = |name: &str, offset: u32, datatype: u8| PointField {
        name: name.into(),
        offset,
        datatype,
        count: 1,
    };
    PointCloud2 {
        header,
        height: 1,
        width,
        fields: vec![
            field("x", 0, PointField::FLOAT32),
            field("y", 4, PointField::FLOAT32),
            field("z", 8, PointField::FLOAT32),
            field("frame", 12, PointField::UINT32),
            field("fruit", 16, PointField::UINT8),
        ],
        is_bigendian: false,
        point_step: CLOUD_POINT_STEP,
        row_step: width * CLOUD_POINT_STEP,
        data,
        is_dense: true,
    }
}

/// A red sphere of the fruit's size at its centre (RViz, Foxglove).
pub fn fruit_marker(centre_mm: &Point3<f64>, radius_mm: f64, header: Header) -> Marker {
    let diameter_m = 2.0 * radius_mm / MM_PER_M;
    Marker {
        header: header.clone(),
        ns: "alacs_fruit".into(),
        id: 0,
        r#type: Marker::SPHERE,
        action: Marker::ADD,
        pose: Pose { position: point_m(centre_mm), orientation: Quaternion::default() },
        scale: Point { x: diameter_m, y: diameter_m, z: diameter_m },
        color: ColorRgba { r: 0.9, g: 0.1, b: 0.1, a: 0.6 },
        lifetime: Duration::zero(),
        frame_locked: false,
        points: Vec::new(),
        colors: Vec::new(),
        texture_resource: String::new(),
        texture: CompressedImage { header, format: String::new(), data: Vec::new() },
        uv_coordinates: Vec::new(),
        text: String::new(),
        mesh_resource: String::new(),
        mesh_file: MeshFile::default(),
        mesh_use_embedded_materials: false,
    }
}

/// A frame as sensor_msgs/Image, rgb8.
pub fn image_message(image: &RgbImage, header: Header) -> Image {
    Image {
        header,
        height: image.height(),
        width: image.width(),
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: image.width() * 3,
        data: image.as_raw().clone(),
    }
}

/// camera.yaml as sensor_msgs/CameraInfo (the distorted image: R = I, P = [K | 0]).
pub fn camera_info(camera: &Camera, header: Header) -> CameraInfo {
    let (fx, fy, cx, cy, s) =
        (camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px, camera.skew_px);
    let (model, d) = camera.distortion.ros_model();
    CameraInfo {
        header,
        height: camera.height_px,
        width: camera.width_px,
        distortion_model: model.to_string(),
        d,
        k: [fx, s, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [fx, s, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        binning_x: 0,
        binning_y: 0,
        roi: RegionOfInterest::default(),
    }
}

/// The camera a CameraInfo describes ([`camera_info`]'s inverse), checked
/// as a camera.yaml is; `name` names it.
pub fn camera_from_info(info: &CameraInfo, name: &str) -> Result<Camera, String> {
    use alacs_model::Distortion;
    let d = info.d.as_slice();
    let distortion = match (info.distortion_model.as_str(), d.len()) {
        (_, _) if d.iter().all(|k| *k == 0.0) => Distortion::None,
        ("plumb_bob", 5) => Distortion::PlumbBob([d[0], d[1], d[2], d[3], d[4]]),
        ("rational_polynomial", 8) => {
            Distortion::RationalPolynomial([d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7]])
        }
        (model, n) => {
            return Err(format!(
                "distortion model `{model}` with {n} coefficients: plumb_bob (5) or rational_polynomial (8) are read"
            ));
        }
    };
    let k = info.k;
    let camera = Camera {
        name: name.to_owned(),
        width_px: info.width,
        height_px: info.height,
        fx_px: k[0],
        fy_px: k[4],
        cx_px: k[2],
        cy_px: k[5],
        skew_px: k[1],
        distortion,
    };
    camera.validate().map_err(|e| e.to_string())?;
    Ok(camera)
}

/// The static transform that mounts the ALACS camera on the robot:
/// `mount_from_camera` (mm) as /tf_static publishes it, the camera's
/// optical frame a child of `mount_frame`. The RGB-D camera's frame belongs
/// to its own driver's tree and never gets a parent here.
pub fn static_transform(
    mount_from_camera: &Isometry3<f64>,
    mount_frame: &str,
    frames: &Frames,
    stamp: Time,
) -> TfMessage {
    let t = mount_from_camera.translation.vector / MM_PER_M;
    let q = mount_from_camera.rotation;
    TfMessage {
        transforms: vec![TransformStamped {
            header: Header::new(stamp, mount_frame),
            child_frame_id: frames.camera.clone(),
            transform: Transform {
                translation: Point { x: t.x, y: t.y, z: t.z },
                rotation: Quaternion { x: q.i, y: q.j, z: q.k, w: q.w },
            },
        }],
    }
}

/// The rotation from a camera's body frame (REP 103: x forward, y left, z
/// up) to its optical frame (x right, y down, z forward), as camera drivers
/// publish `*_link -> *_optical_frame`: roll -90 deg, yaw -90 deg.
pub fn body_from_optical() -> Isometry3<f64> {
    use std::f64::consts::FRAC_PI_2;
    Isometry3::from_parts(
        nalgebra::Translation3::identity(),
        nalgebra::UnitQuaternion::from_euler_angles(-FRAC_PI_2, 0.0, -FRAC_PI_2),
    )
}

#[cfg(test)]
mod camera_info_tests {
    use super::*;

    /// A camera goes into CameraInfo and comes back the same.
    #[test]
    fn a_camera_round_trips_through_camera_info() {
        let mut camera = Camera::blackfly_s_5mp();
        camera.skew_px = 0.25;
        let header = Header::new(Time::now(), "alacs_camera_optical_frame");
        let back = camera_from_info(&camera_info(&camera, header.clone()), &camera.name).unwrap();
        assert_eq!(back, camera);
        let plain = Camera { distortion: alacs_model::Distortion::None, ..camera.clone() };
        assert_eq!(
            camera_from_info(&camera_info(&plain, header.clone()), &plain.name).unwrap(),
            plain
        );
        let mut info = camera_info(&camera, header);
        info.distortion_model = "equidistant".into();
        info.d = vec![0.1, 0.0, 0.0, 0.0];
        assert!(camera_from_info(&info, "x").unwrap_err().contains("equidistant"));
    }
}
