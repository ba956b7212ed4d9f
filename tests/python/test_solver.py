"""bsms.simulate and bsms.generate against `bsms simulate` and `bsms generate`."""

import filecmp
import json

import h5py
import numpy as np
import pytest

import bsms
from conftest import REPO, cli, cli_error

SCENE = REPO / "configs/scenes/rotating_square.json"
SETS = ["solver.end_time=0.02", "output.frames=5"]


def test_simulate_equals_cli(tmp_path):
    cli("simulate", SCENE, "--out", tmp_path / "cli", "--threads", 1,
        *[a for s in SETS for a in ("--set", s)])
    told = []
    frames = bsms.simulate(SCENE, out=tmp_path / "python", sets=SETS, threads=1,
                           progress=lambda done, total: told.append((done, total)))
    assert told == [(k, 4) for k in range(1, 5)]
    for name in ("frames.h5", "scene.json", "frames.xdmf"):
        assert filecmp.cmp(tmp_path / "cli" / name, tmp_path / "python" / name, shallow=False)
    with h5py.File(tmp_path / "cli/frames.h5", "r") as f:
        np.testing.assert_array_equal(frames["position"], f["frames/position"][()])
        np.testing.assert_array_equal(frames["time"], f["frames/time"][()])
        np.testing.assert_array_equal(frames["mass"], f["particles/mass"][()])
        np.testing.assert_array_equal(frames["energy"], f["frames/energy"][()])
        for name in ("velocity", "stress"):
            if name in f["frames"]:
                np.testing.assert_array_equal(frames[name], f["frames"][name][()])
    assert frames["position"].shape[0] == 5 and frames["summary"]["frames"] == 5
    # The same scene as a dict, without writing files.
    scene = json.loads(SCENE.read_text())
    scene["solver"]["end_time"] = 0.02
    scene["output"]["frames"] = 5
    again = bsms.simulate(scene, threads=1)
    np.testing.assert_array_equal(again["position"], frames["position"])


def test_generate_equals_cli(tmp_path):
    family = REPO / "configs/families/disks2d.json"
    args = ["--trajectories", 3, "--split", "1:1:1", "--set", "frames=6", "--set",
            "sample.count=[2,2]", "--seed", 11]
    cli("generate", family, "--out", tmp_path / "cli", "--threads", 1, *args)
    told = []
    summary = bsms.generate(family, tmp_path / "python", 3, split="1:1:1", seed=11, threads=2,
                            sets=["frames=6", "sample.count=[2,2]"],
                            progress=lambda done, total: told.append((done, total)))
    assert summary["generated"] == 3 and summary["merged"]
    assert sorted(told) == [(1, 3), (2, 3), (3, 3)]
    for split in ("train", "valid", "test"):
        a = bsms.Dataset(tmp_path / "cli", split=split)[0]
        b = bsms.Dataset(tmp_path / "python", split=split)[0]
        for name in ("cells", "mesh_pos", "node_type", "body_id", "world_pos", "velocity"):
            np.testing.assert_array_equal(a[name], b[name])


def test_errors_carry_the_cli_message(tmp_path):
    bad = tmp_path / "bad.json"
    scene = json.loads(SCENE.read_text())
    scene["solver"]["dt"] = -1.0
    bad.write_text(json.dumps(scene))
    with pytest.raises(bsms.InputError) as error:
        bsms.simulate(bad)
    assert str(error.value) == cli_error("simulate", bad, "--out", tmp_path / "out")
    with pytest.raises(bsms.InputError) as error:
        bsms.simulate(SCENE, sets=["solver.no_such_key=1"])
    assert str(error.value) == cli_error("simulate", SCENE, "--out", tmp_path / "out", "--set",
                                         "solver.no_such_key=1")
    with pytest.raises(bsms.InputError):
        bsms.simulate(42)
    with pytest.raises(bsms.InputError):
        bsms.generate(REPO / "configs/families/disks2d.json", tmp_path / "g", 0)
    with pytest.raises(ZeroDivisionError):  # an exception in the callback stops the run
        bsms.simulate(SCENE, sets=SETS, progress=lambda done, total: 1 / 0)
