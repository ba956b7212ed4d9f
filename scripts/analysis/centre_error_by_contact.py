#!/usr/bin/env python3
"""Where a rollout's centre error enters: for every body and predicted step, the change
of the error in the body's centre velocity (predicted minus true centroid displacement per frame,
differenced over consecutive steps: the centre acceleration the model got wrong), attributed to
what the body was doing in the predicted state the model saw: touching another body (its nodes
within --gap of another body's), near a wall of the box (--wall), both, or free. Prints each
class's share of the steps, of the squared injected error and of the true centre acceleration,
and the error relative to the truth; for the wall steps, the share along the wall's normal.

With --one-step, the file is a teacher-forced rollout (bsms rollout RUN --one-step: every step
from the true frames): the error is then each step's own (predicted minus true centre after one
step from the truth), classed by the true state, so it measures the model on the states it was
trained on, without the drift of its own rollout.

Usage: scripts/analysis/centre_error_by_contact.py RUN/rollout/test.h5 [--gap 0.12] [--wall 0.08]
       [--box 0 1] [--one-step]   (needs python3-h5py and python3-numpy: apt-get install
       python3-h5py)
Defaults: the default scene's interaction ranges (3 and 2 background cells of 0.04 m, as the
momentum groups use) and its unit box.
"""
import argparse

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import (add_range_options, check_ranges, fail, gap_to_others, np,
                           predicted_and_true, trajectories)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rollout", help="a rollout file: RUN/rollout/SPLIT.h5")
    add_range_options(ap)
    ap.add_argument("--one-step", action="store_true",
                    help="the file holds one-step predictions (bsms rollout --one-step)")
    a = ap.parse_args()
    check_ranges(a)
    rollout = trajectories(a.rollout, "rollout")
    classes = ("contact", "wall", "both", "free")
    err = dict.fromkeys(classes, 0.0)
    true = dict.fromkeys(classes, 0.0)
    steps = dict.fromkeys(classes, 0)
    normal_err = tangential_err = 0.0  # wall steps: along the nearest wall's normal, and across
    lo, hi = a.box
    for name in rollout:
        body, p, q = predicted_and_true(a.rollout, name, rollout[name])
        ids = np.unique(body)
        cp = np.stack([p[:, body == b].mean(1) for b in ids], 1)  # [F, B, dim]
        cq = np.stack([q[:, body == b].mean(1) for b in ids], 1)
        vp, vq = cp[1:] - cp[:-1], cq[1:] - cq[:-1]
        ev = vp - vq
        seen = q if a.one_step else p  # the state the model stepped from
        for t in range(2 if not a.one_step else 1, p.shape[0] - 1):  # its step from t to t + 1
            # Rollout: the change of the centre-velocity error; one step: the step's own error.
            injected = cp[t + 1] - cq[t + 1] if a.one_step else ev[t] - ev[t - 1]
            accel = vq[t] - vq[t - 1]
            for j, b in enumerate(ids):
                x = seen[t, body == b]
                gap = gap_to_others(seen[t], body, b, ids)
                near_wall = min((x - lo).min(), (hi - x).min()) < a.wall
                touching = gap < a.gap
                c = "both" if touching and near_wall else "contact" if touching else \
                    "wall" if near_wall else "free"
                err[c] += float((injected[j] ** 2).sum())
                if c == "wall":
                    axis = int(np.argmin(np.minimum(x.min(0) - lo, hi - x.max(0))))
                    normal_err += float(injected[j][axis] ** 2)
                    tangential_err += float((injected[j] ** 2).sum() - injected[j][axis] ** 2)
                true[c] += float((accel[j] ** 2).sum())
                steps[c] += 1
    total_err, total_true, n = sum(err.values()), sum(true.values()), sum(steps.values())
    if n == 0 or total_err == 0:
        fail(f"{a.rollout}: no predicted steps with an error to attribute")
    print("| class | steps | share of injected centre error² | share of true centre acceleration² "
          "| error / true (RMS) |")
    print("|---|---|---|---|---|")
    for c in classes:
        ratio = np.sqrt(err[c] / true[c]) if true[c] > 0 else float("nan")
        print(f"| {c} | {steps[c] / n:.1%} | {err[c] / total_err:.1%} | {true[c] / total_true:.1%} "
              f"| {ratio:.2f} |")
    if normal_err + tangential_err > 0:
        print(f"\nwall steps: {normal_err / (normal_err + tangential_err):.1%} of the injected "
              "centre error² is along the nearest wall's normal (the bounce)")


if __name__ == "__main__":
    main()
