// Non-parametric transitions between adjacent levels (thesis §4.3.2, docs/design.md "Bi-stride
// multilevel building" item 6), on plain arrays: the reference the LibTorch transitions in models/
// are tested against.
#pragma once

#include <vector>

#include "preprocess/multilevel_graph.hpp"

namespace bsms {

// Down, level k-1 -> k: v_j <- sum_{i->j} down_weight_ij v_i over level-(k-1) edges, then keep the
// pooled nodes. `values` is [N_{k-1}, channels] row-major; returns [N_k, channels].
std::vector<double> transition_down(const MultilevelGraph& graph, int level,
                                    const std::vector<double>& values, int channels);

// Up, level k -> k-1: unpool (zeros on nodes not kept), then v_i <- sum_j down_weight_ij v_j over
// the same edges reversed. `values` is [N_k, channels]; returns [N_{k-1}, channels].
std::vector<double> transition_up(const MultilevelGraph& graph, int level,
                                  const std::vector<double>& values, int channels);

}  // namespace bsms
