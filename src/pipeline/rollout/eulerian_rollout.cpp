// The Eulerian rollout domain (rollout_domain.hpp; public CylinderFlow / Airfoil data): the state
// (velocity, density) advances by the predicted change on NORMAL and OUTFLOW nodes, every other
// node keeps its ground truth; pressure is read from the output. Scored per field beside
// persistence (the first frame held: no model).
#include <torch/torch.h>

#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/runtime.hpp"
#include "models/graph_ops.hpp"
#include "pipeline/adapters/eulerian.hpp"
#include "pipeline/adapters/simulator.hpp"
#include "pipeline/rollout/rollout_domain.hpp"

namespace bsms {

namespace {

namespace fs = std::filesystem;

class EulerianRollout final : public RolloutDomain {
 public:
  // `simulator`: the run's model, loaded before the data is opened (a run without a checkpoint
  // is named first).
  EulerianRollout(const RolloutRequest& request, const RunFolder& folder, EulerianSpec spec,
                  std::shared_ptr<LearnedSimulator> simulator);

  // The truth: the state fields, then the pressure.
  torch::Tensor start(int64_t t, int64_t frames) override;
  // The state plus the predicted change on NORMAL and OUTFLOW nodes, the truth elsewhere.
  torch::Tensor step(int64_t f) override;
  // Errors per field, and the persistence's beside them.
  std::vector<FieldError> accept(int64_t f) override;
  void end_trajectory(int64_t) override { graphs_.reset(); }
  // The persistence's RMSE.
  std::string finish(RolloutMetrics& metrics) const override;

 private:
  std::string model_type_;
  EulerianSpec spec_;
  std::shared_ptr<LearnedSimulator> simulator_;
  std::unique_ptr<GraphStore> store_;
  std::unique_ptr<EulerianAdapter> adapter_;
  // What no model achieves: the first frame held on the predicted nodes (FieldCurves of the
  // persistence's errors, pooled like the model's).
  FieldCurves held_;

