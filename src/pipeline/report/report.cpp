#include "pipeline/report/report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hdf5_file.hpp"
#include "data/dataset/dataset.hpp"
#include "pipeline/experiments/solver_frontier.hpp"
#include "pipeline/report/animation.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/report/plotting.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/runs/train_log.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

struct RunData {
  std::string dir, label;
  RolloutMetrics metrics;
  std::vector<TrainLogRow> log;  // RUN/train_log.csv
  size_t loss_window = 1;        // steps in each point of the plotted training-loss curve
};

// A figure that may be absent, as a number or NaN (shown as "–").
double or_nan(const std::optional<double>& v) {
  return v.value_or(std::nan(""));
}

// RMSE of the field a run's RMSE columns show (RolloutMetrics::primary_field: world positions
// for Lagrangian runs, velocity for Eulerian ones, e.g. public CylinderFlow / Airfoil data).
double primary_rmse(const RolloutMetrics& m, const std::optional<FieldRmse>& over) {
  return RolloutMetrics::rmse(over, m.primary_field());
}

// Mesh edges of a frame as gnuplot segments ("x y" pairs separated by blank lines).
void write_edges(std::ofstream& f, const TrajectoryMesh& mesh, const std::vector<float>& x,
                 int dim) {
  const int k = mesh.cell_size;
  for (int64_t c = 0; c < mesh.num_cells(); ++c)
    for (int a = 0; a < k; ++a)
      for (int b = a + 1; b < k; ++b) {
        const int32_t i = mesh.cells[c * k + a], j = mesh.cells[c * k + b];
        f << x[i * dim] << ' ' << x[i * dim + 1] << '\n'
          << x[j * dim] << ' ' << x[j * dim + 1] << "\n\n";
      }
}

// The model as the tables name it: with --symmetrize, how many symmetries each prediction
// averages.
std::string model_name(const RolloutMetrics& m) {
  return m.model + (m.symmetries > 1
                        ? ", averaged over " + std::to_string(m.symmetries) + " symmetries"
                        : std::string());
}

// A validity measure's worst value, model / truth, or "–" where it does not apply.
std::string validity_cell(const std::optional<ValidityCurve>& model,
                          const std::optional<ValidityCurve>& truth) {
  const auto worst = [](const std::optional<ValidityCurve>& c) {
    return format_number(c ? c->max : std::nan(""), 2, Notation::kScientific);
  };
  if (!model && !truth) return "–";
  return worst(model) + " / " + worst(truth);
}

// Physical validity beside inverted cells: overlap between bodies, nodes inside other bodies and
// outside the walls, prediction against truth.
void write_validity(std::ostringstream& md, const std::vector<RunData>& runs) {
  if (std::none_of(runs.begin(), runs.end(),
                   [](const auto& r) { return r.metrics.validity.has_value(); }))
    return;
  md << "\nPhysical validity: the worst step of any test trajectory, predicted / ground truth at "
        "the same steps (the truth is the reference: bodies the solver pressed together overlap "
        "at the mesh level too). Overlap: the area (2-D) or volume (3-D) where cells of "
        "different bodies overlap, as a fraction of all cells'; nodes inside another body and "
        "outside the walls as fractions of the nodes; outside the walls (m): the farthest node's "
        "distance beyond them.\n\n"
     << "| run | inverted cells (max) | overlap between bodies | nodes inside another body | "
        "outside the walls (m) | nodes outside the walls |\n|---|---|---|---|---|---|\n";
  for (const auto& r : runs) {
    const RolloutMetrics& m = r.metrics;
    if (!m.validity) continue;
    const ValidityMeasures &model = m.validity->model, &truth = m.validity->truth;
    md << "| " << fs::path(r.dir).filename().string() << " | "
       << format_number(m.inverted_cells_max, 4, Notation::kFixed) << " | "
       << validity_cell(model.overlap, truth.overlap) << " | "
       << validity_cell(model.nodes_in_other_body, truth.nodes_in_other_body) << " | "
       << validity_cell(model.outside_walls, truth.outside_walls) << " | "
       << validity_cell(model.nodes_outside_walls, truth.nodes_outside_walls) << " |\n";
  }
}

// Steps averaged into each point of the plotted training-loss curve: 0.5 % of the run.
size_t training_loss_window(size_t steps) {
  return std::max<size_t>(1, steps / 200);
}

// Checks averaged into a run's final validation loss and into the curve that reaches it.
constexpr size_t kValidationWindow = 5;

