#include "pipeline/experiments/experiment_runs.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "core/error.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/report/plotting.hpp"
#include "pipeline/rollout/rollout.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms::experiments {
namespace fs = std::filesystem;

RunInfo run_info(const std::string& dir) {
  const RunFolder run = RunFolder::open(dir);
  RunInfo r;
  r.dir = dir;
  r.model = run.config.model.type;
  r.seeding = to_string(run.config.model.seeding);
  r.data = run.config.data;
  r.label = run.label();
  return r;
}

std::vector<RunInfo> run_infos(const HardCaseRequest& request) {
  if (request.runs.empty()) throw InputError("experiment: give at least one run folder");
  if (request.out.empty()) throw InputError("experiment: --out is required");
  std::vector<RunInfo> runs;
  for (const auto& dir : request.runs) runs.push_back(run_info(dir));
  return runs;
}

namespace {

// The first character of trajectory parameters written as a JSON object.
constexpr char kJsonObjectStart = '{';

// The generator redraws a scene the solver stopped on; `attempt` > 0 in the trajectory's
// parameters records that. Parameters that do not parse count as drawn once: the statistic is
// informative only.
bool redrawn_by_solver(const std::string& parameters, const std::string& location) {
  if (parameters.empty() || parameters.front() != kJsonObjectStart) return false;
  Json j;
  try {
    j = parse_json_text(parameters, location + ": trajectory parameters");
  } catch (const InputError&) {
    return false;
  }
  const Json attempt = j.is_object() ? j.value("attempt", Json(0)) : Json(0);
  return attempt.is_number() && attempt.get<double>() > 0;
}

}  // namespace

SplitStats split_stats(const std::string& dir, const std::string& split) {
  const Dataset data = Dataset::open_split(dir, split);
  SplitStats s;
  s.trajectories = data.num_trajectories();
  if (s.trajectories == 0) throw InputError(data.location() + ": no trajectories");
  s.min_nodes = std::numeric_limits<int64_t>::max();
  s.min_frames = std::numeric_limits<int64_t>::max();
  for (int64_t t = 0; t < s.trajectories; ++t) {
    const int64_t n = data.mesh(t).num_nodes();
    s.min_nodes = std::min(s.min_nodes, n);
    s.max_nodes = std::max(s.max_nodes, n);
    s.mean_nodes += static_cast<double>(n) / static_cast<double>(s.trajectories);
    s.min_frames = std::min(s.min_frames, data.num_frames(t));
    if (redrawn_by_solver(data.parameters(t), data.location())) ++s.redrawn;
  }
  return s;
}

Json stats_json(const SplitStats& s) {
  return {{"trajectories", s.trajectories}, {"min_nodes", s.min_nodes},
          {"max_nodes", s.max_nodes},       {"mean_nodes", s.mean_nodes},
          {"min_frames", s.min_frames},     {"redrawn_by_solver_failure", s.redrawn}};
}

RolloutMetrics run_rollout(const HardCaseRequest& request, const RunInfo& run,
                           const std::string& data, const std::string& seeding,
                           const std::string& tag) {
  RolloutRequest r;
  r.run = run.dir;
  r.split = request.split;
  r.data = data;
  r.seeding = seeding;
  r.out = (fs::path(request.out) / "rollouts" / (fs::path(run.dir).filename().string() + "-" + tag))
              .string();
  r.max_trajectories = request.max_trajectories;
  r.threads = request.threads;
  r.quiet = request.quiet;
  r.projection = request.projection;
  return rollout(r);
}

// RMSE-all of extrapolating the first velocity on the same trajectories (the no-model reference).
double rmse_constant_velocity(const RolloutMetrics& metrics) {
  return metrics.rmse_all_constant_velocity.value_or(std::nan(""));
}

namespace {

std::string worst_pair(const std::optional<PhysicalValidityMetrics>& v,
                       std::optional<ValidityCurve> ValidityMeasures::*measure) {
  if (!v || !(v->model.*measure)) return "–";
  const auto worst = [&](const ValidityMeasures& m) {
    return format_number((m.*measure) ? (m.*measure)->max : std::nan(""), 2, Notation::kScientific);
  };
  return worst(v->model) + " / " + worst(v->truth);
}

}  // namespace

std::string overlap_cell(const RolloutMetrics& metrics) {
  return worst_pair(metrics.validity, &ValidityMeasures::overlap);
}

std::string outside_walls_cell(const RolloutMetrics& metrics) {
  return worst_pair(metrics.validity, &ValidityMeasures::outside_walls);
}

