#include "pipeline/runs/rollout_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <utility>

#include "pipeline/runs/json_measures.hpp"

namespace bsms {

namespace {

Json to_json(const std::optional<FieldRmse>& rmse) {
  if (!rmse) return nullptr;
  Json j = Json::object();
  for (const auto& [field, value] : rmse->fields) j[field] = value;
  j["total"] = rmse->total;
  return j;
}

// An object of field RMSEs and "total", or null when no step was predicted.
std::optional<FieldRmse> field_rmse_from_json(JsonObjectReader& parent, const std::string& key) {
  const Json& value = parent.raw(key);
  if (value.is_null()) return std::nullopt;
  require(value.is_object(), parent.context(key), "an object of field RMSEs and total, or null");
  JsonObjectReader r(value, parent.context(key));
  FieldRmse rmse;
  rmse.total = read_measure(r, "total");
  for (const auto& item : value.items())
    if (item.key() != "total") rmse.fields[item.key()] = read_measure(r, item.key());
  require(!rmse.fields.empty(), parent.context(key), "an object of field RMSEs and total, or null");
  return rmse;
}

Json to_json(const MotionRmse& parts) {
  return {
      {"centre", parts.centre}, {"rotation", parts.rotation}, {"deformation", parts.deformation}};
}

// {centre, rotation, deformation}; absent (Eulerian rollouts) is none.
std::optional<MotionRmse> motion_rmse_from_json(JsonObjectReader& parent, const std::string& key) {
  if (!parent.has(key)) return std::nullopt;
  const Json& value = parent.raw(key);
  require(value.is_object(), parent.context(key), "an object {centre, rotation, deformation}");
  JsonObjectReader r(value, parent.context(key));
  MotionRmse parts;
  parts.centre = read_measure(r, "centre");
  parts.rotation = read_measure(r, "rotation");
  parts.deformation = read_measure(r, "deformation");
  r.finish();
  return parts;
}

std::vector<double> measures_from_json(const Json& values, const JsonContext& where) {
  require(values.is_array(), where, "an array of numbers");
  std::vector<double> out;
  out.reserve(values.size());
  for (size_t i = 0; i < values.size(); ++i)
    out.push_back(measure_from_json(values[i], where.child(std::to_string(i))));
  return out;
}

// Per field, one value per predicted step.
std::map<std::string, std::vector<double>> curves_from_json(JsonObjectReader& parent,
                                                            const std::string& key) {
  const Json& value = parent.raw(key);
  require(value.is_object(), parent.context(key), "an object of per-step RMSE arrays");
  JsonObjectReader r(value, parent.context(key));
  std::map<std::string, std::vector<double>> curves;
  for (const auto& item : value.items())
    curves[item.key()] = measures_from_json(r.raw(item.key()), r.context(item.key()));
  return curves;
}

Json to_json(const TrajectoryRmse& t) {
  return {{"steps", t.steps},
          {"rmse_all", t.model},
          {"rmse_all_constant_velocity", t.constant_velocity}};
}

// {steps, rmse_all, rmse_all_constant_velocity}, arrays of one length; absent (Eulerian
// rollouts) is none.
std::optional<TrajectoryRmse> trajectory_rmse_from_json(JsonObjectReader& parent,
                                                        const std::string& key) {
  if (!parent.has(key)) return std::nullopt;
  const Json& value = parent.raw(key);
  const char* shape =
      "an object {steps, rmse_all, rmse_all_constant_velocity} of equal-length arrays";
  require(value.is_object(), parent.context(key), shape);
  JsonObjectReader r(value, parent.context(key));
  TrajectoryRmse t;
  const Json& steps = r.raw("steps");
  require(steps.is_array(), r.context("steps"), "an array of step counts");
  for (const Json& v : steps) {
    require(v.is_number_integer() && v.get<int64_t>() >= 0, r.context("steps"),
            "an array of step counts (integers >= 0)");
    t.steps.push_back(v.get<int64_t>());
  }
  t.model = measures_from_json(r.raw("rmse_all"), r.context("rmse_all"));
  t.constant_velocity = measures_from_json(r.raw("rmse_all_constant_velocity"),
                                           r.context("rmse_all_constant_velocity"));
  r.finish();
  require(t.model.size() == t.steps.size() && t.constant_velocity.size() == t.steps.size(),
          parent.context(key), shape);
  return t;
}

// [lo, hi] with 0 <= lo <= hi; absent is none.
std::optional<RatioInterval> interval_from_json(JsonObjectReader& parent, const std::string& key) {
  if (!parent.has(key)) return std::nullopt;
  const Json& value = parent.raw(key);
  require(value.is_array() && value.size() == 2 && value[0].is_number() && value[1].is_number(),
          parent.context(key), "[lo, hi]");
  RatioInterval i{value[0].get<double>(), value[1].get<double>()};
  require(std::isfinite(i.lo) && std::isfinite(i.hi) && 0 <= i.lo && i.lo <= i.hi,
          parent.context(key), "[lo, hi] with 0 <= lo <= hi");
  return i;
}

Json to_json(const ValidityMeasures& measures) {
  Json j = Json::object();
  const std::pair<const char*, const std::optional<ValidityCurve>*> curves[] = {
      {"overlap", &measures.overlap},
      {"nodes_in_other_body", &measures.nodes_in_other_body},
      {"outside_walls", &measures.outside_walls},
      {"nodes_outside_walls", &measures.nodes_outside_walls}};
  for (const auto& [key, curve] : curves) {
    if (!*curve) continue;
    Json per_step = Json::array(), per_trajectory = Json::array();
    for (const double v : (*curve)->per_step) per_step.push_back(measure_json(v));
    for (const double v : (*curve)->per_trajectory) per_trajectory.push_back(measure_json(v));
    j[key] = {{"per_step", per_step},
              {"per_trajectory", per_trajectory},
              {"max", measure_json((*curve)->max)}};
  }
  return j;
}

// {overlap, nodes_in_other_body, outside_walls, nodes_outside_walls}, each optional and each
// {per_step, per_trajectory, max}.
ValidityMeasures validity_measures_from_json(JsonObjectReader& parent, const std::string& key) {
  const Json& value = parent.raw(key);
  require(value.is_object(), parent.context(key),
          "an object of validity curves {per_step, per_trajectory, max}");
  JsonObjectReader r(value, parent.context(key));
  ValidityMeasures measures;
  const std::pair<const char*, std::optional<ValidityCurve>*> curves[] = {
      {"overlap", &measures.overlap},
      {"nodes_in_other_body", &measures.nodes_in_other_body},
      {"outside_walls", &measures.outside_walls},
      {"nodes_outside_walls", &measures.nodes_outside_walls}};
  for (const auto& [name, curve] : curves) {
    if (!r.has(name)) continue;
    const Json& object = r.raw(name);
    require(object.is_object(), r.context(name), "an object {per_step, per_trajectory, max}");
    JsonObjectReader c(object, r.context(name));
    ValidityCurve out;
    out.per_step = measures_from_json(c.raw("per_step"), c.context("per_step"));
    out.per_trajectory = measures_from_json(c.raw("per_trajectory"), c.context("per_trajectory"));
    out.max = read_measure(c, "max");
    c.finish();
    *curve = std::move(out);
  }
  r.finish();
  return measures;
}

// {model, truth}; absent (nothing to measure: Eulerian, 1-D, no walls or cells) is none.
std::optional<PhysicalValidityMetrics> validity_from_json(JsonObjectReader& parent,
                                                          const std::string& key) {
  if (!parent.has(key)) return std::nullopt;
  const Json& value = parent.raw(key);
  require(value.is_object(), parent.context(key), "an object {model, truth}");
  JsonObjectReader r(value, parent.context(key));
  PhysicalValidityMetrics v;
  v.model = validity_measures_from_json(r, "model");
  v.truth = validity_measures_from_json(r, "truth");
  r.finish();
  return v;
}

ProjectionMetrics projection_from_json(JsonObjectReader& parent, const std::string& key) {
  const Json& value = parent.raw(key);
  require(value.is_object(), parent.context(key),
          "an object {constraints, steps, nodes_clamped_per_step, ...}");
  JsonObjectReader r(value, parent.context(key));
  ProjectionMetrics p;
  p.constraints = r.get<std::vector<std::string>>("constraints");
  for (const std::string& name : p.constraints)
    require(name == "walls" || name == "cells" || name == "contact", r.context("constraints"),
            "a list of \"walls\", \"cells\" and \"contact\"");
  p.steps = read_int_at_least<int64_t>(r, "steps", 0);
  for (const auto& [name, field] :
       {std::pair{"nodes_clamped_per_step", &p.nodes_clamped_per_step},
        std::pair{"cells_restored_per_step", &p.cells_restored_per_step},
        std::pair{"nodes_pushed_out_per_step", &p.nodes_pushed_out_per_step},
        std::pair{"passes_per_step", &p.passes_per_step}, std::pair{"shift_rms", &p.shift_rms}}) {
    *field = r.get<double>(name);
    require(*field >= 0, r.context(name), "a number >= 0");
  }
  p.unconverged_steps = read_int_at_least<int64_t>(r, "unconverged_steps", 0);
  r.finish();
  return p;
}

std::vector<DivergedTrajectory> diverged_from_json(JsonObjectReader& parent) {
  const Json& list = parent.raw("diverged");
  require(list.is_array(), parent.context("diverged"), "an array of {trajectory, frame}");
  std::vector<DivergedTrajectory> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const JsonContext where = parent.context("diverged." + std::to_string(i));
    require(list[i].is_object(), where, "an object {trajectory, frame}");
    JsonObjectReader r(list[i], where);
    DivergedTrajectory d;
    d.trajectory = read_int_at_least<int64_t>(r, "trajectory", 0);
    d.frame = read_int_at_least<int64_t>(r, "frame", 0);
    r.finish();
    out.push_back(d);
  }
  return out;
}

}  // namespace