// The thesis's training-cost claim as a table: when each run's validation loss first reaches
// each other run's final one, in seconds and as a fraction of that other run's training time.
void write_training_cost(std::ostringstream& md, const std::vector<RunData>& runs) {
  std::vector<std::vector<ValidationPoint>> curves;
  for (const auto& r : runs) curves.push_back(validation_curve(r.log));
  const size_t with_checks = static_cast<size_t>(
      std::count_if(curves.begin(), curves.end(), [](const auto& c) { return !c.empty(); }));
  if (with_checks < 2) return;
  const auto name = [&](size_t r) { return fs::path(runs[r].dir).filename().string(); };
  std::vector<double> ends(runs.size()), total(runs.size());
  for (size_t r = 0; r < runs.size(); ++r) {
    ends[r] = final_validation(curves[r], kValidationWindow);
    total[r] = runs[r].log.empty() ? std::nan("") : runs[r].log.back().wall_s;
  }
  md << "\nTraining cost (the thesis's claim: BSMS-GNN reaches MeshGraphNets' final validation "
        "loss in at most half its training time). Validation loss as a fraction of predicting "
        "zero on the same frames, so that runs validated on other frames compare; a run's final "
        "loss is the mean of its last "
     << kValidationWindow
     << " checks, and a run has reached a loss at the first check where the mean of its last "
     << kValidationWindow
     << " checks is at or below it. Each cell: the wall time of training (s, validation included) "
        "at which the row's run reaches the column's final loss, and that time over the column "
        "run's whole training time.\n\n| run | final / zero | wall time (s) |";
  for (size_t c = 0; c < runs.size(); ++c) md << " reaches " << name(c) << "'s final |";
  md << "\n|---|---|---|";
  for (size_t c = 0; c < runs.size(); ++c) md << "---|";
  md << '\n';
  for (size_t r = 0; r < runs.size(); ++r) {
    md << "| " << name(r) << " | " << format_number(ends[r], 3, Notation::kFixed) << " | "
       << format_number(total[r], 0, Notation::kFixed) << " |";
    for (size_t c = 0; c < runs.size(); ++c) {
      if (c == r || curves[r].empty() || !std::isfinite(ends[c])) {
        md << " – |";
        continue;
      }
      const auto reached = first_reaching(curves[r], ends[c], kValidationWindow);
      if (!reached)
        md << " not reached |";
      else
        md << ' ' << format_number(reached->wall_s, 0, Notation::kFixed) << " ("
           << format_number(reached->wall_s / total[c], 2, Notation::kFixed) << "×) |";
    }
    md << '\n';
  }
}

// The solver settings of a frontier a run is compared with: the ground-truth settings and each
// cheaper one that was stable on every trajectory (a setting's figures over fewer trajectories
// would not be the same test).
std::vector<const FrontierSetting*> frontier_candidates(const SolverFrontier& f) {
  std::vector<const FrontierSetting*> out;
  const auto usable = [](const FrontierSetting& s) {
    return s.unstable == 0 && std::isfinite(s.ms_per_frame) && std::isfinite(s.rmse_all);
  };
  if (usable(f.ground_truth)) out.push_back(&f.ground_truth);
  for (const auto& s : f.settings)
    if (usable(s)) out.push_back(&s);
  return out;
}

// Whether `a` and `b` name the same dataset file (the same path, or the same file by another).
bool same_data(const std::string& a, const std::string& b) {
  if (a == b) return true;
  std::error_code ec;
  return fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec);
}

// The references' rollout table (MeshGraphNets, BSMS-GNN): RMSE over the first 1, 10, 20, 50, 100,
// 200 and all steps, each trajectory's averaged over trajectories, per run and field.
void write_horizon_table(std::ostringstream& md, const std::vector<RunData>& runs) {
  std::vector<std::string> horizons;
  for (const int h : kRmseHorizons) horizons.push_back(std::to_string(h));
  horizons.push_back("all");
  std::vector<std::string> shown;  // horizons some run has
  for (const std::string& h : horizons)
    for (const auto& r : runs)
      if (r.metrics.rmse_trajectory_mean.count(h) &&
          std::find(shown.begin(), shown.end(), h) == shown.end())
        shown.push_back(h);
  if (shown.empty()) return;
  md << "\nRMSE over the first h predicted steps, each test trajectory's averaged over the "
        "trajectories (the convention of MeshGraphNets' and BSMS-GNN's tables; the figures above "
        "pool trajectories and steps):\n\n| run | field |";
  for (const std::string& h : shown) md << " RMSE-" << h << " |";
  md << "\n|---|---|";
  for (size_t k = 0; k < shown.size(); ++k) md << "---|";
  md << "\n";
  for (const auto& r : runs) {
    const auto& table = r.metrics.rmse_trajectory_mean;
    if (table.empty()) continue;
    for (const auto& [field, value] : table.begin()->second.fields) {
      (void)value;
      md << "| " << fs::path(r.dir).filename().string() << " | " << field << " |";
      for (const std::string& h : shown) {
        const auto row = table.find(h);
        md << " "
           << (row == table.end() ? std::string("–")
                                  : format_number(row->second.at(field), 2, Notation::kScientific))
           << " |";
      }
      md << "\n";
    }
  }
}

// A dataset's short name: the folder of a MeshGraphNets split or of a bsms dataset, the file stem
// of a single-file dataset (e.g. "runs/public/cylinder_flow" -> "cylinder_flow").
std::string dataset_name(const std::string& data) {
  fs::path p(data);
  while (!p.empty() && p.filename().empty()) p = p.parent_path();  // trailing slash
  const std::string ext = p.extension().string();
  if (ext == ".tfrecord" || ext == ".h5") {
    const std::string stem = p.stem().string();
    if (stem == "train" || stem == "valid" || stem == "test")
      return p.parent_path().filename().string();
    return stem;
  }
  return p.filename().string();
}

