#!/usr/bin/env python3
"""Maps the simulated corridor from Python, plans footsteps up its 5-degree ramp, and has
mobmap draw the plan over the map's top view.

    PYTHONPATH=build/python python3 examples/plan_from_python.py [--mobmap build/apps/mobmap] [--out DIR]

Writes DIR/seq (the simulated frames), DIR/corridor.ot (+ .json) and DIR/plan.png.
"""

import argparse
import subprocess
from pathlib import Path

import mobmap

START = (1.0, -0.9, 0.1)  # on the floor in front of the ramp (map frame = world frame here)
GOAL = (2.0, -0.9, 0.15)  # near the top of the 5-degree ramp, 4.4 cm up


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mobmap", default="build/apps/mobmap", help="the mobmap executable")
    parser.add_argument("--out", default="maps/python-example", help="output folder")
    parser.add_argument("--frames", type=int, default=60, help="frames to simulate")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    seq = out / "seq"
    subprocess.run([args.mobmap, "simulate", "--out", str(seq), "--frames", str(args.frames), "--force", "--quiet"],
                   check=True)

    # Frames go in while the map can be read: a planner could ask between pushes.
    frames = mobmap.open_recording(str(seq))  # read as `mobmap build` reads it
    mapper = mobmap.LiveMapper(gravity_down_world=frames.gravity_down)
    for frame in frames:
        mapper.push(frame["depth"], frame["intrinsics"], frame["pose"], stamp=frame["number"] / 30.0)
    mapper.finish()
    corridor = mapper.snapshot()
    corridor.save(str(out / "corridor.ot"))
    print(f"mapped {mapper.stats()['fused']} frames: {corridor.info()['leaves']} leaves")

    plan = mobmap.plan(corridor, START, GOAL, max_step_m=0.15)
    if not plan["found"]:
        raise SystemExit(f"no plan: {plan['reason']}")
    print(f"{len(plan['yaw'])} footsteps, {plan['length_m']:.2f} m, {plan['expansions']} states expanded:")
    for (x, y, z), side, mob in zip(plan["xyz"], plan["side"], plan["min_mobility"]):
        print(f"  {'left ' if side == 0 else 'right'} x {x:5.2f}  y {y:5.2f}  z {z:5.3f}  lowest mobility {mob:.2f}")

    # The same map gives `mobmap plan` the same footsteps; it draws them over the top view.
    png = out / "plan.png"
    subprocess.run([args.mobmap, "plan", str(out / "corridor.ot"), "--from", *map(str, START), "--to",
                    *map(str, GOAL), "--png", str(png)], check=True, capture_output=True)
    print(f"drawn: {png}")


if __name__ == "__main__":
    main()
