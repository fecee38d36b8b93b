"""The simulated corridor's geometry, for the live nodes' tests (ROS 1 and ROS 2)."""
import numpy as np


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
