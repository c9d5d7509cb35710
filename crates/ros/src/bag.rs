//! Scans recorded as ROS 2 bags in MCAP (docs/FORMATS.md, "Recordings"):
//! profile `ros2`, `ros2msg` schemas, CDR messages, so that `ros2 bag`,
//! Foxglove and `rosbags` open them. Read and written here, in one place.
//!
//! A scan is, in order: its goal (`<ns>/goal`,
//! `alacs_msgs/action/LocalizeFruit_Goal`: the rough position in the ALACS
//! camera frame and the radius prior) and the rough position as the RGB-D
//! camera gave it (`<ns>/rough_position`, PointStamped in its frame); then
//! per captured image the slide (`<ns>/slide`, JointState, joint "slide",
//! metres), the laser (`<ns>/laser_on`, Bool), the image (`<ns>/image`,
//! rgb8) and the camera (`<ns>/camera_info`, when known), all with the
//! image's stamp; then, when it was localized, the result (`<ns>/result`,
//! `alacs_msgs/action/LocalizeFruit_Result`), the fruit (`<ns>/fruit`,
//! vision_msgs/Detection3DArray, when ok) and the laser points (`<ns>/laser_points`, PointCloud2). A bag
//! holds one scan or several (the ROS node records every goal).

use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{SystemTime, UNIX_EPOCH};

use alacs_locate::Localization;
use alacs_model::Camera;
use alacs_model::ScanPlan;
use alacs_model::io::OutputFile;
use alacs_scanner::{CapturedFrame, CapturedScan};
use byteorder::LittleEndian;
use image::RgbImage;
use mcap::records::MessageHeader;
use nalgebra::Point3;
use ros2_client::builtin_interfaces::Time;
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::convert::{
    Frames, MM_PER_M, camera_info, fruit_detections, image_message, laser_cloud,
    localization_result, point_m, rgb_image,
};
use crate::msgs::{
    Bool, Header, Image, JointState, LOCALIZE_FRUIT_ACTION, LocalizeFruitGoal, PointStamped,
};
use crate::{Error, Result};

/// The most frames one recorded scan may hold (as a scan folder).
const MAX_FRAMES: usize = alacs_locate::MAX_SCAN_FRAMES;

/// The largest record read from a bag: a 100-megapixel rgb8 image and change.
const MAX_RECORD_BYTES: u64 = 320 << 20;

const SEPARATOR: &str =
    "================================================================================\n";
const HEADER_DEF: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const TIME_DEF: &str = "int32 sec\nuint32 nanosec\n";
const POINT_DEF: &str = "float64 x\nfloat64 y\nfloat64 z\n";

/// The QoS rosbag2 records with: reliable, volatile, keep last 10 (its
/// integer form, which every ROS 2 release reads).
const QOS_YAML: &str = "- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  \
deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n  \
liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n  avoid_ros_namespace_conventions: false\n";

/// A `ros2msg` schema: the type's fields, then each dependency's.
fn schema(fields: &str, dependencies: &[(&str, &str)]) -> String {
    let mut text = fields.to_string();
    for (name, definition) in dependencies {
        text += &format!("{SEPARATOR}MSG: {name}\n{definition}");
    }
    text
}

const HEADER_DEPS: [(&str, &str); 2] =
    [("std_msgs/Header", HEADER_DEF), ("builtin_interfaces/Time", TIME_DEF)];

/// The part `index` (0 goal, 1 result) of the action file, without comments.
fn action_part(index: usize) -> String {
    LOCALIZE_FRUIT_ACTION
        .split("---")
        .nth(index)
        .unwrap_or_default()
        .lines()
        .map(|l| l.split('#').next().unwrap_or_default().trim())
        .filter(|l| !l.is_empty())
        .map(|l| format!("{}\n", l.split_whitespace().collect::<Vec<_>>().join(" ")))
        .collect()
}

