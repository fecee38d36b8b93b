"""What the Python tests share: the mobmap executable, and a simulated corridor with its map."""

import os
import subprocess

import pytest

EXE = os.environ.get("MOBMAP_EXE", "mobmap")


def run(*args, stdin=None):
    """Runs `mobmap ARGS`; returns its standard output (fails the test on a non-zero exit)."""
    r = subprocess.run([EXE, *map(str, args)], input=stdin, capture_output=True, text=True)
    assert r.returncode == 0, f"mobmap {' '.join(map(str, args))}: {r.stderr}"
    return r.stdout


@pytest.fixture(scope="session")
def corridor(tmp_path_factory):
    """The simulated corridor (30 frames, Kinect noise) and its map, as `mobmap build` makes it."""
    d = tmp_path_factory.mktemp("corridor")
    run("simulate", "--out", d / "seq", "--frames", 30, "--quiet")
    run("build", d / "seq", "--out", d / "map.ot", "--gravity-refine", "off", "--quiet")
    return {"seq": d / "seq", "map": d / "map.ot", "dir": d}
