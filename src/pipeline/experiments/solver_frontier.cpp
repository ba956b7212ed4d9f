#include "pipeline/experiments/solver_frontier.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <exception>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"
#include "data/generate/trajectory_solver.hpp"
#include "data/mpm/scene_config.hpp"
#include "pipeline/experiments/node_interpolation.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/rollout/rollout_outputs.hpp"
#include "pipeline/runs/json_measures.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

constexpr const char* kGroundTruthName = "ground_truth";
// The scene parser's bound on the CFL number (data/mpm/scene_config.cpp: cfl in (0, 1]).
constexpr double kLargestCfl = 1.0;

bool setting_name_ok(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '+' ||
           c == '-';
  });
}

// One trajectory as stored: its draw and its frames.
struct StoredFrames : generate::StoredDraw {
  int64_t frames = 0;
  std::vector<float> world_pos;  // [F, N, dim]
  TrajectoryMesh mesh;
  std::vector<double> cv_step_sq;  // constant velocity's MSE per predicted step
};

// One solve scored: its squared errors per step, wall time and how it was scored.
struct SolveScore {
  bool unstable = false;
  std::string message;
  double sq = 0.0;  // sum over the predicted steps of the position MSE
  int64_t steps = 0;
  double ms_per_frame = 0.0, max_abs_diff = 0.0;
  bool interpolated = false;
};

double root_mean(double sum_sq, double count) {
  return count > 0 ? std::sqrt(sum_sq / count) : std::numeric_limits<double>::quiet_NaN();
}

// The stored positions [N, dim] of frame f.
const float* frame_of(const StoredFrames& st, int64_t f) {
  return st.world_pos.data() + static_cast<size_t>(f * st.mesh.num_nodes() * st.mesh.dim);
}

// Constant velocity from frames 0 and 1 on the free nodes, the truth on prescribed ones, as bsms
// rollout extrapolates: its MSE at each predicted frame 2 .. F-1.
std::vector<double> constant_velocity_steps(const StoredFrames& st) {
  const int64_t n = st.mesh.num_nodes();
  const int dim = st.mesh.dim;
  std::vector<double> out;
  const float *x0 = frame_of(st, 0), *x1 = frame_of(st, 1);
  for (int64_t f = 1; f + 1 < st.frames; ++f) {
    const float* truth = frame_of(st, f + 1);
    double sum = 0.0;
    for (int64_t i = 0; i < n; ++i) {
      if (st.mesh.node_type[static_cast<size_t>(i)] != static_cast<int32_t>(NodeType::kNormal))
        continue;  // the truth: no error
      for (int a = 0; a < dim; ++a) {
        const size_t k = static_cast<size_t>(i * dim + a);
        // In float, as the rollout's tensors compute it.
        const float cv = x1[k] + static_cast<float>(f) * (x1[k] - x0[k]);
        const double e = static_cast<double>(cv) - static_cast<double>(truth[k]);
        sum += e * e;
      }
    }
    out.push_back(sum / static_cast<double>(n * dim));
  }
  return out;
}

int32_t body_count(const std::vector<int32_t>& body_id) {
  int32_t bodies = 0;
  for (int32_t b : body_id) bodies = std::max(bodies, b + 1);
  return bodies;
}

