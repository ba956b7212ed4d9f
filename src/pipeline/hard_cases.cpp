#include "pipeline/hard_cases.hpp"

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
#include "pipeline/number_format.hpp"
#include "pipeline/plotting.hpp"
#include "pipeline/rollout.hpp"
#include "pipeline/run_files.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

struct RunInfo {
  std::string dir, label, model, seeding, data;
};

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

struct SplitStats {
  int64_t trajectories = 0, min_nodes = 0, max_nodes = 0, min_frames = 0, redrawn = 0;
  double mean_nodes = 0;
};

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
    // The generator redraws a scene the solver stopped on; `attempt` > 0 records that.
    const std::string p = data.parameters(t);
    if (!p.empty() && p.front() == '{') {
      const Json j = Json::parse(p, nullptr, false);
      if (j.is_object() && j.value("attempt", 0) > 0) ++s.redrawn;
    }
  }
  return s;
}

Json stats_json(const SplitStats& s) {
  return {{"trajectories", s.trajectories}, {"min_nodes", s.min_nodes},
          {"max_nodes", s.max_nodes},       {"mean_nodes", s.mean_nodes},
          {"min_frames", s.min_frames},     {"redrawn_by_solver_failure", s.redrawn}};
}

Json run_rollout(const HardCaseRequest& request, const RunInfo& run, const std::string& data,
                 const std::string& seeding, const std::string& tag) {
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
  return rollout(r);
}

// RMSE-all of extrapolating the first velocity on the same trajectories (the no-model reference).
double rmse_constant_velocity(const Json& metrics) {
  const Json& v = metrics["rmse_all_constant_velocity"];
  return v.is_number() ? v.get<double>() : std::nan("");
}

double rmse(const Json& metrics, const char* key) {
  const Json& v = metrics[key];
  if (!v.is_object() || !v["world_pos"].is_number()) return std::nan("");
  return v["world_pos"].get<double>();
}

struct Curve {
  std::string label;
  std::vector<double> values;  // per predicted step (step = index + 1)
  std::string style = "lines lw 2";
};

std::vector<double> to_vector(const Json& array) {
  std::vector<double> v;
  if (array.is_array())
    for (const auto& x : array) v.push_back(x.is_number() ? x.get<double>() : std::nan(""));
  return v;
}

// One gnuplot line plot of per-step curves; `vlines` are (x, label) markers.
void plot_curves(const fs::path& plots, const std::string& name, const std::string& title,
                 const std::string& ylabel, bool logy, const std::vector<Curve>& curves,
                 const std::vector<std::pair<double, std::string>>& vlines = {}) {
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
double rmse_at(const Json& metrics, size_t step) {
  const auto v = to_vector(metrics["rmse_per_step"]["world_pos"]);
  return step >= 1 && step <= v.size() ? v[step - 1] : std::nan("");
}

}  // namespace

