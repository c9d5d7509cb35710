#!/usr/bin/env python3
"""Stand-in RGB-D camera driver for `alacs ros`: publishes one colour image,
its aligned depth image and the colour camera's CameraInfo under
realsense-ros 4.x's names (`<rgbd_ns>/color/image_raw`,
`<rgbd_ns>/aligned_depth_to_color/image_raw`, `<rgbd_ns>/color/camera_info`;
sensor-data QoS, one stamp for the pair), again every half second, until the
node's `<ns>/fruit_rough` (vision_msgs/Detection3DArray) answers that stamp.
With `--boxes`, also publishes those boxes as another detector would
(`<ns>/detections_2d`, vision_msgs/Detection2DArray, the images' stamp).
With `--scan`, then calls `<ns>/scan_detected` (std_srvs/srv/Trigger) as
`ros2 service call` would and waits for its reply and for `<ns>/fruit`.
Prints one JSON object: the detections (class, score, position m,
covariance, size) and the header they came with, and with `--scan` the
service's answer and the fruit it published.

Speaks what rmw_cyclonedds_cpp puts on the wire (Eclipse Cyclone DDS,
XCDR1), as localize_fruit_peer.py, whose message types it shares.

    python3 rgbd_peer.py /alacs --color color.png --depth depth.png \\
        --camera camera.json [--rgbd-ns /camera/camera] [--frame-id F] [--scan] \\
        [--boxes '[[u, v, width, height, "class", score], ...]']

camera.json: {"width", "height", "k": [9], "d": [...], "distortion_model"}.
"""

import argparse
import json
import os
import random
import sys
import time
from dataclasses import dataclass

import cv2
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float64, int64, sequence, uint8, uint32, uint64
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from localize_fruit_peer import (FEEDBACK_QOS, SENSOR_QOS, Detection3DArray, Header,
                                 ObjectHypothesis, ObjectHypothesisWithPose, Point, Pose,
                                 PoseWithCovariance, Quaternion, ServiceClient, Timeout,
                                 now_time, ros_name, take_valid)


@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header
    height: uint32
    width: uint32
    encoding: str
    is_bigendian: uint8
    step: uint32
    data: sequence[uint8]


@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: uint32 = 0
    y_offset: uint32 = 0
    height: uint32 = 0
    width: uint32 = 0
    do_rectify: bool = False


@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header
    height: uint32
    width: uint32
    distortion_model: str
    d: sequence[float64]
    k: array[float64, 9]
    r: array[float64, 9]
    p: array[float64, 12]
    binning_x: uint32
    binning_y: uint32
    roi: RegionOfInterest


@dataclass
class Point2D(IdlStruct, typename="vision_msgs::msg::dds_::Point2D_"):
    x: float64
    y: float64


@dataclass
class Pose2D(IdlStruct, typename="vision_msgs::msg::dds_::Pose2D_"):
    position: Point2D
    theta: float64


@dataclass
class BoundingBox2D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox2D_"):
    center: Pose2D
    size_x: float64
    size_y: float64


@dataclass
class Detection2D(IdlStruct, typename="vision_msgs::msg::dds_::Detection2D_"):
    header: Header
    results: sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox2D
    id: str


@dataclass
class Detection2DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection2DArray_"):
    header: Header
    detections: sequence[Detection2D]


def detections_2d(header, boxes) -> Detection2DArray:
    """vision_msgs 4.x boxes as a YOLO node publishes them: one hypothesis each."""
    no_pose = PoseWithCovariance(Pose(Point(), Quaternion()), [0.0] * 36)
    return Detection2DArray(header, [
        Detection2D(header, [ObjectHypothesisWithPose(ObjectHypothesis(cls, score), no_pose)],
                    BoundingBox2D(Pose2D(Point2D(u, v), 0.0), w, h), "")
        for u, v, w, h, cls, score in boxes])


