// The Lagrangian rollout domain (rollout_domain.hpp): world positions (and, with a stress output,
// the stress) advanced by the model on the predicted nodes, the prescribed path elsewhere; with
// ensembles, frame averaging over the scene's symmetries and constraint projection. Scored beside
// constant velocity, with each body's error split into centre, rotation and deformation, cells
// turned inside out and the physical validity of predicted and true frames.
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "data/mpm/scene_config.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/adapters/lagrangian.hpp"
#include "pipeline/adapters/scene_symmetry.hpp"
#include "pipeline/rollout/body_motion_error.hpp"
#include "pipeline/rollout/rollout_domain.hpp"
#include "pipeline/rollout/rollout_model.hpp"
#include "pipeline/rollout/validity_tally.hpp"

namespace bsms {

namespace {

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

// A further run of an ensemble: Lagrangian, predicting what the first run predicts.
RolloutModel open_member(const std::string& run, const LagrangianSpec& first, const Dataset& data,
                         const std::string& data_dir, const std::string& seeding,
                         const std::string& checkpoint) {
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
  return open_rollout_model(folder, data, data_dir, seeding, checkpoint);
}

bool has_simplices(const Dataset& data, int dim) {
  return data.mesh(0).cell_size == dim + 1 && dim >= 2 && dim <= 3;
}

class LagrangianRollout final : public RolloutDomain {
 public:
  LagrangianRollout(const RolloutRequest& request, const RunFolder& folder);

  // The truth: world positions, then the stress with a stress output.
  torch::Tensor start(int64_t t, int64_t frames) override;
  // Integrated on the predicted nodes (ensemble mean, symmetries averaged, constraints
  // projected), the prescribed path elsewhere.
  torch::Tensor step(int64_t f) override;
  // Position, velocity (and stress) errors; constant velocity, body parts, inverted cells and
  // validity beside them.
  std::vector<FieldError> accept(int64_t f) override;
  void end_trajectory(int64_t steps) override;
  // The references, body parts, per-trajectory RMSE, inverted cells and validity.
  std::string finish(RolloutMetrics& metrics) const override;

 private:
  std::string summary(const RolloutMetrics& metrics) const;
  void open_models(const RunFolder& folder);
  void check_options(const RunFolder& folder);
  // The state the model sees at frame k: its own frames, or the truth with teacher forcing.
  torch::Tensor seen(int64_t k) const { return request_.one_step ? truth_[k] : pred_[k]; }
  FrameState state_for(const RolloutModel& m, const MeshGraphs* graphs, int64_t f) const;
  // One model's output for `own` (its batch `plain` when built) or, with --symmetrize, the mean
  // over `own` mapped by each symmetry (one block-diagonal batch), each prediction mapped back.
  torch::Tensor predict(RolloutModel& m, const FrameState& own, const Batch* plain);
  // Errors of the kept prediction of frame f + 1 against the truth and the references.
  void score_references(int64_t f, const torch::Tensor& mask);

  RolloutRequest request_;
  LagrangianSpec spec_;
  RolloutModel first_;
  std::vector<RolloutModel> members_;
  std::string model_name_;
  std::vector<BoxSymmetry> symmetries_;
  BoxWalls walls_;

  // The trajectory being rolled out.
  int64_t t_ = 0;
  const TrajectoryMesh* mesh_ = nullptr;
  std::shared_ptr<const MeshGraphs> graphs_;
  torch::Tensor truth_, truth_stress_;             // [frames, N, dim], [frames, N, 1]
  std::vector<torch::Tensor> pred_, pred_stress_;  // kept predictions (the given frames first)
  torch::Tensor cells_, reference_sign_;
  std::optional<PhysicalValidity> frame_validity_;
  // Made at the first step, when the batch tells which nodes the model moves (the others are
  // driven by the scene and stay where the truth has them).
  std::optional<PhysicalProjection> projector_;
  std::vector<TrajectoryMesh> mapped_meshes_;     // the mesh under each symmetry after the identity
  torch::Tensor next_, next_stress_, next_mask_;  // step()'s prediction, until accept()
  double model_sq_ = 0, constant_velocity_traj_sq_ = 0;  // this trajectory's sums of step MSE

