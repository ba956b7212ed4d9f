"""What the analysis scripts share: the import check, one-line failures (exit 2), opening a bsms
dataset or rollout file, the interaction-range options and each body's gap to the others.
Imported by the scripts beside it (Python puts a script's own folder on its path)."""
import sys

try:
    import h5py
    import numpy as np
except ImportError as missing:
    print(f"{sys.argv[0]}: {missing} (apt-get install python3-h5py python3-numpy)",
          file=sys.stderr)
    sys.exit(2)


def fail(message):
    print(message, file=sys.stderr)
    sys.exit(2)


def add_range_options(ap):
    """--gap, --wall and --box, with the default scene's ranges: 3 and 2 background cells of
    0.04 m (as the momentum groups use) and its unit box."""
    ap.add_argument("--gap", type=float, default=0.12, help="body-body contact range (m)")
    ap.add_argument("--wall", type=float, default=0.08, help="wall contact range (m)")
    ap.add_argument("--box", type=float, nargs=2, default=[0.0, 1.0], help="box min and max")


def check_ranges(a):
    if not (a.gap > 0 and a.wall > 0 and a.box[1] > a.box[0]):
        fail(f"{sys.argv[0]}: --gap and --wall must be > 0 and --box MIN MAX with MAX > MIN")


def trajectories(path, kind):
    """The trajectories group of a bsms HDF5 file; `kind` names what it should be."""
    try:
        return h5py.File(path, "r")["trajectories"]
    except (OSError, KeyError) as e:
        fail(f"{path}: not a bsms {kind} file ({e})")


def gap_to_others(frame, body, b, ids):
    """Smallest distance from body b's nodes to another body's in one frame [N, dim] (inf alone)."""
    x = frame[body == b]
    return min((np.linalg.norm(x[:, None] - frame[body == o][None], axis=2).min()
                for o in ids if o != b), default=np.inf)


def predicted_and_true(path, name, g):
    """Trajectory `name` (group g) of rollout file `path`: body ids [N], predicted and true world
    positions [F, N, dim] as float64."""
    if "target_world_pos" not in g:
        fail(f"{path}: trajectory {name} has no target_world_pos (not a rollout file)")
    return (g["body_id"][:], g["world_pos"][:].astype(np.float64),
            g["target_world_pos"][:].astype(np.float64))
