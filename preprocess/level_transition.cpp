#include "preprocess/level_transition.hpp"

#include <string>

#include "core/error.hpp"

namespace bsms {

namespace {

void check_level(const MultilevelGraph& graph, int level) {
  if (level < 1 || level >= graph.num_levels()) {
    throw InputError("transition: level " + std::to_string(level) + " is not in 1.." +
                     std::to_string(graph.num_levels() - 1));
  }
}

void check_values(size_t values, int channels, int64_t expected_nodes) {
  if (channels < 1 || values != static_cast<size_t>(expected_nodes) * channels) {
    throw InputError("transition: expected " + std::to_string(expected_nodes) + " x " +
                     std::to_string(channels) + " values, got " + std::to_string(values));
  }
}

}  // namespace

std::vector<double> transition_down(const MultilevelGraph& graph, int level,
                                    const std::vector<double>& values, int channels) {
  check_level(graph, level);
  const GraphLevel& fine = graph.levels[level - 1];
  check_values(values.size(), channels, fine.num_nodes());
  const GraphLevel& coarse = graph.levels[level];
  std::vector<double> gathered(values.size(), 0.0);
  for (int64_t i = 0; i < fine.num_nodes(); ++i) {
    for (int64_t e = fine.graph.offsets[i]; e < fine.graph.offsets[i + 1]; ++e) {
      const int64_t j = fine.graph.targets[e];
      for (int c = 0; c < channels; ++c) {
        gathered[j * channels + c] += coarse.down_weight[e] * values[i * channels + c];
      }
    }
  }
  std::vector<double> out(coarse.pooled.size() * channels);
  for (size_t r = 0; r < coarse.pooled.size(); ++r) {
    for (int c = 0; c < channels; ++c)
      out[r * channels + c] = gathered[coarse.pooled[r] * channels + c];
  }
  return out;
}

std::vector<double> transition_up(const MultilevelGraph& graph, int level,
                                  const std::vector<double>& values, int channels) {
  check_level(graph, level);
  const GraphLevel& coarse = graph.levels[level];
  check_values(values.size(), channels, coarse.num_nodes());
  const GraphLevel& fine = graph.levels[level - 1];
  std::vector<double> unpooled(fine.num_nodes() * channels, 0.0);
  for (size_t r = 0; r < coarse.pooled.size(); ++r) {
    for (int c = 0; c < channels; ++c)
      unpooled[coarse.pooled[r] * channels + c] = values[r * channels + c];
  }
  // Edge i->j reversed carries v_j to i with weight down_weight_ij.
  std::vector<double> out(unpooled.size(), 0.0);
  for (int64_t i = 0; i < fine.num_nodes(); ++i) {
    for (int64_t e = fine.graph.offsets[i]; e < fine.graph.offsets[i + 1]; ++e) {
      const int64_t j = fine.graph.targets[e];
      for (int c = 0; c < channels; ++c) {
        out[i * channels + c] += coarse.down_weight[e] * unpooled[j * channels + c];
      }
    }
  }
  return out;
}

}  // namespace bsms
