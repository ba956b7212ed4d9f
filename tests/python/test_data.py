"""bsms.Dataset against the files the CLI writes: a bsms dataset read with h5py, and DeepMind's
TFRecord fixtures against their conversion by `bsms export`."""

import h5py
import numpy as np
import pytest

import bsms
from conftest import FIXTURES, cli, cli_error

STATIC = ("cells", "mesh_pos", "node_type", "body_id")


def h5_trajectory(path, index):
    with h5py.File(path, "r") as f:
        g = f["trajectories/%06d" % index]
        return {name: g[name][()] for name in g}, dict(f.attrs)


def assert_same(python, stored, frames_first=True):
    for name, value in stored.items():
        got = python[name]
        if name not in STATIC and value.ndim == 2:  # scalar fields: (T, N) in the file
            value = value[..., None]
        np.testing.assert_array_equal(got, value, err_msg=name)


def test_bsms_dataset_equals_its_file(tiny_data):
    for split in ("train", "valid", "test"):
        data = bsms.Dataset(tiny_data, split=split)
        stored, attrs = h5_trajectory(tiny_data / f"{split}.h5", 0)
        trajectory = data[0]
        assert_same(trajectory, stored)
        assert data.meta["layout"] == "bsms dataset"
        assert data.meta["dim"] == attrs["dim"] == 2
        assert data.meta["frame_dt"] == pytest.approx(attrs["frame_dt"])
        assert data.meta["fields"] == {"world_pos": 2, "velocity": 2}
        assert data.meta["scene"]["family"] == "disks"
        assert trajectory["parameters"]["family"] == "disks"
        # One frame without the trajectory, and frames one at a time.
        for k in (0, data.num_frames(0) - 1):
            frame = data.frame(0, k)
            for name in data.meta["fields"]:
                np.testing.assert_array_equal(frame[name], trajectory[name][k])
        assert sum(1 for _ in data.frames(0)) == data.num_frames(0) == 8
        np.testing.assert_array_equal(data.read(0, "world_pos", 3, 2),
                                      trajectory["world_pos"][3:5])
    # A split's file opened directly, and iteration.
    whole = bsms.Dataset(tiny_data / "train.h5")
    assert len(whole) == 1 and len(list(whole)) == 1


@pytest.mark.parametrize("name", ["cylinder_flow", "deforming_plate", "airfoil", "flag_simple"])
def test_tfrecord_equals_bsms_export(tmp_path, name):
    source = FIXTURES / name
    cli("export", source, "--xdmf", "--split", "train", "--trajectory", 0, "--out", tmp_path)
    stored, attrs = h5_trajectory(tmp_path / "train_000000.h5", 0)
    data = bsms.Dataset(source, split="train")
    assert data.meta["layout"] == "MeshGraphNets TFRecord"
    assert data.meta["frame_dt"] == pytest.approx(attrs["frame_dt"])
    assert_same(data[0], stored)
    mesh = data.mesh(0)
    assert not mesh["cells"].flags.writeable  # a view of the dataset's own copy


def test_errors_carry_the_cli_message(tmp_path, tiny_data):
    missing = tmp_path / "nothing"
    with pytest.raises(bsms.InputError) as error:
        bsms.Dataset(missing, split="train")
    assert str(error.value) == cli_error("preprocess", "--data", missing)
    with pytest.raises(bsms.InputError) as error:
        bsms.Dataset(tiny_data, split="train").read(0, "pressure")
    assert "no field pressure" in str(error.value)
    with pytest.raises(bsms.InputError):
        bsms.Dataset(tiny_data, split="train").read(0, "world_pos", 6, 5)
    with pytest.raises(IndexError):
        bsms.Dataset(tiny_data, split="train").mesh(1)


def write_public_trajectory(group, frames, offset):
    group["mesh_pos"] = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
    group["cells"] = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    group["node_type"] = np.array([[0], [4], [5], [6]], dtype=np.int32)
    group["velocity"] = (offset + np.arange(frames * 8, dtype=np.float32)).reshape(frames, 4, 2)
    group["pressure"] = np.full((frames, 4, 1), offset, dtype=np.float32)


@pytest.mark.parametrize("layout", ["folder", "single_file"])
def test_public_hdf5_layouts(tmp_path, layout):
    """BSMS-GNN's {split}/{i}.h5 and the PyTorch ports' {split}.h5 with one group each."""
    if layout == "folder":
        (tmp_path / "valid").mkdir()
        for i in range(3):
            with h5py.File(tmp_path / "valid" / f"{i}.h5", "w") as f:
                write_public_trajectory(f, 3 + i, 100 * i)
    else:
        with h5py.File(tmp_path / "valid.h5", "w") as f:
            for i in range(3):
                write_public_trajectory(f.create_group(str(i)), 3 + i, 100 * i)
    data = bsms.Dataset(tmp_path, split="valid")
    assert len(data) == 3 and data.meta["fields"] == {"velocity": 2, "pressure": 1}
    for i, trajectory in enumerate(data):
        assert data.num_frames(i) == 3 + i
        expected = (100 * i + np.arange((3 + i) * 8, dtype=np.float32)).reshape(3 + i, 4, 2)
        np.testing.assert_array_equal(trajectory["velocity"], expected)
        np.testing.assert_array_equal(trajectory["node_type"], [0, 4, 5, 6])
        np.testing.assert_array_equal(data.frame(i, 1)["pressure"], np.full((4, 1), 100 * i))
