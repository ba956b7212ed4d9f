#include "pipeline/graphs/graph_store.hpp"

#include <algorithm>

namespace bsms {

namespace {

template <class T>
int64_t vector_bytes(const std::vector<T>& v) {
  return static_cast<int64_t>(v.capacity() * sizeof(T));
}

int64_t tensor_bytes(const torch::Tensor& t) {
  return t.defined() ? static_cast<int64_t>(t.nbytes()) : 0;
}

int64_t edge_index_bytes(const EdgeIndex& e) {
  return tensor_bytes(e.senders) + tensor_bytes(e.receivers) + tensor_bytes(e.sender_offsets) +
         tensor_bytes(e.sender_order) + tensor_bytes(e.receiver_offsets) +
         tensor_bytes(e.receiver_order);
}

}  // namespace

int64_t resident_bytes(const MeshGraphs& g) {
  int64_t bytes = static_cast<int64_t>(sizeof(MeshGraphs)) +
                  static_cast<int64_t>(g.mesh_pos.size() * sizeof(double));
  for (const GraphLevel& level : g.multilevel.levels) {
    bytes += vector_bytes(level.graph.offsets) + vector_bytes(level.graph.targets) +
             vector_bytes(level.pooled) + vector_bytes(level.down_weight) +
             vector_bytes(level.node_weight) +
             static_cast<int64_t>(level.positions.size() * sizeof(double));
  }
  for (const auto& sets : g.hierarchy.edge_sets)
    for (const EdgeIndex& e : sets) bytes += edge_index_bytes(e);
  for (const LevelTransition& t : g.hierarchy.transitions)
    bytes += tensor_bytes(t.down_offsets) + tensor_bytes(t.down_columns) +
             tensor_bytes(t.down_values) + tensor_bytes(t.up_offsets) + tensor_bytes(t.up_columns) +
             tensor_bytes(t.up_values);
  return bytes;
}

GraphStore::GraphStore(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
                       uint64_t rng_seed, bool require_write, int64_t cap_bytes)
    : cache_(seeding, levels, std::move(cache_dirs), rng_seed, require_write),
      cap_bytes_(std::max<int64_t>(cap_bytes, 0)) {}

std::shared_ptr<const MeshGraphs> GraphStore::get(const TrajectoryMesh& mesh) {
  const std::string key = topology_key(mesh);
  {
    std::unique_lock<std::mutex> lock(mutex_);
    built_.wait(lock, [&] { return building_.count(key) == 0; });
    auto it = entries_.find(key);
    if (it != entries_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.position);
      return it->second.graphs;
    }
    building_.insert(key);
  }
  // Made outside the lock, so that other threads get (or make) other entries meanwhile.
  std::shared_ptr<MeshGraphs> made;
  try {
    made = std::make_shared<MeshGraphs>();
    static_cast<CachedMultilevel&>(*made) = cache_.load_or_build(mesh);
    made->hierarchy = make_multilevel_tensors(made->multilevel, cache_.levels());
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    building_.erase(key);
    built_.notify_all();
    throw;
  }
  const int64_t bytes = resident_bytes(*made);
  std::lock_guard<std::mutex> lock(mutex_);
  building_.erase(key);
  lru_.push_front(key);
  entries_[key] = Entry{made, bytes, lru_.begin()};
  stats_.bytes += bytes;
  stats_.peak_bytes = std::max(stats_.peak_bytes, stats_.bytes);
  ++stats_.builds;
  evict_locked(key);
  stats_.entries = static_cast<int64_t>(entries_.size());
  built_.notify_all();
  return made;
}

void GraphStore::evict_locked(const std::string& keep) {
  if (cap_bytes_ <= 0) return;
  while (stats_.bytes > cap_bytes_ && !lru_.empty() && lru_.back() != keep) {
    auto it = entries_.find(lru_.back());
    stats_.bytes -= it->second.bytes;
    entries_.erase(it);
    lru_.pop_back();
    ++stats_.evictions;
  }
}

GraphStore::Stats GraphStore::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace bsms
