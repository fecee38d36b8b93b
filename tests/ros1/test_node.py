"""mobmap_node against a real ROS 1 master: roscore on a free loopback port, the node
started by roslaunch with the repository's launch file, the simulated corridor played by
`rosbag play`, and this process listening as any other ROS node would.

Oracles: `mobmap build` of the same bag (mobility), the corridor's exact geometry
(elevation, free floor, the 45-degree ramp), upstream's MD5 sums of grid_map_msgs/GridMap
and octomap_msgs/Octomap, OctoMap's own reader, `mobmap info`. Nothing waits on a clock:
each step waits for what the node reports (its status topic, a message stamped with the
newest frame fused); the generous limits only turn a hang into a failure.
"""
import json
import os
import signal
import socket
import struct
import subprocess

import numpy as np
import pytest

rospy = pytest.importorskip("rospy", reason="rospy (python3-rospy) is not installed")
from std_msgs.msg import String  # noqa: E402
from nav_msgs.msg import OccupancyGrid  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

import mobmap  # noqa: E402
from node_checks import HANG, wait_for, VOXEL, check_cloud, check_elevation, check_occupancy  # noqa: E402

EXE = os.environ["MOBMAP_EXE"]
NODE = os.environ["MOBMAP_NODE"]
WRITE_BAG1 = os.environ["MOBMAP_WRITE_BAG1"]
READ_OCTOMAP = os.environ["MOBMAP_READ_OCTOMAP"]
FRAMES = 240
# Upstream's MD5 sums (the ROS 1 message definitions of grid_map_msgs and octomap_msgs).
GRID_MAP_MD5 = "95681e052b1f73bf87b7eb984382b401"
OCTOMAP_MD5 = "9a45536b45c5e409cd49f04bb2d9999f"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Latest:
    """The messages of a topic as they arrive, raw (AnyMsg) or typed."""

    def __init__(self, topic, kind=rospy.AnyMsg):
        self.messages = []
        self.sub = rospy.Subscriber(topic, kind, self.messages.append, queue_size=50)

    def last(self):
        return self.messages[-1] if self.messages else None


class Reader:
    """ROS 1 serialisation, read by hand (little endian)."""

    def __init__(self, data):
        self.b, self.at = data, 0

    def take(self, fmt):
        v = struct.unpack_from("<" + fmt, self.b, self.at)
        self.at += struct.calcsize("<" + fmt)
        return v if len(v) > 1 else v[0]

    def string(self):
        n = self.take("I")
        s = self.b[self.at:self.at + n].decode()
        self.at += n
        return s

    def header(self):
        seq, sec, nsec = self.take("III")
        return {"stamp_ns": sec * 1_000_000_000 + nsec, "frame_id": self.string()}


def parse_grid_map(data):
    r = Reader(data)
    info = {"header": r.header(), "resolution": r.take("d"), "length_x": r.take("d"), "length_y": r.take("d"),
            "position": r.take("ddd"), "orientation": r.take("dddd")}
    layers = [r.string() for _ in range(r.take("I"))]
    basic = [r.string() for _ in range(r.take("I"))]
    arrays = []
    for _ in range(r.take("I")):
        dims = [(r.string(), r.take("I"), r.take("I")) for _ in range(r.take("I"))]
        r.take("I")  # data_offset
        n = r.take("I")
        arrays.append((dims, np.frombuffer(data, dtype="<f4", count=n, offset=r.at).copy()))
        r.at += 4 * n
    outer, inner = r.take("HH")
    return {"info": info, "layers": layers, "basic_layers": basic, "data": arrays, "outer": outer, "inner": inner,
            "size": len(data), "read": r.at}


def parse_octomap(data):
    r = Reader(data)
    m = {"header": r.header(), "binary": r.take("B"), "id": r.string(), "resolution": r.take("d")}
    n = r.take("I")
    m["data"] = bytes(data[r.at:r.at + n])
    m["rest"] = len(data) - r.at - n
    return m


