"""bsms from Python: bi-stride multilevel graphs, datasets, the UMLS-MPM solver and trained runs.

The C++ core of the bsms command-line tool, with NumPy arrays in and out (docs/python.md):

    import bsms
    levels = bsms.multilevel(positions, cells)            # the bi-stride hierarchy of a mesh
    data = bsms.Dataset("runs/data", split="train")       # any layout `bsms info` reads
    frames = bsms.simulate("configs/scenes/colliding_disks.json")   # one UMLS-MPM scene
    run = bsms.Run("runs/demo/bsms")                      # a trained run: predict, rollout

Errors are bsms.InputError (a ValueError), bsms.NumericalError and bsms.IoError, with the message
the CLI prints for the same failure. Long calls release the GIL; calls into the library run one at
a time (libhdf5 is not thread-safe).
"""

import json as _json
import os as _os
import warnings as _warnings

from ._errors import InputError, IoError, NumericalError

try:
    from ._paths import GMSH_WORKER as _GMSH_WORKER

    # The child process that runs gmsh: beside the executable for the CLI, here from the build.
    if not _os.environ.get("BSMS_GMSH_WORKER") and _os.access(_GMSH_WORKER, _os.X_OK):
        _os.environ["BSMS_GMSH_WORKER"] = _GMSH_WORKER
except ImportError:  # pragma: no cover - a package assembled by hand
    pass


def _prepare_openmp():
    """The CLI's OpenMP setting: threads wait passively (after a short spin) at barriers, so
    serial work between parallel regions keeps its core (2x faster on 2 cores). libgomp reads it
    once, when it loads (with bsms._core below, or earlier with torch), so it is set here unless
    the caller chose one; when libgomp is already loaded, only a warning can help."""
    if "OMP_WAIT_POLICY" in _os.environ or "GOMP_SPINCOUNT" in _os.environ:
        return
    try:
        with open("/proc/self/maps") as maps:
            loaded = any("libgomp" in line for line in maps)
    except OSError:  # pragma: no cover - not Linux
        return
    if loaded:
        _warnings.warn("bsms: OpenMP (libgomp) was loaded before bsms, e.g. by importing torch "
                       "first, with threads that spin at barriers; for bsms's speed set "
                       "OMP_WAIT_POLICY=PASSIVE before Python starts, or import bsms first",
                       RuntimeWarning, stacklevel=3)
    else:
        _os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
        _os.environ["GOMP_SPINCOUNT"] = "100000"


_prepare_openmp()

from . import _core  # noqa: E402  (after the OpenMP setting)
from ._core import Multilevel, read_mesh, read_multilevel  # noqa: E402

__version__ = "0.1"
__all__ = [
    "InputError", "NumericalError", "IoError", "Multilevel", "multilevel", "read_multilevel",
    "read_mesh", "Dataset", "simulate", "generate", "Run",
]


def multilevel(positions, cells, levels="auto", seeding="minave", thinning="auto", seed=0,
               threads=0):
    """The bi-stride multilevel graph of a mesh, as `bsms preprocess --mesh` builds it.

    positions: (N, dim) float array; cells: (C, dim + 1) integer node indices (triangles in 2-D,
    tetrahedra in 3-D; lines also work). levels: "auto" or the level count including the mesh.
    seeding: "minave" (the training default), "closecenter" or "random" (with `seed`).
    thinning: "auto" (thin coarse levels with levels="auto"), "on" or "off". threads: 0 = all.

    Returns a bsms.Multilevel: a sequence of levels, each a dict with num_nodes, edges (2 x E
    int64: senders, receivers; both directions; sorted), and from level 1 on pooled (the level's
    nodes as indices into the level below) and down_weight (float32, one per edge of the level
    below). .save(path) writes the file `bsms preprocess` writes; .contact_enhance(pairs) carries
    contact edges down the levels; .report has the per-level table the CLI prints.
    """
    return _core.multilevel(positions, cells, levels, seeding, thinning, int(seed), int(threads))