std::optional<RatioInterval> bootstrap_ratio_interval(const std::vector<int64_t>& steps,
                                                      const std::vector<double>& a,
                                                      const std::vector<double>& b, double level,
                                                      int resamples, uint64_t seed) {
  if (a.size() != steps.size() || b.size() != steps.size())
    throw std::invalid_argument("bootstrap_ratio_interval: sizes differ");
  if (!(level > 0 && level < 1) || resamples < 2)
    throw std::invalid_argument("bootstrap_ratio_interval: level in (0, 1), resamples >= 2");
  const size_t n = steps.size();
  if (n < 2) return std::nullopt;
  // Each trajectory's squared-error sums: steps x RMSE^2.
  std::vector<double> sa(n), sb(n);
  for (size_t i = 0; i < n; ++i) {
    sa[i] = static_cast<double>(steps[i]) * a[i] * a[i];
    sb[i] = static_cast<double>(steps[i]) * b[i] * b[i];
  }
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<double> ratios;
  ratios.reserve(static_cast<size_t>(resamples));
  for (int k = 0; k < resamples; ++k) {
    double num = 0, den = 0;
    for (size_t j = 0; j < n; ++j) {
      const size_t i = pick(rng);
      num += sa[i];
      den += sb[i];
    }
    if (!(den > 0) || !std::isfinite(num)) return std::nullopt;
    ratios.push_back(std::sqrt(num / den));
  }
  std::sort(ratios.begin(), ratios.end());
  // Percentiles by linear interpolation between order statistics.
  auto quantile = [&](double q) {
    const double at = q * static_cast<double>(ratios.size() - 1);
    const size_t below = static_cast<size_t>(std::floor(at));
    const size_t above = std::min(below + 1, ratios.size() - 1);
    return ratios[below] + (at - static_cast<double>(below)) * (ratios[above] - ratios[below]);
  };
  return RatioInterval{quantile(0.5 * (1 - level)), quantile(0.5 * (1 + level))};
}

