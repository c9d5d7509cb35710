#!/usr/bin/python3
"""Parses ros/alacs_msgs/action/LocalizeFruit.action with ROS 2's own IDL
parser (Debian python3-rosidl: rosidl_adapter) and checks its fields, as
the Rust test `action_file` does with its own reader. Run with Debian's
/usr/bin/python3 (the rosidl modules are installed for it)."""

import sys
from pathlib import Path

from rosidl_adapter.parser import parse_action_string

EXPECTED = (
    [("geometry_msgs/PointStamped", "rough_position"), ("float64", "fruit_radius_m")],
    [("string", "status"), ("string", "reason"), ("geometry_msgs/PointStamped", "position"),
     ("float64", "radius_m"), ("float64[9]", "position_covariance"), ("int32", "selected_frame"),
     ("uint32", "n_points")],
    [("uint32", "frame"), ("uint32", "n_frames"), ("float64", "slide_position_m"),
     ("uint32", "stripe_points")],
)

path = Path(__file__).parent / "alacs_msgs" / "action" / "LocalizeFruit.action"
action = parse_action_string("alacs_msgs", "LocalizeFruit", path.read_text())
parts = (action.goal, action.result, action.feedback)
for part, expected in zip(parts, EXPECTED):
    got = [(str(f.type), f.name) for f in part.fields]
    if got != expected:
        sys.exit(f"{path}: {part.msg_name}: {got} != {expected}")
print(f"{path}: goal, result and feedback parsed by rosidl_adapter, fields as expected")
