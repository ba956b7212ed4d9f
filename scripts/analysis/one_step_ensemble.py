#!/usr/bin/env python3
"""Would averaging models help? For two or more one-step rollouts of the same
trajectories (bsms rollout RUN --one-step: every step from the true frames), each body's centre
error per predicted step (predicted minus true centroid), its RMS per component for each run,
the correlation of the runs' errors, pair by pair, and the RMS of the error of the runs' average
prediction. Uncorrelated errors of equal size average down by 1/sqrt(K); equal ones not at all.

Usage: scripts/analysis/one_step_ensemble.py RUN_A/rollout_one_step/test.h5
       RUN_B/rollout_one_step/test.h5 [...]   (needs python3-h5py and python3-numpy)
"""
import argparse
import itertools

# body_contacts checks for h5py and numpy first, with a one-line message.
from body_contacts import fail, np, predicted_and_true, trajectories


def centre_errors(path):
    """Per trajectory name: [steps, bodies, dim] centre errors of the predicted frames."""
    rollout = trajectories(path, "one-step rollout")
    out = {}
    for name in rollout:
        body, p, q = predicted_and_true(path, name, rollout[name])
        ids = np.unique(body)
        # Frame 0 and 1 are the truth in a one-step rollout; its predictions start at frame 2.
        e = np.stack([(p[2:, body == b] - q[2:, body == b]).mean(1) for b in ids], 1)
        out[name] = (e, q)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rollouts", nargs="+", help="one-step rollout files of the same trajectories")
    a = ap.parse_args()
    if len(a.rollouts) < 2:
        fail(f"{ap.prog}: give at least two one-step rollout files")
    runs = [centre_errors(path) for path in a.rollouts]
    names = sorted(runs[0])
    for path, run in zip(a.rollouts[1:], runs[1:]):
        if sorted(run) != names:
            fail(f"{path}: other trajectories than {a.rollouts[0]} (same data and split needed)")
        for name in names:
            if not np.array_equal(run[name][1], runs[0][name][1]):
                fail(f"{path}: trajectory {name}'s true frames differ from {a.rollouts[0]}'s")
    errors = [np.concatenate([run[name][0].reshape(-1) for name in names]) for run in runs]
    for path, e in zip(a.rollouts, errors):
        print(f"{path}: centre error {np.sqrt(np.mean(e ** 2)):.3e} m (RMS per component)")
    for (i, ei), (j, ej) in itertools.combinations(enumerate(errors), 2):
        corr = float(np.sum(ei * ej) / np.sqrt(np.sum(ei ** 2) * np.sum(ej ** 2)))
        print(f"correlation {i + 1}-{j + 1}: {corr:.3f}")
    mean = np.mean(errors, axis=0)
    best = min(np.sqrt(np.mean(e ** 2)) for e in errors)
    rms_mean = np.sqrt(np.mean(mean ** 2))
    print(f"average of the {len(errors)} predictions: centre error {rms_mean:.3e} m, "
          f"{rms_mean / best:.3f}x the best run's ({errors[0].size} values)")


if __name__ == "__main__":
    main()
