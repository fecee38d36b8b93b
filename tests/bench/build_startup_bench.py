#!/usr/bin/env python3
"""What a short `mobmap build` costs beyond its frames.

    build_startup_bench.py SEQUENCE [--frames 30] [--repeats 5] [--mobmap EXE] [--reference EXE]

Runs `mobmap build SEQUENCE` on the first N and the first 2N frames, REPEATS times each,
alternating, and prints medians: the wall time of both, the cost of a frame (the
difference over N), the fixed cost (what N frames take beyond N frames' cost: opening
the input, the gravity check, saving) and the ratio of the N-frame build's wall time to
its frames' cost. MAP.json's "seconds" (the frame loop) is printed beside. With
--reference a second binary runs alternately with the first, so both see the same
machine, and the map files of the two are compared byte for byte.
"""
import argparse
import filecmp
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def run(exe, seq, frames, out):
    for suffix in (".ot", ".bt", ".octovis.ot", ".json"):
        if os.path.exists(out[:-3] + suffix):
            os.remove(out[:-3] + suffix)
    t0 = time.monotonic()
    subprocess.run([exe, "build", seq, "--frames", f"0:{frames - 1}", "--out", out, "-q"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.monotonic() - t0
    with open(out[:-3] + ".json") as f:
        loop = json.load(f)["seconds"]
    return wall, loop


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--mobmap", default=os.path.join(here, "..", "..", "build", "apps", "mobmap"))
    ap.add_argument("--reference")
    a = ap.parse_args()
    exes = [("mobmap", a.mobmap)] + ([("reference", a.reference)] if a.reference else [])
    counts = (a.frames, 2 * a.frames)
    results = {(name, n): [] for name, _ in exes for n in counts}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(a.repeats):
            for n in counts:
                for name, exe in exes:
                    results[(name, n)].append(run(exe, a.sequence, n, os.path.join(tmp, f"{name}{n}.ot")))
        same = None
        if a.reference:
            same = all(filecmp.cmp(os.path.join(tmp, f"mobmap{n}{s}"), os.path.join(tmp, f"reference{n}{s}"), shallow=False)
                       for n in counts for s in (".ot", ".bt"))
    n = a.frames
    print(f"build {a.sequence}, the first {n} and {2 * n} frames: medians of {a.repeats} runs")
    print(f"{'binary':<10} {'wall_N_s':>8} {'wall_2N_s':>9} {'frame_ms':>8} {'fixed_s':>7} {'wall_N/frames':>13} {'loop_N_s':>8}")
    for name, _ in exes:
        wall1 = statistics.median(w for w, _ in results[(name, n)])
        wall2 = statistics.median(w for w, _ in results[(name, 2 * n)])
        frame = (wall2 - wall1) / n
        loop = statistics.median(l for _, l in results[(name, n)])
        print(f"{name:<10} {wall1:8.2f} {wall2:9.2f} {1000 * frame:8.1f} {wall1 - n * frame:7.2f} {wall1 / (n * frame):13.2f} {loop:8.2f}")
    if same is not None:
        print("maps (.ot, .bt) byte-identical:", "yes" if same else "NO")
        return 0 if same else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
