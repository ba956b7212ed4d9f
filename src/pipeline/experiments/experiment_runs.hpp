// What the hard-case experiments (zero_shot.cpp, seeding_sensitivity.cpp, long_rollout.cpp) share:
// the runs they read, dataset statistics, one rollout per (run, data, seeding), RMSE readers of
// rollout metrics and their two kinds of plot.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/config.hpp"
#include "pipeline/experiments/hard_cases.hpp"
#include "pipeline/runs/rollout_metrics.hpp"

namespace bsms::experiments {

// A trained run as the experiments use it (read through RunFolder, strictly).
struct RunInfo {
  std::string dir, label, model, seeding, data;
};
RunInfo run_info(const std::string& dir);
// The request's runs; InputError without runs or --out.
std::vector<RunInfo> run_infos(const HardCaseRequest& request);

// Mesh sizes and lengths of one split of a dataset folder.
struct SplitStats {
  int64_t trajectories = 0, min_nodes = 0, max_nodes = 0, min_frames = 0, redrawn = 0;
  double mean_nodes = 0;
};
SplitStats split_stats(const std::string& dir, const std::string& split);
Json stats_json(const SplitStats& s);

// Rolls `run` out on `data` with `seeding` (empty: the training seeding) into
// OUT/rollouts/<run>-<tag>/ and returns its metrics.
RolloutMetrics run_rollout(const HardCaseRequest& request, const RunInfo& run,
                           const std::string& data, const std::string& seeding,
                           const std::string& tag);

// Figures of a rollout's metrics (NaN when absent): RMSE-all of constant velocity, the world
// position RMSE under `key` (rmse_1, rmse_50, rmse_all), and the RMSE at predicted step `step`.
double rmse_constant_velocity(const RolloutMetrics& metrics);
double rmse(const RolloutMetrics& metrics, const char* key);
double rmse_at(const RolloutMetrics& metrics, size_t step);
// Physical validity beside the inverted cells, as table cells "model / truth" of the worst value
// over steps and trajectories ("–" where it does not apply): the overlap between bodies (fraction
// of the cells' area or volume) and the farthest node outside the walls (m).
std::string overlap_cell(const RolloutMetrics& metrics);
std::string outside_walls_cell(const RolloutMetrics& metrics);

struct Curve {
  std::string label;
  std::vector<double> values;  // per predicted step (step = index + 1)
  std::string style = "lines lw 2";
};
// One line plot of per-step curves into PLOTS/NAME.png; `vlines` are (x, label) markers.
void plot_curves(const std::filesystem::path& plots, const std::string& name,
                 const std::string& title, const std::string& ylabel, bool logy,
                 const std::vector<Curve>& curves,
                 const std::vector<std::pair<double, std::string>>& vlines = {});
// Ground truth and prediction of the last frame of the first trajectory of a rollout file.
void plot_final_frame(const std::string& rollout_h5, const std::filesystem::path& plots,
                      const std::string& name, const std::string& title);

// The request's output folder, created (InputError when it cannot be).
std::filesystem::path make_out(const HardCaseRequest& request);

}  // namespace bsms::experiments