void HorizonRmse::add(const std::map<std::string, std::vector<double>>& step_mse) {
  size_t steps = 0;
  for (const auto& [field, mse] : step_mse) steps = std::max(steps, mse.size());
  if (steps == 0) return;
  ++trajectories_;
  longest_ = std::max(longest_, steps);
  auto add_over = [&](const std::string& horizon, size_t h) {
    for (const auto& [field, mse] : step_mse) {
      const size_t n = std::min(h, mse.size());
      double sum = 0.0;
      for (size_t s = 0; s < n; ++s) sum += mse[s];
      sums_[horizon][field] += n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
    }
  };
  for (const int h : kRmseHorizons) add_over(std::to_string(h), static_cast<size_t>(h));
  add_over("all", steps);
}

std::map<std::string, FieldRmse> HorizonRmse::result() const {
  std::map<std::string, FieldRmse> out;
  if (trajectories_ == 0) return out;
  for (const auto& [horizon, fields] : sums_) {
    if (horizon != "all" && static_cast<size_t>(std::stoi(horizon)) > longest_) continue;
    FieldRmse rmse;
    double squares = 0.0;
    for (const auto& [field, sum] : fields) {
      const double value = sum / static_cast<double>(trajectories_);
      rmse.fields[field] = value;
      squares += value * value;
    }
    rmse.total = std::sqrt(squares / static_cast<double>(fields.size()));
    out[horizon] = rmse;
  }
  return out;
}

