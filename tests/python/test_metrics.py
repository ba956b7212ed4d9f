"""`bsms rollout`'s table of the references (RMSE over the first 1, 10, 20, 50, 100, 200 and all
predicted steps, each trajectory's RMSE averaged over trajectories) against a hand computation from
the rollout's own prediction file: Lagrangian (a run on a bsms family) and Eulerian (a run on
DeepMind's cylinder_flow fixture)."""

import json
import shutil

import numpy as np
import pytest

import bsms
from conftest import FIXTURES, HAS_TORCH, REPO, cli

pytestmark = pytest.mark.skipif(not HAS_TORCH, reason="built without LibTorch")
HORIZONS = [1, 10, 20, 50, 100, 200]


def table_by_hand(trajectories):
    """trajectories: a list of {field: per-step MSE array}."""
    longest = max(len(mse) for t in trajectories for mse in t.values())
    table = {}
    for h in HORIZONS + ["all"]:
        if h != "all" and h > longest:
            continue
        row = {}
        for field in trajectories[0]:
            row[field] = np.mean([np.sqrt(np.mean(t[field][: (None if h == "all" else h)]))
                                  for t in trajectories])
        row["total"] = np.sqrt(np.mean([v ** 2 for v in row.values()]))
        table[str(h)] = row
    return table


def assert_tables_equal(written, expected):
    assert written.keys() == expected.keys()
    for h, row in expected.items():
        assert written[h].keys() == row.keys(), h
        for field, value in row.items():
            assert written[h][field] == pytest.approx(value, rel=1e-4), (h, field)


def test_lagrangian_table(tiny_run, tmp_path):
    metrics = bsms.Run(tiny_run).rollout(out=tmp_path, threads=1)
    data = bsms.Dataset(tmp_path / "test.h5")
    dt = data.meta["frame_dt"]
    trajectories = []
    for t in range(len(data)):
        pred = data.read(t, "world_pos").astype(np.float64)
        true = data.read(t, "target_world_pos").astype(np.float64)
        # Steps predict frames 2, 3, ...; velocities from the model's own previous frame.
        pos = ((pred[2:] - true[2:]) ** 2).mean(axis=(1, 2))
        vel = ((((pred[2:] - pred[1:-1]) - (true[2:] - true[1:-1])) / dt) ** 2).mean(axis=(1, 2))
        trajectories.append({"world_pos": pos, "velocity": vel})
    assert_tables_equal(metrics["rmse_trajectory_mean"], table_by_hand(trajectories))
    assert set(metrics["rmse_trajectory_mean"]) == {"1", "all"}  # 6 steps per trajectory


def test_eulerian_table_on_the_cylinder_fixture(tmp_path):
    data_dir = tmp_path / "cylinder_flow"
    shutil.copytree(FIXTURES / "cylinder_flow", data_dir)
    run = tmp_path / "run"
    cli("train", REPO / "configs/train/cylinder-mgn.json", "--set", f"data={data_dir}",
        "--set", "steps=6", "--set", "valid_every=6", "--set", "valid_samples=2",
        "--set", "normalizer_steps=3", "--set", "model.latent=16", "--threads", 1,
        "--out", run)
    cli("rollout", run, "--threads", 1, "--out", tmp_path / "r")
    metrics = json.loads((tmp_path / "r/metrics.json").read_text())
    rolled = bsms.Dataset(tmp_path / "r/test.h5")
    trajectories = []
    for t in range(len(rolled)):
        errors = {}
        for field in ("velocity", "pressure"):
            pred = rolled.read(t, field).astype(np.float64)
            true = rolled.read(t, "target_" + field).astype(np.float64)
            errors[field] = ((pred[1:] - true[1:]) ** 2).mean(axis=(1, 2))  # frame 0 is given
        trajectories.append(errors)
    expected = table_by_hand(trajectories)
    assert_tables_equal(metrics["rmse_trajectory_mean"], expected)
    assert set(expected) == {"1", "10", "20", "all"}  # 24 frames: 23 steps