/// (schema name, schema text) of every type a bag holds.
fn schemas() -> Vec<(&'static str, String)> {
    let point_stamped_deps = [HEADER_DEPS[0], HEADER_DEPS[1], ("geometry_msgs/Point", POINT_DEF)];
    vec![
        (
            "sensor_msgs/msg/Image",
            schema(
                "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
                 uint8 is_bigendian\nuint32 step\nuint8[] data\n",
                &HEADER_DEPS,
            ),
        ),
        (
            "sensor_msgs/msg/CameraInfo",
            schema(
                "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n\
                 float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n\
                 uint32 binning_y\nRegionOfInterest roi\n",
                &[
                    HEADER_DEPS[0],
                    HEADER_DEPS[1],
                    (
                        "sensor_msgs/RegionOfInterest",
                        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\n\
                         bool do_rectify\n",
                    ),
                ],
            ),
        ),
        (
            "sensor_msgs/msg/JointState",
            schema(
                "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n\
                 float64[] effort\n",
                &HEADER_DEPS,
            ),
        ),
        ("std_msgs/msg/Bool", "bool data\n".to_string()),
        (
            "geometry_msgs/msg/PointStamped",
            schema("std_msgs/Header header\nPoint point\n", &point_stamped_deps),
        ),
        (
            "sensor_msgs/msg/PointCloud2",
            schema(
                "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\n\
                 bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\n\
                 bool is_dense\n",
                &[
                    HEADER_DEPS[0],
                    HEADER_DEPS[1],
                    (
                        "sensor_msgs/PointField",
                        "string name\nuint32 offset\nuint8 datatype\nuint32 count\n",
                    ),
                ],
            ),
        ),
        (
            "alacs_msgs/action/LocalizeFruit_Goal",
            schema(&action_part(0), &point_stamped_deps_with_prefix()),
        ),
        (
            "alacs_msgs/action/LocalizeFruit_Result",
            schema(&action_part(1), &point_stamped_deps_with_prefix()),
        ),
        (
            "vision_msgs/msg/Detection3DArray",
            schema(
                "std_msgs/Header header\nDetection3D[] detections\n",
                &[
                    HEADER_DEPS[0],
                    HEADER_DEPS[1],
                    (
                        "vision_msgs/Detection3D",
                        "std_msgs/Header header\nObjectHypothesisWithPose[] results\n\
                         BoundingBox3D bbox\nstring id\n",
                    ),
                    (
                        "vision_msgs/ObjectHypothesisWithPose",
                        "ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n",
                    ),
                    ("vision_msgs/ObjectHypothesis", "string class_id\nfloat64 score\n"),
                    ("geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance\n"),
                    ("geometry_msgs/Pose", "Point position\nQuaternion orientation\n"),
                    ("geometry_msgs/Point", POINT_DEF),
                    ("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"),
                    (
                        "vision_msgs/BoundingBox3D",
                        "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
                    ),
                    ("geometry_msgs/Vector3", POINT_DEF),
                ],
            ),
        ),
    ]
}

/// The dependencies of a type holding a `geometry_msgs/PointStamped`.
fn point_stamped_deps_with_prefix() -> [(&'static str, &'static str); 4] {
    [
        ("geometry_msgs/PointStamped", "std_msgs/Header header\nPoint point\n"),
        HEADER_DEPS[0],
        HEADER_DEPS[1],
        ("geometry_msgs/Point", POINT_DEF),
    ]
}

/// The topics of a bag, under a namespace.
struct Topics {
    goal: String,
    rough_position: String,
    slide: String,
    laser_on: String,
    image: String,
    camera_info: String,
    result: String,
    fruit: String,
    laser_points: String,
}

impl Topics {
    fn new(namespace: &str) -> Self {
        let ns = namespace.trim_end_matches('/');
        let t = |name: &str| format!("{ns}/{name}");
        Self {
            goal: t("goal"),
            rough_position: t("rough_position"),
            slide: t("slide"),
            laser_on: t("laser_on"),
            image: t("image"),
            camera_info: t("camera_info"),
            result: t("result"),
            fruit: t("fruit"),
            laser_points: t("laser_points"),
        }
    }
}

/// CDR little endian, as ROS 2 puts it on the wire: the 4-byte
/// encapsulation header, then the body.
fn cdr<T: Serialize>(message: &T) -> std::result::Result<Vec<u8>, String> {
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    out.extend(cdr_encoding::to_vec::<T, LittleEndian>(message).map_err(|e| e.to_string())?);
    Ok(out)
}

