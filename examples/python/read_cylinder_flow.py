"""A DeepMind MeshGraphNets dataset (meta.json + {split}.tfrecord) as NumPy arrays with
bsms.Dataset (docs/python.md, example b). No TensorFlow: bsms reads the TFRecord itself.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/read_cylinder_flow.py [FOLDER]

FOLDER defaults to the repo's small cylinder_flow fixture; the full download
(docs/public-data.md) reads the same way.
"""

import argparse
import pathlib

import numpy as np

import bsms

FIXTURE = pathlib.Path(__file__).resolve().parents[2] / "tests/fixtures/meshgraphnets/cylinder_flow"


def main(path=FIXTURE, split="train", verbose=True):
    say = print if verbose else (lambda *args: None)
    data = bsms.Dataset(path, split=split)
    meta = data.meta
    say(data)
    say(f"layout {meta['layout']}, dim {meta['dim']}, frame_dt {meta['frame_dt']}, "
        f"fields {meta['fields']}")

    # Whole trajectories, one at a time: each is read when the loop reaches it.
    frames, nodes = [], []
    for t, trajectory in enumerate(data):
        velocity = trajectory["velocity"]  # (T, N, 2)
        frames.append(velocity.shape[0])
        nodes.append(velocity.shape[1])
        speed = np.linalg.norm(velocity, axis=-1).mean(axis=1)  # mean speed of each frame
        say(f"trajectory {t}: {velocity.shape[0]} frames, {velocity.shape[1]} nodes, "
            f"{len(trajectory['cells'])} cells; mean speed {speed[0]:.4f} -> {speed[-1]:.4f}")

    # Random access: one frame of the last trajectory, without reading its other frames.
    last = len(data) - 1
    frame = data.frame(last, data.num_frames(last) // 2)
    shapes = {name: tuple(value.shape) for name, value in frame.items()}
    say("one frame:", ", ".join(f"{name} {shape} {frame[name].dtype}"
                                for name, shape in shapes.items()))
    # node_type: 0 fluid, 4 inflow, 5 outflow, 6 wall (MeshGraphNets' NodeType).
    types, counts = np.unique(frame["node_type"], return_counts=True)
    say("node types:", dict(zip(types.tolist(), counts.tolist())))
    return {"trajectories": len(data), "frames": frames, "nodes": nodes, "fields": meta["fields"],
            "frame_shapes": shapes}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("path", nargs="?", default=FIXTURE, help="a MeshGraphNets dataset folder")
    parser.add_argument("--split", default="train", choices=["train", "valid", "test"])
    args = parser.parse_args()
    main(args.path, args.split)
