"""mobmap.open_recording: a bag read in Python as `mobmap build` reads it. The bag is
written by the npm registry's MCAP and CDR writers (tests/recordings), not by mobmap."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

import mobmap

FIXTURES = Path(__file__).resolve().parents[1] / "recordings"


@pytest.fixture(scope="module")
def bag(corridor):
    if not (FIXTURES / "node_modules" / "@mcap" / "core").exists():
        pytest.skip("the bag writers are not installed: run `npm ci --prefix tests/recordings` (scripts/setup.sh does)")
    out = corridor["dir"] / "corridor.mcap"
    if not out.exists():
        subprocess.run(["node", str(FIXTURES / "write_bag.mjs"), "--seq", str(corridor["seq"]), "--out", str(out),
                        "--layout", "base"], check=True)
    return out


def test_a_bag_gives_the_frames_and_poses_of_its_sequence(bag, corridor):
    rec = mobmap.open_recording(str(bag))
    assert rec.format == "ROS 2 bag (MCAP)"
    assert rec.depth_topic == "/camera/depth/image_raw"
    assert rec.world_frame == "map"
    assert rec.gravity_down == (0.0, 0.0, -1.0)
    assert len(rec) == 30 and rec.frames == list(range(30))
    assert {t["name"] for t in rec.topics} >= {"/tf", "/tf_static", "/camera/depth/camera_info"}
    folder = mobmap.open_recording(str(corridor["seq"]))  # the frames the bag was written from
    assert folder.format == "7-Scenes layout" and folder.depth_topic is None and folder.topics == []
    for frame, truth in zip(rec, folder):
        assert frame["depth"].dtype == np.float32 and frame["depth"].shape == truth["depth"].shape
        np.testing.assert_array_equal(frame["depth"], truth["depth"])
        np.testing.assert_allclose(frame["pose"], truth["pose"], atol=1e-9)
        assert frame["frame_id"] == rec.camera_frame and truth["frame_id"] is None
        assert isinstance(frame["stamp"], float) and truth["stamp"] is None
    assert rec[7]["number"] == 7


def test_a_bag_mapped_in_python_is_the_map_build_writes(bag, corridor, tmp_path):
    rec = mobmap.open_recording(str(bag))
    mapper = mobmap.LiveMapper(gravity_down_world=rec.gravity_down)
    for frame in rec:
        mapper.push(frame["depth"], frame["intrinsics"], frame["pose"], stamp=frame["stamp"])
    mapper.finish()
    out = tmp_path / "bag.ot"
    mapper.snapshot().save(str(out))
    assert out.read_bytes() == corridor["map"].read_bytes()


def test_recording_errors_name_the_file(tmp_path, bag):
    fake = tmp_path / "fake.mcap"
    fake.write_bytes(b"not an mcap")
    with pytest.raises(mobmap.RecordingError, match="fake.mcap: not an MCAP file"):
        mobmap.open_recording(str(fake))
    with pytest.raises(OSError, match="has no image topic /nothing"):
        mobmap.open_recording(str(bag), depth_topic="/nothing")
    with pytest.raises(TypeError, match="unexpected keyword argument 'depth'"):
        mobmap.open_recording(str(bag), depth="/x")
