#include "pipeline/experiments/experiment_runs.hpp"
#include "pipeline/experiments/hard_cases.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
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

namespace {

// The training split of every run, after checking that the long rollouts reach 10x each run's
// training horizon (before the first rollout).
std::vector<SplitStats> check_horizons(const std::vector<RunInfo>& runs, const SplitStats& lng,
                                       const std::string& long_data) {
  std::vector<SplitStats> trains;
  for (const auto& run : runs) {
    const SplitStats train = split_stats(run.data, "train");
    const size_t horizon = static_cast<size_t>(train.min_frames - 2);  // predicted steps
    const size_t steps = static_cast<size_t>(lng.min_frames - 2);
    if (steps < 10 * horizon)
      throw InputError(long_data + ": trajectories of " + std::to_string(lng.min_frames) +
                       " frames give " + std::to_string(steps) +
                       " predicted steps, fewer than 10x the training horizon of " + run.dir +
                       " (" + std::to_string(horizon) + " steps)");
    trains.push_back(train);
  }
  return trains;
}

// What the long rollouts of all runs add to the report: tables, curves and metrics.
struct LongRollouts {
  Json per_run = Json::array();
  std::ostringstream table, projection_table;
  std::vector<Curve> rmse_curves, inverted_curves, overlap_curves;
  size_t horizon_marker = 0;
};

void start_long_tables(LongRollouts& out) {
  out.table << "| Run | Horizon H (steps) | RMSE at H (m) | at 2H | at 5H | at 10H | RMSE-all | "
               "Constant velocity RMSE-all | Inverted cells (max) | Overlap between bodies (max, "
               "model / truth) | Outside the walls (m, max, model / truth) | Diverged |\n"
               "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  out.projection_table
      << "| Run | ms per step (projection included) | Wall corrections per step | "
         "Cells restored per step | Nodes pushed out per step | RMS shift per node "
         "and step (m) | Steps left violated |\n|---|---|---|---|---|---|---|\n";
}

void add_projection_row(std::ostringstream& table, const std::string& label,
                        const RolloutMetrics& m) {
  const ProjectionMetrics& p = *m.projection;
  table << "| " << label << " | " << format_number(m.infer_ms_per_step, 3) << " | "
        << format_number(p.nodes_clamped_per_step, 3) << " | "
        << format_number(p.cells_restored_per_step, 3) << " | "
        << format_number(p.nodes_pushed_out_per_step, 3) << " | "
        << format_number(p.shift_rms, 3, Notation::kScientific) << " | " << p.unconverged_steps
        << " of " << p.steps << " |\n";
}

// One run's long rollout: its table rows, curves and metrics.
void add_long_rollout(const RunInfo& run, size_t horizon, const RolloutMetrics& m,
                      LongRollouts& out) {
  Json row = {{"run", run.dir},
              {"model", run.model},
              {"horizon_steps", horizon},
              {"rollout", to_json(m)},
              {"rmse_at", Json::object()}};
  out.table << "| " << run.label << " | " << horizon;
  for (size_t k : {1, 2, 5, 10}) {
    const double v = rmse_at(m, k * horizon);
    row["rmse_at"][std::to_string(k) + "H"] = std::isfinite(v) ? Json(v) : Json(nullptr);
    out.table << " | " << format_number(v, 3, Notation::kScientific);
  }
  out.table << " | " << format_number(rmse(m, "rmse_all"), 3, Notation::kScientific) << " | "
            << format_number(rmse_constant_velocity(m), 3, Notation::kScientific) << " | "
            << format_number(m.inverted_cells_max, 4, Notation::kFixed) << " | " << overlap_cell(m)
            << " | " << outside_walls_cell(m) << " | " << m.diverged.size() << " of "
            << m.num_trajectories << " |\n";
  if (m.projection) add_projection_row(out.projection_table, run.label, m);
  out.rmse_curves.push_back({run.label, m.per_step("world_pos")});
  out.inverted_curves.push_back({run.label, m.inverted_cells_per_step});
  if (m.validity && m.validity->model.overlap) {
    out.overlap_curves.push_back({run.label, m.validity->model.overlap->per_step});
    if (m.validity->truth.overlap)
      out.overlap_curves.push_back(
          {run.label + ", ground truth", m.validity->truth.overlap->per_step, "lines lw 2 dt 2"});
  }
  out.per_run.push_back(row);
}

void plot_long_rollouts(const fs::path& plots, const LongRollouts& lr) {
  const std::vector<std::pair<double, std::string>> marks = {
      {static_cast<double>(lr.horizon_marker), "training horizon"}};
  plot_curves(plots, "long_rmse", "Rollout RMSE over 10x the training horizon", "RMSE (m)", true,
              lr.rmse_curves, marks);
  plot_curves(plots, "long_inverted", "Predicted cells turned inside out (fraction)",
              "fraction of cells", false, lr.inverted_curves, marks);
  if (!lr.overlap_curves.empty())
    plot_curves(plots, "long_overlap", "Overlap between bodies (fraction of the cells' measure)",
                "fraction of cells", false, lr.overlap_curves, marks);
}

// The report section on the long rollouts; `projected` names the projected constraints.
void write_long_section(std::ostringstream& md, const std::string& projected,
                        const std::string& long_data, const SplitStats& lng,
                        const LongRollouts& lr) {
  md << "## Long rollouts and stability" << (projected.empty() ? "" : ", projected") << "\n\n"
     << (projected.empty()
             ? ""
             : "Every predicted step projected onto the constraints " + projected +
                   " (`bsms rollout --project`, docs/design.md \"Projection\"); the figures "
                   "below are of the projected states.\n\n")
     << "Rollouts on `" << long_data << "` (" << lng.trajectories << " trajectories of "
     << lng.min_frames << " frames; the UMLS-MPM solver produced every one"
     << (lng.redrawn > 0
             ? " after redrawing " + std::to_string(lng.redrawn) + " scenes it stopped on"
             : " without a failure")
     << "). H is the training horizon in predicted steps. Stability: a diverged rollout has a "
        "non-finite state; an inverted cell has its orientation flipped against the first frame "
        "(the solver stops on any). Overlap between bodies: the area or volume where cells of "
        "different bodies overlap, as a fraction of all cells', at the worst step of any "
        "trajectory, predicted / ground truth (the truth's own mesh-level overlap is the "
        "reference); outside the walls: the farthest node beyond the box walls. Constant "
        "velocity: extrapolating each trajectory's first velocity, the reference a model must "
        "beat.\n\n"
     << lr.table.str()
     << (projected.empty() ? ""
                           : "\nWhat the projection corrected:\n\n" + lr.projection_table.str())
     << "\n![long RMSE](plots/long_rmse.png)\n\n"
     << "![inverted cells](plots/long_inverted.png)\n\n"
     << (lr.overlap_curves.empty() ? "" : "![overlap between bodies](plots/long_overlap.png)\n\n");
}

// Every run on the hard scenes and on its own test split: metrics into `result`, a plot and a
// report section appended to `md`.
void hard_scenes(const HardCaseRequest& request, const std::vector<RunInfo>& runs,
                 const std::string& hard_data, const SplitStats& hard, const fs::path& plots,
                 Json& result, std::ostringstream& md) {
  result["hard"] = stats_json(hard);
  std::vector<Curve> hard_curves;
  std::ostringstream hard_table;
  hard_table << "| Run | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | Constant velocity RMSE-all (m) "
                "| Own test split RMSE-all (m) | Inverted cells (max) | Overlap between bodies "
                "(max, model / truth) | Outside the walls (m, max, model / truth) | Diverged |\n"
                "|---|---|---|---|---|---|---|---|---|---|\n";
  Json hard_runs = Json::array();
  for (const auto& run : runs) {
    const RolloutMetrics m = run_rollout(request, run, hard_data, "", "hard");
    const RolloutMetrics own = run_rollout(request, run, run.data, "", "own");
    hard_table << "| " << run.label << " | "
               << format_number(rmse(m, "rmse_1"), 3, Notation::kScientific) << " | "
               << format_number(rmse(m, "rmse_50"), 3, Notation::kScientific) << " | "
               << format_number(rmse(m, "rmse_all"), 3, Notation::kScientific) << " | "
               << format_number(rmse_constant_velocity(m), 3, Notation::kScientific) << " | "
               << format_number(rmse(own, "rmse_all"), 3, Notation::kScientific) << " | "
               << format_number(m.inverted_cells_max, 4, Notation::kFixed) << " | "
               << overlap_cell(m) << " | " << outside_walls_cell(m) << " | " << m.diverged.size()
               << " of " << m.num_trajectories << " |\n";
    hard_curves.push_back({run.label + ", hard scenes", m.per_step("world_pos")});
    hard_curves.push_back(
        {run.label + ", own test split", own.per_step("world_pos"), "lines lw 2 dt 2"});
    hard_runs.push_back({{"run", run.dir}, {"hard", to_json(m)}, {"own", to_json(own)}});
  }
  result["hard_runs"] = hard_runs;
  plot_curves(plots, "hard_rmse", "Rollout RMSE on the solver's hard scenes", "RMSE (m)", true,
              hard_curves);
  md << "### Hard scenes\n\nRollouts on `" << hard_data << "` (" << hard.trajectories
     << " trajectories, " << hard.min_nodes << "–" << hard.max_nodes
     << " nodes), scenes outside the training distribution that are hard for the solver too; "
     << hard.redrawn << " drawn scene(s) stopped the solver and were redrawn.\n\n"
     << hard_table.str() << "\n![hard RMSE](plots/hard_rmse.png)\n\n";
}

}  // namespace

