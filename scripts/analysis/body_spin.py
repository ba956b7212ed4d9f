#!/usr/bin/env python3
"""How well a rollout turns its bodies: each body's angular velocity per frame, from the rotation
that best maps its nodes at one frame onto the next (Kabsch fit about the centroid, all nodes
weighted alike), in the prediction and in the truth. Prints, at every --every-th frame and at the
last one, the RMS over bodies of the true spin, of the predicted spin and of their difference,
and the share of the true spin's change since the first frame that the model got wrong: 1 means
a model that keeps each body's first spin (as constant velocity does) would do as well.

With --one-step, the file is a teacher-forced rollout (bsms rollout RUN --one-step: every frame
predicted from the true ones): the script then compares the change of spin over each step
(the angular acceleration the model predicts from the true state) with the true one, as one
RMS over all bodies and steps and their correlation, per axis pooled.

Usage: scripts/analysis/body_spin.py RUN/rollout/test.h5 [--every 8] [--frame-dt 0.02] [--one-step]
       (needs python3-h5py and python3-numpy: apt-get install python3-h5py)
"""
import argparse

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import fail, np, predicted_and_true, trajectories


def rotation_vector(a, b):
    """Rotation vector (axis times angle) of the best-fit rotation taking point set a to b."""
    a = a - a.mean(0)
    b = b - b.mean(0)
    if a.shape[1] == 2:  # in the plane: the angle of the 2x2 fit, as a vector along z
        h = a.T @ b
        return np.array([0.0, 0.0, np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])])
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    angle = np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return axis * angle / (2.0 * np.sin(angle))


def spins(x, body, ids, dt):
    """Angular velocity [B, F-1, 3] of each body between consecutive frames of x [F, N, dim]."""
    return np.stack([[rotation_vector(x[f, body == b], x[f + 1, body == b]) / dt
                      for f in range(x.shape[0] - 1)] for b in ids])


def rms(v):
    return float(np.sqrt((v ** 2).sum(-1).mean())) if v.size else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rollout", help="a rollout file: RUN/rollout/SPLIT.h5")
    ap.add_argument("--every", type=int, default=8, help="print every N-th frame (>= 1)")
    ap.add_argument("--frame-dt", type=float, default=0.02, help="time between frames (s)")
    ap.add_argument("--one-step", action="store_true",
                    help="the file holds one-step predictions (bsms rollout --one-step)")
    a = ap.parse_args()
    if a.every < 1 or not a.frame_dt > 0:
        fail(f"{a.rollout}: --every must be >= 1 and --frame-dt > 0, got {a.every} and {a.frame_dt}")
    rollout = trajectories(a.rollout, "rollout")
    true_spin, predicted_spin, true_change, predicted_change = [], [], [], []
    for name in rollout:
        body, p, q = predicted_and_true(a.rollout, name, rollout[name])
        if not (np.isfinite(p).all() and np.isfinite(q).all()):
            fail(f"{a.rollout}: trajectory {name} has non-finite positions")
        if q.shape[0] < 3:
            fail(f"{a.rollout}: trajectory {name} has {q.shape[0]} frames; needs at least 3")
        ids = [b for b in np.unique(body) if (body == b).sum() >= 3]
        truth = spins(q, body, ids, a.frame_dt)
        if a.one_step:  # frame f+1 predicted from the true f: its spin starts from the truth
            guess = np.stack([[rotation_vector(q[f, body == b], p[f + 1, body == b]) / a.frame_dt
                               for f in range(q.shape[0] - 1)] for b in ids])
            true_change.append((truth[:, 1:] - truth[:, :-1]).reshape(-1, 3))
            predicted_change.append((guess[:, 1:] - truth[:, :-1]).reshape(-1, 3))
        else:
            true_spin.append(truth)
            predicted_spin.append(spins(p, body, ids, a.frame_dt))
    if not rollout:
        fail(f"{a.rollout}: no trajectories")
    if a.one_step:
        t, g = np.concatenate(true_change), np.concatenate(predicted_change)
        corr = float(np.corrcoef(t.ravel(), g.ravel())[0, 1]) if t.size > 1 else 0.0
        print(f"{a.rollout}: {t.shape[0]} body-steps; change of spin per step (rad/s): "
              f"true {rms(t):.4f}, predicted {rms(g):.4f}, error {rms(t - g):.4f} "
              f"({rms(t - g) / max(rms(t), 1e-12):.2f} of the true change), correlation {corr:.3f}")
        return
    frames = min(s.shape[1] for s in true_spin)
    t = np.concatenate([s[:, :frames] for s in true_spin])  # [bodies, frames, 3]
    g = np.concatenate([s[:, :frames] for s in predicted_spin])
    print(f"{a.rollout}: {t.shape[0]} bodies, {frames} frame intervals; spin RMS over bodies "
          "(rad/s): true, predicted, error, error / true change since frame 0")
    for f in sorted(set(range(0, frames, a.every)) | {frames - 1}):
        change = rms(t[:, f] - t[:, 0])
        share = f"{rms(t[:, f] - g[:, f]) / change:6.2f}" if change > 1e-9 else "     -"
        print(f"{f:5d}  {rms(t[:, f]):8.4f} {rms(g[:, f]):8.4f} {rms(t[:, f] - g[:, f]):8.4f} {share}")
    print(f"all frames: true {rms(t):.4f}, predicted {rms(g):.4f}, error {rms(t - g):.4f}, "
          f"error of keeping the first spin {rms(t - t[:, :1]):.4f}")


if __name__ == "__main__":
    main()
