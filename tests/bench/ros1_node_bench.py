#!/usr/bin/python3
"""mobmap_node's latency from an image's stamp to the map, and the cost of its
robot-centric GridMap, with the simulated corridor played by `rosbag play --clock` at
30 Hz (and at 15 Hz for comparison), a listener on every output. A benchmark, not a
test: it prints medians and 95th percentiles as the node's status topic reports them
(the last 300 frames), and `mobmap build`'s time per frame on the same bag as the
reference of the same run.

    /usr/bin/python3 tests/bench/ros1_node_bench.py build [frames]

ROS traffic stays on this machine: a master on a free loopback port, ROS_IP=127.0.0.1.
"""
import json
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main():
    build = Path(sys.argv[1] if len(sys.argv) > 1 else "build").resolve()
    frames = int(sys.argv[2]) if len(sys.argv) > 2 else 240
    exe, node = build / "apps/mobmap", build / "ros1/mobmap/mobmap_node"
    tmp = Path(tempfile.mkdtemp(prefix="mobmap-ros1-bench-"))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = dict(os.environ, ROS_IP="127.0.0.1", ROS_HOSTNAME="127.0.0.1", ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_HOME=str(tmp / "ros_home"), ROS_LOG_DIR=str(tmp / "ros_log"))
    os.environ.update(env)
    subprocess.run([str(exe), "simulate", "--out", str(tmp / "seq"), "--frames", str(frames), "-q"], check=True)
    subprocess.run([str(build / "tests/write_bag1"), "--seq", str(tmp / "seq"), "--out", str(tmp / "c.bag"),
                    "--layout", "base", "--world", "map"], check=True)
    out = subprocess.run([str(exe), "build", str(tmp / "c.bag"), "--out", str(tmp / "b/c.ot")], check=True,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True).stdout
    m = re.search(r"fused .* in ([0-9.]+) s \(([0-9.]+) frames/s\)", out)
    print(f"reference: mobmap build of the same {frames} frames: {m.group(2)} frames/s "
          f"({1000 / float(m.group(2)):.1f} ms a frame on all cores)")
    core = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    import rosgraph
    import rospy
    from std_msgs.msg import String

    while not rosgraph.Master("/bench").is_online():
        time.sleep(0.1)
    rospy.set_param("/use_sim_time", True)
    rospy.init_node("bench", anonymous=True, disable_signals=True)
    try:
        for rate in (1.0, 0.5):
            status = []
            subs = [rospy.Subscriber("/mobmap/status", String, lambda m: status.append(json.loads(m.data)))]
            subs += [rospy.Subscriber(t, rospy.AnyMsg, lambda m: None) for t in
                     ("/mobmap/elevation_map", "/mobmap/mobility_cloud", "/mobmap/occupancy", "/mobmap/octomap_binary")]
            n = subprocess.Popen([str(node), "depth:=/camera/depth/image_raw", "_status_rate:=4"], env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
            while not status or any(s.get_num_connections() == 0 for s in subs):
                time.sleep(0.1)
            subprocess.run(["rosbag", "play", "-q", "--clock", "-r", str(rate), str(tmp / "c.bag")], env=env, check=True,
                           stdout=subprocess.DEVNULL)
            while not status or status[-1]["fused"] + status[-1]["dropped"] + status[-1]["late"] + status[-1]["unreadable"] < status[-1]["received"]:
                time.sleep(0.1)
            n_reports = len(status)
            while len(status) < n_reports + 4:  # a few more GridMaps at the final map, by the node's reports
                time.sleep(0.1)
            s = status[-1]
            # Under simulated time played at `rate`, the node's stamp->map latency is in bag
            # time: divided by the rate it is wall time.
            wall = {k: round(v / rate, 1) for k, v in s["latency_ms"].items()}
            print(f"input at {30 * rate:.0f} Hz: {s['fused']} of {s['received']} frames fused, {s['dropped']} dropped, "
                  f"{s['late']} late; latency stamp->map median {wall['median']} ms, p95 {wall['p95']} ms; "
                  f"perception {s['perception_ms']['median']} ms, fusion {s['fusion_ms']['median']} ms; "
                  f"GridMap (4 x 4 m at 4 cm, 5 layers) median {s['grid_map_ms']['median']} ms, p95 {s['grid_map_ms']['p95']} ms")
            n.send_signal(2)
            n.wait()
            for sub in subs:
                sub.unregister()
    finally:
        rospy.signal_shutdown("done")
        core.send_signal(2)
        core.wait()


if __name__ == "__main__":
    main()
