"""Footstep plans and reachability from Python against `mobmap plan` and the robot's limits."""

import json

import numpy as np
import pytest

import mobmap
from conftest import run


def test_a_plan_equals_the_cli_footstep_for_footstep(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    got = mobmap.plan(m, (1.0, 0.0, 0.1), (3.0, 0.5, 0.1))
    want = json.loads(run("plan", corridor["map"], "--from", 1.0, 0.0, 0.1, "--to", 3.0, 0.5, 0.1, "--json"))
    assert got["found"] and want["found"]
    assert got["reason"] == ""
    steps = want["footsteps"]
    assert len(got["yaw"]) == len(steps) >= 4
    np.testing.assert_array_equal(got["xyz"], [[s["x"], s["y"], s["z"]] for s in steps])
    np.testing.assert_array_equal(got["yaw"], [s["yaw"] for s in steps])
    np.testing.assert_array_equal(got["side"], [0 if s["foot"] == "left" else 1 for s in steps])
    assert got["cost"] == want["cost"]
    assert got["expansions"] == want["expansions"]


def test_no_plan_comes_with_the_reason_and_limits_are_keyword_arguments(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    # A sole longer than the corridor is wide fits nowhere across it, but one along it does.
    tiny = mobmap.plan(m, (1.0, 0.0, 0.1), (3.0, 0.5, 0.1), max_stride_m=0.05)
    assert not tiny["found"]
    assert tiny["reason"]
    assert tiny["xyz"].shape[1] == 3
    with pytest.raises(TypeError, match="unexpected keyword argument 'max_steps'"):
        mobmap.plan(m, (1.0, 0.0, 0.1), (3.0, 0.5, 0.1), max_steps=0.2)
    with pytest.raises(TypeError, match="max_step_m must be a number"):
        mobmap.plan(m, (1.0, 0.0, 0.1), (3.0, 0.5, 0.1), max_step_m="high")
    with pytest.raises(ValueError, match="max_step_m"):
        mobmap.plan(m, (1.0, 0.0, 0.1), (3.0, 0.5, 0.1), max_step_m=-1)
    with pytest.raises(ValueError, match="start"):
        mobmap.plan(m, (1.0, 0.0), (3.0, 0.5, 0.1))


def test_reachability_flags_the_floor_and_not_the_unseen(corridor):
    m = mobmap.open_map(str(corridor["map"]))
    pts = np.array([[1.2, 0.0, 0.1], [2.5, -0.3, 0.1], [50.0, 50.0, 0.1]])
    flags = mobmap.reachable(m, (1.0, 0.0, 0.1), pts)
    assert flags.dtype == bool
    assert flags.tolist() == [True, True, False]
    # A robot that stands only on perfect surfaces reaches no more than one that is less strict.
    strict = mobmap.reachable(m, (1.0, 0.0, 0.1), pts, min_mobility=0.999)
    assert not np.any(strict & ~flags)