  // The trajectory being rolled out.
  const TrajectoryMesh* mesh_ = nullptr;
  std::shared_ptr<const MeshGraphs> graphs_;
  torch::Tensor truth_, truth_p_;  // [frames, N, state_size], [frames, N, 1] (with pressure)
  std::vector<torch::Tensor> pred_, pred_p_;
  torch::Tensor next_, next_p_, next_mask_;  // step()'s prediction, until accept()
};

// The run's model, checkpoint `path` loaded (its step in `step`), in evaluation mode.
std::shared_ptr<LearnedSimulator> load_model(const RunFolder& folder, const EulerianSpec& spec,
                                             const std::string& path, int64_t& step) {
  auto simulator = std::make_shared<LearnedSimulator>(EulerianAdapter(spec).model_shape(),
                                                      folder.config.model, folder.levels);
  step = load_checkpoint(path, *simulator, nullptr).step;
  simulator->eval();
  return simulator;
}

std::vector<ScoredField> scored_fields(const EulerianSpec& spec) {
  std::vector<ScoredField> fields;
  for (const FieldInfo& f : spec.state_fields()) fields.push_back({f.name, true, true});
  if (spec.pressure) fields.push_back({"pressure", true, true});
  return fields;
}

EulerianRollout::EulerianRollout(const RolloutRequest& request, const RunFolder& folder,
                                 EulerianSpec spec, std::shared_ptr<LearnedSimulator> simulator)
    : model_type_(folder.config.model.type),
      spec_(std::move(spec)),
      simulator_(std::move(simulator)),
      held_(scored_fields(spec_)) {
  data_.emplace(
      Dataset::open_split(request.data.empty() ? folder.config.data : request.data, request.split));
  levels = folder.levels;
  if (data_->mesh(0).dim != spec_.dim)
    throw InputError(data_->location() + ": mesh dimension " + std::to_string(data_->mesh(0).dim) +
                     " differs from the model's " + std::to_string(spec_.dim));
  for (const FieldInfo& f : spec_.state_fields())
    if (!data_->has_field(f.name))
      throw InputError(data_->location() + ": the model needs the field " + f.name);
  if (spec_.pressure && !data_->has_field("pressure"))
    throw InputError(data_->location() + ": the model needs the field pressure");
  const std::string data_dir = request.data.empty() ? folder.config.data : request.data;
  const std::vector<std::string> cache_dirs = multilevel_cache_dirs(data_dir, folder.dir);
  std::error_code ec;
  for (const auto& d : cache_dirs) fs::create_directories(d, ec);
  seeding = request.seeding.empty() ? folder.config.model.seeding : parse_seeding(request.seeding);
  store_ = std::make_unique<GraphStore>(seeding, levels, cache_dirs);
  adapter_ = std::make_unique<EulerianAdapter>(spec_);
  layout_.given_frames = 1;
  layout_.dim = spec_.dim;
  layout_.frame = spec_.state_fields();
  if (spec_.pressure) layout_.frame.push_back({"pressure", 1});
  layout_.scored = scored_fields(spec_);
}

torch::Tensor EulerianRollout::start(int64_t t, int64_t frames) {
  mesh_ = &data_->mesh(t);
  truth_ = read_eulerian_state(*data_, spec_, t, 0, frames);
  truth_p_ = read_eulerian_pressure(*data_, spec_, t, 0, frames);
  graphs_ = store_->get(*mesh_);
  pred_ = {truth_[0]};
  pred_p_.clear();
  if (spec_.pressure) pred_p_.push_back(truth_p_[0]);
  return spec_.pressure ? torch::cat({truth_, truth_p_}, 2) : truth_;
}

torch::Tensor EulerianRollout::step(int64_t f) {
  const Batch batch = adapter_->make_batch({EulerianFrame{graphs_.get(), mesh_, pred_[f]}});
  const auto output = simulator_->predict(batch);
  std::tie(next_, next_p_) = adapter_->integrate(
      batch, output, truth_[f + 1], spec_.pressure ? truth_p_[f + 1] : torch::Tensor());
  next_mask_ = batch.mask.unsqueeze(1);
  return spec_.pressure ? torch::cat({next_, next_p_}, 1) : next_;
}

std::vector<FieldError> EulerianRollout::accept(int64_t f) {
  pred_.push_back(next_);
  if (spec_.pressure) pred_p_.push_back(next_p_);
  const auto held = torch::where(next_mask_, truth_[0], truth_[f + 1]);
  const auto err = next_ - truth_[f + 1], err_hold = held - truth_[f + 1];
  const double n = static_cast<double>(mesh_->num_nodes());
  std::vector<FieldError> errors;
  int64_t c0 = 0;
  for (const FieldInfo& field : spec_.state_fields()) {
    const double weight = n * static_cast<double>(field.width);
    errors.push_back(
        {field.name, err.slice(1, c0, c0 + field.width).square().sum().item<double>(), weight});
    held_.add(static_cast<size_t>(f),
              {field.name, err_hold.slice(1, c0, c0 + field.width).square().sum().item<double>(),
               weight});
    c0 += field.width;
  }
  if (spec_.pressure) {
    errors.push_back({"pressure", (next_p_ - truth_p_[f + 1]).square().sum().item<double>(), n});
    const auto held_p = torch::where(next_mask_, truth_p_[0], truth_p_[f + 1]);
    held_.add(static_cast<size_t>(f),
              {"pressure", (held_p - truth_p_[f + 1]).square().sum().item<double>(), n});
  }
  return errors;
}

std::string EulerianRollout::finish(RolloutMetrics& metrics) const {
  metrics.model = model_type_;
  metrics.eulerian = true;
  metrics.rmse_1_persistence = held_.rmse_over(1);
  metrics.rmse_all_persistence = held_.rmse_over(held_.steps());
  std::ostringstream out;
  out << "RMSE-all";
  if (metrics.rmse_all)
    for (const ScoredField& f : layout_.scored)
      out << " " << f.name << " " << metrics.rmse_all->at(f.name) << " (held "
          << RolloutMetrics::rmse(metrics.rmse_all_persistence, f.name) << ")";
  return out.str();
}

}  // namespace

std::unique_ptr<RolloutDomain> eulerian_rollout(const RolloutRequest& request,
                                                const RunFolder& folder) {
  const std::string& config_file = folder.config_path;
  if (!request.ensemble.empty())
    throw InputError(config_file + ": an Eulerian run; --ensemble averages Lagrangian runs");
  if (request.symmetrize)
    throw InputError(config_file + ": an Eulerian run; --symmetrize maps Lagrangian states");
  if (!projection_names(request.projection).empty())
    throw InputError(config_file + ": an Eulerian run; --project moves Lagrangian nodes");
  if (request.one_step)
    throw InputError(request.run +
                     ": --one-step (teacher forcing) is for Lagrangian runs; this one is "
                     "Eulerian (velocity)");
  const int threads = configure_threads(set_num_threads(request.threads));
  EulerianSpec spec = eulerian_spec_from_json(folder.features_resolved, folder.config_path);
  const ModelCheckpoint checkpoint = run_model_checkpoint(folder.dir, request.checkpoint);
  int64_t step = 0;
  auto simulator = load_model(folder, spec, checkpoint.path, step);
  auto domain =
      std::make_unique<EulerianRollout>(request, folder, std::move(spec), std::move(simulator));
  domain->threads = threads;
  domain->checkpoint = checkpoint.name;
  domain->checkpoint_step = step;
  return domain;
}

}  // namespace bsms
