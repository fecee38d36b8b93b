#!/usr/bin/env python3
"""200,000 random points asked of a map three ways: Map.query from Python (numpy in, numpy
out), piped through `mobmap query` as text, and MobilityMap::query in C++
(point_query_bench). Prints the medians and the ratios.

    PYTHONPATH=build/python python3 tests/bench/python_query_bench.py MAP.ot [--mobmap build/apps/mobmap]
        [--cpp build/tests/point_query_bench] [--points 200000]
"""

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import mobmap


def median_ms(f, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map")
    parser.add_argument("--mobmap", default="build/apps/mobmap")
    parser.add_argument("--cpp", default="build/tests/point_query_bench")
    parser.add_argument("--points", type=int, default=200_000)
    args = parser.parse_args()

    m = mobmap.open_map(args.map)
    info = m.info()
    lo, hi = np.array(info["bounds_min"]), np.array(info["bounds_max"])
    rng = np.random.default_rng(1)
    pts = lo + (hi - lo) * rng.random((args.points, 3))

    py_ms = median_ms(lambda: m.query(pts), 5)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "points.txt"
        np.savetxt(path, pts, fmt="%.6f")
        text = path.read_text()
        cli_ms = median_ms(lambda: subprocess.run([args.mobmap, "query", args.map], input=text, capture_output=True,
                                                  text=True, check=True), 3)
        out = subprocess.run([args.cpp, args.map, str(path)], capture_output=True, text=True, check=True).stdout
        cpp_ms = float(out.split("median ")[1].split(" ms")[0])
    print(f"{args.points} points, {args.map}")
    print(f"  Map.query (Python, numpy)   {py_ms:9.1f} ms")
    print(f"  mobmap query (pipe, text)   {cli_ms:9.1f} ms   {cli_ms / py_ms:5.1f}x the Python time")
    print(f"  MobilityMap::query (C++)    {cpp_ms:9.1f} ms   Python takes {py_ms / cpp_ms:4.2f}x the C++ time")


if __name__ == "__main__":
    main()
