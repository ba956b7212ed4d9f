"""bsms against the original BSMS-GNN (github.com/Eydcao/BSMS-GNN, Python, PyTorch) at 2.6K nodes,
alternating in one run: the training and inference step of each, on the same mesh and model size.

    /usr/bin/python3 bench/python/original_bsms.py --original PATH/TO/BSMS-GNN [--build build]
        [--rounds 3] [--threads 2]

PATH/TO/BSMS-GNN is a checkout of the original (tested at accc092); nothing of it is copied here.
Its src/ is imported unmodified; the modules it imports only for logging, plots and MKL's sparse
product (wandb, tabulate, sparse_dot_mkl) are replaced, when not installed, by stand-ins that do
nothing (wandb, tabulate) or call SciPy (the sparse product, used in graph building only).

The case is bench_models' 2.6K: a 65 x 40 rectangle of nodes 1 cm apart, each square cut in two
triangles with alternating diagonals; 5 levels (the original's unet_depth 4, its own bi-stride
graph); latent 128, 2 hidden layers; inputs 3 per node, outputs 2; MSE loss, backward and Adam
(lr 1e-4); inference under torch.inference_mode. Each round times the original in this process
(median of --steps steps after one warm-up), then bench_models' train/bsms/2.6K and
infer/bsms/2.6K in a child process (their median_ms). Both get the same OpenMP wait policy
(OMP_WAIT_POLICY=PASSIVE, GOMP_SPINCOUNT=100000, as bsms sets for itself) and thread count, and
whatever OPENBLAS_CORETYPE the environment has (unset: OpenBLAS picks its kernels for this CPU,
which is the original's best case; the chosen kernels are printed). bsms's own products do not
use OpenBLAS (oneDNN's sgemm, docs/design.md).
"""

import argparse
import ctypes
import json
import os
import statistics
import subprocess
import sys
import time
import types


# The original's best setting found on 2 cores (its inference 170-180 ms against 200-370 with
# a spinning wait or one-threaded OpenBLAS): libgomp's passive wait, OpenBLAS's own threads.
DEFAULT_ORIGINAL_ENV = "OMP_WAIT_POLICY=PASSIVE"


def ensure_environment(original_env):
    """Runs this script under the original's environment (libgomp and OpenBLAS read theirs when
    they load, so this re-executes once), keeping the caller's for bench_models: bsms sets its
    own wait policy unless the caller did."""
    if "ORIGINAL_BSMS_CALLER_ENV" in os.environ:
        return json.loads(os.environ["ORIGINAL_BSMS_CALLER_ENV"])
    env = dict(os.environ, ORIGINAL_BSMS_CALLER_ENV=json.dumps(dict(os.environ)))
    for item in original_env.split():
        key, _, value = item.partition("=")
        env[key] = value
    os.execve(sys.executable, [sys.executable] + sys.argv, env)


def provide_missing_modules():
    import importlib.util

    import scipy.sparse  # noqa: F401

    def stand_in(name, **attrs):
        if importlib.util.find_spec(name) is None:
            module = types.ModuleType(name)
            module.__dict__.update(attrs)
            sys.modules[name] = module

    stand_in("wandb", Image=lambda *a, **k: None, log=lambda *a, **k: None)
    stand_in("tabulate", tabulate=lambda *a, **k: "")
    stand_in("sparse_dot_mkl", dot_product_mkl=lambda a, b: a @ b)


def blas_core():
    try:
        lib = ctypes.CDLL("libopenblas.so.0")
        lib.openblas_get_corename.restype = ctypes.c_char_p
        return lib.openblas_get_corename().decode()
    except OSError:
        return "unknown"


def cpu_name():
    with open("/proc/cpuinfo") as f:
        info = {}
        for line in f:
            if ":" in line:
                key, value = (s.strip() for s in line.split(":", 1))
                info.setdefault(key, value)
    return "{} (family {}, model {})".format(
        info.get("model name", "?"), info.get("cpu family", "?"), info.get("model", "?"))


def rectangle(nx=65, ny=40):
    """bench_models' make_graph for the 2.6K case: positions [N, 2] and edges [2, E] both ways."""
    import numpy as np

    pos = np.zeros((nx * ny, 2))
    pairs = []
    for y in range(ny):
        for x in range(nx):
            i = y * nx + x
            pos[i] = (0.01 * x, 0.01 * y)
            if x + 1 < nx:
                pairs.append((i, i + 1))
            if y + 1 < ny:
                pairs.append((i, i + nx))
            if x + 1 < nx and y + 1 < ny:
                pairs.append((i, i + nx + 1) if (x + y) % 2 == 0 else (i + 1, i + nx))
    e = np.array(pairs).T
    return pos, np.concatenate([e, e[::-1]], axis=1)


