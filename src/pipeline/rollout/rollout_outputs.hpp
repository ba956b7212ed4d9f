// What the rollout loop (rollout.cpp) and the solver frontier (experiments/solver_frontier.cpp)
// write alike: where the outputs go, the XDMF companions of the predicted trajectories, and the
// figures of a run copied into its rollout metrics.
#pragma once

#include <torch/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "data/dataset/dataset.hpp"
#include "pipeline/rollout/rollout_request.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/train_config.hpp"
#include "pipeline/runs/train_stats.hpp"

namespace bsms::rollout_outputs {

// RUN/rollout, or the request's --out folder: the predicted trajectories and metrics.json.
std::filesystem::path out_dir(const RolloutRequest& request);

// OUT_DIR/SPLIT.h5, the file the predicted trajectories go to; an InputError when it is the
// dataset being rolled out (`--out` the `--data` folder), which the predictions would replace.
std::string prediction_file(const std::filesystem::path& out_dir, const std::string& split,
                            const Dataset& data);

// A tensor's values as a flat float32 vector (a written trajectory's field).
std::vector<float> to_floats(const torch::Tensor& t);

// The XDMF companions of a written rollout file (SPLIT_000000.xdmf, ...) beside it.
void write_xdmf_files(const std::string& out_h5, const std::filesystem::path& out_dir,
                      const std::string& split);

// What every rollout tallies over its trajectories besides the errors.
struct RolloutTally {
  std::vector<double> infer_ms;  // per predicted step
  double nodes_total = 0;        // summed over the trajectories
  std::vector<DivergedTrajectory> diverged;
};

// The figures every rollout records besides its errors: seeding, median inference time, peak
// memory, mean node count, threads, levels, the diverged trajectories, and the training figures
// of RUN/train_stats.json (`stats`, read with the run folder before the rollout; none before a
// training session has finished).
void add_run_figures(RolloutMetrics& metrics, const RolloutTally& tally, int64_t count,
                     Seeding seeding, int threads, int levels,
                     const std::optional<TrainStats>& stats);

// The median of per-step times (0 for none).
double median(std::vector<double> v);

}  // namespace bsms::rollout_outputs
