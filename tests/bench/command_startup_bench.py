#!/usr/bin/env python3
"""What starting `mobmap` costs: wall time and peak resident memory of `mobmap --version`
and of `mobmap query` on a small map.

    command_startup_bench.py MAP [--runs 31] [--mobmap EXE] [--reference EXE]

MAP is a map `mobmap build` wrote (a small one: the corridor's two frames); the query asks
about one point on its floor. Each command runs RUNS times; with --reference a second
binary runs alternately with the first, so both see the same machine. Prints the
medians, and with a reference their ratios.
"""
import argparse
import os
import statistics
import subprocess
import time


def once(argv):
    """Wall seconds and peak resident KiB of one run (wait4's rusage of that child)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({os.waitstatus_to_exitcode(status)})")
    return wall, usage.ru_maxrss


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("map")
    ap.add_argument("--runs", type=int, default=31)
    ap.add_argument("--mobmap", default=os.path.join(here, "..", "..", "build", "apps", "mobmap"))
    ap.add_argument("--reference")
    a = ap.parse_args()
    exes = [("mobmap", a.mobmap)] + ([("reference", a.reference)] if a.reference else [])
    commands = [("--version", ["--version"]), ("query MAP 1 0 0.01", ["query", a.map, "1", "0", "0.01"])]
    results = {(name, label): [] for name, _ in exes for label, _ in commands}
    for _ in range(a.runs):
        for label, args in commands:
            for name, exe in exes:
                results[(name, label)].append(once([exe] + args))
    print(f"medians of {a.runs} runs" + (", alternating with the reference" if a.reference else ""))
    print(f"{'command':<22} {'binary':<10} {'wall ms':>8} {'peak MB':>8}")
    for label, _ in commands:
        medians = {}
        for name, _ in exes:
            runs = results[(name, label)]
            wall = statistics.median(w for w, _ in runs) * 1e3
            rss = statistics.median(r for _, r in runs) / 1024
            medians[name] = (wall, rss)
            print(f"{label:<22} {name:<10} {wall:8.1f} {rss:8.1f}")
        if a.reference:
            (w, r), (w0, r0) = medians["mobmap"], medians["reference"]
            print(f"{label:<22} {'ratio':<10} {w / w0:8.2f} {r / r0:8.2f}")


if __name__ == "__main__":
    main()
