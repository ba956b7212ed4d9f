#include "pipeline/experiments/experiment_runs.hpp"
#include "pipeline/experiments/hard_cases.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/report/plotting.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {
namespace fs = std::filesystem;
using namespace experiments;

Json zero_shot_experiment(const HardCaseRequest& request, const std::string& data,
                          double min_ratio) {
  const auto runs = run_infos(request);
  const fs::path out = make_out(request);
  const SplitStats large = split_stats(data, request.split);
  Json result = {{"experiment", "zero-shot"}, {"data", data}, {"large", stats_json(large)}};
  std::vector<Curve> curves;
  std::ostringstream table;
  table << "| Run | Test set | Nodes (mean) | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | "
           "Constant velocity RMSE-all (m) | Infer ms/step | Inverted cells (max) | Overlap "
           "between bodies (max, model / truth) | Outside the walls (m, max, model / truth) |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|\n";
  int64_t train_max = 0;
  Json per_run = Json::array();
  std::vector<std::pair<RunInfo, std::pair<double, double>>> rmse_all;  // own, larger meshes
  // Every run's training meshes against the larger ones before the first rollout.
  std::vector<SplitStats> trains;
  for (const auto& run : runs) {
    const SplitStats train = split_stats(run.data, "train");
    const double ratio =
        static_cast<double>(large.min_nodes) / static_cast<double>(train.max_nodes);
    if (ratio < min_ratio)
      throw InputError(data + ": its smallest mesh has " + std::to_string(large.min_nodes) +
                       " nodes, only " + format_number(ratio, 2, Notation::kFixed) +
                       "x the largest training mesh of " + run.dir + " (" +
                       std::to_string(train.max_nodes) +
                       "); expected >= " + format_number(min_ratio, 1, Notation::kFixed) + "x");
    trains.push_back(train);
  }
  for (size_t i = 0; i < runs.size(); ++i) {
    const RunInfo& run = runs[i];
    const SplitStats& train = trains[i];
    train_max = std::max(train_max, train.max_nodes);
    const double ratio =
        static_cast<double>(large.min_nodes) / static_cast<double>(train.max_nodes);
    const RolloutMetrics own = run_rollout(request, run, run.data, "", "own");
    const RolloutMetrics big = run_rollout(request, run, data, "", "large");
    per_run.push_back({{"run", run.dir},
                       {"model", run.model},
                       {"train", stats_json(train)},
                       {"size_ratio_min", ratio},
                       {"in_distribution", to_json(own)},
                       {"zero_shot", to_json(big)}});
    rmse_all.push_back({run, {rmse(own, "rmse_all"), rmse(big, "rmse_all")}});
    for (const auto* m : {&own, &big}) {
      const bool is_big = m == &big;
      table << "| " << run.label << " | "
            << (is_big ? "zero-shot, larger meshes" : "own test split (training sizes)") << " | "
            << format_number(m->num_nodes_mean, 0, Notation::kFixed) << " | "
            << format_number(rmse(*m, "rmse_1"), 3, Notation::kScientific) << " | "
            << format_number(rmse(*m, "rmse_50"), 3, Notation::kScientific) << " | "
            << format_number(rmse(*m, "rmse_all"), 3, Notation::kScientific) << " | "
            << format_number(rmse_constant_velocity(*m), 3, Notation::kScientific) << " | "
            << format_number(m->infer_ms_per_step, 1, Notation::kFixed) << " | "
            << format_number(m->inverted_cells_max, 4, Notation::kFixed) << " | "
            << overlap_cell(*m) << " | " << outside_walls_cell(*m) << " |\n";
      curves.push_back({run.label + (is_big ? ", larger meshes (zero-shot)" : ", own test split"),
                        m->per_step("world_pos"), is_big ? "lines lw 2" : "lines lw 2 dt 2"});
    }
  }
  result["runs"] = per_run;
  result["train_max_nodes"] = train_max;
  result["size_ratio_min"] =
      static_cast<double>(large.min_nodes) / static_cast<double>(std::max<int64_t>(train_max, 1));
  const fs::path plots = out / "plots";
  plot_curves(plots, "zero_shot_rmse", "Zero-shot rollout RMSE on larger meshes", "RMSE (m)", true,
              curves);
  const std::string first_big =
      (out / "rollouts" / (fs::path(runs.front().dir).filename().string() + "-large") /
       (request.split + ".h5"))
          .string();
  plot_final_frame(first_big, plots, "zero_shot_frame",
                   runs.front().label + ": last frame of a zero-shot rollout");

  std::ostringstream md;
  md << "## Zero-shot inference on larger meshes\n\n"
     << "Models trained on meshes of at most " << train_max << " nodes, rolled out without "
     << "retraining on `" << data << "` (" << large.trajectories << " trajectories, "
     << large.min_nodes << "–" << large.max_nodes << " nodes; the smallest is "
     << format_number(result["size_ratio_min"].get<double>(), 1, Notation::kFixed)
     << "× the largest training mesh). The multilevel graphs of the new meshes are built on "
        "first use with the run's seeding and level count.\n\n"
     << table.str() << "\n![zero-shot RMSE](plots/zero_shot_rmse.png)\n\n"
     << "![zero-shot frame](plots/zero_shot_frame.png)\n\n";
  // Reading of the figures: per run, RMSE-all on the larger meshes against the own test split.
  for (const auto& [run, own_big] : rmse_all) {
    const auto [a, b] = own_big;
    md << "- " << run.dir << " (" << run.model << "): RMSE-all "
       << format_number(b, 3, Notation::kScientific) << " m on the larger meshes against "
       << format_number(a, 3, Notation::kScientific) << " m on its own test split ("
       << format_number(b / a, 2, Notation::kFixed) << "×).\n";
  }
  write_text_atomic((out / "zero_shot.md").string(), md.str());
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

}  // namespace bsms
