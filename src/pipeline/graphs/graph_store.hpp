// Multilevel graphs per mesh topology with their model tensors, in memory: the graphs come from
// MultilevelCache (graph_cache.hpp, on disk), the tensors are made once per topology. A memory
// cap turns the store into an LRU cache (a split of a thousand meshes need not stay resident);
// entries are handed out as shared pointers, so an evicted entry lives on while a batch uses it.
// Thread-safe: a prefetching thread may build entries while the training thread reads others.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "pipeline/graphs/graph_cache.hpp"
#include "pipeline/graphs/multilevel_tensors.hpp"

namespace bsms {

struct MeshGraphs : CachedMultilevel {
  MultilevelTensors hierarchy;  // tensors of `multilevel`, mesh edges only
};

// Bytes an entry holds (graph arrays and tensors; the estimate the cap counts).
int64_t resident_bytes(const MeshGraphs& graphs);

class GraphStore {
 public:
  // As MultilevelCache's arguments; `cap_bytes` > 0 evicts the least recently used entries
  // beyond it (the entry just asked for always stays), 0 keeps every entry.
  GraphStore(Seeding seeding, int levels, std::vector<std::string> cache_dirs,
             uint64_t rng_seed = 0, bool require_write = false, int64_t cap_bytes = 0);
  // The mesh's entry, loaded or built on first use (by this thread, or waited for when another
  // thread is building it).
  std::shared_ptr<const MeshGraphs> get(const TrajectoryMesh& mesh);
  int levels() const { return cache_.levels(); }

  struct Stats {
    int64_t entries = 0;
    int64_t bytes = 0;       // resident, as resident_bytes counts
    int64_t peak_bytes = 0;  // the most resident at once (an entry's arrival counted before
                             // the evictions it causes)
    int64_t builds = 0;      // entries made (loaded from disk or built)
    int64_t evictions = 0;
  };
  Stats stats() const;

 private:
  struct Entry {
    std::shared_ptr<const MeshGraphs> graphs;
    int64_t bytes = 0;
    std::list<std::string>::iterator position;  // in lru_
  };
  void evict_locked(const std::string& keep);

  MultilevelCache cache_;
  int64_t cap_bytes_;
  mutable std::mutex mutex_;
  std::condition_variable built_;
  std::map<std::string, Entry> entries_;
  std::list<std::string> lru_;      // most recently used first
  std::set<std::string> building_;  // keys a thread is making now
  Stats stats_;
};

}  // namespace bsms