// The thesis's Table 4.5 layout: a row per dataset, RMSE-1, RMSE-50 and RMSE-all (×10⁻³, the
// trajectory-mean convention) of MeshGraphNets and BSMS-GNN side by side, for the field each
// dataset is scored on (velocity for Eulerian data, positions for Lagrangian).
void write_thesis_table(std::ostringstream& md, const std::vector<RunData>& runs) {
  std::vector<std::string> datasets;
  std::map<std::pair<std::string, std::string>, std::vector<const RunData*>> by;  // (data, model)
  for (const auto& r : runs) {
    if (r.metrics.rmse_trajectory_mean.empty()) continue;
    const std::string d = dataset_name(r.metrics.data);
    if (std::find(datasets.begin(), datasets.end(), d) == datasets.end()) datasets.push_back(d);
    by[{d, r.metrics.model}].push_back(&r);
  }
  if (datasets.empty()) return;
  const std::vector<std::pair<std::string, std::string>> models = {{"mgn", "MeshGraphNets"},
                                                                   {"bsms", "BSMS-GNN"}};
  md << "\nIn the layout of the BSMS-GNN thesis's Table 4.5 (RMSE ×10⁻³ over the first 1 and 50 "
        "steps and the whole rollout, each test trajectory's averaged over the trajectories):\n\n"
        "| dataset | field |";
  for (const auto& m : models) md << " " << m.second << " RMSE-1 | RMSE-50 | RMSE-all |";
  md << " runs |\n|---|---|";
  for (size_t k = 0; k < models.size(); ++k) md << "---|---|---|";
  md << "---|\n";
  const auto value = [](const RunData& r, const std::string& h, const std::string& field) {
    const auto row = r.metrics.rmse_trajectory_mean.find(h);
    if (row == r.metrics.rmse_trajectory_mean.end()) return std::string("–");
    const auto v = row->second.fields.find(field);
    if (v == row->second.fields.end()) return std::string("–");
    return format_number(1e3 * v->second, 3, Notation::kGeneral);
  };
  for (const std::string& d : datasets) {
    // One row per pairing of runs: the i-th run of each model on this dataset.
    size_t rows = 0;
    for (const auto& m : models)
      if (by.count({d, m.first})) rows = std::max(rows, by[{d, m.first}].size());
    for (size_t i = 0; i < rows; ++i) {
      std::string field, names;
      for (const auto& m : models) {
        const auto it = by.find({d, m.first});
        if (it != by.end() && i < it->second.size()) {
          field = it->second[i]->metrics.primary_field();
          names += (names.empty() ? "" : ", ") + it->second[i]->label;
        }
      }
      md << "| " << d << " | " << field << " |";
      for (const auto& m : models) {
        const auto it = by.find({d, m.first});
        if (it == by.end() || i >= it->second.size()) {
          md << " – | – | – |";
          continue;
        }
        const RunData& r = *it->second[i];
        md << " " << value(r, "1", field) << " | " << value(r, "50", field) << " | "
           << value(r, "all", field) << " |";
      }
      md << " " << names << " |\n";
    }
  }
}

// One run against the frontier's settings (`candidates`: frontier_candidates(f)), one line.
void write_frontier_comparison(std::ostringstream& md, const RunData& r, const SolverFrontier& f,
                               const std::vector<const FrontierSetting*>& candidates) {
  const auto sci = [](double v) { return format_number(v, 2, Notation::kScientific); };
  const RolloutMetrics& m = r.metrics;
  const std::string name = fs::path(r.dir).filename().string();
  if (m.eulerian) {
    md << "- " << name << ": an Eulerian run, not compared with the Lagrangian solver.\n";
    return;
  }
  // A diverged rollout has no RMSE-all: any setting at least as fast beats it.
  double model_rmse = primary_rmse(m, m.rmse_all);
  if (!std::isfinite(model_rmse)) model_rmse = std::numeric_limits<double>::infinity();
  std::vector<const FrontierSetting*> beating;
  for (const FrontierSetting* c : candidates)
    if (c->ms_per_frame <= m.infer_ms_per_step && c->rmse_all < model_rmse) beating.push_back(c);
  std::sort(beating.begin(), beating.end(),
            [](const auto* a, const auto* b) { return a->rmse_all < b->rmse_all; });
  md << "- " << name << " (" << format_number(m.infer_ms_per_step, 2, Notation::kFixed)
     << " ms/step, RMSE-all " << sci(primary_rmse(m, m.rmse_all)) << " m): ";
  if (beating.empty()) {
    md << "no cheaper solver setting is both as fast and as accurate.";
    // Say what is close: the cheapest setting that is more accurate, and its cost in model
    // steps (a setting a hair slower but far more accurate is the reader's real alternative).
    const FrontierSetting* cheapest = nullptr;
    for (const FrontierSetting* c : candidates)
      if (c->rmse_all < model_rmse && (!cheapest || c->ms_per_frame < cheapest->ms_per_frame))
        cheapest = c;
    if (cheapest && m.infer_ms_per_step > 0)
      md << " The cheapest more accurate one, " << cheapest->name << ", costs "
         << format_number(cheapest->ms_per_frame / m.infer_ms_per_step, 2, Notation::kFixed)
         << "× the model's time per frame at " << format_number(cheapest->rmse_all / model_rmse, 3)
         << "× its RMSE-all.";
    // Settings left out for their unstable solves that would otherwise be the answer.
    std::string shaky;
    for (const FrontierSetting& s : f.settings)
      if (s.unstable > 0 && std::isfinite(s.rmse_all) && s.rmse_all < model_rmse &&
          (!cheapest || s.ms_per_frame < cheapest->ms_per_frame))
        shaky += (shaky.empty() ? "" : ", ") + s.name + " (lost " + std::to_string(s.unstable) +
                 " of " + std::to_string(f.trajectories) + " solves)";
    if (!shaky.empty()) md << " Faster than that and more accurate, but unstable: " << shaky << ".";
  } else {
    const FrontierSetting& b = *beating.front();
    md << "beaten by solver setting " << b.name << " ("
       << format_number(b.ms_per_frame, 2, Notation::kFixed) << " ms/frame, RMSE-all "
       << sci(b.rmse_all) << " m)";
    for (size_t k = 1; k < beating.size(); ++k)
      md << (k == 1 ? "; also by " : ", ") << beating[k]->name;
    md << ".";
  }
  const FrontierSetting* floor = another_mesh_setting(f);
  if (floor && floor->rmse_all > 0 && std::isfinite(model_rmse))
    md << " Its RMSE-all is " << format_number(model_rmse / floor->rmse_all, 3) << "× "
       << kAnotherMesh << "'s.";
  if (!same_data(m.data, f.data))
    md << " (Rolled out on `" << m.data << "`, the frontier measured on `" << f.data
       << "`: other trajectories.)";
  md << "\n";
}