Json long_rollout_experiment(const HardCaseRequest& request, const std::string& long_data,
                             const std::string& hard_data) {
  const auto runs = run_infos(request);
  const fs::path out = make_out(request);
  const SplitStats lng = split_stats(long_data, request.split);
  // Every dataset and horizon checked before the first rollout.
  std::optional<SplitStats> hard;
  if (!hard_data.empty()) hard = split_stats(hard_data, request.split);
  const std::vector<SplitStats> trains = check_horizons(runs, lng, long_data);
  Json result = {{"experiment", "long-rollout"}, {"long", stats_json(lng)}};
  LongRollouts lr;
  start_long_tables(lr);
  for (size_t i = 0; i < runs.size(); ++i) {
    const size_t horizon = static_cast<size_t>(trains[i].min_frames - 2);  // predicted steps
    lr.horizon_marker = std::max(lr.horizon_marker, horizon);
    add_long_rollout(runs[i], horizon, run_rollout(request, runs[i], long_data, "", "long"), lr);
  }
  result["runs"] = lr.per_run;
  const fs::path plots = out / "plots";
  plot_long_rollouts(plots, lr);

  std::string projected;
  for (const std::string& name : projection_names(request.projection))
    projected += (projected.empty() ? "" : ", ") + name;
  std::ostringstream md;
  write_long_section(md, projected, long_data, lng, lr);
  if (hard) hard_scenes(request, runs, hard_data, *hard, plots, result, md);
  write_text_atomic((out / "long_rollout.md").string(), md.str());
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

}  // namespace bsms
