"""scripts/analysis/body_spin.py on constructed rollout files of rigidly turning bodies, whose
angular velocities (and their errors) are known in closed form, in 3-D and in the plane, over a
rollout and one step from the truth; and its one-line failures (exit 2)."""

import re
import subprocess
import sys

import h5py
import numpy as np

from conftest import REPO

SCRIPT = REPO / "scripts" / "analysis" / "body_spin.py"
DT = 0.02


def rotate(points, angle, axis):
    """points [N, dim] turned by angle about the unit axis (3-D) or in the plane (2-D)."""
    c, s = np.cos(angle), np.sin(angle)
    if points.shape[1] == 2:
        return points @ np.array([[c, s], [-s, c]])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r = np.eye(3) + s * k + (1 - c) * (k @ k)
    return points @ r.T


def turning(shape, spin, axis, frames, centre_speed):
    """Frames [F, N, dim] of a body turning at spin(f) rad/s between frames f and f+1 while its
    centre moves at a constant velocity."""
    angle, out = 0.0, []
    for f in range(frames):
        out.append(rotate(shape, angle, axis) + centre_speed * f * DT)
        angle += spin(f) * DT
    return np.stack(out)


def write(path, bodies, dim=3, frames=12, one_step_offset=None, seed=0):
    """A rollout file with one trajectory: bodies = [(true spin(f), predicted spin(f), axis)]."""
    rng = np.random.default_rng(seed)
    truth, pred, ids = [], [], []
    for i, (true_spin, predicted_spin, axis) in enumerate(bodies):
        shape = rng.normal(0, 0.1, (20, dim))
        axis = None if axis is None else np.asarray(axis, float) / np.linalg.norm(axis)
        speed = rng.normal(0, 1, dim)
        q = turning(shape, true_spin, axis, frames, speed)
        if one_step_offset is None:
            p = turning(shape, predicted_spin, axis, frames, speed)
        else:  # frame f+1 from the true frame f, turned one_step_offset rad/s faster
            p = q.copy()
            for f in range(frames - 1):
                centre = q[f].mean(0)
                step = rotate(q[f] - centre, (true_spin(f) + one_step_offset) * DT, axis)
                p[f + 1] = step + centre + speed * DT
        truth.append(q)
        pred.append(p)
        ids += [i] * shape.shape[0]
    with h5py.File(path, "w") as f:
        g = f.create_group("trajectories").create_group("000000")
        g["target_world_pos"] = np.concatenate(truth, 1).astype(np.float64)
        g["world_pos"] = np.concatenate(pred, 1).astype(np.float64)
        g["body_id"] = np.array(ids, np.int32)


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True,
                          text=True)


def test_rollout_spins_and_their_error(tmp_path):
    # Body 0 spins up (1 + 0.5 f rad/s) and the model keeps it at 1 rad/s; body 1 spins at a
    # steady 2 rad/s about another axis and the model gets it right.
    path = tmp_path / "spin.h5"
    write(path, [(lambda f: 1 + 0.5 * f, lambda f: 1.0, (0, 0, 1)),
                 (lambda f: 2.0, lambda f: 2.0, (1, 1, 0))])
    done = run(path, "--every", 4)
    assert done.returncode == 0, done.stderr
    rows = {int(line.split()[0]): [float(v) for v in line.split()[1:4]]
            for line in done.stdout.splitlines() if re.match(r"\s+\d+\s", line)}
    assert sorted(rows) == [0, 4, 8, 10]
    for f, (true, predicted, error) in rows.items():
        spin = 1 + 0.5 * f
        assert abs(true - np.sqrt((spin ** 2 + 4) / 2)) < 1e-4
        assert abs(predicted - np.sqrt((1 + 4) / 2)) < 1e-4
        assert abs(error - (spin - 1) / np.sqrt(2)) < 1e-4
    # The model kept body 0's first spin, so its error is exactly that of keeping it.
    last = re.search(r"error ([0-9.]+), error of keeping the first spin ([0-9.]+)", done.stdout)
    assert last and abs(float(last.group(1)) - float(last.group(2))) < 1e-9, done.stdout


def test_plane_bodies(tmp_path):
    path = tmp_path / "plane.h5"
    write(path, [(lambda f: 3.0, lambda f: -1.0, None)], dim=2)
    done = run(path)
    assert done.returncode == 0, done.stderr
    assert re.search(r"true 3\.0000, predicted 1\.0000, error 4\.0000", done.stdout), done.stdout


def test_one_step_change_of_spin(tmp_path):
    # True spin 1 + 0.5 f: its change per step is 0.5 rad/s; the model turns each true frame
    # 0.1 rad/s too fast, so it predicts 0.6 and errs by 0.1 at every step.
    path = tmp_path / "one.h5"
    write(path, [(lambda f: 1 + 0.5 * f, None, (0, 1, 0))], frames=10, one_step_offset=0.1)
    done = run(path, "--one-step")
    assert done.returncode == 0, done.stderr
    found = re.search(r"(\d+) body-steps.*true ([0-9.]+), predicted ([0-9.]+), error ([0-9.]+)",
                      done.stdout)
    assert found, done.stdout
    assert int(found.group(1)) == 8
    assert [round(float(found.group(i)), 6) for i in (2, 3, 4)] == [0.5, 0.6, 0.1]


def test_bad_inputs_exit_2_with_one_line(tmp_path):
    missing = run(tmp_path / "none.h5")
    short = tmp_path / "short.h5"
    write(short, [(lambda f: 1.0, lambda f: 1.0, (0, 0, 1))], frames=2)
    nan = tmp_path / "nan.h5"
    write(nan, [(lambda f: 1.0, lambda f: np.nan, (0, 0, 1))])
    every = run(short, "--every", 0)
    for done, says in ((missing, "not a bsms rollout file"), (run(short), "needs at least 3"),
                       (run(nan), "non-finite"), (every, "--every must be >= 1")):
        assert done.returncode == 2, done
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and says in lines[0], done.stderr