// The frontier as a table, and one sentence per run: is a solver setting at least as fast as the
// model (ms/frame <= its inference ms/step) and more accurate (lower RMSE-all)?
void write_frontier(std::ostringstream& md, const std::vector<RunData>& runs,
                    const SolverFrontier& f, const std::string& source) {
  const auto sci = [](double v) { return format_number(v, 2, Notation::kScientific); };
  md << "\nUMLS-MPM at cheaper settings (`" << source
     << "`, bsms experiment solver-frontier: " << f.trajectories << " trajectories of `" << f.data
     << "` re-solved single-threaded, " << f.threads
     << " at once, and scored against the stored frames like a rollout; speed-up against the "
        "ground-truth settings timed in the same run).\n\n"
     << "| solver setting | changes | ms/frame | speed-up vs ground truth | RMSE-all | × constant "
        "velocity | unstable |\n|---|---|---|---|---|---|---|\n";
  const auto row = [&](const FrontierSetting& s) {
    std::string changes;
    for (const auto& a : s.assignments) changes += (changes.empty() ? "`" : ", `") + a + "`";
    md << "| " << s.name << (s.interpolated ? " (interpolated)" : "") << " | "
       << (changes.empty() ? "as stored" : changes) << " | "
       << format_number(s.ms_per_frame, 2, Notation::kFixed) << " | "
       << format_number(s.speedup_vs_ground_truth, 2, Notation::kFixed) << "× | " << sci(s.rmse_all)
       << " | " << format_number(s.rmse_all_over_constant_velocity, 3) << " | " << s.unstable
       << " |\n";
  };
  row(f.ground_truth);
  for (const auto& s : f.settings) row(s);
  const std::string floor = another_mesh_paragraph(f);
  if (!floor.empty()) md << "\n" << floor;
  md << "\nEach run against the solver at these settings (solver ms/frame single-threaded, the "
        "model's inference ms/step with its own threads; a setting with unstable solves is not "
        "counted):\n\n";
  const std::vector<const FrontierSetting*> candidates = frontier_candidates(f);
  for (const auto& r : runs) write_frontier_comparison(md, r, f, candidates);
}

// The runs named in the request, with their rollout metrics and training logs.
std::vector<RunData> read_runs(const ReportRequest& request) {
  if (request.runs.empty()) throw InputError("report: give at least one run folder");
  const std::string& rollout = request.rollout;
  if (rollout.empty() || rollout.find('/') != std::string::npos || rollout == "." ||
      rollout == "..")
    throw InputError("report: --rollout '" + rollout +
                     "' is not a folder name (e.g. rollout, rollout_symmetric)");
  std::vector<RunData> runs;
  for (const auto& dir : request.runs) {
    const fs::path metrics = fs::path(dir) / rollout / "metrics.json";
    if (!fs::exists(metrics))
      throw InputError(dir + ": no " + rollout + "/metrics.json (run bsms rollout " + dir +
                       " first)");
    RunData r;
    r.dir = dir;
    r.metrics = read_rollout_metrics(metrics.string());
    if (r.metrics.one_step)
      throw InputError(metrics.string() + ": holds one-step errors (bsms rollout --one-step), " +
                       "not a rollout: run bsms rollout " + dir + " for the report");
    r.label = fs::path(dir).filename().string() + " (" + model_name(r.metrics) + ")";
    r.log = read_train_log((fs::path(dir) / "train_log.csv").string());
    r.loss_window = training_loss_window(r.log.size());
    runs.push_back(std::move(r));
  }
  return runs;
}

// Per run: PLOTS/rmse_R.dat (step, RMSE), loss_R.dat and valid_R.dat (the training log).
void write_curve_data(const fs::path& plots, const std::vector<RunData>& runs) {
  for (size_t r = 0; r < runs.size(); ++r) {
    std::ofstream curve(plots / ("rmse_" + std::to_string(r) + ".dat"));
    const std::vector<double>& steps = runs[r].metrics.per_step(runs[r].metrics.primary_field());
    for (size_t s = 0; s < steps.size(); ++s)
      if (std::isfinite(steps[s])) curve << s + 1 << ' ' << steps[s] << '\n';
    std::ofstream loss(plots / ("loss_" + std::to_string(r) + ".dat"));
    std::ofstream valid_out(plots / ("valid_" + std::to_string(r) + ".dat"));
    // Columns: wall time, the step's loss, the trailing mean of the losses (the plotted curve:
    // per-step losses scatter over a decade and would hide the validation curve drawn in the
    // same colour).
    const std::vector<TrainLogRow>& log = runs[r].log;
    const std::vector<double> mean = trailing_mean_loss(log, runs[r].loss_window);
    for (size_t k = 0; k < log.size(); ++k) {
      const TrainLogRow& row = log[k];
      loss << row.wall_s << ' ' << row.loss << ' ';
      if (std::isfinite(mean[k]))
        loss << mean[k] << '\n';
      else
        loss << "NaN\n";
      if (!row.has_valid()) continue;
      valid_out << row.wall_s << ' ' << row.valid_loss << ' ';
      if (std::isfinite(row.valid_zero_prediction))
        valid_out << row.valid_zero_prediction << '\n';
      else
        valid_out << "NaN\n";
    }
  }
}

