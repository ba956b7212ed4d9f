"""bsms's bi-stride multilevel graphs in a plain-PyTorch U-Net (docs/python.md, example a).

bsms.multilevel builds the hierarchy of a mesh; the model uses only its arrays: each level's edges
(2, E), pooled and down_weight. The task needs the whole mesh: each node is given one value of a
random field (an unknown constant plus long plane waves) and must predict the field's mean over
all nodes. Around any one node the waves hide the constant; the coarse levels carry averages
across the square in a few layers. With --levels 1 (the mesh alone) the loss stays near 0.8.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/multilevel_pytorch.py --steps 60
"""

import argparse
import time

import numpy as np

import bsms  # before torch: bsms sets OpenMP's wait policy, read when torch loads libgomp
import torch


def square_mesh(n):
    """Unit square in n x n squares of 2 triangles: (n + 1)^2 nodes."""
    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    cells = np.concatenate([np.stack([a, a + 1, a + n + 2], 1),
                            np.stack([a, a + n + 2, a + n + 1], 1)])
    return np.stack([x.ravel(), y.ravel()], axis=1), cells


def mlp(n_in, n_out, latent):
    return torch.nn.Sequential(torch.nn.Linear(n_in, latent), torch.nn.SiLU(),
                               torch.nn.Linear(latent, n_out))


class Level:
    """One level's tensors: edges, their geometry, and the transition from the level below."""

    def __init__(self, level, positions):
        self.n = level["num_nodes"]
        self.senders, self.receivers = torch.from_numpy(level["edges"])
        rel = positions[self.receivers] - positions[self.senders]
        # Coarse edges are longer; scaled per level, every level's edge features look alike.
        self.edge_features = rel / rel.norm(dim=1).mean()
        degree = torch.zeros(self.n).index_add_(0, self.receivers, torch.ones(len(self.receivers)))
        self.inv_degree = (1.0 / degree.clamp(min=1))[:, None, None]
        if "pooled" in level:  # read-only views of the graph: copied, torch wants writable arrays
            self.pooled = torch.from_numpy(np.array(level["pooled"]))
            self.down_weight = torch.from_numpy(np.array(level["down_weight"]))[:, None, None]


def down(h, fine, coarse):
    """v_j <- sum_i w_ij v_i over the finer level's edges i -> j, then keep the pooled nodes."""
    out = torch.zeros_like(h).index_add_(0, fine.receivers, coarse.down_weight * h[fine.senders])
    return out[coarse.pooled]


def up(h, fine, coarse):
    """Unpool (zeros on nodes not kept), then v_i <- sum_j w_ij v_j over the same edges reversed:
    each fine node gets a weighted sum of its kept neighbours."""
    unpooled = h.new_zeros((fine.n,) + h.shape[1:])
    unpooled[coarse.pooled] = h
    return torch.zeros_like(unpooled).index_add_(0, fine.senders,
                                                 coarse.down_weight * unpooled[fine.receivers])


class MessagePassing(torch.nn.Module):
    """h_j += MLP(h_j, mean_i m_ij), m_ij = SiLU(A h_i + B h_j + C (x_j - x_i)): the products are
    taken per node and then gathered per edge, several times cheaper than an MLP on each edge."""

    def __init__(self, latent):
        super().__init__()
        self.sender = torch.nn.Linear(latent, latent)
        self.receiver = torch.nn.Linear(latent, latent, bias=False)
        self.geometry = torch.nn.Linear(2, latent, bias=False)
        self.node = mlp(2 * latent, latent, latent)

    def forward(self, h, level):  # h: (nodes, batch, latent)
        s, r = level.senders, level.receivers
        messages = torch.nn.functional.silu(self.sender(h)[s] + self.receiver(h)[r] +
                                            self.geometry(level.edge_features)[:, None, :])
        # A mean, not a sum: coarse nodes have many more incoming edges than fine ones.
        agg = torch.zeros_like(h).index_add_(0, r, messages) * level.inv_degree
        return h + self.node(torch.cat([h, agg], dim=-1))


class BiStrideUNet(torch.nn.Module):
    """Message passing on each level going down, and again coming up with skip connections."""

    def __init__(self, levels, n_in, latent):
        super().__init__()
        self.levels = levels
        self.encode = mlp(n_in, latent, latent)
        self.down_mp = torch.nn.ModuleList(MessagePassing(latent) for _ in levels)
        self.up_mp = torch.nn.ModuleList(MessagePassing(latent) for _ in levels[:-1])
        self.decode = mlp(latent, 1, latent)

    def forward(self, x):
        h, skips = self.encode(x), []
        for k, level in enumerate(self.levels):
            h = self.down_mp[k](h, level)
            skips.append(h)
            if k + 1 < len(self.levels):
                h = down(h, level, self.levels[k + 1])
        for k in reversed(range(len(self.levels) - 1)):
            h = up(h, self.levels[k], self.levels[k + 1]) + skips[k]
            h = self.up_mp[k](h, self.levels[k])
        return self.decode(h).squeeze(-1)


def random_fields(xy, batch, rng, modes=4):
    """Fields c + waves of wavelength 0.35-1, (nodes, batch, 1), and their means, (nodes, batch)."""
    # Constants spread evenly over -1.5..1.5: each batch weighs alike, so the curve is smoother.
    c = rng.permutation(np.linspace(-1.5, 1.5, batch))
    k = rng.integers(-2, 3, size=(batch, modes, 2))
    k[np.abs(k).sum(-1) == 0] = 1
    phase = rng.uniform(0, 2 * np.pi, size=(batch, modes))
    a = 1.5 * rng.normal(size=(batch, modes))
    waves = a * np.sin(2 * np.pi * np.einsum("nd,bmd->nbm", xy.numpy(), k) + phase)
    f = torch.tensor(c + waves.sum(-1), dtype=torch.float32)
    return f[..., None], f.mean(0, keepdim=True).expand_as(f)


def main(steps=60, seed=0, verbose=True, levels=6, n=32, batch=8):
    torch.manual_seed(seed)
    torch.set_num_threads(2)
    rng = np.random.default_rng(seed)
    points, cells = square_mesh(n)
    # An explicit level count: "auto" stops while a level still has over a hundred nodes; six
    # levels end with a handful of nodes joined to each other, one layer across the square.
    # threads=2 as well: bsms and torch share OpenMP, and threads=0 would set torch's to all cores.
    graph = bsms.multilevel(points, cells, levels=levels, threads=2)
    if verbose:
        print("levels (nodes, edges):", [(row["nodes"], row["edges"]) for row in graph.report])

    # A coarse level's positions are those of its kept nodes.
    positions = [torch.tensor(points, dtype=torch.float32)]
    for k in range(1, len(graph)):
        positions.append(positions[-1][torch.from_numpy(np.array(graph[k]["pooled"]))])
    model = BiStrideUNet([Level(graph[k], positions[k]) for k in range(len(graph))], 1, latent=16)
    optimizer = torch.optim.Adam(model.parameters(), lr=5e-3)

    losses, start = [], time.perf_counter()
    for step in range(steps):
        x, target = random_fields(positions[0], batch, rng)  # a batch: (nodes, batch, features)
        loss = torch.nn.functional.mse_loss(model(x), target)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
        if verbose and (step % 10 == 0 or step == steps - 1):
            print(f"step {step:4d}  loss {loss.item():.4f}  ({time.perf_counter() - start:.1f} s)")
    return losses


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--levels", type=int, default=6, help="levels, the mesh included")
    args = parser.parse_args()
    main(steps=args.steps, seed=args.seed, levels=args.levels)
