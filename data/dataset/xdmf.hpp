// XDMF 3 descriptions of dataset trajectories, so ParaView opens the HDF5 data in place.
#pragma once

#include <cstdint>
#include <string>

#include "data/dataset/dataset.hpp"

namespace bsms {

// Writes `xdmf_path` describing trajectory `trajectory` of the bsms dataset file `dataset`:
// a temporal collection over frames, geometry from world_pos (else mesh_pos), topology from
// cells, every other dynamic field as a node attribute. The HDF5 path inside the XDMF is relative
// to the XDMF file's folder. Written atomically.
void write_trajectory_xdmf(const Dataset& dataset, int64_t trajectory,
                           const std::string& xdmf_path);

}  // namespace bsms