def _config_source(config, what):
    """(path, JSON text) for a config given as a path or as a dict."""
    if isinstance(config, dict):
        return "", _json.dumps(config)
    if isinstance(config, (str, _os.PathLike)):
        return _os.fspath(config), ""
    raise InputError(f"{what}: expected a path or a dict, got {type(config).__name__}")


def simulate(scene, out=None, sets=(), threads=0, progress=None):
    """Runs one UMLS-MPM scene (a scene file's path, or its dict) as `bsms simulate` does.

    Returns a dict of arrays: time (T,), position and velocity (T, P, dim), stress (T, P) when
    the scene records it, energy (T, 3: kinetic, elastic, gravitational), momentum, mass and
    volume0 (P,), the resolved scene (dict) and a summary (steps, wall_s, energy and momentum
    drift). out: a folder to write frames.h5, frames.xdmf and scene.json into as well.
    sets: "key.path=value" overrides like --set. progress(done, total) after each frame.
    Raises bsms.NumericalError naming the step and the particle when a step fails.
    """
    path, text = _config_source(scene, "scene")
    frames = _core._simulate(path, text, list(sets), int(threads), _os.fspath(out or ""),
                             progress)
    frames["scene"] = _json.loads(frames["scene"])
    return frames


def generate(family, out, trajectories, split="80:10:10", seed=0, threads=0, shard="1/1",
             sets=(), progress=None):
    """Generates (or resumes) a dataset of a scene family as `bsms generate` does.

    family: a family file's path or its dict. Writes out/train.h5, valid.h5 and test.h5 (read
    them with bsms.Dataset(out, split)). progress(done, total) after each trajectory (called
    from the solving threads, one call at a time). Returns the summary as a dict.
    """
    path, text = _config_source(family, "family")
    return _core._generate(path, text, _os.fspath(out), int(trajectories), split, int(seed),
                           int(threads), shard, list(sets), progress)


class Dataset:
    """Random access to the trajectories of a dataset split, as NumPy arrays.

    `path` is a dataset folder (with `split`: train, valid or test; bsms's DIR/{split}.h5,
    DeepMind's meta.json + {split}.tfrecord, BSMS-GNN's {split}/{i}.h5 or the PyTorch ports'
    {split}.h5) or one file or folder of a split itself (split=None).

        data = bsms.Dataset("datasets/cylinder_flow", split="valid")
        data.meta                      # layout, dim, frame_dt, fields {name: width}, scene ...
        len(data), data.num_frames(0)
        data.mesh(0)                   # cells, mesh_pos, node_type, body_id (read-only views)
        data.frame(0, 10)              # mesh + every field at frame 10, (N, width) each
        data.read(0, "world_pos", 5, 3)   # frames 5..7 of one field, (3, N, width)
        for trajectory in data: ...    # dicts: mesh + every field (T, N, width) + seed ...

    A frame is read without reading the rest of its trajectory; the first read of a trajectory
    checks its values (finite, in range) as every bsms command does.
    """

    def __init__(self, path, split=None):
        path = _os.fspath(path)
        if split is not None:
            self._data = _core._Dataset.open_split(path, split)
        elif _os.path.isdir(path) and _core._Dataset.has_split(path, "train") and not \
                _os.path.exists(_os.path.join(path, "0.h5")):
            self._data = _core._Dataset.open_split(path, "train")
        else:
            self._data = _core._Dataset(path)
        self.split = split

    @property
    def meta(self):
        d = self._data
        return {
            "location": d.location, "layout": d.layout, "dim": d.dim, "frame_dt": d.frame_dt,
            "collision_radius": d.collision_radius, "simulator": d.simulator,
            "scene": _json.loads(d.scene), "fields": d.fields,
            "trajectories": d.num_trajectories,
        }

    def __len__(self):
        return self._data.num_trajectories

    def num_frames(self, trajectory):
        return self._data.num_frames(trajectory)

    def mesh(self, trajectory):
        return self._data.mesh(trajectory)

    def read(self, trajectory, field, start=0, count=None):
        if count is None:
            count = self._data.num_frames(trajectory) - start
        return self._data.read(trajectory, field, start, count)

    def frame(self, trajectory, frame):
        """The mesh and every field at one frame: (N, width) arrays."""
        out = dict(self._data.mesh(trajectory))
        for name in self._data.fields:
            out[name] = self._data.read(trajectory, name, frame, 1)[0]
        return out

    def frames(self, trajectory):
        """The frames of a trajectory one at a time (each read when reached)."""
        for k in range(self._data.num_frames(trajectory)):
            yield self.frame(trajectory, k)

    def trajectory(self, trajectory):
        """The mesh, every field (T, N, width), seed, parameters (dict) and solver_wall_s."""
        out = dict(self._data.mesh(trajectory))
        for name in self._data.fields:
            out[name] = self.read(trajectory, name)
        out["seed"] = self._data.seed(trajectory)
        out["parameters"] = _json.loads(self._data.parameters(trajectory))
        out["solver_wall_s"] = self._data.solver_wall_s(trajectory)
        return out

    def __getitem__(self, trajectory):
        if trajectory < 0:
            trajectory += len(self)
        return self.trajectory(trajectory)

    def __iter__(self):
        for t in range(len(self)):
            yield self.trajectory(t)

    def __repr__(self):
        d = self._data
        return f"bsms.Dataset({d.location!r}: {d.layout}, {d.num_trajectories} trajectories)"


