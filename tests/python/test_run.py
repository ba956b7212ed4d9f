"""bsms.Run against `bsms rollout`: the same metrics and predictions from a run the CLI trained."""

import json

import numpy as np
import pytest

import bsms
from conftest import HAS_TORCH, cli, cli_error

pytestmark = pytest.mark.skipif(not HAS_TORCH, reason="built without LibTorch")

# Figures of the machine's state, not of the rollout.
TIMING = {"infer_ms_per_step", "peak_rss_mb_infer", "peak_rss_mb_train", "speedup_vs_solver"}


def without_timing(metrics):
    return {k: v for k, v in metrics.items() if k not in TIMING}


def test_rollout_equals_cli(tiny_run, tmp_path):
    cli("rollout", tiny_run, "--out", tmp_path / "cli", "--threads", 1, "--project", "walls")
    run = bsms.Run(tiny_run)
    assert run.model_type == "bsms" and run.levels == 2 and run.dim == 2
    assert run.checkpoint == "latest"  # trained without checkpoint selection
    metrics = run.rollout(out=tmp_path / "python", threads=1, project=["walls"])
    stored = json.loads((tmp_path / "cli/metrics.json").read_text())
    assert stored["checkpoint"] == "latest" and stored["checkpoint_step"] > 0
    assert without_timing(metrics) == without_timing(stored)
    assert metrics["rmse_all"]["world_pos"] > 0 and metrics["rmse_all_constant_velocity"] > 0
    a = bsms.Dataset(tmp_path / "cli/test.h5")[0]
    b = bsms.Dataset(tmp_path / "python/test.h5")[0]
    np.testing.assert_array_equal(a["world_pos"], b["world_pos"])


def test_predict_is_the_rollouts_step(tiny_run, tmp_path):
    run = bsms.Run(tiny_run)
    run.rollout(out=tmp_path / "r", threads=1)
    predicted = bsms.Dataset(tmp_path / "r/test.h5")[0]
    data = run.data  # the run's training data, test split
    truth = data[0]
    mesh = data.mesh(0)
    x = truth["world_pos"]
    step = run.predict(mesh, [x[0], x[1]], prescribed=x[2], threads=1)
    assert step.shape == x[2].shape and step.dtype == np.float32
    np.testing.assert_allclose(step, predicted["world_pos"][2], rtol=0, atol=1e-6)
    # Its own predictions fed back: the rollout's next frame.
    again = run.predict(mesh, [x[1], step], prescribed=x[3], threads=1)
    np.testing.assert_allclose(again, predicted["world_pos"][3], rtol=0, atol=1e-5)


def test_bad_input(tiny_run, tmp_path):
    run = bsms.Run(tiny_run)
    mesh = run.data.mesh(0)
    x = run.data[0]["world_pos"]
    with pytest.raises(bsms.InputError, match="at least 2 frames"):
        run.predict(mesh, [x[0]])
    with pytest.raises(bsms.InputError, match=r"positions\[1\]: expected shape"):
        run.predict(mesh, [x[0], x[1][:-1]])
    bad = x[1].copy()
    bad[3, 0] = np.nan
    with pytest.raises(bsms.InputError, match="NaN"):
        run.predict(mesh, [x[0], bad])
    broken = dict(mesh)
    broken["cells"] = mesh["cells"].astype(np.float64)
    with pytest.raises(bsms.InputError, match="cells: expected an integer array"):
        run.predict(broken, [x[0], x[1]])
    broken["cells"] = mesh["cells"] + len(x[0])
    with pytest.raises(bsms.InputError, match="cells: cell 0 references node .* outside"):
        run.predict(broken, [x[0], x[1]])  # the message a dataset with that mesh gets
    broken["cells"] = mesh["cells"]
    broken["node_type"] = np.full(len(x[0]), 9)
    with pytest.raises(bsms.InputError, match="node_type of node 0 is 9, expected 0..3"):
        run.predict(broken, [x[0], x[1]])
    missing = tmp_path / "no_run"
    with pytest.raises(bsms.InputError) as error:
        bsms.Run(missing)
    assert str(error.value) == cli_error("rollout", missing)
