#include "data/generate/trajectory_solver.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <system_error>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/mpm/scene_builder.hpp"
#include "data/mpm/solver.hpp"

namespace bsms::generate {

namespace fs = std::filesystem;

namespace {

// Restores the calling thread's OpenMP thread count on scope exit.
class SingleThreadedSolve {
 public:
  SingleThreadedSolve() : saved_(omp_get_max_threads()) { omp_set_num_threads(1); }
  ~SingleThreadedSolve() { omp_set_num_threads(saved_); }
  SingleThreadedSolve(const SingleThreadedSolve&) = delete;
  SingleThreadedSolve& operator=(const SingleThreadedSolve&) = delete;

 private:
  int saved_;
};

bool node_is_fixed(const FixedPlane& plane, const double* x, int dim) {
  double depth = 0.0;
  for (int a = 0; a < dim; ++a) depth += (x[a] - plane.point[a]) * plane.normal[a];
  return depth >= -plane.tolerance;
}

template <int Dim>
Trajectory solve(const FamilyConfig& family, const SampledScene& draw, const mpm::Scene& scene,
                 const FrameHook& hook) {
  mpm::BuiltScene<Dim> built = mpm::build_scene<Dim>(scene);
  Trajectory t;
  TrajectoryMesh& m = t.mesh;
  m.dim = Dim;
  m.cell_size = Dim + 1;
  int64_t offset = 0;
  for (const Mesh& body : built.body_meshes) {
    for (int64_t c = 0; c < body.num_cells(); ++c)
      for (int k = 0; k <= Dim; ++k)
        m.cells.push_back(static_cast<int32_t>(offset + body.cells(c, k)));
    offset += body.num_nodes();
  }
  const mpm::Particles<Dim>& p0 = built.particles;
  if (offset != p0.size()) throw NumericalError("body meshes and particles disagree");
  for (int32_t i = 0; i < p0.size(); ++i) {
    double x[Dim];
    for (int a = 0; a < Dim; ++a) {
      x[a] = p0.x[i][a];
      m.mesh_pos.push_back(static_cast<float>(x[a]));
    }
    const int32_t body = p0.body[i];
    NodeType type = NodeType::kNormal;
    if (std::find(draw.actuator_bodies.begin(), draw.actuator_bodies.end(), body) !=
        draw.actuator_bodies.end())
      type = NodeType::kMoving;
    for (const FixedPlane& plane : draw.fixed)
      if (node_is_fixed(plane, x, Dim)) type = NodeType::kFixed;
    m.node_type.push_back(static_cast<int32_t>(type));
    m.body_id.push_back(body);
  }

  mpm::MpmSolver<Dim> solver(std::move(built.background), std::move(built.materials),
                             std::move(built.particles), std::move(built.constraints),
                             built.settings);
  const bool with_velocity =
      std::find(family.fields.begin(), family.fields.end(), "velocity") != family.fields.end();
  const bool with_stress =
      std::find(family.fields.begin(), family.fields.end(), "stress") != family.fields.end();
  std::vector<float>& pos = t.fields["world_pos"];
  std::vector<float>* vel = with_velocity ? &t.fields["velocity"] : nullptr;
  std::vector<float>* stress = with_stress ? &t.fields["stress"] : nullptr;
  auto record = [&] {
    const mpm::Particles<Dim>& p = solver.particles();
    for (int32_t i = 0; i < p.size(); ++i)
      for (int a = 0; a < Dim; ++a) {
        const float x = static_cast<float>(p.x[i][a]);
        const float v = static_cast<float>(p.v[i][a]);
        // The writer refuses NaN; a non-finite state is an unstable solve, to be redrawn.
        if (!std::isfinite(x) || !std::isfinite(v))
          throw NumericalError("non-finite state of particle " + std::to_string(i) +
                               " at t = " + std::to_string(solver.time()) + " s");
        pos.push_back(x);
        if (vel) vel->push_back(v);
      }
    if (stress)
      for (double s : solver.von_mises_stress()) stress->push_back(static_cast<float>(s));
  };
  std::vector<double> hook_x, hook_v;
  auto perturb = [&](int frame) {
    if (!hook) return;
    const mpm::Particles<Dim>& p = solver.particles();
    hook_x.resize(static_cast<size_t>(p.size()) * Dim);
    hook_v.resize(hook_x.size());
    for (int32_t i = 0; i < p.size(); ++i)
      for (int a = 0; a < Dim; ++a) {
        hook_x[static_cast<size_t>(i) * Dim + a] = p.x[i][a];
        hook_v[static_cast<size_t>(i) * Dim + a] = p.v[i][a];
      }
    hook(frame, hook_x, hook_v);
    for (int32_t i = 0; i < p.size(); ++i)
      solver.set_velocity(i,
                          Eigen::Map<const mpm::Vec<Dim>>(&hook_v[static_cast<size_t>(i) * Dim]));
  };
  record();
  Stopwatch clock;
  for (int k = 1; k < family.frames; ++k) {
    perturb(k - 1);
    solver.advance_to(family.frame_dt * k);
    record();
  }
  t.solver_wall_s = clock.seconds();
  t.num_frames = family.frames;
  return t;
}

}  // namespace

StoredDraw stored_draw(const Dataset& data, int64_t t, const std::string& family) {
  const std::string where = data.location() + ": trajectory " + std::to_string(t);
  const Json p = parse_json_text(data.parameters(t), where + ": parameters");
  StoredDraw d;
  try {
    d.run_seed = p.at("run_seed").get<int64_t>();
    d.index = p.at("index").get<int64_t>();
    d.attempt = p.at("attempt").get<int>();
  } catch (const Json::exception& e) {
    throw InputError(where + ": parameters lack the draw (run_seed, index, attempt): " +
                     truncate_for_message(e.what(), 120));
  }
  const Json drawn_family = p.value("family", Json(""));
  if (!drawn_family.is_string() || drawn_family.get<std::string>() != family)
    throw InputError(where + ": family " + describe_json(drawn_family) + ", generate.json's is " +
                     family);
  return d;
}

Trajectory solve_draw(const FamilyConfig& family, int64_t seed, int64_t index, int attempt,
                      const std::string& work_prefix, const FrameHook& hook) {
  const SingleThreadedSolve single;
  const int64_t traj_seed = trajectory_seed(seed, index, attempt);
  Rng rng(static_cast<uint64_t>(traj_seed));
  SampledScene draw = family.sampler->sample(rng, work_prefix + "_a" + std::to_string(attempt));
  struct Cleanup {
    const std::vector<std::string>& files;
    ~Cleanup() {
      std::error_code ec;
      for (const auto& f : files) fs::remove(f, ec);
    }
  } cleanup{draw.work_files};
  const mpm::Scene scene = mpm::parse_scene(draw.scene, family.file);
  // The stored scene names scratch files by their name only: paths differ between runs.
  Json stored = draw.scene;
  for (auto& body : stored["bodies"])
    if (body["shape"].value("type", "") == "mesh")
      body["shape"]["path"] =
          fs::path(body["shape"]["path"].get<std::string>()).filename().string();
  Trajectory t =
      family.dim == 2 ? solve<2>(family, draw, scene, hook) : solve<3>(family, draw, scene, hook);
  t.seed = traj_seed;
  t.parameters =
      Json{{"family", family.family},    {"index", index}, {"attempt", attempt}, {"run_seed", seed},
           {"sampled", draw.parameters}, {"scene", stored}}
          .dump();
  return t;
}

Trajectory generate_trajectory(const FamilyConfig& family, int64_t seed, int64_t index,
                               int max_attempts, const std::string& work_prefix,
                               const std::function<void(const std::string&)>& on_redraw) {
  std::string last_failure;
  for (int attempt = 0; attempt < max_attempts; ++attempt) {
    try {
      return solve_draw(family, seed, index, attempt, work_prefix);
    } catch (const NumericalError& e) {
      last_failure = e.what();
      if (on_redraw)
        on_redraw("trajectory " + std::to_string(index) + " draw " + std::to_string(attempt) +
                  " (seed " + std::to_string(trajectory_seed(seed, index, attempt)) +
                  ") unstable, redrawn: " + e.what());
    }
  }
  throw NumericalError(
      "trajectory " + std::to_string(index) + ": all " + std::to_string(max_attempts) +
      " draws were unstable (last: " + last_failure + "); check the family's ranges");
}

}  // namespace bsms::generate
