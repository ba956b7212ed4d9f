#!/usr/bin/env python3
"""What a dataset's per-frame accelerations are made of: the targets a Lagrangian model learns
(a = x_{t+1} - 2 x_t + x_{t-1}, per node), split into rest (the node moves less than --rest m per
frame) and, with gravity, free flight (within 20 % of gravity) and impacts (more than 3 g from
gravity), with each class's share of the node-frames and of the variance about the mean; the
share of the targets that each body's rigid motion (translation and linearised rotation, fitted
per frame) carries; the mean and standard deviation per axis. A model's one-step loss is
dominated by the classes that carry the variance, a rollout by the bodies' rigid motion.

Usage: scripts/analysis/acceleration_budget.py DATA/train.h5 [--gravity 0 -9.81 0]
       [--frame-dt 0.02] [--rest 0.002] [--trajectories 40]
       (needs python3-h5py and python3-numpy: apt-get install python3-h5py)
"""
import argparse

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import fail, np, trajectories


def rigid_share(accel, position):
    """Squared norm of the least-squares rigid part of one body's accelerations [N, dim] at
    positions [N, dim] (a uniform part plus alpha x r; in 2-D alpha is a scalar)."""
    n, dim = accel.shape
    r = position - position.mean(0)
    cols = [np.tile(np.eye(dim), (n, 1))]
    if dim == 3:
        rot = np.zeros((3 * n, 3))
        rot[0::3, 1], rot[0::3, 2] = r[:, 2], -r[:, 1]
        rot[1::3, 0], rot[1::3, 2] = -r[:, 2], r[:, 0]
        rot[2::3, 0], rot[2::3, 1] = r[:, 1], -r[:, 0]
        cols.append(rot)
    else:
        rot = np.zeros((2 * n, 1))
        rot[0::2, 0], rot[1::2, 0] = -r[:, 1], r[:, 0]
        cols.append(rot)
    m = np.hstack(cols)
    y = accel.reshape(-1)
    coef, *_ = np.linalg.lstsq(m, y, rcond=None)
    return float(((m @ coef) ** 2).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", help="a bsms dataset split: DATA/train.h5")
    ap.add_argument("--gravity", type=float, nargs="+", default=[0.0, -9.81, 0.0],
                    help="the family's gravity (m/s^2), one value per axis")
    ap.add_argument("--frame-dt", type=float, default=0.02, help="time between frames (s)")
    ap.add_argument("--rest", type=float, default=0.002, help="rest: displacement per frame (m)")
    ap.add_argument("--trajectories", type=int, default=40, help="first N trajectories")
    a = ap.parse_args()
    if not (a.frame_dt > 0 and a.rest > 0 and a.trajectories > 0):
        fail(f"{ap.prog}: --frame-dt, --rest and --trajectories must be > 0")
    group = trajectories(a.data, "dataset")
    names = sorted(group.keys())[: a.trajectories]
    if not names:
        fail(f"{a.data}: no trajectories")
    accel, speed, total, rigid = [], [], 0.0, 0.0
    for name in names:
        g = group[name]
        if "world_pos" not in g or "body_id" not in g:
            fail(f"{a.data}: trajectory {name} lacks world_pos or body_id")
        x = g["world_pos"][:].astype(np.float64)
        if x.shape[0] < 3 or x.shape[2] != len(a.gravity):
            fail(f"{a.data}: trajectory {name}: needs >= 3 frames and {len(a.gravity)} axes "
                 f"(--gravity), has shape {x.shape}")
        body = g["body_id"][:]
        acc = x[2:] - 2 * x[1:-1] + x[:-2]
        accel.append(acc.reshape(-1, x.shape[2]))
        speed.append(np.linalg.norm(x[1:-1] - x[:-2], axis=2).reshape(-1))
        total += float((acc ** 2).sum())
        for on in [body == b for b in np.unique(body)]:
            for t in range(acc.shape[0]):
                rigid += rigid_share(acc[t, on], x[t + 1, on])
    acc = np.concatenate(accel)
    speed = np.concatenate(speed)
    g = np.asarray(a.gravity) * a.frame_dt ** 2
    gnorm = float(np.linalg.norm(g))
    mean, std = acc.mean(0), acc.std(0)
    dev = (((acc - mean) / np.maximum(std, 1e-30)) ** 2).sum(1)
    classes = {f"rest (< {a.rest} m per frame)": speed < a.rest}
    if gnorm > 0:  # without gravity there is no free-flight value to measure against
        off = np.linalg.norm(acc - g, axis=1)
        classes["free flight (within 20 % of g)"] = off < 0.2 * gnorm
        classes["impacts (more than 3 g from g)"] = off > 3 * gnorm
    print(f"{a.data}: {len(names)} trajectories, {acc.shape[0]} node-frames; "
          f"gravity per frame^2 {gnorm:.3g} m")
    print("mean per axis (m/frame^2): " + " ".join(f"{v:.3g}" for v in mean))
    print("std per axis (m/frame^2):  " + " ".join(f"{v:.3g}" for v in std))
    print(f"rigid motion's share of the squared targets: {rigid / max(total, 1e-30):.3f}")
    print("| class | node-frames | share of the normalised variance |")
    print("|---|---|---|")
    for label, on in classes.items():
        print(f"| {label} | {on.mean():.3f} | {dev[on].sum() / dev.sum():.3f} |")


if __name__ == "__main__":
    main()
