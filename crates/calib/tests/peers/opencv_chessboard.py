"""OpenCV's checkerboard detectors on the images a test names: the peer of
alacs's board detection (crates/calib/tests/opencv_boards.rs).

Reads one JSON object on standard input:
  {"inner_corners": [cols, rows], "images": ["/path/a.png", ...]}
and prints {"images": [{"sb": [[u, v], ...] or null,
"classic": [[u, v], ...] or null}, ...]} on standard output, one entry per
image: findChessboardCornersSB (flags EXHAUSTIVE | ACCURACY) and the
classic findChessboardCorners (ADAPTIVE_THRESH | NORMALIZE_IMAGE, then
cornerSubPix in a 5 x 5 window), each the whole board or null. The image is
read as greyscale (luminance).
"""
import json
import sys

import cv2

request = json.load(sys.stdin)
size = tuple(request["inner_corners"])
criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
out = []
for path in request["images"]:
    image = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if image is None:
        sys.exit(f"cannot read {path}")
    found, corners = cv2.findChessboardCornersSB(
        image, size, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    )
    sb = [[float(c[0]), float(c[1])] for c in corners.reshape(-1, 2)] if found else None
    found, corners = cv2.findChessboardCorners(
        image, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    classic = None
    if found:
        corners = cv2.cornerSubPix(image, corners, (5, 5), (-1, -1), criteria)
        classic = [[float(c[0]), float(c[1])] for c in corners.reshape(-1, 2)]
    out.append({"sb": sb, "classic": classic})
json.dump({"images": out}, sys.stdout)