double FieldRmse::at(const std::string& field) const {
  const auto it = fields.find(field);
  return it == fields.end() ? std::nan("") : it->second;
}

double RolloutMetrics::rmse(const std::optional<FieldRmse>& over, const std::string& field) {
  return over ? over->at(field) : std::nan("");
}

const std::vector<double>& RolloutMetrics::per_step(const std::string& field) const {
  static const std::vector<double> none;
  const auto it = rmse_per_step.find(field);
  return it == rmse_per_step.end() ? none : it->second;
}

Json to_json(const RolloutMetrics& m) {
  Json j;
  j["model"] = m.model;
  if (m.eulerian) j["kind"] = "eulerian";
  j["split"] = m.split;
  j["data"] = m.data;
  j["num_trajectories"] = m.num_trajectories;
  if (m.one_step) j["one_step"] = true;
  if (m.symmetries > 1) j["symmetries"] = m.symmetries;
  if (m.projection) {
    const ProjectionMetrics& p = *m.projection;
    j["projection"] = {{"constraints", p.constraints},
                       {"steps", p.steps},
                       {"nodes_clamped_per_step", p.nodes_clamped_per_step},
                       {"cells_restored_per_step", p.cells_restored_per_step},
                       {"nodes_pushed_out_per_step", p.nodes_pushed_out_per_step},
                       {"passes_per_step", p.passes_per_step},
                       {"shift_rms", p.shift_rms},
                       {"unconverged_steps", p.unconverged_steps}};
  }
  j["rmse_1"] = to_json(m.rmse_1);
  j["rmse_50"] = to_json(m.rmse_50);
  j["rmse_all"] = to_json(m.rmse_all);
  j["rmse_per_step"] = m.rmse_per_step;
  if (!m.rmse_trajectory_mean.empty()) {
    Json table = Json::object();
    for (const auto& [horizon, rmse] : m.rmse_trajectory_mean) table[horizon] = to_json(rmse);
    j["rmse_trajectory_mean"] = table;
  }
  if (m.eulerian) {
    j["rmse_1_persistence"] = to_json(m.rmse_1_persistence);
    j["rmse_all_persistence"] = to_json(m.rmse_all_persistence);
  } else {
    if (m.rmse_all_persistence) j["rmse_all_persistence"] = to_json(m.rmse_all_persistence);
    j["rmse_all_constant_velocity"] = nullable_json(m.rmse_all_constant_velocity);
    j["inverted_cells_per_step"] = m.inverted_cells_per_step;
    j["inverted_cells_max"] = m.inverted_cells_max;
    if (m.rmse_all_parts) j["rmse_all_parts"] = to_json(*m.rmse_all_parts);
    if (m.rmse_all_parts_constant_velocity)
      j["rmse_all_parts_constant_velocity"] = to_json(*m.rmse_all_parts_constant_velocity);
    if (m.rmse_all_deformation_rigid)
      j["rmse_all_deformation_rigid"] = *m.rmse_all_deformation_rigid;
    if (m.rmse_all_ratio_interval)
      j["rmse_all_ratio_interval"] = {m.rmse_all_ratio_interval->lo, m.rmse_all_ratio_interval->hi};
    if (m.per_trajectory) j["per_trajectory"] = to_json(*m.per_trajectory);
    if (m.validity)
      j["validity"] = {{"model", to_json(m.validity->model)},
                       {"truth", to_json(m.validity->truth)}};
  }
  j["seeding"] = m.seeding;
  j["infer_ms_per_step"] = m.infer_ms_per_step;
  j["solver_ms_per_frame"] = nullable_json(m.solver_ms_per_frame);
  j["speedup_vs_solver"] = nullable_json(m.speedup_vs_solver);
  j["peak_rss_mb_infer"] = m.peak_rss_mb_infer;
  j["num_nodes_mean"] = m.num_nodes_mean;
  j["threads"] = m.threads;
  if (!m.cpu.empty()) j["cpu"] = m.cpu;
  Json diverged = Json::array();
  for (const auto& d : m.diverged)
    diverged.push_back({{"trajectory", d.trajectory}, {"frame", d.frame}});
  j["diverged"] = diverged;
  j["levels"] = m.levels;
  j["train_ms_per_step"] = nullable_json(m.train_ms_per_step);
  j["peak_rss_mb_train"] = nullable_json(m.peak_rss_mb_train);
  if (m.train_steps) j["train_steps"] = *m.train_steps;
  if (!m.checkpoint.empty()) j["checkpoint"] = m.checkpoint;
  if (m.checkpoint_step) j["checkpoint_step"] = *m.checkpoint_step;
  return j;
}