// PLOTS/speed.dat: each run's inference ms/step and RMSE-all, the solver's; with a frontier, its
// settings as a second data block.
void write_speed_data(const fs::path& plots, const std::vector<RunData>& runs,
                      const std::optional<SolverFrontier>& frontier) {
  double solver_ms = -1;
  std::ofstream speed(plots / "speed.dat");
  for (size_t r = 0; r < runs.size(); ++r) {
    const RolloutMetrics& m = runs[r].metrics;
    speed << '"' << runs[r].label << "\" "
          << format_number(m.infer_ms_per_step, 6, Notation::kFixed) << ' '
          << format_number(primary_rmse(m, m.rmse_all), 8, Notation::kFixed) << '\n';
    if (m.solver_ms_per_frame) solver_ms = *m.solver_ms_per_frame;
  }
  // The solver is the reference: error 0 by definition.
  if (solver_ms > 0) speed << "\"UMLS-MPM solver (ground truth)\" " << solver_ms << " 0\n";
  // A second data block (gnuplot index 1): the frontier's points (not a line: a setting may be
  // cheaper and worse than another), cheapest last.
  if (frontier) {
    std::vector<const FrontierSetting*> points = {&frontier->ground_truth};
    for (const auto& s : frontier->settings) points.push_back(&s);
    std::sort(points.begin(), points.end(),
              [](const auto* a, const auto* b) { return a->ms_per_frame > b->ms_per_frame; });
    speed << "\n\n";
    for (const FrontierSetting* s : points) {
      if (!std::isfinite(s->ms_per_frame) || !std::isfinite(s->rmse_all)) continue;
      speed << '"' << s->name
            << (s->unstable > 0 ? " (" + std::to_string(s->unstable) + " unstable)" : std::string())
            << "\" " << format_number(s->ms_per_frame, 6, Notation::kFixed) << ' '
            << format_number(s->rmse_all, 8, Notation::kFixed) << '\n';
    }
  }
}

void plot_rmse_over_steps(const fs::path& plots, const std::vector<RunData>& runs,
                          std::vector<std::string>& images) {
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / "rmse_over_steps.png").string())
    << "set title 'Rollout RMSE of world position over steps (test split)'\nset xlabel "
       "'predicted step'"
       "\nset ylabel 'RMSE (m)'\nset logscale y\nset key left top\nset grid\nplot ";
  for (size_t r = 0; r < runs.size(); ++r)
    g << (r ? ", " : "")
      << gnuplot_quoted((plots / ("rmse_" + std::to_string(r) + ".dat")).string())
      << " using 1:2 with lines lw 2 title " << gnuplot_quoted(runs[r].label);
  g << '\n';
  if (draw_plot(plots / "rmse_over_steps.gp", g.str())) images.push_back("rmse_over_steps.png");
}

// DATA: step, overlap predicted, overlap true, inverted cells.
void write_validity_data(const fs::path& data, const RolloutMetrics& m) {
  std::ofstream f(data);
  const std::vector<double>& model = m.validity->model.overlap->per_step;
  const std::vector<double> none;
  const std::vector<double>& truth =
      m.validity->truth.overlap ? m.validity->truth.overlap->per_step : none;
  for (size_t s = 0; s < model.size(); ++s) {
    const double t = s < truth.size() ? truth[s] : std::nan("");
    const double inv =
        s < m.inverted_cells_per_step.size() ? m.inverted_cells_per_step[s] : std::nan("");
    f << s + 1;
    for (const double value : {model[s], t, inv}) {
      f << ' ';
      if (std::isfinite(value))
        f << value;
      else
        f << "NaN";
    }
    f << '\n';
  }
}

// Overlap between bodies over steps, predicted and true, beside the inverted cells.
void plot_validity_over_steps(const fs::path& plots, const std::vector<RunData>& runs,
                              std::vector<std::string>& images) {
  if (!std::any_of(runs.begin(), runs.end(), [](const auto& r) {
        return r.metrics.validity && r.metrics.validity->model.overlap;
      }))
    return;
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / "validity_over_steps.png").string())
    << "set title 'Overlap between bodies and inverted cells over steps (test split)'\n"
       "set xlabel 'predicted step'\nset ylabel 'fraction of the cells (area or volume)'\n"
       "set key left top\nset grid\nplot ";
  bool first = true;
  for (size_t r = 0; r < runs.size(); ++r) {
    const RolloutMetrics& m = runs[r].metrics;
    if (!m.validity || !m.validity->model.overlap) continue;
    const fs::path data = plots / ("validity_" + std::to_string(r) + ".dat");
    write_validity_data(data, m);
    const std::string q = gnuplot_quoted(data.string());
    g << (first ? "" : ", ") << q << " using 1:2 with lines lw 2 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + ": overlap") << ", " << q
      << " using 1:3 with lines lw 2 dt 2 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + ": overlap of the truth") << ", " << q
      << " using 1:4 with lines lw 1 dt 3 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + ": inverted cells");
    first = false;
  }
  g << '\n';
  if (draw_plot(plots / "validity_over_steps.gp", g.str()))
    images.push_back("validity_over_steps.png");
}