// Scores a re-solve against the stored frames, reading it at the stored nodes by interpolation
// when its mesh differs.
SolveScore score_solve(const StoredFrames& st, const Trajectory& solved, const std::string& where) {
  const int dim = st.mesh.dim;
  const int64_t n = st.mesh.num_nodes(), m = solved.mesh.num_nodes();
  const auto it = solved.fields.find("world_pos");
  if (it == solved.fields.end()) throw NumericalError(where + ": the solve recorded no world_pos");
  const std::vector<float>& x = it->second;
  if (solved.num_frames != st.frames || static_cast<int64_t>(x.size()) != st.frames * m * dim)
    throw InputError(where + ": the re-solve has " + std::to_string(solved.num_frames) +
                     " frames, the stored trajectory " + std::to_string(st.frames));
  if (body_count(solved.mesh.body_id) != body_count(st.mesh.body_id))
    throw InputError(where + ": the re-solve has " +
                     std::to_string(body_count(solved.mesh.body_id)) + " bodies, the stored " +
                     std::to_string(body_count(st.mesh.body_id)) +
                     " (a setting must not change the scene's bodies)");
  SolveScore s;
  s.ms_per_frame = 1000.0 * solved.solver_wall_s / static_cast<double>(st.frames - 1);
  // The same nodes where the re-solve starts where the stored frames start.
  bool same = m == n;
  for (int64_t k = 0; same && k < n * dim; ++k)
    same = std::abs(x[static_cast<size_t>(k)] - st.world_pos[static_cast<size_t>(k)]) <= 1e-6;
  NodeInterpolation map;
  std::vector<float> read(static_cast<size_t>(n * dim));
  if (!same) {
    s.interpolated = true;
    const std::vector<float> x0(x.begin(), x.begin() + m * dim);
    const std::vector<float> stored0(st.world_pos.begin(), st.world_pos.begin() + n * dim);
    map = locate_points(x0, solved.mesh.body_id, solved.mesh.cells, stored0, st.mesh.body_id, dim);
  }
  for (int64_t f = 1; f + 1 < st.frames; ++f) {
    const float* pred = x.data() + static_cast<size_t>((f + 1) * m * dim);
    if (!same) {
      interpolate_points(map, pred, read.data());
      pred = read.data();
    }
    const float* truth = frame_of(st, f + 1);
    double sum = 0.0;
    for (int64_t k = 0; k < n * dim; ++k) {
      const double e = static_cast<double>(pred[k]) - static_cast<double>(truth[k]);
      sum += e * e;
      s.max_abs_diff = std::max(s.max_abs_diff, std::abs(e));
    }
    s.sq += sum / static_cast<double>(n * dim);
    ++s.steps;
  }
  return s;
}

