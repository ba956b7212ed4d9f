#include "pipeline/experiments/predictability.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <thread>

#include "core/config.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "data/generate/family.hpp"
#include "data/generate/rng.hpp"
#include "data/generate/trajectory_solver.hpp"
#include "pipeline/experiments/experiment_runs.hpp"
#include "pipeline/report/number_format.hpp"
#include "pipeline/rollout/body_motion_error.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"

namespace bsms {
namespace fs = std::filesystem;

double log_log_crossing(const std::vector<double>& x, const std::vector<double>& y, double target) {
  if (x.size() != y.size()) throw std::invalid_argument("log_log_crossing: sizes differ");
  for (size_t i = 0; i + 1 < x.size(); ++i) {
    const double y0 = y[i], y1 = y[i + 1];
    if (!(x[i] > 0 && x[i + 1] > x[i] && y0 > 0 && y1 > 0)) continue;
    if (!(y0 <= target && target <= y1)) continue;
    if (y1 == y0) return x[i];
    const double s = (std::log(target) - std::log(y0)) / (std::log(y1) - std::log(y0));
    return std::exp(std::log(x[i]) + s * (std::log(x[i + 1]) - std::log(x[i])));
  }
  return std::numeric_limits<double>::quiet_NaN();
}

ErrorPersistence one_step_error_persistence(const std::string& rollout_h5, int max_lag) {
  if (max_lag < 1) throw std::invalid_argument("one_step_error_persistence: max_lag < 1");
  const Dataset d(rollout_h5);
  if (!d.has_field("world_pos") || !d.has_field("target_world_pos"))
    throw InputError(rollout_h5 +
                     ": not a rollout file (world_pos and target_world_pos are expected)");
  const int dim = d.dim();
  std::vector<double> num(static_cast<size_t>(max_lag) + 1, 0.0), head(num.size(), 0.0),
      tail(num.size(), 0.0);
  ErrorPersistence out;
  for (int64_t t = 0; t < d.num_trajectories(); ++t) {
    const TrajectoryMesh& mesh = d.mesh(t);
    const int64_t n = mesh.num_nodes(), frames = d.num_frames(t);
    if (frames < 3) continue;
    const auto pred = d.read(t, "world_pos", 0, frames);
    const auto truth = d.read(t, "target_world_pos", 0, frames);
    int32_t bodies = 1;
    for (int32_t b : mesh.body_id) bodies = std::max(bodies, b + 1);
    // e[b][f][a]: body b's centre error at predicted frame f + 2.
    const int64_t m = frames - 2;
    std::vector<double> e(static_cast<size_t>(bodies * m * dim), 0.0);
    std::vector<double> count(static_cast<size_t>(bodies), 0.0);
    for (int64_t i = 0; i < n; ++i) {
      const int32_t b = mesh.body_id.empty() ? 0 : mesh.body_id[static_cast<size_t>(i)];
      if (b < 0) continue;
      count[static_cast<size_t>(b)] += 1;
      for (int64_t f = 0; f < m; ++f)
        for (int a = 0; a < dim; ++a) {
          const size_t k = static_cast<size_t>(((f + 2) * n + i) * dim + a);
          e[static_cast<size_t>((b * m + f) * dim + a)] +=
              static_cast<double>(pred[k]) - static_cast<double>(truth[k]);
        }
    }
    for (int32_t b = 0; b < bodies; ++b) {
      if (count[static_cast<size_t>(b)] == 0) continue;
      out.body_frames += m;
      for (int a = 0; a < dim; ++a) {
        auto at = [&](int64_t f) {
          return e[static_cast<size_t>((b * m + f) * dim + a)] / count[static_cast<size_t>(b)];
        };
        for (int lag = 1; lag <= max_lag && lag < m; ++lag)
          for (int64_t f = 0; f + lag < m; ++f) {
            num[static_cast<size_t>(lag)] += at(f) * at(f + lag);
            head[static_cast<size_t>(lag)] += at(f) * at(f);
            tail[static_cast<size_t>(lag)] += at(f + lag) * at(f + lag);
          }
      }
    }
  }
  bool summing = true;
  for (int lag = 1; lag <= max_lag; ++lag) {
    const double den = std::sqrt(head[static_cast<size_t>(lag)] * tail[static_cast<size_t>(lag)]);
    const double rho =
        den > 0 ? num[static_cast<size_t>(lag)] / den : std::numeric_limits<double>::quiet_NaN();
    out.autocorrelation.push_back(rho);
    if (summing && std::isfinite(rho) && rho > 0)
      out.tau += 2.0 * rho;
    else
      summing = false;
  }
  out.rho_ar1 = (out.tau - 1.0) / (out.tau + 1.0);
  return out;
}

namespace {

struct Point {
  double scale = 1.0;
  bool once = false;
  double rho = 0.0;  // correlation of the kicks between consecutive frames
  // No kicks: the (altered, --solver-set) re-solve scored against the stored frames.
  bool altered = false;
  std::string mode() const {
    return altered   ? "altered solver, no kicks"
           : once    ? "once"
           : rho > 0 ? "every, persistent"
                     : "every, independent";
  }
};

// One trajectory as stored: its draw and its frames.
struct StoredTrajectory : generate::StoredDraw {
  std::vector<float> world_pos;  // [F, N, dim]
  int64_t frames = 0;
  TrajectoryMesh mesh;
};

// What one trajectory contributes to one point (all its draws together).
struct PointResult {
  std::vector<double> step_sq;  // per predicted step, the MSE summed over draws
  BodyMotionError parts, first_parts;
  int draws_done = 0, failed = 0;
  double sq = 0.0;  // per-step MSE summed over steps and draws
  int64_t steps = 0;
};

struct TrajectoryResult {
  double resolve_max_abs_diff = 0.0;
  std::vector<double> cv_step_sq;  // constant velocity, per predicted step
  double cv_sq = 0.0;
  int64_t cv_steps = 0;
  std::vector<PointResult> points;
};

double gaussian(generate::Rng& rng) {
  const double u1 = 1.0 - rng.uniform(), u2 = rng.uniform();  // u1 in (0, 1]
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// Bodies whose nodes are all free (node_type normal): the ones kicked. Node lists by body.
std::vector<std::vector<int32_t>> free_bodies(const TrajectoryMesh& mesh) {
  std::vector<std::vector<int32_t>> nodes;
  std::vector<uint8_t> prescribed;
  for (int64_t i = 0; i < mesh.num_nodes(); ++i) {
    const int32_t b = mesh.body_id.empty() ? 0 : mesh.body_id[static_cast<size_t>(i)];
    if (b < 0) continue;
    if (static_cast<size_t>(b) >= nodes.size()) {
      nodes.resize(static_cast<size_t>(b) + 1);
      prescribed.resize(nodes.size(), 0);
    }
    nodes[static_cast<size_t>(b)].push_back(static_cast<int32_t>(i));
    if (mesh.node_type[static_cast<size_t>(i)] != static_cast<int32_t>(NodeType::kNormal))
      prescribed[static_cast<size_t>(b)] = 1;
  }
  std::vector<std::vector<int32_t>> out;
  for (size_t b = 0; b < nodes.size(); ++b)
    if (!prescribed[b] && !nodes[b].empty()) out.push_back(std::move(nodes[b]));
  return out;
}

// The kicks of one solve: per frame a random rigid velocity change of each free body (see the
// header), its random parts an AR(1) sequence per body with correlation `rho` between frames
// (0: independent), each part N(0, 1) at every frame.
class Kicker {
 public:
  Kicker(const std::vector<std::vector<int32_t>>& bodies, int dim, double frame_dt, double centre,
         double rotation, double rho, uint64_t seed)
      : bodies_(bodies),
        dim_(dim),
        frame_dt_(frame_dt),
        centre_(centre),
        rotation_(rotation),
        rho_(rho),
        rng_(seed),
        state_(bodies.size()) {}

  void operator()(const std::vector<double>& x, std::vector<double>& v) {
    const int spins = dim_ == 2 ? 1 : 3;
    const double keep = started_ ? rho_ : 0.0, fresh = std::sqrt(1.0 - keep * keep);
    started_ = true;
    for (size_t b = 0; b < bodies_.size(); ++b) {
      const auto& body = bodies_[b];
      auto& z = state_[b];  // [0, dim): translation, [3, 3 + spins): spin
      for (int a = 0; a < dim_; ++a) z[a] = keep * z[a] + fresh * gaussian(rng_);
      for (int a = 0; a < spins; ++a) z[3 + a] = keep * z[3 + a] + fresh * gaussian(rng_);
      double c[3] = {0, 0, 0};
      for (int32_t i : body)
        for (int a = 0; a < dim_; ++a) c[a] += x[static_cast<size_t>(i) * dim_ + a];
      for (int a = 0; a < dim_; ++a) c[a] /= static_cast<double>(body.size());
      double r2 = 0.0;  // mean |x − c|²
      for (int32_t i : body)
        for (int a = 0; a < dim_; ++a) {
          const double d = x[static_cast<size_t>(i) * dim_ + a] - c[a];
          r2 += d * d;
        }
      r2 /= static_cast<double>(body.size());
      double dv[3] = {0, 0, 0}, w[3] = {0, 0, 0};
      for (int a = 0; a < dim_; ++a) dv[a] = centre_ / frame_dt_ * z[a];
      // A spin ω with components N(0, σ²) moves a node at r by |ω × r|, whose mean square is
      // σ² r² (2-D) or 2 σ² r² (3-D); per component that is divided by dim.
      if (rotation_ > 0 && r2 > 0) {
        const double sigma = rotation_ / frame_dt_ / std::sqrt((dim_ == 2 ? 1.0 : 2.0) * r2 / dim_);
        for (int a = 0; a < spins; ++a) w[a] = sigma * z[3 + a];
      }
      for (int32_t i : body) {
        double* vi = &v[static_cast<size_t>(i) * dim_];
        const double* xi = &x[static_cast<size_t>(i) * dim_];
        double r[3] = {0, 0, 0};
        for (int a = 0; a < dim_; ++a) r[a] = xi[a] - c[a];
        for (int a = 0; a < dim_; ++a) vi[a] += dv[a];
        if (dim_ == 2) {
          vi[0] += -w[0] * r[1];
          vi[1] += w[0] * r[0];
        } else {
          vi[0] += w[1] * r[2] - w[2] * r[1];
          vi[1] += w[2] * r[0] - w[0] * r[2];
          vi[2] += w[0] * r[1] - w[1] * r[0];
        }
      }
    }
  }

 private:
  const std::vector<std::vector<int32_t>>& bodies_;
  int dim_;
  double frame_dt_, centre_, rotation_, rho_;
  generate::Rng rng_;
  std::vector<std::array<double, 6>> state_;
  bool started_ = false;
};

const std::vector<float>& positions(const Trajectory& t, const std::string& where) {
  const auto it = t.fields.find("world_pos");
  if (it == t.fields.end()) throw NumericalError(where + ": the solve recorded no world_pos");
  return it->second;
}

// Constant velocity from frame 1 against `truth` [F, N, dim], as bsms rollout scores it
// (prescribed nodes take the truth): per predicted step into `result`.
void score_constant_velocity(const torch::Tensor& truth, const TrajectoryMesh& mesh,
                             TrajectoryResult& result) {
  const int64_t frames = truth.size(0), n = mesh.num_nodes();
  std::vector<uint8_t> free_node(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i)
    free_node[static_cast<size_t>(i)] =
        mesh.node_type[static_cast<size_t>(i)] == static_cast<int32_t>(NodeType::kNormal);
  const auto mask =
      torch::from_blob(free_node.data(), {n, 1}, torch::kUInt8).to(torch::kBool).clone();
  for (int64_t f = 1; f + 1 < frames; ++f) {
    const auto cv =
        torch::where(mask, truth[1] + static_cast<double>(f) * (truth[1] - truth[0]), truth[f + 1]);
    const double mse = (cv - truth[f + 1]).pow(2).mean().item<double>();
    result.cv_step_sq.push_back(mse);
    result.cv_sq += mse;
    ++result.cv_steps;
  }
}

// The seed of kick draw `draw` of point `point` on the trajectory of generator index `index`.
uint64_t kick_seed(uint64_t seed, int64_t index, size_t point, int draw) {
  uint64_t h = splitmix64(seed);
  h = splitmix64(h ^ static_cast<uint64_t>(index));
  h = splitmix64(h ^ static_cast<uint64_t>(point));
  return splitmix64(h ^ static_cast<uint64_t>(draw));
}

TrajectoryResult run_trajectory(const generate::FamilyConfig& family, const StoredTrajectory& st,
                                const std::vector<Point>& points, double centre, double rotation,
                                const PredictabilityOptions& o, int64_t position,
                                const std::string& work_prefix) {
  const TrajectoryMesh& mesh = st.mesh;
  const int dim = family.dim;
  const int64_t n = mesh.num_nodes();
  const std::string where =
      "trajectory " + std::to_string(position) + " (index " + std::to_string(st.index) + ")";
  Trajectory reference;
  try {
    reference = generate::solve_draw(family, st.run_seed, st.index, st.attempt, work_prefix);
  } catch (const NumericalError& e) {  // only an altered solver can fail here
    throw NumericalError(where + ", re-solved with --solver-set: " + e.what());
  }
  const std::vector<float>& ref = positions(reference, where);
  if (static_cast<int64_t>(ref.size()) != st.frames * n * dim)
    throw InputError(o.data + ": " + where + " re-solved to " + std::to_string(ref.size()) +
                     " values, stored " + std::to_string(st.frames * n * dim) +
                     "; the family in generate.json does not reproduce it");
  TrajectoryResult result;
  for (size_t k = 0; k < ref.size(); ++k)
    result.resolve_max_abs_diff = std::max(result.resolve_max_abs_diff,
                                           std::abs(static_cast<double>(ref[k]) - st.world_pos[k]));
  const auto truth =
      torch::from_blob(const_cast<float*>(ref.data()), {st.frames, n, dim}, torch::kFloat32);
  score_constant_velocity(truth, mesh, result);

  const auto bodies = free_bodies(mesh);
  result.points.resize(points.size());
  // Scores `pred` [F, N, dim] against `against` like a rollout (frames 2 to the last).
  auto score = [&](PointResult& pr, const at::Tensor& pred, const at::Tensor& against) {
    for (int64_t f = 1; f + 1 < st.frames; ++f) {
      const double mse = (pred[f + 1] - against[f + 1]).pow(2).mean().item<double>();
      pr.step_sq[static_cast<size_t>(f - 1)] += mse;
      pr.sq += mse;
      ++pr.steps;
      const BodyMotionError e = body_motion_error(pred[f + 1], against[f + 1], mesh.body_id);
      pr.parts += e;
      if (f == 1) pr.first_parts += e;
    }
    ++pr.draws_done;
  };
  for (size_t p = 0; p < points.size(); ++p) {
    PointResult& pr = result.points[p];
    pr.step_sq.assign(static_cast<size_t>(std::max<int64_t>(st.frames - 2, 0)), 0.0);
    if (points[p].altered) {  // the altered solve against the stored frames
      const auto stored = torch::from_blob(const_cast<float*>(st.world_pos.data()),
                                           {st.frames, n, dim}, torch::kFloat32);
      score(pr, truth, stored);
      continue;
    }
    for (int d = 0; d < o.draws; ++d) {
      const Point pt = points[p];
      Kicker kicker(bodies, dim, family.frame_dt, centre * pt.scale, rotation * pt.scale, pt.rho,
                    kick_seed(o.seed, st.index, p, d));
      const generate::FrameHook hook = [&](int frame, const std::vector<double>& x,
                                           std::vector<double>& v) {
        if (frame < 1 || (pt.once && frame != 1)) return;
        kicker(x, v);
      };
      Trajectory kicked;
      try {
        kicked = generate::solve_draw(family, st.run_seed, st.index, st.attempt, work_prefix, hook);
      } catch (const NumericalError&) {
        ++pr.failed;  // the kicked state broke the solver: counted, not averaged
        continue;
      }
      const std::vector<float>& kx = positions(kicked, where);
      score(pr,
            torch::from_blob(const_cast<float*>(kx.data()), {st.frames, n, dim}, torch::kFloat32),
            truth);
    }
  }
  return result;
}

double rms(double sum_sq, double count) {
  return count > 0 ? std::sqrt(sum_sq / count) : std::numeric_limits<double>::quiet_NaN();
}

Json number_or_null(double v) {
  return std::isfinite(v) ? Json(v) : Json(nullptr);
}

std::string sci(double v) {
  return format_number(v, 2, Notation::kScientific);
}

void check_options(const PredictabilityOptions& o) {
  if (o.out.empty()) throw InputError("predictability: --out is required");
  if (o.draws < 1) throw InputError("--draws " + std::to_string(o.draws) + ": must be >= 1");
  if (o.scales.empty()) throw InputError("--scales: give at least one scale");
  for (double s : o.scales)
    if (!(s > 0 && std::isfinite(s)))
      throw InputError("--scales " + format_number(s) + ": each scale must be a positive number");
  if (!std::is_sorted(o.scales.begin(), o.scales.end()) ||
      std::adjacent_find(o.scales.begin(), o.scales.end()) != o.scales.end())
    throw InputError("--scales: give distinct scales in ascending order");
  if (!(o.target > 0 && std::isfinite(o.target)))
    throw InputError("--target " + format_number(o.target) + ": must be a positive ratio");
  if (!(std::isfinite(o.centre) && std::isfinite(o.rotation)))
    throw InputError("--centre / --rotation: must be finite");
  for (const std::string& assignment : o.solver_set)
    if (assignment.rfind("scene.", 0) != 0 || assignment.find('=') == std::string::npos)
      throw InputError("--solver-set " + truncate_for_message(assignment, 80) +
                       ": expected scene.KEY=VALUE (a key of the family's scene, e.g. "
                       "scene.background.element_size=0.041)");
}

// The base one-step error per frame, and the run's own rollout when there is one.
struct BaseError {
  double centre = 0.0, rotation = 0.0;
  std::string source = "given";  // "given" or the one-step metrics file it was read from
  std::string data;              // the dataset of that one-step rollout ("" when given)
  std::optional<RolloutMetrics> model_rollout;  // RUN/rollout/metrics.json
};

// The base one-step error: given, or the run's one-step body error.
BaseError resolve_base_error(const PredictabilityOptions& o) {
  BaseError base;
  base.centre = o.centre;
  base.rotation = o.rotation;
  if (!o.run.empty()) {
    const fs::path one_step = fs::path(o.run) / "rollout_one_step" / "metrics.json";
    if (base.centre <= 0 || base.rotation < 0) {
      if (!fs::exists(one_step))
        throw InputError(one_step.string() + ": missing; run bsms rollout " + o.run + " --split " +
                         o.split + " --one-step first, or give --centre");
      const RolloutMetrics m = read_rollout_metrics(one_step.string());
      if (!m.one_step || !m.rmse_all_parts)
        throw InputError(one_step.string() +
                         ": not a one-step rollout with body error parts (rmse_all_parts); "
                         "re-run bsms rollout --one-step");
      if (base.centre <= 0) base.centre = m.rmse_all_parts->centre;
      if (base.rotation < 0) base.rotation = m.rmse_all_parts->rotation;
      base.source = one_step.string();
      base.data = m.data;
    }
    const fs::path rollout = fs::path(o.run) / "rollout" / "metrics.json";
    if (fs::exists(rollout)) base.model_rollout = read_rollout_metrics(rollout.string());
  }
  if (base.rotation < 0) base.rotation = 0.0;
  if (!(base.centre > 0))
    throw InputError(
        "predictability: no base error; give --run RUN (with a --one-step rollout) "
        "or --centre METRES");
  return base;
}

// The family of DATA/generate.json, altered by --solver-set (the re-solve's reference, kicked or
// not).
generate::FamilyConfig load_family(const PredictabilityOptions& o) {
  const fs::path manifest = fs::path(o.data) / "generate.json";
  if (!fs::exists(manifest))
    throw InputError(manifest.string() +
                     ": missing; the experiment re-solves trajectories written by bsms generate");
  const Json gen = load_json_file(manifest.string(), "generate manifest");
  if (!gen.contains("config") || !gen["config"].is_object())
    throw InputError(manifest.string() + ": key config: expected the family config object");
  Json family_json = gen["config"];
  for (const std::string& assignment : o.solver_set)
    apply_override(family_json, assignment, "--solver-set");
  return generate::parse_family(
      family_json, manifest.string() + " (config" +
                       (o.solver_set.empty() ? std::string() : ", altered by --solver-set") + ")");
}

void check_dataset(const Dataset& data, const BaseError& base, const PredictabilityOptions& o) {
  if (!base.data.empty()) {
    // The base error must be the run's error on these trajectories.
    // (A path that no longer resolves, e.g. relative to another folder, is let through.)
    std::error_code same_ec;
    if (fs::exists(base.data, same_ec) && !fs::equivalent(base.data, data.location(), same_ec))
      throw InputError(base.source + ": a one-step rollout on " + base.data + ", not on " +
                       data.location() + "; roll the run out on it (bsms rollout " + o.run +
                       " --data " + o.data + " --split " + o.split +
                       " --one-step) or give --centre and --rotation");
  }
  if (!data.has_field("world_pos"))
    throw InputError(data.location() + ": no world_pos field; a Lagrangian dataset is needed");
}

// The trajectories re-solved, read in full beforehand: the workers read no file.
std::vector<StoredTrajectory> read_stored(const Dataset& data, const generate::FamilyConfig& family,
                                          const PredictabilityOptions& o) {
  const int64_t count = o.max_trajectories > 0
                            ? std::min(o.max_trajectories, data.num_trajectories())
                            : data.num_trajectories();
  if (count < 1) throw InputError(data.location() + ": no trajectories");
  std::vector<StoredTrajectory> stored(static_cast<size_t>(count));
  for (int64_t t = 0; t < count; ++t) {
    StoredTrajectory& st = stored[static_cast<size_t>(t)];
    const std::string where = data.location() + ": trajectory " + std::to_string(t);
    static_cast<generate::StoredDraw&>(st) = generate::stored_draw(data, t, family.family);
    st.frames = data.num_frames(t);
    if (st.frames < 3) throw InputError(where + ": fewer than 3 frames");
    st.world_pos = data.read(t, "world_pos", 0, st.frames);
    st.mesh = data.mesh(t);
  }
  return stored;
}

// The rows of the experiment and how long their kicks persist.
struct KickPlan {
  double rho = 0.0;  // correlation of the persistent rows' kicks between frames
  std::optional<ErrorPersistence> persistence;  // the run's, when rho was measured
  std::vector<Point> points;
};

KickPlan plan_kicks(const PredictabilityOptions& o) {
  // How long the kicks persist: given, or as long as the run's one-step errors.
  KickPlan plan;
  plan.rho = o.correlation;
  if (plan.rho < 0 && !o.run.empty()) {
    const fs::path file = fs::path(o.run) / "rollout_one_step" / (o.split + ".h5");
    if (!fs::exists(file))
      throw InputError(file.string() + ": missing; run bsms rollout " + o.run + " --split " +
                       o.split + " --one-step first, or give --correlation");
    plan.persistence = one_step_error_persistence(file.string());
    plan.rho = plan.persistence->rho_ar1;
  }
  if (!(plan.rho < 1.0))
    throw InputError("--correlation " + format_number(plan.rho) + ": must be < 1");
  for (double s : o.scales) plan.points.push_back({s, false, 0.0});
  if (plan.rho > 0)
    for (double s : o.scales) plan.points.push_back({s, false, plan.rho});
  for (double s : o.scales) plan.points.push_back({s, true, 0.0});
  if (!o.solver_set.empty()) plan.points.push_back({0.0, false, 0.0, true});
  return plan;
}

struct SolvedTrajectories {
  std::vector<TrajectoryResult> results;  // per stored trajectory
  int threads = 1;                        // trajectories solved at once
  double wall_s = 0.0;
};

// Runs every trajectory, `o.threads` at once, in work folders under `work` (removed after); the
// first failure stops the others and is rethrown.
SolvedTrajectories solve_trajectories(const generate::FamilyConfig& family,
                                      const std::vector<StoredTrajectory>& stored,
                                      const std::vector<Point>& points, const BaseError& base,
                                      const PredictabilityOptions& o, const fs::path& work) {
  const auto count = static_cast<int64_t>(stored.size());
  Stopwatch clock;
  SolvedTrajectories solved;
  solved.results.resize(static_cast<size_t>(count));
  std::atomic<int64_t> next{0}, done{0};
  std::mutex failure_mutex;
  std::exception_ptr failure;
  ProgressBar bar("predictability", count);
  auto worker = [&] {
    for (;;) {
      const int64_t t = next.fetch_add(1);
      if (t >= count) return;
      {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        if (failure) return;
      }
      try {
        solved.results[static_cast<size_t>(t)] =
            run_trajectory(family, stored[static_cast<size_t>(t)], points, base.centre,
                           base.rotation, o, t, (work / ("t" + std::to_string(t))).string());
      } catch (...) {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        if (!failure) failure = std::current_exception();
        return;
      }
      const int64_t k = done.fetch_add(1) + 1;
      if (!o.quiet) {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        bar.update(k);
      }
    }
  };
  solved.threads = static_cast<int>(std::min<int64_t>(
      o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency()), count));
  {
    // Each solve is single-threaded; LibTorch's own pool is not wanted for these small tensors.
    const int torch_threads = torch::get_num_threads();
    torch::set_num_threads(1);
    std::vector<std::thread> pool;
    for (int w = 1; w < solved.threads; ++w) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
    torch::set_num_threads(torch_threads);
  }
  std::error_code ec;
  fs::remove_all(work, ec);
  if (failure) std::rethrow_exception(failure);
  if (!o.quiet) bar.finish();
  solved.wall_s = clock.seconds();
  return solved;
}

// Constant velocity over all trajectories, and how far the unkicked re-solves stray.
struct ConstantVelocity {
  double resolve_diff = 0.0;  // largest |re-solved - stored| position, m
  double rmse = 0.0;          // RMSE-all
  std::vector<double> curve;  // RMSE per predicted step, as long as the longest trajectory's
};

ConstantVelocity constant_velocity(const std::vector<TrajectoryResult>& results) {
  ConstantVelocity cv;
  double cv_sq = 0.0;
  int64_t cv_steps = 0;
  size_t max_steps = 0;
  for (const auto& r : results) {
    cv.resolve_diff = std::max(cv.resolve_diff, r.resolve_max_abs_diff);
    cv_sq += r.cv_sq;
    cv_steps += r.cv_steps;
    max_steps = std::max(max_steps, r.cv_step_sq.size());
  }
  cv.rmse = rms(cv_sq, static_cast<double>(cv_steps));
  std::vector<double> cv_count(max_steps, 0.0);
  cv.curve.assign(max_steps, 0.0);
  for (const auto& r : results)
    for (size_t s = 0; s < r.cv_step_sq.size(); ++s) {
      cv.curve[s] += r.cv_step_sq[s];
      cv_count[s] += 1;
    }
  for (size_t s = 0; s < max_steps; ++s) cv.curve[s] = rms(cv.curve[s], cv_count[s]);
  return cv;
}

// One point (row) over all trajectories.
struct PointSummary {
  std::vector<double> curve;  // RMSE per predicted step
  BodyMotionError parts, first;
  double first_count = 0, steps = 0;
  double rmse_all = 0.0, ratio = 0.0;  // RMSE-all, and over constant velocity's on the same
  std::optional<RatioInterval> interval;
  size_t trajectories = 0;  // with at least one scored draw
  int failed = 0;
};

PointSummary summarize_point(const std::vector<TrajectoryResult>& results, size_t p,
                             size_t max_steps) {
  std::vector<double> step_sq(max_steps, 0.0), step_count(max_steps, 0.0);
  PointSummary out;
  double sq = 0;
  TrajectoryRmse per;
  for (const auto& r : results) {
    const PointResult& pr = r.points[p];
    out.failed += pr.failed;
    if (pr.draws_done == 0) continue;
    for (size_t s = 0; s < pr.step_sq.size(); ++s) {
      step_sq[s] += pr.step_sq[s];
      step_count[s] += pr.draws_done;
    }
    out.parts += pr.parts;
    out.first += pr.first_parts;
    out.first_count += pr.draws_done;
    sq += pr.sq;
    out.steps += static_cast<double>(pr.steps);
    per.steps.push_back(r.cv_steps);
    per.model.push_back(rms(pr.sq, static_cast<double>(pr.steps)));
    per.constant_velocity.push_back(rms(r.cv_sq, static_cast<double>(r.cv_steps)));
  }
  out.curve.resize(max_steps);
  for (size_t s = 0; s < max_steps; ++s) out.curve[s] = rms(step_sq[s], step_count[s]);
  out.rmse_all = rms(sq, out.steps);
  double cv_sel_sq = 0, cv_sel_steps = 0;
  for (size_t i = 0; i < per.size(); ++i) {
    cv_sel_sq +=
        per.constant_velocity[i] * per.constant_velocity[i] * static_cast<double>(per.steps[i]);
    cv_sel_steps += static_cast<double>(per.steps[i]);
  }
  out.ratio = out.rmse_all / rms(cv_sel_sq, cv_sel_steps);
  out.interval = bootstrap_ratio_interval(per.steps, per.model, per.constant_velocity);
  out.trajectories = per.size();
  return out;
}

// metrics.json's row of a point; `c`, `r`: its centre and rotation kick per frame, m.
Json point_row(const Point& pt, const PointSummary& s, double c, double r) {
  return {{"scale", pt.scale},
          {"mode", pt.mode()},
          {"centre_per_frame_m", c},
          {"rotation_per_frame_m", r},
          {"rmse_all", number_or_null(s.rmse_all)},
          {"rmse_all_over_constant_velocity", number_or_null(s.ratio)},
          {"rmse_all_ratio_interval",
           s.interval ? Json::array({s.interval->lo, s.interval->hi}) : Json(nullptr)},
          {"rmse_per_step", s.curve},
          {"rmse_all_parts",
           {{"centre", rms(s.parts.centre, s.steps)},
            {"rotation", rms(s.parts.rotation, s.steps)},
            {"deformation", rms(s.parts.deformation, s.steps)}}},
          {"first_step_parts",
           {{"centre", rms(s.first.centre, s.first_count)},
            {"rotation", rms(s.first.rotation, s.first_count)},
            {"deformation", rms(s.first.deformation, s.first_count)}}},
          {"trajectories", s.trajectories},
          {"failed_solves", s.failed}};
}

// predictability.md's table row of a point; `c`, `r` as for point_row.
std::string point_table_row(const Point& pt, const PointSummary& s, double c, double r) {
  const auto at = [&](size_t step) {
    return step >= 1 && step <= s.curve.size() ? s.curve[step - 1]
                                               : std::numeric_limits<double>::quiet_NaN();
  };
  std::ostringstream table;
  table << "| " << (pt.altered ? std::string() : format_number(pt.scale) + "×, ") << pt.mode()
        << " | " << sci(c) << " / " << sci(r) << " | " << sci(rms(s.first.centre, s.first_count))
        << " / " << sci(rms(s.first.rotation, s.first_count)) << " | " << sci(at(10)) << " / "
        << sci(at(20)) << " / " << sci(at(s.curve.size())) << " | " << sci(s.rmse_all) << " | "
        << format_number(s.ratio, 3)
        << (s.interval ? " [" + format_number(s.interval->lo, 3) + "–" +
                             format_number(s.interval->hi, 3) + "]"
                       : std::string())
        << " | " << sci(rms(s.parts.centre, s.steps)) << " / "
        << sci(rms(s.parts.rotation, s.steps)) << " / " << sci(rms(s.parts.deformation, s.steps))
        << " | " << s.failed << " |\n";
  return table.str();
}

// Every point as a metrics row, a table row and (some) a plotted curve.
struct PointTable {
  Json rows = Json::array();
  std::vector<experiments::Curve> curves;
  // Per mode ("every, independent", "every, persistent"): scales and ratios, for the crossing.
  std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> sweeps;
  std::string table;  // markdown
};

PointTable tabulate_points(const std::vector<Point>& points,
                           const std::vector<TrajectoryResult>& results, size_t max_steps,
                           const BaseError& base) {
  PointTable out;
  out.table =
      "| kick | per frame: centre / rotation (m) | first step: centre / rotation part (m) "
      "| RMSE at step 10 / 20 / last (m) | RMSE-all (m) | / constant velocity [95 %] | "
      "centre / rotation / deformation (m) | failed solves |\n"
      "|---|---|---|---|---|---|---|---|\n";
  for (size_t p = 0; p < points.size(); ++p) {
    const PointSummary s = summarize_point(results, p, max_steps);
    const Point& pt = points[p];
    const double c = pt.altered ? 0.0 : base.centre * pt.scale,
                 r = pt.altered ? 0.0 : base.rotation * pt.scale;
    out.rows.push_back(point_row(pt, s, c, r));
    if (pt.altered) {
      out.curves.push_back(
          {"altered solver against the stored frames", s.curve, "lines lw 2 lc rgb 'dark-red'"});
    } else if (!pt.once) {
      out.sweeps[pt.mode()].first.push_back(pt.scale);
      out.sweeps[pt.mode()].second.push_back(s.ratio);
      if (pt.rho > 0 || pt.scale == 1.0)
        out.curves.push_back({pt.mode() + ", " + format_number(pt.scale) + "x", s.curve,
                              pt.rho > 0 ? "lines lw 2" : "lines lw 2 dt 4"});
    } else if (pt.scale == 1.0) {
      out.curves.push_back({"once, 1x", s.curve, "lines lw 2 dt 3"});
    }
    out.table += point_table_row(pt, s, c, r);
  }
  return out;
}

// metrics.json's model_rollout and the report's sentence on the run's own rollout; its curve
// joins `curves`.
std::string add_model_rollout(const RolloutMetrics& rollout, const PredictabilityOptions& o,
                              Json& result, std::vector<experiments::Curve>& curves) {
  const double m_all = experiments::rmse(rollout, "rmse_all");
  const double m_cv = experiments::rmse_constant_velocity(rollout);
  result["model_rollout"] = {{"file", (fs::path(o.run) / "rollout" / "metrics.json").string()},
                             {"data", rollout.data},
                             {"rmse_all", number_or_null(m_all)},
                             {"rmse_all_over_constant_velocity", number_or_null(m_all / m_cv)}};
  curves.push_back({"model rollout (" + o.run + ")", rollout.per_step("world_pos"),
                    "lines lw 3 lc rgb 'black'"});
  std::ostringstream model_line;
  model_line << "The run's own rollout (`" << o.run << "/rollout/metrics.json`, on `"
             << rollout.data << "`): RMSE-all " << sci(m_all) << " m, "
             << format_number(m_all / m_cv, 3) << "× constant velocity"
             << (rollout.rmse_all_ratio_interval
                     ? " [" + format_number(rollout.rmse_all_ratio_interval->lo, 3) + "–" +
                           format_number(rollout.rmse_all_ratio_interval->hi, 3) + "]"
                     : std::string())
             << ".\n\n";
  return model_line.str();
}

// The report's sentence on how long the kicks persist ("" when there are no persistent rows).
std::string persistence_paragraph(const PredictabilityOptions& o, const KickPlan& kicks) {
  std::ostringstream persistence_line;
  if (kicks.persistence) {
    const ErrorPersistence& persistence = *kicks.persistence;
    persistence_line << "The run's one-step errors (`" << o.run << "/rollout_one_step/" << o.split
                     << ".h5`, " << persistence.body_frames
                     << " body-frames) persist: autocorrelation of a body's centre error at lag "
                        "1 / 2 / 3 / 5 frames ";
    for (size_t L : {1, 2, 3, 5})
      persistence_line << (L > 1 ? " / " : "")
                       << format_number(L <= persistence.autocorrelation.size()
                                            ? persistence.autocorrelation[L - 1]
                                            : std::numeric_limits<double>::quiet_NaN(),
                                        3);
    persistence_line << ", integrated time " << format_number(persistence.tau, 3)
                     << " frames; the *persistent* rows draw AR(1) kicks with the same time "
                        "(correlation "
                     << format_number(kicks.rho, 3) << " between frames).\n\n";
  } else if (kicks.rho > 0) {
    persistence_line << "The *persistent* rows draw AR(1) kicks with correlation "
                     << format_number(kicks.rho, 3) << " between frames (given).\n\n";
  }
  return persistence_line.str();
}

// The report's opening paragraph: what was solved and how it is scored.
std::string setup_paragraph(const PredictabilityOptions& o, const std::string& location,
                            int64_t count, const ConstantVelocity& cv, const BaseError& base) {
  std::string altered_list;
  for (const std::string& a : o.solver_set)
    altered_list += (altered_list.empty() ? "`" : ", `") + a + "`";
  std::ostringstream md;
  md << "## Predictability: the solver kicked by one-step errors\n\n"
     << "`" << location << "`, " << count << " trajectories, each solved again by UMLS-MPM "
     << (o.solver_set.empty()
             ? "(largest difference from the stored frames: " + sci(cv.resolve_diff) + " m)"
             : "with the solver altered (" + altered_list +
                   "; the row *altered solver, no "
                   "kicks* scores that solve against the stored frames, like a rollout)")
     << " and then " << o.draws
     << " time(s) per row with random rigid kicks of its free bodies: per frame a "
     << "velocity change whose displacement over one frame is the row's centre error per "
     << "component (RMS) plus a spin moving the body's nodes by the row's rotation error. Base "
     << "error (1×): centre " << sci(base.centre) << " m, rotation " << sci(base.rotation) << " m ("
     << base.source << "). *every*: kicked at frames 1 to the last but one, as a model errs at "
     << "each step; *once*: at frame 1 only. RMSE against the unkicked solve over the "
     << "predicted frames 2 to the last, as bsms rollout scores a model; constant velocity "
     << "(first velocity extrapolated): " << sci(cv.rmse) << " m. Independent kicks give the best "
     << "rollout such one-step errors allow; errors that persist from frame to frame, as a "
     << "model's do, add up faster.\n\n";
  return md.str();
}

// The report's sentence per swept mode: the scale at which it reaches the target, if bracketed.
std::string crossing_paragraphs(const PointTable& points, const Json& crossings,
                                const PredictabilityOptions& o, const BaseError& base) {
  std::ostringstream md;
  for (const auto& [mode, sweep] : points.sweeps) {
    const double x = crossings[mode].is_number() ? crossings[mode].get<double>()
                                                 : std::numeric_limits<double>::quiet_NaN();
    if (std::isfinite(x))
      md << "*" << mode << "*: RMSE-all reaches " << format_number(o.target)
         << "× constant velocity at " << format_number(x, 3) << "× the base error (centre "
         << sci(base.centre * x) << " m, rotation " << sci(base.rotation * x)
         << " m per frame; log-log interpolation).\n\n";
    else
      md << "*" << mode << "*: the rows do not bracket " << format_number(o.target)
         << "× constant velocity; widen --scales to find the one-step error that reaches it.\n\n";
  }
  return md.str();
}

}  // namespace

Json predictability_experiment(const PredictabilityOptions& o) {
  check_options(o);
  const BaseError base = resolve_base_error(o);
  const generate::FamilyConfig family = load_family(o);
  const Dataset data = Dataset::open_split(o.data, o.split);
  check_dataset(data, base, o);
  const std::vector<StoredTrajectory> stored = read_stored(data, family, o);
  const auto count = static_cast<int64_t>(stored.size());
  const KickPlan kicks = plan_kicks(o);

  const fs::path out = o.out;
  std::error_code ec;
  fs::create_directories(out / "plots", ec);
  if (ec) throw InputError(o.out + ": cannot create (" + ec.message() + ")");
  const fs::path work = out / ".work";
  fs::create_directories(work, ec);
  const SolvedTrajectories solved = solve_trajectories(family, stored, kicks.points, base, o, work);

  const ConstantVelocity cv = constant_velocity(solved.results);
  PointTable points = tabulate_points(kicks.points, solved.results, cv.curve.size(), base);
  Json crossings = Json::object();
  for (const auto& [mode, sweep] : points.sweeps)
    crossings[mode] = number_or_null(log_log_crossing(sweep.first, sweep.second, o.target));

  Json result = {
      {"experiment", "predictability"},
      {"data", data.location()},
      {"split", o.split},
      {"trajectories", count},
      {"draws", o.draws},
      {"seed", o.seed},
      {"threads", solved.threads},
      {"wall_s", solved.wall_s},
      {"base", {{"centre_m", base.centre}, {"rotation_m", base.rotation}, {"from", base.source}}},
      {"resolve_max_abs_diff_m", cv.resolve_diff},
      {"solver_set", o.solver_set},
      {"rmse_all_constant_velocity", number_or_null(cv.rmse)},
      {"constant_velocity_per_step", cv.curve},
      {"points", points.rows},
      {"target", o.target},
      {"correlation", kicks.rho > 0 ? Json(kicks.rho) : Json(0.0)},
      {"target_scale", crossings}};
  if (kicks.persistence)
    result["one_step_persistence"] = {{"autocorrelation", kicks.persistence->autocorrelation},
                                      {"tau", kicks.persistence->tau},
                                      {"rho_ar1", kicks.persistence->rho_ar1},
                                      {"body_frames", kicks.persistence->body_frames}};
  const std::string model_line =
      base.model_rollout ? add_model_rollout(*base.model_rollout, o, result, points.curves) : "";
  points.curves.push_back({"constant velocity", cv.curve, "lines lw 2 dt 2 lc rgb 'gray40'"});
  experiments::plot_curves(out / "plots", "predictability_rmse",
                           "Solver kicked by one-step body errors: RMSE against the unkicked solve",
                           "RMSE (m)", true, points.curves);

  const std::string md = setup_paragraph(o, data.location(), count, cv, base) +
                         persistence_paragraph(o, kicks) + points.table + "\n" + model_line +
                         crossing_paragraphs(points, crossings, o, base) +
                         "![kicked solves](plots/predictability_rmse.png)\n";
  write_text_atomic((out / "predictability.md").string(), md);
  write_json_atomic((out / "metrics.json").string(), result);
  return result;
}

}  // namespace bsms
