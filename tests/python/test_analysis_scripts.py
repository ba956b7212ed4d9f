"""scripts/analysis/rollout_drift.py on constructed rollout files: a drift shared by every
trajectory beside offsets that differ between them, with the common share and the spread known
in closed form; and its one-line failures (exit 2)."""

import re
import subprocess
import sys

import h5py
import numpy as np

from conftest import REPO

SCRIPT = REPO / "scripts" / "analysis" / "rollout_drift.py"


def write_rollout(path, offsets, frames=10, nodes=5, dim=3, seed=0):
    """A rollout file whose trajectory i predicts the truth moved by offsets[i](frame) [dim]."""
    rng = np.random.default_rng(seed)
    with h5py.File(path, "w") as f:
        group = f.create_group("trajectories")
        for i, offset in enumerate(offsets):
            truth = rng.uniform(0, 1, (frames, nodes, dim))
            shift = np.stack([offset(t) for t in range(frames)])[:, None, :]
            g = group.create_group(f"{i:06d}")
            g["target_world_pos"] = truth.astype(np.float32)
            g["world_pos"] = (truth + shift).astype(np.float32)
            g["body_id"] = np.zeros(nodes, np.int32)


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True,
                          text=True)


def test_common_drift_share_and_spread(tmp_path):
    # A drift of 0.3 m along y at the last frame (growing linearly) shared by all four, and
    # +-0.1 m along x that differs: mean squared offset 0.09 + 0.01, common share 90 %.
    frames = 10
    common = lambda t: np.array([0.0, 0.3 * t / (frames - 1), 0.0])
    own = [np.array([s * 0.1, 0.0, 0.0]) for s in (1, -1, 1, -1)]
    offsets = [lambda t, o=o: common(t) + o * t / (frames - 1) for o in own]
    path = tmp_path / "drift.h5"
    write_rollout(path, offsets, frames=frames)
    done = run(path, "--every", 3)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert "4 trajectories, 10 frames" in out
    share = re.search(r"carries ([0-9.]+) % .*\(([0-9.]+) m RMS", out)
    assert share, out
    assert abs(float(share.group(1)) - 90.0) < 0.05
    assert abs(float(share.group(2)) - np.sqrt(0.10)) < 1e-3
    last = [line for line in out.splitlines() if line.strip().startswith("9 ")]
    assert len(last) == 1, out
    values = [float(v) for v in last[0].split()[1:]]  # x: mean std ratio, y: ..., z: ...
    assert abs(values[0]) < 1e-4 and abs(values[1] - 0.1) < 1e-4  # x: no common part, 0.1 spread
    assert abs(values[3] - 0.3) < 1e-4 and values[4] < 1e-4  # y: all common


def test_no_drift_gives_zero_share(tmp_path):
    own = [np.array([s * 0.05, 0.0, -s * 0.05]) for s in (1, -1)]
    path = tmp_path / "scatter.h5"
    write_rollout(path, [lambda t, o=o: o * t for o in own])
    done = run(path)
    assert done.returncode == 0, done.stderr
    assert "carries 0.0 %" in done.stdout


def test_bad_inputs_exit_2_with_one_line(tmp_path):
    missing = run(tmp_path / "none.h5")
    dataset = tmp_path / "data.h5"
    with h5py.File(dataset, "w") as f:
        f.create_group("trajectories").create_group("000000")["world_pos"] = np.zeros((3, 2, 3))
    not_rollout = run(dataset)
    one = tmp_path / "one.h5"
    write_rollout(one, [lambda t: np.zeros(3)])
    alone = run(one)
    every = run(one, "--every", 0)
    for done, says in ((missing, "not a bsms rollout file"), (not_rollout, "no target_world_pos"),
                       (alone, "at least 2"), (every, "--every must be >= 1")):
        assert done.returncode == 2, done
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and says in lines[0], done.stderr
