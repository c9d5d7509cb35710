"""OpenCV's calibrateCamera on the corners a test gives: the peer of alacs's
camera calibration controls (crates/calib/tests/opencv_controls.rs).

Reads one JSON object on standard input:
  {"image_size": [w, h], "object_points": [[[x, y, z], ...] per view],
   "image_points": [[[u, v], ...] per view], "flags": ["FIX_K3", ...],
   "initial": {"K": [9 values], "dist": [...]} or null}
and prints {"rms_px", "fx", "fy", "cx", "cy", "dist"} on standard output.
The flags are names of cv2.CALIB_* constants. The termination criteria are
tightened from OpenCV's default (30 iterations) so that both sides report
their converged minimum.
"""
import json
import sys

import cv2
import numpy as np

request = json.load(sys.stdin)
flags = 0
for name in request["flags"]:
    flags |= getattr(cv2, "CALIB_" + name)
object_points = [np.asarray(v, dtype=np.float32) for v in request["object_points"]]
image_points = [np.asarray(v, dtype=np.float32).reshape(-1, 1, 2) for v in request["image_points"]]
initial = request.get("initial")
if initial is not None:
    camera_matrix = np.asarray(initial["K"], dtype=np.float64).reshape(3, 3)
    dist = np.asarray(initial["dist"], dtype=np.float64).reshape(-1, 1)
else:
    camera_matrix = np.eye(3)
    dist = np.zeros((8 if flags & cv2.CALIB_RATIONAL_MODEL else 5, 1))
criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-15)
rms, k, d, _, _ = cv2.calibrateCamera(
    object_points, image_points, tuple(request["image_size"]), camera_matrix, dist,
    flags=flags, criteria=criteria)
print(json.dumps({
    "rms_px": rms, "fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2],
    "dist": d.flatten().tolist(),
}))
