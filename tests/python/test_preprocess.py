"""bsms.multilevel, read_multilevel, read_mesh and contact_enhance against the CLI's
`bsms preprocess` (files equal bit for bit) and against brute-force definitions on small meshes."""

import filecmp

import numpy as np
import pytest

import bsms
from conftest import REPO, cli, cli_error
from meshes import grid_2d, grid_3d, write_msh22

CASES = [  # (levels, seeding, thinning, seed)
    ("auto", "minave", "auto", 0),
    ("auto", "closecenter", "auto", 0),
    (3, "minave", "off", 0),
    (4, "random", "on", 7),
]


@pytest.mark.parametrize("levels,seeding,thinning,seed", CASES)
@pytest.mark.parametrize("mesh", ["grid2d", "grid3d"])
def test_file_equals_cli_bit_for_bit(tmp_path, mesh, levels, seeding, thinning, seed):
    points, cells = grid_2d(23, 17, jitter=0.3, seed=1) if mesh == "grid2d" else grid_3d(6)
    msh = tmp_path / "mesh.msh"
    write_msh22(msh, points, cells)
    cli("preprocess", "--mesh", msh, "--out", tmp_path / "cli.h5", "--levels", levels,
        "--seeding", seeding, "--thinning", thinning, "--seed", seed)
    graph = bsms.multilevel(points, cells, levels=levels, seeding=seeding, thinning=thinning,
                            seed=seed)
    graph.save(tmp_path / "python.h5")
    assert filecmp.cmp(tmp_path / "cli.h5", tmp_path / "python.h5", shallow=False)
    # The file read back gives the same levels.
    again = bsms.read_multilevel(tmp_path / "cli.h5")
    assert len(again) == len(graph) and again.seeding == seeding
    for a, b in zip(graph, again):
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])


def test_geometry_through_read_mesh(tmp_path):
    geo = REPO / "configs/geometry/plate_hole.geo"
    cli("preprocess", "--mesh", geo, "--out", tmp_path / "cli.h5", "--seeding", "minave")
    mesh = bsms.read_mesh(geo)
    assert mesh["positions"].shape[1] == 2 and mesh["cells"].shape[1] == 3
    bsms.multilevel(mesh["positions"], mesh["cells"]).save(tmp_path / "python.h5")
    assert filecmp.cmp(tmp_path / "cli.h5", tmp_path / "python.h5", shallow=False)


def test_levels_match_their_definition():
    """Level 0 is the mesh graph; pooled indices, down weights and coarse edges obey the file
    format's rules (docs/design.md "Multilevel graph file")."""
    points, cells = grid_2d(12, 9, jitter=0.2, seed=3)
    graph = bsms.multilevel(points, cells.astype(np.int32), levels=3, thinning="off")
    n = len(points)
    pairs = {(int(c[i]), int(c[j])) for c in cells for i in range(3) for j in range(3) if i != j}
    e0 = graph[0]["edges"]
    assert e0.shape == (2, len(pairs)) and e0.dtype == np.int64
    assert set(zip(e0[0].tolist(), e0[1].tolist())) == pairs
    assert graph[0]["num_nodes"] == n and "pooled" not in graph[0]
    for k in range(1, len(graph)):
        fine, coarse = graph[k - 1], graph[k]
        pooled = coarse["pooled"]
        assert np.all(np.diff(pooled) > 0) and pooled[-1] < fine["num_nodes"]
        assert coarse["down_weight"].shape == (fine["edges"].shape[1],)
        assert coarse["down_weight"].dtype == np.float32
        # Exact A²: kept nodes joined when within 2 hops at the finer level.
        a = np.zeros((fine["num_nodes"],) * 2, dtype=bool)
        a[fine["edges"][0], fine["edges"][1]] = True
        a2 = (a.astype(int) + np.eye(len(a), dtype=int)) @ (a.astype(int) + np.eye(len(a),
                                                                                  dtype=int)) > 0
        np.fill_diagonal(a2, False)
        expected = a2[np.ix_(pooled, pooled)]
        got = np.zeros_like(expected)
        got[coarse["edges"][0], coarse["edges"][1]] = True
        np.testing.assert_array_equal(got, expected)
    # Views of the graph's own memory: read-only.
    with pytest.raises(ValueError):
        graph[1]["pooled"][0] = 0
    assert [row["level"] for row in graph.report] == list(range(len(graph)))


