// XDMF 3 descriptions of dataset trajectories, so ParaView opens the HDF5 data in place.
#pragma once

#include <cstdint>
#include <string>

#include "data/dataset/dataset.hpp"

namespace bsms {

// The HDF5 file that holds the per-frame views an XDMF file reads: `xdmf_path` + ".h5".
std::string xdmf_views_path(const std::string& xdmf_path);

// Writes `xdmf_path` describing trajectory `trajectory` of the bsms dataset file `dataset`:
// a temporal collection over frames, geometry from world_pos (else mesh_pos), topology from
// cells, every other dynamic field as a node attribute. Public layouts are refused (bsms export
// converts them to a bsms file first).
//
// Every reader of ParaView 5.11 must open it without a warning: the legacy XDMFReader warns on a
// HyperSlab in a Geometry and the Xdmf3 readers crash on HyperSlab items, while none of them
// accepts the other's inline slab syntax. So each frame of a [T, N(, w)] field is its own HDF5
// dataset: a virtual dataset in the views file beside the XDMF (xdmf_views_path) that maps one
// frame of the dataset file, with no copy of the data. Positions and 2- or 3-component fields are
// views of 3 components (the missing ones read as 0): XYZ geometry and "Vector" attributes that
// every reader takes as vectors; wider fields are "Matrix", scalars [N]. Static integer arrays
// (cells, node_type, body_id) are read from the dataset file directly. HDF5 paths are relative
// to the XDMF file's folder. Both files are written atomically, the views first.
void write_trajectory_xdmf(const Dataset& dataset, int64_t trajectory,
                           const std::string& xdmf_path);

}  // namespace bsms