def parse_cloud(data):
    """sensor_msgs/PointCloud2 with float32 fields -> dict of arrays."""
    r = Reader(data)
    header = r.header()
    height, width = r.take("II")
    fields = []
    for _ in range(r.take("I")):
        name = r.string()
        offset, datatype, count = r.take("IBI")
        fields.append((name, offset, datatype, count))
    big, point_step, row_step = r.take("BII")
    n = r.take("I")
    raw = np.frombuffer(data, dtype=np.uint8, count=n, offset=r.at)
    out = {"header": header, "width": width, "height": height, "fields": [f[0] for f in fields]}
    for name, offset, datatype, count in fields:
        assert datatype == 7 and count == 1  # FLOAT32
        out[name] = raw.reshape(-1, point_step)[:, offset:offset + 4].copy().view("<f4").ravel()
    return out


def status_of(latest):
    m = latest.last()
    return json.loads(m.data) if m is not None else None


def accounted(s, frames):
    return s and s["received"] >= frames and s["fused"] + s["dropped"] + s["late"] + s["unreadable"] >= frames


@pytest.fixture(scope="module")
def ros(tmp_path_factory):
    """roscore, the corridor's bag, its `mobmap build` map, the node by roslaunch, this
    process as a ROS node, and the bag played at a quarter of real time."""
    tmp = tmp_path_factory.mktemp("ros1")
    port = free_port()
    env = dict(os.environ, ROS_IP="127.0.0.1", ROS_HOSTNAME="127.0.0.1", ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_HOME=str(tmp / "ros_home"), ROS_LOG_DIR=str(tmp / "ros_log"),
               ROS_PACKAGE_PATH=os.environ["MOBMAP_ROS_PACKAGE_PATH"], PYTHONUNBUFFERED="1")
    os.environ.update({k: env[k] for k in ("ROS_IP", "ROS_HOSTNAME", "ROS_MASTER_URI", "ROS_HOME", "ROS_LOG_DIR")})
    seq, bag = tmp / "corridor", tmp / "corridor.bag"
    subprocess.run([EXE, "simulate", "--out", str(seq), "--frames", str(FRAMES), "-q"], check=True)
    subprocess.run([WRITE_BAG1, "--seq", str(seq), "--out", str(bag), "--layout", "base", "--world", "map"], check=True)
    subprocess.run([EXE, "build", str(bag), "--out", str(tmp / "built" / "corridor.ot"), "-q"], check=True)
    procs = []
    logs = []

    def start(args, name):
        log = open(tmp / (name + ".log"), "w")
        logs.append(log)
        p = subprocess.Popen(args, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(p)
        return p

    try:
        start(["roscore", "-p", str(port)], "roscore")
        import rosgraph

        wait_for("the master", lambda: rosgraph.Master("/test").is_online())
        rospy.set_param("/use_sim_time", True)
        rospy.init_node("mobmap_test", anonymous=True, disable_signals=True)
        status = Latest("/mobmap/status", String)
        outputs = {"cloud": Latest("/mobmap/mobility_cloud"), "grid_map": Latest("/mobmap/elevation_map"),
                   "octomap": Latest("/mobmap/octomap_binary"), "occupancy": Latest("/mobmap/occupancy", OccupancyGrid)}
        launch = start(["roslaunch", "--wait", "mobmap", "mobmap.launch", "depth:=/camera/depth/image_raw",
                        "camera_info:=/camera/depth/camera_info", f"save_on_exit:={tmp / 'exit' / 'corridor.ot'}"], "roslaunch")
        wait_for("the node's first status", lambda: status.last() is not None)
        # Every output's subscription is connected before the first frame is played.
        wait_for("the node to see the listeners", lambda: all(o.sub.get_num_connections() > 0 for o in outputs.values()))
        subprocess.run(["rosbag", "play", "-q", "--clock", "-r", "0.25", str(bag)], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        final = wait_for("every frame to be accounted for", lambda: accounted(status_of(status), FRAMES) and status_of(status))
        yield {"tmp": tmp, "env": env, "status": status, "final": final, "outputs": outputs, "launch": launch,
               "built": tmp / "built" / "corridor.ot", "bag": bag, "start": start}
    finally:
        rospy.signal_shutdown("done")
        for p in reversed(procs):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(60)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
        for log in logs:
            log.close()


def final_message(ros, name):
    """The output's message stamped with the newest frame fused."""
    stamp = ros["final"]["map_stamp_ns"]
    latest = ros["outputs"][name]

    def stamped():
        for m in reversed(latest.messages):
            if name == "occupancy":
                got = m.header.stamp.to_nsec()
            else:
                raw = m._buff if hasattr(m, "_buff") else None
                got = Reader(raw).header()["stamp_ns"] if name != "grid_map" else parse_grid_map(raw)["info"]["header"]["stamp_ns"]
            if got == stamp:
                return m
        return None

    return wait_for(f"the {name} of the final map", stamped)


def test_frames_are_fused_and_reported(ros):
    s = ros["final"]
    assert s["world_frame"] == "map"
    assert s["received"] == FRAMES
    assert s["unreadable"] == 0
    assert s["fused"] >= FRAMES // 4, s  # a quarter of real time leaves the node time for most frames
    assert s["map_frames"] == s["fused"]
    assert s["latency_ms"]["median"] is not None and s["latency_ms"]["median"] > 0


def test_the_cloud_agrees_with_mobmap_build(ros):
    m = final_message(ros, "cloud")
    assert m._connection_header["type"] == "sensor_msgs/PointCloud2"
    c = parse_cloud(m._buff)
    assert c["fields"] == ["x", "y", "z", "mobility", "variance"]
    assert c["header"]["frame_id"] == "map"
    check_cloud(c, mobmap.open_map(str(ros["built"])), seed=67)


def test_the_occupancy_grid_has_the_floor_free_and_the_45_degree_ramp_occupied(ros):
    g = final_message(ros, "occupancy")
    info = g.info
    assert g.header.frame_id == "map"
    data = np.array(g.data, dtype=np.int16).reshape(info.height, info.width)
    check_occupancy(data, info.origin.position.x, info.origin.position.y, info.resolution)


def test_the_elevation_map_is_upstreams_grid_map_and_matches_the_corridor(ros):
    m = final_message(ros, "grid_map")
    assert m._connection_header["type"] == "grid_map_msgs/GridMap"
    assert m._connection_header["md5sum"] == GRID_MAP_MD5
    g = parse_grid_map(m._buff)
    assert g["read"] == g["size"]
    assert g["layers"] == ["elevation", "mobility", "step", "slope", "variance"]
    info = g["info"]
    assert info["header"]["frame_id"] == "map"
    n = int(round(info["length_x"] / info["resolution"]))
    assert n == 100 and int(round(info["length_y"] / info["resolution"])) == 100
    dims, elevation = g["data"][0]
    assert [d[0] for d in dims] == ["column_index", "row_index"] and elevation.size == n * n
    # grid_map's order: column-major, index (0, 0) at the largest x and y.
    cx, cy = info["position"][0], info["position"][1]
    res = info["resolution"]
    check_elevation(elevation, n, cx, cy, res)


def test_the_octomap_is_upstreams_and_loads_with_octomaps_reader(ros):
    m = final_message(ros, "octomap")
    assert m._connection_header["type"] == "octomap_msgs/Octomap"
    assert m._connection_header["md5sum"] == OCTOMAP_MD5
    o = parse_octomap(m._buff)
    assert o["rest"] == 0 and o["binary"] == 1 and o["id"] == "OcTree"
    assert o["header"]["frame_id"] == "mobmap_map"
    path = ros["tmp"] / "octomap.bin"
    path.write_bytes(o["data"])
    read = json.loads(subprocess.run([READ_OCTOMAP, str(path), str(o["resolution"])], check=True, capture_output=True,
                                     text=True).stdout)
    cloud = parse_cloud(final_message(ros, "cloud")._buff)
    # The same map: one cloud point per occupied voxel.
    assert read["occupied_voxels"] == cloud["width"]


def test_the_save_service_writes_a_map_mobmap_info_reads(ros):
    target = ros["tmp"] / "saved" / "live.ot"
    rospy.set_param("/mobmap/save_path", str(target))
    rospy.wait_for_service("/mobmap/save_map", timeout=HANG)
    answer = rospy.ServiceProxy("/mobmap/save_map", Trigger)()
    assert answer.success, answer.message
    for suffix in (".ot", ".bt", ".octovis.ot", ".json"):
        assert (target.parent / ("live" + suffix)).is_file()
    info = subprocess.run([EXE, "info", str(target), "--json"], check=True, capture_output=True, text=True)
    assert json.loads(info.stdout)["metadata"]["frames"] == ros["final"]["map_frames"]


def test_sigint_saves_a_complete_map(ros):
    launch = ros["launch"]
    os.killpg(launch.pid, signal.SIGINT)
    assert launch.wait(HANG) == 0
    exit_map = ros["tmp"] / "exit" / "corridor.ot"
    info = subprocess.run([EXE, "info", str(exit_map), "--json"], check=True, capture_output=True, text=True)
    assert json.loads(info.stdout)["metadata"]["frames"] == ros["final"]["map_frames"]
    assert not list((ros["tmp"] / "exit").glob("*.tmp*"))


def rss_kb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0


def test_played_fast_frames_are_dropped_and_counted_and_memory_stays_flat(ros):
    """A second node, started directly with ROS's own arguments and serve's HTTP API on a
    free port, fed an image it cannot read, then the bag at 2x and at 4x four times (no
    sim time: the stamps are the bag's)."""
    from sensor_msgs.msg import Image
    import urllib.request

    rospy.set_param("/use_sim_time", False)
    status = Latest("/soak/status", String)
    node = ros["start"]([NODE, "__name:=soak", "depth:=/camera/depth/image_raw", "_grid_map_rate:=0",
                         "_status_rate:=5", "_http_port:=0"], "soak")
    wait_for("the soak node's status", lambda: status.last() is not None)
    # A colour image on the depth topic: a warning and a count, not a crash.
    pub = rospy.Publisher("/camera/depth/image_raw", Image, queue_size=1)
    wait_for("the node to take the test's images", lambda: pub.get_num_connections() > 0)
    colour = Image(height=2, width=2, encoding="rgb8", step=6, data=bytes(12))
    colour.header.frame_id = "camera_depth_optical_frame"
    pub.publish(colour)
    wait_for("the colour image to be refused", lambda: (status_of(status) or {}).get("unreadable") == 1)
    pub.unregister()
    rss, total, before = [], 1, 1

    def settled():
        # Everything the node was handed is fused, dropped, late or unreadable. (At 4x a
        # loaded machine's ROS subscriber queue may drop images before the node sees them:
        # those are ROS's, not counted here.)
        s = status_of(status)
        return s and s["received"] > before and s["fused"] + s["dropped"] + s["late"] + s["unreadable"] == s["received"] and s

    for rate in ("2", "4", "4", "4", "4"):
        subprocess.run(["rosbag", "play", "-q", "-r", rate, str(ros["bag"])], env=ros["env"], check=True,
                       stdout=subprocess.DEVNULL)
        total += FRAMES
        s = wait_for(f"the frames played at {rate}x", settled)
        before = s["received"]
        rss.append(rss_kb(node.pid))
        print(f"soak at {rate}x: {s['received']} received, {s['fused']} fused, {s['dropped']} dropped, {s['late']} late; "
              f"RSS {rss[-1] / 1024:.0f} MB")
    assert s["dropped"] > 0, "played faster than the node perceives, frames are dropped and counted"
    assert total // 2 <= s["received"] <= total
    # The same corridor again and again: the map stops growing, and so does the node.
    assert rss[-1] <= rss[1] * 1.1 + 20 * 1024, rss
    # serve's API on the live map: the frames fused so far, a height scan on the floor.
    port = rospy.get_param("/soak/http_port_bound")
    url = f"http://127.0.0.1:{port}"

    def info():
        with urllib.request.urlopen(url + "/api/info") as r:
            return json.load(r)

    wait_for("the served map to catch up", lambda: info()["frames"] == s["map_frames"])
    body = json.dumps({"poses": [[1.0, 0.0, 0.5, 0.0]], "size": [0.4, 0.4], "resolution": 0.1, "frame": "world"}).encode()
    request = urllib.request.Request(url + "/api/height_scan", data=body, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(request) as r:
        scan = json.load(r)
    heights = [h for row in scan["height"][0] for h in row if h is not None]
    assert heights and all(abs(h + 0.5) <= 2 * VOXEL for h in heights), scan  # the floor, half a metre below
    os.killpg(node.pid, signal.SIGINT)
    assert node.wait(HANG) == 0
