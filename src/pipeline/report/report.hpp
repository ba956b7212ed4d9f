// `bsms report`: the paper-style table (thesis Tables 4.5-4.6) and PNG plots from any runs.
#pragma once

#include <string>
#include <vector>

namespace bsms {

struct ReportRequest {
  std::vector<std::string> runs;  // run folders with <rollout>/metrics.json
  std::string out;                // folder for report.md and plots/
  std::string title = "bsms report";
  // The rollout folder read in each run: "rollout", or e.g. "rollout_symmetric" (bsms rollout
  // --symmetrize) or "rollout_ensemble"; a folder name, not a path.
  std::string rollout = "rollout";
  // Output folder (or its metrics.json) of bsms experiment solver-frontier: the solver at cheaper
  // settings drawn beside the models in the speed-error plot, tabled, and each run compared with
  // them. Empty: none.
  std::string solver_frontier;
};

// Writes OUT/report.md and OUT/plots/*.png (gnuplot): per-model table, rollout RMSE over steps,
// speed against error (solver and models), training loss against wall time, ground truth next to
// prediction for the first test trajectory; with a solver frontier, its settings as a second
// series of the speed-error plot, a table and one sentence per run saying whether a solver
// setting is at least as fast and more accurate. Returns the path of report.md.
std::string write_report(const ReportRequest& request);

}  // namespace bsms