fn from_cdr<T: DeserializeOwned>(payload: &[u8]) -> std::result::Result<T, String> {
    match payload {
        [0x00, 0x01, _, _, body @ ..] => cdr_encoding::from_bytes::<T, LittleEndian>(body)
            .map(|(value, _)| value)
            .map_err(|e| format!("not a valid CDR message: {e}")),
        _ => Err("only little-endian CDR messages are read".into()),
    }
}

/// Nanoseconds since the epoch of a stamp (0 before it).
fn nanos(stamp: &Time) -> u64 {
    u64::try_from(stamp.to_nanos()).unwrap_or(0)
}

/// Writes scans into a new bag; the file appears, whole, at
/// [`BagWriter::finish`] (nothing is left at the path if writing fails).
pub struct BagWriter {
    out: Channels,
    topics: Topics,
    frames: Frames,
    scans: usize,
}

/// The MCAP file being written: its channels, opened as topics are first used.
struct Channels {
    writer: mcap::Writer<OutputFile>,
    path: PathBuf,
    /// Channel ids by topic.
    channels: BTreeMap<String, u16>,
    /// Schema ids by name.
    schema_ids: BTreeMap<&'static str, u16>,
    sequence: u32,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter").field("path", &self.out.path).finish_non_exhaustive()
    }
}