double rmse(const RolloutMetrics& metrics, const char* key) {
  const std::string k = key;
  const std::optional<FieldRmse>& over = k == "rmse_1"    ? metrics.rmse_1
                                         : k == "rmse_50" ? metrics.rmse_50
                                                          : metrics.rmse_all;
  if (k != "rmse_1" && k != "rmse_50" && k != "rmse_all")
    throw std::logic_error("rmse: unknown key " + k);
  return RolloutMetrics::rmse(over, "world_pos");
}

// One gnuplot line plot of per-step curves; `vlines` are (x, label) markers.
void plot_curves(const fs::path& plots, const std::string& name, const std::string& title,
                 const std::string& ylabel, bool logy, const std::vector<Curve>& curves,
                 const std::vector<std::pair<double, std::string>>& vlines) {
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / (name + ".png")).string()) << "set title "
    << gnuplot_quoted(title) << "\nset xlabel 'predicted step'\nset ylabel "
    << gnuplot_quoted(ylabel) << "\nset key left top\nset grid\n";
  if (logy) g << "set logscale y\n";
  for (size_t i = 0; i < vlines.size(); ++i)
    g << "set arrow " << i + 1 << " from " << vlines[i].first << ", graph 0 to " << vlines[i].first
      << ", graph 1 nohead dt 2 lc rgb 'gray40'\nset label " << i + 1 << ' '
      << gnuplot_quoted(vlines[i].second) << " at " << vlines[i].first
      << ", graph 0.96 left offset 0.5,0 tc rgb 'gray30'\n";
  g << "plot ";
  for (size_t c = 0; c < curves.size(); ++c) {
    const fs::path dat = plots / (name + "_" + std::to_string(c) + ".dat");
    std::ostringstream d;
    for (size_t s = 0; s < curves[c].values.size(); ++s) {
      const double v = curves[c].values[s];
      // Log plots skip non-positive values (an exact zero error has no logarithm).
      if (std::isfinite(v) && (!logy || v > 0)) d << s + 1 << ' ' << v << '\n';
    }
    write_text_atomic(dat.string(), d.str());
    g << (c ? ", " : "") << gnuplot_quoted(dat.string()) << " using 1:2 with " << curves[c].style
      << " title " << gnuplot_quoted(curves[c].label);
  }
  g << '\n';
  const fs::path script = plots / (name + ".gp");
  draw_plot(script.string(), g.str());
}

// Last predicted frame of the first trajectory of a rollout file: ground truth and prediction.
void plot_final_frame(const std::string& rollout_h5, const fs::path& plots, const std::string& name,
                      const std::string& title) {
  const Dataset d(rollout_h5);
  if (d.num_trajectories() == 0 || d.dim() != 2) return;
  const int64_t frame = d.num_frames(0) - 1;
  const auto pred = d.read(0, "world_pos", frame);
  const auto truth = d.read(0, "target_world_pos", frame);
  std::ostringstream pd, td;
  for (size_t i = 0; i + 1 < pred.size(); i += 2) {
    pd << pred[i] << ' ' << pred[i + 1] << '\n';
    td << truth[i] << ' ' << truth[i + 1] << '\n';
  }
  write_text_atomic((plots / (name + "_pred.dat")).string(), pd.str());
  write_text_atomic((plots / (name + "_truth.dat")).string(), td.str());
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / (name + ".png")).string(), 800, 800) << "set title "
    << gnuplot_quoted(title)
    << "\nset size ratio -1\nset key outside bottom center horizontal\nset grid\nplot "
    << gnuplot_quoted((plots / (name + "_truth.dat")).string())
    << " using 1:2 with points pt 7 ps 0.5 lc rgb 'gray60' title 'ground truth (UMLS-MPM)', "
    << gnuplot_quoted((plots / (name + "_pred.dat")).string())
    << " using 1:2 with points pt 7 ps 0.3 lc rgb '#d62728' title 'prediction'\n";
  const fs::path script = plots / (name + ".gp");
  draw_plot(script.string(), g.str());
}

fs::path make_out(const HardCaseRequest& request) {
  const fs::path out = request.out;
  std::error_code ec;
  fs::create_directories(out / "plots", ec);
  if (ec) throw InputError(out.string() + ": cannot create the folder (" + ec.message() + ")");
  return out;
}

// RMSE of world position at predicted step `step` (1-based) of a metrics' per-step curve.
double rmse_at(const RolloutMetrics& metrics, size_t step) {
  const auto& v = metrics.per_step("world_pos");
  return step >= 1 && step <= v.size() ? v[step - 1] : std::nan("");
}

}  // namespace bsms::experiments