RolloutMetrics rollout_metrics_from_json(const Json& json, const std::string& file) {
  RolloutMetrics m;
  require(json.is_object(), {file, ""}, "a JSON object");
  JsonObjectReader r(json, {file, ""});
  m.model = r.get<std::string>("model");
  {  // one model, or an ensemble's members joined by "+"
    bool known = !m.model.empty();
    for (size_t at = 0; known && at <= m.model.size();) {
      const size_t end = std::min(m.model.find('+', at), m.model.size());
      const std::string member = m.model.substr(at, end - at);
      known = member == "bsms" || member == "mgn";
      at = end + 1;
    }
    require(known, r.context("model"),
            "\"bsms\" or \"mgn\", or an ensemble's members joined by \"+\" (e.g. \"bsms+mgn\")");
  }
  if (r.has("kind")) {
    require(r.get<std::string>("kind") == "eulerian", r.context("kind"),
            "\"eulerian\" (Lagrangian metrics have no kind)");
    m.eulerian = true;
  }
  m.split = r.get<std::string>("split");
  m.data = r.get<std::string>("data");
  m.num_trajectories = read_int_at_least<int64_t>(r, "num_trajectories", 0);
  m.one_step = r.opt<bool>("one_step", false);
  if (r.has("symmetries")) m.symmetries = read_int_at_least<int>(r, "symmetries", 1);
  if (r.has("projection")) m.projection = projection_from_json(r, "projection");
  m.rmse_1 = field_rmse_from_json(r, "rmse_1");
  m.rmse_50 = field_rmse_from_json(r, "rmse_50");
  m.rmse_all = field_rmse_from_json(r, "rmse_all");
  m.rmse_per_step = curves_from_json(r, "rmse_per_step");
  if (r.has("rmse_trajectory_mean")) {
    const Json& table = r.raw("rmse_trajectory_mean");
    const JsonContext where = r.context("rmse_trajectory_mean");
    require(table.is_object(), where, "an object of horizons (\"1\", ..., \"all\")");
    JsonObjectReader t(table, where);
    for (const auto& item : table.items()) {
      const std::string& h = item.key();
      bool known = h == "all";
      for (const int k : kRmseHorizons) known = known || h == std::to_string(k);
      require(known, where,
              "horizons 1, 10, 20, 50, 100, 200 and all (not " + truncate_for_message(h) + ")");
      if (auto rmse = field_rmse_from_json(t, h)) m.rmse_trajectory_mean[h] = *rmse;
    }
  }
  if (m.eulerian) {
    m.rmse_1_persistence = field_rmse_from_json(r, "rmse_1_persistence");
    m.rmse_all_persistence = field_rmse_from_json(r, "rmse_all_persistence");
  } else {
    if (r.has("rmse_all_persistence"))
      m.rmse_all_persistence = field_rmse_from_json(r, "rmse_all_persistence");
    m.rmse_all_constant_velocity = read_nullable(r, "rmse_all_constant_velocity");
    // Fractions of the cells: in [0, 1] (NaN for a diverged step).
    m.inverted_cells_per_step =
        measures_from_json(r.raw("inverted_cells_per_step"), r.context("inverted_cells_per_step"));
    for (const double f : m.inverted_cells_per_step)
      require(!(f > 1.0), r.context("inverted_cells_per_step"), "a list of fractions in [0, 1]");
    m.inverted_cells_max = read_at_least(r, "inverted_cells_max");
    require(m.inverted_cells_max <= 1.0, r.context("inverted_cells_max"), "a fraction in [0, 1]");
    m.rmse_all_parts = motion_rmse_from_json(r, "rmse_all_parts");
    m.rmse_all_parts_constant_velocity =
        motion_rmse_from_json(r, "rmse_all_parts_constant_velocity");
    if (r.has("rmse_all_deformation_rigid"))
      m.rmse_all_deformation_rigid = read_measure(r, "rmse_all_deformation_rigid");
    m.rmse_all_ratio_interval = interval_from_json(r, "rmse_all_ratio_interval");
    m.per_trajectory = trajectory_rmse_from_json(r, "per_trajectory");
    m.validity = validity_from_json(r, "validity");
  }
  m.seeding = r.get<std::string>("seeding");
  m.infer_ms_per_step = read_at_least(r, "infer_ms_per_step");
  m.solver_ms_per_frame = read_nullable(r, "solver_ms_per_frame");
  m.speedup_vs_solver = read_nullable(r, "speedup_vs_solver");
  m.peak_rss_mb_infer = read_at_least(r, "peak_rss_mb_infer");
  m.num_nodes_mean = read_at_least(r, "num_nodes_mean");
  m.threads = read_int_at_least<int>(r, "threads", 0);
  m.cpu = r.opt<std::string>("cpu", "");
  m.diverged = diverged_from_json(r);
  m.levels = read_int_at_least<int>(r, "levels", 1);
  m.train_ms_per_step = read_nullable(r, "train_ms_per_step");
  m.peak_rss_mb_train = read_nullable(r, "peak_rss_mb_train");
  if (r.has("train_steps")) m.train_steps = read_int_at_least<int64_t>(r, "train_steps", 0);
  m.checkpoint = r.opt<std::string>("checkpoint", "");
  require(m.checkpoint.empty() || m.checkpoint == "best" || m.checkpoint == "latest",
          r.context("checkpoint"), "\"best\" or \"latest\"");
  if (r.has("checkpoint_step"))
    m.checkpoint_step = read_int_at_least<int64_t>(r, "checkpoint_step", 0);
  r.finish();
  return m;
}

RolloutMetrics read_rollout_metrics(const std::string& file) {
  if (!std::filesystem::exists(file))
    throw InputError(file + ": not found (run bsms rollout first)");
  return rollout_metrics_from_json(load_json_file(file, "rollout metrics"), file);
}

}  // namespace bsms