# std_srvs/srv/Trigger with rmw_cyclonedds's request header in front (see
# localize_fruit_peer.py); an empty request holds ROS 2's placeholder byte.
@dataclass
class Trigger_Request(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    structure_needs_at_least_one_field: uint8


@dataclass
class Trigger_Response(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    success: bool
    message: str


def detections_json(m) -> list:
    out = []
    for d in m.detections:
        for hyp in d.results:
            pos = hyp.pose.pose.position
            out.append({"class_id": hyp.hypothesis.class_id, "score": hyp.hypothesis.score,
                        "position": [pos.x, pos.y, pos.z],
                        "covariance": list(hyp.pose.covariance),
                        "size": [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z]})
    return out


def scan_detected(dp, namespace: str, deadline: float, log) -> dict:
    """Calls <ns>/scan_detected once and waits for its reply and <ns>/fruit."""
    fruit_r = DataReader(dp, Topic(dp, "rt" + ros_name(namespace, "fruit"), Detection3DArray,
                                   qos=FEEDBACK_QOS), qos=FEEDBACK_QOS)
    client = ServiceClient(dp, ros_name(namespace, "scan_detected"), Trigger_Request,
                           Trigger_Response, random.getrandbits(63) | 1)
    while not client.matched():
        if time.monotonic() > deadline:
            raise Timeout("scan_detected: no server matched")
        time.sleep(0.05)
    seq = client.send(lambda g, s: Trigger_Request(g, s, 0))
    reply = client.wait_reply(seq, deadline)
    log(f"scan_detected: success={reply.success} {reply.message}")
    fruit = None
    while reply.success and fruit is None and time.monotonic() < deadline:
        for m in take_valid(fruit_r, 8):
            fruit = {"frame_id": m.header.frame_id, "detections": detections_json(m)}
        time.sleep(0.01)
    return {"success": reply.success, "message": reply.message, "fruit": fruit}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("namespace", help="the node's namespace (fruit_rough is <ns>/fruit_rough)")
    ap.add_argument("--rgbd-ns", default="/camera/camera")
    ap.add_argument("--color", required=True, help="colour PNG (published rgb8)")
    ap.add_argument("--depth", required=True, help="16-bit depth PNG, mm (published 16UC1)")
    ap.add_argument("--camera", required=True, help="camera.json (see the docstring)")
    ap.add_argument("--frame-id", default="camera_color_optical_frame")
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--boxes", help="JSON [[u, v, width, height, class, score], ...] to "
                    "publish on <ns>/detections_2d with each pair")
    ap.add_argument("--scan", action="store_true",
                    help="then call <ns>/scan_detected and report <ns>/fruit")
    args = ap.parse_args(argv)
    log = lambda *a: print("[rgbd peer]", *a, file=sys.stderr, flush=True)

    bgr = cv2.imread(args.color, cv2.IMREAD_COLOR)
    depth = cv2.imread(args.depth, cv2.IMREAD_UNCHANGED)
    if bgr is None or depth is None or depth.dtype.name != "uint16":
        log("cannot read the colour or 16-bit depth image")
        return 3
    rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    with open(args.camera) as f:
        cam = json.load(f)
    h, w = rgb.shape[:2]

    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))
    topic = lambda name, t, qos: Topic(dp, "rt" + ros_name(args.rgbd_ns, name), t, qos=qos)
    color_w = DataWriter(dp, topic("color/image_raw", Image, SENSOR_QOS), qos=SENSOR_QOS)
    depth_w = DataWriter(dp, topic("aligned_depth_to_color/image_raw", Image, SENSOR_QOS),
                         qos=SENSOR_QOS)
    info_w = DataWriter(dp, topic("color/camera_info", CameraInfo, SENSOR_QOS), qos=SENSOR_QOS)
    boxes = json.loads(args.boxes) if args.boxes else None
    boxes_w = DataWriter(dp, Topic(dp, "rt" + ros_name(args.namespace, "detections_2d"),
                                   Detection2DArray, qos=FEEDBACK_QOS),
                         qos=FEEDBACK_QOS) if boxes is not None else None
    rough_r = DataReader(dp, Topic(dp, "rt" + ros_name(args.namespace, "fruit_rough"),
                                   Detection3DArray, qos=FEEDBACK_QOS), qos=FEEDBACK_QOS)

    k = cam["k"]
    p = [k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0]
    deadline = time.monotonic() + args.timeout
    stamps = []
    while time.monotonic() < deadline:
        stamp = now_time()
        stamps.append((stamp.sec, stamp.nanosec))
        header = Header(stamp, args.frame_id)
        info_w.write(CameraInfo(header, h, w, cam.get("distortion_model", "plumb_bob"),
                                cam["d"], k, [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0], p, 0, 0,
                                RegionOfInterest()))
        color_w.write(Image(header, h, w, "rgb8", 0, w * 3, rgb.tobytes()))
        depth_w.write(Image(header, h, w, "16UC1", 0, w * 2, depth.astype("<u2").tobytes()))
        if boxes_w is not None:
            boxes_w.write(detections_2d(header, boxes))
        t_next = time.monotonic() + 0.5
        while time.monotonic() < t_next:
            for m in take_valid(rough_r, 8):
                if (m.header.stamp.sec, m.header.stamp.nanosec) not in stamps:
                    continue
                result = {"frame_id": m.header.frame_id, "published": len(stamps),
                          "detections": detections_json(m)}
                if args.scan:
                    try:
                        result["scan"] = scan_detected(dp, args.namespace, deadline, log)
                    except Timeout as e:
                        log(str(e))
                        return 5
                print(json.dumps(result))
                return 0
            time.sleep(0.01)
    log(f"no fruit_rough for any of {len(stamps)} published pairs within {args.timeout} s")
    return 4


if __name__ == "__main__":
    sys.exit(main())
