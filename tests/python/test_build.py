"""mobmap.build against `mobmap build`: the same options give the same files, byte for byte
(MAP.json but for the run's timing), on a 7-Scenes folder, a bag whose camera hangs on a
robot's TF tree with gravity from its IMU, and a run whose given gravity is refined to the
floor; and the library's errors name Python's keywords."""

import json
import os
import shutil
import subprocess

import pytest

import mobmap
from conftest import run

HERE = os.path.dirname(os.path.abspath(__file__))
RECORDINGS = os.path.join(HERE, "..", "recordings")


def same_map(a, b):
    """The two maps' files are the same bytes, and their MAP.json the same but for timing."""
    for suffix in (".ot", ".bt", ".octovis.ot"):
        with open(str(a)[:-3] + suffix, "rb") as fa, open(str(b)[:-3] + suffix, "rb") as fb:
            assert fa.read() == fb.read(), suffix
    untimed = []
    for path in (a, b):
        with open(str(path)[:-3] + ".json") as f:
            meta = json.load(f)
        for key in ("seconds", "frames_per_second"):
            meta.pop(key)
        untimed.append(meta)
    assert untimed[0] == untimed[1]


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    d = tmp_path_factory.mktemp("build")
    run("simulate", "--out", d / "seq", "--frames", 12, "--quiet")
    return d


def test_a_seven_scenes_folder_gives_the_clis_bytes(sequence):
    run("build", sequence / "seq", "--out", sequence / "cli.ot", "--frames", "0:7:2", "-q")
    lines = []
    report = mobmap.build(str(sequence / "seq"), out=str(sequence / "py.ot"), frames="0:7:2",
                          progress=lambda done, total: lines.append((done, total)))
    same_map(sequence / "cli.ot", sequence / "py.ot")
    assert report["written"] and report["frames_fused"] == 4 and report["frames_selected"] == 4
    assert lines[-1] == (4, 4) and all(t == 4 for _, t in lines)
    assert report["gravity_source"].startswith("gravity-direction.txt")


def test_extrinsics_and_a_depth_scale_give_the_clis_bytes(sequence):
    # The camera 5 cm ahead of and turned 2 degrees about x on the posed body, depth read
    # 1 % further than stored.
    extrinsics = "0.05,0,0.02,0.0174524064372835,0,0,0.999847695156391"
    run("build", sequence / "seq", "--out", sequence / "cli-x.ot", "--frames", "0:5", "--extrinsics", extrinsics,
        "--depth-scale", 990, "-q")
    mobmap.build(str(sequence / "seq"), out=str(sequence / "py-x.ot"), frames="0:5",
                 extrinsics=[float(v) for v in extrinsics.split(",")], depth_scale=990)
    same_map(sequence / "cli-x.ot", sequence / "py-x.ot")


def test_a_given_gravity_refined_to_the_floor_gives_the_clis_bytes(sequence):
    # Two degrees off the corridor's floor: refined to it (MAP.json records both).
    run("build", sequence / "seq", "--out", sequence / "cli-g.ot", "--gravity", "0.035,0,-1", "-q")
    report = mobmap.build(str(sequence / "seq"), out=str(sequence / "py-g.ot"), gravity=(0.035, 0, -1))
    same_map(sequence / "cli-g.ot", sequence / "py-g.ot")
    assert "refined to the floor" in report["gravity_source"]
    assert report["gravity_source"].startswith("`gravity`")


@pytest.mark.skipif(shutil.which("node") is None or not os.path.isdir(os.path.join(RECORDINGS, "node_modules")),
                    reason="node and tests/recordings' npm packages write the bag (scripts/setup.sh installs them)")
def test_a_bag_on_a_robots_tf_tree_with_imu_gravity_gives_the_clis_bytes(sequence):
    bag = sequence / "robot.mcap"
    subprocess.run(["node", os.path.join(RECORDINGS, "write_bag.mjs"), "--seq", str(sequence / "seq"), "--out", str(bag),
                    "--layout", "base", "--imu"], check=True, capture_output=True)
    run("build", bag, "--out", sequence / "cli-bag.ot", "--imu-topic", "/camera/imu", "-q")
    report = mobmap.build(str(bag), out=str(sequence / "py-bag.ot"), imu_topic="/camera/imu")
    same_map(sequence / "cli-bag.ot", sequence / "py-bag.ot")
    assert "the IMU on /camera/imu" in report["gravity_source"]


def test_errors_name_the_keywords(sequence):
    with pytest.raises(ValueError, match=r"`max_range_m` is 0.1 \(must be finite and > min_range_m\)") as e:
        mobmap.build(str(sequence / "seq"), out=str(sequence / "bad.ot"), max_range_m=0.1)
    assert "--" not in str(e.value)
    with pytest.raises(ValueError, match="`out` must end in .ot"):
        mobmap.build(str(sequence / "seq"), out=str(sequence / "bad.map"))
    with pytest.raises(ValueError, match="`force` overwrites it"):
        mobmap.build(str(sequence / "seq"), out=str(sequence / "py.ot"))
    with pytest.raises(TypeError, match="unexpected keyword argument 'max_range'"):
        mobmap.build(str(sequence / "seq"), out=str(sequence / "bad.ot"), max_range=2)
    assert not os.path.exists(sequence / "bad.ot")
