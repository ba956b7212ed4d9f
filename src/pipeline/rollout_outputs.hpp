// What the Lagrangian rollout (rollout.cpp) and the Eulerian one (rollout_eulerian.cpp) share:
// where the outputs go, the XDMF companions of the predicted trajectories, and the figures of a
// run copied into its rollout metrics.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/rollout.hpp"
#include "pipeline/rollout_metrics.hpp"

namespace bsms::rollout_outputs {

// RUN/rollout, or the request's --out folder: the predicted trajectories and metrics.json.
std::filesystem::path out_dir(const RolloutRequest& request);

// The XDMF companions of a written rollout file (SPLIT_000000.xdmf, ...) beside it.
void write_xdmf_files(const std::string& out_h5, const std::filesystem::path& out_dir,
                      const std::string& split);

// Training figures of RUN/train_stats.json copied into the metrics (none before a training
// session has finished).
void add_train_stats(RolloutMetrics& metrics, const std::string& run);

// The median of per-step times (0 for none).
double median(std::vector<double> v);

}  // namespace bsms::rollout_outputs
