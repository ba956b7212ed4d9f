#!/usr/bin/env python3
"""Whether a rollout's error is a drift the model applies to every scene alike: per predicted
frame, the offset of each trajectory's centre of mass (predicted minus true, all nodes weighted
alike), its mean over the trajectories and its spread across them. A mean offset much larger
than the spread is a common drift (e.g. bodies that stop falling in every scene) rather than
scene-dependent error; the script prints, per axis, the mean, the standard deviation and their
ratio at every --every-th frame and at the last one, and the share of the last frame's mean
squared offset that the common part carries.

Usage: scripts/analysis/rollout_drift.py RUN/rollout/test.h5 [--every 8]
       (needs python3-h5py and python3-numpy: apt-get install python3-h5py)
"""
import argparse

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import fail, np, predicted_and_true, trajectories


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rollout", help="a rollout file: RUN/rollout/SPLIT.h5")
    ap.add_argument("--every", type=int, default=8, help="print every N-th frame (>= 1)")
    a = ap.parse_args()
    if a.every < 1:
        fail(f"{a.rollout}: --every must be >= 1, got {a.every}")
    rollout = trajectories(a.rollout, "rollout")
    offsets = []
    for name in rollout:
        _, p, q = predicted_and_true(a.rollout, name, rollout[name])
        offsets.append(p.mean(1) - q.mean(1))  # [F, dim]
    if len(offsets) < 2:
        fail(f"{a.rollout}: {len(offsets)} trajectory(ies); a spread needs at least 2")
    frames = min(o.shape[0] for o in offsets)
    d = np.stack([o[:frames] for o in offsets])  # [T, F, dim]
    if not np.isfinite(d).all():
        fail(f"{a.rollout}: non-finite positions")
    mean, std = d.mean(0), d.std(0)
    dim = d.shape[2]
    axes = "xyz"[:dim]
    print(f"{a.rollout}: {d.shape[0]} trajectories, {frames} frames; centre offset "
          "predicted - true (m): mean over trajectories / standard deviation across them")
    print("frame  " + "  ".join(f"{c}: mean      std    ratio" for c in axes))
    shown = sorted(set(range(0, frames, a.every)) | {frames - 1})
    for f in shown:
        cells = [f"{mean[f, k]:+9.4f} {std[f, k]:8.4f} {abs(mean[f, k]) / max(std[f, k], 1e-12):7.2f}"
                 for k in range(dim)]
        print(f"{f:5d}  " + "  ".join(cells))
    last = d[:, -1]
    total = float((last ** 2).sum(1).mean())
    common = float((mean[-1] ** 2).sum())
    share = common / total if total > 0 else 0.0
    print(f"last frame: the common drift carries {100 * share:.1f} % of the mean squared centre "
          f"offset ({np.sqrt(total):.4f} m RMS over trajectories)")


if __name__ == "__main__":
    main()
