#!/usr/bin/env bash
# alacs against its OpenCV peer on the same files, in one run (issue 16):
# the laser stripe of a 5 MP simulated calibration view, and checkerboard
# corners in the 640 x 480 photographs of testdata/opencv_right.
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
"$venv/bin/python" benches/peers/peer.py "$target/release/examples/peer_timing" "$repeats" \
    "$work/session/view01.png" -- 9 6 testdata/opencv_right/right*.jpg
