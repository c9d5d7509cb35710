"""OpenCV's ChArUco detector on the images a test names: the peer of
alacs's ChArUco detection (crates/calib/tests/opencv_charuco.rs).

Reads one JSON object on standard input:
  {"squares": [across, down], "square_mm": s, "marker_mm": m,
   "dictionary": "DICT_5X5_100", "images": ["/path/a.png", ...]}
and prints {"images": [{"ids": [...], "corners": [[u, v], ...]}, ...]} on
standard output, one entry per image (empty where OpenCV finds no board).
OpenCV 4.6+'s board layout (not the legacy pattern), its default detector
parameters (corner refinement by cornerSubPix inside CharucoDetector), and
the image read as greyscale (luminance).
"""
import json
import sys

import cv2

request = json.load(sys.stdin)
dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, request["dictionary"]))
board = cv2.aruco.CharucoBoard(
    tuple(request["squares"]), request["square_mm"], request["marker_mm"], dictionary
)
detector = cv2.aruco.CharucoDetector(board)
out = []
for path in request["images"]:
    image = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if image is None:
        sys.exit(f"cannot read {path}")
    corners, ids, _, _ = detector.detectBoard(image)
    if ids is None:
        out.append({"ids": [], "corners": []})
        continue
    out.append(
        {
            "ids": [int(i) for i in ids.reshape(-1)],
            "corners": [[float(c[0]), float(c[1])] for c in corners.reshape(-1, 2)],
        }
    )
json.dump({"images": out}, sys.stdout)
