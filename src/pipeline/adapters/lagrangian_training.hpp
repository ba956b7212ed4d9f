// Lagrangian training samples: a frame of a trajectory as the state the adapter makes a batch
// of, with the true frames around it (lagrangian.hpp).
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <memory>

#include "data/dataset/dataset.hpp"
#include "pipeline/adapters/adapter.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/graphs/graph_store.hpp"

namespace bsms {

struct LoadedSample {
  FrameState state;
  torch::Tensor next;
  torch::Tensor truth;  // [before + 3, N, dim]: the true frames t-1-before .. t+1
  std::shared_ptr<const MeshGraphs> graphs;  // keeps state.graphs alive (the store may evict)
};

// Sample `ref` (frame t) with the state at frames t-1-before and t-before (the truth; before > 0
// for pushforward, which rolls it on to t) and the true next frame t+1; with `history` > 1 also
// the history - 1 frames before t-1-before that the trajectory has (FrameState::older).
LoadedSample load_sample(const Dataset& data, GraphStore& store, const SampleRef& ref,
                         int64_t before = 0, int history = 1);

}  // namespace bsms
