# Opens one XDMF file in one ParaView reader and compares it with its HDF5 source (run by
# paraview_xdmf.sh under pvbatch, one process per file and reader, so a crash names both):
#
#   pvbatch --force-offscreen-rendering paraview_xdmf.py READER XDMF KIND H5 ARRAY
#
# READER: XDMFReader, Xdmf3ReaderS or Xdmf3ReaderT. KIND: "dataset" (H5 is the bsms dataset file
# the XDMF describes, trajectory 000000 in it; ARRAY a dynamic field or node_type) or "frames"
# (H5 is bsms simulate's frames.h5). Checks the number of points, cells and time steps, one
# point's coordinates at the middle frame and the same point's value of the node field ARRAY
# there (vectors: the source's components, then 0 up to 3 components). Prints one line; exit 1
# on a mismatch.
import os
import sys

import h5py
import numpy as np
from paraview import servermanager
from paraview.simple import XDMFReader, Xdmf3ReaderS, Xdmf3ReaderT

reader_name, xdmf, kind, h5, array = sys.argv[1:6]
xdmf = os.path.abspath(xdmf)  # the Xdmf3 readers resolve HDF5 paths against the XDMF's folder

with h5py.File(h5, "r") as f:
    if kind == "dataset":
        g = f["/trajectories/000000"]
        points, cells = g["mesh_pos"].shape[0], g["cells"].shape[0]
        positions = g["world_pos"] if "world_pos" in g else None
        steps = (positions if positions is not None else g[array]).shape[0]
        frame = steps // 2
        node = points // 3
        coords = positions[frame, node] if positions is not None else g["mesh_pos"][node]
        field = g[array]  # [T, N(, w)], or static [N] (node_type, body_id)
        value = np.atleast_1d(field[node] if field.ndim == 1 else field[frame, node])
    else:
        points = cells = f["/particles/mass"].shape[0]
        steps = f["/frames/time"].shape[0]
        frame = steps // 2
        node = points // 3
        coords = f["/frames/position"][frame, node]
        value = np.atleast_1d(f["/frames/" + array][frame, node])
coords = np.pad(coords, (0, 3 - len(coords)))
if len(value) in (2, 3):
    value = np.pad(value, (0, 3 - len(value)))

if reader_name == "XDMFReader":
    reader = XDMFReader(FileNames=[xdmf])
elif reader_name == "Xdmf3ReaderS":
    reader = Xdmf3ReaderS(FileName=[xdmf])
else:
    reader = Xdmf3ReaderT(FileName=[xdmf])
times = reader.TimestepValues
times = list(times) if hasattr(times, "__len__") else ([times] if times is not None else [])
problems = []
if len(times) != steps:
    problems.append(f"{len(times)} time steps, expected {steps}")
reader.UpdatePipeline(times[frame] if frame < len(times) else 0.0)
data = servermanager.Fetch(reader)
if data.IsA("vtkMultiBlockDataSet"):
    data = data.GetBlock(0)
if data.GetNumberOfPoints() != points:
    problems.append(f"{data.GetNumberOfPoints()} points, expected {points}")
if data.GetNumberOfCells() != cells:
    problems.append(f"{data.GetNumberOfCells()} cells, expected {cells}")
if not problems:
    got = np.array(data.GetPoint(node))
    if not np.allclose(got, coords, rtol=1e-6, atol=1e-7):
        problems.append(f"point {node} at frame {frame} is {got}, expected {coords}")
    values = data.GetPointData().GetArray(array)
    if values is None:
        problems.append(f"no point array {array}")
    else:
        got = np.array(values.GetTuple(node))
        if got.shape != value.shape or not np.allclose(got, value, rtol=1e-6, atol=1e-7):
            problems.append(f"{array}[{node}] at frame {frame} is {got}, expected {value}")
name = f"{os.path.basename(xdmf)} in {reader_name}"
if problems:
    print(f"FAIL {name}: " + "; ".join(problems))
    sys.exit(1)
print(f"ok   {name}: {points} points, {cells} cells, {steps} steps, {array} matches at frame {frame}")