impl BagWriter {
    /// A bag to be written at `path` (.mcap), topics under `namespace`,
    /// frames named as `frames`. An existing file is refused unless
    /// `overwrite` (a recording is not replaced by accident).
    pub fn create(path: &Path, namespace: &str, frames: &Frames, overwrite: bool) -> Result<Self> {
        let bad = |message: String| Error::Bag { path: path.to_path_buf(), message };
        if path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref()
            != Some("mcap")
        {
            return Err(bad("a recording is an MCAP file: name it FILE.mcap".into()));
        }
        crate::node::validate_namespace(namespace)?;
        if !overwrite && path.exists() {
            return Err(bad("exists; a recording is not replaced unless asked (--force)".into()));
        }
        let file = OutputFile::create(path)?;
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("alacs ", env!("CARGO_PKG_VERSION")))
            .compression(None)
            .chunk_size(Some(4 << 20))
            .create(file)
            .map_err(|e| bad(format!("cannot be written: {e}")))?;
        let mut schema_ids = BTreeMap::new();
        for (name, text) in schemas() {
            let id = writer
                .add_schema(name, "ros2msg", text.as_bytes())
                .map_err(|e| bad(format!("cannot be written: {e}")))?;
            schema_ids.insert(name, id);
        }
        Ok(Self {
            out: Channels {
                writer,
                path: path.to_path_buf(),
                channels: BTreeMap::new(),
                schema_ids,
                sequence: 0,
            },
            topics: Topics::new(namespace),
            frames: frames.clone(),
            scans: 0,
        })
    }

    /// Records `scan`: its goal, each image with the slide and the laser
    /// (and `camera` as CameraInfo when given), and `localization` when
    /// there is one. Each image is stamped with its capture time (now, for
    /// a frame that has none); the goal with the first image's.
    pub fn write_scan(
        &mut self,
        scan: &CapturedScan,
        camera: Option<&Camera>,
        localization: Option<&Localization>,
    ) -> Result<()> {
        let now = Time::now();
        let stamps: Vec<Time> = scan
            .frames
            .iter()
            .flat_map(|f| {
                let off = f.image_laser_off.as_ref().map(|_| stamp_of(f.captured_at[1], now));
                std::iter::once(stamp_of(f.captured_at[0], now)).chain(off)
            })
            .collect();
        let start = stamps.first().copied().unwrap_or(now);
        let goal = LocalizeFruitGoal {
            rough_position: PointStamped {
                header: Header::new(start, &self.frames.camera),
                point: point_m(&scan.rough_position_mm),
            },
            fruit_radius_m: scan.fruit_radius_mm / MM_PER_M,
        };
        let rough_in_rgbd = PointStamped {
            header: Header::new(start, &self.frames.rgbd),
            point: point_m(&scan.rough_position_in_rgbd_mm),
        };
        let (out, topics) = (&mut self.out, &self.topics);
        out.write(&topics.goal, "alacs_msgs/action/LocalizeFruit_Goal", &start, &goal)?;
        out.write(
            &topics.rough_position,
            "geometry_msgs/msg/PointStamped",
            &start,
            &rough_in_rgbd,
        )?;
        let mut stamp = stamps.iter();
        for frame in &scan.frames {
            let shots = std::iter::once((true, &frame.image))
                .chain(frame.image_laser_off.as_deref().map(|off| (false, off)));
            for (laser_on, image) in shots {
                let at = stamp.next().copied().unwrap_or(start);
                self.write_image(at, frame.slide_mm, laser_on, image, camera)?;
            }
        }
        if let Some(localization) = localization {
            let end = stamps.last().copied().unwrap_or(start);
            let result = localization_result(localization, Header::new(end, &self.frames.camera));
            let cloud = laser_cloud(localization, Header::new(end, &self.frames.camera));
            let (out, topics) = (&mut self.out, &self.topics);
            out.write(&topics.result, "alacs_msgs/action/LocalizeFruit_Result", &end, &result)?;
            if let Some(detections) =
                fruit_detections(localization, Header::new(end, &self.frames.camera))
            {
                out.write(&topics.fruit, "vision_msgs/msg/Detection3DArray", &end, &detections)?;
            }
            out.write(&topics.laser_points, "sensor_msgs/msg/PointCloud2", &end, &cloud)?;
        }
        self.scans += 1;
        Ok(())
    }

    fn write_image(
        &mut self,
        stamp: Time,
        slide_mm: f64,
        laser_on: bool,
        image: &RgbImage,
        camera: Option<&Camera>,
    ) -> Result<()> {
        let header = Header::new(stamp, &self.frames.camera);
        let slide = JointState {
            header: Header::new(stamp, &self.frames.camera),
            name: vec!["slide".into()],
            position: vec![slide_mm / MM_PER_M],
            velocity: Vec::new(),
            effort: Vec::new(),
        };
        let (out, topics) = (&mut self.out, &self.topics);
        out.write(&topics.slide, "sensor_msgs/msg/JointState", &stamp, &slide)?;
        out.write(&topics.laser_on, "std_msgs/msg/Bool", &stamp, &Bool { data: laser_on })?;
        out.write(
            &topics.image,
            "sensor_msgs/msg/Image",
            &stamp,
            &image_message(image, header.clone()),
        )?;
        if let Some(camera) = camera {
            out.write(
                &topics.camera_info,
                "sensor_msgs/msg/CameraInfo",
                &stamp,
                &camera_info(camera, header),
            )?;
        }
        Ok(())
    }

    /// Scans written so far.
    pub fn scans(&self) -> usize {
        self.scans
    }

    /// Ends the bag (its summary and index) and puts it at its path.
    pub fn finish(self) -> Result<PathBuf> {
        let mut out = self.out;
        out.writer.finish().map_err(|e| out.bad(e))?;
        let path = out.path.clone();
        out.writer.into_inner().commit()?;
        Ok(path)
    }
}

impl Channels {
    fn bad(&self, message: impl std::fmt::Display) -> Error {
        Error::Bag { path: self.path.clone(), message: format!("cannot be written: {message}") }
    }

    /// Writes one message of schema `schema` on `topic` at `stamp`.
    fn write<T: Serialize>(
        &mut self,
        topic: &str,
        schema: &'static str,
        stamp: &Time,
        message: &T,
    ) -> Result<()> {
        let channel = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let schema_id = *self.schema_ids.get(schema).ok_or_else(|| self.bad(schema))?;
                let metadata = BTreeMap::from([
                    ("offered_qos_profiles".to_string(), QOS_YAML.to_string()),
                    ("topic_type_hash".to_string(), String::new()),
                ]);
                let id = self
                    .writer
                    .add_channel(schema_id, topic, "cdr", &metadata)
                    .map_err(|e| self.bad(e))?;
                self.channels.insert(topic.to_string(), id);
                id
            }
        };
        let payload = cdr(message).map_err(|e| self.bad(e))?;
        self.sequence = self.sequence.wrapping_add(1);
        let time = nanos(stamp);
        let header = MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: time,
            publish_time: time,
        };
        self.writer.write_to_known_channel(&header, &payload).map_err(|e| self.bad(e))
    }
}

