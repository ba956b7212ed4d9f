#include "pipeline/rollout/rollout.hpp"

#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/dataset/dataset.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/graphs/graph_store.hpp"
#include "pipeline/rollout/body_motion_error.hpp"
#include "pipeline/rollout/rollout_eulerian.hpp"
#include "pipeline/rollout/rollout_model.hpp"
#include "pipeline/rollout/rollout_outputs.hpp"
#include "pipeline/rollout/scene_symmetry.hpp"
#include "pipeline/rollout/validity_tally.hpp"
#include "pipeline/runs/rollout_metrics.hpp"
#include "pipeline/runs/run_files.hpp"
#include "pipeline/train/trainer.hpp"

namespace bsms {
namespace fs = std::filesystem;

namespace {

// Mean squared error per predicted step, per field, accumulated over trajectories.
struct ErrorCurves {
  std::vector<double> pos_sum, vel_sum;
  std::vector<double> stress_sum;    // with a stress output (has_stress)
  std::vector<double> inverted_sum;  // fraction of cells with flipped orientation, predicted
  std::vector<int64_t> count;
  bool has_stress = false;
  void add(size_t step, double pos_mse, double vel_mse, double inverted, double stress_mse = 0) {
    if (pos_sum.size() <= step) {
      pos_sum.resize(step + 1, 0.0);
      vel_sum.resize(step + 1, 0.0);
      stress_sum.resize(step + 1, 0.0);
      inverted_sum.resize(step + 1, 0.0);
      count.resize(step + 1, 0);
    }
    pos_sum[step] += pos_mse;
    vel_sum[step] += vel_mse;
    stress_sum[step] += stress_mse;
    inverted_sum[step] += inverted;
    ++count[step];
  }
};

// Signed measure (2D: doubled area, 3D: 6 x volume) of every simplex of `cells` at positions
// `x` [N, dim]; the sign tells the orientation.
torch::Tensor signed_measures(const torch::Tensor& cells, const torch::Tensor& x, int dim) {
  std::vector<torch::Tensor> edges;
  const auto x0 = x.index_select(0, cells.select(1, 0));
  for (int k = 1; k <= dim; ++k) edges.push_back(x.index_select(0, cells.select(1, k)) - x0);
  if (dim == 2)
    return edges[0].select(1, 0) * edges[1].select(1, 1) -
           edges[0].select(1, 1) * edges[1].select(1, 0);
  if (dim == 3) return (torch::cross(edges[0], edges[1], 1) * edges[2]).sum(1);
  return edges[0].select(1, 0);
}

// Fraction of cells whose orientation in `x` differs from the reference orientation.
double inverted_fraction(const torch::Tensor& cells, const torch::Tensor& reference_sign,
                         const torch::Tensor& x, int dim) {
  if (cells.size(0) == 0) return 0.0;
  const auto sign = signed_measures(cells, x, dim).sign();
  return (sign * reference_sign <= 0).to(torch::kFloat64).mean().item<double>();
}

// Sums of per-step body motion errors (mean squared) and their count, as RMSE parts.
struct MotionErrorSum {
  BodyMotionError sum;
  int64_t count = 0;
  void add(const BodyMotionError& e) {
    sum += e;
    ++count;
  }
  std::optional<MotionRmse> rmse() const {
    if (count == 0) return std::nullopt;
    const double c = static_cast<double>(count);
    return MotionRmse{std::sqrt(sum.centre / c), std::sqrt(sum.rotation / c),
                      std::sqrt(sum.deformation / c)};
  }
};

std::optional<FieldRmse> rmse_over(const ErrorCurves& c, size_t steps) {
  double pos = 0, vel = 0, stress = 0;
  int64_t n = 0;
  for (size_t s = 0; s < std::min(steps, c.count.size()); ++s) {
    pos += c.pos_sum[s];
    vel += c.vel_sum[s];
    stress += c.stress_sum[s];
    n += c.count[s];
  }
  if (n == 0) return std::nullopt;
  pos /= static_cast<double>(n);
  vel /= static_cast<double>(n);
  stress /= static_cast<double>(n);
  FieldRmse rmse;
  rmse.fields = {{"world_pos", std::sqrt(pos)}, {"velocity", std::sqrt(vel)}};
  if (c.has_stress) rmse.fields["stress"] = std::sqrt(stress);
  rmse.total = std::sqrt(0.5 * (pos + vel));
  return rmse;
}

// A further run of an ensemble: Lagrangian, predicting what the first run predicts.
RolloutModel open_member(const std::string& run, const LagrangianSpec& first, const Dataset& data,
                         const std::string& data_dir, const std::string& seeding) {
  const RunFolder folder = RunFolder::open(run);
  const Json& features = folder.features_resolved;
  if (features.is_object() && features.value("kind", std::string()) == "eulerian")
    throw InputError(folder.config_path + ": --ensemble " + run +
                     " is an Eulerian run; an ensemble averages Lagrangian runs");
  const LagrangianSpec spec = lagrangian_spec_from_json(features, folder.config_path);
  if (spec.dim != first.dim || spec.first_order != first.first_order || spec.stress != first.stress)
    throw InputError(folder.config_path + ": --ensemble " + run + " predicts " +
                     (spec.first_order ? "velocities" : "accelerations") + " in " +
                     std::to_string(spec.dim) + "-D" + (spec.stress ? " and stress" : "") +
                     "; the first run " + (first.first_order ? "velocities" : "accelerations") +
                     " in " + std::to_string(first.dim) + "-D" +
                     (first.stress ? " and stress" : ""));
  return open_rollout_model(folder, data, data_dir, seeding);
}

}  // namespace

RolloutMetrics rollout(const RolloutRequest& request) {
  const std::string run = request.run;
  const RunFolder folder = RunFolder::open(run);
  const std::string& config_file = folder.config_path;
  const TrainConfig& config = folder.config;
  const int levels = folder.levels;
  const Json& features = folder.features_resolved;
  if (features.is_object() && features.value("kind", std::string()) == "eulerian") {
    if (!request.ensemble.empty())
      throw InputError(config_file + ": an Eulerian run; --ensemble averages Lagrangian runs");
    if (request.symmetrize)
      throw InputError(config_file + ": an Eulerian run; --symmetrize maps Lagrangian states");
    if (!projection_names(request.projection).empty())
      throw InputError(config_file + ": an Eulerian run; --project moves Lagrangian nodes");
    return rollout_eulerian(request, config, eulerian_spec_from_json(features, config_file), levels,
                            folder.stats);
  }
  LagrangianSpec spec = lagrangian_spec_from_json(features, config_file);
  const int threads = configure_threads(set_num_threads(request.threads));

  const std::string data_dir = request.data.empty() ? config.data : request.data;
  const Dataset data = Dataset::open_split(data_dir, request.split);
  if (data.dim() != spec.dim || data.mesh(0).dim != spec.mesh_dimension())
    throw InputError(data.location() + ": dimension " + std::to_string(data.dim()) + " (mesh " +
                     std::to_string(data.mesh(0).dim) + ") differs from the model's " +
                     std::to_string(spec.dim) + " (mesh " + std::to_string(spec.mesh_dimension()) +
                     ")");
  RolloutModel first = open_rollout_model(folder, data, data_dir, request.seeding);
  spec = first.spec;
  std::string model_name = first.model_type;
  std::vector<RolloutModel> members;
  for (const std::string& other : request.ensemble) {
    members.push_back(open_member(other, spec, data, data_dir, request.seeding));
    model_name += "+" + members.back().model_type;
  }
  if (!data.has_field("world_pos"))
    throw InputError(data.location() + ": a Lagrangian rollout needs the field world_pos");
  if (spec.stress && !data.has_field("stress"))
    throw InputError(data.location() +
                     ": the model predicts stress and the data has no field "
                     "stress to start from and score against");
  if (spec.stress && request.symmetrize)
    throw InputError(config_file +
                     ": --symmetrize averages motions over the box's symmetries; this run also "
                     "predicts stress: roll it out without --symmetrize");
  // Frame averaging: each model's prediction averaged over the scene's symmetries.
  std::vector<BoxSymmetry> symmetries;
  if (request.symmetrize) {
    std::string why;
    symmetries = scene_symmetries(data.scene(), spec.dim, &why);
    if (symmetries.size() < 2)
      throw InputError(data.location() + ": --symmetrize: " + why +
                       ", so there is no symmetry to average over");
    if (spec.mesh_dimension() != spec.dim)
      throw InputError(config_file + ": --symmetrize needs mesh positions in " +
                       std::to_string(spec.dim) + "-D like the world positions (the run has " +
                       std::to_string(spec.mesh_dimension()) + "-D ones)");
  }
  const int64_t count = request.max_trajectories > 0
                            ? std::min(request.max_trajectories, data.num_trajectories())
                            : data.num_trajectories();
  std::error_code ec;
  const Seeding seeding = first.seeding;
  GraphStore& store = *first.store;
  const LagrangianAdapter& adapter = *first.adapter;

  const fs::path out_dir = rollout_outputs::out_dir(request);
  const std::string out_h5 = rollout_outputs::prediction_file(out_dir, request.split, data);
  fs::create_directories(out_dir, ec);
  DatasetWriter writer(out_h5, data.scene(), spec.dim, data.frame_dt());

  const double frame_dt = data.frame_dt() > 0 ? data.frame_dt() : 1.0;
  ErrorCurves curves;
  curves.has_stress = spec.stress;
  double stress_held_sq = 0;  // reference: the stress of frame 1 held (pooled like curves)
  int64_t stress_held_count = 0;
  std::vector<double> solver_ms_per_frame;
  // Reference: constant-velocity extrapolation from the first two frames (zero acceleration).
  double inertial_sq = 0.0;
  int64_t inertial_count = 0;
  // RMSE-all split into each body's centre, rotation and deformation, model and reference.
  MotionErrorSum model_parts, inertial_parts, rigid_parts;
  TrajectoryRmse per_trajectory;
  HorizonRmse horizons;  // the references' table: RMSE over the first h steps, per trajectory
  // Physical validity of the predicted and the true frames: overlap between bodies (cells of the
  // full dimension) and nodes outside the walls (box scenes with walls).
  const BoxWalls walls = scene_walls(data.scene(), spec.dim);
  const ProjectionOptions& projection = request.projection;
  if (projection.walls && walls.empty())
    throw InputError(data.location() +
                     ": --project walls needs a box scene with walls (its scene has none)");
  if ((projection.cells || projection.contact) &&
      !(data.mesh(0).cell_size == spec.dim + 1 && spec.dim >= 2 && spec.dim <= 3))
    throw InputError(data.location() +
                     ": --project cells and contact need triangles (2-D) or tetrahedra (3-D); its "
                     "cells have " +
                     std::to_string(data.mesh(0).cell_size) + " nodes in " +
                     std::to_string(spec.dim) + "-D");
  ProjectionTally projection_tally;
  ValidityTally validity(data.mesh(0).cell_size == spec.dim + 1 && spec.dim >= 2 && spec.dim <= 3,
                         !walls.empty() && spec.dim >= 2 && spec.dim <= 3);
  rollout_outputs::RolloutTally tally;
  ProgressBar bar("rollout " + request.split, count);
  torch::InferenceMode inference;
  for (int64_t t = 0; t < count; ++t) {
    const TrajectoryMesh& mesh = data.mesh(t);
    const int64_t n = mesh.num_nodes();
    tally.nodes_total += static_cast<double>(n);
    int64_t frames = data.num_frames(t);
    if (request.max_steps > 0) frames = std::min(frames, request.max_steps + 2);
    if (frames < 3)
      throw InputError(data.location() + ": trajectory " + std::to_string(t) +
                       " has fewer than 3 frames");
    auto raw = data.read(t, "world_pos", 0, frames);
    const auto truth = torch::from_blob(raw.data(), {frames, n, spec.dim}, torch::kFloat32).clone();
    std::vector<torch::Tensor> pred = {truth[0], truth[1]};
    torch::Tensor truth_stress;  // [frames, n, 1] with a stress output
    std::vector<torch::Tensor> pred_stress;
    if (spec.stress) {
      auto values = data.read(t, "stress", 0, frames);
      truth_stress = torch::from_blob(values.data(), {frames, n, 1}, torch::kFloat32).clone();
      pred_stress = {truth_stress[0], truth_stress[1]};
    }
    const auto graphs_owner = store.get(mesh);
    const MeshGraphs& graphs = *graphs_owner;
    // Orientation checks need simplices of the full dimension (e.g. not shells in 3D).
    const bool simplices = mesh.cell_size == spec.dim + 1 && mesh.num_cells() > 0;
    const auto cells = simplices
                           ? torch::from_blob(const_cast<int32_t*>(mesh.cells.data()),
                                              {mesh.num_cells(), mesh.cell_size}, torch::kInt32)
                                 .to(torch::kInt64)
                           : torch::zeros({0, spec.dim + 1}, torch::kInt64);
    const auto reference_sign = signed_measures(cells, truth[0], spec.dim).sign();
    const std::optional<PhysicalValidity> frame_validity = validity_for_mesh(mesh, spec.dim, walls);
    // Made at the first step, when the batch tells which nodes the model moves (the others are
    // driven by the scene and stay where the truth has them).
    std::optional<PhysicalProjection> projector;
    validity.start_trajectory();
    std::vector<TrajectoryMesh> mapped_meshes;  // the mesh under each symmetry after the identity
    for (size_t k = 1; k < symmetries.size(); ++k)
      mapped_meshes.push_back(symmetries[k].mesh(mesh));
    int64_t steps = 0;
    double model_sq = 0, inertial_traj_sq = 0;            // this trajectory's sums of per-step MSE
    std::map<std::string, std::vector<double>> step_mse;  // this trajectory's, for `horizons`
    for (int64_t f = 1; f + 1 < frames; ++f) {
      Stopwatch clock;
      // The state the model sees: its own frames, or the truth with teacher forcing.
      auto seen = [&](int64_t k) { return request.one_step ? truth[k] : pred[k]; };
      FrameState state{&graphs, &mesh, seen(f - 1), seen(f), truth[f + 1], {}};
      for (int64_t k = f - 2; k >= 0 && k > f - 1 - spec.history; --k)
        state.older.push_back(seen(k));
      Batch batch = adapter.make_batch({state});
      if (!projector && !projection_names(projection).empty()) {
        const auto rest = truth[0].contiguous();
        const auto movable = batch.mask.to(torch::kUInt8).contiguous();
        projector.emplace(
            spec.dim, simplices ? mesh.cells : std::vector<int32_t>{}, mesh.body_id, n,
            rest.data_ptr<float>(), projection.walls ? walls : BoxWalls{}, projection,
            std::vector<uint8_t>(movable.data_ptr<uint8_t>(), movable.data_ptr<uint8_t>() + n));
      }
      // One model's acceleration for `own` (the state through that model's graphs; `plain`: its
      // batch, when built) or, with --symmetrize, the mean over `own` mapped by each symmetry
      // (one block-diagonal batch), each prediction mapped back.
      auto predict = [&](RolloutModel& m, const FrameState& own, const Batch* plain) {
        if (symmetries.empty())
          return m.simulator->predict(plain ? *plain : m.adapter->make_batch({own}));
        std::vector<FrameState> views = {own};
        for (size_t k = 1; k < symmetries.size(); ++k) {
          const BoxSymmetry& g = symmetries[k];
          FrameState view = own;
          view.mesh = &mapped_meshes[k - 1];
          view.prev = g.points(own.prev);
          view.cur = g.points(own.cur);
          view.next = g.points(own.next);
          for (auto& older : view.older) older = g.points(older);
          views.push_back(view);
        }
        const int64_t count = static_cast<int64_t>(symmetries.size());
        const auto out =
            m.simulator->predict(m.adapter->make_batch(views)).view({count, n, spec.dim});
        torch::Tensor sum = out[0];
        for (int64_t k = 1; k < count; ++k) sum = sum + symmetries[k].vectors_back(out[k]);
        return sum / static_cast<double>(count);
      };
      auto accel = predict(first, state, &batch);
      for (RolloutModel& m : members) {  // the same state through each member's own inputs
        FrameState own{m.store->get(mesh).get(), &mesh, seen(f - 1), seen(f), truth[f + 1], {}};
        for (int64_t k = f - 2; k >= 0 && k > f - 1 - m.spec.history; --k)
          own.older.push_back(seen(k));
        accel = accel + predict(m, own, nullptr);
      }
      if (!members.empty()) accel = accel / static_cast<double>(members.size() + 1);
      torch::Tensor stress;  // predicted on the solved nodes, the truth elsewhere
      if (spec.stress) {
        stress = torch::where(batch.mask.unsqueeze(1), accel.narrow(1, spec.dim, 1),
                              truth_stress[f + 1]);
        accel = accel.narrow(1, 0, spec.dim);
      }
      auto next = adapter.integrate(batch, accel, truth[f + 1]);
      if (projector) {
        next = next.contiguous();
        projection_tally.add(projector->project(next.data_ptr<float>()), n);
      }
      tally.infer_ms.push_back(clock.milliseconds());
      if (!torch::isfinite(next).all().item<bool>() ||
          (stress.defined() && !torch::isfinite(stress).all().item<bool>())) {
        tally.diverged.push_back({t, f + 1});
        break;
      }
      pred.push_back(next);
      double stress_err = 0;
      if (stress.defined()) {
        pred_stress.push_back(stress);
        stress_err = (stress - truth_stress[f + 1]).pow(2).mean().item<double>();
        stress_held_sq += (truth_stress[1] - truth_stress[f + 1]).pow(2).mean().item<double>();
        ++stress_held_count;
        step_mse["stress"].push_back(stress_err);
      }
      {
        const auto mask = batch.mask.unsqueeze(1);
        // With teacher forcing the references start from the true frames too: one step at the
        // last true velocity, and each body's shape of frame f held.
        const auto inertial =
            request.one_step
                ? torch::where(mask, 2 * truth[f] - truth[f - 1], truth[f + 1])
                : torch::where(mask, truth[1] + static_cast<double>(f) * (truth[1] - truth[0]),
                               truth[f + 1]);
        const double inertial_mse = (inertial - truth[f + 1]).pow(2).mean().item<double>();
        inertial_sq += inertial_mse;
        inertial_traj_sq += inertial_mse;
        ++inertial_count;
        inertial_parts.add(body_motion_error(inertial, truth[f + 1], mesh.body_id));
        rigid_parts.add(
            body_motion_error(request.one_step ? truth[f] : truth[1], truth[f + 1], mesh.body_id));
      }
      model_parts.add(body_motion_error(next, truth[f + 1], mesh.body_id));
      const auto pos_err = (next - truth[f + 1]).pow(2).mean().item<double>();
      const auto vel_err =
          ((next - seen(f)) - (truth[f + 1] - truth[f])).div(frame_dt).pow(2).mean().item<double>();
      curves.add(static_cast<size_t>(f - 1), pos_err, vel_err,
                 inverted_fraction(cells, reference_sign, next, spec.dim), stress_err);
      if (frame_validity) {
        const auto predicted = next.contiguous();
        const auto target = truth[f + 1].contiguous();
        validity.add(static_cast<size_t>(f - 1),
                     frame_validity->measure(predicted.data_ptr<float>()),
                     frame_validity->measure(target.data_ptr<float>()));
      }
      model_sq += pos_err;
      step_mse["world_pos"].push_back(pos_err);
      step_mse["velocity"].push_back(vel_err);
      ++steps;
    }
    horizons.add(step_mse);
    const double inv_steps = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
    per_trajectory.steps.push_back(steps);
    per_trajectory.model.push_back(std::sqrt(model_sq * inv_steps));
    per_trajectory.constant_velocity.push_back(std::sqrt(inertial_traj_sq * inv_steps));
    const double solver_s = data.solver_wall_s(t);
    if (solver_s >= 0)
      solver_ms_per_frame.push_back(1000.0 * solver_s /
                                    static_cast<double>(data.num_frames(t) - 1));

    Trajectory out;
    out.mesh = mesh;
    out.seed = data.seed(t);
    out.parameters = data.parameters(t);
    out.num_frames = static_cast<int64_t>(pred.size());
    out.fields["world_pos"] = rollout_outputs::to_floats(torch::stack(pred));
    out.fields["target_world_pos"] = rollout_outputs::to_floats(truth.slice(0, 0, out.num_frames));
    if (spec.stress) {
      out.fields["stress"] = rollout_outputs::to_floats(torch::stack(pred_stress));
      out.fields["target_stress"] =
          rollout_outputs::to_floats(truth_stress.slice(0, 0, out.num_frames));
    }
    writer.add(out);
    if (!request.quiet) bar.update(t + 1);
  }
  writer.commit();
  if (!request.quiet) bar.finish();
  rollout_outputs::write_xdmf_files(out_h5, out_dir, request.split);

  RolloutMetrics metrics;
  metrics.model = model_name;
  metrics.split = request.split;
  metrics.data = data.location();
  metrics.num_trajectories = count;
  metrics.one_step = request.one_step;
  metrics.symmetries = symmetries.empty() ? 1 : static_cast<int>(symmetries.size());
  metrics.projection = projection_tally.metrics(projection_names(projection));
  metrics.rmse_1 = rmse_over(curves, 1);
  metrics.rmse_50 = rmse_over(curves, 50);
  metrics.rmse_all = rmse_over(curves, curves.count.size());
  metrics.rmse_trajectory_mean = horizons.result();
  if (stress_held_count > 0) {
    FieldRmse held;
    held.fields = {{"stress", std::sqrt(stress_held_sq / static_cast<double>(stress_held_count))}};
    held.total = held.fields["stress"];
    metrics.rmse_all_persistence = held;
  }
  if (inertial_count > 0)
    metrics.rmse_all_constant_velocity =
        std::sqrt(inertial_sq / static_cast<double>(inertial_count));
  metrics.rmse_all_parts = model_parts.rmse();
  metrics.rmse_all_parts_constant_velocity = inertial_parts.rmse();
  if (const auto rigid = rigid_parts.rmse())
    metrics.rmse_all_deformation_rigid = rigid->deformation;
  metrics.rmse_all_ratio_interval = bootstrap_ratio_interval(
      per_trajectory.steps, per_trajectory.model, per_trajectory.constant_velocity);
  metrics.per_trajectory = std::move(per_trajectory);
  std::vector<double>& per_step = metrics.rmse_per_step["world_pos"];
  for (size_t s = 0; s < curves.count.size(); ++s)
    per_step.push_back(std::sqrt(curves.pos_sum[s] / static_cast<double>(curves.count[s])));
  if (spec.stress) {
    std::vector<double>& stress_step = metrics.rmse_per_step["stress"];
    for (size_t s = 0; s < curves.count.size(); ++s)
      stress_step.push_back(std::sqrt(curves.stress_sum[s] / static_cast<double>(curves.count[s])));
  }
  // Stability: the fraction of predicted cells turned inside out (orientation flipped against
  // the first frame), per step and at worst; the ground truth has none (the solver stops on J <=
  // 0).
  for (size_t s = 0; s < curves.count.size(); ++s) {
    const double f = curves.inverted_sum[s] / static_cast<double>(curves.count[s]);
    metrics.inverted_cells_per_step.push_back(f);
    metrics.inverted_cells_max = std::max(metrics.inverted_cells_max, f);
  }
  metrics.validity = validity.metrics();
  rollout_outputs::add_run_figures(metrics, tally, count, seeding, threads, levels, folder.stats);
  if (!solver_ms_per_frame.empty()) {
    metrics.solver_ms_per_frame = rollout_outputs::median(solver_ms_per_frame);
    if (metrics.infer_ms_per_step > 0)
      metrics.speedup_vs_solver = *metrics.solver_ms_per_frame / metrics.infer_ms_per_step;
  }
  write_json_atomic((out_dir / "metrics.json").string(), to_json(metrics));
  if (!request.quiet) {
    std::cerr << "bsms rollout: " << count << " trajectories, "
              << (request.one_step ? "one-step (teacher forcing) " : "") << "RMSE-all(world_pos) "
              << (metrics.rmse_all ? metrics.rmse_all->at("world_pos") : 0.0);
    if (metrics.rmse_all && metrics.rmse_all->fields.count("stress"))
      std::cerr << ", RMSE-all(stress) " << metrics.rmse_all->at("stress") << " (held "
                << (metrics.rmse_all_persistence ? metrics.rmse_all_persistence->at("stress") : 0.0)
                << ")";
    if (metrics.rmse_all_parts)
      std::cerr << " (by body: centre " << metrics.rmse_all_parts->centre << ", rotation "
                << metrics.rmse_all_parts->rotation << ", deformation "
                << metrics.rmse_all_parts->deformation << ")";
    if (metrics.rmse_all && metrics.rmse_all_constant_velocity &&
        *metrics.rmse_all_constant_velocity > 0) {
      std::cerr << ", " << metrics.rmse_all->at("world_pos") / *metrics.rmse_all_constant_velocity
                << "x constant velocity";
      if (metrics.rmse_all_ratio_interval)
        std::cerr << " (95 % over trajectories " << metrics.rmse_all_ratio_interval->lo << "-"
                  << metrics.rmse_all_ratio_interval->hi << ")";
    }
    if (metrics.validity && metrics.validity->model.overlap && metrics.validity->truth.overlap)
      std::cerr << ", overlap between bodies at worst " << metrics.validity->model.overlap->max
                << " (truth " << metrics.validity->truth.overlap->max << ")";
    std::cerr << ", " << metrics.infer_ms_per_step << " ms/step -> "
              << (out_dir / "metrics.json").string() << "\n";
  }
  return metrics;
}

}  // namespace bsms