def test_contact_enhance_is_thesis_eq_4_1():
    points, cells = grid_2d(8, 8, jitter=0.1, seed=5)
    graph = bsms.multilevel(points, cells, levels=3, thinning="off")
    contact = np.array([[0, 5, 80, 40], [80, 44, 0, 41]])
    levels = graph.contact_enhance(contact)
    assert len(levels) == len(graph)
    current = {tuple(p) for p in contact.T.tolist()}
    assert set(zip(*levels[0].tolist())) == current
    for k in range(1, len(graph)):
        fine = graph[k - 1]
        n = fine["num_nodes"]
        a = np.eye(n, dtype=int)
        a[fine["edges"][0], fine["edges"][1]] = 1
        c = np.zeros((n, n), dtype=int)
        for s, r in current:
            c[s, r] = 1
        pooled = graph[k]["pooled"]
        expected = ((a @ c @ a) > 0)[np.ix_(pooled, pooled)]
        current = set(zip(*np.nonzero(expected)))
        assert set(zip(*levels[k].tolist())) == {(int(s), int(r)) for s, r in current}


BAD = [  # (positions, cells, keyword arguments, words the message must hold)
    (np.array([["a", "b"]] * 3), [[0, 1, 2]], {}, "positions: expected a floating-point array"),
    (np.zeros((3, 2)), np.array([[0.0, 1.0, 2.0]]), {}, "cells: expected an integer array"),
    (np.zeros((3, 4)), [[0, 1, 2]], {}, "positions: expected shape (N, 1), (N, 2) or (N, 3)"),
    (np.zeros(6), [[0, 1, 2]], {}, "positions: expected 2 dimensions, got shape (6,)"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1, 3]], {}, "positions/cells"),
    ([[0, 0], [1, 0], [np.nan, 1]], [[0, 1, 2]], {}, "positions/cells"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], {"levels": 0}, "levels 0: expected auto or an integer"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], {"seeding": "best"}, "best"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], {"thinning": "maybe"}, "maybe"),
]


@pytest.mark.parametrize("positions,cells,kwargs,words", BAD)
def test_bad_input_raises_input_error(positions, cells, kwargs, words):
    with pytest.raises(bsms.InputError) as error:
        bsms.multilevel(positions, cells, **kwargs)
    assert isinstance(error.value, ValueError)
    assert words in str(error.value)
    assert "\n" not in str(error.value)


def test_file_errors_carry_the_cli_message(tmp_path):
    missing = tmp_path / "missing.msh"
    with pytest.raises(bsms.InputError) as error:
        bsms.read_mesh(missing)
    assert str(error.value) == cli_error("preprocess", "--mesh", missing, "--out",
                                         tmp_path / "x.h5")
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(b"\x89HDF\r\n\x1a\nnot really")
    with pytest.raises(bsms.InputError) as error:
        bsms.read_multilevel(damaged)
    assert str(damaged) in str(error.value)
    with pytest.raises(bsms.InputError) as error:
        bsms.multilevel(*grid_2d(2, 2)).save(tmp_path)
    assert "output is a folder" in str(error.value)


def test_build_releases_the_gil():
    """Another Python thread runs while a build is in C++. Python does not preempt threads here
    (a switch interval of an hour), so the main thread can run during the call only if the call
    itself lets go of the GIL; it then sees the call in progress."""
    import sys
    import threading
    import time

    points, cells = grid_2d(150, 150)  # ~23K nodes: a build of some tenths of a second
    state = {"in_call": False, "seen": 0}

    def build():
        state["in_call"] = True
        bsms.multilevel(points, cells, seeding="minave", threads=1)
        state["in_call"] = False

    interval = sys.getswitchinterval()
    sys.setswitchinterval(3600)
    try:
        worker = threading.Thread(target=build)
        worker.start()
        while worker.is_alive():
            if state["in_call"]:
                state["seen"] += 1
            time.sleep(0.001)  # lets the worker back in once its call returns
        worker.join()
    finally:
        sys.setswitchinterval(interval)
    assert state["seen"] >= 1


def test_threads_hold_for_the_call_only():
    """A call's threads= leaves the caller's OpenMP/torch thread count as it was."""
    torch = pytest.importorskip("torch")
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        bsms.multilevel(*grid_2d(6, 6), threads=2)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)