void plot_speed_vs_error(const fs::path& plots, bool frontier, std::vector<std::string>& images) {
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / "speed_vs_error.png").string())
    << "set title 'Speed against error: ms per frame vs rollout RMSE (all steps)'\n"
       "set xlabel 'wall time per frame (ms, 2 cores)'\nset ylabel 'RMSE of world position (m)'\n"
       "set logscale x\nset grid\nset key left top\nset offsets graph 0.15, graph 0.3, graph "
       "0.1, graph 0.05\n";
  const std::string dat = gnuplot_quoted((plots / "speed.dat").string());
  g << "plot " << dat << (frontier ? " index 0" : "")
    << " using 2:3:1 with labels point pt 7 ps 2 offset 1,1 notitle";
  if (frontier)
    g << ", " << dat
      << " index 1 using 2:3 with points pt 5 ps 1.5 lc rgb 'dark-red' title "
         "'UMLS-MPM at cheaper settings', "
      << dat << " index 1 using 2:3:1 with labels offset 1,-1 tc rgb 'dark-red' notitle";
  g << '\n';
  if (draw_plot(plots / "speed_vs_error.gp", g.str())) images.push_back("speed_vs_error.png");
}

void plot_loss_vs_wall(const fs::path& plots, const std::vector<RunData>& runs,
                       std::vector<std::string>& images) {
  std::ostringstream g;
  g << gnuplot_png_preamble((plots / "loss_vs_wall.png").string())
    << "set title 'Training loss against wall time'\nset xlabel 'wall time (s)'\n"
       "set ylabel 'loss (normalised MSE)'\nset logscale y\nset grid\nplot ";
  // Training losses first, validation and its zero-prediction reference drawn over them.
  for (size_t r = 0; r < runs.size(); ++r)
    g << (r ? ", " : "")
      << gnuplot_quoted((plots / ("loss_" + std::to_string(r) + ".dat")).string())
      << " using 1:3 with lines lw 1 dt 3 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + " train (mean of " + std::to_string(runs[r].loss_window) +
                        " steps)");
  for (size_t r = 0; r < runs.size(); ++r) {
    const std::string valid =
        gnuplot_quoted((plots / ("valid_" + std::to_string(r) + ".dat")).string());
    g << ", " << valid << " using 1:2 with linespoints lw 2 pt 7 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + " valid") << ", " << valid
      << " using 1:3 with lines lw 2 dt 2 lc " << r + 1 << " title "
      << gnuplot_quoted(runs[r].label + " valid, predicting zero");
  }
  g << '\n';
  if (draw_plot(plots / "loss_vs_wall.gp", g.str())) images.push_back("loss_vs_wall.png");
}

// Ground truth next to prediction: first trajectory of each run, three frames, and an animation
// of every frame.
void plot_rollouts(const fs::path& plots, const std::vector<RunData>& runs,
                   const std::string& rollout, std::vector<std::string>& images) {
  for (size_t r = 0; r < runs.size(); ++r) {
    const std::string& split = runs[r].metrics.split;
    const fs::path h5 = fs::path(runs[r].dir) / rollout / (split + ".h5");
    if (!fs::exists(h5)) continue;
    const Dataset d(h5.string());
    if (d.dim() < 2 || !d.has_field("target_world_pos")) continue;
    const auto& mesh = d.mesh(0);
    const int64_t frames = d.num_frames(0);
    const std::vector<int64_t> shown = {0, frames / 2, frames - 1};
    std::ostringstream g;
    g << gnuplot_png_preamble((plots / ("rollout_" + std::to_string(r) + ".png")).string(), 1500,
                              560)
      << "set multiplot layout 1,3 title "
      << gnuplot_quoted("Ground truth (grey) and prediction (red): " + runs[r].label)
      << "\nset size ratio -1\nunset key\n";
    for (size_t k = 0; k < shown.size(); ++k) {
      const std::string base = "frames_" + std::to_string(r) + "_" + std::to_string(k);
      {
        std::ofstream truth(plots / (base + "_truth.dat")), pred(plots / (base + "_pred.dat"));
        write_edges(truth, mesh, d.read(0, "target_world_pos", shown[k]), d.dim());
        write_edges(pred, mesh, d.read(0, "world_pos", shown[k]), d.dim());
      }
      g << "set title 'frame " << shown[k] << "'\nplot "
        << gnuplot_quoted((plots / (base + "_truth.dat")).string())
        << " with lines lc rgb '#999999' lw 2, "
        << gnuplot_quoted((plots / (base + "_pred.dat")).string())
        << " with lines lc rgb '#d62728' lw 1\n";
    }
    g << "unset multiplot\n";
    const fs::path script = plots / ("rollout_" + std::to_string(r) + ".gp");
    if (draw_plot(script, g.str())) images.push_back("rollout_" + std::to_string(r) + ".png");
    const std::string animation = "rollout_" + std::to_string(r) + "_animation";
    if (animate_rollout(d, plots.string(), animation,
                        runs[r].label + ", trajectory 0: truth (grey), prediction (red)"))
      images.push_back(animation + ".gif");
  }
}

