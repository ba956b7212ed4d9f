#!/usr/bin/env python3
"""What a rollout's start costs a model with history: rolls a trained run out from the true
frames 0..s for each start s given (s = 1 is bsms rollout's start: the velocities before frame 0
are missing and read as constant velocity), and scores every start on the same frames (after
the latest start) against constant velocity from that frame. A large gain from a later start
means the padded history at the start is what the rollout lacks; a small one, that the model
drifts on its own predictions wherever it starts.

Usage: PYTHONPATH=build/python scripts/analysis/late_start.py RUN DATA [--split test]
       [--starts 1,5] [--trajectories 20]   (needs the bsms Python module: docs/python.md)
"""
import argparse
import sys

try:
    import numpy as np

    import bsms
except ImportError as missing:
    print(f"{sys.argv[0]}: {missing} (build the bsms Python module and set PYTHONPATH: "
          "docs/python.md)", file=sys.stderr)
    sys.exit(2)


def fail(message):
    print(message, file=sys.stderr)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a run folder written by bsms train (Lagrangian data)")
    ap.add_argument("data", help="the dataset folder to roll out on")
    ap.add_argument("--split", default="test")
    ap.add_argument("--starts", default="1,5", help="comma-separated last true frames (>= 1)")
    ap.add_argument("--trajectories", type=int, default=20, help="at most this many (>= 1)")
    a = ap.parse_args()
    try:
        starts = sorted({int(s) for s in a.starts.split(",")})
    except ValueError:
        fail(f"--starts: '{a.starts}' is not a comma-separated list of integers")
    if starts[0] < 1 or a.trajectories < 1:
        fail(f"--starts must be >= 1 and --trajectories >= 1 (got {a.starts}, {a.trajectories})")
    try:
        run = bsms.Run(a.run)
        data = bsms.Dataset(a.data, split=a.split)
    except Exception as e:  # the module's errors already name the file and the key
        fail(f"{sys.argv[0]}: {e}")
    last = starts[-1]
    model = dict.fromkeys(starts, 0.0)
    baseline = 0.0
    count = 0
    for i in range(min(len(data), a.trajectories)):
        mesh = data.mesh(i)
        x = data.read(i, "world_pos").astype(np.float64)
        frames = x.shape[0]
        if frames < last + 2:
            fail(f"{a.data}: trajectory {i} has {frames} frames; start {last} needs {last + 2}")
        for s in starts:
            seen = [x[k].astype(np.float32) for k in range(s + 1)]
            for t in range(s, frames - 1):
                # The model reads only the last history + 1 frames: pass no more than those.
                recent = seen[-(run.history + 1):]
                seen.append(run.predict(mesh, recent, prescribed=x[t + 1].astype(np.float32)))
            p = np.stack(seen).astype(np.float64)
            model[s] += ((p[last + 1:] - x[last + 1:]) ** 2).sum()
        prev, cur = x[last - 1], x[last]
        for t in range(last, frames - 1):
            prev, cur = cur, 2 * cur - prev
            baseline += ((cur - x[t + 1]) ** 2).sum()
        count += (frames - 1 - last) * x.shape[1] * x.shape[2]
    cv = np.sqrt(baseline / count)
    print(f"{a.run} on {a.data} ({a.split}, {min(len(data), a.trajectories)} trajectories), "
          f"scored on frames {last + 1}.. : constant velocity from frame {last}: {cv:.4f} m")
    for s in starts:
        rmse = np.sqrt(model[s] / count)
        print(f"start from true frames 0..{s}: RMSE-all {rmse:.4f} m, {rmse / cv:.3f}x constant "
              "velocity")


if __name__ == "__main__":
    main()
