"""Small meshes for the tests: structured grids with jittered nodes, and MSH 2.2 files of them."""

import numpy as np


def grid_2d(nx, ny, jitter=0.0, seed=0):
    """Triangulated rectangle: (nx + 1)(ny + 1) nodes, 2 nx ny triangles."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(nx + 1, dtype=float), np.arange(ny + 1, dtype=float))
    points = np.stack([x.ravel(), y.ravel()], axis=1)
    points += jitter * rng.uniform(-0.5, 0.5, points.shape)
    cells = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 1, a + nx + 2
            cells += [(a, b, d), (a, d, c)] if (i + j) % 2 == 0 else [(a, b, c), (b, d, c)]
    return points, np.array(cells, dtype=np.int64)


def grid_3d(n):
    """Unit cube in n^3 cubes of 6 tetrahedra each (Freudenthal)."""
    idx = lambda i, j, k: (k * (n + 1) + j) * (n + 1) + i
    g = np.arange(n + 1, dtype=float)
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) / n
    paths = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]
    cells = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                for path in paths:
                    c = [i, j, k]
                    tet = [idx(*c)]
                    for axis in path:
                        c[axis] += 1
                        tet.append(idx(*c))
                    cells.append(tet)
    return points, np.array(cells, dtype=np.int64)


def write_msh22(path, points, cells):
    """An ASCII MSH 2.2 file of the mesh (node tags 1..N, z = 0 in 2-D)."""
    element_type = {3: 2, 4: 4}[cells.shape[1]]
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(points))
        for i, p in enumerate(points):
            xyz = list(p) + [0.0] * (3 - len(p))
            f.write("%d %.17g %.17g %.17g\n" % (i + 1, *xyz))
        f.write("$EndNodes\n$Elements\n%d\n" % len(cells))
        for e, c in enumerate(cells):
            f.write("%d %d 2 1 1 %s\n" % (e + 1, element_type, " ".join(str(v + 1) for v in c)))
        f.write("$EndElements\n")
