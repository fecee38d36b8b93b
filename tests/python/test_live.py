"""LiveMapper from Python: the same map as `mobmap build`, queries from another thread
while frames go in, and one frame through the pipeline as `mobmap analyze` scores it."""

import json
import threading

import numpy as np
import pytest

import mobmap
from conftest import run


def millimetres(depth_m):
    """float32 metres read from a 16-bit PNG, back to its uint16 millimetres."""
    return np.round(depth_m.astype(np.float64) * 1000.0).astype(np.uint16)


def test_a_live_map_saves_the_bytes_mobmap_build_writes(corridor, tmp_path):
    frames = mobmap.open_recording(str(corridor["seq"]))
    assert frames.format == "7-Scenes layout" and len(frames) == 30
    mapper = mobmap.LiveMapper(gravity_down_world=frames.gravity_down)
    for i, frame in enumerate(frames):
        mapper.push(frame["depth"], frame["intrinsics"], frame["pose"], stamp=i / 30.0)
    mapper.finish()
    assert mapper.stats()["fused"] == 30
    out = tmp_path / "live.ot"
    mapper.snapshot().save(str(out))
    assert out.read_bytes() == corridor["map"].read_bytes()
    saved = mobmap.open_map(str(out))
    assert saved.info()["frames"] == 30
    # Height scans of the snapshot are those of the saved map.
    poses = np.array([[1.5, 0.0, 0.45, 0.0], [2.5, 0.6, 0.45, 2.0], [3.2, -0.5, 0.6, -1.0]])
    live, disk = mapper.snapshot().height_scan(poses), saved.height_scan(poses)
    assert np.isfinite(disk["height"]).sum() > 100
    for key in ("height", "mobility"):
        np.testing.assert_array_equal(live[key], disk[key])


def test_a_thread_queries_while_another_pushes(corridor):
    frames = mobmap.open_recording(str(corridor["seq"]))
    mapper = mobmap.LiveMapper(gravity_down_world=frames.gravity_down)
    pts = np.column_stack([np.linspace(0.8, 3.5, 200), np.zeros(200), np.full(200, 0.01)])
    done = threading.Event()
    seen = []
    errors = []

    def reader():
        try:
            while True:  # at least one round, then until the pushing thread is done
                last = done.is_set()
                snap = mapper.snapshot()
                seen.append(int(np.sum(snap.query(pts)["state"] == mobmap.SURFACE)))
                if last:
                    return
        except Exception as e:  # reported by the main thread
            errors.append(e)

    t = threading.Thread(target=reader)
    t.start()
    for frame in frames:  # depth as uint16 millimetres here
        mapper.push(millimetres(frame["depth"]), frame["intrinsics"], frame["pose"])
    mapper.finish()
    done.set()
    t.join()
    assert not errors, errors
    assert len(seen) >= 1
    final = mapper.snapshot().query(pts)
    assert seen[-1] == int(np.sum(final["state"] == mobmap.SURFACE)) > 50


def test_bad_frames_are_value_errors(corridor):
    mapper = mobmap.LiveMapper()
    k = (585.0, 585.0, 320.0, 240.0)
    with pytest.raises(ValueError, match="uint16 .* or float32"):
        mapper.push(np.zeros((480, 640), dtype=np.int64), k, np.eye(4))
    with pytest.raises(ValueError, match="2-D image"):
        mapper.push(np.zeros((480, 640, 3), dtype=np.uint16), k, np.eye(4))
    with pytest.raises(ValueError, match="4x4"):
        mapper.push(np.zeros((480, 640), dtype=np.uint16), k, np.eye(3))
    bent = np.eye(4)
    bent[0, 1] = 0.5
    with pytest.raises(ValueError, match="T_world_camera"):
        mapper.push(np.zeros((480, 640), dtype=np.uint16), k, bent)
    with pytest.raises(ValueError, match="four numbers"):
        mapper.push(np.zeros((480, 640), dtype=np.uint16), (585.0, 585.0), np.eye(4))
    with pytest.raises(TypeError, match="unexpected keyword argument 'gravity'"):
        mobmap.LiveMapper(gravity=(0, 0, -1))


def test_analyze_scores_a_frame_as_mobmap_analyze_does(corridor):
    frames = mobmap.open_recording(str(corridor["seq"]))
    frame = frames[5]
    gravity_camera = frame["pose"][:3, :3].T @ np.array(frames.gravity_down)
    got = mobmap.analyze(frame["depth"], frame["intrinsics"], gravity=gravity_camera)
    want = json.loads(run("analyze", corridor["seq"], "--frame", 5, "--json"))
    segs = got["segments"]
    assert len(segs["points"]) == len(want["segments"]) > 3
    for i, w in enumerate(want["segments"]):
        assert segs["points"][i] == w["points"]
        assert segs["is_ground"][i] == w["is_ground"]
        assert segs["slope_deg"][i] == pytest.approx(w["slope_deg"], abs=1e-6)
        assert segs["roughness"][i] == pytest.approx(w["roughness"], abs=1e-6)
        assert segs["mobility"][i] == pytest.approx(w["mobility"], abs=1e-6)
    image = got["segment_image"]
    assert image.shape == (480, 640)
    assert set(np.unique(image)) <= set(range(-1, len(segs["points"])))
    # Each segment covers at least as many pixels as it has voxel points.
    counts = np.bincount(image[image >= 0].ravel(), minlength=len(segs["points"]))
    assert np.all(counts >= segs["points"])


@pytest.mark.parametrize("threads", [0, -1, 257, 100000])
def test_a_thread_count_out_of_range_is_a_value_error(threads):
    with pytest.raises(ValueError, match=r"perception_threads must be in \[1, 256\]"):
        mobmap.LiveMapper(perception_threads=threads)


@pytest.mark.parametrize("origin", [(1e300, 0, 0), (0, 0, 2e8), (np.nan, 0, 0)])
def test_an_origin_that_is_not_in_metres_is_a_value_error(origin):
    with pytest.raises(ValueError, match="origin_world"):
        mobmap.LiveMapper(origin_world=origin)
