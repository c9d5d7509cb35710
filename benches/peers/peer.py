#!/usr/bin/env python3
"""The OpenCV peer of alacs's stripe and board jobs, and the side-by-side table.

    peer.py ALACS_PEER_TIMING REPEATS STRIPE_FRAME -- BOARD_COLS BOARD_ROWS PHOTO... [-- BOARD_COLS BOARD_ROWS PHOTO...]...

Times OpenCV on the files (decoded first, as alacs does), runs alacs's
`peer_timing` example on the same files, and prints one table. Both sides
take the median of REPEATS runs per file; the table gives the median over
the files and the number of boards found.

The peers, as issue 16 states them:
- stripe: score = R - max(G, B) saturating (u8), argmax per row, rows whose
  peak is below 40 rejected, centre of gravity of the scores within +-5 px;
  numpy, vectorised over the whole frame;
- board: cv2.findChessboardCorners (adaptive threshold, normalise) then
  cv2.cornerSubPix (5 x 5 window).
"""
import json
import statistics
import subprocess
import sys
import time

import cv2
import numpy as np


def median_ms(repeats, job):
    times = []
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        job()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def stripe_peer(bgr):
    b, g, r = bgr[:, :, 0], bgr[:, :, 1], bgr[:, :, 2]
    score = cv2.subtract(r, cv2.max(g, b))
    peak = np.argmax(score, axis=1)
    rows = np.arange(score.shape[0])
    strong = score[rows, peak] >= 40
    offsets = np.arange(-5, 6)
    cols = np.clip(peak[:, None] + offsets[None, :], 0, score.shape[1] - 1)
    window = score[rows[:, None], cols].astype(np.float32)
    total = window.sum(axis=1)
    centre = (window * cols).sum(axis=1) / np.maximum(total, 1e-6)
    return centre[strong]


def board_peer(gray, size):
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
    if found:
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
        cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), criteria)
    return found


def alacs(binary, args):
    out = subprocess.run([binary, *args], check=True, capture_output=True, text=True).stdout
    return [json.loads(line) for line in out.splitlines() if line.strip()]


def main():
    if len(sys.argv) < 7 or "--" not in sys.argv:
        sys.exit(__doc__)
    split = sys.argv.index("--")
    binary, repeats, frames = sys.argv[1], int(sys.argv[2]), sys.argv[3:split]
    board_sets, current = [], None
    for arg in sys.argv[split:]:
        if arg == "--":
            current = []
            board_sets.append(current)
        else:
            current.append(arg)
    cv2.setNumThreads(2)

    table = []
    peer_ms, peer_rows = [], 0
    for f in frames:
        bgr = cv2.imread(f, cv2.IMREAD_COLOR)
        if bgr is None:
            sys.exit(f"peer.py: cannot read {f}")
        peer_ms.append(median_ms(repeats, lambda: stripe_peer(bgr)))
        peer_rows = len(stripe_peer(bgr))
    ours = alacs(binary, ["stripe", str(repeats), *frames])
    h, w = cv2.imread(frames[0]).shape[:2]
    table.append((f"stripe, {w}x{h} frame ({len(frames)} file), full frame",
                  statistics.median(o["ms"] for o in ours), f"{ours[0]['rows']} rows",
                  statistics.median(peer_ms), f"{peer_rows} rows"))

    for board_set in board_sets:
        if len(board_set) < 3:
            sys.exit(__doc__)
        cols, rows, photos = int(board_set[0]), int(board_set[1]), board_set[2:]
        peer_ms, peer_found = [], 0
        for f in photos:
            gray = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
            if gray is None:
                sys.exit(f"peer.py: cannot read {f}")
            peer_ms.append(median_ms(repeats, lambda: board_peer(gray, (cols, rows))))
            peer_found += bool(board_peer(gray, (cols, rows)))
        ours = alacs(binary, ["board", str(repeats), str(cols), str(rows), *photos])
        h, w = cv2.imread(photos[0]).shape[:2]
        table.append((f"board {cols}x{rows}, {w}x{h}, {len(photos)} photos",
                      statistics.median(o["ms"] for o in ours),
                      f"{sum(o['found'] for o in ours)} found",
                      statistics.median(peer_ms), f"{peer_found} found"))

    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}; median of {repeats} runs per file, "
          "then the median over the files")
    print("| job | alacs | OpenCV peer | OpenCV / alacs |")
    print("|---|---|---|---|")
    for job, ours_ms, ours_what, peer, peer_what in table:
        print(f"| {job} | {ours_ms:.2f} ms, {ours_what} | {peer:.2f} ms, {peer_what} | {peer / ours_ms:.2f} |")


if __name__ == "__main__":
    main()
