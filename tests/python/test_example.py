"""The example script runs from a clean folder and finds its way up the ramp."""

import os
import subprocess
import sys
from pathlib import Path

from conftest import EXE

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "plan_from_python.py"


def test_the_example_plans_up_the_ramp_and_draws_it(tmp_path):
    r = subprocess.run([sys.executable, str(EXAMPLE), "--mobmap", EXE, "--out", str(tmp_path), "--frames", "30"],
                       capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    assert "footsteps" in r.stdout
    assert (tmp_path / "plan.png").stat().st_size > 1000
    assert (tmp_path / "corridor.ot").exists() and (tmp_path / "corridor.json").exists()