class Original:
    """The original's encoder, BSGMP processor and decoder (its BSMS_Simulator without the
    normalisers), on its own bi-stride graph of the rectangle."""

    def __init__(self, src, threads, steps):
        import torch

        sys.path.insert(0, src)
        provide_missing_modules()
        from graph_wrappers import BistrideMultiLayerGraph
        from ops import BSGMP, MLP

        torch.manual_seed(0)
        torch.set_num_threads(threads)
        self.torch = torch
        self.steps = steps
        pos, edges = rectangle()
        depth = 4
        graph = BistrideMultiLayerGraph(edges, depth, pos.shape[0], pos)
        _, flat_edges, ids = graph.get_multi_layer_graphs()
        self.edges_all_levels = int(sum(e.shape[1] for e in flat_edges))
        self.ids = [torch.tensor(i, dtype=torch.long) for i in ids]
        self.gs = [torch.tensor(e, dtype=torch.long) for e in flat_edges]
        self.pos = torch.tensor(pos, dtype=torch.float)
        latent, hidden = 128, 2
        self.encode = MLP(3, latent, latent, hidden, True)
        self.process = BSGMP(depth, latent, hidden, 2)
        self.decode = MLP(latent, latent, 2, hidden, False)
        params = (list(self.encode.parameters()) + list(self.process.parameters()) +
                  list(self.decode.parameters()))
        self.adam = torch.optim.Adam(params, lr=1e-4)
        self.nodes = torch.randn(pos.shape[0], 3)
        self.target = torch.randn(pos.shape[0], 2)

    def forward(self):
        h = self.encode(self.nodes)
        h = self.process(h, self.ids, self.gs, self.pos)
        return self.decode(h)

    def train_step(self):
        self.adam.zero_grad()
        loss = (self.forward() - self.target).square().mean()
        loss.backward()
        self.adam.step()

    def infer_step(self):
        with self.torch.inference_mode():
            self.forward()

    def median_ms(self, step, count):
        step()
        times = []
        for _ in range(count):
            t0 = time.perf_counter()
            step()
            times.append((time.perf_counter() - t0) * 1e3)
        return statistics.median(times)


def bsms_medians(build, threads, caller_env):
    env = dict(caller_env, BSMS_BENCH_THREADS=str(threads))
    out = subprocess.run(
        [os.path.join(build, "bench", "bench_models"),
         "--benchmark_filter=^(train|infer)/bsms/2.6K/", "--benchmark_format=json"],
        check=True, capture_output=True, text=True, env=env).stdout
    result = {}
    for b in json.loads(out)["benchmarks"]:
        result[b["name"].split("/")[0]] = b["median_ms"]
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--original", required=True,
                        help="checkout of github.com/Eydcao/BSMS-GNN (its src/ is imported)")
    parser.add_argument("--build", default="build", help="bsms build folder (bench/bench_models)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--train-steps", type=int, default=10)
    parser.add_argument("--infer-steps", type=int, default=20)
    parser.add_argument("--original-env", default=DEFAULT_ORIGINAL_ENV,
                        help="environment of the original's process (default: %(default)s)")
    args = parser.parse_args()
    caller_env = ensure_environment(args.original_env)
    src = os.path.join(args.original, "src")
    if not os.path.isfile(os.path.join(src, "ops", "BSMS.py")):
        sys.exit("original_bsms.py: {} is not a checkout of BSMS-GNN (no src/ops/BSMS.py)".format(
            args.original))
    bench = os.path.join(args.build, "bench", "bench_models")
    if not os.access(bench, os.X_OK):
        sys.exit("original_bsms.py: {} not found (build bench_models first)".format(bench))

    original = Original(src, args.threads, args.train_steps)
    print("cpu: {}; threads {}; original's environment: {}; its OpenBLAS kernels: {}; its edges "
          "over all levels: {}".format(cpu_name(), args.threads, args.original_env, blas_core(),
                                       original.edges_all_levels))
    print("| round | original train / infer (ms) | bsms train / infer (ms) | ratio train / infer |")
    print("|---|---|---|---|")
    ratios = []
    for r in range(1, args.rounds + 1):
        o_train = original.median_ms(original.train_step, args.train_steps)
        o_infer = original.median_ms(original.infer_step, args.infer_steps)
        b = bsms_medians(args.build, args.threads, caller_env)
        ratios.append((o_train / b["train"], o_infer / b["infer"]))
        print("| {} | {:.1f} / {:.1f} | {:.1f} / {:.1f} | {:.2f}x / {:.2f}x |".format(
            r, o_train, o_infer, b["train"], b["infer"], *ratios[-1]), flush=True)
    print("median ratio: train {:.2f}x, infer {:.2f}x".format(
        statistics.median(x for x, _ in ratios), statistics.median(y for _, y in ratios)))


if __name__ == "__main__":
    main()
