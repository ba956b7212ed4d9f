// Multilevel graphs per mesh topology, built with the bi-stride builder on first use and cached
// on disk (beside the dataset when writable, else in the run folder). No LibTorch: `bsms
// preprocess --data` fills the cache with it; GraphStore (graph_store.hpp) adds the model tensors.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "preprocess/multilevel_graph.hpp"

namespace bsms {

struct CachedMultilevel {
  std::string key;              // hash of the mesh topology (cells and node count)
  MultilevelGraph multilevel;   // exactly `levels` levels
  bool from_cache = false;      // read from a cache folder rather than built
  RowMatrixXd mesh_pos;         // [N, dim] reference positions
  double mean_edge_length = 0;  // over mesh edges, in mesh_pos units
};

// 64-bit hash of a mesh's topology (node count, cell size, cell node ids; byte-wise FNV-1a
// steps with FNV's 64-bit prime, but the offset basis 1469598103934665603, a digit short of FNV's
// 14695981039346656037: kept as it is, since cache file names on disk are built from it), as 16
// hex digits.
std::string topology_key(const TrajectoryMesh& mesh);

class MultilevelCache {
 public:
  // `levels` >= 1 is the exact level count of every graph; `cache_dirs` are tried in order.
  // `rng_seed`: random seeding's generator seed. A cache entry that cannot be read, or that does
  // not match, is rebuilt with a one-line warning; when no folder takes the new entry, a one-line
  // warning says the graph stays in memory only, unless `require_write` (`bsms preprocess
  // --data`, whose product is the cache): then that is an IoError.
  MultilevelCache(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
                  uint64_t rng_seed = 0, bool require_write = false);
  // The mesh's graph from the first cache folder that holds a matching one, else built and
  // written to the first folder that takes it. Not memoised: the caller keeps what it reuses.
  // Threads may call it at once for different meshes.
  CachedMultilevel load_or_build(const TrajectoryMesh& mesh);
  int levels() const { return levels_; }

 private:
  Seeding seeding_;
  int levels_;
  uint64_t rng_seed_;
  std::vector<std::string> cache_dirs_;
  bool require_write_;
  std::atomic<bool> warned_write_{false};  // the in-memory-only warning is said once
};

// File name of a cached multilevel graph: "<seeding>-L<levels>-<topology key>.h5", with the seed
// for random seeding ("random-s<seed>-L..."), whose graphs differ by seed. Written by
// `bsms preprocess --data` and by training on first use; read by training and rollout.
std::string multilevel_cache_name(Seeding seeding, int levels, const std::string& key,
                                  uint64_t rng_seed = 0);

// The level count `--levels auto` chooses for a mesh (preprocess rule).
int auto_levels(const TrajectoryMesh& mesh, Seeding seeding);

// A Mesh (core) from a dataset mesh, validated.
Mesh to_mesh(const TrajectoryMesh& mesh);

}  // namespace bsms
