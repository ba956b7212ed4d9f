"""A trained run rolled out with bsms.Run and plotted with matplotlib (docs/python.md, example c):
predicted against true node positions at a few frames, and the RMSE of each step against
constant velocity's (the baseline bsms rollout reports beside every model).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/plot_rollout.py RUN rollout.png
"""

import argparse
import os

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import bsms  # noqa: E402


def main(run, out_png, split="test", rollout_out=None, threads=0):
    run = bsms.Run(run, split=split)
    rollout_out = rollout_out or os.path.join(run.path, "rollout")
    metrics = run.rollout(split=split, out=rollout_out, max_trajectories=1, threads=threads)

    # The rollout's file holds the prediction (world_pos) and the truth (target_world_pos).
    predicted = bsms.Dataset(os.path.join(rollout_out, f"{split}.h5"))
    mesh = predicted.mesh(0)
    x = predicted.read(0, "world_pos")
    truth = predicted.read(0, "target_world_pos")
    # rmse_per_step has one entry per predicted frame; the first frames (history) are given.
    curve = np.asarray(metrics["rmse_per_step"]["world_pos"])
    first = len(x) - len(curve)
    frames = sorted({first, (first + len(x) - 1) // 2, len(x) - 1})

    fig, axes = plt.subplots(1, len(frames) + 1, figsize=(4 * (len(frames) + 1), 4))
    for ax, k in zip(axes, frames):
        ax.scatter(truth[k, :, 0], truth[k, :, 1], s=6, c="0.6", label="truth")
        ax.scatter(x[k, :, 0], x[k, :, 1], s=3, c="tab:red", label="bsms")
        if mesh["cells"].shape[1] == 3:  # the predicted mesh's edges in 2-D
            ax.triplot(x[k, :, 0], x[k, :, 1], mesh["cells"], lw=0.2, c="tab:red")
        ax.set_title(f"frame {k}")
        ax.set_aspect("equal")
    axes[0].legend(loc="upper right", fontsize=8)

    # Constant velocity's RMSE is one number over all steps: a line to compare the curve with.
    ax = axes[-1]
    ax.plot(np.arange(first, len(x)), curve, label=f"{run.model_type} (per step)")
    cv = metrics.get("rmse_all_constant_velocity")
    if cv is not None:
        ax.axhline(cv, ls="--", c="0.4", label="constant velocity (all steps)")
    ax.axhline(metrics["rmse_all"]["world_pos"], ls=":", c="tab:blue", label="model (all steps)")
    ax.set_xlabel("frame")
    ax.set_ylabel("RMSE of world_pos")
    ax.legend(fontsize=8)
    fig.suptitle(f"{run.path}: {split}, trajectory 0")
    fig.tight_layout()
    fig.savefig(out_png, dpi=100)
    plt.close(fig)
    return out_png


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", help="a run folder written by bsms train")
    parser.add_argument("out_png")
    parser.add_argument("--split", default="test")
    parser.add_argument("--rollout-out", help="where the rollout's files go (default RUN/rollout)")
    args = parser.parse_args()
    print(main(args.run, args.out_png, args.split, args.rollout_out))