Json zero_shot_experiment(const HardCaseRequest& request, const std::string& data,
                          double min_ratio) {
  const auto runs = run_infos(request);
  const fs::path out = make_out(request);
  const SplitStats large = split_stats(data, request.split);
  Json result = {{"experiment", "zero-shot"}, {"data", data}, {"large", stats_json(large)}};
  std::vector<Curve> curves;
  std::ostringstream table;
  table << "| Run | Test set | Nodes (mean) | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | "
           "Constant velocity RMSE-all (m) | Infer ms/step | Inverted cells (max) |\n"
           "|---|---|---|---|---|---|---|---|---|\n";
  int64_t train_max = 0;
  Json per_run = Json::array();
  for (const auto& run : runs) {
    const SplitStats train = split_stats(run.data, "train");
    train_max = std::max(train_max, train.max_nodes);
    const double ratio =
        static_cast<double>(large.min_nodes) / static_cast<double>(train.max_nodes);
    if (ratio < min_ratio)
      throw InputError(data + ": its smallest mesh has " + std::to_string(large.min_nodes) +
                       " nodes, only " + format_number(ratio, 2, Notation::kFixed) +
                       "x the largest training mesh of " + run.dir + " (" +
                       std::to_string(train.max_nodes) +
                       "); expected >= " + format_number(min_ratio, 1, Notation::kFixed) + "x");
    const Json own = run_rollout(request, run, run.data, "", "own");
    const Json big = run_rollout(request, run, data, "", "large");
    per_run.push_back({{"run", run.dir},
                       {"model", run.model},
                       {"train", stats_json(train)},
                       {"size_ratio_min", ratio},
                       {"in_distribution", own},
                       {"zero_shot", big}});
    for (const auto* m : {&own, &big}) {
      const bool is_big = m == &big;
      table << "| " << run.label << " | "
            << (is_big ? "zero-shot, larger meshes" : "own test split (training sizes)") << " | "
            << format_number((*m)["num_nodes_mean"].get<double>(), 0, Notation::kFixed) << " | "
            << format_number(rmse(*m, "rmse_1"), 3, Notation::kScientific) << " | "
            << format_number(rmse(*m, "rmse_50"), 3, Notation::kScientific) << " | "
            << format_number(rmse(*m, "rmse_all"), 3, Notation::kScientific) << " | "
            << format_number(rmse_constant_velocity(*m), 3, Notation::kScientific) << " | "
            << format_number((*m)["infer_ms_per_step"].get<double>(), 1, Notation::kFixed) << " | "
            << format_number((*m)["inverted_cells_max"].get<double>(), 4, Notation::kFixed)
            << " |\n";
      curves.push_back({run.label + (is_big ? ", larger meshes (zero-shot)" : ", own test split"),
                        to_vector((*m)["rmse_per_step"]["world_pos"]),
                        is_big ? "lines lw 2" : "lines lw 2 dt 2"});
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
  for (const auto& r : per_run) {
    const double a = rmse(r["in_distribution"], "rmse_all");
    const double b = rmse(r["zero_shot"], "rmse_all");
    md << "- " << r["run"].get<std::string>() << " (" << r["model"].get<std::string>()
       << "): RMSE-all " << format_number(b, 3, Notation::kScientific)
       << " m on the larger meshes against " << format_number(a, 3, Notation::kScientific)
       << " m on its own test split (" << format_number(b / a, 2, Notation::kFixed) << "×).\n";
  }
  write_text_atomic((out / "zero_shot.md").string(), md.str());
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

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
  std::vector<Curve> curves;
  for (const auto& run : runs) {
    if (run.model != "bsms") {
      md << "- " << run.label << ": skipped (a single-level model has no seeding).\n";
      continue;
    }
    Json rows = Json::object();
    for (const std::string& seeding : seeding_names())
      rows[seeding] =
          run_rollout(request, run, data.empty() ? run.data : data, seeding, "seeding-" + seeding);
    const Json& base = rows[run.seeding];
    md << "**" << run.label << "**, trained with " << run.seeding << ":\n\n"
       << "| Seeding @ test | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | Ratio 1-step | Ratio "
          "50-step | Ratio rollout |\n|---|---|---|---|---|---|---|\n";
    Json ratios = Json::object();
    for (const std::string& seeding : seeding_names()) {
      const Json& m = rows[seeding];
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
                        to_vector(m["rmse_per_step"]["world_pos"]),
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

Json long_rollout_experiment(const HardCaseRequest& request, const std::string& long_data,
                             const std::string& hard_data) {
  const auto runs = run_infos(request);
  const fs::path out = make_out(request);
  const SplitStats lng = split_stats(long_data, request.split);
  Json result = {{"experiment", "long-rollout"}, {"long", stats_json(lng)}};
  std::vector<Curve> rmse_curves, inverted_curves;
  std::ostringstream table;
  table << "| Run | Horizon H (steps) | RMSE at H (m) | at 2H | at 5H | at 10H | RMSE-all | "
           "Constant velocity RMSE-all | Inverted cells (max) | Diverged |\n"
           "|---|---|---|---|---|---|---|---|---|---|\n";
  Json per_run = Json::array();
  size_t horizon_marker = 0;
  for (const auto& run : runs) {
    const SplitStats train = split_stats(run.data, "train");
    const size_t horizon = static_cast<size_t>(train.min_frames - 2);  // predicted steps
    horizon_marker = std::max(horizon_marker, horizon);
    const size_t steps = static_cast<size_t>(lng.min_frames - 2);
    if (steps < 10 * horizon)
      throw InputError(long_data + ": trajectories of " + std::to_string(lng.min_frames) +
                       " frames give " + std::to_string(steps) +
                       " predicted steps, fewer than 10x the training horizon of " + run.dir +
                       " (" + std::to_string(horizon) + " steps)");
    const Json m = run_rollout(request, run, long_data, "", "long");
    Json row = {{"run", run.dir},
                {"model", run.model},
                {"horizon_steps", horizon},
                {"rollout", m},
                {"rmse_at", Json::object()}};
    table << "| " << run.label << " | " << horizon;
    for (size_t k : {1, 2, 5, 10}) {
      const double v = rmse_at(m, k * horizon);
      row["rmse_at"][std::to_string(k) + "H"] = std::isfinite(v) ? Json(v) : Json(nullptr);
      table << " | " << format_number(v, 3, Notation::kScientific);
    }
    table << " | " << format_number(rmse(m, "rmse_all"), 3, Notation::kScientific) << " | "
          << format_number(rmse_constant_velocity(m), 3, Notation::kScientific) << " | "
          << format_number(m["inverted_cells_max"].get<double>(), 4, Notation::kFixed) << " | "
          << m["diverged"].size() << " of " << m["num_trajectories"].get<int64_t>() << " |\n";
    rmse_curves.push_back({run.label, to_vector(m["rmse_per_step"]["world_pos"])});
    inverted_curves.push_back({run.label, to_vector(m["inverted_cells_per_step"])});
    per_run.push_back(row);
  }
  result["runs"] = per_run;
  const fs::path plots = out / "plots";
  const std::vector<std::pair<double, std::string>> marks = {
      {static_cast<double>(horizon_marker), "training horizon"}};
  plot_curves(plots, "long_rmse", "Rollout RMSE over 10x the training horizon", "RMSE (m)", true,
              rmse_curves, marks);
  plot_curves(plots, "long_inverted", "Predicted cells turned inside out (fraction)",
              "fraction of cells", false, inverted_curves, marks);

  std::ostringstream md;
  md << "## Long rollouts and stability\n\n"
     << "Rollouts on `" << long_data << "` (" << lng.trajectories << " trajectories of "
     << lng.min_frames << " frames; the UMLS-MPM solver produced every one"
     << (lng.redrawn > 0
             ? " after redrawing " + std::to_string(lng.redrawn) + " scenes it stopped on"
             : " without a failure")
     << "). H is the training horizon in predicted steps. Stability: a diverged rollout has a "
        "non-finite state; an inverted cell has its orientation flipped against the first frame "
        "(the solver stops on any). Constant velocity: extrapolating each trajectory's first "
        "velocity, the reference a model must beat.\n\n"
     << table.str() << "\n![long RMSE](plots/long_rmse.png)\n\n"
     << "![inverted cells](plots/long_inverted.png)\n\n";

  if (!hard_data.empty()) {
    const SplitStats hard = split_stats(hard_data, request.split);
    result["hard"] = stats_json(hard);
    std::vector<Curve> hard_curves;
    std::ostringstream hard_table;
    hard_table
        << "| Run | RMSE-1 (m) | RMSE-50 (m) | RMSE-all (m) | Constant velocity RMSE-all (m) "
           "| Own test split RMSE-all (m) | Inverted cells (max) | Diverged |\n"
           "|---|---|---|---|---|---|---|---|\n";
    Json hard_runs = Json::array();
    for (const auto& run : runs) {
      const Json m = run_rollout(request, run, hard_data, "", "hard");
      const Json own = run_rollout(request, run, run.data, "", "own");
      hard_table << "| " << run.label << " | "
                 << format_number(rmse(m, "rmse_1"), 3, Notation::kScientific) << " | "
                 << format_number(rmse(m, "rmse_50"), 3, Notation::kScientific) << " | "
                 << format_number(rmse(m, "rmse_all"), 3, Notation::kScientific) << " | "
                 << format_number(rmse_constant_velocity(m), 3, Notation::kScientific) << " | "
                 << format_number(rmse(own, "rmse_all"), 3, Notation::kScientific) << " | "
                 << format_number(m["inverted_cells_max"].get<double>(), 4, Notation::kFixed)
                 << " | " << m["diverged"].size() << " of " << m["num_trajectories"].get<int64_t>()
                 << " |\n";
      hard_curves.push_back(
          {run.label + ", hard scenes", to_vector(m["rmse_per_step"]["world_pos"])});
      hard_curves.push_back({run.label + ", own test split",
                             to_vector(own["rmse_per_step"]["world_pos"]), "lines lw 2 dt 2"});
      hard_runs.push_back({{"run", run.dir}, {"hard", m}, {"own", own}});
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
  write_text_atomic((out / "long_rollout.md").string(), md.str());
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

}  // namespace bsms