/// What a bag holds, scan by scan.
#[derive(Debug, Clone, PartialEq)]
pub struct BagSummary {
    /// Frames (laser-on images) of each scan.
    pub frames_per_scan: Vec<usize>,
    /// Messages per topic.
    pub messages: BTreeMap<String, u64>,
    /// The camera of the scan read, from its first CameraInfo, if it has one.
    pub camera: Option<Camera>,
}

/// Reads scan `index` (from 0) of the bag at `path`, and what the whole bag
/// holds. Only that scan's images are decoded; all of them are held (`bag
/// export` writes them); [`localize_scan`] holds a few at a time.
pub fn read_scan(path: &Path, index: usize) -> Result<(CapturedScan, BagSummary)> {
    let (mut reader, mut scan) = ScanReader::open(path, index, true)?;
    while let Some(frame) = reader.next_frame()? {
        scan.frames.push(frame);
    }
    let summary = reader.summary;
    scan.plan = ScanPlan {
        slides_mm: scan.frames.iter().map(|f| f.slide_mm).collect(),
        unclamped_start_mm: scan.frames.first().map_or(0.0, |f| f.slide_mm),
        shifted: false,
    };
    Ok((scan, summary))
}

/// Localizes the fruit of scan `index` (from 0) of the bag at `path` with
/// the same checks and limits as a scan folder (`alacs_locate`'s
/// [`locate_frames`](alacs_locate::locate_frames)), reading the bag once and
/// holding a few frames at a time. Returns the answer and the scan's prior.
/// `progress(done)` after each frame read.
pub fn localize_scan(
    path: &Path,
    index: usize,
    camera: &Camera,
    laser: &alacs_model::LaserModel,
    options: &alacs_locate::LocateOptions,
    progress: impl Fn(usize) + Sync,
) -> Result<(Localization, alacs_locate::Prior)> {
    let (mut reader, scan) = ScanReader::open(path, index, false)?;
    let prior = scan.prior();
    let shown = path.display().to_string();
    let frames = std::iter::from_fn(|| match reader.next_frame() {
        Ok(Some(frame)) => Some(Ok(alacs_locate::PendingFrame {
            slide_mm: frame.slide_mm,
            name: format!("{} (scan {index})", path.display()),
            decode: Box::new(move || {
                let off = frame.image_laser_off.map(Arc::unwrap_or_clone);
                Ok((frame.image, off))
            }),
        })),
        Ok(None) => None,
        // Named in the bag's error; carried through as bad input.
        Err(e) => Some(Err(alacs_locate::Error::InvalidInput(e.to_string()))),
    });
    let mut answers = alacs_locate::locate_frames(
        frames,
        None,
        std::slice::from_ref(&prior),
        camera,
        laser,
        options,
        |done, _| progress(done),
    )
    .map_err(|e| match e {
        alacs_locate::Error::InvalidInput(message) if message.starts_with(&shown) => {
            Error::InvalidInput(message)
        }
        alacs_locate::Error::InvalidInput(message) => {
            Error::Bag { path: path.to_path_buf(), message }
        }
        other => Error::Scanner(other.into()),
    })?;
    let answer = answers.pop().ok_or_else(|| Error::InvalidInput("no fruit to locate".into()))?;
    Ok((answer, prior))
}

/// Reads one scan of a bag frame by frame, in one pass over the file: the
/// goal first ([`ScanReader::open`]), then each laser-on image with its
/// laser-off image, if one follows ([`ScanReader::next_frame`]).
struct ScanReader {
    path: PathBuf,
    reader: mcap::io::MessageReader<BufReader<std::fs::File>>,
    /// The scan read (from 0).
    index: usize,
    /// Read past the scan to the bag's end, for the summary.
    whole_bag: bool,
    summary: BagSummary,
    /// The scan's goal and rough position, until [`ScanReader::open`] hands it out.
    scan: Option<CapturedScan>,
    /// The slide and the laser of the next image.
    slide_mm: Option<f64>,
    laser_on: Option<bool>,
    /// A laser-on frame waiting for its laser-off image, and whether it was mono8.
    pending: Option<(CapturedFrame, bool)>,
    done: bool,
}

