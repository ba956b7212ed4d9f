"""What the Python binding adds to a multilevel build: bsms.multilevel on the 50K-node rectangle
of bench_preprocess's BM_MinAveBuild/50000 (exact MinAve, --levels auto), against the C++ call.

    PYTHONPATH=build/python /usr/bin/python3 bench/python/multilevel_overhead.py [--build build]

Alternates, in one run: the Python call (wall time around bsms.multilevel: array checks, mesh
copy, build, result object) and the C++ call (bench_preprocess's BM_MinAveBuild/50000, the same
mesh and options, one build per repetition). Prints the medians and their ratio; the issue's
bound is 1.05. Threads: OMP_NUM_THREADS, else every core, the same for both.
"""

import argparse
import json
import os
import statistics
import subprocess
import time

import numpy as np

import bsms


def rectangle(target):
    """bench_preprocess's rectangle_mesh: side^2 nodes 1 cm apart, each square in 2 triangles."""
    side = int(round(target ** 0.5))
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    points = np.stack([0.01 * i.ravel(), 0.01 * j.ravel()], axis=1)
    a = (i[:-1, :-1] * side + j[:-1, :-1]).ravel()
    b, d = a + side, a + 1
    e = b + 1
    cells = np.empty((2 * len(a), 3), dtype=np.int64)
    cells[0::2] = np.stack([a, b, e], axis=1)
    cells[1::2] = np.stack([a, e, d], axis=1)
    return points, cells


def cpp_ms(build):
    out = subprocess.run(
        [os.path.join(build, "bench", "bench_preprocess"), "--benchmark_filter=BM_MinAveBuild/50000",
         "--benchmark_format=json"],
        capture_output=True, text=True, check=True)
    # The benchmark repeats itself (3 builds) and reports aggregates only: its median.
    rows = json.loads(out.stdout)["benchmarks"]
    median = [b for b in rows if b.get("aggregate_name") == "median"]
    return (median or rows)[0]["real_time"]  # ms


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default="build")
    parser.add_argument("--repetitions", type=int, default=5)
    args = parser.parse_args()
    points, cells = rectangle(50_000)
    python_ms, inside_ms, cpp = [], [], []
    for _ in range(args.repetitions):
        start = time.perf_counter()
        graph = bsms.multilevel(points, cells, seeding="minave")
        python_ms.append(1000 * (time.perf_counter() - start))
        inside_ms.append(sum(row["ms"] for row in graph.report))
        cpp.append(cpp_ms(args.build))
    py, cc, ins = (statistics.median(v) for v in (python_ms, cpp, inside_ms))
    print(f"nodes {len(points)}, levels {len(graph)}, threads "
          f"{os.environ.get('OMP_NUM_THREADS', bsms._core.hardware_threads())}")
    print(f"python bsms.multilevel  median {py:8.1f} ms  (runs: {', '.join(f'{v:.0f}' for v in python_ms)})")
    print(f"  of which the build    median {ins:8.1f} ms")
    print(f"C++ BM_MinAveBuild      median {cc:8.1f} ms  (runs: {', '.join(f'{v:.0f}' for v in cpp)})")
    print(f"ratio python / C++      {py / cc:.3f}   (python wall / its own build: {py / ins:.3f})")


if __name__ == "__main__":
    main()
