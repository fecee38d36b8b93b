"""Map queries from Python against the C++ API's answers (through `mobmap query`), and
the checks of what numpy hands in."""

import json
import subprocess

import numpy as np
import pytest

import mobmap
from conftest import EXE, run


def cli_points(map_path, points, *options):
    lines = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in points)
    return [json.loads(line) for line in run("query", map_path, "--json", *options, stdin=lines).splitlines()]


def corridor_points(n, seed):
    """Half at the floor's voxel centres (z = 0.01), half anywhere in the corridor's box."""
    rng = np.random.default_rng(seed)
    z = np.where(np.arange(n) % 2 == 0, 0.01, rng.uniform(-0.1, 0.7, n))
    return np.column_stack([rng.uniform(0.5, 4.0, n), rng.uniform(-1.6, 1.6, n), z])


def test_point_queries_equal_the_cli(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    pts = corridor_points(400, 1)
    got = m.query(pts)
    want = cli_points(corridor["map"], pts)
    names = {"unknown": mobmap.UNKNOWN, "free": mobmap.FREE, "surface": mobmap.SURFACE}
    assert sum(w["state"] == "surface" for w in want) > 20  # the sample hits surfaces
    for i, w in enumerate(want):
        assert got["state"][i] == names[w["state"]]
        assert got["count"][i] == w["count"]
        if w["mobility"] is None:
            assert np.isnan(got["mobility"][i]) and np.isinf(got["variance"][i])
        else:
            assert got["mobility"][i] == w["mobility"]
            assert got["variance"][i] == w["variance"]
        np.testing.assert_array_equal(got["voxel_centre"][i], w["voxel_centre"])


def test_snapped_queries_equal_the_cli(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    pts = corridor_points(200, 2)
    got = m.query(pts, snap=0.5)
    want = cli_points(corridor["map"], pts, "--snap", 0.5)
    for i, w in enumerate(want):
        found = w.get("state", "unknown") == "surface"
        assert (got["state"][i] == mobmap.SURFACE) == found, w
        if found:
            assert got["mobility"][i] == w["mobility"]
            np.testing.assert_array_equal(got["voxel_centre"][i], w["voxel_centre"])


def test_footprints_equal_the_cli(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    rng = np.random.default_rng(3)
    n = 60
    soles = np.column_stack([rng.uniform(0.8, 3.5, n), rng.uniform(-1.2, 1.2, n), np.full(n, 0.02),
                             rng.uniform(-3, 3, n), np.full(n, 0.25), np.full(n, 0.12)])
    got = m.footprint(soles)
    lines = "".join(" ".join(repr(v) for v in s) + "\n" for s in soles)
    want = [json.loads(line) for line in run("query", corridor["map"], "--feet", "--json", stdin=lines).splitlines()]
    for i, w in enumerate(want):
        assert got["min_mobility"][i] == w["min_mobility"]
        assert got["mean_mobility"][i] == w["mean_mobility"]
        assert got["known_fraction"][i] == w["known_fraction"]
        assert got["max_height_difference"][i] == w["max_height_difference_m"]
        if w.get("support_plane"):
            assert got["support_height"][i] == pytest.approx(w["support_plane"]["point"][2], abs=1e-12)
        else:
            assert np.isnan(got["support_height"][i])


def test_world_frame_queries_go_through_the_map_frame(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    pts = corridor_points(50, 4)
    world = m.map_to_world(pts)
    np.testing.assert_allclose(m.world_to_map(world), pts, atol=1e-12)
    a, b = m.query(pts), m.query(world, frame="world")
    np.testing.assert_array_equal(a["state"], b["state"])
    np.testing.assert_array_equal(a["count"], b["count"])
    np.testing.assert_allclose(m.world_to_map(b["voxel_centre"]), a["voxel_centre"], atol=1e-9)


def test_a_saved_map_reads_back_the_same(corridor, tmp_path):
    m = mobmap.open_map(str(corridor["map"]))
    out = tmp_path / "copy.ot"
    m.save(str(out))
    assert out.read_bytes() == corridor["map"].read_bytes()
    again = mobmap.open_map(str(out))
    pts = corridor_points(100, 5)
    for key in ("state", "count", "voxel_centre"):
        np.testing.assert_array_equal(again.query(pts)[key], m.query(pts)[key])
    info = again.info()
    assert info["resolution_m"] == 0.02 and info["nodes"] == m.info()["nodes"]
    json.loads((tmp_path / "copy.json").read_text())  # MAP.json beside it
    with pytest.raises(ValueError, match="must end in .ot"):
        m.save(str(tmp_path / "copy.bt"))


@pytest.mark.parametrize("bad, message", [
    (np.zeros((5, 2)), r"shape \(N, 3\), got \(5, 2\)"),
    (np.zeros(3), r"shape \(N, 3\), got \(3,\)"),
    (np.array([["a", "b", "c"]]), "numeric array"),
    (np.zeros((2, 3), dtype=complex), "numeric array"),
])
def test_arrays_of_the_wrong_shape_or_dtype_are_value_errors(corridor, bad, message):
    m = mobmap.open_map(str(corridor["map"]))
    with pytest.raises(ValueError, match=message):
        m.query(bad)
    with pytest.raises(ValueError):
        m.footprint(np.zeros((3, 5)))
    with pytest.raises(ValueError, match='frame must be "map" or "world"'):
        m.query(np.zeros((1, 3)), frame="camera")


def test_a_missing_map_is_an_os_error_naming_the_file(tmp_path):
    with pytest.raises(OSError, match="nothing.ot"):
        mobmap.open_map(str(tmp_path / "nothing.ot"))


@pytest.mark.parametrize("length, width", [(0.0, 0.12), (-0.25, 0.12), (np.nan, 0.12), (np.inf, 0.12), (100.0, 100.0),
                                           (0.25, 10.5)])
def test_unusable_soles_are_value_errors_as_in_the_cli(corridor, length, width):
    m = mobmap.open_map(str(corridor["map"]))
    soles = np.array([[2.0, 0.0, 0.02, 0.0, 0.25, 0.12], [2.0, 0.0, 0.02, 0.0, length, width]])
    with pytest.raises(ValueError, match=r"soles\[1\]"):
        m.footprint(soles)
    # The CLI refuses the same sole.
    r = subprocess.run([EXE, "query", str(corridor["map"]), "--foot", "2", "0", "0.02", "0", repr(length), repr(width)],
                       capture_output=True, text=True)
    assert r.returncode != 0


def test_a_sole_that_is_not_finite_is_a_value_error(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    with pytest.raises(ValueError, match="not finite"):
        m.footprint(np.array([[2.0, np.nan, 0.02, 0.0, 0.25, 0.12]]))


def test_a_map_json_nested_past_the_limit_is_an_os_error_naming_it(corridor, tmp_path):
    # 100,000 nested objects under a key nobody reads recursed past the stack on copy.
    (tmp_path / "deep.ot").write_bytes(corridor["map"].read_bytes())
    meta = json.loads((corridor["dir"] / "map.json").read_text())
    text = json.dumps(meta)[:-1] + ', "extra": ' + '{"a": ' * 100000 + "1" + "}" * 100000 + "}"
    (tmp_path / "deep.json").write_text(text)
    with pytest.raises(OSError, match=r"deep\.json.*nested more than 64 deep"):
        mobmap.open_map(str(tmp_path / "deep.ot"))


def column_scan(m, poses, size, resolution, clearance):
    """Height scans the slow way, from Map.query: each grid point's column of voxels from
    30 above the clearance's voxel down to the bottom of the map, the first occupied voxel
    at or below the clearance above the pose, the top of its run (no higher than that) and the run's highest
    mobility going down from that top."""
    res = m.resolution
    nx, ny = round(size[0] / resolution) + 1, round(size[1] / resolution) + 1
    bottom = m.info()["bounds_min"][2]
    height = np.full((len(poses), ny, nx), np.nan)
    mobility = np.full((len(poses), ny, nx), np.nan)
    for p, (x, y, z, yaw) in enumerate(poses):
        kz = int(np.floor((z + clearance) / res))
        levels = np.arange(kz + 30, int(np.floor(bottom / res)) - 1, -1)  # highest first
        gx, gy = np.meshgrid((np.arange(nx) - (nx - 1) / 2) * resolution, (np.arange(ny) - (ny - 1) / 2) * resolution)
        px, py = x + np.cos(yaw) * gx - np.sin(yaw) * gy, y + np.sin(yaw) * gx + np.cos(yaw) * gy
        pts = np.column_stack([np.repeat(px.ravel(), len(levels)), np.repeat(py.ravel(), len(levels)),
                               np.tile((levels + 0.5) * res, px.size)])
        q = m.query(pts)
        occupied = (q["state"] == mobmap.SURFACE).reshape(px.size, len(levels))
        mob = q["mobility"].reshape(px.size, len(levels))
        for g in range(px.size):
            below = np.nonzero(occupied[g] & (levels <= kz))[0]
            if len(below) == 0:
                continue
            top = below[0]
            while top > 0 and occupied[g, top - 1]:
                top -= 1
            height.flat[p * px.size + g] = min((levels[top] + 1) * res, z + clearance) - z
            for k in range(top, len(levels)):
                if not occupied[g, k]:
                    break
                if not np.isnan(mob[g, k]):
                    mobility.flat[p * px.size + g] = mob[g, k]
                    break
    return height, mobility


def test_height_scans_equal_a_column_search_through_point_queries(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    rng = np.random.default_rng(54)
    n = 12
    # Bases 0.3-0.6 m above the floor anywhere in the corridor (over ramps, the box and the
    # stairs), facing anywhere.
    poses = np.column_stack([rng.uniform(0.5, 4.5, n), rng.uniform(-1.6, 1.6, n), rng.uniform(0.3, 0.6, n),
                             rng.uniform(-np.pi, np.pi, n)])
    for size, resolution, clearance in (((1.6, 1.0), 0.1, None), ((0.3, 0.2), 0.02, 0.0), ((1.6, 1.0), 0.1, 0.25)):
        if clearance is None:  # the default: the layers' robot height
            got, clearance = m.height_scan(poses, size=size, resolution=resolution), 1.0
        else:
            got = m.height_scan(poses, size=size, resolution=resolution, clearance=clearance)
        want_h, want_m = column_scan(m, poses, size, resolution, clearance)
        assert got["height"].dtype == np.float32 and got["height"].shape == want_h.shape
        assert np.isfinite(want_h).sum() > want_h.size // 3  # the poses see ground
        np.testing.assert_allclose(got["height"], want_h, atol=1e-6)  # float32 of the same double
        np.testing.assert_array_equal(np.isnan(got["mobility"]), np.isnan(want_m))
        np.testing.assert_allclose(got["mobility"], want_m, atol=1e-6)
    # The default grid is legged_gym's: 17 x 11 points.
    assert m.height_scan(poses[:2])["height"].shape == (2, 11, 17)


def test_height_scans_in_the_world_frame_go_through_the_map_frame(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    pts = corridor_points(40, 6)
    pts[:, 2] += 0.4
    poses = np.column_stack([pts, np.zeros(len(pts))])
    world = np.column_stack([m.map_to_world(pts), np.zeros(len(pts))])
    a = m.height_scan(poses, size=(0, 0))
    b = m.height_scan(world, size=(0, 0), frame="world")
    np.testing.assert_allclose(a["height"], b["height"], atol=1e-5)
    np.testing.assert_array_equal(np.isnan(a["mobility"]), np.isnan(b["mobility"]))


@pytest.mark.parametrize("poses, kwargs, message", [
    (np.zeros((2, 3)), {}, r"shape \(N, 4\)"),
    (np.array([[1.0, np.nan, 0.3, 0.0]]), {}, r"poses\[0\].*not finite"),
    (np.zeros((1, 4)), {"resolution": 0.0}, "resolution"),
    (np.zeros((1, 4)), {"size": (-1.0, 1.0)}, "size"),
    (np.zeros((1, 4)), {"size": (1e9, 1.0)}, "points"),
    (np.zeros((40000, 4)), {"size": (10.0, 10.0), "resolution": 0.01}, "batches"),
])
def test_unusable_height_scans_are_value_errors(corridor, poses, kwargs, message):
    m = mobmap.open_map(str(corridor["map"]))
    with pytest.raises(ValueError, match=message):
        m.height_scan(poses, **kwargs)


def test_no_pose_is_an_empty_scan(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    assert m.height_scan(np.zeros((0, 4)))["height"].shape == (0, 11, 17)


def test_layers_equal_a_column_search_through_point_queries(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    res = m.resolution
    got = m.layers()
    assert got["level"] == 0 and got["cell"] == res and len(got["levels"]) >= 1
    level_top = got["levels"][0]["z_m"] + 1.0  # a robot 1 m tall fits under nothing lower
    rows, cols = got["elevation"].shape
    assert got["elevation"].dtype == np.float32 and rows > 50 and cols > 50
    for name in ("elevation_variance", "mobility", "mobility_variance", "step", "slope_deg", "known"):
        assert got[name].shape == (rows, cols)
    lo, hi = m.info()["bounds_min"][2], m.info()["bounds_max"][2]
    ks = np.arange(int(np.floor(hi / res)), int(np.floor(lo / res)) - 1, -1)  # voxel keys, highest first
    checked = 0
    for r in range(0, rows, 5):
        for c in range(0, cols, 5):
            x, y = got["x_min"] + (c + 0.5) * res, got["y_min"] + (rows - r - 0.5) * res
            q = m.query(np.column_stack([np.full(len(ks), x), np.full(len(ks), y), (ks + 0.5) * res]))
            occupied = q["state"] == mobmap.SURFACE
            want = np.nan
            k = 0
            while k < len(ks):  # runs from the top down: the first whose bottom lies below the band's top
                if not occupied[k]:
                    k += 1
                    continue
                top = k
                while k + 1 < len(ks) and occupied[k + 1]:
                    k += 1
                if ks[k] * res < level_top - 1e-9:
                    want = (ks[top] + 1) * res
                    break
                k += 1
            e = got["elevation"][r, c]
            assert np.isnan(e) == np.isnan(want), (x, y, e, want)
            if not np.isnan(want):
                assert e == np.float32(want), (x, y, e, want)
                checked += 1
    assert checked > 300


def test_layers_of_a_level_the_map_has_not_are_value_errors(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    with pytest.raises(ValueError, match="levels"):
        m.layers(level=7)
    with pytest.raises(ValueError, match="cell size"):
        m.layers(cell=0.001)
    with pytest.raises(ValueError, match="clearance"):
        m.layers(clearance=0.0)
