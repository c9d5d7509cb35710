#!/usr/bin/env python3
"""Stand-in ROS 2 action client for `<ns>/localize_fruit` (alacs_msgs/action/LocalizeFruit).

Speaks the ROS 2 DDS wire conventions exactly as rmw_cyclonedds_cpp does, using
Eclipse Cyclone DDS Python (PyPI `cyclonedds`, tested with 11.0.1):

* topics  rt/<ns>/...                 (ROS topic -> DDS topic "rt" + name)
* service rq/<ns>/localize_fruit/_action/send_goalRequest / rr/...Reply, etc.
* type names <pkg>::<msg|srv|action>::dds_::<Type>_
* every service request / reply payload starts with rmw_cyclonedds's
  cdds_request_header_t { uint64_t guid; int64_t seq; } (16 bytes, native
  little endian, right after the 4-byte encapsulation header), followed by the
  plain-CDR (XCDR1) message. The server must echo guid and seq in its reply;
  the client keeps only replies whose guid equals its own.
  On the Rust side this is ros2_client::ServiceMapping::Cyclone.

Flow: wait for the action server (matched request writers and reply readers),
send one goal, read feedback/status, request the result, collect PointCloud2
samples, print a JSON summary on stdout. Optionally cancel the goal
(--cancel-after), send a second goal while the first runs (--second-goal: the
summary says whether the server accepted it), or signal the node's process
mid-goal (--signal-after with --signal-pid). Exit codes:
  0 result received (and, with --expect-status, the status matched)
  2 goal rejected            3 timeout (server not found / no reply / no result)
  4 result status mismatch   5 required point cloud not received
  1 usage / other errors
Environment: ROS_DOMAIN_ID (default 0), CYCLONEDDS_URI (Cyclone config).
"""

import argparse
import json
import os
import random
import signal
import sys
import time
import uuid
from dataclasses import dataclass

from cyclonedds.core import Qos, Policy
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.internal import InvalidSample
from cyclonedds.idl.types import (array, float32, float64, int8, int32, int64,
                                  sequence, uint8, uint32, uint64)
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

# --------------------------------------------------------------------------
# ROS 2 message types (field order == .msg order; names must match ROS's)
# --------------------------------------------------------------------------


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class PointStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PointStamped_"):
    header: Header
    point: Point


@dataclass
class UUID(IdlStruct, typename="unique_identifier_msgs::msg::dds_::UUID_"):
    uuid: array[uint8, 16]


@dataclass
class GoalInfo(IdlStruct, typename="action_msgs::msg::dds_::GoalInfo_"):
    goal_id: UUID
    stamp: Time


@dataclass
class GoalStatus(IdlStruct, typename="action_msgs::msg::dds_::GoalStatus_"):
    goal_info: GoalInfo
    status: int8


@dataclass
class GoalStatusArray(IdlStruct, typename="action_msgs::msg::dds_::GoalStatusArray_"):
    status_list: sequence[GoalStatus]


GOAL_STATUS = {0: "UNKNOWN", 1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING",
               4: "SUCCEEDED", 5: "CANCELED", 6: "ABORTED"}

# --- alacs_msgs/action/LocalizeFruit -------------------------------------


