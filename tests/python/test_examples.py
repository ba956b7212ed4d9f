"""The examples in examples/python/ (docs/python.md) run and do what they say: each one's main()
called as the script calls it."""

import importlib.util

import numpy as np
import pytest

import bsms
from conftest import FIXTURES, HAS_TORCH, REPO


def example(name):
    path = REPO / "examples" / "python" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"example_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_multilevel_pytorch_learns():
    pytest.importorskip("torch")  # Debian's python3-torch, not bsms's LibTorch: absent without it
    losses = example("multilevel_pytorch").main(steps=60, seed=0, verbose=False)
    assert len(losses) == 60 and all(np.isfinite(losses))
    assert np.mean(losses[-5:]) < 0.5 * np.mean(losses[:5]), losses


def test_read_cylinder_flow_shapes():
    source = FIXTURES / "cylinder_flow"
    found = example("read_cylinder_flow").main(source, split="train", verbose=False)
    data = bsms.Dataset(source, split="train")
    assert found["trajectories"] == len(data) > 0
    assert found["fields"] == data.meta["fields"] == {"velocity": 2, "pressure": 1}
    for t in range(len(data)):
        n = len(data.mesh(t)["mesh_pos"])
        assert found["frames"][t] == data.num_frames(t)
        assert found["nodes"][t] == n
    last = len(data) - 1
    n = len(data.mesh(last)["mesh_pos"])
    shapes = found["frame_shapes"]
    assert shapes["velocity"] == (n, 2) and shapes["pressure"] == (n, 1)
    assert shapes["mesh_pos"] == (n, 2) and shapes["node_type"] == (n,)
    assert shapes["cells"] == data.mesh(last)["cells"].shape


@pytest.mark.skipif(not HAS_TORCH, reason="built without LibTorch")
def test_plot_rollout_writes_a_png(tiny_run, tmp_path):
    png = tmp_path / "rollout.png"
    got = example("plot_rollout").main(tiny_run, png, split="test",
                                       rollout_out=tmp_path / "rollout", threads=1)
    assert str(got) == str(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert bsms.Dataset(tmp_path / "rollout" / "test.h5").meta["fields"]["target_world_pos"] == 2