impl ScanReader {
    /// Reads the bag up to scan `index`'s goal and rough position.
    fn open(path: &Path, index: usize, whole_bag: bool) -> Result<(Self, CapturedScan)> {
        // A FIFO or a device would hang the reader or never end: a regular file only.
        let file = alacs_model::io::open_input(path)?;
        // A chunk whose CRC does not match is refused before any of its
        // messages is used: a corrupted byte is an error, never an image.
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_record_length_limit(usize::try_from(MAX_RECORD_BYTES).unwrap_or(usize::MAX))
            .with_validate_chunk_crcs(true)
            .with_prevalidate_chunk_crcs(true)
            .with_validate_data_section_crc(true);
        let reader = mcap::io::MessageReader::new_with_options(BufReader::new(file), options);
        let mut this = ScanReader {
            path: path.to_path_buf(),
            reader,
            index,
            whole_bag,
            summary: BagSummary {
                frames_per_scan: Vec::new(),
                messages: BTreeMap::new(),
                camera: None,
            },
            scan: None,
            slide_mm: None,
            laser_on: None,
            pending: None,
            done: false,
        };
        let mut found = false;
        // Up to the scan's first image: its goal and rough position are known then.
        while !found || this.pending.is_none() {
            match this.step()? {
                Step::End => break,
                Step::Goal(goal) if this.summary.frames_per_scan.len() - 1 == index => {
                    this.scan = Some(empty_scan(&goal).map_err(|e| this.bad(e))?);
                    found = true;
                }
                _ => {}
            }
        }
        if !found {
            let scans = this.summary.frames_per_scan.len();
            return Err(this.bad(if scans == 0 {
                "holds no scan (no alacs_msgs/action/LocalizeFruit_Goal message)".to_string()
            } else {
                format!("holds {scans} scans, numbered from 0; there is no scan {index}")
            }));
        }
        let (Some(scan), Some(_)) = (this.scan.take(), this.pending.as_ref()) else {
            return Err(this.bad(format!("scan {index} holds no laser-on image")));
        };
        Ok((this, scan))
    }

    fn bad(&self, message: String) -> Error {
        Error::Bag { path: self.path.clone(), message }
    }

    /// The scan's next frame, once its laser-off image (if any) is read;
    /// `None` after its last.
    fn next_frame(&mut self) -> Result<Option<CapturedFrame>> {
        while !self.done {
            match self.step()? {
                Step::Frame(frame) => return self.finished(frame).map(Some),
                Step::End => {
                    self.done = true;
                }
                Step::Goal(_) if !self.whole_bag && self.current() > Some(self.index) => {
                    self.done = true;
                }
                _ => {}
            }
        }
        match self.pending.take() {
            Some(frame) => self.finished(frame).map(Some),
            None => Ok(None),
        }
    }

    /// A frame of the scan, complete: a greyscale frame needs its
    /// laser-off image, as a scan folder's (the red stripe is found by its
    /// colour, or by the difference).
    fn finished(&self, (frame, grey): (CapturedFrame, bool)) -> Result<CapturedFrame> {
        if grey && frame.image_laser_off.is_none() {
            return Err(self.bad(format!(
                "scan {}: a mono8 (greyscale) image without a laser-off image: the red laser stripe is found by its colour, so it needs rgb8 or bgr8 images (or laser-off images to difference with)",
                self.index
            )));
        }
        Ok(frame)
    }

    /// The scan the last goal began (from 0).
    fn current(&self) -> Option<usize> {
        self.summary.frames_per_scan.len().checked_sub(1)
    }

