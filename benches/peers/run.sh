#!/usr/bin/env bash
# alacs against its OpenCV peer on the same files, in one run (issue 16):
# the laser stripe of a 5 MP simulated calibration view, and checkerboard
# corners in the 640 x 480 photographs of testdata/opencv_right and in 14
# simulated 1152 x 768 views with the red laser line across the board
# (issue 16's photographs of that size are not public; these stand in).
#
#   benches/peers/run.sh [REPEATS]      (default 20)
#
# Installs the peer (benches/peers/requirements.txt, PyPI wheels) into a
# virtual environment under target/, builds alacs's `peer_timing` example,
# and prints one Markdown table. Takes a minute or two on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
repeats="${1:-20}"
target="${CARGO_TARGET_DIR:-target}"
venv="$target/peer-bench-venv"
work="$target/peer-bench"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install -q -r benches/peers/requirements.txt
cargo build --release -q -p alacs-cli -p alacs-board --example peer_timing
if [ ! -f "$work/session/view01.png" ]; then
    rm -rf "$work/session"
    "$target/release/alacs" simulate session --out "$work/session" --views 1 --seed 1 >/dev/null
fi
if [ ! -f "$work/session1152/view14.png" ]; then
    rm -rf "$work/session1152"
    mkdir -p "$work"
    # A 1152 x 768 camera with the 5 MP camera's field of view (and its lens's distortion).
    cat > "$work/camera1152.yaml" <<'YAML'
image_width: 1152
image_height: 768
camera_name: peer_1152
camera_matrix: {rows: 3, cols: 3, data: [1092.0, 0.0, 576.0, 0.0, 1092.0, 384.0, 0.0, 0.0, 1.0]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-0.080, 0.125, 0.00014, -7.0e-5, -0.018]}
YAML
    "$target/release/alacs" simulate session --out "$work/session1152" --views 14 --seed 16 \
        --camera "$work/camera1152.yaml" >/dev/null
fi
"$venv/bin/python" benches/peers/peer.py "$target/release/examples/peer_timing" "$repeats" \
    "$work/session/view01.png" -- 9 6 testdata/opencv_right/right*.jpg \
    -- 11 8 "$work"/session1152/view*.png