// A figure over the stable trajectories of one setting.
FrontierSetting summarise(const SolverSetting& setting, const std::vector<StoredFrames>& stored,
                          const std::vector<SolveScore>& scores,
                          const std::vector<SolveScore>& truth_scores) {
  FrontierSetting row;
  row.name = setting.name;
  row.assignments = setting.assignments;
  double sq = 0, cv_sq = 0, steps = 0;
  std::vector<double> ms, speedups;
  for (size_t t = 0; t < stored.size(); ++t) {
    const SolveScore& s = scores[t];
    FrontierTrajectory tr;
    tr.trajectory = static_cast<int64_t>(t);
    tr.index = stored[t].index;
    double cv_t = 0;
    for (double v : stored[t].cv_step_sq) cv_t += v;
    const double cv_steps = static_cast<double>(stored[t].cv_step_sq.size());
    tr.rmse_all_constant_velocity = root_mean(cv_t, cv_steps);
    if (s.unstable) {
      tr.unstable = true;
      tr.message = s.message;
      tr.ms_per_frame = tr.rmse_all = std::numeric_limits<double>::quiet_NaN();
      ++row.unstable;
    } else {
      tr.ms_per_frame = s.ms_per_frame;
      tr.rmse_all = root_mean(s.sq, static_cast<double>(s.steps));
      tr.steps = s.steps;
      row.interpolated = row.interpolated || s.interpolated;
      row.max_abs_diff_m = std::max(row.max_abs_diff_m, s.max_abs_diff);
      sq += s.sq;
      cv_sq += cv_t;
      steps += static_cast<double>(s.steps);
      ms.push_back(s.ms_per_frame);
      if (s.ms_per_frame > 0) speedups.push_back(truth_scores[t].ms_per_frame / s.ms_per_frame);
    }
    row.per_trajectory.push_back(tr);
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  row.ms_per_frame = ms.empty() ? nan : rollout_outputs::median(ms);
  row.speedup_vs_ground_truth = speedups.empty() ? nan : rollout_outputs::median(speedups);
  row.rmse_all = root_mean(sq, steps);
  row.rmse_all_over_constant_velocity = row.rmse_all / root_mean(cv_sq, steps);
  if (steps == 0) row.max_abs_diff_m = nan;
  return row;
}

std::string assignment_list(const std::vector<std::string>& assignments) {
  std::string s;
  for (const auto& a : assignments) s += (s.empty() ? "`" : ", `") + a + "`";
  return s.empty() ? "as stored" : s;
}

std::string markdown(const SolverFrontier& r) {
  const auto sci = [](double v) { return format_number(v, 2, Notation::kScientific); };
  std::ostringstream md;
  md << "## The solver's own speed–error frontier\n\n"
     << "`" << r.data << "` (family " << r.family << "), " << r.trajectories << " trajectories of "
     << r.frames
     << " frames, each solved again by UMLS-MPM at its ground-truth settings and at each setting "
        "below: single-threaded solves, "
     << r.threads << " at once (" << r.hardware_threads << " hardware threads, "
     << (r.cpu.empty() ? std::string("CPU not recorded") : r.cpu)
     << "), timed in the same run. Scored against the stored frames as bsms "
        "rollout scores a model: RMSE of world position over the predicted frames 2 to the last "
        "(m), beside constant velocity (the first velocity extrapolated: "
     << sci(r.rmse_all_constant_velocity)
     << " m). ms/frame: the solve's wall time per frame, the median over trajectories; "
        "speed-up: the median of each trajectory's ground-truth time over its time. Settings "
        "that change the particle spacing are read at the stored nodes by linear interpolation "
        "in the re-solve's initial cells (*interpolated*). Unstable solves are left out of a "
        "setting's figures and counted.\n\n"
     << "| setting | changes | ms/frame | speed-up | RMSE-all (m) | × constant velocity | "
        "largest difference (m) | unstable |\n|---|---|---|---|---|---|---|---|\n";
  const auto row = [&md, &sci](const FrontierSetting& s) {
    md << "| " << s.name << (s.interpolated ? " (interpolated)" : "") << " | "
       << assignment_list(s.assignments) << " | "
       << format_number(s.ms_per_frame, 2, Notation::kFixed) << " | "
       << format_number(s.speedup_vs_ground_truth, 2, Notation::kFixed) << "× | " << sci(s.rmse_all)
       << " | " << format_number(s.rmse_all_over_constant_velocity, 3) << " | "
       << sci(s.max_abs_diff_m) << " | " << s.unstable << " |\n";
  };
  row(r.ground_truth);
  for (const auto& s : r.settings) row(s);
  md << "\nThe ground-truth row re-solves the data: its RMSE-all (" << sci(r.ground_truth.rmse_all)
     << " m) checks that the re-solve reproduces the stored frames.";
  if (r.stored_ms_per_frame)
    md << " bsms generate timed the same solves at "
       << format_number(*r.stored_ms_per_frame, 2, Notation::kFixed)
       << " ms/frame (the solver column of bsms report; another run, another load).";
  md << "\n";
  for (const auto& s : r.settings)
    for (const auto& t : s.per_trajectory)
      if (t.unstable)
        md << "\n- " << s.name << ", trajectory " << t.trajectory << " (index " << t.index
           << "): unstable: " << truncate_for_message(t.message, 200);
  for (const auto& note : r.notes) md << "\n- " << note;
  md << "\n";
  const std::string floor = another_mesh_paragraph(r);
  if (!floor.empty()) md << "\n" << floor;
  return md.str();
}

// A solve of every (trajectory, setting) pair, `threads` at once; setting 0 is the ground truth.
std::vector<std::vector<SolveScore>> solve_all(const std::vector<generate::FamilyConfig>& families,
                                               const std::vector<std::string>& names,
                                               const std::vector<StoredFrames>& stored, int threads,
                                               const fs::path& work, bool quiet) {
  const int64_t count = static_cast<int64_t>(stored.size());
  const int64_t per = static_cast<int64_t>(families.size());
  std::vector<std::vector<SolveScore>> scores(families.size(),
                                              std::vector<SolveScore>(stored.size()));
  std::atomic<int64_t> next{0}, done{0};
  std::mutex mutex;
  std::exception_ptr failure;
  ProgressBar bar("solver-frontier", count * per);
  // Tasks by trajectory, then setting: a trajectory's settings run at about the same time, under
  // about the same load.
  auto worker = [&] {
    for (;;) {
      const int64_t task = next.fetch_add(1);
      if (task >= count * per) return;
      {
        const std::lock_guard<std::mutex> lock(mutex);
        if (failure) return;
      }
      const int64_t t = task / per, s = task % per;
      const StoredFrames& st = stored[static_cast<size_t>(t)];
      const std::string where = "trajectory " + std::to_string(t) + " (index " +
                                std::to_string(st.index) + "), setting " +
                                names[static_cast<size_t>(s)];
      SolveScore& out = scores[static_cast<size_t>(s)][static_cast<size_t>(t)];
      try {
        Trajectory solved;
        try {
          solved = generate::solve_draw(
              families[static_cast<size_t>(s)], st.run_seed, st.index, st.attempt,
              (work / ("t" + std::to_string(t) + "_s" + std::to_string(s))).string());
        } catch (const NumericalError& e) {
          if (s == 0)  // the stored settings must reproduce the stored solve
            throw NumericalError(where + ": " + e.what());
          out.unstable = true;
          out.message = e.what();
        }
        if (!out.unstable) out = score_solve(st, solved, where);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (!failure) failure = std::current_exception();
        return;
      }
      const int64_t k = done.fetch_add(1) + 1;
      if (!quiet) {
        const std::lock_guard<std::mutex> lock(mutex);
        bar.update(k);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int w = 1; w < threads; ++w) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();
  std::error_code ec;
  fs::remove_all(work, ec);
  if (failure) std::rethrow_exception(failure);
  if (!quiet) bar.finish();
  return scores;
}

}  // namespace

SolverSetting parse_solver_setting(const std::string& text) {
  const std::string shown = "--setting " + truncate_for_message(text, 80);
  const auto eq = text.find('=');
  SolverSetting s;
  s.name = eq == std::string::npos ? std::string() : text.substr(0, eq);
  if (!setting_name_ok(s.name))
    throw InputError(shown +
                     ": expected NAME=scene.KEY=VALUE[,scene.KEY=VALUE...] with NAME of letters, "
                     "digits and _ . + -");
  if (s.name == kGroundTruthName)
    throw InputError(shown + ": the name " + kGroundTruthName + " is the stored settings' row");
  // Split at commas outside brackets and quotes: a value may be a JSON list.
  std::string current;
  int depth = 0;
  bool quoted = false;
  const std::string rest = text.substr(eq + 1);
  for (size_t i = 0; i <= rest.size(); ++i) {
    const char c = i < rest.size() ? rest[i] : ',';
    if (quoted) {
      if (c == '\\' && i + 1 < rest.size()) {
        current += c;
        current += rest[++i];
        continue;
      }
      if (c == '"') quoted = false;
    } else if (c == '"') {
      quoted = true;
    } else if (c == '[' || c == '{') {
      ++depth;
    } else if (c == ']' || c == '}') {
      --depth;
    } else if (c == ',' && depth <= 0) {
      s.assignments.push_back(current);
      current.clear();
      continue;
    }
    current += c;
  }
  for (const std::string& a : s.assignments) {
    const auto at = a.find('=');
    const bool known_section = a.rfind("scene.", 0) == 0 || a.rfind("sample.", 0) == 0;
    if (!known_section || at == std::string::npos || at + 1 == a.size() || a[at - 1] == '.')
      throw InputError(shown + ": '" + truncate_for_message(a, 60) +
                       "' is not scene.KEY=VALUE or sample.KEY=VALUE (a key of the family's "
                       "scene or sample section, e.g. scene.background.element_size=0.06)");
  }
  return s;
}

std::vector<SolverSetting> default_solver_settings(const Json& family, const std::string& file,
                                                   std::vector<std::string>& notes) {
  std::vector<SolverSetting> out;
  const auto text = [](double v) { return format_number(v, 6); };
  // The family's base scene, typed (its defaults are the parser's).
  const mpm::Scene scene = mpm::parse_base_scene(family.at("scene"), {file, "scene"});
  const bool sized = scene.background.element_size > 0;
  if (sized) {
    for (const auto& [label, factor] : {std::pair{"1.5", 1.5}, std::pair{"2", 2.0}})
      out.push_back(
          {std::string("background_x") + label,
           {"scene.background.element_size=" + text(scene.background.element_size * factor)}});
  } else {
    notes.push_back(
        "No default background setting: the family has no scene.background.element_size; give "
        "--setting NAME=scene.background.KEY=VALUE.");
  }
  if (scene.solver.dt > 0) {
    notes.push_back("No default CFL settings: the family's scene fixes the time step (dt).");
  } else {
    const double cfl = scene.solver.cfl;
    double previous = cfl;
    for (const auto& [label, factor] : {std::pair{"2", 2.0}, std::pair{"3", 3.0}}) {
      const double value = std::min(cfl * factor, kLargestCfl);
      if (!(value > previous)) continue;  // capped to the one before
      if (cfl * factor > kLargestCfl)
        notes.push_back(std::string("cfl_x") + label + ": capped at CFL " + text(kLargestCfl) +
                        " (the scene parser's bound), " + text(value / cfl) + "× the stored " +
                        text(cfl) + ".");
      out.push_back({std::string("cfl_x") + label, {"scene.solver.cfl=" + text(value)}});
      previous = value;
    }
  }
  SolverSetting spacing{"spacing_x1.5", {}};
  if (family.contains("sample") && family["sample"].is_object())
    for (const auto& item : family["sample"].items()) {
      const std::string& key = item.key();
      const bool named =
          key == "spacing" || (key.size() > 8 && key.compare(key.size() - 8, 8, "_spacing") == 0);
      if (!named) continue;
      const Json& v = item.value();
      if (v.is_number()) {
        spacing.assignments.push_back("sample." + key + "=" + text(v.get<double>() * 1.5));
      } else if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number()) {
        spacing.assignments.push_back("sample." + key + "=[" + text(v[0].get<double>() * 1.5) +
                                      "," + text(v[1].get<double>() * 1.5) + "]");
      }
    }
  // The bodies family bounds a draw's estimated node count, which a coarser spacing lowers by
  // 1.5^dim: the bounds follow, so that the re-solve draws the same bodies.
  if (!spacing.assignments.empty() && family["sample"].contains("nodes")) {
    const Json& v = family["sample"]["nodes"];
    const double shrink = std::pow(1.5, -scene.dim);
    if (v.is_number()) {
      spacing.assignments.push_back("sample.nodes=" + text(v.get<double>() * shrink));
    } else if (v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number()) {
      spacing.assignments.push_back("sample.nodes=[" + text(v[0].get<double>() * shrink) + "," +
                                    text(v[1].get<double>() * shrink) + "]");
    }
  }
  if (!spacing.assignments.empty())
    out.push_back(spacing);
  else
    notes.push_back(
        "No default spacing setting: the family's sample section has no key spacing or "
        "*_spacing; give --setting NAME=sample.KEY=VALUE.");
  if (sized)
    out.push_back({kAnotherMesh,
                   {"scene.background.element_size=" +
                    text(scene.background.element_size * kAnotherMeshFactor)}});
  return out;
}

namespace {

// `settings` as given, each bare name (no assignments yet) replaced by that default setting of
// `family` (the config in `manifest`); all the defaults, with their notes, when none is given.
std::vector<SolverSetting> resolve_settings(std::vector<SolverSetting> settings, const Json& family,
                                            const std::string& manifest,
                                            std::vector<std::string>& notes) {
  std::vector<std::string> default_notes;
  const std::vector<SolverSetting> defaults =
      default_solver_settings(family, manifest + " (config)", default_notes);
  if (settings.empty()) {
    notes = default_notes;
    return defaults;
  }
  for (SolverSetting& s : settings) {
    if (!s.assignments.empty()) continue;
    const auto it = std::find_if(defaults.begin(), defaults.end(),
                                 [&s](const SolverSetting& d) { return d.name == s.name; });
    if (it == defaults.end()) {
      std::string known;
      for (const auto& d : defaults) known += (known.empty() ? "" : ", ") + d.name;
      throw InputError("--setting " + s.name + ": not a default setting of " + manifest +
                       "'s family (" + (known.empty() ? std::string("it has none") : known) +
                       "); give NAME=scene.KEY=VALUE");
    }
    s = *it;
  }
  return settings;
}

}  // namespace

SolverFrontier solver_frontier_experiment(const SolverFrontierOptions& o) {
  if (o.out.empty()) throw InputError("solver-frontier: --out is required");
  // A bare NAME is one of the default settings, looked up once the family is read: its
  // assignments stay empty until then.
  std::vector<SolverSetting> settings;
  for (const std::string& text : o.settings)
    settings.push_back(text.find('=') == std::string::npos && setting_name_ok(text)
                           ? SolverSetting{text, {}}
                           : parse_solver_setting(text));
  {
    std::set<std::string> names;
    for (const auto& s : settings)
      if (!names.insert(s.name).second)
        throw InputError("--setting " + s.name + ": the name is given twice");
  }
  const fs::path manifest = fs::path(o.data) / "generate.json";
  if (!fs::exists(manifest))
    throw InputError(manifest.string() +
                     ": missing; the experiment re-solves trajectories written by bsms generate");
  const Json gen = load_json_file(manifest.string(), "generate manifest");
  if (!gen.contains("config") || !gen["config"].is_object())
    throw InputError(manifest.string() + ": key config: expected the family config object");
  SolverFrontier result;
  settings = resolve_settings(std::move(settings), gen["config"], manifest.string(), result.notes);
  if (settings.empty())
    throw InputError(manifest.string() + ": no default setting applies; give --setting");
  // Every setting checked (unknown keys, bad values) before any solve.
  std::vector<generate::FamilyConfig> families = {
      generate::parse_family(gen["config"], manifest.string() + " (config)")};
  std::vector<std::string> names = {kGroundTruthName};
  for (const SolverSetting& s : settings) {
    Json altered = gen["config"];
    for (const std::string& a : s.assignments) apply_override(altered, a, "--setting " + s.name);
    families.push_back(generate::parse_family(
        altered, manifest.string() + " (config, altered by --setting " + s.name + ")"));
    names.push_back(s.name);
  }
  const generate::FamilyConfig& family = families.front();

  const Dataset data = Dataset::open_split(o.data, o.split);
  if (!data.has_field("world_pos"))
    throw InputError(data.location() + ": no world_pos field; a Lagrangian dataset is needed");
  const int64_t count = o.max_trajectories > 0
                            ? std::min(o.max_trajectories, data.num_trajectories())
                            : data.num_trajectories();
  if (count < 1) throw InputError(data.location() + ": no trajectories");
  std::vector<StoredFrames> stored(static_cast<size_t>(count));
  std::vector<double> stored_ms;
  for (int64_t t = 0; t < count; ++t) {
    StoredFrames& st = stored[static_cast<size_t>(t)];
    const std::string where = data.location() + ": trajectory " + std::to_string(t);
    static_cast<generate::StoredDraw&>(st) = generate::stored_draw(data, t, family.family);
    st.frames = data.num_frames(t);
    if (st.frames < 3) throw InputError(where + ": fewer than 3 frames");
    if (st.frames != family.frames)
      throw InputError(where + ": " + std::to_string(st.frames) + " frames, generate.json's " +
                       std::to_string(family.frames));
    st.world_pos = data.read(t, "world_pos", 0, st.frames);
    st.mesh = data.mesh(t);
    if (data.solver_wall_s(t) >= 0)
      stored_ms.push_back(1000.0 * data.solver_wall_s(t) / static_cast<double>(st.frames - 1));
    st.cv_step_sq = constant_velocity_steps(st);
  }

  const fs::path out = o.out;
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw InputError(o.out + ": cannot create the output folder (" + ec.message() + ")");
  const int threads =
      static_cast<int>(std::min<int64_t>(o.threads > 0 ? o.threads : hardware_threads(),
                                         count * static_cast<int64_t>(families.size())));
  Stopwatch clock;
  const auto scores = solve_all(families, names, stored, threads, out / ".work", o.quiet);

  result.data = data.location();
  result.split = o.split;
  result.family = family.family;
  result.trajectories = count;
  result.frames = family.frames;
  result.threads = threads;
  result.hardware_threads = hardware_threads();
  result.cpu = cpu_model_name();
  result.wall_s = clock.seconds();
  double cv_sq = 0, cv_steps = 0;
  for (const auto& st : stored)
    for (double v : st.cv_step_sq) {
      cv_sq += v;
      ++cv_steps;
    }
  result.rmse_all_constant_velocity = root_mean(cv_sq, cv_steps);
  if (!stored_ms.empty()) result.stored_ms_per_frame = rollout_outputs::median(stored_ms);
  result.ground_truth = summarise({kGroundTruthName, {}}, stored, scores[0], scores[0]);
  for (size_t s = 0; s < settings.size(); ++s)
    result.settings.push_back(summarise(settings[s], stored, scores[s + 1], scores[0]));
  write_text_atomic((out / "solver_frontier.md").string(), markdown(result));
  write_json_atomic((out / "metrics.json").string(), to_json(result));
  return result;
}

}  // namespace bsms
