// metrics.json of `bsms experiment solver-frontier`, and what its another_mesh setting means:
// written by the experiment, read by `bsms report`. Apart from the experiment
// (solver_frontier.cpp), which needs the solver, so that the report reads these files without it.
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "pipeline/experiments/solver_frontier.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/runs/json_measures.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

constexpr const char* kFrontierExperiment = "solver-frontier";

Json to_json(const FrontierSetting& s) {
  Json per = Json::array();
  for (const auto& t : s.per_trajectory) {
    Json j = {{"trajectory", t.trajectory},
              {"index", t.index},
              {"unstable", t.unstable},
              {"ms_per_frame", measure_json(t.ms_per_frame)},
              {"rmse_all", measure_json(t.rmse_all)},
              {"rmse_all_constant_velocity", measure_json(t.rmse_all_constant_velocity)},
              {"steps", t.steps}};
    if (t.unstable) j["message"] = t.message;
    per.push_back(j);
  }
  return {{"name", s.name},
          {"assignments", s.assignments},
          {"interpolated", s.interpolated},
          {"ms_per_frame", measure_json(s.ms_per_frame)},
          {"speedup_vs_ground_truth", measure_json(s.speedup_vs_ground_truth)},
          {"rmse_all", measure_json(s.rmse_all)},
          {"rmse_all_over_constant_velocity", measure_json(s.rmse_all_over_constant_velocity)},
          {"max_abs_diff_m", measure_json(s.max_abs_diff_m)},
          {"unstable", s.unstable},
          {"per_trajectory", per}};
}

std::vector<std::string> strings_from_json(const Json& value, const JsonContext& where) {
  require(value.is_array(), where, "an array of strings");
  std::vector<std::string> out;
  for (const Json& v : value) {
    require(v.is_string(), where, "an array of strings");
    out.push_back(v.get<std::string>());
  }
  return out;
}

FrontierSetting setting_from_json(const Json& value, const JsonContext& where) {
  require(value.is_object(), where, "an object describing one solver setting");
  JsonObjectReader r(value, where);
  FrontierSetting s;
  s.name = r.get<std::string>("name");
  s.assignments = strings_from_json(r.raw("assignments"), r.context("assignments"));
  s.interpolated = r.get<bool>("interpolated");
  s.ms_per_frame = read_measure(r, "ms_per_frame");
  s.speedup_vs_ground_truth = read_measure(r, "speedup_vs_ground_truth");
  s.rmse_all = read_measure(r, "rmse_all");
  s.rmse_all_over_constant_velocity = read_measure(r, "rmse_all_over_constant_velocity");
  s.max_abs_diff_m = read_measure(r, "max_abs_diff_m");
  s.unstable = read_int_at_least<int64_t>(r, "unstable", 0);
  const Json& per = r.raw("per_trajectory");
  require(per.is_array(), r.context("per_trajectory"), "an array of per-trajectory objects");
  for (size_t i = 0; i < per.size(); ++i) {
    const JsonContext at = r.context("per_trajectory." + std::to_string(i));
    require(per[i].is_object(), at, "an object");
    JsonObjectReader t(per[i], at);
    FrontierTrajectory tr;
    tr.trajectory = read_int_at_least<int64_t>(t, "trajectory", 0);
    tr.index = read_int_at_least<int64_t>(t, "index", 0);
    tr.unstable = t.get<bool>("unstable");
    if (tr.unstable) tr.message = t.get<std::string>("message");
    tr.ms_per_frame = read_measure(t, "ms_per_frame");
    tr.rmse_all = read_measure(t, "rmse_all");
    tr.rmse_all_constant_velocity = read_measure(t, "rmse_all_constant_velocity");
    tr.steps = read_int_at_least<int64_t>(t, "steps", 0);
    t.finish();
    s.per_trajectory.push_back(tr);
  }
  r.finish();
  require(s.unstable <= static_cast<int64_t>(s.per_trajectory.size()), r.context("unstable"),
          "at most the number of trajectories");
  return s;
}

}  // namespace

Json to_json(const SolverFrontier& r) {
  Json settings = Json::array();
  for (const auto& s : r.settings) settings.push_back(to_json(s));
  return {{"experiment", kFrontierExperiment},
          {"data", r.data},
          {"split", r.split},
          {"family", r.family},
          {"trajectories", r.trajectories},
          {"frames", r.frames},
          {"threads", r.threads},
          {"hardware_threads", r.hardware_threads},
          {"cpu", r.cpu},
          {"wall_s", r.wall_s},
          {"rmse_all_constant_velocity", measure_json(r.rmse_all_constant_velocity)},
          {"stored_ms_per_frame", nullable_json(r.stored_ms_per_frame)},
          {"ground_truth", to_json(r.ground_truth)},
          {"settings", settings},
          {"notes", r.notes}};
}