class Run:
    """A run folder written by `bsms train` (LibTorch is loaded when the first one is opened).

        run = bsms.Run("runs/demo/bsms")
        metrics = run.rollout(split="test")      # what `bsms rollout` writes to metrics.json
        nxt = run.predict(mesh, [x_prev, x_now])  # one step: positions at t+1, (N, dim)

    data: the dataset folder (default: the run's training data), whose scene gives the walls
    the model's features use and whose `split` predict() is paired with.
    """

    def __init__(self, path, data=None, split="test", seeding=None):
        from . import _torch

        self._torch = _torch
        self.path = _os.fspath(path)
        self._run = _torch._Run(self.path, _os.fspath(data or ""), split, seeding or "")

    @property
    def model_type(self):
        return self._run.model_type

    @property
    def levels(self):
        return self._run.levels

    @property
    def dim(self):
        return self._run.dim

    @property
    def checkpoint(self):
        """The checkpoint predict() uses: "best" (selected by validation rollouts) or "latest"."""
        return self._run.checkpoint

    @property
    def history(self):
        """Velocities the model sees: predict() uses the last history + 1 positions given."""
        return self._run.history

    @property
    def config(self):
        with open(self._run.config_path) as f:
            return _json.load(f)

    @property
    def data(self):
        return Dataset(self._run.data)

    def predict(self, mesh, positions, prescribed=None, threads=0):
        """One step of the learned simulator: the world positions at t+1, (N, dim) float32.

        mesh: a dict like bsms.Dataset.mesh() gives (cells, mesh_pos, node_type, body_id).
        positions: the world positions (N, dim) of the last frames, oldest first, at least 2
        (x_{t-1}, x_t; more for history > 1). prescribed: positions at t+1 of the nodes the
        scene drives (fixed and moving nodes; default: where they are at t).
        """
        return self._run.predict(mesh, list(positions), prescribed, int(threads))

    def rollout(self, split="test", data=None, out=None, max_trajectories=0, max_steps=0,
                seeding=None,
                one_step=False, project=None, threads=0):
        """Rolls the model out as `bsms rollout` does and returns its metrics.json as a dict.

        Writes out (default RUN/rollout)/<split>.h5 with the predicted and true positions
        (bsms.Dataset reads it), an XDMF per trajectory and metrics.json. project: e.g.
        "walls,cells,contact" or "all" (--project). max_trajectories, max_steps: 0 = all.
        """
        if isinstance(project, (list, tuple)):
            project = ",".join(project)
        text = self._torch._rollout(self.path, split, _os.fspath(data or ""), seeding or "",
                                    _os.fspath(out or ""), int(max_trajectories),
                                    int(max_steps),
                                    bool(one_step), project or "", int(threads))
        return _json.loads(text)

    def __repr__(self):
        return f"bsms.Run({self.path!r}: {self.model_type}, {self.levels} levels)"