  // Over all trajectories.
  std::vector<double> inverted_sum_;
  std::vector<int64_t> inverted_count_;
  double stress_held_sq_ = 0;  // reference: the stress of frame 1 held (pooled like the errors)
  int64_t stress_held_count_ = 0;
  // Reference: constant-velocity extrapolation from the first two frames (zero acceleration).
  double constant_velocity_sq_ = 0;
  int64_t constant_velocity_count_ = 0;
  // RMSE-all split into each body's centre, rotation and deformation, model and reference.
  MotionErrorSum model_parts_, constant_velocity_parts_, rigid_parts_;
  TrajectoryRmse per_trajectory_;
  ProjectionTally projection_tally_;
  ValidityTally validity_;
};

LagrangianRollout::LagrangianRollout(const RolloutRequest& request, const RunFolder& folder)
    : request_(request),
      spec_(lagrangian_spec_from_json(folder.features_resolved, folder.config_path)),
      validity_(false, false) {
  data_.emplace(
      Dataset::open_split(request.data.empty() ? folder.config.data : request.data, request.split));
  levels = folder.levels;
  if (data_->dim() != spec_.dim || data_->mesh(0).dim != spec_.mesh_dimension())
    throw InputError(data_->location() + ": dimension " + std::to_string(data_->dim()) + " (mesh " +
                     std::to_string(data_->mesh(0).dim) + ") differs from the model's " +
                     std::to_string(spec_.dim) + " (mesh " +
                     std::to_string(spec_.mesh_dimension()) + ")");
  open_models(folder);
  check_options(folder);
  layout_.given_frames = 2;
  layout_.dim = spec_.dim;
  layout_.frame = {{"world_pos", spec_.dim}};
  layout_.scored = {{"world_pos", true, true}, {"velocity", true, false}};
  if (spec_.stress) {
    layout_.frame.push_back({"stress", 1});
    layout_.scored.push_back({"stress", false, true});
  }
  validity_ = ValidityTally(has_simplices(*data_, spec_.dim),
                            !walls_.empty() && spec_.dim >= 2 && spec_.dim <= 3);
}

void LagrangianRollout::open_models(const RunFolder& folder) {
  const std::string data_dir = request_.data.empty() ? folder.config.data : request_.data;
  first_ = open_rollout_model(folder, *data_, data_dir, request_.seeding, request_.checkpoint);
  spec_ = first_.spec;
  seeding = first_.seeding;
  checkpoint = first_.checkpoint;
  checkpoint_step = first_.checkpoint_step;
  model_name_ = first_.model_type;
  for (const std::string& other : request_.ensemble) {
    members_.push_back(
        open_member(other, spec_, *data_, data_dir, request_.seeding, request_.checkpoint));
    model_name_ += "+" + members_.back().model_type;
  }
}

void LagrangianRollout::check_options(const RunFolder& folder) {
  const std::string& config_file = folder.config_path;
  if (!data_->has_field("world_pos"))
    throw InputError(data_->location() + ": a Lagrangian rollout needs the field world_pos");
  if (spec_.stress && !data_->has_field("stress"))
    throw InputError(data_->location() +
                     ": the model predicts stress and the data has no field "
                     "stress to start from and score against");
  if (spec_.stress && request_.symmetrize)
    throw InputError(config_file +
                     ": --symmetrize averages motions over the box's symmetries; this run also "
                     "predicts stress: roll it out without --symmetrize");
  if (request_.symmetrize) {  // frame averaging: each prediction averaged over the symmetries
    std::string why;
    symmetries_ = scene_symmetries(data_->parsed_scene(), spec_.dim, &why);
    if (symmetries_.size() < 2)
      throw InputError(data_->location() + ": --symmetrize: " + why +
                       ", so there is no symmetry to average over");
    if (spec_.mesh_dimension() != spec_.dim)
      throw InputError(config_file + ": --symmetrize needs mesh positions in " +
                       std::to_string(spec_.dim) + "-D like the world positions (the run has " +
                       std::to_string(spec_.mesh_dimension()) + "-D ones)");
  }
  // Physical validity of the predicted and the true frames: overlap between bodies (cells of the
  // full dimension) and nodes outside the walls (box scenes with walls).
  walls_ = scene_walls(data_->parsed_scene(), spec_.dim);
  const ProjectionOptions& projection = request_.projection;
  if (projection.walls && walls_.empty())
    throw InputError(data_->location() +
                     ": --project walls needs a box scene with walls (its scene has none)");
  if ((projection.cells || projection.contact) && !has_simplices(*data_, spec_.dim))
    throw InputError(data_->location() +
                     ": --project cells and contact need triangles (2-D) or tetrahedra (3-D); its "
                     "cells have " +
                     std::to_string(data_->mesh(0).cell_size) + " nodes in " +
                     std::to_string(spec_.dim) + "-D");
}

torch::Tensor LagrangianRollout::start(int64_t t, int64_t frames) {
  t_ = t;
  mesh_ = &data_->mesh(t);
  const TrajectoryMesh& mesh = *mesh_;
  const int64_t n = mesh.num_nodes();
  auto raw = data_->read(t, "world_pos", 0, frames);
  truth_ = torch::from_blob(raw.data(), {frames, n, spec_.dim}, torch::kFloat32).clone();
  pred_ = {truth_[0], truth_[1]};
  torch::Tensor truth = truth_;
  if (spec_.stress) {
    auto values = data_->read(t, "stress", 0, frames);
    truth_stress_ = torch::from_blob(values.data(), {frames, n, 1}, torch::kFloat32).clone();
    pred_stress_ = {truth_stress_[0], truth_stress_[1]};
    truth = torch::cat({truth_, truth_stress_}, 2);
  }
  graphs_ = first_.store->get(mesh);
  // Orientation checks need simplices of the full dimension (e.g. not shells in 3D).
  const bool simplices = mesh.cell_size == spec_.dim + 1 && mesh.num_cells() > 0;
  cells_ = simplices ? torch::from_blob(const_cast<int32_t*>(mesh.cells.data()),
                                        {mesh.num_cells(), mesh.cell_size}, torch::kInt32)
                           .to(torch::kInt64)
                     : torch::zeros({0, spec_.dim + 1}, torch::kInt64);
  reference_sign_ = signed_measures(cells_, truth_[0], spec_.dim).sign();
  frame_validity_ = validity_for_mesh(mesh, spec_.dim, walls_);
  projector_.reset();
  validity_.start_trajectory();
  mapped_meshes_.clear();
  for (size_t k = 1; k < symmetries_.size(); ++k)
    mapped_meshes_.push_back(symmetries_[k].mesh(mesh));
  model_sq_ = constant_velocity_traj_sq_ = 0;
  return truth;
}

FrameState LagrangianRollout::state_for(const RolloutModel& m, const MeshGraphs* graphs,
                                        int64_t f) const {
  FrameState state{graphs, mesh_, seen(f - 1), seen(f), truth_[f + 1], {}};
  for (int64_t k = f - 2; k >= 0 && k > f - 1 - m.spec.history; --k) state.older.push_back(seen(k));
  return state;
}

torch::Tensor LagrangianRollout::predict(RolloutModel& m, const FrameState& own,
                                         const Batch* plain) {
  if (symmetries_.empty())
    return m.simulator->predict(plain ? *plain : m.adapter->make_batch({own}));
  std::vector<FrameState> views = {own};
  for (size_t k = 1; k < symmetries_.size(); ++k) {
    const BoxSymmetry& g = symmetries_[k];
    FrameState view = own;
    view.mesh = &mapped_meshes_[k - 1];
    view.prev = g.points(own.prev);
    view.cur = g.points(own.cur);
    view.next = g.points(own.next);
    for (auto& older : view.older) older = g.points(older);
    views.push_back(view);
  }
  const int64_t count = static_cast<int64_t>(symmetries_.size());
  const int64_t n = own.cur.size(0);
  const auto out = m.simulator->predict(m.adapter->make_batch(views)).view({count, n, spec_.dim});
  torch::Tensor sum = out[0];
  for (int64_t k = 1; k < count; ++k) sum = sum + symmetries_[k].vectors_back(out[k]);
  return sum / static_cast<double>(count);
}

torch::Tensor LagrangianRollout::step(int64_t f) {
  const int64_t n = mesh_->num_nodes();
  const FrameState state = state_for(first_, graphs_.get(), f);
  const Batch batch = first_.adapter->make_batch({state});
  const ProjectionOptions& projection = request_.projection;
  if (!projector_ && !projection_names(projection).empty()) {
    const auto rest = truth_[0].contiguous();
    const auto movable = batch.mask.to(torch::kUInt8).contiguous();
    projector_.emplace(
        spec_.dim, cells_.size(0) > 0 ? mesh_->cells : std::vector<int32_t>{}, mesh_->body_id, n,
        rest.data_ptr<float>(), projection.walls ? walls_ : BoxWalls{}, projection,
        std::vector<uint8_t>(movable.data_ptr<uint8_t>(), movable.data_ptr<uint8_t>() + n));
  }
  auto accel = predict(first_, state, &batch);
  for (RolloutModel& m : members_)  // the same state through each member's own inputs
    accel = accel + predict(m, state_for(m, m.store->get(*mesh_).get(), f), nullptr);
  if (!members_.empty()) accel = accel / static_cast<double>(members_.size() + 1);
  next_stress_ = torch::Tensor();  // predicted on the solved nodes, the truth elsewhere
  if (spec_.stress) {
    next_stress_ =
        torch::where(batch.mask.unsqueeze(1), accel.narrow(1, spec_.dim, 1), truth_stress_[f + 1]);
    accel = accel.narrow(1, 0, spec_.dim);
  }
  next_ = first_.adapter->integrate(batch, accel, truth_[f + 1]);
  if (projector_) {
    next_ = next_.contiguous();
    projection_tally_.add(projector_->project(next_.data_ptr<float>()), n);
  }
  next_mask_ = batch.mask;
  return spec_.stress ? torch::cat({next_, next_stress_}, 1) : next_;
}

std::vector<FieldError> LagrangianRollout::accept(int64_t f) {
  pred_.push_back(next_);
  std::vector<FieldError> errors;
  const double frame_dt = data_->frame_dt() > 0 ? data_->frame_dt() : 1.0;
  const auto pos_err = (next_ - truth_[f + 1]).pow(2).mean().item<double>();
  const auto vel_err =
      ((next_ - seen(f)) - (truth_[f + 1] - truth_[f])).div(frame_dt).pow(2).mean().item<double>();
  errors.push_back({"world_pos", pos_err, 1.0});
  errors.push_back({"velocity", vel_err, 1.0});
  if (spec_.stress) {
    pred_stress_.push_back(next_stress_);
    errors.push_back(
        {"stress", (next_stress_ - truth_stress_[f + 1]).pow(2).mean().item<double>(), 1.0});
    stress_held_sq_ += (truth_stress_[1] - truth_stress_[f + 1]).pow(2).mean().item<double>();
    ++stress_held_count_;
  }
  score_references(f, next_mask_.unsqueeze(1));
  const size_t step = static_cast<size_t>(f - 1);
  if (inverted_sum_.size() <= step) {
    inverted_sum_.resize(step + 1, 0.0);
    inverted_count_.resize(step + 1, 0);
  }
  inverted_sum_[step] += inverted_fraction(cells_, reference_sign_, next_, spec_.dim);
  ++inverted_count_[step];
  if (frame_validity_) {
    const auto predicted = next_.contiguous();
    const auto target = truth_[f + 1].contiguous();
    validity_.add(step, frame_validity_->measure(predicted.data_ptr<float>()),
                  frame_validity_->measure(target.data_ptr<float>()));
  }
  model_sq_ += pos_err;
  return errors;
}

void LagrangianRollout::score_references(int64_t f, const torch::Tensor& mask) {
  const auto& truth = truth_;
  // With teacher forcing the references start from the true frames too: one step at the last
  // true velocity, and each body's shape of frame f held.
  const auto constant_velocity =
      request_.one_step
          ? torch::where(mask, 2 * truth[f] - truth[f - 1], truth[f + 1])
          : torch::where(mask, truth[1] + static_cast<double>(f) * (truth[1] - truth[0]),
                         truth[f + 1]);
  const double mse = (constant_velocity - truth[f + 1]).pow(2).mean().item<double>();
  constant_velocity_sq_ += mse;
  constant_velocity_traj_sq_ += mse;
  ++constant_velocity_count_;
  constant_velocity_parts_.add(body_motion_error(constant_velocity, truth[f + 1], mesh_->body_id));
  rigid_parts_.add(
      body_motion_error(request_.one_step ? truth[f] : truth[1], truth[f + 1], mesh_->body_id));
  model_parts_.add(body_motion_error(next_, truth[f + 1], mesh_->body_id));
}

void LagrangianRollout::end_trajectory(int64_t steps) {
  const double inv_steps = steps > 0 ? 1.0 / static_cast<double>(steps) : 0.0;
  per_trajectory_.steps.push_back(steps);
  per_trajectory_.model.push_back(std::sqrt(model_sq_ * inv_steps));
  per_trajectory_.constant_velocity.push_back(std::sqrt(constant_velocity_traj_sq_ * inv_steps));
  graphs_.reset();
}

std::string LagrangianRollout::finish(RolloutMetrics& metrics) const {
  metrics.model = model_name_;
  metrics.one_step = request_.one_step;
  metrics.symmetries = symmetries_.empty() ? 1 : static_cast<int>(symmetries_.size());
  metrics.projection = projection_tally_.metrics(projection_names(request_.projection));
  if (stress_held_count_ > 0) {
    FieldRmse held;
    held.fields = {
        {"stress", std::sqrt(stress_held_sq_ / static_cast<double>(stress_held_count_))}};
    held.total = held.fields["stress"];
    metrics.rmse_all_persistence = held;
  }
  if (constant_velocity_count_ > 0)
    metrics.rmse_all_constant_velocity =
        std::sqrt(constant_velocity_sq_ / static_cast<double>(constant_velocity_count_));
  metrics.rmse_all_parts = model_parts_.rmse();
  metrics.rmse_all_parts_constant_velocity = constant_velocity_parts_.rmse();
  if (const auto rigid = rigid_parts_.rmse())
    metrics.rmse_all_deformation_rigid = rigid->deformation;
  metrics.rmse_all_ratio_interval = bootstrap_ratio_interval(
      per_trajectory_.steps, per_trajectory_.model, per_trajectory_.constant_velocity);
  metrics.per_trajectory = per_trajectory_;
  // Stability: the fraction of predicted cells turned inside out (orientation flipped against
  // the first frame), per step and at worst; the ground truth has none (the solver stops on J <=
  // 0).
  for (size_t s = 0; s < inverted_count_.size(); ++s) {
    const double f = inverted_sum_[s] / static_cast<double>(inverted_count_[s]);
    metrics.inverted_cells_per_step.push_back(f);
    metrics.inverted_cells_max = std::max(metrics.inverted_cells_max, f);
  }
  metrics.validity = validity_.metrics();
  return summary(metrics);
}

std::string LagrangianRollout::summary(const RolloutMetrics& metrics) const {
  std::ostringstream out;
  out << (request_.one_step ? "one-step (teacher forcing) " : "") << "RMSE-all(world_pos) "
      << (metrics.rmse_all ? metrics.rmse_all->at("world_pos") : 0.0);
  if (metrics.rmse_all && metrics.rmse_all->fields.count("stress"))
    out << ", RMSE-all(stress) " << metrics.rmse_all->at("stress") << " (held "
        << (metrics.rmse_all_persistence ? metrics.rmse_all_persistence->at("stress") : 0.0) << ")";
  if (metrics.rmse_all_parts)
    out << " (by body: centre " << metrics.rmse_all_parts->centre << ", rotation "
        << metrics.rmse_all_parts->rotation << ", deformation "
        << metrics.rmse_all_parts->deformation << ")";
  if (metrics.rmse_all && metrics.rmse_all_constant_velocity &&
      *metrics.rmse_all_constant_velocity > 0) {
    out << ", " << metrics.rmse_all->at("world_pos") / *metrics.rmse_all_constant_velocity
        << "x constant velocity";
    if (metrics.rmse_all_ratio_interval)
      out << " (95 % over trajectories " << metrics.rmse_all_ratio_interval->lo << "-"
          << metrics.rmse_all_ratio_interval->hi << ")";
  }
  if (metrics.validity && metrics.validity->model.overlap && metrics.validity->truth.overlap)
    out << ", overlap between bodies at worst " << metrics.validity->model.overlap->max
        << " (truth " << metrics.validity->truth.overlap->max << ")";
  return out.str();
}

}  // namespace

std::unique_ptr<RolloutDomain> lagrangian_rollout(const RolloutRequest& request,
                                                  const RunFolder& folder) {
  const int threads = configure_threads(set_num_threads(request.threads));
  auto domain = std::make_unique<LagrangianRollout>(request, folder);
  domain->threads = threads;
  return domain;
}

}  // namespace bsms