SolverFrontier solver_frontier_from_json(const Json& json, const std::string& file) {
  require(json.is_object(), {file, ""}, "a JSON object");
  JsonObjectReader r(json, {file, ""});
  require(r.get<std::string>("experiment") == kFrontierExperiment, r.context("experiment"),
          std::string("\"") + kFrontierExperiment + "\" (bsms experiment solver-frontier)");
  SolverFrontier f;
  f.data = r.get<std::string>("data");
  f.split = r.get<std::string>("split");
  f.family = r.get<std::string>("family");
  f.trajectories = read_int_at_least<int64_t>(r, "trajectories", 1);
  f.frames = read_int_at_least<int64_t>(r, "frames", 3);
  f.threads = read_int_at_least<int>(r, "threads", 1);
  f.hardware_threads = read_int_at_least<int>(r, "hardware_threads", 1);
  f.cpu = r.opt<std::string>("cpu", "");
  f.wall_s = read_at_least(r, "wall_s");
  f.rmse_all_constant_velocity = read_measure(r, "rmse_all_constant_velocity");
  f.stored_ms_per_frame = read_nullable(r, "stored_ms_per_frame");
  f.ground_truth = setting_from_json(r.raw("ground_truth"), r.context("ground_truth"));
  const Json& settings = r.raw("settings");
  require(settings.is_array(), r.context("settings"), "an array of solver settings");
  for (size_t i = 0; i < settings.size(); ++i)
    f.settings.push_back(
        setting_from_json(settings[i], r.context("settings." + std::to_string(i))));
  f.notes = strings_from_json(r.raw("notes"), r.context("notes"));
  r.finish();
  const auto whole = [&](const FrontierSetting& s, const std::string& key) {
    require(static_cast<int64_t>(s.per_trajectory.size()) == f.trajectories, r.context(key),
            "one per_trajectory entry per trajectory (" + std::to_string(f.trajectories) + ")");
  };
  whole(f.ground_truth, "ground_truth");
  for (size_t i = 0; i < f.settings.size(); ++i)
    whole(f.settings[i], "settings." + std::to_string(i));
  return f;
}

SolverFrontier read_solver_frontier(const std::string& path) {
  const fs::path file = fs::is_directory(path) ? fs::path(path) / "metrics.json" : fs::path(path);
  if (!fs::exists(file))
    throw InputError(file.string() + ": not found (run bsms experiment solver-frontier first)");
  return solver_frontier_from_json(load_json_file(file.string(), "solver-frontier metrics"),
                                   file.string());
}

const FrontierSetting* another_mesh_setting(const SolverFrontier& f) {
  for (const auto& s : f.settings)
    if (s.name == kAnotherMesh && std::isfinite(s.rmse_all)) return &s;
  return nullptr;
}

std::string another_mesh_paragraph(const SolverFrontier& f) {
  const FrontierSetting* s = another_mesh_setting(f);
  if (!s) return "";
  std::ostringstream md;
  if (!(s->rmse_all > 0)) {
    md << kAnotherMesh << " reproduced the stored frames exactly: its change of the background "
       << "element size left the mesh as it was, so it does not measure the mesh's part of the "
          "truth here; give --setting "
       << kAnotherMesh << "=scene.background.element_size=VALUE with a size that remeshes.\n";
    return md.str();
  }
  md << kAnotherMesh
     << " solves each trajectory at the same resolution on another background mesh. Contact and "
        "wall forces act through the background nodes, so part of the truth depends on the exact "
        "mesh; "
     << kAnotherMesh << "'s " << format_number(s->rmse_all_over_constant_velocity, 3)
     << "× constant velocity is that part's size: the scale of the data's floor for a model "
        "that does not see the background mesh, an error no training of such a model removes.";
  // Stiff scenes lose a few re-solves on another mesh; the floor is still what the others say.
  if (s->unstable > 0)
    md << " (Over the trajectories it solved: " << s->unstable << " of " << f.trajectories
       << " re-solves were unstable.)";
  md << "\n";
  return md.str();
}

}  // namespace bsms
