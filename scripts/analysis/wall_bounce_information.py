#!/usr/bin/env python3
"""How much of a wall bounce the model's inputs determine: for every body and frame t
of a dataset where the body is within --wall of a wall and no other body within --gap, the
acceleration of the body's centre along the wall's normal (x_{t+1} - 2 x_t + x_{t-1}, m per
frame²) is fitted by least squares on quadratic features of body-level summaries taken from the
frames a model sees: its gap to the wall, its extent along the normal (how compressed it is), its
size and its normal velocity, from two frames (t-1, t: what a model with one velocity sees) or
more (the velocities before). The fit is made on one split and scored on another as the RMS error
relative to the RMS truth: a small figure means the frames determine the bounce; what a
2-frame fit cannot explain, no model with one velocity input can learn from those summaries.

Usage: scripts/analysis/wall_bounce_information.py DATA/train.h5 DATA/test.h5 [--gap 0.12]
       [--wall 0.08] [--box 0 1]   (needs python3-h5py and python3-numpy)
Defaults: the default scene's interaction ranges (as centre_error_by_contact.py) and unit box.
"""
import argparse

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import add_range_options, check_ranges, fail, gap_to_others, np, trajectories

# Feature sets: name, and the summaries each uses (suffix k = frame t-k).
FEATURE_SETS = (
    ("2 frames (t-1, t): gap, extent, size, normal velocity", ("gap0", "ext0", "size", "v0")),
    ("3 frames: + gap, extent and velocity one frame earlier",
     ("gap0", "ext0", "size", "v0", "gap1", "ext1", "v1")),
    ("4 frames: + velocity and extent two frames earlier",
     ("gap0", "ext0", "size", "v0", "gap1", "ext1", "v1", "v2", "ext2")),
)


def wall_events(path, a):
    """One row of summaries per (trajectory, body, frame) at a wall and away from other bodies."""
    data = trajectories(path, "dataset")
    lo, hi = a.box
    rows = []
    for name in data:
        g = data[name]
        if "world_pos" not in g or "body_id" not in g:
            fail(f"{path}: trajectory {name} has no world_pos or body_id (not Lagrangian bodies)")
        p = g["world_pos"][:].astype(np.float64)
        body = g["body_id"][:]
        if p.ndim != 3 or p.shape[1] != body.shape[0]:
            fail(f"{path}: trajectory {name}: world_pos {p.shape} does not match body_id")
        ids = np.unique(body)
        for t in range(3, p.shape[0] - 1):
            for b in ids:
                m = body == b
                x = p[t, m]
                gap = gap_to_others(p[t], body, b, ids)
                sides = np.concatenate([x.min(0) - lo, hi - x.max(0)])
                k = int(np.argmin(sides))
                if sides[k] >= a.wall or gap < a.gap:
                    continue
                axis, outward = k % p.shape[2], (-1.0 if k < p.shape[2] else 1.0)
                c = [p[t - j, m].mean(0)[axis] * outward for j in range(4)] + \
                    [p[t + 1, m].mean(0)[axis] * outward]
                normal = [p[t - j, m][:, axis] for j in range(3)]
                row = {"size": np.sqrt(m.sum()), "acc": c[4] - 2 * c[0] + c[1]}
                for j in range(3):
                    row[f"gap{j}"] = normal[j].min() - lo if outward < 0 else hi - normal[j].max()
                    row[f"ext{j}"] = normal[j].max() - normal[j].min()
                    row[f"v{j}"] = c[j] - c[j + 1]
                rows.append(row)
    if not rows:
        fail(f"{path}: no body-frame at a wall (within {a.wall} m) and away from other bodies")
    return rows


def quadratic(rows, keys):
    x = np.array([[r[k] for k in keys] for r in rows])
    cols = [np.ones(len(x))] + [x[:, i] for i in range(x.shape[1])]
    cols += [x[:, i] * x[:, j] for i in range(x.shape[1]) for j in range(i, x.shape[1])]
    return np.stack(cols, 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("fit", help="dataset split to fit on: DATA/train.h5")
    ap.add_argument("score", help="dataset split to score on: DATA/test.h5")
    add_range_options(ap)
    a = ap.parse_args()
    check_ranges(a)
    fit, score = wall_events(a.fit, a), wall_events(a.score, a)
    y, y_score = np.array([r["acc"] for r in fit]), np.array([r["acc"] for r in score])
    print(f"wall events: {len(fit)} to fit ({a.fit}), {len(score)} to score ({a.score}); "
          f"RMS normal centre acceleration {np.sqrt((y_score ** 2).mean()):.3e} m/frame²\n")
    print("| inputs (body-level summaries, quadratic least squares) | error / true (RMS) |")
    print("|---|---|")
    for name, keys in FEATURE_SETS:
        w = np.linalg.lstsq(quadratic(fit, keys), y, rcond=None)[0]
        err = quadratic(score, keys) @ w - y_score
        print(f"| {name} | {np.sqrt((err ** 2).mean() / (y_score ** 2).mean()):.3f} |")


if __name__ == "__main__":
    main()
