#!/usr/bin/env bash
# Draws docs/images/ros1_rviz.png: RViz (Debian's, under Xvfb) showing mobmap_node's
# mobility cloud (coloured by its `mobility` channel, red 0 to green 1) and occupancy grid
# while the node maps the simulated corridor played from a ROS 1 bag.
#   bash scripts/rviz_screenshot.sh [OUT.png]
# Needs a build (scripts/build.sh) and Debian's rviz, xvfb and imagemagick. ROS traffic
# stays on this machine: a master on a free loopback port, ROS_IP=127.0.0.1.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out="${1:-$root/docs/images/ros1_rviz.png}"
build="$root/build"
for p in rviz xvfb imagemagick; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || {
    echo "rviz_screenshot: install $p (apt-get install rviz xvfb imagemagick)" >&2; exit 1; }
done
tmp="$(mktemp -d)"
pids=()
cleanup() { for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; rm -rf "$tmp"; }
trap cleanup EXIT
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
display=":$((port % 500 + 100))"
export ROS_IP=127.0.0.1 ROS_HOSTNAME=127.0.0.1 ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOME="$tmp/ros" ROS_LOG_DIR="$tmp/log"
"$build/apps/mobmap" simulate --out "$tmp/corridor" --frames 240 -q
"$build/tests/write_bag1" --seq "$tmp/corridor" --out "$tmp/corridor.bag" --layout base --world map
roscore -p "$port" >"$tmp/roscore.log" 2>&1 & pids+=($!)
until rosparam list >/dev/null 2>&1; do sleep 0.2; done
rosparam set /use_sim_time true
"$build/ros1/mobmap/mobmap_node" depth:=/camera/depth/image_raw >"$tmp/node.log" 2>&1 & pids+=($!)
Xvfb "$display" -screen 0 1200x760x24 >"$tmp/xvfb.log" 2>&1 & pids+=($!)
until xdpyinfo -display "$display" >/dev/null 2>&1 || [ -e "/tmp/.X11-unix/X${display#:}" ]; do sleep 0.2; done
DISPLAY="$display" rviz -d "$root/ros1/rviz/mobmap.rviz" >"$tmp/rviz.log" 2>&1 & pids+=($!)
# RViz subscribes to both outputs before the first frame is played.
until [ "$(rostopic info /mobmap/mobility_cloud 2>/dev/null | grep -c rviz)" -ge 1 ] &&
      [ "$(rostopic info /mobmap/occupancy 2>/dev/null | grep -c rviz)" -ge 1 ]; do sleep 0.5; done
rosbag play -q --clock -r 0.5 "$tmp/corridor.bag" >/dev/null
# The status says every frame is accounted for; then the last cloud and grid are drawn.
until rostopic echo -p -n 1 /mobmap/status 2>/dev/null | python3 -c '
import json, sys
s = json.loads(sys.stdin.read().splitlines()[1].split(",", 1)[1])
sys.exit(0 if s["fused"] + s["dropped"] + s["late"] + s["unreadable"] >= 240 else 1)'; do sleep 1; done
sleep 4  # RViz draws at 10 Hz; the last messages arrive within the outputs' periods (1 s, 2 s)
mkdir -p "$(dirname "$out")"
DISPLAY="$display" import -window root "$out"
echo "wrote $out"