    /// Reads one message: a goal, a laser-on image of the scan that
    /// completes the previous frame, the end, or anything else.
    fn step(&mut self) -> Result<Step> {
        let Some(message) = self.reader.next() else { return Ok(Step::End) };
        let message = message.map_err(|e| self.bad(format!("not a readable MCAP file: {e}")))?;
        let channel: &Arc<mcap::Channel<'_>> = &message.channel;
        *self.summary.messages.entry(channel.topic.clone()).or_default() += 1;
        let schema = channel.schema.as_ref().map(|s| s.name.as_str()).unwrap_or_default();
        let topic = channel.topic.as_str();
        let current = self.current();
        let ours = current == Some(self.index);
        let at = |what: &str| Error::Bag {
            path: self.path.clone(),
            message: format!("{topic} (message {} of the bag): {what}", message.sequence),
        };
        match schema {
            "alacs_msgs/action/LocalizeFruit_Goal" => {
                let goal: LocalizeFruitGoal = from_cdr(&message.data).map_err(|e| at(&e))?;
                self.summary.frames_per_scan.push(0);
                self.slide_mm = None;
                self.laser_on = None;
                return Ok(Step::Goal(goal));
            }
            "geometry_msgs/msg/PointStamped" if topic.ends_with("/rough_position") => {
                if let Some(scan) = self.scan.as_mut().filter(|_| ours && self.pending.is_none()) {
                    let rough: PointStamped = from_cdr(&message.data).map_err(|e| at(&e))?;
                    scan.rough_position_in_rgbd_mm = alacs_model::checked_rough_position_mm(
                        mm(&rough.point).coords.as_slice(),
                        false,
                    )
                    .map_err(|e| at(&format!("the rough position {e}")))?;
                }
            }
            "sensor_msgs/msg/JointState" => {
                let state: JointState = from_cdr(&message.data).map_err(|e| at(&e))?;
                let Some(k) = state.name.iter().position(|n| n == "slide") else {
                    return Ok(Step::Other);
                };
                let position = state.position.get(k).copied().unwrap_or(f64::NAN);
                if !(position.is_finite()
                    && position.abs() * MM_PER_M <= alacs_model::MAX_ABS_SLIDE_MM)
                {
                    return Err(at(&format!(
                        "slide position {} m is not a slide travel",
                        alacs_model::Num(position)
                    )));
                }
                self.slide_mm = Some(position * MM_PER_M);
            }
            "sensor_msgs/msg/CameraInfo" if ours && self.summary.camera.is_none() => {
                let info: crate::msgs::CameraInfo = from_cdr(&message.data).map_err(|e| at(&e))?;
                let camera =
                    crate::convert::camera_from_info(&info, "recorded").map_err(|e| at(&e))?;
                self.summary.camera = Some(camera);
            }
            "std_msgs/msg/Bool" if topic.ends_with("/laser_on") => {
                let state: Bool = from_cdr(&message.data).map_err(|e| at(&e))?;
                self.laser_on = Some(state.data);
            }
            "sensor_msgs/msg/Image" => {
                let Some(i) = current else {
                    return Err(at("an image before any goal: not a recording of alacs scans"));
                };
                let (Some(slide), Some(on)) = (self.slide_mm, self.laser_on) else {
                    return Err(at(
                        "an image without the slide position and laser state before it",
                    ));
                };
                // Each image has its own slide and laser messages before it
                // (as the writer puts them): none is carried to the next.
                self.slide_mm = None;
                self.laser_on = None;
                if on {
                    self.summary.frames_per_scan[i] += 1;
                    if self.summary.frames_per_scan[i] > MAX_FRAMES {
                        return Err(at(&format!("more than {MAX_FRAMES} frames in one scan")));
                    }
                }
                if !ours {
                    return Ok(Step::Other);
                }
                let image: Image = from_cdr(&message.data).map_err(|e| at(&e))?;
                let grey = image.encoding == "mono8";
                let image = rgb_image(image).map_err(|e| at(&e))?;
                let captured_at = system_time(message.log_time);
                if on {
                    let frame = CapturedFrame {
                        planned_slide_mm: slide,
                        slide_mm: slide,
                        image,
                        image_laser_off: None,
                        captured_at: [Some(captured_at), None],
                    };
                    if let Some(previous) = self.pending.replace((frame, grey)) {
                        return Ok(Step::Frame(previous));
                    }
                } else {
                    match self.pending.as_mut() {
                        Some((frame, _))
                            if frame.slide_mm == slide && frame.image_laser_off.is_none() =>
                        {
                            frame.image_laser_off = Some(Arc::new(image));
                            frame.captured_at[1] = Some(captured_at);
                        }
                        _ => {
                            return Err(at(
                                "a laser-off image that follows no laser-on image at its slide position",
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
        Ok(Step::Other)
    }
}

/// What one message of a bag was to [`ScanReader`].
enum Step {
    /// A goal: a scan begins.
    Goal(LocalizeFruitGoal),
    /// The scan's previous laser-on frame is complete.
    Frame((CapturedFrame, bool)),
    /// The bag's end.
    End,
    Other,
}

fn mm(point: &crate::msgs::Point) -> Point3<f64> {
    Point3::new(point.x * MM_PER_M, point.y * MM_PER_M, point.z * MM_PER_M)
}

/// A scan of `goal` before its frames; the goal's values held to a scan
/// folder's bounds (FORMATS.md, scan.yaml).
fn empty_scan(goal: &LocalizeFruitGoal) -> std::result::Result<CapturedScan, String> {
    let rough = mm(&goal.rough_position.point);
    let rough = alacs_model::checked_rough_position_mm(rough.coords.as_slice(), true)
        .map_err(|e| format!("the goal's rough position {e}"))?;
    let radius_mm = goal.fruit_radius_m * MM_PER_M;
    let fruit_radius_mm = if radius_mm == 0.0 {
        alacs_model::DEFAULT_FRUIT_RADIUS_MM
    } else {
        alacs_model::checked_fruit_radius_mm(radius_mm)
            .map_err(|e| format!("the goal's fruit radius {e} (0: unknown)"))?
    };
    Ok(CapturedScan {
        rough_position_in_rgbd_mm: rough,
        rough_position_mm: rough,
        fruit_radius_mm,
        more_targets: Vec::new(),
        plan: ScanPlan { slides_mm: Vec::new(), unclamped_start_mm: 0.0, shifted: false },
        frames: Vec::new(),
        exposure: None,
        sweep_speed_mm_per_s: None,
    })
}

/// A capture time as a ROS stamp (`default` when unknown).
fn stamp_of(time: Option<SystemTime>, default: Time) -> Time {
    time.and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .and_then(|d| i64::try_from(d.as_nanos()).ok())
        .map_or(default, Time::from_nanos)
}

/// A bag's log time as a capture time.
fn system_time(log_time_ns: u64) -> SystemTime {
    UNIX_EPOCH + std::time::Duration::from_nanos(log_time_ns)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{Header, Point, PointStamped};
    use ros2_client::builtin_interfaces::Time;

    fn goal(x: f64, radius_m: f64) -> LocalizeFruitGoal {
        LocalizeFruitGoal {
            rough_position: PointStamped {
                header: Header::new(Time::now(), "alacs_camera_optical_frame"),
                point: Point { x, y: 0.0, z: 0.8 },
            },
            fruit_radius_m: radius_m,
        }
    }

    /// A recorded goal is held to a scan folder's bounds: the radius 0
    /// (unknown) is the default prior; 5 m, a position of 1e303 m and one
    /// behind the camera are refused, naming the value.
    #[test]
    fn a_recorded_goal_is_held_to_a_scan_folders_bounds() {
        let scan = empty_scan(&goal(0.03, 0.0)).unwrap();
        assert_eq!(scan.fruit_radius_mm, alacs_model::DEFAULT_FRUIT_RADIUS_MM);
        assert_eq!(empty_scan(&goal(0.03, 0.04)).unwrap().fruit_radius_mm, 40.0);
        let e = empty_scan(&goal(0.03, 5.0)).unwrap_err();
        assert!(e.contains("5000 mm"), "{e}");
        let e = empty_scan(&goal(1e303, 0.04)).unwrap_err();
        assert!(e.contains("rough position"), "{e}");
        assert!(empty_scan(&goal(f64::NAN, 0.04)).is_err());
        // Behind the camera, as a scan folder refuses it.
        let mut behind = goal(0.03, 0.04);
        behind.rough_position.point.z = -0.8;
        let e = empty_scan(&behind).unwrap_err();
        assert!(e.contains("z > 0"), "{e}");
    }
}
