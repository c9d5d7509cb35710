#!/bin/sh
# The ROS node's soak (issue "ROS 2 node", item 6): N goals in a row to
# `alacs ros --sim` from the Cyclone DDS peer, in a network namespace of its
# own (root), and the node's resident memory after 10 goals and after all.
#
#   ros/peer/soak.sh [N] [PYTHON]     # N = 1000; PYTHON with cyclonedds
#
# Prints the peer's JSON (latency, statuses, node_rss_mib_after_10,
# node_rss_mib_after_all, rss_growth_percent) and the node's summary; exits
# non-zero if a goal failed or the memory grew 10 % or more.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
n=${1:-1000}
python=${2:-${ALACS_PEER_PYTHON:-python3}}
alacs=${ALACS:-$repo/target/release/alacs}
export CYCLONEDDS_URI="file://$repo/ros/dds/cyclonedds-loopback.xml"
export ROS_LOCALHOST_ONLY=1 RMW_IMPLEMENTATION=rmw_cyclonedds_cpp ROS_DOMAIN_ID=23
rough=$("$python" - "$alacs" <<'PY'
import json, subprocess, sys, tempfile
with tempfile.TemporaryDirectory() as d:
    subprocess.run([sys.argv[1], "simulate", "scan", "--seed", "4", "--scale", "0.25", "--out", d,
                    "--force"], check=True, stdout=subprocess.DEVNULL)
    t = json.load(open(f"{d}/truth.json"))
print(" ".join(str(v / 1000) for v in t["rough_position_mm"]))
PY
)
exec unshare --net sh -c "
ip link set lo up
'$alacs' ros --sim --seed 4 --scale 0.25 --no-images --max-goals $n --json 2>/dev/null &
node=\$!
'$python' '$here/localize_fruit_peer.py' /alacs --soak $n --watch-pid \$node --rough $rough \
    --radius 0.04 --discovery-timeout 60 --timeout 120
peer=\$?
wait \$node
exit \$peer
"