// The report's title and its main table: a row per run (timings, RMSE, memory), with a note
// under each diverged run.
void write_run_table(std::ostringstream& md, const std::string& title,
                     const std::vector<RunData>& runs) {
  // What the RMSE columns measure: positions (Lagrangian) or velocities (Eulerian), against the
  // dataset's stored frames (UMLS-MPM's for bsms data, the publisher's solver's for public data).
  bool any_eulerian = false, any_lagrangian = false;
  for (const auto& r : runs) (r.metrics.eulerian ? any_eulerian : any_lagrangian) = true;
  const std::string measured = any_eulerian && any_lagrangian
                                   ? "world positions (m, Lagrangian runs) or velocities "
                                     "(Eulerian runs)"
                               : any_eulerian ? "velocities"
                                              : "world positions (m)";
  md << "# " << title << "\n\n"
     << "Per model, as in the BSMS-GNN paper's Tables 4.5–4.6. Times are medians on this machine; "
        "RMSE is the root mean squared error of predicted "
     << measured
     << " against the dataset's ground truth over the first 1, 50 and all predicted steps of "
        "the test split (pooled over trajectories and steps; a rollout shorter than 50 steps "
        "gives its whole length as RMSE-50 here).\n\n"
     << "| run | model | levels | train steps | train ms/step | infer ms/step | solver ms/frame | "
        "speed-up | RMSE-1 | RMSE-50 | RMSE-all | inverted cells (max) | peak RAM train (MB) | "
        "peak RAM infer (MB) | nodes | threads |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : runs) {
    const RolloutMetrics& m = r.metrics;
    md << "| " << fs::path(r.dir).filename().string() << " | " << model_name(m) << " | " << m.levels
       << " | " << (m.train_steps ? std::to_string(*m.train_steps) : "–") << " | "
       << format_number(or_nan(m.train_ms_per_step), 1, Notation::kFixed) << " | "
       << format_number(m.infer_ms_per_step, 2, Notation::kFixed) << " | "
       << format_number(or_nan(m.solver_ms_per_frame), 1, Notation::kFixed) << " | "
       << format_number(or_nan(m.speedup_vs_solver), 3, Notation::kFixed) << " | "
       << format_number(primary_rmse(m, m.rmse_1), 2, Notation::kScientific) << " | "
       << format_number(primary_rmse(m, m.rmse_50), 2, Notation::kScientific) << " | "
       << format_number(primary_rmse(m, m.rmse_all), 2, Notation::kScientific)
       << " | "
       // Eulerian runs have no cells that could invert.
       << format_number(m.eulerian ? std::nan("") : m.inverted_cells_max, 4, Notation::kFixed)
       << " | " << format_number(or_nan(m.peak_rss_mb_train), 0, Notation::kFixed) << " | "
       << format_number(m.peak_rss_mb_infer, 0, Notation::kFixed) << " | "
       << format_number(m.num_nodes_mean, 0, Notation::kFixed) << " | " << m.threads << " |\n";
    if (!m.diverged.empty()) {
      md << "\n_" << r.label << " diverged (non-finite prediction):";
      for (const DivergedTrajectory& d : m.diverged)
        md << " trajectory " << d.trajectory << " at frame " << d.frame << ";";
      md << "_\n";
    }
  }
}

// Which CPU timed the figures above (a run rolled out elsewhere says so).
void write_cpus(std::ostringstream& md, const std::vector<RunData>& runs) {
  std::vector<std::string> cpus;
  for (const auto& r : runs)
    if (std::find(cpus.begin(), cpus.end(), r.metrics.cpu) == cpus.end())
      cpus.push_back(r.metrics.cpu);
  md << "\nTimed on: ";
  for (size_t k = 0; k < cpus.size(); ++k)
    md << (k ? "; " : "") << (cpus[k].empty() ? "CPU not recorded" : cpus[k]);
  md << ".\n";
}

// What a model must beat, in the first run's data: holding the first frame (Eulerian) and
// extrapolating the first velocity of each test trajectory (`cv`: its RMSE-all, or NaN).
void write_references(std::ostringstream& md, const std::vector<RunData>& runs, double cv) {
  const double held = RolloutMetrics::rmse(runs.front().metrics.rmse_all_persistence, "velocity");
  if (std::isfinite(held))
    md << "\nEulerian runs: RMSE columns are the velocity's (per-field figures in each run's "
          "metrics.json). Reference without a model: holding the first frame on the solved nodes "
          "gives a velocity RMSE-all of "
       << format_number(held, 2, Notation::kScientific) << ".\n";
  if (std::isfinite(cv))
    md << "\nReference without a model: extrapolating each trajectory's first velocity (zero "
          "acceleration) gives RMSE-all "
       << format_number(cv, 2, Notation::kScientific)
       << " m. Inverted cells: the largest fraction of predicted cells turned inside out at a "
          "step (the solver never inverts one).\n";
}

