// Hard-case experiments on trained runs (thesis §4.4.3-4.4.4): zero-shot inference on
// larger meshes, seeding sensitivity at test time (Table 4.8) and long rollouts. Each writes
// OUT/metrics.json, OUT/<name>.md (a report section whose images are under OUT/plots/) and the
// rollouts it ran under OUT/rollouts/.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/config.hpp"
#include "core/physical_projection.hpp"

namespace bsms {

struct HardCaseRequest {
  std::vector<std::string> runs;  // trained run folders (bsms train)
  std::string out;
  std::string split = "test";
  int64_t max_trajectories = 0;  // 0: all of the split
  int threads = 0;
  bool quiet = false;
  // Constraints projected after each predicted step of every rollout (bsms rollout --project).
  ProjectionOptions projection;
};

// Rolls every run out on its own test split and on `data` (meshes at least 4x larger than any
// training mesh; the ratio is measured and reported, and below 4 is an InputError).
Json zero_shot_experiment(const HardCaseRequest& request, const std::string& data,
                          double min_ratio = 4.0);

// Rolls each BSMS run out with the multilevel graphs of every seeding (minave, closecenter,
// random) and reports RMSE ratios against the seeding the run was trained with; `data` is the
// dataset folder rolled out (empty: each run's own training data folder).
Json seeding_experiment(const HardCaseRequest& request, const std::string& data = "");

// Rolls every run out on `long_data` (trajectories longer than the training horizon) and, when
// `hard_data` is not empty, on harder scenes; reports error growth and stability (diverged
// trajectories, inverted cells, overlap between bodies and nodes outside the walls beside the
// ground truth's) against the step.
Json long_rollout_experiment(const HardCaseRequest& request, const std::string& long_data,
                             const std::string& hard_data);

}  // namespace bsms
