// Multilevel graphs per mesh topology with their model tensors, in memory for the whole run: the
// graphs come from MultilevelCache (graph_cache.hpp, on disk), the tensors are made once per
// topology.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "pipeline/graphs/graph_cache.hpp"
#include "pipeline/graphs/multilevel_tensors.hpp"

namespace bsms {

struct MeshGraphs : CachedMultilevel {
  MultilevelTensors hierarchy;  // tensors of `multilevel`, mesh edges only
};

class GraphStore {
 public:
  // As MultilevelCache's arguments.
  GraphStore(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
             uint64_t rng_seed = 0, bool require_write = false);
  const MeshGraphs& get(const TrajectoryMesh& mesh);
  int levels() const { return cache_.levels(); }

 private:
  MultilevelCache cache_;
  std::map<std::string, std::unique_ptr<MeshGraphs>> graphs_;
};

}  // namespace bsms