// How far each ratio could move on another draw of test trajectories: RMSE-all over a few dozen
// trajectories of colliding bodies is carried by the few whose collisions went another way.
void write_ratio_intervals(std::ostringstream& md, const std::vector<RunData>& runs) {
  if (!std::any_of(runs.begin(), runs.end(),
                   [](const auto& r) { return r.metrics.per_trajectory.has_value(); }))
    return;
  const RolloutMetrics& first = runs.front().metrics;
  const std::string first_name = fs::path(runs.front().dir).filename().string();
  md << "\nRatios with 95 % intervals from resampling the test trajectories (percentile "
        "bootstrap, 4,000 draws; against the first run paired: each draw takes the same "
        "trajectories of both, so what the two runs share cancels).\n\n"
     << "| run | RMSE-all / constant velocity | 95 % interval | RMSE-all / " << first_name
     << "'s | 95 % interval (paired) |\n|---|---|---|---|---|\n";
  const auto interval = [](const std::optional<RatioInterval>& i) {
    return i ? format_number(i->lo, 3, Notation::kFixed) + "–" +
                   format_number(i->hi, 3, Notation::kFixed)
             : std::string("–");
  };
  for (const auto& r : runs) {
    const RolloutMetrics& m = r.metrics;
    const double all = primary_rmse(m, m.rmse_all);
    const double own_cv = or_nan(m.rmse_all_constant_velocity);
    std::optional<RatioInterval> paired;
    double against_first = std::nan("");
    // Paired only on the same test trajectories, rolled out over the same steps.
    if (&r != &runs.front() && m.per_trajectory && first.per_trajectory && m.data == first.data &&
        m.split == first.split && m.per_trajectory->steps == first.per_trajectory->steps) {
      against_first = all / primary_rmse(first, first.rmse_all);
      paired = bootstrap_ratio_interval(m.per_trajectory->steps, m.per_trajectory->model,
                                        first.per_trajectory->model);
    }
    md << "| " << fs::path(r.dir).filename().string() << " | "
       << format_number(all / own_cv, 3, Notation::kFixed) << " | "
       << interval(m.rmse_all_ratio_interval) << " | "
       << format_number(against_first, 3, Notation::kFixed) << " | " << interval(paired) << " |\n";
  }
}

// Where the position error lies, body by body; `cv`: the first run's constant-velocity RMSE-all.
void write_motion_parts(std::ostringstream& md, const std::vector<RunData>& runs, double cv) {
  if (!std::any_of(runs.begin(), runs.end(),
                   [](const auto& r) { return r.metrics.rmse_all_parts; }))
    return;
  md << "\nWhere the position error lies, body by body (RMSE-all split into each body's "
        "centre, its rotation about the centre and its deformation; the squares add up to "
        "RMSE-all's). On colliding bodies the centre part is mostly which way they leave a "
        "collision; the deformation part measures the elastic response.\n\n"
     << "| run | RMSE-all | centre | rotation | deformation |\n|---|---|---|---|---|\n";
  const auto row = [&md](const std::string& name, double all, const MotionRmse& p) {
    md << "| " << name << " | " << format_number(all, 2, Notation::kScientific) << " | "
       << format_number(p.centre, 2, Notation::kScientific) << " | "
       << format_number(p.rotation, 2, Notation::kScientific) << " | "
       << format_number(p.deformation, 2, Notation::kScientific) << " |\n";
  };
  for (const auto& r : runs)
    if (r.metrics.rmse_all_parts)
      row(fs::path(r.dir).filename().string(), primary_rmse(r.metrics, r.metrics.rmse_all),
          *r.metrics.rmse_all_parts);
  const RolloutMetrics& first = runs.front().metrics;
  if (first.rmse_all_parts_constant_velocity)
    row("constant velocity (" + fs::path(runs.front().dir).filename().string() + "'s data)", cv,
        *first.rmse_all_parts_constant_velocity);
  if (first.rmse_all_deformation_rigid)
    md << "| rigid bodies (each body's first shape held) | – | – | – | "
       << format_number(*first.rmse_all_deformation_rigid, 2, Notation::kScientific) << " |\n";
}
}  // namespace

std::string write_report(const ReportRequest& request) {
  const std::vector<RunData> runs = read_runs(request);
  std::optional<SolverFrontier> frontier;
  if (!request.solver_frontier.empty()) frontier = read_solver_frontier(request.solver_frontier);
  const fs::path out = request.out;
  const fs::path plots = out / "plots";
  std::error_code ec;
  fs::create_directories(plots, ec);
  if (ec)
    throw InputError(out.string() + ": cannot create the report folder (" + ec.message() + ")");

  write_curve_data(plots, runs);
  write_speed_data(plots, runs, frontier);

  std::vector<std::string> images;
  plot_rmse_over_steps(plots, runs, images);
  plot_validity_over_steps(plots, runs, images);
  plot_speed_vs_error(plots, frontier.has_value(), images);
  plot_loss_vs_wall(plots, runs, images);
  plot_rollouts(plots, runs, request.rollout, images);

  std::ostringstream md;
  write_run_table(md, request.title, runs);
  write_cpus(md, runs);
  write_horizon_table(md, runs);
  write_thesis_table(md, runs);
  if (frontier) write_frontier(md, runs, *frontier, request.solver_frontier);
  const double cv = or_nan(runs.front().metrics.rmse_all_constant_velocity);
  write_references(md, runs, cv);
  write_ratio_intervals(md, runs);
  write_validity(md, runs);
  write_training_cost(md, runs);
  write_motion_parts(md, runs, cv);
  md << "\n";
  for (const auto& image : images) md << "![" << image << "](plots/" << image << ")\n\n";
  const fs::path report = out / "report.md";
  write_text_atomic(report, md.str());
  return report.string();
}

}  // namespace bsms
