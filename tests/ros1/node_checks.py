"""What the live nodes' tests (ROS 1 and ROS 2) share: the simulated corridor's geometry,
the judgments of the outputs against it and against `mobmap build`, and waiting on what a
node reports."""
import time

import numpy as np
import pytest

HANG = 300  # seconds after which a wait is a failure, never a pass


def wait_for(what, condition):
    """Polls `condition` until it returns something true; fails after HANG seconds."""
    end = time.monotonic() + HANG
    while time.monotonic() < end:
        got = condition()
        if got:
            return got
        time.sleep(0.05)
    pytest.fail("gave up waiting for " + what)


def cloud_agreement(cloud, built_map, seed):
    """The cloud's scored voxels (dict of x, y, z, mobility arrays) probed in `built_map`
    (a mobmap.Map): (scored voxels, probes scored in both, fraction of those probes scored
    in both, walkable-or-not agreement on them)."""
    scored = np.isfinite(cloud["mobility"])
    pts = np.column_stack([cloud["x"], cloud["y"], cloud["z"]])[scored].astype(np.float64)
    probe = np.random.default_rng(seed).choice(len(pts), size=min(4000, len(pts)), replace=False)
    q = built_map.query(pts[probe], frame="world")
    both = np.isfinite(q["mobility"])
    agree = np.mean((cloud["mobility"][scored][probe][both] >= 0.5) == (q["mobility"][both] >= 0.5))
    return len(pts), int(both.sum()), float(both.mean()), float(agree)


def corridor_height(x, y):
    """The corridor's highest surface at (x, y) (tests' copy of the simulator's scene,
    ground_truth.json), or None where a test should not judge it (edges, the rough patch,
    the moving box, the walls)."""
    margin = 0.08
    if abs(y) > 1.5 - margin:
        return None
    if 1.4 - margin < x < 2.2 + margin and 0.5 - margin < y < 1.3 + margin:
        return None  # rough patch
    if 2.4 < x < 4.0 and -0.5 < y < 0.5:
        return None  # the moving box's path
    for x0, slope in ((1.5, 5), (2.7, 15), (3.9, 25), (5.1, 35), (6.3, 45)):
        if x0 - margin < x < x0 + 0.6 + margin and -1.3 - margin < y < -0.5 + margin:
            if not (x0 + margin < x < x0 + 0.6 - margin and -1.3 + margin < y < -0.5 - margin):
                return None
            return (x - x0) * np.tan(np.radians(slope))
    if 4.6 - margin < x < 5.0 + margin and 0.6 - margin < y < 1.0 + margin:
        return 0.5 if (4.6 + margin < x < 5.0 - margin and 0.6 + margin < y < 1.0 - margin) else None
    if 6.0 - margin < x < 7.2 + margin and 0.4 - margin < y < 1.4 + margin:
        for k, x0 in enumerate((6.0, 6.3, 6.6, 6.9)):
            if x0 + margin < x < x0 + 0.3 - margin and 0.4 + margin < y < 1.4 - margin:
                return 0.17 * (k + 1)
        return None
    return 0.0


VOXEL = 0.02


def in_shadow(x, y):
    """Floor the camera never saw: behind what stands 15 cm or more above it as the walk
    passes it (the far sides of the steeper ramps, the box, the stairs), and the moving
    box's path. Depth cameras mix depth across such edges into surfaces that are not
    there; the map holds them as `mobmap build` does."""
    behind = [(3.3, -1.4, -0.4), (4.5, -1.4, -0.4), (5.7, -1.4, -0.4), (6.9, -1.4, -0.4), (5.0, 0.5, 1.1), (7.2, 0.3, 1.5)]
    if any(x0 <= x <= x0 + 0.6 and y0 <= y <= y1 for x0, y0, y1 in behind):
        return True
    return 2.9 <= x <= 3.9 and -0.5 <= y <= 1.5


def judge_occupancy(data, x0, y0, resolution):
    """An OccupancyGrid's cells (rows along +y from the origin (x0, y0)) on the corridor:
    the values of the known cells of open floor (away from edges and the sensor's shadow)
    and of the 45-degree ramp's inner part."""
    height, width = data.shape
    floor, ramp = [], []
    for r in range(height):
        y = y0 + (r + 0.5) * resolution
        for c in range(width):
            x = x0 + (c + 0.5) * resolution
            v = data[r, c]
            if v < 0:
                continue
            if 6.4 < x < 6.8 and -1.2 < y < -0.6:
                ramp.append(v)
            elif all(corridor_height(x + dx, y + dy) == 0.0 for dx, dy in ((0, 0), (-.3, 0), (.3, 0), (0, -.3), (0, .3))) \
                    and abs(y) < 1.2 and not in_shadow(x, y):
                floor.append(v)
    return np.array(floor), np.array(ramp)


def judge_elevation(elevation, n, cx, cy, res):
    """A GridMap's elevation layer (n x n, grid_map's order: column-major, index (0, 0) at
    the largest x and y, centred on (cx, cy)) against the corridor: the cells judged and
    those within a voxel of the highest surface in the cell (the top face of the voxel
    holding it, one more for the sensor's noise)."""
    judged = within = 0
    for j in range(n):
        for i in range(n):
            e = elevation[j * n + i]
            if not np.isfinite(e):
                continue
            x, y = cx + (n / 2 - i - 0.5) * res, cy + (n / 2 - j - 0.5) * res
            truths = [corridor_height(x + dx, y + dy) for dx in (-res / 2, 0, res / 2) for dy in (-res / 2, 0, res / 2)]
            if any(t is None for t in truths) or in_shadow(x, y):
                continue
            judged += 1
            within += -VOXEL - 1e-4 <= e - max(truths) <= 2 * VOXEL + 1e-4
    return judged, within


def check_cloud(cloud, built_map, seed):
    """The node's cloud agrees with `mobmap build` of the same recording (cloud_agreement):
    many scored voxels, lying where build's are, walkable-or-not alike on 95 % of probes."""
    n, probes, scored_in_both, agree = cloud_agreement(cloud, built_map, seed)
    assert n > 5000
    assert scored_in_both > 0.8, "the node's surface voxels lie where build's are"
    print(f"cloud: {n} scored voxels; {probes} probes scored in both; walkable agrees at {agree:.3f}")
    assert agree >= 0.95


def check_occupancy(data, x0, y0, resolution):
    """judge_occupancy's open floor free and 45-degree ramp occupied, each at 90 %."""
    floor, ramp = judge_occupancy(data, x0, y0, resolution)
    print(f"occupancy: {len(floor)} floor cells {np.mean(floor == 0):.3f} free; {len(ramp)} ramp cells {np.mean(ramp == 100):.3f} occupied")
    assert len(floor) > 500 and np.mean(floor == 0) >= 0.9
    assert len(ramp) > 20 and np.mean(ramp == 100) >= 0.9


def check_elevation(elevation, n, cx, cy, res):
    """judge_elevation: many cells judged, 95 % of them within a voxel of the corridor."""
    judged, within = judge_elevation(elevation, n, cx, cy, res)
    print(f"elevation map at ({cx:.2f}, {cy:.2f}): {judged} cells judged, {within / max(judged, 1):.3f} within a voxel")
    assert judged > 1000
    assert within / judged >= 0.95
