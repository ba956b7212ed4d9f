#include "pipeline/experiments/experiment_runs.hpp"
#include "pipeline/experiments/hard_cases.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
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

Json seeding_experiment(const HardCaseRequest& request, const std::string& data) {
  const auto runs = run_infos(request);
  const fs::path out = make_out(request);
  Json result = {{"experiment", "seeding"}};
  Json per_run = Json::array();
  std::ostringstream md;
  md << "## Seeding sensitivity at test time (thesis Table 4.8)\n\n"
     << "A BSMS-GNN trained with one seeding heuristic is rolled out with multilevel graphs built "
        "by each heuristic; ratios are RMSE(test seeding) / RMSE(training seeding), as in the "
        "thesis (its ratios: 1.01–2.04× for random and 1.13–2.21× for the inverse heuristic on "
        "rollouts).\n\n";
  if (!data.empty()) {
    const SplitStats s = split_stats(data, request.split);
    md << "Test set: `" << data << "` (" << s.trajectories << " trajectories, " << s.min_nodes
       << "–" << s.max_nodes << " nodes).\n\n";
  }
  // Each run's own test data opened before the first rollout (a broken one is found now).
  if (data.empty())
    for (const auto& run : runs)
      if (run.model == "bsms") (void)Dataset::open_split(run.data, request.split);
  std::vector<Curve> curves;
  for (const auto& run : runs) {
    if (run.model != "bsms") {
      md << "- " << run.label << ": skipped (a single-level model has no seeding).\n";
      continue;
    }
    std::map<std::string, RolloutMetrics> rows;
    for (const std::string& seeding : seeding_names())
      rows[seeding] =
          run_rollout(request, run, data.empty() ? run.data : data, seeding, "seeding-" + seeding);
    const RolloutMetrics& base = rows.at(run.seeding);
    md << "**" << run.label << "**, trained with " << run.seeding << ":\n\n"
       << "| Seeding @ test | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | Ratio 1-step | Ratio "
          "50-step | Ratio rollout |\n|---|---|---|---|---|---|---|\n";
    Json ratios = Json::object();
    for (const std::string& seeding : seeding_names()) {
      const RolloutMetrics& m = rows.at(seeding);
      const double r1 = rmse(m, "rmse_1") / rmse(base, "rmse_1");
      const double r50 = rmse(m, "rmse_50") / rmse(base, "rmse_50");
      const double rall = rmse(m, "rmse_all") / rmse(base, "rmse_all");
      ratios[seeding] = {{"rmse_1", r1}, {"rmse_50", r50}, {"rmse_all", rall}};
      md << "| " << seeding << (seeding == run.seeding ? " (training)" : "") << " | "
         << format_number(rmse(m, "rmse_1"), 3, Notation::kScientific) << " | "
         << format_number(rmse(m, "rmse_50"), 3, Notation::kScientific) << " | "
         << format_number(rmse(m, "rmse_all"), 3, Notation::kScientific) << " | "
         << format_number(r1, 2, Notation::kFixed) << " | "
         << format_number(r50, 2, Notation::kFixed) << " | "
         << format_number(rall, 2, Notation::kFixed) << " |\n";
      curves.push_back({run.label + ", " + seeding + (seeding == run.seeding ? " (training)" : ""),
                        m.per_step("world_pos"),
                        seeding == run.seeding ? "lines lw 3" : "lines lw 2"});
    }
    double worst = 0;
    for (const auto& [name, r] : ratios.items())
      if (name != run.seeding) worst = std::max(worst, r["rmse_all"].get<double>());
    md << "\nLargest rollout ratio for another seeding: "
       << format_number(worst, 2, Notation::kFixed) << "×.\n\n";
    per_run.push_back(
        {{"run", run.dir}, {"trained_with", run.seeding}, {"rollouts", rows}, {"ratios", ratios}});
  }
  if (per_run.empty())
    throw InputError("experiment seeding: none of the runs is a BSMS-GNN (model.type bsms)");
  result["runs"] = per_run;
  plot_curves(out / "plots", "seeding_rmse",
              "Rollout RMSE with each seeding heuristic at test time", "RMSE (m)", true, curves);
  md << "![seeding RMSE](plots/seeding_rmse.png)\n\n";
  write_text_atomic((out / "seeding.md").string(), md.str());
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

}  // namespace bsms
