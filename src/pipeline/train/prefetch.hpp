// Work for the samples of coming training batches done ahead, on a thread of its own: their
// meshes' graph hierarchies (GraphStore) and the first read of their trajectories (which checks
// the stored values and, for TFRecord data, the record's CRC). Training draws its samples
// deterministically (draw_sample), so the prefetcher knows them before the training thread
// asks. It stays at most `lookahead` batches ahead; an error is left for the training thread,
// which meets it itself when it reaches that sample.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "pipeline/graphs/graph_store.hpp"

namespace bsms {

class Prefetcher {
 public:
  // `trajectories(position)`: the trajectories of the batch at `position` (0, 1, ...: the order
  // in which the training thread asks for batches).
  Prefetcher(const Dataset& data, GraphStore& store,
             std::function<std::vector<int64_t>(int64_t position)> trajectories, int64_t lookahead);
  ~Prefetcher();  // stops the thread
  Prefetcher(const Prefetcher&) = delete;
  Prefetcher& operator=(const Prefetcher&) = delete;
  // The training thread is at batch `position`: the prefetcher may work up to position +
  // lookahead.
  void reached(int64_t position);
  int64_t batches_done() const;  // batches prefetched so far

 private:
  void run();

  const Dataset& data_;
  GraphStore& store_;
  std::function<std::vector<int64_t>(int64_t)> trajectories_;
  int64_t lookahead_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  int64_t reached_ = 0;
  int64_t next_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace bsms