@dataclass
class LocalizeFruit_Goal(IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_Goal_"):
    rough_position: PointStamped
    fruit_radius_m: float64


@dataclass
class LocalizeFruit_Result(IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_Result_"):
    status: str
    reason: str
    position: PointStamped
    radius_m: float64
    position_covariance: array[float64, 9]
    selected_frame: int32
    n_points: uint32


@dataclass
class LocalizeFruit_Feedback(IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_Feedback_"):
    frame: uint32
    n_frames: uint32
    slide_position_m: float64
    stripe_points: uint32


# Service payloads: cdds_request_header_t {uint64 guid; int64 seq} flattened in
# front of the ROS fields. In XCDR1 this is byte-identical to rmw_cyclonedds's
# serializer (put_bytes(guid,8); put_bytes(seq,8); then the message with
# alignment counted from the same origin; 16 is a multiple of 8).


@dataclass
class LocalizeFruit_SendGoal_Request(
        IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_SendGoal_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    goal_id: UUID
    goal: LocalizeFruit_Goal


@dataclass
class LocalizeFruit_SendGoal_Response(
        IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_SendGoal_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    accepted: bool
    stamp: Time


@dataclass
class LocalizeFruit_GetResult_Request(
        IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_GetResult_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    goal_id: UUID


@dataclass
class LocalizeFruit_GetResult_Response(
        IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_GetResult_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    status: int8
    result: LocalizeFruit_Result


@dataclass
class LocalizeFruit_FeedbackMessage(
        IdlStruct, typename="alacs_msgs::action::dds_::LocalizeFruit_FeedbackMessage_"):
    goal_id: UUID
    feedback: LocalizeFruit_Feedback


@dataclass
class CancelGoal_Request(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    goal_info: GoalInfo


@dataclass
class CancelGoal_Response(IdlStruct, typename="action_msgs::srv::dds_::CancelGoal_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    return_code: int8
    goals_canceling: sequence[GoalInfo]

# --- sensor_msgs/PointCloud2 ---------------------------------------------


@dataclass
class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    name: str
    offset: uint32
    datatype: uint8
    count: uint32


@dataclass
class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    header: Header
    height: uint32
    width: uint32
    fields: sequence[PointField]
    is_bigendian: bool
    point_step: uint32
    row_step: uint32
    data: sequence[uint8]
    is_dense: bool


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3
    rotation: Quaternion


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped]


# --- vision_msgs 4.x Detection3DArray --------------------------------------


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class ObjectHypothesis(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesis_"):
    class_id: str
    score: float64


@dataclass
class ObjectHypothesisWithPose(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesisWithPose_"):
    hypothesis: ObjectHypothesis
    pose: PoseWithCovariance


@dataclass
class BoundingBox3D(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox3D_"):
    center: Pose
    size: Vector3


@dataclass
class Detection3D(IdlStruct, typename="vision_msgs::msg::dds_::Detection3D_"):
    header: Header
    results: sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox3D
    id: str


@dataclass
class Detection3DArray(IdlStruct, typename="vision_msgs::msg::dds_::Detection3DArray_"):
    header: Header
    detections: sequence[Detection3D]


# --------------------------------------------------------------------------
# QoS profiles (ROS 2 defaults), all forced to XCDR1 (plain CDR), which is
# what rmw_cyclonedds and RustDDS use. RustDDS rejects XCDR2 payloads.
# --------------------------------------------------------------------------
XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)
SERVICE_QOS = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                  Policy.Durability.Volatile, Policy.History.KeepLast(10), XCDR1)
FEEDBACK_QOS = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                   Policy.Durability.Volatile, Policy.History.KeepLast(100), XCDR1)
STATUS_QOS = Qos(Policy.Reliability.Reliable(max_blocking_time=1_000_000_000),
                 Policy.Durability.TransientLocal, Policy.History.KeepLast(1), XCDR1)
SENSOR_QOS = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile,
                 Policy.History.KeepLast(5), XCDR1)


class Timeout(Exception):
    pass


def take_valid(reader, n):
    """take() but drop InvalidSample entries (dispose/unregister notifications)."""
    return [s for s in reader.take(N=n) if not isinstance(s, InvalidSample)]


def ros_name(ns: str, name: str) -> str:
    """ROS name (no leading 'rt'): '/ns/name'. Absolute `name` ignores ns."""
    if name.startswith("/"):
        return name.rstrip("/")
    ns = "/" + ns.strip("/") if ns.strip("/") else ""
    return f"{ns}/{name}"


def now_time() -> Time:
    t = time.time_ns()
    return Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)


# How often replies are polled: fine enough not to blur the goal-to-result
# latency that --soak measures.
POLL_S = 0.0005


class ServiceClient:
    """One ROS 2 service client with rmw_cyclonedds request header."""

    def __init__(self, dp, service: str, req_t, resp_t, guid: int):
        self.req_topic = Topic(dp, f"rq{service}Request", req_t, qos=SERVICE_QOS)
        self.rep_topic = Topic(dp, f"rr{service}Reply", resp_t, qos=SERVICE_QOS)
        self.writer = DataWriter(dp, self.req_topic, qos=SERVICE_QOS)
        self.reader = DataReader(dp, self.rep_topic, qos=SERVICE_QOS)
        self.guid = guid
        self.seq = 0
        self.name = service
        self.pending: dict[int, object] = {}

    def matched(self) -> bool:
        return bool(self.writer.get_matched_subscriptions()) and \
            bool(self.reader.get_matched_publications())

    def send(self, make_req) -> int:
        self.seq += 1
        self.writer.write(make_req(self.guid, self.seq))
        return self.seq

    def poll(self):
        for s in take_valid(self.reader, 32):
            if getattr(s, "cdds_guid", None) == self.guid:  # skip other clients' replies
                self.pending[s.cdds_seq] = s

    def wait_reply(self, seq: int, deadline: float, idle=None):
        while time.monotonic() < deadline:
            self.poll()
            if seq in self.pending:
                return self.pending.pop(seq)
            if idle:
                idle()
            time.sleep(POLL_S)
        raise Timeout(f"no reply on rr{self.name}Reply for seq {seq}")


def rss_mib(pid):
    """Resident and peak resident memory of process `pid`, MiB (from /proc)."""
    if pid is None:
        return None, None
    fields = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            key, _, value = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                fields[key] = int(value.split()[0]) / 1024.0
    return fields.get("VmRSS"), fields.get("VmHWM")


def soak(args, send_goal, get_result, log) -> int:
    """Sends args.soak goals one after the other; prints one JSON object with
    the goal-to-result latency and the watched node's memory after 10 goals
    and after the last."""
    latencies, statuses = [], {}
    rss_warm = None
    for k in range(args.soak):
        goal_uuid = uuid.uuid4().bytes
        goal = LocalizeFruit_Goal(
            rough_position=PointStamped(Header(now_time(), args.frame_id), Point(*args.rough)),
            fruit_radius_m=args.radius)
        t_goal = time.monotonic()
        seq = send_goal.send(lambda g, s: LocalizeFruit_SendGoal_Request(g, s, UUID(goal_uuid), goal))
        rep = send_goal.wait_reply(seq, t_goal + 10.0)
        if not rep.accepted:
            log(f"goal {k + 1} rejected")
            return 2
        rseq = get_result.send(lambda g, s: LocalizeFruit_GetResult_Request(g, s, UUID(goal_uuid)))
        res = get_result.wait_reply(rseq, t_goal + args.timeout)
        latencies.append(time.monotonic() - t_goal)
        if args.latencies:
            print(f"latency {k + 1} {latencies[-1] * 1000:.3f} ms", file=sys.stderr, flush=True)
        statuses[res.result.status] = statuses.get(res.result.status, 0) + 1
        if k + 1 == 10:
            rss_warm, _ = rss_mib(args.watch_pid)
        if (k + 1) % 100 == 0:
            log(f"{k + 1} goals, last latency {latencies[-1] * 1000:.0f} ms")
    rss_end, hwm = rss_mib(args.watch_pid)
    latencies.sort()
    growth = None if rss_warm is None else 100.0 * (rss_end - rss_warm) / rss_warm
    print(json.dumps({
        "goals": args.soak, "statuses": statuses,
        "latency_s": {"median": latencies[len(latencies) // 2],
                      "p95": latencies[int(len(latencies) * 0.95) - 1], "max": latencies[-1]},
        "node_rss_mib_after_10": rss_warm, "node_rss_mib_after_all": rss_end,
        "node_peak_rss_mib": hwm, "rss_growth_percent": growth}, indent=1))
    return 6 if growth is not None and growth >= 10.0 else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("namespace", help="node/action namespace, e.g. /alacs or / (action is <ns>/localize_fruit)")
    ap.add_argument("--action", default="localize_fruit", help="action base name (default localize_fruit)")
    ap.add_argument("--cloud-topic", default="laser_points",
                    help="PointCloud2 topic, relative to namespace unless it starts with / (default laser_points)")
    ap.add_argument("--frame-id", default="alacs_camera_optical_frame")
    ap.add_argument("--rough", type=float, nargs=3, default=[0.0, 0.0, 0.5], metavar=("X", "Y", "Z"))
    ap.add_argument("--radius", type=float, default=0.035)
    ap.add_argument("--discovery-timeout", type=float, default=20.0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds from goal send to result")
    ap.add_argument("--expect-status", default=None,
                    help="required final GoalStatus name, e.g. SUCCEEDED (exit 4 otherwise)")
    ap.add_argument("--require-cloud", action="store_true", help="exit 5 if no PointCloud2 arrived")
    ap.add_argument("--cancel-after", type=float, default=None,
                    help="send cancel_goal this many seconds after acceptance")
    ap.add_argument("--soak", type=int, default=None, metavar="N",
                    help="send N goals in a row (each after the last result) and print latency and "
                         "the node's memory (--watch-pid); exit 6 if its RSS grew 10 %% or more")
    ap.add_argument("--latencies", action="store_true",
                    help="with --soak: print each goal's latency on stderr ('latency K MS ms')")
    ap.add_argument("--second-goal", action="store_true",
                    help="send a second goal right after the first is accepted; the summary's "
                         "second_goal_accepted says whether the server took it")
    ap.add_argument("--signal-after", type=float, default=None, metavar="S",
                    help="send SIGTERM to --signal-pid S seconds after the goal is accepted")
    ap.add_argument("--signal-pid", type=int, default=None, help="the node's process id (--signal-after)")
    ap.add_argument("--watch-pid", type=int, default=None,
                    help="the node's process id, whose resident memory --soak reports")
    ap.add_argument("--tf", nargs=9, default=None,
                    metavar=("PARENT", "CHILD", "X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                    help="publish this transform on /tf at 20 Hz (as a robot's state publisher) "
                    "from before the goal to the end")
    ap.add_argument("--check-only", action="store_true",
                    help="create participant and all entities, then exit 0 (smoke test)")
    args = ap.parse_args(argv)
    if (args.signal_after is None) != (args.signal_pid is None):
        ap.error("--signal-after and --signal-pid go together")

    domain = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    dp = DomainParticipant(domain)
    action = ros_name(args.namespace, args.action)           # /ns/localize_fruit
    base = f"{action}/_action"
    guid = random.getrandbits(63) | 1                         # any value; replies are filtered on it
    send_goal = ServiceClient(dp, f"/{base.lstrip('/')}/send_goal",
                              LocalizeFruit_SendGoal_Request, LocalizeFruit_SendGoal_Response, guid)
    get_result = ServiceClient(dp, f"/{base.lstrip('/')}/get_result",
                               LocalizeFruit_GetResult_Request, LocalizeFruit_GetResult_Response, guid)
    cancel = ServiceClient(dp, f"/{base.lstrip('/')}/cancel_goal",
                           CancelGoal_Request, CancelGoal_Response, guid)
    fb_reader = DataReader(dp, Topic(dp, f"rt{base}/feedback", LocalizeFruit_FeedbackMessage,
                                     qos=FEEDBACK_QOS), qos=FEEDBACK_QOS)
    st_reader = DataReader(dp, Topic(dp, f"rt{base}/status", GoalStatusArray, qos=STATUS_QOS),
                           qos=STATUS_QOS)
    cloud_name = ros_name(args.namespace, args.cloud_topic)
    cloud_reader = DataReader(dp, Topic(dp, f"rt{cloud_name}", PointCloud2, qos=SENSOR_QOS),
                              qos=SENSOR_QOS)
    # <ns>/fruit: vision_msgs/Detection3DArray, reliable and volatile as the node publishes it.
    fruit_reader = DataReader(dp, Topic(dp, f"rt{ros_name(args.namespace, 'fruit')}",
                                        Detection3DArray, qos=FEEDBACK_QOS), qos=FEEDBACK_QOS)
    # /tf_static as tf2's static listener reads it: reliable, transient local.
    tf_reader = DataReader(dp, Topic(dp, "rt/tf_static", TFMessage, qos=STATUS_QOS),
                           qos=STATUS_QOS)
    log = lambda *a: print("[peer]", *a, file=sys.stderr, flush=True)
    log(f"domain={domain} action={action} cloud=rt{cloud_name} "
        f"CYCLONEDDS_URI={os.environ.get('CYCLONEDDS_URI', '<unset>')}")
    if args.check_only:
        log("participant and entities created; --check-only: exiting")
        return 0

    summary = {"action": action, "feedback": [], "statuses": [], "clouds": [], "tf_static": [],
               "fruit": []}

    tf_writer, last_tf = None, [0.0]
    if args.tf:
        # /tf as tf2's broadcaster publishes it: reliable, volatile, depth 100.
        tf_writer = DataWriter(dp, Topic(dp, "rt/tf", TFMessage, qos=FEEDBACK_QOS), qos=FEEDBACK_QOS)

    def publish_tf():
        parent, child, *numbers = args.tf
        x, y, z, qx, qy, qz, qw = map(float, numbers)
        tf_writer.write(TFMessage([TransformStamped(Header(now_time(), parent), child,
                                                    Transform(Vector3(x, y, z),
                                                              Quaternion(qx, qy, qz, qw)))]))
        last_tf[0] = time.monotonic()

    def drain():
        if tf_writer is not None and time.monotonic() - last_tf[0] > 0.05:
            publish_tf()
        for m in take_valid(fb_reader, 64):
            if bytes(m.goal_id.uuid) == goal_uuid:
                f = m.feedback
                summary["feedback"].append({"frame": f.frame, "n_frames": f.n_frames,
                                            "slide_position_m": f.slide_position_m,
                                            "stripe_points": f.stripe_points})
        for m in take_valid(st_reader, 16):
            for s in m.status_list:
                if bytes(s.goal_info.goal_id.uuid) == goal_uuid:
                    name = GOAL_STATUS.get(s.status, str(s.status))
                    if not summary["statuses"] or summary["statuses"][-1] != name:
                        summary["statuses"].append(name)
        for m in take_valid(tf_reader, 4):
            for t in m.transforms:
                tr, q = t.transform.translation, t.transform.rotation
                summary["tf_static"].append({"parent": t.header.frame_id, "child": t.child_frame_id,
                                             "translation": [tr.x, tr.y, tr.z],
                                             "rotation": [q.x, q.y, q.z, q.w]})
        for m in take_valid(fruit_reader, 8):
            for d in m.detections:
                for h in d.results:
                    p = h.pose.pose.position
                    summary["fruit"].append({
                        "frame_id": m.header.frame_id, "class_id": h.hypothesis.class_id,
                        "score": h.hypothesis.score, "position": [p.x, p.y, p.z],
                        "covariance": list(h.pose.covariance),
                        "size": [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z]})
        for c in take_valid(cloud_reader, 8):
            summary["clouds"].append({"frame_id": c.header.frame_id, "width": c.width,
                                      "height": c.height, "point_step": c.point_step,
                                      "fields": [f.name for f in c.fields], "bytes": len(c.data)})

    try:
        # 1. wait for the server, like rclpy's wait_for_server()
        t_end = time.monotonic() + args.discovery_timeout
        while not (send_goal.matched() and get_result.matched() and cancel.matched()):
            if time.monotonic() > t_end:
                raise Timeout(f"action server {action} not discovered within {args.discovery_timeout}s "
                              f"(send_goal matched={send_goal.matched()}, get_result matched={get_result.matched()}, "
                              f"cancel matched={cancel.matched()})")
            time.sleep(0.05)
        time.sleep(0.5)  # let the server side finish matching our reply readers (volatile replies)
        log("action server discovered")
        if tf_writer is not None:
            for _ in range(20):  # a second of the robot's /tf before the goal
                publish_tf()
                time.sleep(0.05)

        if args.soak:
            return soak(args, send_goal, get_result, log)

        # 2. send goal
        goal_uuid = uuid.uuid4().bytes
        goal = LocalizeFruit_Goal(
            rough_position=PointStamped(Header(now_time(), args.frame_id), Point(*args.rough)),
            fruit_radius_m=args.radius)
        seq = send_goal.send(lambda g, s: LocalizeFruit_SendGoal_Request(g, s, UUID(goal_uuid), goal))
        t_goal = time.monotonic()
        rep = send_goal.wait_reply(seq, t_goal + min(args.timeout, 10.0), idle=drain)
        summary["accepted"] = bool(rep.accepted)
        summary["accept_stamp"] = [rep.stamp.sec, rep.stamp.nanosec]
        log(f"goal {goal_uuid.hex()} accepted={rep.accepted}")
        if not rep.accepted:
            print(json.dumps(summary, indent=1))
            return 2

        # 3. request the result immediately (server answers when the goal ends)
        rseq = get_result.send(lambda g, s: LocalizeFruit_GetResult_Request(g, s, UUID(goal_uuid)))
        deadline = t_goal + args.timeout
        if args.second_goal:
            second_uuid = uuid.uuid4().bytes
            sseq = send_goal.send(lambda g, s: LocalizeFruit_SendGoal_Request(g, s, UUID(second_uuid), goal))
            srep = send_goal.wait_reply(sseq, deadline, idle=drain)
            summary["second_goal_accepted"] = bool(srep.accepted)
            log(f"second goal {second_uuid.hex()} accepted={srep.accepted}")
        if args.signal_after is not None:
            t_signal = time.monotonic() + args.signal_after
            while time.monotonic() < t_signal:
                drain(); time.sleep(0.01)
            os.kill(args.signal_pid, signal.SIGTERM)
            summary["signalled"] = "SIGTERM"
            log(f"sent SIGTERM to {args.signal_pid}")
        if args.cancel_after is not None:
            t_cancel = time.monotonic() + args.cancel_after
            while time.monotonic() < t_cancel:
                drain(); time.sleep(0.01)
            cseq = cancel.send(lambda g, s: CancelGoal_Request(g, s, GoalInfo(UUID(goal_uuid), Time(0, 0))))
            crep = cancel.wait_reply(cseq, deadline, idle=drain)
            summary["cancel"] = {"return_code": crep.return_code,
                                 "goals_canceling": [bytes(gi.goal_id.uuid).hex() for gi in crep.goals_canceling]}
        res = get_result.wait_reply(rseq, deadline, idle=drain)
        time.sleep(0.2); drain()
        r = res.result
        summary["result_status"] = GOAL_STATUS.get(res.status, str(res.status))
        summary["result"] = {
            "status": r.status, "reason": r.reason, "frame_id": r.position.header.frame_id,
            "position": [r.position.point.x, r.position.point.y, r.position.point.z],
            "radius_m": r.radius_m, "position_covariance": list(r.position_covariance),
            "selected_frame": r.selected_frame, "n_points": r.n_points}
    except Timeout as e:
        log(f"TIMEOUT: {e}")
        summary["error"] = f"timeout: {e}"
        print(json.dumps(summary, indent=1))
        return 3

    print(json.dumps(summary, indent=1))
    if args.expect_status and summary["result_status"] != args.expect_status.upper():
        log(f"result status {summary['result_status']} != expected {args.expect_status.upper()}")
        return 4
    if args.require_cloud and not summary["clouds"]:
        log("no PointCloud2 received on rt" + cloud_name)
        return 5
    return 0


if __name__ == "__main__":
    sys.exit(main())
