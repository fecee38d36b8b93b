#!/usr/bin/python3
"""mobmap_ros2's latency from an image's stamp to the map and what DDS loses, with the
simulated corridor's ROS 2 recording published by a Fast DDS participant (dds_peer) at
30 Hz and 15 Hz with /clock, images best effort (sensor data QoS), a subscriber on every
output. A benchmark, not a test: it prints the node's status (medians and 95th
percentiles over the last 300 frames) and `mobmap build`'s time per frame on the same
recording as the reference of the same run; then 30 Hz again with a small socket receive
buffer, to show what the buffer is for.

    /usr/bin/python3 tests/bench/ros2_node_bench.py build [frames]

DDS stays on this machine: every participant on 127.0.0.1 without multicast, inside a
network namespace of its own when `unshare -rn` works (the script re-runs itself there).
"""
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main():
    build = Path(sys.argv[1] if len(sys.argv) > 1 else "build").resolve()
    frames = int(sys.argv[2]) if len(sys.argv) > 2 else 240
    if not os.environ.get("MOBMAP_NETNS") and subprocess.run(["unshare", "-rn", "true"]).returncode == 0:
        os.execvp("sh", ["sh", str(HERE.parent / "ros2" / "isolated.sh"), sys.executable] + sys.argv)
    exe = build / "apps/mobmap"
    os.environ.update(MOBMAP_EXE=str(exe), MOBMAP_ROS2=str(build / "ros2/mobmap_ros2"),
                      MOBMAP_DDS_PEER=str(build / "tests/dds_peer"), MOBMAP_RECORDINGS=str(HERE.parent / "recordings"))
    sys.path[:0] = [str(HERE.parent / "ros2"), str(HERE.parent / "ros1"), str(build / "python")]
    import test_ros2_node as t

    tmp = Path(tempfile.mkdtemp(prefix="mobmap-ros2-bench-"))
    (tmp / "cyclone.xml").write_text(t.CYCLONE_LOOPBACK)
    subprocess.run([str(exe), "simulate", "--out", str(tmp / "seq"), "--frames", str(frames), "-q"], check=True)
    for out in (["--feed", str(tmp / "c.jsonl")], ["--out", str(tmp / "c.mcap")]):
        subprocess.run(["node", str(HERE.parent / "recordings/write_bag.mjs"), "--seq", str(tmp / "seq"), "--layout", "base",
                        "--world", "map"] + out, check=True, stdout=subprocess.DEVNULL)
    out = subprocess.run([str(exe), "build", str(tmp / "c.mcap"), "--out", str(tmp / "b/c.ot")], check=True,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True).stdout
    m = re.search(r"fused .* in ([0-9.]+) s \(([0-9.]+) frames/s\)", out)
    print(f"reference: mobmap build of the same {frames} frames: {m.group(2)} frames/s "
          f"({1000 / float(m.group(2)):.1f} ms a frame on all cores)")
    rmem = Path("/proc/sys/net/core/rmem_max").read_text().strip()
    print(f"net.core.rmem_max {rmem} bytes")
    for run, (rate, buffer_mb) in enumerate(((1.0, 8), (0.5, 8), (1.0, 0.25))):
        domain = 10 + run
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), CYCLONEDDS_URI="file://" + str(tmp / "cyclone.xml"))
        log = open(tmp / f"node{run}.log", "w")
        node = subprocess.Popen([t.NODE, "--ros-args", "-r", "depth:=/camera/depth/image_raw", "-p", "use_sim_time:=true",
                                 "-p", "status_rate:=4", "-p", f"receive_buffer_mb:={buffer_mb}"],
                                env=env, stdout=log, stderr=subprocess.STDOUT)
        peer = t.Peer(tmp, f"peer{run}", domain, env, pace=0)  # as a camera driver sends
        for name, topic, kind in t.SUBS:
            peer(f"sub {name} {topic} {kind} latched")
        for name, topic, kind, qos in t.PUBS:
            peer(f"pub {name} {topic} {kind} {'sensor' if name.startswith('/camera') else qos}")
        while not all(peer.matched(p[0]) for p in t.PUBS + [(s[0],) for s in t.SUBS]):
            time.sleep(0.1)
        peer(f"play {tmp / 'c.jsonl'} {rate} clock")
        while not peer.seen(event="played"):
            time.sleep(0.1)
        # Every frame received is fused, dropped, late or unreadable before the numbers are read.
        while True:
            s = t.status_of(peer)
            if s and s["fused"] + s["dropped"] + s["late"] + s["unreadable"] >= s["received"]:
                break
            time.sleep(0.1)
        n = len(peer.samples("status"))
        while len(peer.samples("status")) < n + 4:  # a few more GridMaps at the final map
            time.sleep(0.1)
        s = t.status_of(peer)
        wall = {k: round(v / rate, 1) for k, v in s["latency_ms"].items()}
        print(f"input at {30 * rate:.0f} Hz, receive buffer {buffer_mb} MB: {s['received']} of {frames} images received "
              f"(DDS reports {s['dds_lost']:.0f} lost), {s['fused']} fused, {s['dropped']} dropped, {s['late']} late; "
              f"latency stamp->map median {wall['median']} ms, p95 {wall['p95']} ms; perception {s['perception_ms']['median']} ms, "
              f"fusion {s['fusion_ms']['median']} ms; GridMap median {s['grid_map_ms']['median']} ms, p95 {s['grid_map_ms']['p95']} ms")
        peer.stop()
        node.send_signal(2)
        node.wait()
        log.close()


if __name__ == "__main__":
    main()
