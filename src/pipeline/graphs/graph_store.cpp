#include "pipeline/graphs/graph_store.hpp"

namespace bsms {

GraphStore::GraphStore(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
                       uint64_t rng_seed, bool require_write)
    : cache_(seeding, levels, std::move(cache_dirs), rng_seed, require_write) {}

const MeshGraphs& GraphStore::get(const TrajectoryMesh& mesh) {
  const std::string key = topology_key(mesh);
  auto it = graphs_.find(key);
  if (it != graphs_.end()) return *it->second;
  auto entry = std::make_unique<MeshGraphs>();
  static_cast<CachedMultilevel&>(*entry) = cache_.load_or_build(mesh);
  entry->hierarchy = make_multilevel_tensors(entry->multilevel, cache_.levels());
  return *graphs_.emplace(key, std::move(entry)).first->second;
}

}  // namespace bsms
